//! Missions as the autopilot executes them: items in the local ENU frame, altitudes
//! relative to the home position's ground (PX4's MAV_FRAME_GLOBAL_RELATIVE_ALT). Scripted
//! pilots and (later) the MAVLink mission protocol both produce this.

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

/// One mission step.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum MissionItem {
    /// Climb vertically to `alt_rel_home_m`.
    Takeoff { alt_rel_home_m: f64 },
    /// Fly to a horizontal position (ENU east/north, m) at an altitude above home, then hold.
    Waypoint { target_en_m: Vector2<f64>, alt_rel_home_m: f64, hold_s: f64 },
    /// Hold the current position for `hold_s`.
    Loiter { hold_s: f64 },
    /// Return home and land.
    ReturnToLaunch,
    /// Land at the current position.
    Land,
    /// From here on fly at `speed_mps` horizontally (MAV_CMD_DO_CHANGE_SPEED); done at once.
    ChangeSpeed { speed_mps: f64 },
}

/// A mission with its cruise speed.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct MissionPlan {
    pub items: Vec<MissionItem>,
    /// Horizontal cruise speed, m/s.
    pub speed_mps: f64,
}

/// PX4's default cruise speed for missions (MPC_XY_CRUISE), m/s.
pub const DEFAULT_CRUISE_MPS: f64 = 5.0;
