//! The paper's case study, flown end to end with the built-in scripted pilots:
//! `sadesim run examples/chicago-museum.yaml --clock asFastAsPossible`.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunOptions, run_local};
use sadesim_crds::run::{Clock, ClockMode};

#[test]
fn chicago_case_study_flies_every_scripted_plan() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/chicago-museum.yaml");
    let mut run = sadesim_crds::parse_run(&std::fs::read_to_string(file).unwrap()).unwrap();
    run.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
    let root = std::env::temp_dir().join(format!("sadesim-chicago-{}", std::process::id()));
    let options = RunOptions { out_root: Some(root.clone()), mavlink: false, ..RunOptions::default() };
    let report = run_local(&run, &options, Arc::new(AtomicBool::new(false))).unwrap();
    let s = &report.summary;
    assert_eq!((s.drones, s.shards, s.end_reason.as_str()), (32, 2, "duration"));
    assert_eq!(s.crashed, 0, "{:?}", s.per_drone.iter().filter(|d| d.crashed).collect::<Vec<_>>());
    for d in &s.per_drone {
        assert!(d.took_off && d.landed, "{} did not fly its plan: {d:?}", d.name);
        assert_eq!(d.failsafes, 0, "{}: {d:?}", d.name);
        // Mission items reached: takeoff + the waypoint(s); the final RTL lands instead.
        let (expected_items, ceiling) = match d.group.as_str() {
            "public-safety" => (2, 121.92),
            "journalists" => (4, 121.92),
            "recreational" => (9, 30.48),
            other => panic!("unexpected group {other}"),
        };
        assert_eq!(d.waypoints_reached, expected_items, "{}: {d:?}", d.name);
        assert!(d.max_height_agl_m <= ceiling + 1.5, "{} flew to {:.1} m AGL", d.name, d.max_height_agl_m);
    }
    // Public safety reached the museum at 375 ft: above the zone's 350 ft minimum.
    let dps_max = s.per_drone.iter().filter(|d| d.group == "public-safety").map(|d| d.max_height_agl_m);
    assert!(dps_max.fold(f64::INFINITY, f64::min) > 106.68);
    std::fs::remove_dir_all(&root).unwrap();
}
