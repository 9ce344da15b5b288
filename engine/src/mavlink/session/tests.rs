use ::mavlink::MavHeader;
use ::mavlink::dialects::common::*;
use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};

use super::*;
use crate::mavlink::frame::{FrameParser, encode, encode_command_ack};
use crate::mavlink::telemetry::{BatteryView, MissionProgress, PositionEstimate};

/// Records what the session asked of the autopilot; refuses what `refuse` says.
#[derive(Default)]
struct FakeVehicle {
    commands: Vec<Command>,
    config: NavigatorConfig,
    refuse: Option<Rejection>,
}

impl Vehicle for FakeVehicle {
    fn command(&mut self, cmd: Command) -> Result<(), Rejection> {
        self.commands.push(cmd);
        self.refuse.clone().map_or(Ok(()), Err)
    }
    fn navigator_config(&self) -> NavigatorConfig {
        self.config
    }
    fn set_navigator_config(&mut self, config: NavigatorConfig) {
        self.config = config;
    }
}

fn frame_origin() -> LocalFrame {
    LocalFrame::new(GeoPoint { latitude_deg: 41.88, longitude_deg: -87.62, altitude_msl_m: 180.0 })
}

fn session() -> Session {
    let id = VehicleIdentity { system_id: 7, frame: frame_origin(), unix_epoch_at_start_us: 0, uid: 7 };
    let preset = crate::preset::Preset::named("x500").expect("x500 preset");
    Session::new(id, ParamTable::px4(7, &preset, &NavigatorConfig::default()))
}

fn view(t: f64) -> VehicleView {
    VehicleView {
        time_s: t,
        armed: true,
        mode: FlightMode::Hold,
        on_ground: false,
        crashed: false,
        armable: false,
        estimate: Some(PositionEstimate {
            position_enu_m: Vector3::new(10.0, 20.0, 32.0),
            velocity_enu_mps: Vector3::zeros(),
            eph_m: 0.5,
            epv_m: 0.8,
        }),
        attitude: UnitQuaternion::identity(),
        attitude_ned: crate::mavlink::telemetry::attitude_ned_frd(&UnitQuaternion::identity()),
        rate_body_rps: Vector3::zeros(),
        gnss: None,
        battery: BatteryView { voltage_v: 16.0, current_a: 10.0, remaining: 0.9, consumed_mah: 100.0 },
        home_enu_m: Vector3::new(0.0, 0.0, 2.0),
        local_origin_enu_m: Vector3::new(0.0, 0.0, 2.0),
        mission: MissionProgress::default(),
        throttle: 0.5,
        airspeed_mps: 0.0,
        ground_up_m: 1.9,
    }
}

/// A frame from a ground station (255/190) as the parser would deliver it.
fn from_gcs(msg: MavMessage) -> Frame {
    let bytes = encode(MavHeader { system_id: 255, component_id: 190, sequence: 0 }, &msg);
    FrameParser::new().push(&bytes).remove(0)
}

fn command_long(command: MavCmd, params: [f32; 7]) -> MavMessage {
    crate::mavlink::gcs_messages::command_long(7, command, params)
}

fn replies(s: &mut Session, t: f64) -> Vec<MavMessage> {
    s.poll(&view(t)).into_iter().flat_map(Outgoing::into_messages).collect()
}

fn acks(s: &mut Session) -> Vec<COMMAND_ACK_DATA> {
    replies(s, 0.0)
        .into_iter()
        .filter_map(|m| if let MavMessage::COMMAND_ACK(a) = m { Some(a) } else { None })
        .collect()
}

#[test]
fn arm_is_forwarded_and_acked_to_the_sender() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    s.handle(
        &from_gcs(command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        &view(0.0),
        &mut v,
    );
    assert_eq!(v.commands, vec![Command::Arm]);
    let a = acks(&mut s);
    assert_eq!(a.len(), 1);
    assert_eq!(a[0].result, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!((a[0].target_system, a[0].target_component), (255, 190));
}

#[test]
fn refusals_map_to_px4_results() {
    let mut s = session();
    let mut v = FakeVehicle { refuse: Some(Rejection::ArmingCheck("no fix".into())), ..Default::default() };
    s.handle(&from_gcs(command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0; 7])), &view(0.0), &mut v);
    assert_eq!(acks(&mut s)[0].result, MavResult::MAV_RESULT_TEMPORARILY_REJECTED);
    let mut v = FakeVehicle { refuse: Some(Rejection::NotArmed), ..Default::default() };
    s.handle(&from_gcs(command_long(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7])), &view(0.0), &mut v);
    assert_eq!(acks(&mut s)[0].result, MavResult::MAV_RESULT_DENIED);
}

