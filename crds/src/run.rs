//! The `SimulationRun` custom resource: the one document that declares a run.
//!
//! Field names carry their unit (`altitudeMslM`, `physicsRateHz`); durations are Go-style
//! strings (`90s`, `15m`, `1h30m`) as everywhere else in Kubernetes. Every optional field
//! is skipped when unset so server-side apply never sends nulls.

use kube::{CustomResource, KubeSchema, core::Duration};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::criteria::Criterion;
use crate::environment::Environment;
use crate::fleet::FleetGroup;
use crate::status::SimulationRunStatus;
use crate::zones::Zone;

/// Default physics rate, Hz: the paper's 1000 Hz lockstep.
pub const DEFAULT_PHYSICS_RATE_HZ: u32 = 1000;
/// Default drones per physics shard.
pub const DEFAULT_DRONES_PER_SHARD: u32 = 100;
/// Default sync window: physics steps between shard <-> coordinator exchanges (DESIGN §5).
pub const DEFAULT_SYNC_WINDOW_STEPS: u32 = 10;
/// Default half-width of the square world around the origin, metres.
pub const DEFAULT_WORLD_EXTENT_M: f64 = 3000.0;

/// Specification of one simulation run: where, how long, which drones with which pilot,
/// under which airspace rules, and how to judge and keep the result.
#[derive(CustomResource, KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[kube(
    group = "sadesim.io",
    version = "v1alpha1",
    kind = "SimulationRun",
    plural = "simulationruns",
    namespaced,
    shortname = "simrun",
    category = "sadesim",
    status = "SimulationRunStatus",
    derive = "PartialEq",
    doc = "A SADE-SIM simulation run: fleet, world, environment, airspace zones, pilot and evidence archive.",
    printcolumn = r#"{"name":"Phase","type":"string","jsonPath":".status.phase"}"#,
    printcolumn = r#"{"name":"Drones","type":"integer","jsonPath":".status.drones"}"#,
    printcolumn = r#"{"name":"Shards","type":"integer","jsonPath":".status.shardCount"}"#,
    printcolumn = r#"{"name":"SimTime","type":"number","jsonPath":".status.simTimeS","description":"Simulated seconds elapsed"}"#,
    printcolumn = r#"{"name":"RTF","type":"number","jsonPath":".status.realTimeFactor","description":"Simulated seconds per wall-clock second"}"#,
    printcolumn = r#"{"name":"Age","type":"date","jsonPath":".metadata.creationTimestamp"}"#
)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("has(self.clock) == has(oldSelf.clock) && has(self.physicsRateHz) == has(oldSelf.physicsRateHz) && has(self.seed) == has(oldSelf.seed) && has(self.world) == has(oldSelf.world) && has(self.environment) == has(oldSelf.environment) && has(self.zones) == has(oldSelf.zones) && has(self.pilot) == has(oldSelf.pilot) && has(self.rendering) == has(oldSelf.rendering) && has(self.sharding) == has(oldSelf.sharding) && has(self.recording) == has(oldSelf.recording) && has(self.archive) == has(oldSelf.archive) && has(self.criteria) == has(oldSelf.criteria) && has(self.queue) == has(oldSelf.queue) && has(self.groundStations) == has(oldSelf.groundStations)").message("spec fields cannot be added or removed once the run exists: only spec.abort may change (create a new run instead)"))]
#[x_kube(validation = Rule::new("has(self.pilot) || self.fleet.all(g, has(g.mission))").message("spec.pilot is required: a fleet group without a mission is flown over MAVLink by the pilot").field_path(".pilot"))]
pub struct SimulationRunSpec {
    /// Geodetic origin of the run's local ENU frame, on the ground at the centre of the world.
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub origin: Origin,
    /// Simulated time the run lasts (Go duration, e.g. `15m`). The run may end earlier when
    /// the pilot exits or the run is aborted.
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub duration: Duration,
    /// How simulated time relates to wall-clock time. Default `realtime`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub clock: Option<Clock>,
    /// Physics steps per simulated second. Default 1000 Hz.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 50, max = 10000))]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub physics_rate_hz: Option<u32>,
    /// Seed of every random stream in the run (DESIGN §5). Same seed, same run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub seed: Option<u64>,
    /// The world: ground, buildings, extent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub world: Option<World>,
    /// Environment factors sampled by physics and sensors: wind, GNSS.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub environment: Option<Environment>,
    /// Drone groups. Drones get global indices in group order.
    #[schemars(length(min = 1, max = 64))]
    #[x_kube(merge_strategy = ListMerge::Map(vec!["name".into()]))]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub fleet: Vec<FleetGroup>,
    /// Airspace zones (SADE Zones) enforced by the airspace authority.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 64))]
    #[x_kube(merge_strategy = ListMerge::Map(vec!["name".into()]))]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub zones: Vec<Zone>,
    /// The software pilot under test: flies every group that has no scripted mission.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub pilot: Option<Pilot>,
    /// Live 3D rendering.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub rendering: Option<Rendering>,
    /// How physics is split across shards.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub sharding: Option<Sharding>,
    /// What is recorded (MCAP, ULog) and at which rates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub recording: Option<Recording>,
    /// Where the run's evidence is archived.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub archive: Option<Archive>,
    /// Pass/fail criteria evaluated at the end of the run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 64))]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub criteria: Vec<Criterion>,
    /// Kueue LocalQueue to admit the run through (Kubernetes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1, max = 63), pattern(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$"))]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub queue: Option<String>,
    /// Who outside the run may reach its MAVLink routers, drones and airspace API, and MAVLink
    /// signing for ground stations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[x_kube(validation = Rule::new("self == oldSelf").message("is immutable once the run exists: only spec.abort may change (create a new run instead)"))]
    pub ground_stations: Option<crate::ground_stations::GroundStations>,
    /// Set to true to stop the run: pilot first, then shards, then the archive is written.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub abort: bool,
}

