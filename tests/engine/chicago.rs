//! The paper's case study end to end (§4): `examples/chicago-museum.yaml` flown by the
//! case-study pilot (`examples/pilots/chicago`) over MAVLink and the airspace API, with
//! the compliance monitor judging the criteria; and its non-compliant variant, which must
//! fail with the violations listed.
//!
//! The pilot binary is `target/debug/chicago-pilot` (`tests/run.sh` builds it before the
//! tests; `cargo build -p chicago-pilot` by hand).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunOptions, RunReport, run_local};
use sadesim_crds::run::{Clock, ClockMode};
use sadesim_integration_tests::mavlink_ports;
use serde_json::Value;

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples")
}

/// Flies `examples/<file>` as fast as possible with the debug pilot binary (the example's
/// own command, `cargo run --release`, would build a second copy).
fn fly(file: &str) -> RunReport {
    let pilot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/debug/chicago-pilot");
    assert!(pilot.exists(), "{} is missing: run `cargo build -p chicago-pilot` first", pilot.display());
    let scenario = examples().join(file);
    let mut run = sadesim_crds::parse_run(&std::fs::read_to_string(&scenario).unwrap()).unwrap();
    run.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
    let command = &mut run.spec.pilot.as_mut().expect("the example has a pilot").command;
    // Keep the example's own arguments (after `--`), swap the program.
    let args: Vec<String> = command.iter().skip_while(|a| *a != "--").skip(1).cloned().collect();
    *command = std::iter::once(pilot.display().to_string()).chain(args).collect();
    let root = std::env::temp_dir().join(format!("sadesim-chicago-{}-{file}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let options = RunOptions { out_root: Some(root), scenario: Some(scenario), ..RunOptions::default() };
    run_local(&run, &options, Arc::new(AtomicBool::new(false))).unwrap()
}

fn json(dir: &Path, file: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(file)).unwrap()).unwrap()
}

fn events(dir: &Path) -> Vec<Value> {
    std::fs::read_to_string(dir.join("events.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Group of each drone index, from the summary.
fn groups(summary: &Value) -> BTreeMap<u64, String> {
    summary["perDrone"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| (d["index"].as_u64().unwrap(), d["group"].as_str().unwrap().to_string()))
        .collect()
}

#[test]
fn chicago_case_study_passes_its_criteria_with_mavlink() {
    let _ports = mavlink_ports();
    let report = fly("chicago-museum.yaml");
    let dir = &report.out_dir;
    let verdict = report.summary.verdict.as_ref().expect("a verdict");
    assert!(verdict.passed, "{verdict:#?}\npilot log: {}", std::fs::read_to_string(dir.join("pilot.log")).unwrap());
    assert_eq!(verdict.criteria.len(), 7);
    assert_eq!(report.summary.crashed, 0);

    let summary = json(dir, "summary.json");
    let group = groups(&summary);
    let airspace = json(dir, "airspace.json");
    // Every drone asked for the museum zone: the 5 public-safety drones were granted, the
    // 27 others denied for their credentials.
    let mut verdicts: BTreeMap<u64, Vec<(String, Option<String>)>> = BTreeMap::new();
    for r in airspace["requests"].as_array().unwrap() {
        assert_eq!(r["zone"], "museum-tfr");
        let v = (r["verdict"].as_str().unwrap().to_string(), r["reason"].as_str().map(str::to_string));
        verdicts.entry(r["drone"].as_u64().unwrap()).or_default().push(v);
    }
    assert_eq!(verdicts.len(), 32, "drones that asked: {:?}", verdicts.keys());
    for (drone, vs) in &verdicts {
        let expected = if group[drone] == "public-safety" {
            ("granted".to_string(), None)
        } else {
            ("denied".to_string(), Some("insufficient_credentials".to_string()))
        };
        assert!(vs.iter().all(|v| *v == expected), "drone {drone} ({}): {vs:?}", group[drone]);
    }
    // All five DPS drones were inside, never below 350 ft AGL; nobody else was.
    let presences = airspace["presences"].as_array().unwrap();
    for p in presences {
        let drone = p["drone"].as_u64().unwrap();
        assert_eq!(group[&drone], "public-safety", "{p}");
        assert_eq!(p["authorized"], true, "{p}");
        assert!(p["minAglM"].as_f64().unwrap() >= 106.68, "{p}");
    }
    let inside: std::collections::BTreeSet<u64> = presences.iter().map(|p| p["drone"].as_u64().unwrap()).collect();
    assert_eq!(inside.len(), 5, "{presences:?}");
    assert!(airspace["violations"].as_array().unwrap().is_empty(), "{}", airspace["violations"]);

    // The events log has every request and its verdict.
    let events = events(dir);
    let count = |kind: &str| events.iter().filter(|e| e["event"] == kind).count();
    let requests = airspace["requests"].as_array().unwrap().len();
    assert_eq!(count("zoneRequested"), requests);
    assert_eq!(count("zoneGranted") + count("zoneDenied"), requests);
    assert_eq!(count("zoneEntered"), presences.len());
    std::fs::remove_dir_all(dir.parent().unwrap().parent().unwrap()).unwrap();
}

#[test]
fn chicago_journalists_ignoring_denials_fail_the_run_with_mavlink() {
    let _ports = mavlink_ports();
    let report = fly("chicago-museum-noncompliant.yaml");
    let dir = &report.out_dir;
    let verdict = report.summary.verdict.as_ref().expect("a verdict");
    assert!(!verdict.passed);
    let failed: Vec<&str> = verdict.criteria.iter().filter(|c| !c.passed).map(|c| c.criterion.as_str()).collect();
    assert!(failed.contains(&"noUnauthorizedEntries"), "{verdict:#?}");
    let entries = verdict.criteria.iter().find(|c| c.criterion == "noUnauthorizedEntries").unwrap();
    // Every journalist is listed, by name, with time and place.
    for k in 0..10 {
        let name = format!("journalists-{k} ");
        assert!(entries.failures.iter().any(|f| f.starts_with(&name)), "{name}missing: {:#?}", entries.failures);
    }
    assert!(entries.failures.iter().all(|f| f.contains("museum-tfr") && f.contains(" N ") && f.contains("AGL")));
    // The violations are in the events log too.
    let group = groups(&json(dir, "summary.json"));
    let violations: Vec<Value> = events(dir).into_iter().filter(|e| e["event"] == "violationStarted").collect();
    assert!(!violations.is_empty());
    for v in &violations {
        assert_eq!(v["rule"], "unauthorizedEntry", "{v}");
        assert_eq!(group[&v["drone"].as_u64().unwrap()], "journalists", "{v}");
    }
    std::fs::remove_dir_all(dir.parent().unwrap().parent().unwrap()).unwrap();
}