#[test]
fn unknown_and_unsupported_commands_get_unsupported() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    // A command number outside the dialect: decoded as UnknownCommand, acked by hand.
    let mut payload = vec![0u8; 33];
    payload[28..30].copy_from_slice(&31_999u16.to_le_bytes());
    payload[30] = 7;
    payload[31] = 1;
    let mut bytes = vec![0xFD, 33, 0, 0, 0, 255, 190, 76, 0, 0];
    bytes.extend(&payload);
    let crc = crate::mavlink::frame::checksum(&bytes[1..], MavMessage::extra_crc(76));
    bytes.extend(crc.to_le_bytes());
    let f = FrameParser::new().push(&bytes).remove(0);
    s.handle(&f, &view(0.0), &mut v);
    let out = s.poll(&view(0.0));
    assert!(out.contains(&Outgoing::UnknownCommandAck {
        command: 31_999,
        result: MavResult::MAV_RESULT_UNSUPPORTED,
        target: (255, 190)
    }));
    let wire = encode_command_ack(MavHeader::default(), 31_999, MavResult::MAV_RESULT_UNSUPPORTED, (255, 190));
    assert_eq!(u16::from_le_bytes([wire[10], wire[11]]), 31_999);
    // A defined command we do not implement.
    s.handle(&from_gcs(command_long(MavCmd::MAV_CMD_DO_SET_SERVO, [0.0; 7])), &view(0.0), &mut v);
    assert_eq!(acks(&mut s)[0].result, MavResult::MAV_RESULT_UNSUPPORTED);
    assert!(v.commands.is_empty(), "nothing reached the autopilot");
}

#[test]
fn messages_for_another_system_are_ignored() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let MavMessage::COMMAND_LONG(mut c) = command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0; 7]) else {
        unreachable!()
    };
    c.target_system = 8;
    s.handle(&from_gcs(MavMessage::COMMAND_LONG(c)), &view(0.0), &mut v);
    assert!(v.commands.is_empty());
    assert!(acks(&mut s).is_empty());
}

#[test]
fn takeoff_uses_mis_takeoff_alt_unless_an_amsl_altitude_is_given() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let nan = f32::NAN;
    s.handle(&from_gcs(command_long(MavCmd::MAV_CMD_NAV_TAKEOFF, [nan; 7])), &view(0.0), &mut v);
    assert_eq!(v.commands.last(), Some(&Command::Takeoff { altitude_rel_home_m: 2.5 }), "PX4's default");
    // PARAM_SET MIS_TAKEOFF_ALT = 12 changes the default.
    let mut id = [0u8; 16];
    id[..15].copy_from_slice(b"MIS_TAKEOFF_ALT");
    s.handle(
        &from_gcs(MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: 12.0,
            target_system: 7,
            target_component: 1,
            param_id: id.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        })),
        &view(0.0),
        &mut v,
    );
    assert!(replies(&mut s, 0.0).iter().any(|m| matches!(m, MavMessage::PARAM_VALUE(p) if p.param_value == 12.0)));
    s.handle(&from_gcs(command_long(MavCmd::MAV_CMD_NAV_TAKEOFF, [nan; 7])), &view(0.0), &mut v);
    assert_eq!(v.commands.last(), Some(&Command::Takeoff { altitude_rel_home_m: 12.0 }));
    // param7 = 200 m AMSL; home is 2 m above the 180 m origin: 18 m above home.
    let mut p = [nan; 7];
    p[6] = 200.0;
    s.handle(&from_gcs(command_long(MavCmd::MAV_CMD_NAV_TAKEOFF, p)), &view(0.0), &mut v);
    let Some(Command::Takeoff { altitude_rel_home_m }) = v.commands.last() else { panic!() };
    assert!((altitude_rel_home_m - 18.0).abs() < 1e-6);
}

