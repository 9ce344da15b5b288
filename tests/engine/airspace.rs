//! Airspace in a local run: the compliance monitor catches a drone that flies through a
//! zone without a lease (the run fails with the violation listed), and the built-in
//! geofence keeps drones of fenced groups out (hold, or return to launch).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunOptions, run_local};
use sadesim_crds::SimulationRun;
use sadesim_crds::criteria::Criterion;
use sadesim_crds::fixtures::{HOMES, RunBuilder, near_homes, zone};
use sadesim_crds::fleet::{Area, GeofenceAction, HomePlacement};
use sadesim_crds::geo::GeoPoint;
use sadesim_crds::run::{Clock, ClockMode};
use sadesim_integration_tests::fly_to_and_land;
use serde_json::Value;

fn out_root(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-airspace-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// North of the home disc's centre, metres, where the zone's south edge is.
const ZONE_SOUTH_M: f64 = 120.0;
const ZONE_NORTH_M: f64 = 180.0;

/// Three one-drone groups start in a 30 m disc and fly 300 m north at 20 m AGL, across a
/// 400 m wide, 60 m deep zone nobody holds a lease for: `intruders` (no geofence),
/// `holders` (geofence hold) and `returners` (geofence RTL).
fn scenario() -> SimulationRun {
    RunBuilder::test()
        .with(|r| {
            r.spec.duration = "180s".parse().unwrap();
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            let at = near_homes(r.spec.origin.geo());
            let north = at(0.0, 300.0);
            // The waypoint takes latitude and longitude only.
            let target = GeoPoint::new(north.latitude_deg, north.longitude_deg, 0.0);
            let template = r.spec.fleet[0].clone();
            r.spec.fleet = [
                ("intruders", None),
                ("holders", Some(GeofenceAction::Hold)),
                ("returners", Some(GeofenceAction::ReturnToLaunch)),
            ]
            .into_iter()
            .map(|(name, geofence)| {
                let mut g = template.clone();
                g.name = name.into();
                g.count = 1;
                g.homes = HomePlacement::RandomInArea(Area { name: None, center: HOMES, radius_m: 30.0 });
                g.mission = Some(fly_to_and_land(target, 20.0, 20.0, None, 8.0));
                g.geofence = geofence;
                g
            })
            .collect();
            let polygon = vec![
                at(-200.0, ZONE_SOUTH_M),
                at(200.0, ZONE_SOUTH_M),
                at(200.0, ZONE_NORTH_M),
                at(-200.0, ZONE_NORTH_M),
            ];
            let mut wall = zone("wall", polygon, 100.0);
            wall.policy.authorized_operators.clear();
            r.spec.zones = vec![wall];
            r.spec.criteria = vec![Criterion::NoUnauthorizedEntries {}, Criterion::AltitudeLimitsRespected {}];
        })
        .build()
}

fn events(dir: &std::path::Path) -> Vec<Value> {
    std::fs::read_to_string(dir.join("events.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn an_entry_without_a_lease_fails_the_run_and_geofences_keep_fenced_drones_out() {
    let root = out_root("fence");
    let options = RunOptions { out_root: Some(root.clone()), mavlink: false, ..RunOptions::default() };
    let report = run_local(&scenario(), &options, Arc::new(AtomicBool::new(false))).unwrap();
    let verdict = report.summary.verdict.as_ref().expect("a verdict");
    assert!(!verdict.passed, "{verdict:#?}");
    let entries = &verdict.criteria[0];
    assert_eq!((entries.criterion.as_str(), entries.passed), ("noUnauthorizedEntries", false), "{entries:#?}");
    // Only the unfenced drone is listed, by name, with the zone.
    assert_eq!(entries.failures.len(), 1, "{entries:#?}");
    assert!(entries.failures[0].contains("intruders-0") && entries.failures[0].contains("wall"), "{entries:#?}");
    assert!(verdict.criteria[1].passed, "{:#?}", verdict.criteria[1]);

    let events = events(&report.out_dir);
    let of = |drone: u64, kind: &str| {
        events.iter().filter(|e| e["drone"] == drone && e["event"] == kind).cloned().collect::<Vec<_>>()
    };
    // Drone 0 (intruders) entered unauthorised and the violation is in the log with a place.
    let entered = of(0, "zoneEntered");
    assert_eq!(entered.len(), 1, "{entered:?}");
    assert_eq!(entered[0]["authorized"], false);
    let north = entered[0]["at"]["northM"].as_f64().unwrap();
    let started = of(0, "violationStarted");
    assert_eq!(started[0]["rule"], "unauthorizedEntry");
    assert_eq!(of(0, "zoneExited").len(), 1, "it flew through and out");
    // Drones 1 and 2 never entered: their geofence fired first.
    for (drone, action) in [(1, "hold"), (2, "returnToLaunch")] {
        assert!(of(drone, "zoneEntered").is_empty(), "drone {drone} entered: {events:?}");
        let fired = of(drone, "failsafe");
        assert!(!fired.is_empty(), "drone {drone}: no geofence failsafe");
        assert_eq!((fired[0]["reason"].as_str(), fired[0]["action"].as_str()), (Some("geofence:wall"), Some(action)));
    }
    let s = &report.summary;
    // The holder hovers short of the zone; the returner went home and landed.
    assert!(!s.per_drone[1].landed && s.per_drone[2].landed, "{:?}", s.per_drone);
    assert!(north.is_finite());

    // airspace.json has the compliance records; summary.json has the verdict.
    let airspace: Value =
        serde_json::from_str(&std::fs::read_to_string(report.out_dir.join("airspace.json")).unwrap()).unwrap();
    assert_eq!(airspace["violations"].as_array().unwrap().len(), 1, "{airspace}");
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(report.out_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["verdict"]["passed"], false);
    std::fs::remove_dir_all(&root).unwrap();
}
