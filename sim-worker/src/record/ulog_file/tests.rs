use std::collections::HashMap;

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::geo::{Enu, LocalFrame};

use super::topics::*;
use super::writer::{LogLevel, MAGIC, ParamValue, UlogWriter};
use super::*;
use sadesim_engine::events::FlightMode;
use sadesim_engine::fixtures::plan_of;
use sadesim_engine::protocol::{DroneDetail, EstimateDetail, GnssDetail};

// ---------------------------------------------------------------------------------------
// A small, strict ULog reader: enough to check what the writer produced byte by byte.

#[derive(Debug, Default)]
struct Parsed {
    start_us: u64,
    /// Format name -> fields (type, name, offset, size).
    formats: HashMap<String, Vec<Field>>,
    /// Info key -> (type, value bytes).
    info: HashMap<String, (String, Vec<u8>)>,
    params: HashMap<String, ParamValue>,
    /// msg_id -> format name.
    subscriptions: HashMap<u16, String>,
    /// (msg_id, payload without the id), in file order.
    data: Vec<(u16, Vec<u8>)>,
    logs: Vec<(u8, u64, String)>,
}

#[derive(Clone, Debug)]
struct Field {
    ty: String,
    name: String,
    offset: usize,
    size: usize,
}

fn base_size(ty: &str) -> usize {
    match ty {
        "int8_t" | "uint8_t" | "bool" | "char" => 1,
        "int16_t" | "uint16_t" => 2,
        "int32_t" | "uint32_t" | "float" => 4,
        "int64_t" | "uint64_t" | "double" => 8,
        other => panic!("unknown ULog type {other}"),
    }
}

/// `float[4]` -> ("float", 4 elements).
fn type_size(ty: &str) -> usize {
    match ty.split_once('[') {
        Some((base, n)) => base_size(base) * n.trim_end_matches(']').parse::<usize>().expect("array length"),
        None => base_size(ty),
    }
}

fn parse(bytes: &[u8]) -> Parsed {
    assert_eq!(&bytes[..7], &MAGIC, "magic");
    assert_eq!(bytes[7], 1, "version");
    let mut p = Parsed { start_us: u64::from_le_bytes(bytes[8..16].try_into().unwrap()), ..Default::default() };
    let mut at = 16;
    let mut first = true;
    while at < bytes.len() {
        assert!(at + 3 <= bytes.len(), "truncated message header at byte {at}");
        let size = usize::from(u16::from_le_bytes([bytes[at], bytes[at + 1]]));
        let kind = bytes[at + 2];
        let body = &bytes[at + 3..at + 3 + size];
        at += 3 + size;
        if first {
            assert_eq!((kind, size), (b'B', 40), "flag bits must follow the header");
            assert!(body.iter().all(|&b| b == 0), "no flags set");
            first = false;
            continue;
        }
        match kind {
            b'F' => {
                let text = std::str::from_utf8(body).unwrap();
                let (name, rest) = text.split_once(':').expect("name:fields");
                let mut offset = 0;
                let mut fields = Vec::new();
                for decl in rest.split(';').filter(|d| !d.is_empty()) {
                    let (ty, field) = decl.split_once(' ').expect("type name");
                    let size = type_size(ty);
                    fields.push(Field { ty: ty.into(), name: field.into(), offset, size });
                    offset += size;
                }
                assert_eq!((fields[0].ty.as_str(), fields[0].name.as_str()), ("uint64_t", "timestamp"));
                assert!(p.formats.insert(name.into(), fields).is_none(), "format {name} defined twice");
            }
            b'I' | b'P' => {
                let key_len = usize::from(body[0]);
                let key = std::str::from_utf8(&body[1..1 + key_len]).unwrap();
                let (ty, name) = key.split_once(' ').unwrap();
                let value = body[1 + key_len..].to_vec();
                if let Some(n) = ty.strip_prefix("char[") {
                    assert_eq!(n.trim_end_matches(']').parse::<usize>().unwrap(), value.len(), "{name} length");
                } else {
                    assert_eq!(type_size(ty), value.len(), "{name} size");
                }
                if kind == b'I' {
                    p.info.insert(name.into(), (ty.into(), value));
                } else {
                    let v = match ty {
                        "int32_t" => ParamValue::Int32(i32::from_le_bytes(value.try_into().unwrap())),
                        "float" => ParamValue::Float(f32::from_le_bytes(value.try_into().unwrap())),
                        other => panic!("parameter type {other}"),
                    };
                    p.params.insert(name.into(), v);
                }
            }
            b'A' => {
                assert_eq!(body[0], 0, "multi_id");
                let id = u16::from_le_bytes([body[1], body[2]]);
                let name = std::str::from_utf8(&body[3..]).unwrap();
                assert!(p.formats.contains_key(name), "subscription to undefined format {name}");
                p.subscriptions.insert(id, name.into());
            }
            b'D' => {
                let id = u16::from_le_bytes([body[0], body[1]]);
                let name = p.subscriptions.get(&id).unwrap_or_else(|| panic!("data for unsubscribed id {id}"));
                let size: usize = p.formats[name].iter().map(|f| f.size).sum();
                assert_eq!(body.len() - 2, size, "data size of {name} must match its format");
                p.data.push((id, body[2..].to_vec()));
            }
            b'L' => {
                let ts = u64::from_le_bytes(body[1..9].try_into().unwrap());
                p.logs.push((body[0], ts, String::from_utf8(body[9..].to_vec()).unwrap()));
            }
            other => panic!("unexpected message type {}", other as char),
        }
    }
    assert!(!first, "no flag bits message");
    p
}