impl SimulationRunSpec {
    pub fn clock(&self) -> Clock {
        self.clock.clone().unwrap_or_default()
    }
    /// Whether any group has onboard cameras (`spec.fleet[].cameras`).
    pub fn has_cameras(&self) -> bool {
        self.fleet.iter().any(|g| !g.cameras.is_empty())
    }
    pub fn physics_rate_hz(&self) -> u32 {
        self.physics_rate_hz.unwrap_or(DEFAULT_PHYSICS_RATE_HZ)
    }
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(0)
    }
    pub fn world(&self) -> World {
        self.world.clone().unwrap_or_default()
    }
    pub fn environment(&self) -> Environment {
        self.environment.clone().unwrap_or_default()
    }
    pub fn sharding(&self) -> Sharding {
        self.sharding.clone().unwrap_or_default()
    }
    pub fn rendering(&self) -> Rendering {
        self.rendering.clone().unwrap_or_default()
    }
    pub fn recording(&self) -> Recording {
        self.recording.clone().unwrap_or_default()
    }
    /// Total drones over all groups.
    pub fn total_drones(&self) -> u64 {
        self.fleet.iter().map(|g| u64::from(g.count)).sum()
    }
    /// Duration in simulated seconds (negative durations are rejected by validation).
    pub fn duration_s(&self) -> f64 {
        let d: std::time::Duration = self.duration.into();
        if self.duration.is_negative() { -d.as_secs_f64() } else { d.as_secs_f64() }
    }
}

/// WGS84 origin of the local frame: the ground point at the centre of the world.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Origin {
    /// Latitude, degrees north (WGS84), -85..85.
    #[schemars(range(min = -85.0, max = 85.0))]
    pub latitude_deg: f64,
    /// Longitude, degrees east (WGS84), -180..180.
    #[schemars(range(min = -180.0, max = 180.0))]
    pub longitude_deg: f64,
    /// Ground altitude at the origin, metres above mean sea level.
    #[schemars(range(min = -500.0, max = 9000.0))]
    pub altitude_msl_m: f64,
}

impl Origin {
    pub fn geo(&self) -> crate::geo::GeoPoint {
        crate::geo::GeoPoint::new(self.latitude_deg, self.longitude_deg, self.altitude_msl_m)
    }
}

