//! The hold for the pilot in `sadesim run`: simulated time stands at the release until the
//! pilot's MAVLink reaches a drone it flies, for at most `spec.pilot.connectTimeoutS`.
//!
//! The pilots are bash scripts that send ready-made MAVLink 2 frames to the drone's UDP
//! endpoint (`/dev/udp`), so what they do does not depend on a MAVLink library's timers.
//! The runs hold [`mavlink_ports`].

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunOptions, RunReport, run_local};
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::run::{Clock, ClockMode, PilotExit};
use sadesim_integration_tests::{mavlink_ports, plan};

/// COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (param1 1) to system 1, component 1, from
/// system 255 component 190, MAVLink 2 (pymavlink 2.4's encoding of it, trailing zeros cut).
const ARM: &str = r"\xfd\x20\x00\x00\x00\xff\xbe\x4c\x00\x00\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x90\x01\x01\x01\x9e\x4e";
/// COMMAND_LONG MAV_CMD_NAV_TAKEOFF (param7 NaN: the default takeoff altitude), likewise.
const TAKEOFF: &str = r"\xfd\x20\x00\x00\x01\xff\xbe\x4c\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xc0\x7f\x16\x00\x01\x01\x82\x48";

/// One drone flown by `script` (bash), as fast as possible for `duration`.
fn scenario(script: &str, duration: &str, connect_timeout_s: Option<u32>) -> SimulationRun {
    RunBuilder::test()
        .with_pilot(&["bash", "-c", script])
        .with(|r| {
            r.spec.duration = duration.parse().unwrap();
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            let pilot = r.spec.pilot.as_mut().unwrap();
            pilot.on_exit = Some(PilotExit::Continue);
            pilot.connect_timeout_s = connect_timeout_s;
        })
        .build()
}

fn root(name: &str) -> PathBuf {
    crate::local::scratch("hold", name)
}

fn run(r: &SimulationRun, root: &Path) -> RunReport {
    let options = RunOptions {
        out_root: Some(root.join("out")),
        scenario: Some(root.join("scenario/run.yaml")),
        ..RunOptions::default()
    };
    run_local(r, &options, Arc::new(AtomicBool::new(false))).expect("the run ends cleanly")
}

fn events(out_dir: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(out_dir.join("events.jsonl")).unwrap();
    text.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

/// A pilot that starts 5 s of wall time late (a `cargo run` building, an SDK importing),
/// then arms and takes off over and over: the run held at the release for it, so its
/// drone takes off right after the release in simulated time, not minutes of simulated
/// time later as in a run that ran on without it.
#[test]
fn a_pilot_started_late_still_flies_from_the_release_with_mavlink() {
    let _ports = mavlink_ports();
    let root = root("late");
    let probe = scenario("true", "90s", None);
    let port = plan(&probe).drones[0].ports.endpoint;
    let script = format!(
        "sleep 5; while :; do printf '{ARM}' > /dev/udp/127.0.0.1/{port}; printf '{TAKEOFF}' > /dev/udp/127.0.0.1/{port}; sleep 0.05; done"
    );
    let report = run(&scenario(&script, "90s", None), &root);
    let s = &report.summary;
    assert_eq!(s.end_reason, EndReason::Duration);
    let waited = s.pilot_connect_wait_s.expect("the run held for the pilot");
    assert!(waited >= 5.0, "held {waited} s for a pilot 5 s late");
    let released = s.pilots_released_at_s.expect("released");
    let events = events(&report.out_dir);
    let takeoff = events.iter().find(|e| e["event"] == "takeoff").expect("the drone took off");
    let takeoff_s = takeoff["timeS"].as_f64().unwrap();
    // Arming waits for a good fix (a few seconds after the release at most); a run that did
    // not hold would have run 5 s of wall time as fast as possible first.
    assert!(takeoff_s - released < 10.0, "took off at {takeoff_s} s, released at {released} s");
    assert!(s.per_drone[0].took_off);
    std::fs::remove_dir_all(&root).unwrap();
}

/// A pilot that never says a word: the run ends at the release after the limit, failed,
/// with the reason in summary.json and events.jsonl, and no verdict on a run nobody flew.
#[test]
fn a_pilot_that_never_connects_ends_the_run_with_the_reason_with_mavlink() {
    let _ports = mavlink_ports();
    let root = root("never");
    let mut r = scenario("sleep 600", "10m", Some(2));
    r.spec.criteria = vec![sadesim_crds::criteria::Criterion::NoCrashes {}];
    let report = run(&r, &root);
    let s = &report.summary;
    let EndReason::PilotNotConnected(why) = &s.end_reason else { panic!("{:?}", s.end_reason) };
    assert_eq!(
        why,
        "the pilot did not connect within 2 s: no MAVLink frame reached the drone it flies (spec.pilot.connectTimeoutS; see pilot.log)"
    );
    assert!(s.end_reason.is_failure());
    assert!(s.verdict.is_none(), "no verdict on a run nobody flew: {:?}", s.verdict);
    assert_eq!(s.pilot_connect_wait_s, None);
    // Simulated time stood at the release: the run ended one window after it.
    let released = s.pilots_released_at_s.expect("released");
    assert!(s.sim_time_s - released < 0.05, "{} s, released at {released} s", s.sim_time_s);
    assert!(s.wall_time_s >= 2.0, "{} s", s.wall_time_s);
    let written: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report.out_dir.join("summary.json")).unwrap()).unwrap();
    assert!(
        written["endReason"].as_str().unwrap().starts_with("pilotNotConnected: the pilot did not connect within 2 s")
    );
    let last = events(&report.out_dir).pop().unwrap();
    assert_eq!(last["event"], "runEnded");
    assert!(last["reason"].as_str().unwrap().starts_with("pilotNotConnected: "), "{last}");
    // The pilot was stopped by the runner.
    assert!(report.pilot.as_ref().is_some_and(|p| p.stopped_by_runner), "{:?}", report.pilot);
    std::fs::remove_dir_all(&root).unwrap();
}
