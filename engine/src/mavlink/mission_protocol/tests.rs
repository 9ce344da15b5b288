use ::mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA, MavCmd, MavFrame, MavMessage,
    MavMissionResult as R, MavMissionType as T, MissionState,
};
use nalgebra::Vector2;
use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};

use super::*;

/// A client the way MAVSDK shows up (sysid 245, component MISSIONPLANNER).
const GCS: Peer = (245, 190);
/// A second client (QGroundControl's usual ids).
const QGC: Peer = (255, 190);
/// Home ground, m AMSL (the origin is at 488 m; home sits 2 m higher).
const HOME_AMSL_M: f64 = 490.0;

fn frame() -> LocalFrame {
    LocalFrame::new(GeoPoint::new(47.397_742, 8.545_594, 488.0))
}

fn ctx(frame: &LocalFrame) -> MissionContext<'_> {
    MissionContext {
        frame,
        home_alt_amsl_m: HOME_AMSL_M,
        cruise_speed_mps: 5.0,
        current_seq: 0,
        our_system: 1,
        our_component: 1,
    }
}

/// Lat/lon in 1e-7 degrees of an ENU offset from the origin.
fn latlon_e7(frame: &LocalFrame, east_m: f64, north_m: f64) -> (i32, i32) {
    let g = frame.to_geodetic(Enu::new(east_m, north_m, 0.0));
    ((g.latitude_deg * 1e7).round() as i32, (g.longitude_deg * 1e7).round() as i32)
}

fn item(seq: u16, command: MavCmd, frame: MavFrame, x: i32, y: i32, z: f32) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        param1: 0.0,
        param2: 0.0,
        param3: 0.0,
        param4: f32::NAN,
        x,
        y,
        z,
        seq,
        command,
        target_system: 1,
        target_component: 1,
        frame,
        current: u8::from(seq == 0),
        autocontinue: 1,
        mission_type: T::MAV_MISSION_TYPE_MISSION,
    }
}

/// A MAVSDK waypoint: GLOBAL_RELATIVE_ALT_INT, acceptance radius 1 m, yaw NaN.
fn waypoint(frame: &LocalFrame, seq: u16, east_m: f64, north_m: f64, alt_m: f32) -> MISSION_ITEM_INT_DATA {
    let (x, y) = latlon_e7(frame, east_m, north_m);
    MISSION_ITEM_INT_DATA {
        param2: 1.0,
        ..item(seq, MavCmd::MAV_CMD_NAV_WAYPOINT, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, x, y, alt_m)
    }
}

/// MAVSDK's speed item: MAV_FRAME_MISSION, ground speed, throttle unchanged.
fn change_speed(seq: u16, speed_mps: f32) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        param1: 1.0,
        param2: speed_mps,
        param3: -1.0,
        param4: 0.0,
        ..item(seq, MavCmd::MAV_CMD_DO_CHANGE_SPEED, MavFrame::MAV_FRAME_MISSION, 0, 0, 0.0)
    }
}

fn mavsdk_mission(frame: &LocalFrame) -> Vec<MISSION_ITEM_INT_DATA> {
    vec![
        waypoint(frame, 0, 0.0, 0.0, 10.0),
        change_speed(1, 8.0),
        waypoint(frame, 2, 120.0, 40.0, 25.0),
        waypoint(frame, 3, -60.0, 200.0, 15.5),
    ]
}

fn count_msg_of(count: u16, mission_type: T) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count,
        target_system: 1,
        target_component: 1,
        mission_type,
        opaque_id: 0,
    })
}

fn count(count: u16) -> MavMessage {
    count_msg_of(count, T::MAV_MISSION_TYPE_MISSION)
}

fn request_list(mission_type: T) -> MavMessage {
    MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA { target_system: 1, target_component: 1, mission_type })
}

fn request_int(seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: 1,
        target_component: 1,
        mission_type: T::MAV_MISSION_TYPE_MISSION,
    })
}

fn client_ack(result: R, mission_type: T) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 1,
        target_component: 1,
        mavtype: result,
        mission_type,
        opaque_id: 0,
    })
}

fn clear_all(mission_type: T) -> MavMessage {
    MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA { target_system: 1, target_component: 1, mission_type })
}

/// The only reply, which must be a MISSION_ACK to `to`: (result, mission type, opaque id).
fn only_ack(replies: &[MavMessage], to: Peer) -> (R, T, u32) {
    match replies {
        [MavMessage::MISSION_ACK(a)] => {
            assert_eq!((a.target_system, a.target_component), to, "ACK addressed to the requester");
            (a.mavtype, a.mission_type, a.opaque_id)
        }
        other => panic!("expected one MISSION_ACK, got {other:?}"),
    }
}