/// How the coordinator paces simulated time: `realtime` (1 sim s per wall s: external
/// pilots and ground stations), `scaled` (`factor` sim s per wall s), `asFastAsPossible`
/// (scripted missions and CI).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum ClockMode {
    /// One simulated second per wall-clock second: for external pilots and ground stations.
    #[default]
    Realtime,
    /// `factor` simulated seconds per wall-clock second.
    Scaled,
    /// As fast as the slowest shard: for scripted missions and CI.
    AsFastAsPossible,
}

/// Clock: `{mode: realtime}`, `{mode: scaled, factor: 4}` or `{mode: asFastAsPossible}`.
#[derive(KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("self.mode == 'scaled' ? has(self.factor) : !has(self.factor)").message("clock.factor is required with mode scaled and only allowed with it").field_path(".factor"))]
pub struct Clock {
    pub mode: ClockMode,
    /// Simulated seconds per wall-clock second with `mode: scaled`, 0.01..1000.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.01, max = 1000.0))]
    pub factor: Option<f64>,
}

/// Where the world geometry comes from: `procedural` (a seeded city of streets, buildings
/// and parks around the origin) or `osm` (the buildings and parks of an OpenStreetMap
/// extract, `world.osm`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum WorldSource {
    /// A seeded procedural city (streets, buildings, parks) around the origin.
    #[default]
    Procedural,
    /// The buildings (footprints with courtyards, tagged or estimated heights, building
    /// parts) and parks of the OpenStreetMap extract `world.osm.file`, on flat ground or
    /// `world.terrain`.
    Osm,
}

/// The OpenStreetMap extract of `world.source: osm`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct OsmExtract {
    /// The `.osm.pbf` file (Geofabrik, BBBike, `osmium extract`): a path, relative to the
    /// scenario file's folder, a `file://` URL, or an object-store URL (`s3://bucket/key`,
    /// `gs://`, `az://`; what a Kubernetes run needs). It must cover the whole world square.
    #[schemars(length(min = 1, max = 4096))]
    pub file: String,
    /// Roof height, metres above the building's base, of the buildings whose map has no
    /// `height`, `building:height` or `building:levels` tag (2..300). Default 9 (three
    /// storeys). Where the map leaves most heights out and the local stock is known (the
    /// five- to seven-storey blocks of a European centre: ~20 m), say so here: urban GNSS
    /// and contacts depend on it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 2.0, max = 300.0))]
    pub default_height_m: Option<f64>,
}

/// The ground of the world.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct TerrainSpec {
    /// A digital elevation model: a GeoTIFF (EPSG:4326 or WGS84 UTM) or an SRTM `.hgt` tile,
    /// elevations in metres above mean sea level. It replaces the procedural relief;
    /// buildings stand on it and every AGL height (homes, altitude limits, zones, the
    /// monitor, criteria) is above it. It must cover the whole world square.
    pub dem: DemFile,
}

/// A DEM file.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct DemFile {
    /// A path, relative to the scenario file's folder, a `file://` URL, or an object-store
    /// URL (`s3://bucket/key`, `gs://`, `az://`; what a Kubernetes run needs).
    #[schemars(length(min = 1, max = 4096))]
    pub file: String,
}

/// The world around the origin.
#[derive(KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("(has(self.source) && self.source == 'osm') == has(self.osm)").message("world.osm is required with source osm and only allowed with it").field_path(".osm"))]
#[x_kube(validation = Rule::new("!(has(self.source) && self.source == 'osm') || (!has(self.city) && !has(self.openAreas))").message("world.city and world.openAreas shape the procedural city: with source osm the map's buildings and parks are the world"))]
pub struct World {
    #[serde(default)]
    pub source: WorldSource,
    /// The extract of `source: osm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub osm: Option<OsmExtract>,
    /// The ground from a DEM instead of the procedural relief (or the flat ground of a
    /// mapped city). Local runs only so far.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terrain: Option<TerrainSpec>,
    /// Half-width of the square world centred on the origin, metres (100..50000). Homes,
    /// waypoints and zones must lie inside.
    #[serde(default = "default_extent_m")]
    #[schemars(range(min = 100.0, max = 50000.0))]
    pub extent_m: f64,
    /// Procedural city parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub city: Option<City>,
    /// Discs kept free of buildings: real parks, plazas, rivers or airfields the pilot's
    /// routes rely on. (Home areas of the fleet are kept open automatically.)
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 256))]
    pub open_areas: Vec<crate::fleet::Area>,
    /// Fiducial markers on the ground (ArUco), seen by the onboard cameras only: a world
    /// with markers needs a group with cameras.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 64))]
    pub markers: Vec<crate::camera::GroundMarker>,
}

