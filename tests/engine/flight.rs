//! A scripted drone flies its mission through the whole stack: world, environment,
//! sensors, estimator, navigator, controller, motors, rigid body, contacts.

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::{Mission, MissionItem};
use sadesim_crds::geo::{Enu, LocalFrame};
use sim_worker::events::{EventKind, FlightMode};
use sim_worker::shard::Shard;

use sadesim_integration_tests::{plan as plan_for, world as world_for};

#[test]
fn a_scripted_mission_takes_off_reaches_its_waypoint_and_lands() {
    let run = RunBuilder::test().with_drones(1).build();
    let frame = LocalFrame::new(run.spec.origin.geo());
    let mut run = run;
    // Home is random in the fixture's area; fly 60 m north of it at 30 m AGL.
    let plan0 = plan_for(&run);
    let home = plan0.drones[0].home.local;
    let wp = frame.to_geodetic(Enu::new(home.east_m, home.north_m + 60.0, 0.0));
    run.spec.fleet[0].mission = Some(Mission {
        items: vec![
            MissionItem::Takeoff { altitude_agl_m: 20.0 },
            MissionItem::Waypoint {
                latitude_deg: wp.latitude_deg,
                longitude_deg: wp.longitude_deg,
                altitude_agl_m: 30.0,
                hold_s: Some(3.0),
            },
            MissionItem::Land {},
        ],
        speed_mps: Some(5.0),
    });
    let plan = plan_for(&run);
    let world = world_for(&plan);
    let mut shard = Shard::new(&plan, 0, world.clone()).unwrap();
    let mut events = Vec::new();
    // Warm up until the estimator has a fix, then release the pilot.
    events.extend(shard.advance(500));
    assert!(shard.drones()[0].is_ready());
    let mut max_agl: f64 = 0.0;
    let mut closest = f64::INFINITY;
    let target = frame.to_enu(wp);
    for window in 1..=900 {
        let msg = shard
            .handle(sim_worker::protocol::ToShard::Advance { until_step: 500 + window * 100, release_pilots: true });
        let Some(sim_worker::protocol::FromShard::Advanced { drones, events: e, .. }) = msg else { panic!() };
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