/// The only reply, which must be a MISSION_REQUEST_INT for the mission to `to`: its seq.
fn only_request_int(replies: &[MavMessage], to: Peer) -> u16 {
    match replies {
        [MavMessage::MISSION_REQUEST_INT(r)] => {
            assert_eq!((r.target_system, r.target_component), to, "request addressed to the uploader");
            assert_eq!(r.mission_type, T::MAV_MISSION_TYPE_MISSION);
            r.seq
        }
        other => panic!("expected one MISSION_REQUEST_INT, got {other:?}"),
    }
}

/// Uploads `items` as a well-behaved client at 10 ms per message; returns the requested
/// seqs and the output of the last item.
fn upload(
    p: &mut MissionProtocol,
    from: Peer,
    items: &[MISSION_ITEM_INT_DATA],
    ctx: &MissionContext,
) -> (Vec<u16>, MissionOutput) {
    let n = u16::try_from(items.len()).unwrap();
    let mut out = p.handle(from, &count(n), 0.0, ctx);
    let mut requested = Vec::new();
    for (i, it) in items.iter().enumerate() {
        requested.push(only_request_int(&out.replies, from));
        out = p.handle(from, &MavMessage::MISSION_ITEM_INT(it.clone()), 0.01 * (i + 1) as f64, ctx);
        if matches!(out.replies.as_slice(), [MavMessage::MISSION_ACK(_)]) {
            break;
        }
    }
    (requested, out)
}

fn assert_near(got: Vector2<f64>, want: Vector2<f64>, tol_m: f64) {
    assert!((got - want).norm() <= tol_m, "got {got:?}, want {want:?} within {tol_m} m");
}

#[test]
fn mavsdk_upload_requests_every_item_then_accepts_with_positions_from_the_local_frame() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();

    let (requested, out) = upload(&mut p, GCS, &items, &c);

    assert_eq!(requested, vec![0, 1, 2, 3]);
    let (result, kind, id) = only_ack(&out.replies, GCS);
    assert_eq!((result, kind), (R::MAV_MISSION_ACCEPTED, T::MAV_MISSION_TYPE_MISSION));
    assert_ne!(id, 0, "PX4 returns the new plan's opaque id");
    assert_eq!(id, p.mission_id());
    assert_eq!(p.count(), 4);
    assert!(!p.transfer_in_progress());

    let plan = out.loaded.expect("an accepted upload is loaded");
    assert_eq!(plan.items.len(), 4, "one autopilot item per MAVLink seq");
    assert_eq!(plan.speed_mps, 5.0);
    let expect = [(0.0, 0.0, 10.0), (120.0, 40.0, 25.0), (-60.0, 200.0, 15.5)];
    let waypoints: Vec<_> = plan
        .items
        .iter()
        .filter_map(|i| match i {
            MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s } => {
                Some((*target_en_m, *alt_rel_home_m, *hold_s))
            }
            _ => None,
        })
        .collect();
    assert_eq!(waypoints.len(), 3);
    for ((en, alt, hold), (e, n, a)) in waypoints.iter().zip(expect) {
        assert_near(*en, Vector2::new(e, n), 0.1);
        assert_eq!(*alt, a);
        assert_eq!(*hold, 0.0);
    }
    assert_eq!(plan.items[1], MissionItem::ChangeSpeed { speed_mps: 8.0 });
}

#[test]
fn download_returns_the_uploaded_items_addressed_to_the_requester() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();
    let (_, up) = upload(&mut p, GCS, &items, &c);
    let (_, _, upload_id) = only_ack(&up.replies, GCS);

    // A different client downloads.
    let out = p.handle(QGC, &request_list(T::MAV_MISSION_TYPE_MISSION), 1.0, &c);
    match out.replies.as_slice() {
        [MavMessage::MISSION_COUNT(m)] => {
            assert_eq!((m.count, m.mission_type, m.opaque_id), (4, T::MAV_MISSION_TYPE_MISSION, upload_id));
            assert_eq!((m.target_system, m.target_component), QGC);
        }
        other => panic!("expected MISSION_COUNT, got {other:?}"),
    }
    assert!(p.transfer_in_progress());
    for (seq, sent) in items.iter().enumerate() {
        let out = p.handle(QGC, &request_int(seq as u16), 1.1, &c);
        let [MavMessage::MISSION_ITEM_INT(got)] = out.replies.as_slice() else {
            panic!("expected MISSION_ITEM_INT, got {:?}", out.replies)
        };
        let want = MISSION_ITEM_INT_DATA { target_system: QGC.0, target_component: QGC.1, ..sent.clone() };
        // NaN yaw is not equal to itself: compare the bits.
        assert_eq!(format!("{got:?}"), format!("{want:?}"));
    }
    assert!(!p.transfer_in_progress(), "the last item completes the download");
    assert!(
        p.handle(QGC, &client_ack(R::MAV_MISSION_ACCEPTED, T::MAV_MISSION_TYPE_MISSION), 1.2, &c).replies.is_empty()
    );
}