fn default_extent_m() -> f64 {
    DEFAULT_WORLD_EXTENT_M
}

impl Default for World {
    fn default() -> Self {
        Self {
            source: WorldSource::Procedural,
            osm: None,
            terrain: None,
            extent_m: DEFAULT_WORLD_EXTENT_M,
            city: None,
            open_areas: Vec::new(),
            markers: Vec::new(),
        }
    }
}

impl World {
    pub fn city(&self) -> City {
        self.city.clone().unwrap_or_default()
    }
}

/// Shape of the procedural city. Defaults resemble a North American downtown grid.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct City {
    /// Side of a city block between streets, metres.
    #[serde(default = "City::default_block_m")]
    #[schemars(range(min = 20.0, max = 1000.0))]
    pub block_size_m: f64,
    /// Street width between blocks, metres.
    #[serde(default = "City::default_street_m")]
    #[schemars(range(min = 5.0, max = 200.0))]
    pub street_width_m: f64,
    /// Median building height, metres (heights are log-normal around it).
    #[serde(default = "City::default_median_height_m")]
    #[schemars(range(min = 3.0, max = 300.0))]
    pub median_building_height_m: f64,
    /// Tallest building, metres.
    #[serde(default = "City::default_max_height_m")]
    #[schemars(range(min = 3.0, max = 1000.0))]
    pub max_building_height_m: f64,
    /// Fraction of block area covered by buildings, 0..1.
    #[serde(default = "City::default_built_fraction")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub built_fraction: f64,
}

impl City {
    fn default_block_m() -> f64 {
        120.0
    }
    fn default_street_m() -> f64 {
        25.0
    }
    fn default_median_height_m() -> f64 {
        30.0
    }
    fn default_max_height_m() -> f64 {
        300.0
    }
    fn default_built_fraction() -> f64 {
        0.5
    }
}

impl Default for City {
    fn default() -> Self {
        Self {
            block_size_m: Self::default_block_m(),
            street_width_m: Self::default_street_m(),
            median_building_height_m: Self::default_median_height_m(),
            max_building_height_m: Self::default_max_height_m(),
            built_fraction: Self::default_built_fraction(),
        }
    }
}

/// What the run does when the pilot exits before `duration`: `endRun` (default) or
/// `continue` until `duration`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum PilotExit {
    /// End the run (its exit status is judged by `expectedExit`, the run by the criteria).
    #[default]
    EndRun,
    /// Keep simulating until `duration`.
    Continue,
}

/// How the pilot is expected to end (default `success`), judged with the criteria: a pilot
/// that ends otherwise fails the run (`sadesim run` exits 1; on Kubernetes the run is
/// `Failed`). Only an exit the pilot makes itself is judged: a pilot stopped because the
/// run ended first is not.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum ExpectedExit {
    /// Exit code 0 (default): a pilot that exits with another code or is killed by a
    /// signal before the run ends fails the run. A pilot still running at the end passes.
    #[default]
    Success,
    /// A non-zero exit code or a signal before the run ends (a pilot meant to give up, e.g.
    /// on a refused mission); exit code 0, or still running at the end, fails the run.
    Failure,
    /// Not judged: the pilot may exit in any way, or not at all.
    Any,
}

impl ExpectedExit {
    /// The value as written in the scenario.
    pub fn as_str(self) -> &'static str {
        match self {
            ExpectedExit::Success => "success",
            ExpectedExit::Failure => "failure",
            ExpectedExit::Any => "any",
        }
    }
}

