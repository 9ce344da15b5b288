//! Writes synthetic runs and reads them back with the `mcap` crate's reader.

use std::collections::{BTreeMap, BTreeSet};

use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::{Compression, RecordingRates};
use serde_json::Value;

use super::{CHUNK_BYTES, MCAP_FILE, McapRecorder};
use sadesim_engine::events::{Event, EventKind, FlightMode};
use sadesim_engine::fixtures::{plan_of, rect_zone, run_with_groups, world_of};
use sadesim_engine::protocol::{DroneDetail, DroneSnapshot, EstimateDetail, GnssDetail, SkyDetail};

/// Physics windows of 10 ms, as the default plan.
const WINDOW_S: f64 = 0.01;

use crate::record::test_dir::TempDir;

fn plan(drones: u32) -> RunPlan {
    plan_of(
        run_with_groups(&[("a", drones)])
            .with(|r| r.spec.zones.push(rect_zone("museum", (-50.0, 50.0), (-20.0, 20.0), 0.0, 120.0)))
            .build(),
    )
}

/// A drone flying a circle, with every detail a function of time so values can be checked.
fn snapshot(index: u32, t: f64) -> DroneSnapshot {
    let k = f64::from(index);
    let (s, c) = (0.5 * t).sin_cos();
    let half = 0.25 * t;
    let estimate_from_s = 0.505;
    DroneSnapshot {
        index,
        position_enu_m: [20.0 * c + 100.0 * k, 20.0 * s, 10.0 + t],
        velocity_enu_mps: [-10.0 * s, 10.0 * c, 1.0],
        attitude_wxyz: [half.cos(), 0.0, 0.0, half.sin()],
        height_agl_m: 10.0 + t,
        mode: if t < 1.0 { FlightMode::Takeoff } else { FlightMode::Mission },
        armed: true,
        on_ground: false,
        crashed: false,
        battery_remaining: 1.0 - 0.01 * t,
        position_valid: t >= estimate_from_s,
        detail: DroneDetail {
            rate_body_rps: [0.0, 0.0, 0.5],
            estimate: (t >= estimate_from_s).then(|| EstimateDetail {
                position_enu_m: [20.0 * c + 100.0 * k + 0.3, 20.0 * s - 0.2, 10.0 + t + 0.1],
                velocity_enu_mps: [-10.0 * s, 10.0 * c, 1.0],
                attitude_wxyz: [half.cos(), 0.0, 0.0, half.sin()],
                eph_m: 0.8,
                epv_m: 1.2,
            }),
            // A 5 Hz receiver: the latest fix is at the last multiple of 0.2 s.
            gnss: Some(GnssDetail {
                time_s: (t / 0.2 + 1e-9).floor() * 0.2,
                position_enu_m: [20.0 * c + 100.0 * k, 20.0 * s, 10.0 + t],
                velocity_enu_mps: [0.0; 3],
                fix_type: 3,
                satellites: 12,
                eph_m: Some(0.7),
                epv_m: Some(1.1),
                hdop: Some(0.9),
                vdop: Some(1.3),
                sky: Some(SkyDetail { above_mask: 14, line_of_sight: 10, reflected: 3 }),
            }),
            motor_commands: [0.5 + 0.01 * t, 0.51, 0.52, 0.53, 0.0, 0.0, 0.0, 0.0],
            motor_count: 4,
            battery_voltage_v: 16.8 - 0.01 * t,
            battery_current_a: 12.5,
            battery_consumed_mah: 3.5 * t,
            wind_enu_mps: [3.0, -1.0, 0.0],
            local_origin_enu_m: [100.0 * k, 0.0, 0.0],
        },
    }
}