#[test]
fn download_of_an_unknown_seq_is_an_error_and_the_client_ack_ends_the_download() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    upload(&mut p, GCS, &mavsdk_mission(&f), &c);

    p.handle(GCS, &request_list(T::MAV_MISSION_TYPE_MISSION), 1.0, &c);
    let out = p.handle(GCS, &request_int(9), 1.1, &c);
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_ERROR);
    assert!(!p.transfer_in_progress());

    p.handle(GCS, &request_list(T::MAV_MISSION_TYPE_MISSION), 2.0, &c);
    p.handle(GCS, &client_ack(R::MAV_MISSION_OPERATION_CANCELLED, T::MAV_MISSION_TYPE_MISSION), 2.1, &c);
    assert!(!p.transfer_in_progress());
}

#[test]
fn stalled_download_is_forgotten_so_another_client_can_upload() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    upload(&mut p, GCS, &mavsdk_mission(&f), &c);
    p.handle(QGC, &request_list(T::MAV_MISSION_TYPE_MISSION), 1.0, &c);

    // Busy: QGC is reading the mission.
    let out = p.handle(GCS, &count(1), 2.0, &c);
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_ERROR);

    assert!(p.poll(1.0 + DOWNLOAD_TIMEOUT_S + 0.1).is_empty());
    assert!(!p.transfer_in_progress());
    let out = p.handle(GCS, &count(1), 7.0, &c);
    assert_eq!(only_request_int(&out.replies, GCS), 0);
}

#[test]
fn clear_all_and_empty_upload_remove_the_mission() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    upload(&mut p, GCS, &mavsdk_mission(&f), &c);

    let out = p.handle(GCS, &clear_all(T::MAV_MISSION_TYPE_MISSION), 1.0, &c);
    assert_eq!(only_ack(&out.replies, GCS), (R::MAV_MISSION_ACCEPTED, T::MAV_MISSION_TYPE_MISSION, 0));
    assert!(out.cleared);
    assert_eq!((p.count(), p.mission_id()), (0, 0));
    let out = p.handle(GCS, &request_list(T::MAV_MISSION_TYPE_MISSION), 1.1, &c);
    assert!(matches!(out.replies.as_slice(), [MavMessage::MISSION_COUNT(m)] if m.count == 0 && m.opaque_id == 0));
    assert!(!p.transfer_in_progress(), "an empty download needs no requests");

    upload(&mut p, GCS, &mavsdk_mission(&f), &c);
    let out = p.handle(GCS, &count(0), 2.0, &c);
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_ACCEPTED);
    assert!(out.cleared);
    assert_eq!(p.count(), 0);

    upload(&mut p, GCS, &mavsdk_mission(&f), &c);
    let out = p.handle(GCS, &clear_all(T::MAV_MISSION_TYPE_ALL), 3.0, &c);
    assert_eq!(only_ack(&out.replies, GCS), (R::MAV_MISSION_ACCEPTED, T::MAV_MISSION_TYPE_ALL, 0));
    assert!(out.cleared);
    assert_eq!(p.count(), 0);
}

#[test]
fn out_of_order_items_are_dropped_and_the_expected_seq_requested_again() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();
    let item_msg = |i: usize| MavMessage::MISSION_ITEM_INT(items[i].clone());

    assert_eq!(only_request_int(&p.handle(GCS, &count(4), 0.0, &c).replies, GCS), 0);
    // Item 1 before item 0 (0 was lost): ask for 0 again.
    assert_eq!(only_request_int(&p.handle(GCS, &item_msg(1), 0.01, &c).replies, GCS), 0);
    assert_eq!(only_request_int(&p.handle(GCS, &item_msg(0), 0.02, &c).replies, GCS), 1);
    // A duplicate of 0 (our request for 1 was slow): ask for 1 again.
    assert_eq!(only_request_int(&p.handle(GCS, &item_msg(0), 0.03, &c).replies, GCS), 1);
    assert_eq!(only_request_int(&p.handle(GCS, &item_msg(1), 0.04, &c).replies, GCS), 2);
    assert_eq!(only_request_int(&p.handle(GCS, &item_msg(3), 0.05, &c).replies, GCS), 2);
    assert_eq!(only_request_int(&p.handle(GCS, &item_msg(2), 0.06, &c).replies, GCS), 3);
    let out = p.handle(GCS, &item_msg(3), 0.07, &c);
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_ACCEPTED);
    assert_eq!(out.loaded.map(|plan| plan.items.len()), Some(4));
}

