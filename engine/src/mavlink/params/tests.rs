use ::mavlink::{MavlinkVersion, Message};

use super::*;

const SYSID: u8 = 7;

fn x500() -> Preset {
    Preset::named("x500").expect("x500 preset")
}

fn table() -> ParamTable {
    ParamTable::px4(SYSID, &x500(), &NavigatorConfig::default())
}

fn request_list(target_system: u8) -> MavMessage {
    MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system, target_component: 1 })
}

fn read_by_name(name: &str) -> MavMessage {
    MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: SYSID,
        target_component: 1,
        param_id: CharArray::from(name),
    })
}

fn read_by_index(param_index: i16) -> MavMessage {
    MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index,
        target_system: SYSID,
        target_component: 1,
        // Ignored when the index is given (MAVLink): a name that exists, to prove it.
        param_id: CharArray::from("MPC_XY_CRUISE"),
    })
}

fn param_set(name: &str, value: ParamValue) -> MavMessage {
    MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: value.to_wire(),
        target_system: SYSID,
        target_component: 1,
        param_id: CharArray::from(name),
        param_type: value.mav_type(),
    })
}

/// The single PARAM_VALUE of a reply.
fn only_value(reply: &ParamReply) -> &PARAM_VALUE_DATA {
    match reply.messages.as_slice() {
        [MavMessage::PARAM_VALUE(v)] => v,
        other => panic!("expected one PARAM_VALUE, got {other:?}"),
    }
}

fn name_of(v: &PARAM_VALUE_DATA) -> &str {
    v.param_id.to_str().expect("ASCII name")
}

#[test]
fn table_size_order_and_names_are_stable() {
    let t = table();
    assert!((60..=90).contains(&t.len()), "{} parameters", t.len());
    let names: Vec<&str> = t.params().iter().map(|p| p.name).collect();
    assert!(names.windows(2).all(|w| w[0] < w[1]), "sorted and unique: {names:?}");
    assert!(names.iter().all(|n| n.len() <= NAME_MAX_LEN && n.bytes().all(|b| b.is_ascii_graphic())));
    // Same order for every drone, whatever its id or config.
    let other = ParamTable::px4(200, &x500(), &NavigatorConfig { rtl_altitude_m: 50.0, ..NavigatorConfig::default() });
    assert_eq!(names, other.params().iter().map(|p| p.name).collect::<Vec<_>>());
}

#[test]
fn required_parameters_are_present_with_px4_types() {
    let t = table();
    let real32 = "MIS_TAKEOFF_ALT MPC_XY_CRUISE MPC_XY_VEL_MAX MPC_Z_VEL_MAX_UP MPC_Z_VEL_MAX_DN MPC_TKO_SPEED \
        MPC_LAND_SPEED MPC_Z_V_AUTO_DN MPC_LAND_ALT2 NAV_ACC_RAD NAV_MC_ALT_RAD RTL_RETURN_ALT RTL_DESCEND_ALT \
        RTL_LAND_DELAY COM_OF_LOSS_T COM_DISARM_LAND BAT_LOW_THR BAT_CRIT_THR BAT_EMERGEN_THR GF_MAX_HOR_DIST \
        GF_MAX_VER_DIST MPC_XY_P MPC_Z_P MC_ROLL_P MC_PITCH_P MC_YAW_P";
    for name in real32.split_whitespace() {
        assert!(matches!(t.get(name), Some(ParamValue::Real32(_))), "{name} REAL32");
    }
    let int32 = "COM_OBL_RC_ACT COM_RC_IN_MODE BAT1_N_CELLS MAV_SYS_ID MAV_COMP_ID MAV_TYPE SYS_AUTOSTART \
        SYS_HITL GF_ACTION CAL_ACC0_ID CAL_GYRO0_ID CAL_MAG0_ID SENS_BOARD_ROT";
    for name in int32.split_whitespace() {
        assert!(matches!(t.get(name), Some(ParamValue::Int32(_))), "{name} INT32");
    }
    assert!(t.params().iter().any(|p| p.name.starts_with("EKF2_")));
    assert!(t.params().iter().any(|p| p.name.starts_with("LNDMC_")));
}