impl Parsed {
    fn samples(&self, topic: &str) -> Vec<Sample<'_>> {
        let fields = &self.formats[topic];
        let id = self.subscriptions.iter().find(|(_, n)| *n == topic).map(|(id, _)| *id).expect("subscribed");
        self.data.iter().filter(|(i, _)| *i == id).map(|(_, bytes)| Sample { fields, bytes }).collect()
    }

    fn info_str(&self, key: &str) -> String {
        String::from_utf8(self.info[key].1.clone()).unwrap()
    }
}

struct Sample<'a> {
    fields: &'a [Field],
    bytes: &'a [u8],
}

impl Sample<'_> {
    fn raw(&self, name: &str) -> (&str, &[u8]) {
        let (base, index) = match name.split_once('[') {
            Some((b, i)) => (b, Some(i.trim_end_matches(']').parse::<usize>().unwrap())),
            None => (name, None),
        };
        let f = self.fields.iter().find(|f| f.name == base).unwrap_or_else(|| panic!("no field {name}"));
        let ty = f.ty.split('[').next().unwrap();
        let size = base_size(ty);
        let offset = f.offset + index.unwrap_or(0) * size;
        (ty, &self.bytes[offset..offset + size])
    }

    /// Any numeric field as f64.
    fn get(&self, name: &str) -> f64 {
        let (ty, b) = self.raw(name);
        match ty {
            "uint8_t" | "bool" => f64::from(b[0]),
            "uint16_t" => f64::from(u16::from_le_bytes(b.try_into().unwrap())),
            "uint32_t" => f64::from(u32::from_le_bytes(b.try_into().unwrap())),
            "int32_t" => f64::from(i32::from_le_bytes(b.try_into().unwrap())),
            "uint64_t" => u64::from_le_bytes(b.try_into().unwrap()) as f64,
            "float" => f64::from(f32::from_le_bytes(b.try_into().unwrap())),
            "double" => f64::from_le_bytes(b.try_into().unwrap()),
            other => panic!("type {other}"),
        }
    }

    fn timestamp(&self) -> u64 {
        u64::from_le_bytes(self.raw("timestamp").1.try_into().unwrap())
    }
}