/// An environment variable for the pilot.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct EnvVar {
    /// Variable name; the `SADESIM_` prefix is reserved.
    #[schemars(length(min = 1, max = 253), pattern(r"^[A-Za-z_][A-Za-z0-9_]*$"))]
    pub name: String,
    /// Value.
    #[schemars(length(max = 4096))]
    pub value: String,
}

/// The software pilot under test. Locally `command` is started as a child process (from the
/// scenario file's folder); on Kubernetes `image` runs as a Job with `command`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Pilot {
    /// Container image (Kubernetes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1, max = 512))]
    pub image: Option<String>,
    /// Program and arguments. Required for local runs (`sadesim run` starts it from the
    /// scenario file's folder); on Kubernetes it overrides the image's entrypoint when set,
    /// unless `containerCommand` is given.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 64), inner(length(max = 4096)))]
    pub command: Vec<String>,
    /// Program and arguments in the pilot container on Kubernetes, when they differ from the
    /// local `command` (e.g. `cargo run ...` locally, the built binary in the image); `[]`
    /// runs the image's own entrypoint. Needs `image`. Default: `command`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(max = 64), inner(length(max = 4096)))]
    pub container_command: Option<Vec<String>>,
    /// Extra environment. `SADESIM_FLEET` (the fleet file) is always set.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 128))]
    pub env: Vec<EnvVar>,
    /// What the run does when the pilot exits early. Default `endRun`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub on_exit: Option<PilotExit>,
    /// How the pilot is expected to exit: `success` (default: exit code 0; a non-zero
    /// code or a signal fails the run), `failure` (a non-zero code or a signal) or `any`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expected_exit: Option<ExpectedExit>,
    /// Resources for the pilot container (Kubernetes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resources: Option<PilotResources>,
    /// Longest wall-clock wait, seconds, for the pilot to connect: simulated time holds at
    /// the release (`pilotsReleased`) until the first MAVLink frame from the pilot reaches
    /// any drone it flies, and a pilot silent this long ends the run as failed
    /// (`pilotNotConnected`). Covers a pilot that builds, imports or pulls its image first.
    /// 1..3600, default 300; `sadesim run --pilot-connect-timeout` overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1, max = 3600))]
    pub connect_timeout_s: Option<u32>,
}

impl Pilot {
    /// Default of [`Pilot::connect_timeout_s`], seconds.
    pub const DEFAULT_CONNECT_TIMEOUT_S: u32 = 300;

    /// [`Pilot::connect_timeout_s`] or its default, seconds.
    pub fn connect_timeout_s(&self) -> u32 {
        self.connect_timeout_s.unwrap_or(Self::DEFAULT_CONNECT_TIMEOUT_S)
    }
}

/// CPU and memory for the pilot container.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct PilotResources {
    /// Millicores, 10..64000.
    #[schemars(range(min = 10, max = 64000))]
    pub cpu_millis: u32,
    /// Mebibytes, 16..262144.
    #[schemars(range(min = 16, max = 262_144))]
    pub memory_mib: u32,
}

/// Live 3D view in a browser.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Rendering {
    /// Start the renderer (browser 3D view). Default false.
    #[serde(default)]
    pub enabled: bool,
    /// GPUs (`nvidia.com/gpu`) on Kubernetes for the pod that renders the onboard cameras
    /// (the coordinator), 1..=8; needs cameras in `spec.fleet[].cameras`, since the live
    /// view draws in each browser. Absent: the cameras render on the CPU (Mesa's lavapipe).
    /// Locally the cameras use whatever Vulkan device the machine has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpus: Option<u32>,
}

/// What the recorder writes besides events, trajectory and summary (always written).
///
/// Streams are sampled at sync-window boundaries (every `syncWindowSteps` physics steps,
/// 10 ms by default), so a rate above the window rate records once per window.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Recording {
    /// Write `recording.mcap` (Foxglove schemas). Default true.
    #[serde(default = "default_true")]
    pub mcap: bool,
    /// Write one PX4 ULog per drone under `ulog/`. Default true.
    #[serde(default = "default_true")]
    pub ulog: bool,
    /// MCAP chunk compression. Default `zstd`.
    #[serde(default)]
    pub compression: Compression,
    /// Samples per simulated second of each stream.
    #[serde(default)]
    pub rates: RecordingRates,
}

