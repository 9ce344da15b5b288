//! Fleet groups: how many drones of which airframe, who operates them, where they start,
//! how high they may fly, and who flies them (a scripted mission or the external pilot).

use kube::KubeSchema;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Most drones in one group and in one run.
pub const MAX_DRONES: u32 = 10_000;

/// The operator's kind of flying: `publicSafety`, `journalist`, `recreational`,
/// `commercial`, `delivery` or `other` (default). Shapes reports (colours, legends), not
/// physics.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum Role {
    PublicSafety,
    Journalist,
    Recreational,
    Commercial,
    Delivery,
    #[default]
    Other,
}

/// A group of identical drones.
#[derive(KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("!has(self.homes.explicit) || size(self.homes.explicit) == self.count").message("homes.explicit must list exactly `count` positions").field_path(".homes.explicit"))]
pub struct FleetGroup {
    /// Unique group name (DNS label): drones are named `<group>-<k>`.
    #[schemars(length(min = 1, max = 40), pattern(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$"))]
    pub name: String,
    /// Number of drones, 1..10000.
    #[schemars(range(min = 1, max = 10000))]
    pub count: u32,
    /// Airframe preset (see the scenario reference), e.g. `x500`, `mini250`.
    #[schemars(length(min = 1, max = 63))]
    pub airframe: String,
    /// Operator (organisation) id the airspace authority knows the drones by.
    #[schemars(length(min = 1, max = 63), pattern(r"^[A-Za-z0-9]([-_.A-Za-z0-9]*[A-Za-z0-9])?$"))]
    pub operator: String,
    /// Kind of operation. Default `other`.
    #[serde(default)]
    pub role: Role,
    /// Bearer credential presented to the airspace authority.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub credential: Option<Credential>,
    /// Where the drones start (on the ground).
    pub homes: HomePlacement,
    /// Altitude limits the group must respect everywhere (checked by the compliance monitor).
    pub altitude: AltitudeLimits,
    /// Scripted mission flown by the built-in pilot. Without it the group is flown over
    /// MAVLink by `spec.pilot`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mission: Option<Mission>,
    /// Built-in geofence: what the autopilot does on reaching a zone the drone holds no
    /// lease for. Default: no geofence (the pilot alone is responsible).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geofence: Option<GeofenceAction>,
    /// Onboard cameras of every drone of the group (needs `spec.rendering.enabled`); their
    /// frames are served to pilots over HTTP.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 4))]
    pub cameras: Vec<crate::camera::Camera>,
}

/// Where a bearer credential comes from.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub enum Credential {
    /// Inline value (local runs and tests only: visible to anyone who reads the run).
    Value(#[schemars(length(min = 1, max = 4096))] String),
    /// A key of a Secret in the run's namespace (Kubernetes).
    SecretKeyRef(SecretKeyRef),
}

/// Reference to one key of a Secret.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct SecretKeyRef {
    /// Secret name, in the run's namespace.
    #[schemars(length(min = 1, max = 253))]
    pub name: String,
    /// Key within the Secret's data.
    #[schemars(length(min = 1, max = 253))]
    pub key: String,
}

/// A horizontal position, degrees WGS84.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct LatLon {
    /// Latitude, degrees north (WGS84).
    #[schemars(range(min = -90.0, max = 90.0))]
    pub latitude_deg: f64,
    /// Longitude, degrees east (WGS84).
    #[schemars(range(min = -180.0, max = 180.0))]
    pub longitude_deg: f64,
}

/// A disc on the ground: centre and radius in metres.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Area {
    /// Optional label (a park's name, for reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(max = 128))]
    pub name: Option<String>,
    pub center: LatLon,
    /// Radius, metres (1..20000).
    #[schemars(range(min = 1.0, max = 20000.0))]
    pub radius_m: f64,
}