// ---------------------------------------------------------------------------------------
// The byte-level writer.

#[test]
fn header_is_magic_version_timestamp_then_flag_bits() {
    let w = UlogWriter::new(Vec::new(), 0x0102_0304_0506_0708).unwrap();
    let bytes = w.into_inner();
    assert_eq!(&bytes[..8], b"ULog\x01\x12\x35\x01");
    assert_eq!(&bytes[8..16], &0x0102_0304_0506_0708u64.to_le_bytes());
    // msg_size 40, type 'B', 40 zero bytes.
    assert_eq!(&bytes[16..19], &[40, 0, b'B']);
    assert_eq!(bytes.len(), 16 + 3 + 40);
}

/// A message half written when the disk filled: once there is room, the file is cut back
/// to its last whole message and reads whole, with every message written before.
#[test]
fn a_message_cut_by_a_full_disk_is_cut_off_once_there_is_room() {
    use crate::record::disk::FillingDisk;
    let mut w = UlogWriter::new(FillingDisk::with_room(3000), 5).unwrap();
    w.format("vehicle_attitude", &VehicleAttitude::fields()).unwrap();
    w.add_logged(0, 3, "vehicle_attitude").unwrap();
    let mut buf = Vec::new();
    let mut written = 0u64;
    let error = loop {
        buf.clear();
        VehicleAttitude { timestamp: written + 1, ..Default::default() }.encode(&mut buf);
        match w.data(3, &buf) {
            Ok(()) => written += 1,
            Err(e) => break e,
        }
    };
    assert_eq!(error.raw_os_error(), Some(28));
    assert!(w.written() < 3000, "part of the last message reached the disk, beyond the whole ones");
    let w = w.cut_back(|disk, len| disk.freed(1 << 20, len)).unwrap();
    let p = parse(&w.into_inner().bytes);
    let samples = p.samples("vehicle_attitude");
    assert_eq!(samples.len() as u64, written);
    assert_eq!(samples.last().unwrap().timestamp(), written);
}

#[test]
fn messages_round_trip_through_the_reader() {
    let mut w = UlogWriter::new(Vec::new(), 5).unwrap();
    w.format("vehicle_attitude", &VehicleAttitude::fields()).unwrap();
    w.info_str("sys_name", "SADE-SIM").unwrap();
    w.info_i32("time_ref_utc", -3600).unwrap();
    w.parameter("SYS_AUTOSTART", ParamValue::Int32(4001)).unwrap();
    w.parameter("MPC_XY_CRUISE", ParamValue::Float(8.5)).unwrap();
    w.add_logged(0, 3, "vehicle_attitude").unwrap();
    let mut buf = Vec::new();
    VehicleAttitude { timestamp: 42, q: [1.0, 0.0, 0.0, 0.5], ..Default::default() }.encode(&mut buf);
    w.data(3, &buf).unwrap();
    w.log(LogLevel::Warning, 43, "battery low").unwrap();
    let p = parse(&w.into_inner());

    assert_eq!(p.start_us, 5);
    assert_eq!(p.info_str("sys_name"), "SADE-SIM");
    assert_eq!(p.info["time_ref_utc"], ("int32_t".to_string(), (-3600i32).to_le_bytes().to_vec()));
    assert_eq!(p.params["SYS_AUTOSTART"], ParamValue::Int32(4001));
    assert_eq!(p.params["MPC_XY_CRUISE"], ParamValue::Float(8.5));
    let s = p.samples("vehicle_attitude");
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].timestamp(), 42);
    assert_eq!((s[0].get("q[0]"), s[0].get("q[3]")), (1.0, 0.5));
    assert_eq!(p.logs, vec![(b'4', 43, "battery low".to_string())]);
}

