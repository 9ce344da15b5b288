//! Messages a ground station or a pilot sends, for this crate's tests and fuzz seeds: one
//! builder each, so the tests of the frame parser, the signing and the session, and the
//! seeds of the fuzz targets, send the same bytes a ground station would.
#![allow(deprecated)]

use ::mavlink::dialects::common::*;

/// A ground station's HEARTBEAT (QGroundControl's: a GCS, no autopilot).
pub(crate) fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// COMMAND_LONG `command` with `params` (param1 to param7) to the autopilot (component 1)
/// of `target_system`.
pub(crate) fn command_long(target_system: u8, command: MavCmd, params: [f32; 7]) -> MavMessage {
    let [param1, param2, param3, param4, param5, param6, param7] = params;
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1,
        param2,
        param3,
        param4,
        param5,
        param6,
        param7,
        command,
        target_system,
        target_component: 1,
        confirmation: 0,
    })
}
