//! The ranging GNSS receiver in flight: a drone holding position on GNSS alone in a street
//! canyon drifts with its fix, and a fix lost under cover triggers the failsafe. The sky is
//! the synthetic GPS-like Walker constellation (`sadesim_gnss::synthetic`), so the test
//! needs no orbit file.

use std::sync::Arc;

use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_engine::events::{EventKind, FlightMode};
use sadesim_gnss::{Constellation, RunSky};
use sadesim_world::{Building, Footprint, World};

use sadesim_integration_tests::{environment, fly_in, fly_to_and_land, plan as plan_for};

fn urban_gnss(run: &mut SimulationRun) {
    run.spec.environment = Some(environment(serde_json::json!({
        // Not read here: the test hands the shard its sky.
        "gnss": {"constellation": {"file": "walker.tle", "elevationMaskDeg": 10}}
    })));
}

fn sky(plan: &RunPlan) -> Arc<RunSky> {
    let c = Constellation::from_tle(&sadesim_gnss::synthetic::walker_gps_galileo_tle()).unwrap();
    let epoch = c.newest_epoch_unix_s();
    Arc::new(RunSky::new(c, plan.spec.origin.geo(), epoch, 10.0))
}

/// A prism over `[e0, e1] x [n0, n1]` from `base_m` to `roof_m`.
fn prism(e0: f64, n0: f64, e1: f64, n1: f64, base_m: f64, roof_m: f64) -> Building {
    let square = vec![[e0, n0], [e1, n0], [e1, n1], [e0, n1]];
    Building::new(Footprint::new(square, vec![]).unwrap(), base_m, roof_m - base_m).unwrap()
}

#[test]
fn a_drone_holding_on_gnss_in_a_deep_canyon_wanders_more_than_over_the_park() {
    let mut run = RunBuilder::test().with(urban_gnss).build();
    let plan0 = plan_for(&run);
    let home = plan0.drones[0].home.local;
    let (e, n) = (home.east_m, home.north_m);
    // Take off in the open (a drone at the bottom of a deep canyon may have no fix to arm
    // with), fly 150 m north at 20 m above the ground and hold there.
    let frame = LocalFrame::new(run.spec.origin.geo());
    let hold_at = frame.to_geodetic(Enu::new(e, n + 150.0, 0.0));
    run.spec.fleet[0].mission = Some(fly_to_and_land(hold_at, 20.0, 20.0, Some(200.0), 5.0));
    let plan = plan_for(&run);
    let extent_m = plan.spec.world().extent_m;
    // A north-south street 40 m wide between 50 m slabs from 40 m north of home.
    let canyon = World::of_buildings(
        extent_m,
        vec![
            prism(e - 60.0, n + 40.0, e - 20.0, n + 640.0, 0.0, 50.0),
            prism(e + 20.0, n + 40.0, e + 60.0, n + 640.0, 0.0, 50.0),
        ],
    );
    let park = World::of_buildings(extent_m, vec![]);
    let (park_events, park_track) = fly_in(&plan, Arc::new(park), Some(sky(&plan)), 120, 100);
    let (canyon_events, canyon_track) = fly_in(&plan, Arc::new(canyon), Some(sky(&plan)), 120, 100);
    assert!(!park_events.iter().any(|e| matches!(e.kind, EventKind::Crashed { .. })), "{park_events:?}");
    // Largest true distance from the hold point from 48 s (the leg ends by ~45 s) until the
    // end or until the drone touches a wall: the estimator follows the canyon's fixes, whose
    // reflected signals bias them by metres to tens of metres, and flies the drone with them.
    let hold = [e, n + 150.0];
    let stray_m = |track: &[sadesim_engine::protocol::DroneSnapshot], events: &[sadesim_engine::events::Event]| {
        let end_s =
            events.iter().find(|ev| matches!(ev.kind, EventKind::Crashed { .. })).map_or(f64::INFINITY, |ev| ev.time_s);
        track[480..]
            .iter()
            .enumerate()
            .take_while(|(k, _)| 0.3 + (480 + k + 1) as f64 * 0.1 < end_s)
            .map(|(_, s)| (s.position_enu_m[0] - hold[0]).hypot(s.position_enu_m[1] - hold[1]))
            .fold(0.0, f64::max)
    };
    let (park_m, canyon_m) = (stray_m(&park_track, &park_events), stray_m(&canyon_track, &canyon_events));
    eprintln!("largest distance from the hold point: park {park_m:.2} m, canyon {canyon_m:.2} m");
    assert!(park_m < 3.0, "over the park the hold is as tight as the open-sky fix: {park_m:.2} m");
    assert!(canyon_m > 3.0 * park_m && canyon_m > 5.0, "canyon {canyon_m:.2} m vs park {park_m:.2} m");
    // The receiver's own account: fewer satellites used in the canyon.
    let used = |track: &[sadesim_engine::protocol::DroneSnapshot]| {
        let fixes: Vec<u8> =
            track[400..500].iter().filter_map(|s| s.detail.gnss.as_ref()).map(|g| g.satellites).collect();
        fixes.iter().map(|&k| f64::from(k)).sum::<f64>() / fixes.len() as f64
    };
    eprintln!("satellites used: park {:.1}, canyon {:.1}", used(&park_track), used(&canyon_track));
    assert!(used(&canyon_track) < used(&park_track));
}