#[test]
fn identity_and_navigator_values_come_from_the_constructor() {
    let nav = NavigatorConfig { rtl_altitude_m: 45.0, acceptance_radius_m: 1.5, ..NavigatorConfig::default() };
    let t = ParamTable::px4(42, &x500(), &nav);
    assert_eq!(t.get("MAV_SYS_ID"), Some(ParamValue::Int32(42)));
    assert_eq!(t.get("MAV_COMP_ID"), Some(ParamValue::Int32(1)));
    assert_eq!(t.get("MAV_TYPE"), Some(ParamValue::Int32(2)));
    assert_eq!(t.get("SYS_AUTOSTART"), Some(ParamValue::Int32(4001)));
    assert_eq!(t.get("RTL_RETURN_ALT"), Some(ParamValue::Real32(45.0)));
    assert_eq!(t.get("NAV_ACC_RAD"), Some(ParamValue::Real32(1.5)));
    assert_eq!(t.get("MIS_TAKEOFF_ALT"), Some(ParamValue::Real32(2.5)));
    assert_eq!((t.takeoff_altitude_m(), t.cruise_speed_mps()), (2.5, 5.0));
    for name in ["CAL_ACC0_ID", "CAL_GYRO0_ID", "CAL_MAG0_ID"] {
        assert!(matches!(t.get(name), Some(ParamValue::Int32(id)) if id != 0), "{name} calibrated");
    }
}

#[test]
fn untouched_table_returns_the_base_navigator_config_exactly() {
    let base = NavigatorConfig::default();
    assert_eq!(table().navigator_config(base), base);
}

#[test]
fn request_list_answers_every_parameter_with_index_and_count() {
    let mut t = table();
    let reply = t.handle(&request_list(SYSID));
    assert_eq!(reply.messages.len(), t.len());
    for (i, msg) in reply.messages.iter().enumerate() {
        let MavMessage::PARAM_VALUE(v) = msg else { panic!("{msg:?}") };
        assert_eq!((usize::from(v.param_index), usize::from(v.param_count)), (i, t.len()));
        assert_eq!(name_of(v), t.params()[i].name);
        assert_eq!(v.param_type, t.params()[i].value.mav_type());
    }
    // Broadcast is answered too; another drone's request is not ours.
    assert_eq!(t.handle(&request_list(0)).messages.len(), t.len());
    assert!(t.handle(&request_list(SYSID + 1)).messages.is_empty());
}

#[test]
fn read_by_name_and_by_index() {
    let mut t = table();
    let by_name = t.handle(&read_by_name("RTL_RETURN_ALT"));
    let v = only_value(&by_name);
    assert_eq!(
        (name_of(v), v.param_value, v.param_type),
        ("RTL_RETURN_ALT", 30.0, MavParamType::MAV_PARAM_TYPE_REAL32)
    );
    let index = t.index_of("RTL_RETURN_ALT").expect("present");
    assert_eq!(usize::from(v.param_index), index);

    let by_index = t.handle(&read_by_index(i16::try_from(index).expect("small")));
    assert_eq!(only_value(&by_index), v);

    // INT32 read back bytewise.
    let sysid = t.handle(&read_by_name("MAV_SYS_ID"));
    assert_eq!(only_value(&sysid).param_value.to_bits(), u32::from(SYSID));
}

#[test]
fn unknown_reads_get_no_answer_like_px4() {
    let mut t = table();
    assert!(t.handle(&read_by_name("NO_SUCH_PARAM")).messages.is_empty());
    assert!(t.handle(&read_by_index(i16::try_from(t.len()).expect("small"))).messages.is_empty());
    assert!(t.handle(&param_set("NO_SUCH_PARAM", ParamValue::Real32(1.0))).messages.is_empty());
}

