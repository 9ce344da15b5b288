use proptest::prelude::*;

use super::*;
use sadesim_engine::events::EventKind;

/// A drone with every optional part present, and numbers JSON would have to get exactly
/// right too: negative zero, subnormals, the extremes, a sum with no short decimal.
fn full_drone(index: u32) -> DroneSnapshot {
    let mut d = DroneSnapshot::climbing(index, 12.5, 3.0);
    d.position_enu_m = [-0.0, 0.1 + 0.2, f64::MAX];
    d.velocity_enu_mps = [f64::MIN_POSITIVE / 4.0, -1e-300, 7.0];
    d.mode = FlightMode::ReturnToLaunch;
    d.crashed = true;
    d.position_valid = true;
    d.battery_remaining = 0.731_234_567_89;
    d.detail = DroneDetail {
        rate_body_rps: [0.01, -0.02, 0.03],
        estimate: Some(EstimateDetail {
            position_enu_m: [1.0, 2.0, 3.0],
            velocity_enu_mps: [4.0, 5.0, 6.0],
            attitude_wxyz: [0.5, 0.5, -0.5, 0.5],
            eph_m: 0.8,
            epv_m: 1.6,
        }),
        gnss: Some(GnssDetail {
            time_s: 2.8,
            position_enu_m: [1.1, 2.1, 3.1],
            velocity_enu_mps: [0.0, 0.1, -0.1],
            fix_type: 3,
            satellites: 17,
            eph_m: Some(0.7),
            epv_m: None,
            hdop: Some(0.9),
            vdop: None,
            sky: Some(SkyDetail { above_mask: 21, line_of_sight: 14, reflected: 3 }),
        }),
        motor_commands: [0.61, 0.62, 0.63, 0.64, 0.0, 0.0, 0.0, 0.0],
        motor_count: 4,
        battery_voltage_v: 15.9,
        battery_current_a: 21.3,
        battery_consumed_mah: 412.25,
        wind_enu_mps: [3.0, -1.0, 0.2],
        local_origin_enu_m: [12.5, 0.0, 0.0],
    };
    d
}

/// A window of three drones (everything present, a GNSS output without a fix or sky,
/// nothing optional at all) and two events.
fn window() -> FromShard {
    let mut no_fix = full_drone(8);
    no_fix.detail.estimate = None;
    let gnss = no_fix.detail.gnss.as_mut().unwrap();
    (gnss.fix_type, gnss.eph_m, gnss.hdop, gnss.sky) = (1, None, None, None);
    let bare = DroneSnapshot::climbing(9, 0.0, 0.5);
    FromShard::Advanced {
        shard: 2,
        step: 123_456_789_012,
        ready: true,
        drones: vec![full_drone(7), no_fix, bare],
        events: vec![
            Event { time_s: 1.25, drone: Some(7), kind: EventKind::Takeoff },
            Event { time_s: 1.26, drone: None, kind: EventKind::PilotsReleased },
        ],
    }
}

fn encoded(msg: &impl Wire) -> Vec<u8> {
    let mut out = Vec::new();
    msg.encode(&mut out);
    out
}

