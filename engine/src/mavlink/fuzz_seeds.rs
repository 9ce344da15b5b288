//! The seed corpora of the MAVLink fuzz targets in `fuzz/` (`mavlink_frame`,
//! `mavlink_session`, `mavlink_router`), written from this crate's own encoder and signer
//! when `SADESIM_FUZZ_SEEDS` names a folder (`tests/fuzz.sh` sets it), and checked here to
//! be what they claim: streams of good frames, signed frames that verify, a mission upload
//! the session accepts. Nothing is committed.
//!
//! The signing key and clock are the fuzz crate's (`fuzz/src/lib.rs`: `PASSPHRASE`, `NOW`).
#![allow(deprecated)]

use ::mavlink::dialects::common::*;
use ::mavlink::{MavHeader, Message};

use super::frame::{FrameParser, checksum, encode};
use super::gcs_messages::{command_long, heartbeat};
use super::signing::{SecretKey, Verifier, sign_into};

const PASSPHRASE: &str = "sadesim fuzz";
/// 2026-12-06 00:00 UTC as a signing timestamp.
const NOW: u64 = (1_796_515_200 - 1_420_070_400) * 100_000;
/// The drone of the session seeds.
const DRONE: u8 = 1;

/// Writes `seeds` into `$SADESIM_FUZZ_SEEDS/<target>/` when the variable is set.
fn write_seeds(target: &str, seeds: &[(&str, Vec<u8>)]) {
    let Some(root) = std::env::var_os("SADESIM_FUZZ_SEEDS") else { return };
    let dir = std::path::Path::new(&root).join(target);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, bytes) in seeds {
        std::fs::write(dir.join(name), bytes).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
}

/// Frames from a ground station (255/190); the sequence byte is the session target's clock
/// step (10 ms units), so 5 is 50 ms between frames.
fn gcs(messages: &[MavMessage]) -> Vec<u8> {
    messages.iter().flat_map(|m| encode(MavHeader { system_id: 255, component_id: 190, sequence: 5 }, m)).collect()
}

fn command(command: MavCmd, params: [f32; 7]) -> MavMessage {
    command_long(DRONE, command, params)
}

fn item(seq: u16, command: MavCmd, east: i32, z: f32) -> MavMessage {
    MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
        param1: 0.0,
        param2: 1.0,
        param3: 0.0,
        param4: f32::NAN,
        x: 418_800_000 + east,
        y: -876_200_000,
        z,
        seq,
        command,
        target_system: DRONE,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        current: u8::from(seq == 0),
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
    })
}

/// A mission of three items uploaded, then downloaded, then the mission started.
fn mission_upload() -> Vec<u8> {
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 3,
        target_system: DRONE,
        target_component: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        opaque_id: 0,
    });
    let request = |seq| {
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: DRONE,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        })
    };
    gcs(&[
        count,
        item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, 0, 20.0),
        item(1, MavCmd::MAV_CMD_NAV_WAYPOINT, 2000, 25.0),
        item(2, MavCmd::MAV_CMD_NAV_LAND, 2000, 0.0),
        MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            target_system: DRONE,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        }),
        request(0),
        request(1),
        request(2),
        MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: DRONE,
            target_component: 1,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            opaque_id: 0,
        }),
        MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA { seq: 1, target_system: DRONE, target_component: 1 }),
        command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]),
        MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: DRONE,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_ALL,
        }),
    ])
}

/// The parameter protocol: list, read by name and index, set.
fn parameters() -> Vec<u8> {
    let id = |name: &str| {
        let mut id = [0u8; 16];
        id[..name.len()].copy_from_slice(name.as_bytes());
        id.into()
    };
    gcs(&[
        MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: DRONE, target_component: 1 }),
        MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: DRONE,
            target_component: 1,
            param_id: id("MPC_XY_CRUISE"),
        }),
        MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: 3,
            target_system: DRONE,
            target_component: 1,
            param_id: id(""),
        }),
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: 12.0,
            target_system: DRONE,
            target_component: 1,
            param_id: id("MIS_TAKEOFF_ALT"),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }),
    ])
}

/// Commands and the other messages a ground station or an offboard program sends.
fn commands() -> Vec<u8> {
    let mut bytes = gcs(&[
        heartbeat(),
        command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, f32::NAN, f32::NAN, f32::NAN, 230.0]),
        command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0]),
        command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [33.0, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        command(MavCmd::MAV_CMD_REQUEST_MESSAGE, [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            param1: -1.0,
            param2: 1.0,
            param3: 0.0,
            param4: f32::NAN,
            x: 418_801_000,
            y: -876_201_000,
            z: 40.0,
            command: MavCmd::MAV_CMD_DO_REPOSITION,
            target_system: DRONE,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            current: 0,
            autocontinue: 0,
        }),
        MavMessage::SET_MODE(SET_MODE_DATA {
            custom_mode: 4 << 16 | 3 << 24,
            target_system: DRONE,
            base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
        }),
        MavMessage::PING(PING_DATA { time_usec: 1, seq: 2, target_system: 0, target_component: 0 }),
        MavMessage::TIMESYNC(TIMESYNC_DATA { tc1: 0, ts1: 5, target_system: DRONE, target_component: 1 }),
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms: 0,
            x: 5.0,
            y: 3.0,
            z: -10.0,
            vx: 0.0,
            vy: 0.0,
            vz: 0.0,
            afx: 0.0,
            afy: 0.0,
            afz: 0.0,
            yaw: 0.5,
            yaw_rate: 0.0,
            type_mask: PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
                | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE
                | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE,
            target_system: DRONE,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        }),
        command(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]),
        command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]),
    ]);
    // A COMMAND_LONG whose command id the dialect does not define (it gets UNSUPPORTED).
    let mut unknown = encode(
        MavHeader { system_id: 255, component_id: 190, sequence: 5 },
        &command(MavCmd::MAV_CMD_NAV_LAND, [1.0; 7]),
    );
    unknown[10 + 28..10 + 30].copy_from_slice(&60_000u16.to_le_bytes());
    let end = unknown.len() - 2;
    let crc = checksum(&unknown[1..end], MavMessage::extra_crc(76));
    unknown[end..].copy_from_slice(&crc.to_le_bytes());
    bytes.extend(unknown);
    bytes
}