/// Home placement. Exactly one of `explicit`, `randomInArea`, `areas`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub enum HomePlacement {
    /// One position per drone, in order.
    Explicit(#[schemars(length(min = 1, max = 10000))] Vec<LatLon>),
    /// Uniformly random inside one disc (seeded).
    RandomInArea(Area),
    /// Drones are spread round-robin over a list of discs (e.g. parks), each uniformly at
    /// random inside its disc (seeded).
    Areas(#[schemars(length(min = 1, max = 256))] Vec<Area>),
}

/// Altitude limits above ground level, metres. The paper's 400 ft = 121.92 m.
#[derive(KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("!has(self.minAglM) || self.minAglM < self.maxAglM").message("altitude.minAglM must be below altitude.maxAglM").field_path(".minAglM"))]
pub struct AltitudeLimits {
    /// Highest allowed altitude above ground, metres (1..1000).
    #[schemars(range(min = 1.0, max = 1000.0))]
    pub max_agl_m: f64,
    /// Lowest allowed altitude above ground while cruising, metres (0..1000): judged from
    /// the drone's first climb to it after takeoff until it lands or switches to `land` or
    /// `returnToLaunch`, so takeoff and landing are excepted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 1000.0))]
    pub min_agl_m: Option<f64>,
}

/// Built-in geofence breach action (PX4-like): `hold` (stop outside the zone) or
/// `returnToLaunch`. Without it the pilot alone is responsible for staying out.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum GeofenceAction {
    /// Stop and hold position outside the zone.
    Hold,
    /// Return to launch.
    ReturnToLaunch,
}

/// A scripted mission flown by the built-in pilot.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Mission {
    /// Items in order, like a MAVLink mission.
    #[schemars(length(min = 1, max = 1000))]
    pub items: Vec<MissionItem>,
    /// Cruise ground speed, m/s (0.5..30). Default 5 (PX4's MPC_XY_CRUISE).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.5, max = 30.0))]
    pub speed_mps: Option<f64>,
}

/// One mission step.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", rename_all_fields = "camelCase", deny_unknown_fields)]
pub enum MissionItem {
    /// Arm and climb vertically to `altitudeAglM`.
    Takeoff {
        /// Altitude above the home's ground, metres (1..1000).
        #[schemars(range(min = 1.0, max = 1000.0))]
        altitude_agl_m: f64,
    },
    /// Fly to a position and altitude, then hold `holdS` seconds.
    Waypoint {
        /// Latitude, degrees north (WGS84).
        #[schemars(range(min = -90.0, max = 90.0))]
        latitude_deg: f64,
        /// Longitude, degrees east (WGS84).
        #[schemars(range(min = -180.0, max = 180.0))]
        longitude_deg: f64,
        /// Altitude above the ground under the waypoint, metres (1..1000).
        #[schemars(range(min = 1.0, max = 1000.0))]
        altitude_agl_m: f64,
        /// Seconds to hold at the waypoint before the next item. Default 0.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        #[schemars(range(min = 0.0, max = 86400.0))]
        hold_s: Option<f64>,
    },
    /// Hold position for `holdS` seconds.
    Loiter {
        /// Seconds to hold (0..86400).
        #[schemars(range(min = 0.0, max = 86400.0))]
        hold_s: f64,
    },
    /// Recreational flying: `count` waypoints drawn (seeded, per drone) inside `area` at
    /// altitudes in `[minAltitudeAglM, maxAltitudeAglM]`.
    RandomWaypoints {
        /// Disc the waypoints are drawn in. Omitted: the drone's own home area (its park for
        /// `areas`, which the world keeps free of buildings; the disc for `randomInArea`,
        /// which it does not).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        area: Option<Area>,
        /// Number of waypoints (1..10000).
        #[schemars(range(min = 1, max = 10000))]
        count: u32,
        /// Lowest waypoint altitude above ground, metres.
        #[schemars(range(min = 1.0, max = 1000.0))]
        min_altitude_agl_m: f64,
        /// Highest waypoint altitude above ground, metres.
        #[schemars(range(min = 1.0, max = 1000.0))]
        max_altitude_agl_m: f64,
        /// Seconds to hold at each waypoint. Default 0.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        #[schemars(range(min = 0.0, max = 86400.0))]
        hold_s: Option<f64>,
    },
    /// Fly home and land.
    ReturnToLaunch {},
    /// Land where the drone is.
    Land {},
}
