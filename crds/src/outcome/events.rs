//! Run events: what happened to whom and when (sim time). Shards emit drone events, the
//! coordinator adds lifecycle events; the recorder writes them as JSON lines.

use serde::{Deserialize, Serialize};

use super::ending::{CrashCause, EndReason};

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

impl FlightMode {
    /// The mode's name in events.jsonl, trajectory.csv and the recordings (serde's name,
    /// without serializing).
    pub fn as_str(self) -> &'static str {
        match self {
            FlightMode::Idle => "idle",
            FlightMode::Takeoff => "takeoff",
            FlightMode::Hold => "hold",
            FlightMode::Mission => "mission",
            FlightMode::Offboard => "offboard",
            FlightMode::ReturnToLaunch => "returnToLaunch",
            FlightMode::Land => "land",
        }
    }
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
    /// The run ended, for `reason`.
    RunEnded {
        reason: EndReason,
    },
    Armed,
    Disarmed,
    /// Left the ground.
    Takeoff,
    /// Touched down gently.
    Landed,
    /// Hit a building or the ground too hard; the drone stops.
    Crashed {
        with: CrashCause,
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
    /// The airspace authority received entry request `request` for `zone`.
    ZoneRequested {
        zone: String,
        request: u64,
        operator: String,
        /// Requested altitude band inside the zone, metres AGL.
        min_agl_m: f64,
        max_agl_m: f64,
    },
    /// Request `request` was granted: `lease` is valid until `expires_at_s`.
    ZoneGranted {
        zone: String,
        request: u64,
        lease: String,
        expires_at_s: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        min_altitude_agl_m: Option<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max_altitude_agl_m: Option<f64>,
    },
    /// Request `request` was denied (`insufficient_credentials`, `capacity_exhausted`,
    /// `unsafe_altitude`, `zone_inactive`).
    ZoneDenied {
        zone: String,
        request: u64,
        reason: String,
        message: String,
    },
    LeaseRenewed {
        zone: String,
        lease: String,
        expires_at_s: f64,
    },
    LeaseReleased {
        zone: String,
        lease: String,
    },
    LeaseExpired {
        zone: String,
        lease: String,
    },
    /// The drone entered an active zone's volume; `authorized`: it held a valid lease.
    ZoneEntered {
        zone: String,
        authorized: bool,
        at: Place,
    },
    /// The drone left the zone (or the zone ended) after `duration_s` inside.
    ZoneExited {
        zone: String,
        duration_s: f64,
        at: Place,
    },
    /// A compliance rule started being broken (see `airspace::monitor::ViolationKind`).
    ViolationStarted {
        rule: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        zone: Option<String>,
        /// The other drone, for separation losses.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        other: Option<u32>,
        /// The limit broken (metres: AGL altitude, or distance for separation).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        limit_m: Option<f64>,
        at: Place,
        detail: String,
    },
    /// The rule is respected again after `duration_s`; `worst_m`: the furthest value
    /// reached (lowest or highest AGL altitude, closest distance).
    ViolationEnded {
        rule: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        zone: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        other: Option<u32>,
        duration_s: f64,
        worst_m: f64,
    },
}

/// Where something happened: world ENU and geodetic, with the height above the ground.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct Place {
    pub east_m: f64,
    pub north_m: f64,
    pub up_m: f64,
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_msl_m: f64,
    pub height_agl_m: f64,
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

#[cfg(test)]
mod flight_mode_tests {
    use super::FlightMode;

    #[test]
    fn mode_names_are_serde_s_names() {
        use FlightMode::*;
        for mode in [Idle, Takeoff, Hold, Mission, Offboard, ReturnToLaunch, Land] {
            assert_eq!(serde_json::to_value(mode).unwrap(), mode.as_str(), "{mode:?}");
        }
    }
}
