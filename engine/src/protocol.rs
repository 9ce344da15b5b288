//! The shard <-> coordinator message set (DESIGN §5): the same types travel over in-process
//! channels and, as binary frames (`sim_worker::transport::wire`), over TCP between
//! `sim-worker shard` and `sim-worker coordinator` processes.

use serde::{Deserialize, Serialize};

use crate::events::{Event, FlightMode};

/// Bumped on any incompatible change; peers refuse other versions. 4: binary frames on
/// TCP instead of JSON lines (a peer of version 3 or older is refused at its first line).
/// 5: `Hold` and `Held`, the hold for the pilot at the release.
pub const PROTOCOL_VERSION: u32 = 5;

/// A drone's state at a window boundary (ground truth), for the merged snapshot, the
/// recorder and everything that couples drones.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct DroneSnapshot {
    /// Global drone index.
    pub index: u32,
    /// ENU position, m.
    pub position_enu_m: [f64; 3],
    /// ENU velocity, m/s.
    pub velocity_enu_mps: [f64; 3],
    /// Body -> ENU quaternion, (w, x, y, z).
    pub attitude_wxyz: [f64; 4],
    /// Height above the ground below, m.
    pub height_agl_m: f64,
    pub mode: FlightMode,
    pub armed: bool,
    pub on_ground: bool,
    pub crashed: bool,
    /// Remaining battery fraction, 0..1.
    pub battery_remaining: f64,
    /// The estimator has a position (GNSS fix received).
    pub position_valid: bool,
    /// What the flight stack saw and did: recorded into MCAP and ULog.
    pub detail: DroneDetail,
}

/// The flight stack's side of a drone at a window boundary, for the recordings. Frames:
/// world ENU (metres from the run origin, z up) and body FLU, like the rest of the snapshot.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct DroneDetail {
    /// Ground-truth body rates, FLU, rad/s.
    pub rate_body_rps: [f64; 3],
    /// The estimator's output, `None` before its first GNSS fix.
    pub estimate: Option<EstimateDetail>,
    /// The latest GNSS receiver output (a new fix when `time_s` changes), `None` before the first.
    pub gnss: Option<GnssDetail>,
    /// Motor commands, normalized 0..1 (rotor speed / max speed), rotor order of the
    /// airframe; only the first `motor_count` entries are meaningful.
    pub motor_commands: [f64; 8],
    pub motor_count: u8,
    /// Battery terminal voltage, V.
    pub battery_voltage_v: f64,
    /// Battery current, A.
    pub battery_current_a: f64,
    /// Charge used since the start, mAh.
    pub battery_consumed_mah: f64,
    /// Wind at the drone (mean + turbulence), ENU, m/s.
    pub wind_enu_mps: [f64; 3],
    /// Where the drone booted (its local NED origin, like PX4's EKF origin), ENU, m.
    pub local_origin_enu_m: [f64; 3],
}

/// The estimator's output (what the controllers fly on).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct EstimateDetail {
    /// ENU, m.
    pub position_enu_m: [f64; 3],
    /// ENU, m/s.
    pub velocity_enu_mps: [f64; 3],
    /// Body (FLU) -> ENU, (w, x, y, z).
    pub attitude_wxyz: [f64; 4],
    /// 1-sigma horizontal / vertical position uncertainty, m.
    pub eph_m: f64,
    pub epv_m: f64,
}

impl DroneSnapshot {
    /// The true position (ENU, m) at the earlier sim time `at_s` of this snapshot taken at
    /// `window_s`, back along its velocity: a GNSS fix is measured at its own epoch, up to a
    /// window before the snapshot.
    pub fn position_back_at(&self, at_s: f64, window_s: f64) -> [f64; 3] {
        let dt = (window_s - at_s).max(0.0);
        let (p, v) = (self.position_enu_m, self.velocity_enu_mps);
        [p[0] - v[0] * dt, p[1] - v[1] * dt, p[2] - v[2] * dt]
    }
}