#[test]
fn every_topic_encodes_exactly_its_format_size() {
    fn check<T: Topic + Default>() {
        let declared: usize = T::fields().iter().map(|(ty, _)| type_size(ty)).sum();
        let mut buf = Vec::new();
        T::default().encode(&mut buf);
        assert_eq!(buf.len(), declared, "{:?}", T::fields());
        assert_eq!(T::fields()[0], ("uint64_t".to_string(), "timestamp"));
    }
    check::<VehicleLocalPosition>();
    check::<VehicleGlobalPosition>();
    check::<VehicleAttitude>();
    check::<SensorGps>();
    check::<BatteryStatus>();
    check::<VehicleStatus>();
    check::<ActuatorOutputs>();
}

#[test]
fn px4_field_types_are_spelled_as_ulog_expects() {
    let fields: HashMap<_, _> = VehicleLocalPosition::fields().into_iter().map(|(t, n)| (n, t)).collect();
    assert_eq!(fields["ref_lat"], "double");
    assert_eq!(fields["x"], "float");
    assert_eq!(fields["delta_xy"], "float[2]");
    assert_eq!(fields["xy_valid"], "bool");
    assert_eq!(fields["xy_reset_counter"], "uint8_t");
    let fields: HashMap<_, _> = ActuatorOutputs::fields().into_iter().map(|(t, n)| (n, t)).collect();
    assert_eq!((fields["noutputs"].as_str(), fields["output"].as_str()), ("uint32_t", "float[16]"));
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    let mut w = UlogWriter::new(Vec::new(), 1).unwrap();
    let err = w.format("bad name", &VehicleAttitude::fields()).unwrap_err();
    assert!(err.to_string().contains("format name `bad name`"), "{err}");
    let err = w.format("no_timestamp", &[("float".into(), "x")]).unwrap_err();
    assert!(err.to_string().contains("uint64_t timestamp"), "{err}");
    let err = w.parameter("A_VERY_LONG_PARAMETER", ParamValue::Int32(1)).unwrap_err();
    assert!(err.to_string().contains("16 characters"), "{err}");
    let err = w.log(LogLevel::Info, 1, &"x".repeat(70_000)).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    assert!(err.to_string().contains("65535"), "{err}");
}

// ---------------------------------------------------------------------------------------
// Conversions.

#[test]
fn flight_modes_map_to_px4_navigation_states() {
    assert_eq!(nav_state(FlightMode::Takeoff), 17);
    assert_eq!(nav_state(FlightMode::Mission), 3);
    assert_eq!(nav_state(FlightMode::Hold), 4);
    assert_eq!(nav_state(FlightMode::Idle), 4);
    assert_eq!(nav_state(FlightMode::ReturnToLaunch), 5);
    assert_eq!(nav_state(FlightMode::Land), 18);
    assert_eq!(nav_state(FlightMode::Offboard), 14);
}

/// Body FLU -> ENU for a level drone whose nose points `yaw_enu` from east, counter-clockwise.
fn level_yaw(yaw_enu_rad: f64) -> [f64; 4] {
    [(yaw_enu_rad / 2.0).cos(), 0.0, 0.0, (yaw_enu_rad / 2.0).sin()]
}

#[test]
fn attitude_converts_to_frd_to_ned() {
    let close = |a: [f64; 4], b: [f64; 4]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
    // Nose east in ENU = heading 90 deg in NED: rotation of +90 deg about down.
    let h = std::f64::consts::FRAC_PI_4;
    assert!(close(q_ned_frd(level_yaw(0.0)), [h.cos(), 0.0, 0.0, h.sin()]), "{:?}", q_ned_frd(level_yaw(0.0)));
    // Nose north = heading 0 = identity.
    assert!(close(q_ned_frd(level_yaw(std::f64::consts::FRAC_PI_2)), [1.0, 0.0, 0.0, 0.0]));
    // Rolled right 10 deg (right side down) while facing north: +10 deg about the forward
    // axis in FLU (left side up) and in FRD (right side down) alike.
    let r = 10f64.to_radians() / 2.0;
    let q_flu = {
        let [w, x, y, z] = level_yaw(std::f64::consts::FRAC_PI_2);
        // yaw(90 deg) * roll(+10 deg about body x)
        let (rw, rx) = (r.cos(), r.sin());
        [w * rw - x * rx, w * rx + x * rw, y * rw + z * rx, z * rw - y * rx]
    };
    assert!(close(q_ned_frd(q_flu), [r.cos(), r.sin(), 0.0, 0.0]), "{:?}", q_ned_frd(q_flu));
}