#[test]
fn do_set_mode_maps_px4_modes_to_autopilot_commands() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    for (main, sub, expected) in [
        (4.0, 4.0, Command::StartMission),
        (4.0, 5.0, Command::ReturnToLaunch),
        (4.0, 6.0, Command::Land),
        (4.0, 3.0, Command::Hold),
        (6.0, 0.0, Command::StartOffboard),
    ] {
        s.handle(
            &from_gcs(command_long(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, main, sub, 0.0, 0.0, 0.0, 0.0])),
            &view(0.0),
            &mut v,
        );
        assert_eq!(v.commands.last(), Some(&expected));
        assert_eq!(acks(&mut s)[0].result, MavResult::MAV_RESULT_ACCEPTED);
    }
    // Position control needs sticks: refused, nothing commanded.
    let before = v.commands.len();
    s.handle(
        &from_gcs(command_long(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        &view(0.0),
        &mut v,
    );
    assert_eq!(v.commands.len(), before);
    assert_eq!(acks(&mut s)[0].result, MavResult::MAV_RESULT_UNSUPPORTED);
}

#[test]
fn reposition_flies_to_the_global_point_in_the_local_frame() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let target = frame_origin().to_geodetic(Enu { east_m: 50.0, north_m: -30.0, up_m: 0.0 });
    s.handle(
        &from_gcs(MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            param1: -1.0,
            param2: 1.0,
            param3: 0.0,
            param4: f32::NAN,
            x: (target.latitude_deg * 1e7).round() as i32,
            y: (target.longitude_deg * 1e7).round() as i32,
            z: 215.0, // AMSL: 35 m above the origin, 33 m above home
            command: MavCmd::MAV_CMD_DO_REPOSITION,
            target_system: 7,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            current: 0,
            autocontinue: 0,
        })),
        &view(0.0),
        &mut v,
    );
    let Some(Command::GoTo { target_en_m, altitude_rel_home_m }) = v.commands.last() else {
        panic!("{:?}", v.commands)
    };
    assert!((target_en_m.x - 50.0).abs() < 0.05 && (target_en_m.y + 30.0).abs() < 0.05, "{target_en_m}");
    assert!((altitude_rel_home_m - 33.0).abs() < 1e-3);
}

#[test]
fn offboard_local_ned_setpoints_become_enu_positions_from_the_local_origin() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    s.handle(
        &from_gcs(MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            x: 10.0,  // north
            y: -4.0,  // east
            z: -20.0, // up 20
            yaw: 0.0, // facing north
            type_mask: PositionTargetTypemask::from_bits_truncate(0b0000_1111_1111_1000 & !(1 << 10)),
            target_system: 7,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        })),
        &view(0.0),
        &mut v,
    );
    let Some(Command::OffboardSetpoint(Setpoint::Position { position_enu_m, yaw_rad, .. })) = v.commands.last() else {
        panic!("{:?}", v.commands)
    };
    assert_eq!(*position_enu_m, Vector3::new(-4.0, 10.0, 22.0));
    assert!((yaw_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-9, "north in ENU");
    assert!(acks(&mut s).is_empty(), "setpoints are not acknowledged");
}

#[test]
fn ping_and_timesync_are_answered_to_the_sender() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    s.handle(
        &from_gcs(MavMessage::TIMESYNC(TIMESYNC_DATA { tc1: 0, ts1: 123, target_system: 0, target_component: 0 })),
        &view(2.5),
        &mut v,
    );
    s.handle(
        &from_gcs(MavMessage::PING(PING_DATA { time_usec: 9, seq: 4, target_system: 0, target_component: 0 })),
        &view(2.5),
        &mut v,
    );
    let out = replies(&mut s, 2.5);
    assert!(out.iter().any(
        |m| matches!(m, MavMessage::TIMESYNC(t) if t.ts1 == 123 && t.tc1 == 2_500_000_000 && t.target_system == 255)
    ));
    assert!(
        out.iter()
            .any(|m| matches!(m, MavMessage::PING(p) if p.seq == 4 && p.time_usec == 9 && p.target_system == 255))
    );
}

fn count(out: &[MavMessage], name: &str) -> usize {
    out.iter().filter(|m| m.message_name() == name).count()
}