#[test]
fn unsupported_command_is_refused_after_its_item_and_the_loaded_mission_is_kept() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    let first = mavsdk_mission(&f);
    upload(&mut p, GCS, &first, &c);
    let id_before = p.mission_id();

    let mut second =
        vec![waypoint(&f, 0, 10.0, 10.0, 20.0), waypoint(&f, 1, 20.0, 10.0, 20.0), waypoint(&f, 2, 0.0, 0.0, 20.0)];
    second[1].command = MavCmd::MAV_CMD_NAV_LOITER_TURNS;
    let (requested, out) = upload(&mut p, GCS, &second, &c);

    assert_eq!(requested, vec![0, 1], "refused right after seq 1, nothing more requested");
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_UNSUPPORTED);
    assert_eq!((out.loaded, out.cleared), (None, false));
    assert!(!p.transfer_in_progress());
    assert_eq!((p.count(), p.mission_id()), (4, id_before));
    assert_eq!(format!("{:?}", p.items()), format!("{first:?}"));
    assert_eq!(to_plan(&second, &c), Err((1, R::MAV_MISSION_UNSUPPORTED)));
    // Items after the error are not part of any transfer.
    let late = p.handle(GCS, &MavMessage::MISSION_ITEM_INT(second[2].clone()), 1.0, &c);
    assert_eq!(only_ack(&late.replies, GCS).0, R::MAV_MISSION_ERROR);
}

#[test]
fn unsupported_frames_are_refused_with_unsupported_frame() {
    let f = frame();
    let c = ctx(&f);
    for frame_kind in
        [MavFrame::MAV_FRAME_LOCAL_NED, MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT, MavFrame::MAV_FRAME_MISSION]
    {
        let mut wp = waypoint(&f, 0, 10.0, 0.0, 20.0);
        wp.frame = frame_kind;
        assert_eq!(to_plan(&[wp.clone()], &c), Err((0, R::MAV_MISSION_UNSUPPORTED_FRAME)), "{frame_kind:?}");
        let mut p = MissionProtocol::new();
        let (_, out) = upload(&mut p, GCS, &[wp], &c);
        assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_UNSUPPORTED_FRAME);
        assert_eq!(p.count(), 0);
    }
    let mut rtl = item(0, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, MavFrame::MAV_FRAME_LOCAL_NED, 0, 0, 0.0);
    assert_eq!(to_plan(&[rtl.clone()], &c), Err((0, R::MAV_MISSION_UNSUPPORTED_FRAME)));
    rtl.frame = MavFrame::MAV_FRAME_MISSION;
    assert_eq!(to_plan(&[rtl], &c).map(|p| p.items), Ok(vec![MissionItem::ReturnToLaunch]));
}

#[test]
fn fence_and_rally_are_empty_plans_clients_can_list_clear_and_upload_empty() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    upload(&mut p, GCS, &mavsdk_mission(&f), &c);

    for kind in [T::MAV_MISSION_TYPE_FENCE, T::MAV_MISSION_TYPE_RALLY] {
        let out = p.handle(GCS, &count_msg_of(3, kind), 1.0, &c);
        assert_eq!(only_ack(&out.replies, GCS), (R::MAV_MISSION_UNSUPPORTED, kind, 0));
        assert!(!p.transfer_in_progress());

        // QGroundControl uploads an empty fence and rally plan after every mission.
        let out = p.handle(GCS, &count_msg_of(0, kind), 1.1, &c);
        assert_eq!(only_ack(&out.replies, GCS), (R::MAV_MISSION_ACCEPTED, kind, 0));
        assert!(!out.cleared);

        let out = p.handle(QGC, &request_list(kind), 1.2, &c);
        match out.replies.as_slice() {
            [MavMessage::MISSION_COUNT(m)] => {
                assert_eq!((m.count, m.mission_type, m.opaque_id), (0, kind, 0));
                assert_eq!((m.target_system, m.target_component), QGC);
            }
            other => panic!("expected MISSION_COUNT, got {other:?}"),
        }

        let out = p.handle(GCS, &clear_all(kind), 1.3, &c);
        assert_eq!(only_ack(&out.replies, GCS), (R::MAV_MISSION_ACCEPTED, kind, 0));
        assert!(!out.cleared, "clearing the fence leaves the mission alone");
    }
    assert_eq!(p.count(), 4);
}

#[test]
fn unanswered_request_is_resent_then_the_upload_is_cancelled() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();
    assert_eq!(only_request_int(&p.handle(GCS, &count(4), 0.0, &c).replies, GCS), 0);
    assert!(p.poll(0.1).is_empty(), "not before the retry timeout");

    // Item 0 arrives late, after one re-request: the retry budget starts over for item 1.
    assert_eq!(only_request_int(&p.poll(0.26), GCS), 0);
    assert_eq!(
        only_request_int(&p.handle(GCS, &MavMessage::MISSION_ITEM_INT(items[0].clone()), 0.3, &c).replies, GCS),
        1
    );
    assert!(p.poll(0.5).is_empty());

    let mut t = 0.3;
    for _ in 0..MAX_RETRIES {
        t += RETRY_TIMEOUT_S + 0.01;
        assert_eq!(only_request_int(&p.poll(t), GCS), 1);
    }
    t += RETRY_TIMEOUT_S + 0.01;
    assert_eq!(only_ack(&p.poll(t), GCS), (R::MAV_MISSION_OPERATION_CANCELLED, T::MAV_MISSION_TYPE_MISSION, 0));
    assert!(!p.transfer_in_progress());
    assert!(p.poll(t + 1.0).is_empty());
    assert_eq!(p.count(), 0, "nothing half-uploaded is kept");

    // The client's item after the cancel finds no transfer.
    let late = p.handle(GCS, &MavMessage::MISSION_ITEM_INT(items[1].clone()), t + 1.1, &c);
    assert_eq!(only_ack(&late.replies, GCS).0, R::MAV_MISSION_ERROR);
}