#[test]
fn set_real32_round_trips_and_reports_the_navigator_change() {
    let mut t = table();
    let reply = t.handle(&param_set("RTL_RETURN_ALT", ParamValue::Real32(45.3)));
    let v = only_value(&reply);
    assert_eq!((name_of(v), v.param_value), ("RTL_RETURN_ALT", 45.3));
    assert!(reply.navigator_changed && reply.rejection.is_none());
    assert_eq!(t.get("RTL_RETURN_ALT"), Some(ParamValue::Real32(45.3)));

    // The autopilot sees the decimal the user typed, the other fields stay exact.
    let base = NavigatorConfig::default();
    let config = t.navigator_config(base);
    assert_eq!(config, NavigatorConfig { rtl_altitude_m: 45.3, ..base });

    // Writing the same value again is answered, but changes nothing.
    let again = t.handle(&param_set("RTL_RETURN_ALT", ParamValue::Real32(45.3)));
    assert!(!again.navigator_changed && again.rejection.is_none() && again.messages.len() == 1);
}

#[test]
fn set_takeoff_altitude_and_cruise_speed() {
    let mut t = table();
    assert!(t.handle(&param_set("MIS_TAKEOFF_ALT", ParamValue::Real32(12.0))).navigator_changed);
    assert!(t.handle(&param_set("MPC_XY_CRUISE", ParamValue::Real32(8.5))).navigator_changed);
    assert_eq!((t.takeoff_altitude_m(), t.cruise_speed_mps()), (12.0, 8.5));
    // A parameter the autopilot does not read is stored, without the flag.
    let reply = t.handle(&param_set("MPC_XY_P", ParamValue::Real32(1.2)));
    assert!(!reply.navigator_changed && reply.rejection.is_none());
    assert_eq!(t.get("MPC_XY_P"), Some(ParamValue::Real32(1.2)));
}

#[test]
fn set_int32_bytewise_round_trips() {
    let mut t = table();
    // COM_OBL_RC_ACT 4 (land) travels as the float with bit pattern 4.
    let msg = param_set("COM_OBL_RC_ACT", ParamValue::Int32(4));
    let MavMessage::PARAM_SET(ref set) = msg else { unreachable!() };
    assert_eq!(set.param_value.to_bits(), 4);
    let reply = t.handle(&msg);
    let v = only_value(&reply);
    assert_eq!((v.param_value.to_bits(), v.param_type), (4, MavParamType::MAV_PARAM_TYPE_INT32));
    assert_eq!(t.get("COM_OBL_RC_ACT"), Some(ParamValue::Int32(4)));

    // -1 is all ones: a NaN bit pattern, which must survive decoding.
    let reply = t.handle(&param_set("SENS_BOARD_ROT", ParamValue::Int32(-1)));
    assert!(reply.rejection.is_none(), "{:?}", reply.rejection);
    assert_eq!(only_value(&reply).param_value.to_bits(), u32::MAX);
    assert_eq!(t.get("SENS_BOARD_ROT"), Some(ParamValue::Int32(-1)));
}

#[test]
fn int32_bit_patterns_survive_the_wire() {
    // Serialised and parsed by the dialect code the endpoint uses: a NaN-patterned INT32
    // (-1) must arrive bit for bit, not as a canonical NaN.
    let mut t = table();
    let _ = t.set("SYS_HITL", ParamValue::Int32(-1)).expect("in range");
    let msg = t.value_message(t.index_of("SYS_HITL").expect("present")).expect("exists");
    let mut payload = [0u8; 255];
    let len = msg.ser(MavlinkVersion::V2, &mut payload);
    let parsed = MavMessage::parse(MavlinkVersion::V2, msg.message_id(), &payload[..len]).expect("parses");
    let MavMessage::PARAM_VALUE(v) = parsed else { panic!("{parsed:?}") };
    assert_eq!(v.param_value.to_bits(), u32::MAX);
    assert_eq!(ParamValue::from_wire(v.param_value, v.param_type), Some(ParamValue::Int32(-1)));
}