fn default_true() -> bool {
    true
}

impl Default for Recording {
    fn default() -> Self {
        Self { mcap: true, ulog: true, compression: Compression::default(), rates: RecordingRates::default() }
    }
}

/// MCAP chunk compression.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum Compression {
    #[default]
    Zstd,
    Lz4,
    None,
}

/// Recording rates, Hz of simulated time. GNSS fixes are recorded as the receiver makes
/// them (its own rate); events, zone changes and logs as they happen.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct RecordingRates {
    /// Ground-truth pose, velocity and frame transforms in `recording.mcap`, 0.1..1000.
    /// Default 100. The ULog files log their `*_groundtruth` topics at `estimatorHz`, as
    /// PX4 SITL does.
    #[serde(default = "RecordingRates::default_ground_truth_hz")]
    #[schemars(range(min = 0.1, max = 1000.0))]
    pub ground_truth_hz: f64,
    /// Estimator output (position, velocity, attitude), 0.1..1000. Default 10 (PX4's
    /// default logging profile logs `vehicle_local_position` at 10 Hz).
    #[serde(default = "RecordingRates::default_estimator_hz")]
    #[schemars(range(min = 0.1, max = 1000.0))]
    pub estimator_hz: f64,
    /// Motor commands, 0.1..1000. Default 10 (PX4's default profile logs
    /// `actuator_outputs` at 10 Hz).
    #[serde(default = "RecordingRates::default_actuators_hz")]
    #[schemars(range(min = 0.1, max = 1000.0))]
    pub actuators_hz: f64,
    /// Battery, flight mode and wind at each drone, 0.1..1000. Default 10.
    #[serde(default = "RecordingRates::default_status_hz")]
    #[schemars(range(min = 0.1, max = 1000.0))]
    pub status_hz: f64,
}

impl RecordingRates {
    fn default_ground_truth_hz() -> f64 {
        100.0
    }
    fn default_estimator_hz() -> f64 {
        10.0
    }
    fn default_actuators_hz() -> f64 {
        10.0
    }
    fn default_status_hz() -> f64 {
        10.0
    }
}

impl Default for RecordingRates {
    fn default() -> Self {
        Self {
            ground_truth_hz: Self::default_ground_truth_hz(),
            estimator_hz: Self::default_estimator_hz(),
            actuators_hz: Self::default_actuators_hz(),
            status_hz: Self::default_status_hz(),
        }
    }
}

/// How drones are split into physics shards.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Sharding {
    /// Drones per shard (one pod per shard on Kubernetes), 1..2000. Default 100.
    #[serde(default = "Sharding::default_drones_per_shard")]
    #[schemars(range(min = 1, max = 2000))]
    pub drones_per_shard: u32,
    /// Physics steps between snapshot exchanges with the coordinator, 1..1000. Default 10.
    #[serde(default = "Sharding::default_sync_window_steps")]
    #[schemars(range(min = 1, max = 1000))]
    pub sync_window_steps: u32,
}

impl Sharding {
    fn default_drones_per_shard() -> u32 {
        DEFAULT_DRONES_PER_SHARD
    }
    fn default_sync_window_steps() -> u32 {
        DEFAULT_SYNC_WINDOW_STEPS
    }
}

impl Default for Sharding {
    fn default() -> Self {
        Self { drones_per_shard: DEFAULT_DRONES_PER_SHARD, sync_window_steps: DEFAULT_SYNC_WINDOW_STEPS }
    }
}

/// Where evidence goes: `file:///abs/path` or a relative `file://runs`, `s3://bucket/prefix`,
/// `gs://bucket/prefix`, `az://container/prefix`. Default: `./runs` locally, the operator's
/// configured bucket on Kubernetes.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Archive {
    /// Archive URL: `file://`, `s3://`, `gs://` or `az://`.
    #[schemars(length(min = 1, max = 1024), pattern(r"^(file|s3|gs|az)://"))]
    pub url: String,
}
