//! A scripted drone flies its mission through the whole stack: world, environment,
//! sensors, estimator, navigator, controller, motors, rigid body, contacts.

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::{Mission, MissionItem};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_engine::events::{EventKind, FlightMode};
use sadesim_engine::shard::Shard;

use sadesim_integration_tests::{
    environment, fly_to_and_land, median, over_seeds, plan as plan_for, world as world_for,
};

#[test]
fn a_scripted_mission_takes_off_reaches_its_waypoint_and_lands() {
    let run = RunBuilder::test().with_drones(1).build();
    let frame = LocalFrame::new(run.spec.origin.geo());
    let mut run = run;
    // Home is random in the fixture's area; fly 60 m north of it at 30 m AGL.
    let plan0 = plan_for(&run);
    let home = plan0.drones[0].home.local;
    let wp = frame.to_geodetic(Enu::new(home.east_m, home.north_m + 60.0, 0.0));
    run.spec.fleet[0].mission = Some(fly_to_and_land(wp, 20.0, 30.0, Some(3.0), 5.0));
    let plan = plan_for(&run);
    let world = world_for(&plan);
    let mut shard =
        Shard::new(&plan, 0, &sadesim_engine::shard::Surroundings::new(&plan, world.clone(), None)).unwrap();
    let mut events = Vec::new();
    // Warm up until the estimator has a fix and a settled height, then release the pilot.
    events.extend(shard.advance(5_000));
    assert!(shard.drones()[0].is_ready());
    let mut max_agl: f64 = 0.0;
    let mut closest = f64::INFINITY;
    let target = frame.to_enu(wp);
    for window in 1..=900 {
        let msg = shard.handle(sadesim_engine::protocol::ToShard::Advance {
            until_step: 5_000 + window * 100,
            release_pilots: true,
            leases: None,
        });
        let Some(sadesim_engine::protocol::FromShard::Advanced { drones, events: e, .. }) = msg else { panic!() };
        events.extend(e);
        let s = &drones[0];
        max_agl = max_agl.max(s.height_agl_m);
        let d = ((s.position_enu_m[0] - target.east_m).powi(2) + (s.position_enu_m[1] - target.north_m).powi(2)).sqrt();
        if (s.height_agl_m - 30.0).abs() < 1.5 {
            closest = closest.min(d);
        }
    }
    let kinds: Vec<&EventKind> = events.iter().map(|e| &e.kind).collect();
    assert!(!kinds.iter().any(|k| matches!(k, EventKind::Crashed { .. })), "{kinds:?}");
    assert!(kinds.contains(&&EventKind::Takeoff), "{kinds:?}");
    assert!(kinds.contains(&&EventKind::WaypointReached { seq: 1 }), "{kinds:?}");
    assert!(kinds.contains(&&EventKind::Landed) && kinds.contains(&&EventKind::Disarmed), "{kinds:?}");
    assert!(closest < 1.5, "passed within {closest:.2} m of the waypoint (GNSS noise 0.5 m)");
    assert!((28.0..33.0).contains(&max_agl), "max AGL {max_agl}");
    let last = shard.drones()[0].snapshot();
    assert!(last.on_ground && !last.armed && last.mode == FlightMode::Idle, "{last:?}");
}

/// Drone 0's events and true state every 0.1 s.
fn fly(
    run: &sadesim_crds::SimulationRun,
    seconds: u64,
) -> (Vec<sadesim_engine::events::Event>, Vec<sadesim_engine::protocol::DroneSnapshot>) {
    sadesim_integration_tests::fly(run, seconds, 100)
}

fn hover_mission(seconds: f64) -> Mission {
    Mission {
        items: vec![
            MissionItem::Takeoff { altitude_agl_m: 30.0 },
            MissionItem::Loiter { hold_s: seconds },
            MissionItem::Land {},
        ],
        speed_mps: None,
    }
}

#[test]
fn gnss_loss_in_flight_triggers_the_land_failsafe_and_a_safe_landing() {
    let run = RunBuilder::test()
        .with(|r| {
            r.spec.fleet[0].mission = Some(hover_mission(300.0));
            r.spec.environment = Some(environment(serde_json::json!({
                "gnss": {"dropouts": [{"start": "40s", "duration": "5m", "groups": ["alpha"]}]}
            })));
        })
        .build();
    let (events, track) = fly(&run, 120);
    let failsafe = events
        .iter()
        .find(|e| e.kind == EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land })
        .expect("the GNSS-loss failsafe fires");
    // Fixes stop at 40 s; the estimator declares GNSS lost after its 1 s timeout.
    assert!((40.0..42.5).contains(&failsafe.time_s), "failsafe at {}", failsafe.time_s);
    assert!(events.iter().any(|e| e.kind == EventKind::Landed && e.time_s > failsafe.time_s));
    assert!(!events.iter().any(|e| matches!(e.kind, EventKind::Crashed { .. })), "dead-reckoned descent lands softly");
    let last = track.last().unwrap();
    assert!(last.on_ground && !last.armed, "{last:?}");
}

