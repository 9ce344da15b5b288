//! Run events: what happened to whom and when (sim time). Shards emit drone events, the
//! coordinator adds lifecycle events; the recorder writes them as JSON lines.

use serde::{Deserialize, Serialize};

/// Flight mode of the built-in autopilot, named as PX4 users know them.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[serde(rename_all = "camelCase")]
pub enum FlightMode {
    /// On the ground, waiting (PX4: disarmed, any mode).
    #[default]
    Idle,
    /// Vertical climb to the takeoff altitude (PX4 AUTO.TAKEOFF).
    Takeoff,
    /// Hold position (PX4 AUTO.LOITER).
    Hold,
    /// Fly the mission items (PX4 AUTO.MISSION).
    Mission,
    /// Follow external position/velocity setpoints (PX4 OFFBOARD).
    Offboard,
    /// Return to launch: climb, fly home, land (PX4 AUTO.RTL).
    ReturnToLaunch,
    /// Descend and disarm on touchdown (PX4 AUTO.LAND).
    Land,
}

/// What happened.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "event", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum EventKind {
    /// Every shard is ready; simulated time starts.
    RunStarted {
        drones: u32,
        shards: u32,
    },
    /// Pilots released (all drones ready, as in the paper).
    PilotsReleased,
    /// The run ended at `reason` (duration, pilotExited, aborted, failed).
    RunEnded {
        reason: String,
    },
    Armed,
    Disarmed,
    /// Left the ground.
    Takeoff,
    /// Touched down gently.
    Landed,
    /// Hit a building or the ground too hard; the drone stops.
    Crashed {
        with: String,
        speed_mps: f64,
    },
    ModeChanged {
        from: FlightMode,
        to: FlightMode,
    },
    /// Reached mission item `seq` (0-based).
    WaypointReached {
        seq: u32,
    },
    MissionCompleted,
    /// A failsafe fired (gnssLost, lowBattery, ...) and took `action`.
    Failsafe {
        reason: String,
        action: FlightMode,
    },
    /// A command was refused (arming checks, invalid mode).
    CommandRejected {
        command: String,
        reason: String,
    },
}

/// One event with its time and drone.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Event {
    /// Simulated seconds since the start.
    pub time_s: f64,
    /// Global drone index, when the event is about a drone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drone: Option<u32>,
    #[serde(flatten)]
    pub kind: EventKind,
}