#[test]
fn streams_follow_px4_rates_and_set_message_interval() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let mut all = Vec::new();
    for i in 0..1000 {
        all.extend(replies(&mut s, f64::from(i) * 0.01));
    }
    assert!((9..=11).contains(&count(&all, "HEARTBEAT")), "1 Hz for 10 s: {}", count(&all, "HEARTBEAT"));
    assert!((490..=510).contains(&count(&all, "GLOBAL_POSITION_INT")), "50 Hz: {}", count(&all, "GLOBAL_POSITION_INT"));
    // 2 Hz GLOBAL_POSITION_INT from now on.
    s.handle(
        &from_gcs(command_long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [33.0, 500_000.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        &view(10.0),
        &mut v,
    );
    let mut all = Vec::new();
    for i in 1000..2000 {
        all.extend(replies(&mut s, f64::from(i) * 0.01));
    }
    assert!((19..=21).contains(&count(&all, "GLOBAL_POSITION_INT")), "{}", count(&all, "GLOBAL_POSITION_INT"));
    // An id we cannot produce.
    s.handle(
        &from_gcs(command_long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [9999.0, 1000.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        &view(20.0),
        &mut v,
    );
    assert_eq!(acks(&mut s)[0].result, MavResult::MAV_RESULT_UNSUPPORTED);
}

#[test]
fn request_message_sends_autopilot_version_once() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    s.handle(
        &from_gcs(command_long(MavCmd::MAV_CMD_REQUEST_MESSAGE, [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        &view(0.0),
        &mut v,
    );
    let out = replies(&mut s, 0.0);
    assert_eq!(count(&out, "AUTOPILOT_VERSION"), 1);
    let Some(MavMessage::AUTOPILOT_VERSION(a)) = out.iter().find(|m| m.message_name() == "AUTOPILOT_VERSION") else {
        panic!()
    };
    assert!(a.capabilities.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT));
    assert!(out.iter().any(|m| matches!(m, MavMessage::COMMAND_ACK(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)));
}

#[test]
fn reached_items_and_failsafes_are_reported() {
    let mut s = session();
    s.on_events(&[
        EventKind::WaypointReached { seq: 3 },
        EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land },
    ]);
    let out = replies(&mut s, 0.0);
    assert!(out.iter().any(|m| matches!(m, MavMessage::MISSION_ITEM_REACHED(r) if r.seq == 3)));
    assert!(
        out.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(t) if t.severity == MavSeverity::MAV_SEVERITY_WARNING))
    );
}

#[test]
fn an_uploaded_mission_is_loaded_into_the_autopilot() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let f = frame_origin();
    s.handle(
        &from_gcs(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 1,
            target_system: 7,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            opaque_id: 0,
        })),
        &view(0.0),
        &mut v,
    );
    assert!(replies(&mut s, 0.0).iter().any(|m| matches!(m, MavMessage::MISSION_REQUEST_INT(r) if r.seq == 0)));
    let g = f.to_geodetic(Enu { east_m: 100.0, north_m: 0.0, up_m: 0.0 });
    s.handle(
        &from_gcs(MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            x: (g.latitude_deg * 1e7).round() as i32,
            y: (g.longitude_deg * 1e7).round() as i32,
            z: 20.0,
            seq: 0,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            target_system: 7,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            autocontinue: 1,
            ..Default::default()
        })),
        &view(0.1),
        &mut v,
    );
    assert!(
        replies(&mut s, 0.1)
            .iter()
            .any(|m| matches!(m, MavMessage::MISSION_ACK(a) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED))
    );
    let Some(Command::LoadMission(plan)) = v.commands.last() else { panic!("{:?}", v.commands) };
    assert_eq!(plan.items.len(), 1);
}

#[test]
fn reposition_with_an_unset_position_changes_only_the_altitude() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    s.handle(
        &from_gcs(MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            param4: f32::NAN,
            x: 0,
            y: 0,
            z: 40.0,
            command: MavCmd::MAV_CMD_DO_REPOSITION,
            target_system: 7,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            ..Default::default()
        })),
        &view(0.0),
        &mut v,
    );
    let Some(Command::GoTo { target_en_m, altitude_rel_home_m }) = v.commands.last() else {
        panic!("{:?}", v.commands)
    };
    assert!((target_en_m.x - 10.0).abs() < 0.01 && (target_en_m.y - 20.0).abs() < 0.01, "{target_en_m}");
    assert!((altitude_rel_home_m - 40.0).abs() < 1e-6);
}

mod flood;
mod presets;