#[test]
fn amsl_frame_altitudes_are_converted_to_above_home() {
    let f = frame();
    let c = ctx(&f);
    let (x, y) = latlon_e7(&f, 30.0, -40.0);
    let takeoff =
        item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, MavFrame::MAV_FRAME_GLOBAL_INT, 0, 0, (HOME_AMSL_M + 12.0) as f32);
    let wp = item(1, MavCmd::MAV_CMD_NAV_WAYPOINT, MavFrame::MAV_FRAME_GLOBAL_INT, x, y, (HOME_AMSL_M + 30.0) as f32);
    let legacy_name =
        item(2, MavCmd::MAV_CMD_NAV_WAYPOINT, MavFrame::MAV_FRAME_GLOBAL, x, y, (HOME_AMSL_M + 35.5) as f32);

    let plan = to_plan(&[takeoff.clone(), wp, legacy_name], &c).unwrap();

    assert_eq!(plan.items[0], MissionItem::Takeoff { alt_rel_home_m: 12.0 });
    let MissionItem::Waypoint { target_en_m, alt_rel_home_m, .. } = plan.items[1] else { panic!("{:?}", plan.items) };
    assert_near(target_en_m, Vector2::new(30.0, -40.0), 0.1);
    assert!((alt_rel_home_m - 30.0).abs() < 1e-3, "{alt_rel_home_m}");
    let MissionItem::Waypoint { alt_rel_home_m, .. } = plan.items[2] else { panic!("{:?}", plan.items) };
    assert!((alt_rel_home_m - 35.5).abs() < 1e-3, "{alt_rel_home_m}");

    // A takeoff to an AMSL altitude below home is not a takeoff.
    let low = MISSION_ITEM_INT_DATA { z: (HOME_AMSL_M - 1.0) as f32, ..takeoff };
    assert_eq!(to_plan(&[low], &c), Err((0, R::MAV_MISSION_INVALID_PARAM7)));
}

#[test]
fn legacy_float_items_upload_and_download_in_the_legacy_form() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    let targets = [(50.0, 20.0, 15.0_f32), (-30.0, 80.0, 22.5)];
    let legacy: Vec<MISSION_ITEM_DATA> = targets
        .iter()
        .enumerate()
        .map(|(seq, &(e, n, alt))| {
            let g = f.to_geodetic(Enu::new(e, n, 0.0));
            MISSION_ITEM_DATA {
                param1: 2.0,
                param2: 1.0,
                param3: 0.0,
                param4: 0.0,
                x: g.latitude_deg as f32,
                y: g.longitude_deg as f32,
                z: alt,
                seq: seq as u16,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                target_system: 1,
                target_component: 1,
                frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
                current: 0,
                autocontinue: 1,
                mission_type: T::MAV_MISSION_TYPE_MISSION,
            }
        })
        .collect();

    assert_eq!(only_request_int(&p.handle(GCS, &count(2), 0.0, &c).replies, GCS), 0);
    let out = p.handle(GCS, &MavMessage::MISSION_ITEM(legacy[0].clone()), 0.01, &c);
    // PX4 answers a float client in its own form from then on.
    let [MavMessage::MISSION_REQUEST(r)] = out.replies.as_slice() else { panic!("{:?}", out.replies) };
    assert_eq!((r.seq, r.target_system, r.target_component), (1, GCS.0, GCS.1));
    // ... and re-sends that form on a timeout.
    assert!(matches!(p.poll(0.5).as_slice(), [MavMessage::MISSION_REQUEST(r)] if r.seq == 1));
    let out = p.handle(GCS, &MavMessage::MISSION_ITEM(legacy[1].clone()), 0.6, &c);
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_ACCEPTED);

    let plan = out.loaded.unwrap();
    for (got, m) in plan.items.iter().zip(&legacy) {
        // Expected from the float lat/lon the client sent (f32 resolves ~0.4 m here).
        let (e, n) = f.to_plane(f64::from(m.x), f64::from(m.y));
        let MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s } = got else { panic!("{got:?}") };
        assert_near(*target_en_m, Vector2::new(e, n), 0.1);
        assert_eq!((*alt_rel_home_m, *hold_s), (f64::from(m.z), 2.0));
    }

    for m in &legacy {
        let req = MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
            seq: m.seq,
            target_system: 1,
            target_component: 1,
            mission_type: T::MAV_MISSION_TYPE_MISSION,
        });
        let out = p.handle(QGC, &req, 1.0, &c);
        let [MavMessage::MISSION_ITEM(got)] = out.replies.as_slice() else { panic!("{:?}", out.replies) };
        assert_eq!((got.x, got.y, got.z, got.frame), (m.x, m.y, m.z, m.frame));
        assert_eq!((got.target_system, got.target_component, got.current), (QGC.0, QGC.1, u8::from(m.seq == 0)));
    }
}