/// Runs `seconds` of windows through a recorder (plus the final run-ended window) and
/// returns the file's bytes.
fn record(dir: &TempDir, plan: &RunPlan, seconds: f64, compression: Compression, rates: RecordingRates) -> Vec<u8> {
    let mut recorder = McapRecorder::create_with(&dir.0, plan, &world_of(plan), compression, rates, &[]).unwrap();
    let windows = (seconds / WINDOW_S).round() as u32;
    for w in 1..=windows {
        let t = f64::from(w) * WINDOW_S;
        let drones: Vec<_> = (0..plan.drones.len() as u32).map(|i| snapshot(i, t)).collect();
        let mut events = Vec::new();
        if w == 1 {
            events.push(Event { time_s: 0.0, drone: None, kind: EventKind::RunStarted { drones: 2, shards: 1 } });
        }
        if w == 100 {
            events.push(Event {
                time_s: t - 0.005,
                drone: Some(1),
                kind: EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land },
            });
        }
        recorder.write_window(t, &drones, &events).unwrap();
    }
    let end = f64::from(windows) * WINDOW_S;
    let drones: Vec<_> = (0..plan.drones.len() as u32).map(|i| snapshot(i, end)).collect();
    let ended = [Event { time_s: end, drone: None, kind: EventKind::RunEnded { reason: "duration".into() } }];
    recorder.write_window(end, &drones, &ended).unwrap();
    recorder.finish().unwrap();
    std::fs::read(dir.0.join(MCAP_FILE)).unwrap()
}

/// One message read back.
struct Read {
    topic: String,
    schema: String,
    log_time: u64,
    publish_time: u64,
    json: Value,
}

fn read_all(bytes: &[u8]) -> Vec<Read> {
    mcap::MessageStream::new(bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            // Protobuf messages are decoded into the JSON the other channels hold.
            let json = match (m.channel.message_encoding.as_str(), schema.encoding.as_str()) {
                ("json", "jsonschema") => serde_json::from_slice(&m.data).unwrap(),
                ("protobuf", "protobuf") => super::protobuf::decode::to_json(&schema.name, &m.data),
                (message, schema) => {
                    panic!("{}: message encoding {message}, schema encoding {schema}", m.channel.topic)
                }
            };
            Read {
                topic: m.channel.topic.clone(),
                schema: schema.name.clone(),
                log_time: m.log_time,
                publish_time: m.publish_time,
                json,
            }
        })
        .collect()
}

fn counts(messages: &[Read]) -> BTreeMap<String, usize> {
    let mut counts = BTreeMap::new();
    for m in messages {
        *counts.entry(m.topic.clone()).or_insert(0) += 1;
    }
    counts
}

fn ns_to_s(v: &Value) -> f64 {
    v["sec"].as_f64().unwrap() + v["nsec"].as_f64().unwrap() * 1e-9
}