/// One GNSS receiver output.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct GnssDetail {
    /// Simulated time of the measurement, s.
    pub time_s: f64,
    /// Measured position, ENU, m (meaningless without a 3D fix).
    pub position_enu_m: [f64; 3],
    /// Measured velocity, ENU, m/s.
    pub velocity_enu_mps: [f64; 3],
    /// MAVLink GPS_FIX_TYPE (3 = 3D fix, 1 = no fix).
    pub fix_type: u8,
    pub satellites: u8,
    /// 1-sigma accuracies, m; `None` (JSON null) without a fix.
    pub eph_m: Option<f64>,
    pub epv_m: Option<f64>,
    /// Dilutions of precision; `None` without a fix.
    pub hdop: Option<f64>,
    pub vdop: Option<f64>,
    /// The ranging receiver's sky (`None` for the statistical receiver): satellites above
    /// the mask, received directly, received only by a reflection.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky: Option<SkyDetail>,
}

/// Satellites by signal path at one fix epoch (see `sensors::SkyCounts`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[serde(rename_all = "camelCase")]
pub struct SkyDetail {
    pub above_mask: u8,
    pub line_of_sight: u8,
    pub reflected: u8,
}

#[cfg(any(test, feature = "fixtures"))]
impl DroneSnapshot {
    /// For tests: drone `index` climbing at 1 m/s from the ground at `east_m` east of the
    /// origin, `t` seconds after the start, in a takeoff with a quad's four motors.
    pub fn climbing(index: u32, east_m: f64, t: f64) -> Self {
        DroneSnapshot {
            index,
            position_enu_m: [east_m, 0.0, t],
            velocity_enu_mps: [0.0, 0.0, 1.0],
            attitude_wxyz: [1.0, 0.0, 0.0, 0.0],
            height_agl_m: t,
            mode: crate::events::FlightMode::Takeoff,
            armed: true,
            on_ground: false,
            crashed: false,
            battery_remaining: 1.0,
            position_valid: true,
            detail: DroneDetail { motor_count: 4, ..DroneDetail::default() },
        }
    }
}

pub use sadesim_crds::outcome::summary::FleetCounts;

/// How many of `drones` are in the air, on the ground, crashed.
pub fn fleet_counts(drones: &[DroneSnapshot]) -> FleetCounts {
    FleetCounts::from_flags(drones.iter().map(|d| (d.on_ground, d.crashed)))
}

/// Coordinator -> shard.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum ToShard {
    /// Simulate up to (excluding) physics step `until_step`; `release_pilots` starts the
    /// scripted pilots. (The merged snapshot stays with the coordinator, which runs every
    /// drone-coupling check; a shard-side consumer such as detect-and-avoid would add it
    /// here.)
    ///
    /// `leases`, when present, replaces the set of valid zone leases as `[drone, zone]`
    /// pairs (global drone index, index in `spec.zones`): the built-in geofence lets a
    /// drone into the zones it holds a lease for. Sent only when the set changed.
    Advance {
        until_step: u64,
        release_pilots: bool,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        leases: Option<Vec<[u32; 2]>>,
    },
    /// Simulated time stays where it is (the coordinator holds the run at the release until
    /// the pilot connects): read what the drones' MAVLink peers sent, keeping the frames for
    /// the sessions at the next exchange, and with `heartbeat` send every drone's HEARTBEAT
    /// at the held time, so that a pilot waiting for one finds its drones. Answered with
    /// `Held`. Nothing is simulated: the run is the same whatever the wall time held.
    Hold { heartbeat: bool },
    /// End of run: flush and exit.
    Stop,
}

/// Shard -> coordinator.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum FromShard {
    /// Sent once after the shard built its world and drones.
    Hello { version: u32, shard: u32, drones: u32 },
    /// A window is done: state at `step` (the next step to simulate) and what happened.
    Advanced {
        shard: u32,
        step: u64,
        /// Every drone of the shard has a position estimate (pilots may be released).
        ready: bool,
        drones: Vec<DroneSnapshot>,
        events: Vec<Event>,
    },
    /// The answer to `Hold`: the drones (global indices, ascending) that have MAVLink frames
    /// from a peer waiting for their sessions.
    Held { shard: u32, heard: Vec<u32> },
    /// The shard stopped cleanly.
    Stopped { shard: u32 },
    /// The shard cannot go on.
    Failed { shard: u32, reason: String },
}