// ---------------------------------------------------------------------------------------
// The recorder over synthetic snapshots.

use crate::record::test_dir::TempDir;

const ORIGIN_0: [f64; 3] = [10.0, -20.0, 0.3];

/// Drone `index` at `t`: flies east at 2 m/s and climbs at 1 m/s from its origin, nose
/// north; the estimate is 0.5 m north of the truth from t = 0.5 s; GNSS at 5 Hz from t = 0.
fn snapshot(index: u32, t: f64) -> DroneSnapshot {
    let origin = if index == 0 { ORIGIN_0 } else { [0.0, 0.0, 0.3] };
    let p = [origin[0] + 2.0 * t, origin[1], origin[2] + t];
    let fix_t = (t * 5.0).floor() / 5.0;
    let q = level_yaw(std::f64::consts::FRAC_PI_2);
    DroneSnapshot {
        index,
        position_enu_m: p,
        velocity_enu_mps: [2.0, 0.0, 1.0],
        attitude_wxyz: q,
        height_agl_m: p[2],
        mode: if t < 1.0 { FlightMode::Takeoff } else { FlightMode::Mission },
        armed: true,
        on_ground: t < 0.2,
        crashed: false,
        battery_remaining: 1.0 - 0.01 * t,
        position_valid: t >= 0.5,
        detail: DroneDetail {
            estimate: (t >= 0.5).then(|| EstimateDetail {
                position_enu_m: [p[0], p[1] + 0.5, p[2]],
                velocity_enu_mps: [2.0, 0.0, 1.0],
                attitude_wxyz: q,
                eph_m: 0.4,
                epv_m: 0.6,
            }),
            gnss: Some(GnssDetail {
                time_s: fix_t,
                position_enu_m: [origin[0] + 2.0 * fix_t, origin[1], origin[2] + fix_t],
                velocity_enu_mps: [2.0, 0.0, 1.0],
                fix_type: 3,
                satellites: 12,
                eph_m: Some(0.5),
                epv_m: Some(0.8),
                hdop: Some(0.9),
                vdop: Some(1.2),
                sky: None,
            }),
            motor_commands: [0.5, 0.6, 0.7, 0.8, 0.0, 0.0, 0.0, 0.0],
            motor_count: 4,
            battery_voltage_v: 16.0 - t,
            battery_current_a: 20.0,
            battery_consumed_mah: 5.0 * t,
            local_origin_enu_m: origin,
            ..Default::default()
        },
    }
}