fn xyz(v: &Value) -> [f64; 3] {
    [v["x"].as_f64().unwrap(), v["y"].as_f64().unwrap(), v["z"].as_f64().unwrap()]
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn counts_per_stream_are_duration_times_rate() {
    let dir = TempDir::new("counts");
    let plan = plan(2);
    let bytes = record(&dir, &plan, 3.0, Compression::Zstd, RecordingRates::default());
    let counts = counts(&read_all(&bytes));
    for name in ["a-0", "a-1"] {
        let n = |stream: &str| counts.get(&format!("/drones/{name}/{stream}")).copied().unwrap_or(0);
        assert_eq!(n("pose"), 300, "100 Hz x 3 s");
        assert_eq!(n("velocity"), 300);
        // The estimate starts at 0.505 s: samples at 0.6, 0.7, ..., 3.0.
        assert_eq!(n("estimate"), 25);
        assert_eq!(n("motors"), 30, "10 Hz x 3 s");
        for stream in ["battery", "status", "wind", "location"] {
            assert_eq!(n(stream), 30, "{stream}: 10 Hz x 3 s");
        }
        // A new fix every 0.2 s from 0 (seen at 0.01) to 3.0: 16 fixes.
        assert_eq!(n("gnss"), 16);
    }
    assert_eq!(counts["/tf"], 300, "one message for all drones at 100 Hz");
    assert_eq!(counts["/zones"], 1);
    assert_eq!(counts["/world"], 1);
    assert_eq!(counts["/events"], 3, "run started, failsafe, run ended");
}

#[test]
fn the_city_is_one_scene_of_the_world_buildings_and_ground() {
    let dir = TempDir::new("city");
    let plan = plan(1);
    let world = world_of(&plan);
    let messages = read_all(&record(&dir, &plan, 0.1, Compression::Zstd, RecordingRates::default()));
    let scene = &messages.iter().find(|m| m.topic == "/world").expect("a /world message").json;
    let entity = |id: &str| {
        scene["entities"].as_array().unwrap().iter().find(|e| e["id"] == id).unwrap_or_else(|| panic!("{id}")).clone()
    };
    let buildings = entity("buildings");
    assert_eq!(buildings["frame_id"], "world");
    assert_eq!(buildings["metadata"][0]["value"], world.buildings().len().to_string());
    let mesh = sadesim_world::mesh::buildings_mesh(&world);
    let solid = &buildings["triangles"][0];
    assert_eq!(solid["points"].as_array().unwrap().len(), mesh.positions_enu_m.len());
    assert_eq!(solid["indices"].as_array().unwrap().len(), 3 * mesh.triangles.len());
    // The tallest roof, to the centimetre.
    let top = solid["points"].as_array().unwrap().iter().map(|p| p["z"].as_f64().unwrap()).fold(f64::MIN, f64::max);
    let tallest = world.buildings().iter().map(|b| b.roof_up_m()).fold(f64::MIN, f64::max);
    assert!((top - tallest).abs() <= 0.005, "{top} vs {tallest}");
    let ground = &entity("ground")["triangles"][0];
    let corner = &ground["points"][0];
    let e = world.extent_m();
    assert_eq!((corner["x"].as_f64(), corner["y"].as_f64()), (Some(-e), Some(-e)));
    assert!((corner["z"].as_f64().unwrap() - world.ground_up_m(-e, -e)).abs() <= 0.005);
}

#[test]
fn rates_follow_the_spec() {
    let dir = TempDir::new("rates");
    let plan = plan(1);
    let rates = RecordingRates { ground_truth_hz: 25.0, estimator_hz: 7.0, actuators_hz: 1000.0, status_hz: 0.5 };
    let counts = counts(&read_all(&record(&dir, &plan, 4.0, Compression::Lz4, rates)));
    assert_eq!(counts["/drones/a-0/pose"], 100, "25 Hz x 4 s");
    // 7 Hz from 0.505 s: samples at k/7 for k = 4..=28.
    assert_eq!(counts["/drones/a-0/estimate"], 25);
    assert_eq!(counts["/drones/a-0/motors"], 400, "at most one sample per 10 ms window");
    assert_eq!(counts["/drones/a-0/status"], 2, "0.5 Hz x 4 s");
}

#[test]
fn schemas_are_foxglove_well_known_ones_where_they_exist() {
    let dir = TempDir::new("schemas");
    let plan = plan(1);
    let messages = read_all(&record(&dir, &plan, 0.5, Compression::None, RecordingRates::default()));
    let by_topic: BTreeMap<&str, &str> = messages.iter().map(|m| (m.topic.as_str(), m.schema.as_str())).collect();
    assert_eq!(by_topic["/drones/a-0/pose"], "foxglove.PoseInFrame");
    assert_eq!(by_topic["/tf"], "foxglove.FrameTransforms");
    assert_eq!(by_topic["/drones/a-0/gnss"], "foxglove.LocationFix");
    assert_eq!(by_topic["/drones/a-0/location"], "foxglove.LocationFix");
    assert_eq!(by_topic["/zones"], "foxglove.SceneUpdate");
    assert_eq!(by_topic["/events"], "foxglove.Log");
    assert_eq!(by_topic["/drones/a-0/motors"], "sadesim.MotorCommands");
    let summary = mcap::Summary::read(&record(&dir, &plan, 0.5, Compression::None, RecordingRates::default()))
        .unwrap()
        .expect("a finished file has a summary");
    let names: BTreeSet<String> = summary.schemas.values().map(|s| s.name.clone()).collect();
    assert_eq!(names.len(), super::schemas::ALL.len() + super::schemas::PROTOBUF.len());
    for schema in summary.schemas.values() {
        if super::schemas::PROTOBUF.contains(&schema.name.as_str()) {
            assert_eq!(schema.encoding, "protobuf", "{}", schema.name);
            assert_eq!(*schema.data, super::protobuf::descriptor_set(&schema.name).unwrap(), "{}", schema.name);
            continue;
        }
        assert_eq!(schema.encoding, "jsonschema", "{}", schema.name);
        let parsed: Value = serde_json::from_slice(&schema.data).expect("schema data is JSON");
        assert_eq!(parsed["title"], schema.name.as_str(), "title of {}", schema.name);
        assert_eq!(parsed["type"], "object");
    }
    let encodings: BTreeMap<&str, &str> =
        summary.channels.values().map(|c| (c.topic.as_str(), c.message_encoding.as_str())).collect();
    for (topic, encoding) in
        [("/drones/a-0/pose", "protobuf"), ("/tf", "protobuf"), ("/drones/a-0/velocity", "protobuf")]
    {
        assert_eq!(encodings[topic], encoding, "{topic}");
    }
    assert_eq!(encodings["/drones/a-0/gnss"], "json");
}

#[test]
fn the_summary_indexes_every_chunk_for_seeking_readers() {
    for compression in [Compression::Zstd, Compression::Lz4, Compression::None] {
        let dir = TempDir::new(&format!("summary-{compression:?}"));
        let plan = plan(20);
        let bytes = record(&dir, &plan, 4.0, compression, RecordingRates::default());
        let streamed = read_all(&bytes);
        let summary = mcap::Summary::read(&bytes).unwrap().expect("a finished file has a summary");
        let stats = summary.stats.as_ref().expect("statistics");
        assert_eq!(stats.message_count, streamed.len() as u64);
        assert_eq!(stats.channel_count as usize, summary.channels.len());
        assert_eq!(stats.chunk_count as usize, summary.chunk_indexes.len());
        assert!(summary.chunk_indexes.len() >= 3, "several 1 MiB chunks: {}", summary.chunk_indexes.len());
        assert_eq!(stats.message_start_time, 0);
        assert_eq!(stats.message_end_time, 4_000_000_000);
        let per_channel: u64 = stats.channel_message_counts.values().sum();
        assert_eq!(per_channel, stats.message_count);
        // Reading chunk by chunk through the indexes (as a seeking reader) finds every
        // message, inside each chunk's time range.
        let mut seeked = 0;
        for index in &summary.chunk_indexes {
            assert!(index.message_start_time <= index.message_end_time);
            for m in summary.stream_chunk(&bytes, index).unwrap() {
                let m = m.unwrap();
                assert!((index.message_start_time..=index.message_end_time).contains(&m.log_time));
                seeked += 1;
            }
        }
        assert_eq!(seeked, streamed.len(), "{compression:?}");
    }
}

#[test]
fn log_times_are_monotonic_per_channel_and_timestamps_match() {
    let dir = TempDir::new("monotonic");
    let plan = plan(2);
    let messages = read_all(&record(&dir, &plan, 2.0, Compression::Zstd, RecordingRates::default()));
    let mut last: BTreeMap<&str, u64> = BTreeMap::new();
    for m in &messages {
        if let Some(&previous) = last.get(m.topic.as_str()) {
            assert!(m.log_time >= previous, "{}: {} after {previous}", m.topic, m.log_time);
        }
        last.insert(&m.topic, m.log_time);
        assert!(m.publish_time <= m.log_time, "{}", m.topic);
        let stamped: Vec<&Value> = match m.topic.as_str() {
            "/zones" | "/world" => Vec::new(),
            "/tf" => m.json["transforms"].as_array().unwrap().iter().map(|t| &t["timestamp"]).collect(),
            _ => vec![&m.json["timestamp"]],
        };
        for stamp in stamped {
            let t = stamp["sec"].as_u64().unwrap() * 1_000_000_000 + stamp["nsec"].as_u64().unwrap();
            assert_eq!(t, m.publish_time, "{}", m.topic);
        }
    }
    assert_eq!(last.len(), 4 + 2 * 10, "every channel has messages");
}

#[test]
fn values_equal_the_snapshots() {
    let dir = TempDir::new("values");
    let plan = plan(2);
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let messages = read_all(&record(&dir, &plan, 1.5, Compression::Zstd, RecordingRates::default()));
    let mut checked = BTreeMap::new();
    for m in &messages {
        let t = m.log_time as f64 * 1e-9;
        let drone = m.topic.strip_prefix("/drones/a-").and_then(|r| r.split('/').next()).and_then(|i| i.parse().ok());
        let stream = m.topic.rsplit('/').next().unwrap();
        let j = &m.json;
        match (drone, stream) {
            (Some(i), "pose") => {
                let s = snapshot(i, t);
                assert_eq!(j["frame_id"], "world");
                assert!(close(xyz(&j["pose"]["position"]), s.position_enu_m, 0.5e-3), "{t} {j}");
                let q = &j["pose"]["orientation"];
                assert!((q["w"].as_f64().unwrap() - s.attitude_wxyz[0]).abs() <= 0.5e-5);
                assert!((q["z"].as_f64().unwrap() - s.attitude_wxyz[3]).abs() <= 0.5e-5);
            }
            (Some(i), "velocity") => {
                assert!(close(xyz(&j["velocity_enu_mps"]), snapshot(i, t).velocity_enu_mps, 0.5e-3));
            }
            (Some(i), "estimate") => {
                let s = snapshot(i, t);
                let e = s.detail.estimate.as_ref().unwrap();
                assert!(close(xyz(&j["position_enu_m"]), e.position_enu_m, 0.5e-3));
                assert!(close(xyz(&j["position_error_enu_m"]), [0.3, -0.2, 0.1], 1e-4));
                assert_eq!(j["eph_m"], 0.8);
            }
            (Some(i), "motors") => {
                let s = snapshot(i, t);
                let commands: Vec<f64> =
                    j["commands"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
                assert_eq!(commands.len(), 4);
                assert!((commands[0] - s.detail.motor_commands[0]).abs() <= 0.5e-4);
            }
            (Some(i), "status") => {
                let s = snapshot(i, t);
                assert_eq!(j["mode"], if s.mode == FlightMode::Takeoff { "takeoff" } else { "mission" });
                assert_eq!(j["armed"], true);
            }
            (Some(i), "location") => {
                let [e, n, u] = snapshot(i, t).position_enu_m;
                let g = frame.to_geodetic(Enu::new(e, n, u));
                assert!((j["latitude"].as_f64().unwrap() - g.latitude_deg).abs() <= 0.5e-8);
                assert!((j["longitude"].as_f64().unwrap() - g.longitude_deg).abs() <= 0.5e-8);
                assert!((j["altitude"].as_f64().unwrap() - g.altitude_msl_m).abs() <= 0.5e-3);
                assert_eq!(j["frame_id"], format!("drone/a-{i}"));
            }
            (Some(_), "gnss") => {
                assert_eq!(j["position_covariance_type"], 2);
                assert!((j["position_covariance"][0].as_f64().unwrap() - 0.49).abs() < 1e-9);
                assert!((j["position_covariance"][8].as_f64().unwrap() - 1.21).abs() < 1e-9);
                let fix_s = ns_to_s(&j["timestamp"]);
                assert!(((fix_s / 0.2).round() * 0.2 - fix_s).abs() < 1e-6, "fix times are multiples of 0.2 s");
            }
            (Some(i), "gnss_quality") => {
                // The snapshot's fix lies at its own time's circle point; the truth is taken
                // back along the velocity from the window to the fix time.
                let fix_s = ns_to_s(&j["timestamp"]);
                let s = snapshot(i, t);
                let g = s.detail.gnss.as_ref().unwrap();
                let truth = s.position_back_at(g.time_s, t);
                let expected = (g.position_enu_m[0] - truth[0]).hypot(g.position_enu_m[1] - truth[1]);
                assert!((fix_s - g.time_s).abs() < 1e-6);
                assert!((j["horizontal_error_m"].as_f64().unwrap() - expected).abs() < 1e-3, "{j}");
                assert_eq!((j["fix_type"].as_u64(), j["satellites_used"].as_u64()), (Some(3), Some(12)));
                assert_eq!((j["satellites_above_mask"].as_u64(), j["reflected"].as_u64()), (Some(14), Some(3)));
                assert_eq!(j["hdop"], 0.9);
            }
            (None, "tf") => {
                let transforms = j["transforms"].as_array().unwrap();
                assert_eq!(transforms.len(), 2, "one transform per drone");
                for (k, j) in transforms.iter().enumerate() {
                    let child = j["child_frame_id"].as_str().unwrap();
                    let i: u32 = child.strip_prefix("drone/a-").unwrap().parse().unwrap();
                    assert_eq!(i as usize, k);
                    assert_eq!(j["parent_frame_id"], "world");
                    assert!(close(xyz(&j["translation"]), snapshot(i, t).position_enu_m, 0.5e-3));
                }
            }
            (None, "events") => {
                let event: Event = serde_json::from_str(j["message"].as_str().unwrap()).unwrap();
                let failsafe = matches!(event.kind, EventKind::Failsafe { .. });
                assert_eq!(j["level"], if failsafe { 3 } else { 2 });
                assert_eq!(j["name"], if failsafe { "a-1" } else { "run" });
            }
            (None, "zones") => {
                let entity = &j["entities"][0];
                assert_eq!(entity["id"], "zone/museum");
                assert_eq!(entity["frame_id"], "world");
                let walls = entity["triangles"][0]["points"].as_array().unwrap();
                assert_eq!(walls.len(), 4 * 6, "two triangles per wall of a rectangle");
                let ups: BTreeSet<i64> = walls.iter().map(|p| p["z"].as_f64().unwrap().round() as i64).collect();
                assert_eq!(ups, BTreeSet::from([0, 120]));
                let easts: Vec<f64> = walls.iter().map(|p| p["x"].as_f64().unwrap()).collect();
                assert!(easts.iter().all(|e| (e.abs() - 50.0).abs() < 0.01), "{easts:?}");
            }
            _ => {}
        }
        *checked.entry(stream.to_string()).or_insert(0) += 1;
    }
    for stream in [
        "pose",
        "velocity",
        "estimate",
        "motors",
        "status",
        "location",
        "gnss",
        "gnss_quality",
        "tf",
        "events",
        "zones",
    ] {
        assert!(checked.get(stream).copied().unwrap_or(0) > 0, "no {stream} message checked");
    }
}

#[test]
fn an_unfinished_file_reads_up_to_its_last_chunk() {
    let dir = TempDir::new("killed");
    let plan = plan(20);
    let mut recorder =
        McapRecorder::create_with(&dir.0, &plan, &world_of(&plan), Compression::Zstd, RecordingRates::default(), &[])
            .unwrap();
    let path = dir.0.join(MCAP_FILE);
    // Write until the file has grown three times (the first chunk with schemas, channels
    // and zones, then two chunks of messages), then copy it as a killed process would
    // leave it: no summary, no footer.
    let mut t = 0.0;
    let mut copy = std::fs::read(&path).unwrap();
    let mut growths = 1;
    while growths < 3 && t < 60.0 {
        t += WINDOW_S;
        let drones: Vec<_> = (0..20).map(|i| snapshot(i, t)).collect();
        recorder.write_window(t, &drones, &[]).unwrap();
        let now = std::fs::read(&path).unwrap();
        if now.len() > copy.len() {
            growths += 1;
        }
        copy = now;
    }
    assert_eq!(growths, 3, "chunks reach the file while the recorder is open");
    // The synthetic flights are smooth: zstd compresses a whole chunk of them about 20x.
    assert!(copy.len() > 2 * CHUNK_BYTES / 50, "two compressed chunks: {} bytes", copy.len());
    let mut read = 0;
    let mut last_pose = BTreeMap::new();
    for m in mcap::MessageStream::new(&copy).unwrap() {
        let Ok(m) = m else { break };
        if m.channel.topic.ends_with("/pose") {
            let j = super::protobuf::decode::to_json("foxglove.PoseInFrame", &m.data);
            let i: u32 = m.channel.topic.trim_start_matches("/drones/a-").trim_end_matches("/pose").parse().unwrap();
            let time = m.log_time as f64 * 1e-9;
            assert!(close(xyz(&j["pose"]["position"]), snapshot(i, time).position_enu_m, 0.5e-3));
            let previous = last_pose.insert(i, m.log_time);
            assert!(previous.is_none_or(|p| p < m.log_time));
        }
        read += 1;
    }
    assert!(read > 2000, "read {read} messages");
    assert_eq!(last_pose.len(), 20);
    drop(recorder);
}

/// Cost of recording 100 drones for 20 s at default rates (run with `--release --ignored
/// --nocapture`); compare with the simulation's CPU time from `sadesim bench`.
#[test]
#[ignore = "a measurement, not a check"]
fn recording_cost() {
    let plan = plan(100);
    for compression in [Compression::Zstd, Compression::Lz4, Compression::None] {
        // SADESIM_MCAP_COST=Zstd (or Lz4, None) measures one only, e.g. under perf.
        if std::env::var("SADESIM_MCAP_COST").is_ok_and(|only| only != format!("{compression:?}")) {
            continue;
        }
        let dir = TempDir::new(&format!("cost-{compression:?}"));
        let windows: Vec<Vec<DroneSnapshot>> =
            (1..=200).map(|w| (0..100).map(|i| snapshot(i, f64::from(w) * WINDOW_S)).collect()).collect();
        let started = std::time::Instant::now();
        let mut recorder =
            McapRecorder::create_with(&dir.0, &plan, &world_of(&plan), compression, RecordingRates::default(), &[])
                .unwrap();
        for w in 1..=2000u32 {
            let t = f64::from(w) * WINDOW_S;
            recorder.write_window(t, &windows[(w % 200) as usize], &[]).unwrap();
        }
        recorder.finish().unwrap();
        let size = std::fs::metadata(dir.0.join(MCAP_FILE)).unwrap().len();
        println!("{compression:?}: {:.3} s, {:.1} MB", started.elapsed().as_secs_f64(), size as f64 / 1e6);
    }
}

/// A downward camera on drone 1, recorded with depth.
fn down_camera() -> crate::record::CameraStream {
    crate::record::CameraStream {
        drone: 1,
        camera: "down".into(),
        width: 4,
        height: 2,
        k: [2.0, 0.0, 1.5, 0.0, 2.0, 0.5, 0.0, 0.0, 1.0],
        p: [2.0, 0.0, 1.5, 0.0, 0.0, 2.0, 0.5, 0.0, 0.0, 0.0, 1.0, 0.0],
        mount_offset_flu_m: [0.1, 0.0, -0.05],
        // Optical z (forward) along body -z (down), optical x (right) along body -y.
        mount_optical_to_flu_wxyz: [0.0, std::f64::consts::FRAC_1_SQRT_2, -std::f64::consts::FRAC_1_SQRT_2, 0.0],
        depth: true,
    }
}

#[test]
fn camera_frames_are_recorded_with_their_calibration_depth_and_mount() {
    use crate::record::CameraImage;
    let plan = plan(2);
    let dir = TempDir::new("mcap-cameras");
    let camera = down_camera();
    let mut recorder = McapRecorder::create_with(
        &dir.0,
        &plan,
        &world_of(&plan),
        Compression::Zstd,
        RecordingRates::default(),
        std::slice::from_ref(&camera),
    )
    .unwrap();
    let jpeg = vec![0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3];
    let depth: Vec<u8> = (0..8u16).flat_map(|mm| (1000 + mm).to_le_bytes()).collect();
    for w in 1..=100u32 {
        let t = f64::from(w) * WINDOW_S;
        let drones: Vec<_> = (0..2).map(|i| snapshot(i, t)).collect();
        recorder.write_window(t, &drones, &[]).unwrap();
        if w % 50 == 0 {
            let image = CameraImage { stream: 0, time_s: t, jpeg: jpeg.clone(), depth_mm_le: Some(depth.clone()) };
            recorder.write_images(t, &[image]).unwrap();
        }
    }
    let unknown = CameraImage { stream: 1, time_s: 1.0, jpeg: jpeg.clone(), depth_mm_le: None };
    let err = recorder.write_images(1.0, &[unknown]).unwrap_err();
    assert!(err.to_string().contains("no recorded camera 1"), "{err}");
    recorder.finish().unwrap();
    let messages = read_all(&std::fs::read(dir.0.join(MCAP_FILE)).unwrap());
    let on = |topic: &str| messages.iter().filter(|m| m.topic == topic).collect::<Vec<_>>();

    let images = on("/drones/a-1/cameras/down/image");
    assert_eq!(images.len(), 2, "a frame at 0.5 s and 1.0 s");
    assert_eq!(images[0].schema, "foxglove.CompressedImage");
    assert_eq!(images[1].log_time, 1_000_000_000);
    let image = &images[0].json;
    assert_eq!((image["format"].as_str(), image["frame_id"].as_str()), (Some("jpeg"), Some("drone/a-1/down")));
    assert_eq!(image["data"]["bytes"], 7);
    assert_eq!(ns_to_s(&image["timestamp"]), 0.5);

    let calibration = on("/drones/a-1/cameras/down/calibration");
    assert_eq!(calibration.len(), 2);
    let c = &calibration[0].json;
    assert_eq!(calibration[0].schema, "foxglove.CameraCalibration");
    assert_eq!((c["width"].as_u64(), c["height"].as_u64()), (Some(4), Some(2)));
    assert_eq!(c["K"], serde_json::json!(camera.k));
    assert_eq!(c["P"], serde_json::json!(camera.p));
    assert_eq!(c["R"], serde_json::json!([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]));
    assert_eq!(c.get("D"), None, "no distortion: D is empty");
    assert_eq!(c["distortion_model"], "plumb_bob");

    let depths = on("/drones/a-1/cameras/down/depth");
    assert_eq!(depths.len(), 2);
    let d = &depths[0].json;
    assert_eq!(depths[0].schema, "foxglove.RawImage");
    assert_eq!((d["encoding"].as_str(), d["step"].as_u64()), (Some("16UC1"), Some(8)));
    assert_eq!(d["data"]["bytes"], 16);
    assert_eq!(d["data"]["head"], serde_json::json!([0xE8, 0x03, 0xE9, 0x03]), "1000 mm, 1001 mm, little-endian");

    // The mount: one transform at 0, the camera's optical frame under the drone's body.
    let mount = on("/tf").into_iter().find(|m| m.log_time == 0).expect("the mounts at 0");
    let t = &mount.json["transforms"][0];
    assert_eq!(
        (t["parent_frame_id"].as_str(), t["child_frame_id"].as_str()),
        (Some("drone/a-1"), Some("drone/a-1/down"))
    );
    assert!(close(xyz(&t["translation"]), [0.1, 0.0, -0.05], 1e-3));
    assert!((t["rotation"]["x"].as_f64().unwrap() - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-4);
}

#[test]
fn a_recording_without_cameras_declares_no_image_schemas() {
    let plan = plan(1);
    let dir = TempDir::new("mcap-no-cameras");
    let bytes = record(&dir, &plan, 0.1, Compression::None, RecordingRates::default());
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let names: BTreeSet<_> = summary.schemas.values().map(|s| s.name.clone()).collect();
    assert!(!names.contains("foxglove.CompressedImage") && !names.contains("foxglove.CameraCalibration"), "{names:?}");
}

/// A run's end is an ERROR log when the run failed (a shard or the pilot), INFO otherwise;
/// drone trouble is a WARNING.
#[test]
fn log_levels_follow_the_typed_end_reason() {
    use super::messages::level;
    use sadesim_engine::events::{CrashCause, EndReason};
    let ended = |reason: EndReason| level(&EventKind::RunEnded { reason });
    assert_eq!(ended(EndReason::ShardFailed("shard 1 failed: connection closed".into())), 4);
    assert_eq!(ended(EndReason::PilotFailed), 4);
    assert_eq!(ended(EndReason::Duration), 2);
    assert_eq!(ended(EndReason::Aborted), 2);
    assert_eq!(level(&EventKind::Crashed { with: CrashCause::Ground, speed_mps: 4.0 }), 3);
}