#[test]
fn new_count_from_the_uploader_restarts_while_other_clients_are_refused() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();
    p.handle(GCS, &count(4), 0.0, &c);
    p.handle(GCS, &MavMessage::MISSION_ITEM_INT(items[0].clone()), 0.01, &c);
    p.handle(GCS, &MavMessage::MISSION_ITEM_INT(items[1].clone()), 0.02, &c);

    let other = p.handle(QGC, &count(2), 0.03, &c);
    assert_eq!(only_ack(&other.replies, QGC).0, R::MAV_MISSION_ERROR);
    let other = p.handle(QGC, &clear_all(T::MAV_MISSION_TYPE_MISSION), 0.03, &c);
    assert_eq!(only_ack(&other.replies, QGC).0, R::MAV_MISSION_ERROR);

    let shorter = [waypoint(&f, 0, 5.0, 5.0, 12.0), waypoint(&f, 1, 0.0, 0.0, 12.0)];
    let (requested, out) = upload(&mut p, GCS, &shorter, &c);
    assert_eq!(requested, vec![0, 1], "restarted from seq 0 with the new count");
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_ACCEPTED);
    assert_eq!(p.count(), 2);
}

#[test]
fn a_repeated_last_item_gets_the_lost_ack_again() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();
    let (_, out) = upload(&mut p, GCS, &items, &c);
    let first = only_ack(&out.replies, GCS);

    let again = p.handle(GCS, &MavMessage::MISSION_ITEM_INT(items[3].clone()), 1.0, &c);
    assert_eq!(only_ack(&again.replies, GCS), first);
    assert_eq!(again.loaded, None, "nothing is loaded twice");
    let not_last = p.handle(GCS, &MavMessage::MISSION_ITEM_INT(items[2].clone()), 1.1, &c);
    assert_eq!(only_ack(&not_last.replies, GCS).0, R::MAV_MISSION_ERROR);
}

#[test]
fn client_cancel_ends_the_upload_and_keeps_the_mission() {
    let f = frame();
    let c = ctx(&f);
    let items = mavsdk_mission(&f);
    let mut p = MissionProtocol::new();
    upload(&mut p, GCS, &items, &c);
    p.handle(GCS, &count(4), 1.0, &c);
    p.handle(GCS, &MavMessage::MISSION_ITEM_INT(waypoint(&f, 0, 1.0, 1.0, 5.0)), 1.01, &c);

    let out = p.handle(GCS, &client_ack(R::MAV_MISSION_OPERATION_CANCELLED, T::MAV_MISSION_TYPE_MISSION), 1.02, &c);
    assert!(out.replies.is_empty());
    assert!(!p.transfer_in_progress());
    assert!(p.poll(5.0).is_empty());
    assert_eq!(format!("{:?}", p.items()), format!("{items:?}"));
}

#[test]
fn client_refusing_int_requests_is_asked_in_the_float_form() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    p.handle(GCS, &count(1), 0.0, &c);
    let out = p.handle(GCS, &client_ack(R::MAV_MISSION_UNSUPPORTED, T::MAV_MISSION_TYPE_MISSION), 0.01, &c);
    assert!(matches!(out.replies.as_slice(), [MavMessage::MISSION_REQUEST(r)] if r.seq == 0));
}

#[test]
fn messages_for_other_systems_or_components_are_ignored() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    let other_system = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        target_system: 2,
        target_component: 1,
        count: 3,
        ..Default::default()
    });
    let other_component = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        target_system: 1,
        target_component: 100,
        count: 3,
        ..Default::default()
    });
    assert_eq!(p.handle(GCS, &other_system, 0.0, &c), MissionOutput::default());
    assert_eq!(p.handle(GCS, &other_component, 0.0, &c), MissionOutput::default());
    // Component 0 (all) addresses us.
    let all = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        target_system: 1,
        target_component: 0,
        count: 3,
        ..Default::default()
    });
    assert_eq!(only_request_int(&p.handle(GCS, &all, 0.0, &c).replies, GCS), 0);
}

#[test]
fn too_many_items_is_no_space() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    let out = p.handle(GCS, &count(MAX_MISSION_ITEMS + 1), 0.0, &c);
    assert_eq!(only_ack(&out.replies, GCS).0, R::MAV_MISSION_NO_SPACE);
    assert!(!p.transfer_in_progress());
}

