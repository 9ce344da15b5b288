//! PX4's custom flight modes on MAVLink.
//!
//! PX4 reports its mode in HEARTBEAT.custom_mode as a `px4_custom_mode` union (PX4
//! `src/modules/commander/px4_custom_mode.h`): bytes `[reserved u16][main_mode u8][sub_mode
//! u8]`, little-endian, so `custom_mode = main << 16 | sub << 24`. QGroundControl, MAVSDK and
//! pymavlink decode it that way, and accept DO_SET_MODE with `param2 = main`, `param3 = sub`.

use crate::events::FlightMode;

/// PX4 main modes (`PX4_CUSTOM_MAIN_MODE`).
pub mod main_mode {
    pub const MANUAL: u8 = 1;
    pub const ALTCTL: u8 = 2;
    pub const POSCTL: u8 = 3;
    pub const AUTO: u8 = 4;
    pub const OFFBOARD: u8 = 6;
}

/// PX4 sub modes of AUTO (`PX4_CUSTOM_SUB_MODE_AUTO`).
pub mod auto_sub_mode {
    pub const READY: u8 = 1;
    pub const TAKEOFF: u8 = 2;
    pub const LOITER: u8 = 3;
    pub const MISSION: u8 = 4;
    pub const RTL: u8 = 5;
    pub const LAND: u8 = 6;
}

/// HEARTBEAT.base_mode flags (`MAV_MODE_FLAG`).
pub mod base_mode_flag {
    pub const CUSTOM_MODE_ENABLED: u8 = 1;
    pub const AUTO_ENABLED: u8 = 4;
    pub const GUIDED_ENABLED: u8 = 8;
    pub const STABILIZE_ENABLED: u8 = 16;
    pub const SAFETY_ARMED: u8 = 128;
}

/// (main, sub) of a flight mode. A drone idle on the ground reports AUTO.LOITER, as PX4
/// does after boot with a position fix.
pub fn to_px4(mode: FlightMode) -> (u8, u8) {
    use auto_sub_mode::*;
    match mode {
        FlightMode::Idle | FlightMode::Hold => (main_mode::AUTO, LOITER),
        FlightMode::Takeoff => (main_mode::AUTO, TAKEOFF),
        FlightMode::Mission => (main_mode::AUTO, MISSION),
        FlightMode::ReturnToLaunch => (main_mode::AUTO, RTL),
        FlightMode::Land => (main_mode::AUTO, LAND),
        FlightMode::Offboard => (main_mode::OFFBOARD, 0),
    }
}

/// HEARTBEAT.custom_mode for a flight mode.
pub fn custom_mode(mode: FlightMode) -> u32 {
    let (main, sub) = to_px4(mode);
    (u32::from(main) << 16) | (u32::from(sub) << 24)
}

/// HEARTBEAT.base_mode: custom mode enabled, the autonomy flags PX4 sets for AUTO and
/// OFFBOARD, and the armed flag.
pub fn base_mode(mode: FlightMode, armed: bool) -> u8 {
    use base_mode_flag::*;
    let autonomy = match mode {
        FlightMode::Offboard => GUIDED_ENABLED | STABILIZE_ENABLED,
        _ => AUTO_ENABLED | GUIDED_ENABLED | STABILIZE_ENABLED,
    };
    CUSTOM_MODE_ENABLED | autonomy | if armed { SAFETY_ARMED } else { 0 }
}

/// PX4's `vehicle_status.nav_state` (what its ULogs record) of a flight mode: the navigation
/// state PX4's commander enters for the mode's (main, sub) pair of [`to_px4`].
pub fn nav_state(mode: FlightMode) -> u8 {
    use auto_sub_mode::*;
    match to_px4(mode) {
        (main_mode::AUTO, TAKEOFF) => nav_state::AUTO_TAKEOFF,
        (main_mode::AUTO, MISSION) => nav_state::AUTO_MISSION,
        (main_mode::AUTO, RTL) => nav_state::AUTO_RTL,
        (main_mode::AUTO, LAND) => nav_state::AUTO_LAND,
        (main_mode::OFFBOARD, _) => nav_state::OFFBOARD,
        _ => nav_state::AUTO_LOITER,
    }
}

/// PX4's navigation states (`vehicle_status_s::NAVIGATION_STATE_*`) the built-in autopilot's
/// modes map to.
pub mod nav_state {
    pub const AUTO_MISSION: u8 = 3;
    pub const AUTO_LOITER: u8 = 4;
    pub const AUTO_RTL: u8 = 5;
    pub const OFFBOARD: u8 = 14;
    pub const AUTO_TAKEOFF: u8 = 17;
    pub const AUTO_LAND: u8 = 18;
}

/// The flight mode a DO_SET_MODE (`param2` main, `param3` sub) asks for; `None` for PX4
/// modes the built-in autopilot does not fly (manual, altitude, position control, ...),
/// which the endpoint refuses with MAV_RESULT_UNSUPPORTED.
pub fn from_px4(main: u8, sub: u8) -> Option<FlightMode> {
    use auto_sub_mode::*;
    match (main, sub) {
        (main_mode::AUTO, LOITER) => Some(FlightMode::Hold),
        (main_mode::AUTO, TAKEOFF) => Some(FlightMode::Takeoff),
        (main_mode::AUTO, MISSION) => Some(FlightMode::Mission),
        (main_mode::AUTO, RTL) => Some(FlightMode::ReturnToLaunch),
        (main_mode::AUTO, LAND) => Some(FlightMode::Land),
        (main_mode::OFFBOARD, _) => Some(FlightMode::Offboard),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn custom_modes_match_px4s_published_values() {
        // Values as QGroundControl's PX4FirmwarePlugin and pymavlink's
        // mode_mapping_px4 decode them.
        assert_eq!(custom_mode(FlightMode::Mission), 0x0404_0000);
        assert_eq!(custom_mode(FlightMode::Hold), 0x0304_0000);
        assert_eq!(custom_mode(FlightMode::ReturnToLaunch), 0x0504_0000);
        assert_eq!(custom_mode(FlightMode::Land), 0x0604_0000);
        assert_eq!(custom_mode(FlightMode::Takeoff), 0x0204_0000);
        assert_eq!(custom_mode(FlightMode::Offboard), 0x0006_0000);
    }

    #[test]
    fn every_mode_round_trips_through_do_set_mode() {
        for mode in [
            FlightMode::Hold,
            FlightMode::Takeoff,
            FlightMode::Mission,
            FlightMode::ReturnToLaunch,
            FlightMode::Land,
            FlightMode::Offboard,
        ] {
            let (main, sub) = to_px4(mode);
            assert_eq!(from_px4(main, sub), Some(mode));
        }
        assert_eq!(from_px4(main_mode::POSCTL, 0), None, "position control needs a stick: not flown");
        assert_eq!(from_px4(main_mode::MANUAL, 0), None);
    }

    #[test]
    fn base_mode_flags_follow_arming_and_mode() {
        assert_eq!(base_mode(FlightMode::Mission, true), 1 | 4 | 8 | 16 | 128);
        assert_eq!(base_mode(FlightMode::Idle, false), 1 | 4 | 8 | 16);
        assert_eq!(base_mode(FlightMode::Offboard, true) & base_mode_flag::AUTO_ENABLED, 0);
    }
}