#[test]
fn flying_into_a_covered_street_loses_the_fix_and_the_failsafe_lands_the_drone() {
    let mut run = RunBuilder::test().with(urban_gnss).build();
    let plan0 = plan_for(&run);
    let home = plan0.drones[0].home.local;
    let (e, n) = (home.east_m, home.north_m);
    let frame = LocalFrame::new(run.spec.origin.geo());
    let inside = frame.to_geodetic(Enu::new(e, n + 200.0, 0.0));
    run.spec.fleet[0].mission = Some(fly_to_and_land(inside, 8.0, 8.0, Some(10.0), 3.0));
    let plan = plan_for(&run);
    // A street 20 m wide between 80 m slabs, roofed over from 20 m up (a tunnel under a
    // building) from 40 m north of home for 300 m.
    let tunnel = World::of_buildings(
        plan.spec.world().extent_m,
        vec![
            prism(e - 40.0, n + 40.0, e - 10.0, n + 340.0, 0.0, 80.0),
            prism(e + 10.0, n + 40.0, e + 40.0, n + 340.0, 0.0, 80.0),
            prism(e - 10.0, n + 40.0, e + 10.0, n + 340.0, 20.0, 80.0),
        ],
    );
    let (events, track) = fly_in(&plan, Arc::new(tunnel), Some(sky(&plan)), 150, 100);
    for s in &track[120..190] {
        let g = s.detail.gnss.as_ref().unwrap();
        let est = s.detail.estimate.as_ref().map(|x| x.position_enu_m);
        eprintln!(
            "{:.1}: true {:.1?} v {:.1?} fix {} sats {} at {:.1?} est {:.1?}",
            s.height_agl_m,
            [s.position_enu_m[0] - e, s.position_enu_m[1] - n, s.position_enu_m[2]],
            s.velocity_enu_mps,
            g.fix_type,
            g.satellites,
            [g.position_enu_m[0] - e, g.position_enu_m[1] - n, g.position_enu_m[2]],
            est.map(|p| [p[0] - e, p[1] - n, p[2]])
        );
    }
    let failsafe = events
        .iter()
        .find(|ev| ev.kind == EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land })
        .unwrap_or_else(|| panic!("the GNSS-loss failsafe fires: {events:?}"));
    // Samples every 0.1 s after the 0.3 s warm-up.
    let at = &track[((failsafe.time_s - 0.3) / 0.1) as usize];
    eprintln!("failsafe at {:.1} s, {:.1} m north of home", failsafe.time_s, at.position_enu_m[1] - n);
    // The slabs and the roof shade the sky from before the tunnel's mouth (40 m north).
    assert!(at.position_enu_m[1] - n > 25.0, "at or under the roof when the fix was lost");
    assert!(events.iter().any(|ev| ev.kind == EventKind::Landed && ev.time_s > failsafe.time_s), "{events:?}");
    assert!(!events.iter().any(|ev| matches!(ev.kind, EventKind::Crashed { .. })), "{events:?}");
}