#[test]
fn mission_current_reports_total_and_id_like_px4() {
    let f = frame();
    let c = ctx(&f);
    let mut p = MissionProtocol::new();
    let none = p.mission_current(0, MissionState::MISSION_STATE_NO_MISSION, 2);
    assert!(matches!(none, MavMessage::MISSION_CURRENT(m) if m.total == u16::MAX && m.mission_id == 0));
    upload(&mut p, GCS, &mavsdk_mission(&f), &c);
    let some = p.mission_current(2, MissionState::MISSION_STATE_ACTIVE, 1);
    let MavMessage::MISSION_CURRENT(m) = some else { panic!() };
    assert_eq!((m.seq, m.total, m.mission_id, m.mission_mode), (2, 4, p.mission_id(), 1));
    assert!(matches!(MissionProtocol::item_reached(3), MavMessage::MISSION_ITEM_REACHED(r) if r.seq == 3));
}

#[test]
fn opaque_id_changes_with_any_item_change() {
    let f = frame();
    let items = mavsdk_mission(&f);
    let mut moved = items.clone();
    moved[2].x += 1;
    let mut slower = items.clone();
    slower[1].param2 = 7.0;
    let ids = [opaque_id(&items), opaque_id(&moved), opaque_id(&slower), opaque_id(&items[..3])];
    for (i, a) in ids.iter().enumerate() {
        assert_ne!(*a, 0);
        for b in &ids[i + 1..] {
            assert_ne!(a, b);
        }
    }
    assert_eq!(opaque_id(&items), opaque_id(&items.clone()));
    // The CRC-32 check value.
    assert_eq!(crc32(0, b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(crc32(0, b"1234"), b"56789"), 0xCBF4_3926);
}

#[test]
fn takeoff_land_rtl_and_loiters_map_one_item_per_seq() {
    let f = frame();
    let c = ctx(&f);
    let rel = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
    let (x, y) = latlon_e7(&f, 40.0, 40.0);
    let (fx, fy) = latlon_e7(&f, 500.0, 0.0);
    let with = |mut it: MISSION_ITEM_INT_DATA, p1: f32| {
        it.param1 = p1;
        it
    };
    let items = [
        // Takeoff with a lat/lon (QGC fills one in): climbs in place.
        item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, rel, fx, fy, 20.0),
        with(item(1, MavCmd::MAV_CMD_NAV_LOITER_TIME, rel, x, y, 25.0), 7.5),
        with(item(2, MavCmd::MAV_CMD_NAV_LOITER_TIME, rel, 0, 0, 25.0), 3.0),
        // MAVSDK's land: at the previous waypoint's position.
        item(3, MavCmd::MAV_CMD_NAV_LAND, rel, x + 10, y - 10, 0.0),
        item(4, MavCmd::MAV_CMD_NAV_TAKEOFF, rel, 0, 0, 10.0),
        item(5, MavCmd::MAV_CMD_NAV_LOITER_UNLIM, rel, i32::MAX, i32::MAX, 10.0),
        item(6, MavCmd::MAV_CMD_NAV_LAND, rel, 0, 0, 0.0),
        item(7, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, MavFrame::MAV_FRAME_MISSION, 0, 0, 0.0),
    ];
    let plan = to_plan(&items, &c).unwrap();
    assert_eq!(plan.items.len(), items.len());
    assert_eq!(plan.items[0], MissionItem::Takeoff { alt_rel_home_m: 20.0 });
    let MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s } = plan.items[1] else { panic!() };
    assert_near(target_en_m, Vector2::new(40.0, 40.0), 0.1);
    assert_eq!((alt_rel_home_m, hold_s), (25.0, 7.5));
    assert_eq!(plan.items[2], MissionItem::Loiter { hold_s: 3.0 });
    assert_eq!(plan.items[3], MissionItem::Land);
    assert_eq!(plan.items[5], MissionItem::Loiter { hold_s: HOLD_FOREVER_S });
    assert_eq!(plan.items[6], MissionItem::Land);
    assert_eq!(plan.items[7], MissionItem::ReturnToLaunch);

    // A landing point away from where the drone is would be flown wrongly: refused.
    let far_land = [waypoint(&f, 0, 40.0, 40.0, 20.0), item(1, MavCmd::MAV_CMD_NAV_LAND, rel, fx, fy, 0.0)];
    assert_eq!(to_plan(&far_land, &c), Err((1, R::MAV_MISSION_INVALID_PARAM5_X)));
    let unlim_at = [item(0, MavCmd::MAV_CMD_NAV_LOITER_UNLIM, rel, x, y, 12.0)];
    assert!(matches!(to_plan(&unlim_at, &c).unwrap().items[0], MissionItem::Waypoint { hold_s: HOLD_FOREVER_S, .. }));
    // Serialised plans keep a forever hold (JSON has no infinity).
    let plan = to_plan(&unlim_at, &c).unwrap();
    let json = serde_json::to_string(&plan).unwrap();
    assert_eq!(serde_json::from_str::<MissionPlan>(&json).unwrap(), plan);
}