#[test]
fn synthetic_flight_round_trips_with_rates_frames_and_events() {
    let tmp = TempDir::new("round-trip");
    let plan = plan_of(RunBuilder::test().with_drones(2).build());
    let rates = plan.spec.recording().rates;
    let mut rec = UlogRecorder::create(&tmp.0, &plan).unwrap();
    let duration_s = 2.0;
    let windows = 200; // 10 ms
    for k in 1..=windows {
        let t = f64::from(k) / 100.0;
        let drones = [snapshot(0, t), snapshot(1, t)];
        let mut events = Vec::new();
        if k == 100 {
            let kind = EventKind::ModeChanged { from: FlightMode::Takeoff, to: FlightMode::Mission };
            events.push(Event { time_s: t - 0.005, drone: Some(0), kind });
        }
        if k == 150 {
            let kind = EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land };
            events.push(Event { time_s: t, drone: Some(1), kind });
        }
        rec.write_window(t, &drones, &events).unwrap();
    }
    let end = [Event { time_s: duration_s, drone: None, kind: EventKind::RunEnded { reason: "duration".into() } }];
    rec.write_window(duration_s, &[snapshot(0, duration_s), snapshot(1, duration_s)], &end).unwrap();
    rec.finish().unwrap();

    let bytes = std::fs::read(tmp.0.join("ulog/alpha-0.ulg")).unwrap();
    let p = parse(&bytes);

    // Definitions.
    assert_eq!(p.info_str("sys_name"), "SADE-SIM");
    assert_eq!(p.info_str("sys_uuid"), "test-run/alpha-0");
    assert_eq!(p.params["SYS_AUTOSTART"], ParamValue::Int32(4001));
    assert_eq!(p.params["MPC_XY_CRUISE"], ParamValue::Float(5.0));

    // Counts: duration x rate; the estimator from its first output (0.5 s).
    let count = |topic: &str| p.samples(topic).len();
    let n = |hz: f64, from_s: f64| ((duration_s - from_s) * hz).round() as usize;
    // Ground truth at the estimator's rate (as PX4 SITL), from the start.
    assert_ne!(rates.ground_truth_hz, rates.estimator_hz);
    assert_eq!(count("vehicle_local_position_groundtruth"), n(rates.estimator_hz, 0.0));
    assert_eq!(count("vehicle_attitude_groundtruth"), n(rates.estimator_hz, 0.0));
    assert_eq!(count("actuator_outputs"), n(rates.actuators_hz, 0.0));
    assert_eq!(count("battery_status"), n(rates.status_hz, 0.0));
    assert_eq!(count("vehicle_status"), n(rates.status_hz, 0.0));
    // Estimator samples at 0.5 s (its first output) .. 2.0 s: one more than the span x rate.
    assert_eq!(count("vehicle_local_position"), n(rates.estimator_hz, 0.5) + 1);
    assert_eq!(count("vehicle_global_position"), count("vehicle_local_position"));
    // GNSS outputs at 0.0, 0.2, .. 2.0 s: 11 distinct fixes.
    assert_eq!(count("sensor_gps"), 11);
    assert_eq!(count("vehicle_gps_position"), 11);

    // Timestamps strictly increase per topic and never go back across the file.
    for topic in p.formats.keys() {
        let ts: Vec<u64> = p.samples(topic).iter().map(Sample::timestamp).collect();
        assert!(ts.windows(2).all(|w| w[0] < w[1]), "{topic}: {ts:?}");
        assert!(ts.first().is_none_or(|&t| t > 0));
    }
    let log_ts: Vec<u64> = p.logs.iter().map(|l| l.1).collect();
    assert!(log_ts.windows(2).all(|w| w[0] <= w[1]));

    // Ground truth in NED from the drone's origin: at t, north 0, east 2t, down -t.
    for s in p.samples("vehicle_local_position_groundtruth") {
        let t = s.timestamp() as f64 * 1e-6;
        assert!(s.get("x").abs() < 1e-4, "north {}", s.get("x"));
        assert!((s.get("y") - 2.0 * t).abs() < 1e-4);
        assert!((s.get("z") + t).abs() < 1e-4);
        assert!((s.get("vy") - 2.0).abs() < 1e-6 && (s.get("vz") + 1.0).abs() < 1e-6);
        assert!(s.get("heading").abs() < 1e-6, "nose north");
    }
    // The estimate is 0.5 m north of the truth.
    for s in p.samples("vehicle_local_position") {
        assert!((s.get("x") - 0.5).abs() < 1e-4);
        assert!((s.get("eph") - 0.4).abs() < 1e-6);
    }
    // The reference point is the drone's origin, as geodetic coordinates.
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let origin = frame.to_geodetic(Enu::new(ORIGIN_0[0], ORIGIN_0[1], ORIGIN_0[2]));
    let lp = &p.samples("vehicle_local_position_groundtruth")[0];
    assert!((lp.get("ref_lat") - origin.latitude_deg).abs() < 1e-12);
    assert!((lp.get("ref_lon") - origin.longitude_deg).abs() < 1e-12);
    // Global positions agree with the local ones.
    let last = p.samples("vehicle_global_position_groundtruth").pop().unwrap();
    let expected = frame.to_geodetic(Enu::new(ORIGIN_0[0] + 4.0, ORIGIN_0[1], ORIGIN_0[2] + 2.0));
    assert!((last.get("lat") - expected.latitude_deg).abs() < 1e-9);
    assert!((last.get("lon") - expected.longitude_deg).abs() < 1e-9);
    assert!((last.get("alt") - expected.altitude_msl_m).abs() < 1e-3);
    // Attitude: nose north, level -> identity.
    let q = &p.samples("vehicle_attitude_groundtruth")[0];
    assert!((q.get("q[0]") - 1.0).abs() < 1e-6 && q.get("q[3]").abs() < 1e-6);
    // GNSS: measured time in timestamp_sample, NED velocity.
    let gps = p.samples("sensor_gps");
    assert_eq!(gps[1].get("timestamp_sample"), 200_000.0);
    assert!((gps[1].get("vel_e_m_s") - 2.0).abs() < 1e-6 && (gps[1].get("vel_d_m_s") + 1.0).abs() < 1e-6);
    assert_eq!((gps[1].get("fix_type"), gps[1].get("satellites_used")), (3.0, 12.0));
    // Battery and status.
    let battery = p.samples("battery_status");
    assert!(battery.windows(2).all(|w| w[1].get("remaining") < w[0].get("remaining")));
    assert_eq!(battery[0].get("cell_count"), 4.0);
    let status = p.samples("vehicle_status");
    let nav: Vec<f64> = status.iter().map(|s| s.get("nav_state")).collect();
    assert_eq!(nav.first(), Some(&17.0));
    assert_eq!(nav.last(), Some(&3.0));
    assert_eq!(status[0].get("arming_state"), 2.0);
    assert_eq!(status.last().unwrap().get("nav_state_timestamp"), 1_000_000.0);
    let act = &p.samples("actuator_outputs")[0];
    assert_eq!((act.get("noutputs"), act.get("output[0]"), act.get("output[3]")), (4.0, 1500.0, 1800.0));
    assert_eq!(act.get("output[4]"), 0.0);

    // Events: this drone's mode change (INFO) and the run end; not the other drone's failsafe.
    let texts: Vec<&str> = p.logs.iter().map(|l| l.2.as_str()).collect();
    assert!(texts.iter().any(|t| t.contains("Takeoff -> Mission")), "{texts:?}");
    assert!(texts.iter().any(|t| t.contains("run ended: duration")), "{texts:?}");
    assert!(!texts.iter().any(|t| t.contains("failsafe")), "{texts:?}");
    assert_eq!(p.logs.iter().find(|l| l.2.contains("Mission")).unwrap().0, b'6');

    let other = parse(&std::fs::read(tmp.0.join("ulog/alpha-1.ulg")).unwrap());
    let failsafe = other.logs.iter().find(|l| l.2.contains("failsafe")).expect("failsafe logged");
    assert_eq!((failsafe.0, failsafe.1), (b'2', 1_500_000));
    assert!(other.samples("vehicle_status").last().unwrap().get("failsafe") == 1.0);
}