/// A MAVLink 1 HEARTBEAT: STX 0xFE, len, seq, sysid, compid, msgid, payload, CRC.
fn mavlink1_heartbeat() -> Vec<u8> {
    let mut frame = vec![0xFE, 9, 0, 255, 190, 0];
    frame.extend([0, 0, 0, 0, 6, 8, 0, 4, 3]);
    let crc = checksum(&frame[1..], MavMessage::extra_crc(0));
    frame.extend(crc.to_le_bytes());
    frame
}

/// `frames` (a stream of unsigned frames) each signed with the fuzz key, timestamps from NOW.
fn signed(frames: &[u8], link: u8) -> Vec<u8> {
    let key = SecretKey::from_passphrase(PASSPHRASE);
    let mut out = Vec::new();
    for (i, f) in FrameParser::new().push(frames).iter().enumerate() {
        sign_into(&mut out, &f.bytes, &key, link, NOW + i as u64);
    }
    out
}

/// A shard's datagram to the router: the telemetry of several drones, one frame of the
/// router's own (253/240, dropped) and a few bytes of garbage.
fn shard_datagram() -> Vec<u8> {
    let mut bytes = Vec::new();
    for sysid in 1..=4u32 {
        let header = MavHeader { system_id: sysid, component_id: 1, sequence: sysid as u8 };
        bytes.extend(encode(header, &heartbeat()));
        bytes.extend(encode(
            header,
            &MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: 1000 * sysid,
                roll: 0.1,
                pitch: -0.2,
                yaw: 1.5,
                rollspeed: 0.0,
                pitchspeed: 0.0,
                yawspeed: 0.01,
            }),
        ));
    }
    bytes.extend(encode(MavHeader { system_id: 253, component_id: 240, sequence: 0 }, &heartbeat()));
    bytes.extend([0x00, 0xFD, 0x03]);
    bytes
}

#[test]
fn the_fuzz_seeds_are_good_mavlink() {
    let v1 = mavlink1_heartbeat();
    let mut parser = FrameParser::new();
    assert!(parser.push(&v1).is_empty());
    assert_eq!(parser.stats.mavlink1_frames, 1, "the MAVLink 1 seed is a good frame");

    let (mission, params, commands) = (mission_upload(), parameters(), commands());
    let stream = [gcs(&[heartbeat()]), v1.clone(), params.clone()].concat();
    let signed_stream = signed(&[gcs(&[heartbeat()]), commands.clone()].concat(), 3);
    let mut verifier = Verifier::new(SecretKey::from_passphrase(PASSPHRASE));
    let signed_frames = FrameParser::new().push(&signed_stream);
    assert_eq!(signed_frames.len(), 15);
    for f in &signed_frames {
        assert_eq!(verifier.check(&f.bytes, NOW), Ok(()), "a signed seed frame does not verify");
    }
    for (name, bytes) in [("mission", &mission), ("params", &params), ("commands", &commands)] {
        let frames = FrameParser::new().push(bytes);
        assert!(frames.iter().all(|f| f.bytes.len() > 10), "{name}");
        assert_eq!(frames.iter().map(|f| f.bytes.len()).sum::<usize>(), bytes.len(), "{name}: not all good frames");
    }

    let frame_seeds = [
        ("v2-heartbeat", gcs(&[heartbeat()])),
        ("v1-heartbeat", v1.clone()),
        ("v2-signed", signed(&gcs(&[heartbeat(), command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0; 7])]), 7)),
        ("mixed-stream", stream),
        ("commands", commands.clone()),
    ];
    write_seeds("mavlink_frame", &frame_seeds);
    write_seeds(
        "mavlink_session",
        &[
            ("mission", mission.clone()),
            ("params", params.clone()),
            ("commands", commands.clone()),
            ("everything", [commands.clone(), mission.clone(), params.clone()].concat()),
        ],
    );
    write_seeds(
        "mavlink_router",
        &[
            ("shard-datagram", shard_datagram()),
            ("gcs-signed", signed_stream),
            ("gcs-mission", signed(&mission, 1)),
            ("gcs-v1", [v1, gcs(&[heartbeat()])].concat()),
        ],
    );
}

#[test]
fn the_session_seed_uploads_a_mission() {
    use super::mission_protocol::{MissionContext, MissionProtocol};
    use sadesim_crds::geo::{GeoPoint, LocalFrame};
    let frame = LocalFrame::new(GeoPoint { latitude_deg: 41.88, longitude_deg: -87.62, altitude_msl_m: 180.0 });
    let ctx = MissionContext {
        frame: &frame,
        home_alt_amsl_m: 180.0,
        cruise_speed_mps: 5.0,
        current_seq: 0,
        our_system: DRONE,
        our_component: 1,
    };
    let mut p = MissionProtocol::new();
    let mut loaded = None;
    for (i, f) in FrameParser::new().push(&mission_upload()).iter().take(4).enumerate() {
        let super::frame::Decoded::Message(m) = &f.message else { panic!("frame {i} does not decode") };
        loaded = loaded.or(p.handle((255, 190), m, i as f64 * 0.05, &ctx).loaded);
    }
    assert_eq!(p.count(), 3);
    assert_eq!(loaded.expect("the upload completes").items.len(), 3);
}