#[test]
fn a_window_comes_back_exactly_as_it_was_sent() {
    let sent = window();
    let bytes = encoded(&sent);
    assert_eq!(bytes[0], b'W');
    let back = FromShard::decode(&bytes).unwrap();
    assert_eq!(back, sent);
    // Bit for bit, negative zero and subnormals included (== alone would let -0.0 be 0.0).
    let (FromShard::Advanced { drones: a, .. }, FromShard::Advanced { drones: b, .. }) = (&back, &sent) else {
        unreachable!()
    };
    for (x, y) in a.iter().zip(b) {
        let bits = |d: &DroneSnapshot| {
            d.position_enu_m.iter().chain(&d.velocity_enu_mps).map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(bits(x), bits(y));
    }
    // About half the JSON line it replaces, and no number to parse.
    let json = serde_json::to_vec(&sent).unwrap();
    assert!(bytes.len() * 5 < json.len() * 3, "{} bytes binary, {} JSON", bytes.len(), json.len());
}

#[test]
fn a_window_without_events_or_drones_comes_back_too() {
    let sent = FromShard::Advanced { shard: 0, step: 10, ready: false, drones: vec![], events: vec![] };
    assert_eq!(FromShard::decode(&encoded(&sent)).unwrap(), sent);
}

#[test]
fn every_other_message_comes_back() {
    for sent in [
        ToShard::Advance { until_step: 40, release_pilots: false, leases: None },
        ToShard::Advance { until_step: u64::MAX, release_pilots: true, leases: Some(vec![]) },
        ToShard::Advance { until_step: 50, release_pilots: false, leases: Some(vec![[3, 0], [4_000_000, 2]]) },
        ToShard::Stop,
    ] {
        assert_eq!(ToShard::decode(&encoded(&sent)).unwrap(), sent);
    }
    for sent in [
        FromShard::Hello { version: sadesim_engine::protocol::PROTOCOL_VERSION, shard: 3, drones: 100 },
        FromShard::Stopped { shard: 1 },
        FromShard::Failed { shard: 1, reason: "drone 4: NaN in the state".into() },
    ] {
        let bytes = encoded(&sent);
        assert_eq!(bytes[0], b'J');
        assert_eq!(FromShard::decode(&bytes).unwrap(), sent);
    }
}

#[test]
fn every_flight_mode_has_the_code_of_its_place() {
    for (code, mode) in MODES.iter().enumerate() {
        assert_eq!(usize::from(mode_code(*mode)), code, "{mode:?}");
        let mut d = full_drone(0);
        d.mode = *mode;
        let msg = FromShard::Advanced { shard: 0, step: 1, ready: true, drones: vec![d], events: vec![] };
        assert_eq!(FromShard::decode(&encoded(&msg)).unwrap(), msg);
    }
    assert_eq!(mode_of(MODES.len() as u8), None);
}

#[test]
fn a_truncated_message_is_refused_at_every_length_naming_the_byte() {
    let bytes = encoded(&window());
    for n in 0..bytes.len() {
        let err = FromShard::decode(&bytes[..n]).expect_err("truncated");
        let named = err.starts_with("byte ") || err.starts_with("drones[");
        assert!(named && (err.contains(" more expected") || err.contains("does not fit")), "at {n}: {err}");
    }
    // Inside a drone: the header is 18 bytes, and the drone's GNSS accuracy flag is its
    // 283rd byte (index, 11 state doubles, mode, flags, battery, rates, the estimate, the
    // GNSS time, position, velocity, fix type and satellites before it).
    let one = FromShard::Advanced { shard: 0, step: 1, ready: true, drones: vec![full_drone(0)], events: vec![] };
    let err = FromShard::decode(&encoded(&one)[..300]).unwrap_err();
    assert_eq!(err, "drones[0]: byte 300: detail.gnss.ephM: the message ends after 300 bytes, 1 more expected");
}

#[test]
fn bad_bytes_are_named() {
    let good = encoded(&window());
    let estimate_flag = 1 + 4 + 8 + 1 + 4 + (4 + 11 * 8 + 2 + 8 + 3 * 8);
    assert_eq!(good[estimate_flag], 1, "the first drone's estimate flag");

    let mut bad = good.clone();
    bad[estimate_flag] = 7;
    let err = FromShard::decode(&bad).unwrap_err();
    assert_eq!(err, format!("drones[0]: byte {estimate_flag}: detail.estimate: expected a flag (0 or 1), found 7"));

    let mode = 1 + 4 + 8 + 1 + 4 + 4 + 11 * 8;
    let mut bad = good.clone();
    bad[mode] = 200;
    assert_eq!(
        FromShard::decode(&bad).unwrap_err(),
        format!("drones[0]: byte {mode}: mode: no flight mode has code 200")
    );
    let mut bad = good.clone();
    bad[mode + 1] = 0x30;
    assert_eq!(
        FromShard::decode(&bad).unwrap_err(),
        format!("drones[0]: byte {}: flags: unknown bits in 0x30", mode + 1)
    );

    // A drone count the payload cannot hold is refused before anything is allocated.
    let mut bad = good.clone();
    bad[14..18].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = FromShard::decode(&bad).unwrap_err();
    assert!(err.starts_with("byte 14: drones: a count of 4294967295 does not fit"), "{err}");

    let mut bad = good.clone();
    bad.push(0);
    assert_eq!(
        FromShard::decode(&bad).unwrap_err(),
        format!("byte {}: 1 bytes after the end of the message", good.len())
    );

    let err = FromShard::decode(b"X").unwrap_err();
    assert_eq!(err, "byte 0: kind: expected 'A', 'W' or 'J', found 0x58");
}

#[test]
fn a_json_line_from_an_older_peer_is_refused_saying_so() {
    let line = serde_json::to_vec(&FromShard::Hello { version: 3, shard: 0, drones: 4 }).unwrap();
    let err = FromShard::decode(&line).unwrap_err();
    assert!(
        err.contains("found 0x7b (a JSON line: the peer speaks the shard protocol of sadesim before version 4"),
        "{err}"
    );
}

#[test]
fn a_json_error_quoting_a_line_break_is_one_line() {
    // Found by fuzz/fuzz_targets/shard_wire.rs: serde_json quotes an unknown variant as the
    // peer wrote it, and a `\n` escape in it made the error two lines.
    let err = ToShard::decode(b"J{\"type\":\"[\\n[\"}").unwrap_err();
    assert!(err.starts_with("byte 1: message: unknown variant `[\\n[`, expected one of `advance`"), "{err}");
    assert!(!err.contains('\n'), "{err}");
    let err = FromShard::decode(b"J{\"type\":\"a\\nb\"}").unwrap_err();
    assert!(!err.contains('\n') && err.contains("`a\\nb`"), "{err}");
}

proptest! {
    /// Whatever arrives, decoding answers (a message or an error), never panics.
    #[test]
    fn any_bytes_decode_or_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..600), flip in 0usize..2000, to in any::<u8>()) {
        let _ = FromShard::decode(&bytes);
        let _ = ToShard::decode(&bytes);
        // And a valid window with one byte changed.
        let mut window = encoded(&window());
        let at = flip % window.len();
        window[at] = to;
        let _ = FromShard::decode(&window);
    }
}