#[test]
fn files_are_flushed_every_simulated_second() {
    let tmp = TempDir::new("flush");
    let plan = plan_of(RunBuilder::test().with_drones(1).build());
    let mut rec = UlogRecorder::create(&tmp.0, &plan).unwrap();
    for k in 1..=150 {
        let t = f64::from(k) / 100.0;
        rec.write_window(t, &[snapshot(0, t)], &[]).unwrap();
    }
    // Without finish(): what a killed run leaves. Everything up to 1.0 s is on disk.
    let bytes = std::fs::read(tmp.0.join("ulog/alpha-0.ulg")).unwrap();
    let p = parse(&bytes);
    let gt = p.samples("vehicle_local_position_groundtruth");
    assert!(gt.last().unwrap().timestamp() >= 1_000_000, "{} samples on disk", gt.len());
    drop(rec);
}

/// Regression (SYS_AUTOSTART was 4001 over MAVLink and 0 in the mini250's ULog): for every
/// preset, the parameters in the drone's ULog are exactly the PARAM_VALUEs its MAVLink
/// parameter table answers a PARAM_REQUEST_LIST with, name for name, type for type (the
/// test fixture's mission has no speed, so MPC_XY_CRUISE is the table's too).
#[test]
fn ulog_parameters_equal_the_mavlink_table_for_every_preset() {
    use ::mavlink::dialects::common::{MavMessage, PARAM_REQUEST_LIST_DATA};

    use sadesim_engine::mavlink::params::{self as mavlink_params, plan::drone_table};

    for preset in sadesim_engine::preset::Preset::all() {
        let name = preset.name().to_owned();
        let tmp = TempDir::new(&format!("params-{name}"));
        let plan = plan_of(RunBuilder::test().with_drones(1).with(|r| r.spec.fleet[0].airframe = name.clone()).build());
        let drone = &plan.drones[0];
        assert_eq!(drone.airframe, name);
        UlogRecorder::create(&tmp.0, &plan).unwrap().finish().unwrap();
        let p = parse(&std::fs::read(tmp.0.join(format!("ulog/{}.ulg", drone.name))).unwrap());

        let mut table = drone_table(&plan, drone).expect("known preset");
        let list = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: drone.system_id,
            target_component: 1,
        });
        let mut mavlink = HashMap::new();
        for msg in table.handle(&list).messages {
            let MavMessage::PARAM_VALUE(v) = msg else { panic!("{msg:?}") };
            let value = match mavlink_params::ParamValue::from_wire(v.param_value, v.param_type) {
                Some(mavlink_params::ParamValue::Int32(i)) => ParamValue::Int32(i),
                Some(mavlink_params::ParamValue::Real32(f)) => ParamValue::Float(f),
                None => panic!("{v:?}"),
            };
            mavlink.insert(v.param_id.to_str().unwrap().to_owned(), value);
        }
        assert_eq!(mavlink.len(), table.len(), "{name}");
        assert_eq!(p.params, mavlink, "{name}: ULog parameters differ from MAVLink's");
        assert_eq!(p.params["SYS_AUTOSTART"], ParamValue::Int32(preset.sys_autostart), "{name}");
        assert_eq!(p.params["BAT1_N_CELLS"], ParamValue::Int32(preset.airframe.battery.cells as i32), "{name}");
        assert_eq!(p.params["MAV_SYS_ID"], ParamValue::Int32(i32::from(drone.system_id)), "{name}");
    }
}

#[test]
fn ulog_cruise_parameter_is_the_scripted_mission_speed() {
    let tmp = TempDir::new("cruise");
    let run =
        RunBuilder::test().with_drones(1).with(|r| r.spec.fleet[0].mission.as_mut().unwrap().speed_mps = Some(8.0));
    let plan = plan_of(run.build());
    UlogRecorder::create(&tmp.0, &plan).unwrap().finish().unwrap();
    let p = parse(&std::fs::read(tmp.0.join("ulog/alpha-0.ulg")).unwrap());
    assert_eq!(p.params["MPC_XY_CRUISE"], ParamValue::Float(8.0));
    let table = sadesim_engine::mavlink::params::plan::drone_table(&plan, &plan.drones[0]).unwrap();
    assert_eq!(p.params.len(), table.len(), "every other parameter is the table's");
}