#[test]
fn change_speed_keeps_no_change_and_default_meanings() {
    let f = frame();
    let c = ctx(&f);
    let speed = |seq, kind: f32, v: f32| MISSION_ITEM_INT_DATA { param1: kind, ..change_speed(seq, v) };
    let items = [
        speed(0, 1.0, 9.0),
        speed(1, 1.0, -1.0), // no change: still 9
        speed(2, 0.0, -2.0), // back to the default 5
        speed(3, 2.0, 3.0),  // climb speed: horizontal speed unchanged
        speed(4, f32::NAN, 6.5),
    ];
    let plan = to_plan(&items, &c).unwrap();
    let speeds: Vec<_> = plan
        .items
        .iter()
        .map(|i| match i {
            MissionItem::ChangeSpeed { speed_mps } => *speed_mps,
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(speeds, vec![9.0, 9.0, 5.0, 5.0, 6.5]);
    assert_eq!(plan.speed_mps, 5.0);
    assert_eq!(to_plan(&[speed(0, 7.0, 3.0)], &c), Err((0, R::MAV_MISSION_INVALID_PARAM1)));
    assert_eq!(to_plan(&[speed(0, 1.0, -5.0)], &c), Err((0, R::MAV_MISSION_INVALID_PARAM2)));
    assert_eq!(to_plan(&[speed(0, 1.0, f32::NAN)], &c), Err((0, R::MAV_MISSION_INVALID_PARAM2)));
}

#[test]
fn invalid_coordinates_and_parameters_name_the_parameter() {
    let f = frame();
    let c = ctx(&f);
    let wp = waypoint(&f, 0, 10.0, 10.0, 20.0);
    let cases = [
        (MISSION_ITEM_INT_DATA { x: 910_000_000, ..wp.clone() }, R::MAV_MISSION_INVALID_PARAM5_X),
        (MISSION_ITEM_INT_DATA { x: i32::MAX, ..wp.clone() }, R::MAV_MISSION_INVALID_PARAM5_X),
        (MISSION_ITEM_INT_DATA { y: -1_810_000_000, ..wp.clone() }, R::MAV_MISSION_INVALID_PARAM6_Y),
        (MISSION_ITEM_INT_DATA { z: f32::NAN, ..wp.clone() }, R::MAV_MISSION_INVALID_PARAM7),
        (MISSION_ITEM_INT_DATA { z: f32::INFINITY, ..wp.clone() }, R::MAV_MISSION_INVALID_PARAM7),
        (MISSION_ITEM_INT_DATA { param1: -1.0, ..wp.clone() }, R::MAV_MISSION_INVALID_PARAM1),
        (
            MISSION_ITEM_INT_DATA { command: MavCmd::MAV_CMD_NAV_LOITER_TIME, param1: f32::NAN, ..wp.clone() },
            R::MAV_MISSION_INVALID_PARAM1,
        ),
        (
            MISSION_ITEM_INT_DATA { command: MavCmd::MAV_CMD_DO_SET_ROI_LOCATION, ..wp.clone() },
            R::MAV_MISSION_UNSUPPORTED,
        ),
        (MISSION_ITEM_INT_DATA { command: MavCmd::MAV_CMD_DO_JUMP, ..wp.clone() }, R::MAV_MISSION_UNSUPPORTED),
    ];
    for (it, want) in cases {
        let prefix = waypoint(&f, 0, 0.0, 0.0, 10.0);
        assert_eq!(to_plan(&[prefix, MISSION_ITEM_INT_DATA { seq: 1, ..it.clone() }], &c), Err((1, want)), "{it:?}");
    }
    // A NaN hold on a waypoint is MAVSDK's "no hold".
    let nan_hold = MISSION_ITEM_INT_DATA { param1: f32::NAN, ..wp };
    assert!(matches!(to_plan(&[nan_hold], &c).unwrap().items[0], MissionItem::Waypoint { hold_s: 0.0, .. }));
}

#[test]
fn nav_delay_waits_where_the_drone_is_and_the_time_of_day_form_is_refused() {
    let f = frame();
    let c = ctx(&f);
    let mut delay = item(1, MavCmd::MAV_CMD_NAV_DELAY, MavFrame::MAV_FRAME_MISSION, 0, 0, 0.0);
    delay.param1 = 4.0;
    let items = vec![waypoint(&f, 0, 10.0, 10.0, 20.0), delay.clone()];
    let plan = to_plan(&items, &c).unwrap();
    assert_eq!(plan.items[1], MissionItem::Loiter { hold_s: 4.0 });
    delay.param1 = -1.0; // "at a time of day"
    assert_eq!(to_plan(&[delay], &c), Err((0, R::MAV_MISSION_INVALID_PARAM1)));
}
