//! Environment factors: sampled at a drone's position and time by physics and sensors.
//! New factors (fog, rain, ...) are new optional fields here and new `EnvironmentFactor`
//! implementations in `sim-worker`; physics does not change.

use kube::core::Duration;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// All environment factors; each is off when absent.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Environment {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<Wind>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss: Option<Gnss>,
}

/// Turbulence intensity of the Dryden model (MIL-F-8785C levels): `none` (default),
/// `light`, `moderate`, `severe`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum Turbulence {
    #[default]
    None,
    Light,
    Moderate,
    Severe,
}

/// Mean wind with a logarithmic height profile, plus Dryden turbulence seeded per drone.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Wind {
    /// Mean wind speed at `referenceHeightM` above ground, m/s (0..40).
    #[schemars(range(min = 0.0, max = 40.0))]
    pub speed_mps: f64,
    /// Direction the wind blows *from*, degrees clockwise from true north (0..360).
    #[schemars(range(min = 0.0, max = 360.0))]
    pub direction_from_deg: f64,
    /// Height of the speed measurement above ground, metres. Default 10 (meteorological
    /// standard).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1.0, max = 500.0))]
    pub reference_height_m: Option<f64>,
    /// Turbulence intensity. Default none.
    #[serde(default)]
    pub turbulence: Turbulence,
    /// The wind around the world's buildings. Default: the built-in diagnostic model when
    /// the world has buildings (`model: diagnostic`, 8 sectors, 5 m cells or coarser for
    /// large worlds); `model: none` flies the plain profile everywhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urban: Option<UrbanWind>,
}

/// How the wind around buildings is computed.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct UrbanWind {
    /// `diagnostic` (default): the built-in Röckle-type model made mass-consistent;
    /// `none`: no building effects; `openfoam`: the field computed by OpenFOAM (Debian's
    /// `openfoam`: blockMesh, snappyHexMesh over the buildings, simpleFoam with an
    /// atmospheric boundary-layer inlet) in the asset phase for the sectors of the run's
    /// wind direction, or imported from `case`.
    #[serde(default)]
    pub model: UrbanWindModel,
    /// With `model: openfoam`: an OpenFOAM case computed elsewhere, imported instead of
    /// running OpenFOAM (local runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case: Option<OpenFoamCase>,
    /// Edge of the field's cubic cells, metres (1..100). Default 5, coarser when the world
    /// square would be more than 200 cells across.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1.0, max = 100.0))]
    pub spacing_m: Option<f64>,
    /// Inflow direction sectors around the compass (4..36). Default 8 (45° apart): a
    /// direction between two sectors blends their fields.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 4, max = 36))]
    pub sectors: Option<u32>,
}

/// An OpenFOAM case computed elsewhere: its latest time directory holds the cell centres
/// `C` (`postProcess -func writeCellCentres`) and the velocity `U`, ASCII, in the run's ENU
/// frame (x east, y north, z up, metres from the origin) and m/s. It must cover the world's
/// wind grid (docs/wind-cfd.md).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct OpenFoamCase {
    /// The case directory: a path, relative to the scenario file's folder.
    #[schemars(length(min = 1, max = 4096))]
    pub dir: String,
    /// Where the case's wind blows from, degrees clockwise from north (0..360): the
    /// scenario's `directionFromDeg` must be the same (a case is one direction).
    #[schemars(range(min = 0.0, max = 360.0))]
    pub direction_from_deg: f64,
    /// The case's undisturbed inflow speed 10 m above open ground, m/s (0.1..100): the
    /// field is stored as factors of it and flown at the scenario's speed.
    #[schemars(range(min = 0.1, max = 100.0))]
    pub reference_speed_mps: f64,
}

/// The urban wind model.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum UrbanWindModel {
    #[default]
    Diagnostic,
    None,
    #[serde(rename = "openfoam")]
    OpenFoam,
}

/// GNSS receiver model. Without `constellation`: the statistical receiver (white noise, a
/// random-walk bias). With it: the ranging receiver, whose fix is solved from
/// pseudoranges to the real satellites, blocked and reflected by the world's buildings and
/// terrain. Both honour `rateHz` and the scheduled `dropouts`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Gnss {
    /// The satellites of an orbit file: turns on the ranging receiver (urban GNSS). The
    /// statistical receiver's noise fields (`horizontalSigmaM`, `verticalSigmaM`,
    /// `biasWalkMPerSqrtS`) are then not allowed: the errors come from the geometry.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constellation: Option<GnssConstellation>,
    /// Fix rate, Hz (1..20). Default 5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1.0, max = 20.0))]
    pub rate_hz: Option<f64>,
    /// 1-sigma horizontal white noise, metres (0..100). Default 0.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 100.0))]
    pub horizontal_sigma_m: Option<f64>,
    /// 1-sigma vertical white noise, metres (0..100). Default 0.8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 100.0))]
    pub vertical_sigma_m: Option<f64>,
    /// Bias random-walk intensity, metres per sqrt(second) (0..10). Default 0.01.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 10.0))]
    pub bias_walk_m_per_sqrt_s: Option<f64>,
    /// A constant position error added to every fix, metres, world ENU: a datum error, a
    /// spoofed or multipath-biased fix. A drone flying by GNSS alone then misses its target
    /// by exactly this. Applies to both receivers. Default none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias: Option<GnssBias>,
    /// Scheduled outages.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 256))]
    pub dropouts: Vec<GnssDropout>,
}

/// A constant GNSS position bias, metres, world ENU (each -100..100, default 0): the fix
/// reports the drone `eastM` east, `northM` north and `upM` above where it is.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct GnssBias {
    /// East error, metres (-100..100).
    #[serde(default)]
    #[schemars(range(min = -100.0, max = 100.0))]
    pub east_m: f64,
    /// North error, metres (-100..100).
    #[serde(default)]
    #[schemars(range(min = -100.0, max = 100.0))]
    pub north_m: f64,
    /// Up error, metres (-100..100).
    #[serde(default)]
    #[schemars(range(min = -100.0, max = 100.0))]
    pub up_m: f64,
}

/// The GNSS constellation of a run: which orbit file, which instant is the run's t = 0.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct GnssConstellation {
    /// Orbit file: two- or three-line element sets (TLE), or Orbit Mean-Elements Messages
    /// (OMM) in KVN, XML, JSON or CSV, as CelesTrak publishes its GNSS groups. A local path
    /// (relative to the scenario's folder), `file://`, or an object-store URL (`s3://`,
    /// `gs://`, `az://`) on a cluster. Default: the nominal GPS + Galileo constellation
    /// shipped with sadesim (48 satellites in their nominal Walker patterns, element sets of
    /// 2020-11-30T12:00:00Z): a plausible sky for any epoch, not a real day's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1, max = 1024))]
    pub file: Option<String>,
    /// UTC time of the run's t = 0 (RFC 3339, e.g. `2020-12-01T12:00:00Z`). Default: the
    /// newest element set's epoch in the file (orbits are most accurate near their epoch).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(max = 64))]
    pub epoch: Option<String>,
    /// Satellites below this elevation are not tracked, degrees (0..60). Default 10.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 60.0))]
    pub elevation_mask_deg: Option<f64>,
}

/// No fix for `duration` from sim time `start`, for the listed groups (all when empty).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct GnssDropout {
    /// Sim time the outage starts (Go duration from the run start).
    pub start: Duration,
    /// How long it lasts.
    pub duration: Duration,
    /// Affected fleet groups; empty means every drone.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 64), inner(length(max = 40)))]
    pub groups: Vec<String>,
}