#[test]
fn out_of_range_set_keeps_the_old_value_and_says_so() {
    let mut t = table();
    // MPC_XY_CRUISE is 3..20 m/s in PX4.
    let reply = t.handle(&param_set("MPC_XY_CRUISE", ParamValue::Real32(25.0)));
    assert_eq!(only_value(&reply).param_value, 5.0);
    assert!(!reply.navigator_changed);
    assert!(matches!(reply.rejection, Some(SetRejection::OutOfRange { name: "MPC_XY_CRUISE", max: 20.0, .. })));
    assert_eq!(t.cruise_speed_mps(), 5.0);

    // Bounds are inclusive, compared in f32.
    for (name, edge) in [("MC_PITCHRATE_P", 0.6), ("NAV_ACC_RAD", 0.05), ("BAT_LOW_THR", 0.12)] {
        assert_eq!(t.set(name, ParamValue::Real32(edge)), Ok(true), "{name} = {edge}");
    }
    // An integer enumeration past its last value.
    let reply = t.handle(&param_set("GF_ACTION", ParamValue::Int32(6)));
    assert_eq!(only_value(&reply).param_value.to_bits(), 2);
    assert!(reply.rejection.is_some());
}

#[test]
fn wrong_type_not_finite_and_read_only_are_refused_with_the_current_value() {
    let mut t = table();
    // An INT32 parameter written as REAL32 (a classic client bug: 4.0 instead of bits 4).
    let reply = t.handle(&param_set("COM_OBL_RC_ACT", ParamValue::Real32(4.0)));
    assert_eq!(only_value(&reply).param_value.to_bits(), 0);
    assert!(matches!(reply.rejection, Some(SetRejection::TypeMismatch { .. })));
    // A type PX4 does not have.
    let mut msg = param_set("COM_OBL_RC_ACT", ParamValue::Int32(4));
    if let MavMessage::PARAM_SET(set) = &mut msg {
        set.param_type = MavParamType::MAV_PARAM_TYPE_UINT8;
    }
    assert!(matches!(t.handle(&msg).rejection, Some(SetRejection::TypeMismatch { .. })));
    assert_eq!(t.get("COM_OBL_RC_ACT"), Some(ParamValue::Int32(0)));

    let reply = t.handle(&param_set("RTL_RETURN_ALT", ParamValue::Real32(f32::NAN)));
    assert_eq!(only_value(&reply).param_value, 30.0);
    assert_eq!(reply.rejection, Some(SetRejection::NotFinite("RTL_RETURN_ALT")));

    let reply = t.handle(&param_set("MAV_SYS_ID", ParamValue::Int32(9)));
    assert_eq!(only_value(&reply).param_value.to_bits(), u32::from(SYSID));
    assert_eq!(reply.rejection, Some(SetRejection::ReadOnly("MAV_SYS_ID")));
}

#[test]
fn messages_for_others_and_other_messages_are_ignored() {
    let mut t = table();
    let before = t.clone();
    let mut msg = param_set("RTL_RETURN_ALT", ParamValue::Real32(50.0));
    if let MavMessage::PARAM_SET(set) = &mut msg {
        set.target_system = SYSID + 1;
    }
    assert_eq!(t.handle(&msg), ParamReply::default());
    if let MavMessage::PARAM_SET(set) = &mut msg {
        set.target_system = SYSID;
        set.target_component = 100; // a camera, not the autopilot
    }
    assert_eq!(t.handle(&msg), ParamReply::default());
    let heartbeat = MavMessage::HEARTBEAT(::mavlink::dialects::common::HEARTBEAT_DATA::default());
    assert_eq!(t.handle(&heartbeat), ParamReply::default());
    assert_eq!(t, before);
}

#[test]
fn a_sixteen_character_name_without_terminator_is_found() {
    let mut t = table();
    let name = "MPC_XY_VEL_P_ACC";
    assert_eq!(name.len(), NAME_MAX_LEN);
    let reply = t.handle(&read_by_name(name));
    assert_eq!(name_of(only_value(&reply)), name);
}

#[test]
fn every_preset_value_names_a_parameter_of_its_type() {
    for p in Preset::all() {
        let t = ParamTable::px4(SYSID, &p, &NavigatorConfig::default());
        assert_eq!(t.len(), table().len(), "{}: same parameters for every preset", p.name());
        for (name, value) in super::preset::values(&p) {
            let expected = match t.get(name) {
                Some(ParamValue::Int32(_)) => ParamValue::Int32(value as i32),
                Some(ParamValue::Real32(_)) => ParamValue::Real32(value as f32),
                None => panic!("{}: {name} is not a parameter", p.name()),
            };
            assert_eq!(t.get(name), Some(expected), "{}: {name}", p.name());
        }
    }
}
