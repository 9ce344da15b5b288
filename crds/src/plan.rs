//! `RunPlan`: the fully resolved run (DESIGN §4). The planner computes it once from a
//! validated `SimulationRun`; every role reads it and none recomputes it.

use serde::{Deserialize, Serialize};

use crate::fleet::Role;
use crate::geo::{Enu, GeoPoint};
use crate::run::SimulationRunSpec;

/// Bumped when the plan's meaning changes incompatibly; roles refuse other versions.
pub const PLAN_FORMAT_VERSION: u32 = 1;

/// Which run a plan belongs to.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RunRef {
    pub name: String,
    pub namespace: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uid: Option<String>,
}

/// The resolved run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RunPlan {
    pub format_version: u32,
    pub run: RunRef,
    /// The validated specification the plan was made from.
    pub spec: SimulationRunSpec,
    /// Simulated seconds the run lasts.
    pub duration_s: f64,
    /// Physics steps per simulated second.
    pub physics_rate_hz: u32,
    /// Physics steps per shard <-> coordinator exchange.
    pub sync_window_steps: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Every drone, by global index (`drones[i].index == i`).
    pub drones: Vec<PlannedDrone>,
    /// Physics shards, each owning a contiguous range of drone indices.
    pub shards: Vec<PlannedShard>,
    /// MAVLink router segments (at most 250 system ids each).
    pub segments: Vec<RouterSegment>,
    /// Content hash of everything that shapes the world assets (hex sha256).
    pub asset_cache_key: String,
    /// Ports of the run-wide services.
    pub services: ServicePorts,
    /// Resource estimate per role, for Kubernetes requests and for the user.
    pub resources: ResourcePlan,
}

impl RunPlan {
    /// The drones of one shard.
    pub fn shard_drones(&self, shard: &PlannedShard) -> &[PlannedDrone] {
        &self.drones[shard.first_drone as usize..(shard.first_drone + shard.drone_count) as usize]
    }
}

/// One drone.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct PlannedDrone {
    /// Global index, 0-based, in fleet group order.
    pub index: u32,
    /// `<group>-<k>`, k 0-based within the group.
    pub name: String,
    pub group: String,
    /// Index of the group in `spec.fleet`.
    pub group_index: u32,
    /// Position within the group, 0-based (the `k` of the name).
    pub member: u32,
    pub operator: String,
    pub role: Role,
    pub airframe: String,
    /// MAVLink system id within the drone's segment, 1..=250.
    pub system_id: u8,
    /// MAVLink component id of the autopilot (MAV_COMP_ID_AUTOPILOT1).
    pub component_id: u8,
    /// Router segment index.
    pub segment: u32,
    /// Physics shard index.
    pub shard: u32,
    pub ports: DronePorts,
    pub home: Home,
    /// Flown by the built-in scripted pilot (true) or over MAVLink by `spec.pilot` (false).
    pub scripted: bool,
}

/// A drone's MAVLink ports (UDP unless named TCP).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct DronePorts {
    /// The drone *sends* its API/offboard link to this port on the pilot's host, like PX4
    /// SITL instance i (MAVSDK `udpin://0.0.0.0:14540` sees drone 0).
    pub api_udp: u16,
    /// The drone *listens* here for clients that connect to it (`udpout://host:port`), and
    /// on the same number over TCP.
    pub endpoint: u16,
}

/// A drone's start position, on the ground.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Home {
    /// Local ENU, metres from the origin (`up` 0 = origin ground level).
    pub local: Enu,
    pub global: GeoPoint,
}

/// A physics shard: drones `[firstDrone, firstDrone + droneCount)`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct PlannedShard {
    pub index: u32,
    pub first_drone: u32,
    pub drone_count: u32,
}

/// A MAVLink router segment: drones `[firstDrone, firstDrone + droneCount)`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct RouterSegment {
    pub index: u32,
    pub first_drone: u32,
    pub drone_count: u32,
    /// GCS UDP port (QGroundControl's default 14550 for segment 0).
    pub gcs_udp: u16,
    /// GCS TCP port (5760 for segment 0).
    pub gcs_tcp: u16,
}

/// Ports of the run-wide services.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct ServicePorts {
    /// Coordinator <-> shard protocol (TCP).
    pub coordinator: u16,
    /// Airspace authority HTTP API.
    pub airspace_http: u16,
    /// Renderer HTTP.
    pub renderer_http: u16,
    /// Prometheus metrics of the roles.
    pub metrics: u16,
}

/// CPU (millicores) and memory (MiB) for one instance of a role.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct RoleResources {
    pub cpu_millis: u32,
    pub memory_mib: u32,
}

/// Resource estimate per role instance.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct ResourcePlan {
    pub assets: RoleResources,
    /// One entry per shard, in shard order.
    pub shards: Vec<RoleResources>,
    pub coordinator: RoleResources,
    /// Per router segment.
    pub router: RoleResources,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub renderer: Option<RoleResources>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pilot: Option<RoleResources>,
}

impl ResourcePlan {
    /// The whole gang's requests: what must fit before the run can start.
    pub fn total(&self, segments: usize) -> RoleResources {
        let mut all: Vec<RoleResources> = self.shards.clone();
        all.push(self.coordinator);
        all.extend(std::iter::repeat_n(self.router, segments));
        all.extend(self.renderer);
        all.extend(self.pilot);
        RoleResources {
            cpu_millis: all.iter().map(|r| r.cpu_millis).sum(),
            memory_mib: all.iter().map(|r| r.memory_mib).sum(),
        }
    }
}