#[test]
fn hover_holds_position_in_gusty_wind() {
    let run = RunBuilder::test()
        .with(|r| {
            r.spec.fleet[0].mission = Some(hover_mission(120.0));
            r.spec.environment = Some(environment(serde_json::json!({
                "wind": {"speedMps": 8, "directionFromDeg": 270, "turbulence": "moderate"}
            })));
        })
        .build();
    let (events, track) = fly(&run, 90);
    assert!(!events.iter().any(|e| matches!(e.kind, EventKind::Crashed { .. })));
    // From 40 s (climb done, integrators settled) to 90 s: hold within a few metres of the
    // mean position despite 8 m/s wind with moderate Dryden gusts and GNSS noise.
    let held: Vec<[f64; 3]> = track[400..].iter().map(|s| s.position_enu_m).collect();
    let n = held.len() as f64;
    let mean = [0, 1, 2].map(|k| held.iter().map(|p| p[k]).sum::<f64>() / n);
    let worst = held.iter().map(|p| (p[0] - mean[0]).hypot(p[1] - mean[1])).fold(0.0, f64::max);
    let worst_z = held.iter().map(|p| (p[2] - mean[2]).abs()).fold(0.0, f64::max);
    assert!(worst < 3.0, "horizontal excursion {worst:.2} m");
    assert!(worst_z < 2.0, "vertical excursion {worst_z:.2} m");
    // The drone leans into the wind from the west: its mean roll/pitch tilts it westward,
    // which shows the wind force is real (not a numerical no-op).
    let tilt_west = track[400..]
        .iter()
        .map(|s| {
            let [w, x, y, z] = s.attitude_wxyz;
            let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            (q * nalgebra::Vector3::z()).x // body z axis in ENU: negative x = leaning west
        })
        .sum::<f64>()
        / (track.len() - 400) as f64;
    assert!(tilt_west < -0.05, "mean body-z east component {tilt_west:.3}: should lean into a west wind");
}

#[test]
fn a_drifting_gnss_bias_really_moves_the_vehicle() {
    // The estimator trusts GNSS for position, so a receiver whose bias wanders drags the
    // true position along while the drone believes it holds still. Judged over ten noise
    // realizations (`SEEDS`).
    let excursion = |seed: u64, bias_walk: f64| {
        let run = RunBuilder::test()
            .with_seed(seed)
            .with(|r| {
                r.spec.fleet[0].mission = Some(hover_mission(200.0));
                r.spec.environment = Some(environment(serde_json::json!({
                    "gnss": {"biasWalkMPerSqrtS": bias_walk, "horizontalSigmaM": 0.3}
                })));
            })
            .build();
        let (_, track) = fly(&run, 150);
        let start = track[300].position_enu_m; // 30 s: climb done, holding
        track[300..]
            .iter()
            .map(|s| (s.position_enu_m[0] - start[0]).hypot(s.position_enu_m[1] - start[1]))
            .fold(0.0, f64::max)
    };
    let pairs = over_seeds(|seed| (excursion(seed, 0.0), excursion(seed, 1.0)));
    let steady = median(&pairs.iter().map(|p| p.0).collect::<Vec<_>>());
    let drifting = median(&pairs.iter().map(|p| p.1).collect::<Vec<_>>());
    assert!(steady < 1.5, "no bias walk: held within a median {steady:.2} m ({pairs:.2?})");
    assert!(
        drifting > 3.0 * steady && drifting > 4.0,
        "1 m/sqrt(s) bias walk moved the drone a median {drifting:.2} m ({pairs:.2?})"
    );
}

#[test]
fn a_shard_gives_the_same_flights_whatever_its_window() {
    // A shard steps each drone through a whole window before the next drone (for cache
    // locality). That is only right while drones do not interact within a window: windows
    // of one step (every drone at every step) must give the very same flights and events.
    let run = RunBuilder::test()
        .with_drones(4)
        .with(|r| {
            r.spec.fleet[0].mission = Some(hover_mission(20.0));
            r.spec.environment = Some(environment(serde_json::json!({
                "wind": {"speedMps": 6, "directionFromDeg": 250, "turbulence": "moderate"}
            })));
        })
        .build();
    let plan = plan_for(&run);
    let world = world_for(&plan);
    let fly = |window: u64| {
        let surroundings = sadesim_engine::shard::Surroundings::new(&plan, world.clone(), None);
        let mut shard = Shard::new(&plan, 0, &surroundings).unwrap();
        let mut events = Vec::new();
        let mut step = 0;
        while step < 15_000 {
            // Pilots released from step 5 000 on, whatever the window.
            let release_pilots = step >= 5_000;
            step += window;
            let Some(sadesim_engine::protocol::FromShard::Advanced { events: e, .. }) = shard
                .handle(sadesim_engine::protocol::ToShard::Advance { until_step: step, release_pilots, leases: None })
            else {
                panic!("the shard stopped")
            };
            events.extend(e);
        }
        let snapshots: Vec<_> = shard.drones().iter().map(|d| d.snapshot()).collect();
        (serde_json::to_string(&events).unwrap(), serde_json::to_string(&snapshots).unwrap())
    };
    let (events, snapshots) = fly(100);
    assert!(events.contains("takeoff"), "the drones flew: {events}");
    let (events_1, snapshots_1) = fly(1);
    assert_eq!(events, events_1);
    assert_eq!(snapshots, snapshots_1);
}
