//! Airspace zones (SADE Zones): a polygon with a floor and a ceiling, and the policy the
//! airspace authority applies to entry requests.

use kube::{KubeSchema, core::Duration};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::fleet::LatLon;

/// Most vertices in one zone polygon.
pub const MAX_POLYGON_VERTICES: usize = 256;

/// What an altitude is measured from.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum AltitudeReference {
    /// Above ground level directly below the drone.
    Agl,
    /// Above mean sea level.
    Msl,
}

/// A height with its reference.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct ZoneAltitude {
    /// Metres above the reference (-500..20000).
    #[schemars(range(min = -500.0, max = 20000.0))]
    pub height_m: f64,
    pub reference: AltitudeReference,
}

/// A restricted volume of airspace.
#[derive(KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("!has(self.floor) || self.floor.reference != self.ceiling.reference || self.floor.heightM < self.ceiling.heightM").message("zone floor must be below its ceiling").field_path(".ceiling"))]
pub struct Zone {
    /// Unique zone name (DNS label); the API and events refer to it.
    #[schemars(length(min = 1, max = 63), pattern(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$"))]
    pub name: String,
    /// Outline, at least 3 vertices, not self-intersecting; implicitly closed.
    #[schemars(length(min = 3, max = 256))]
    pub polygon: Vec<LatLon>,
    /// Bottom of the volume. Default: the ground (0 m AGL).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor: Option<ZoneAltitude>,
    /// Top of the volume.
    pub ceiling: ZoneAltitude,
    /// Sim time the zone becomes active. Default: from the start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub active_from: Option<Duration>,
    /// Sim time the zone stops being active. Default: until the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub active_until: Option<Duration>,
    /// Who may enter, how many at once, for how long, under which constraints.
    pub policy: ZonePolicy,
}

impl Zone {
    pub fn floor(&self) -> ZoneAltitude {
        self.floor.unwrap_or(ZoneAltitude { height_m: 0.0, reference: AltitudeReference::Agl })
    }
}

/// The authority's rules for one zone. Requests from other operators are denied with
/// `insufficient_credentials`.
#[derive(KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("!has(self.minAltitudeAglM) || !has(self.maxAltitudeAglM) || self.minAltitudeAglM < self.maxAltitudeAglM").message("policy.minAltitudeAglM must be below policy.maxAltitudeAglM").field_path(".minAltitudeAglM"))]
pub struct ZonePolicy {
    /// Operators that may be granted entry.
    #[serde(default)]
    #[schemars(length(max = 64), inner(length(max = 63)))]
    pub authorized_operators: Vec<String>,
    /// Most drones holding a lease at once. Default unlimited.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1, max = 10000))]
    pub capacity: Option<u32>,
    /// Lease length before it must be renewed. Default 10m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lease_duration: Option<Duration>,
    /// Lowest altitude above ground allowed inside the zone, metres (the paper: 350 ft).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 20000.0))]
    pub min_altitude_agl_m: Option<f64>,
    /// Highest altitude above ground allowed inside the zone, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 20000.0))]
    pub max_altitude_agl_m: Option<f64>,
}
