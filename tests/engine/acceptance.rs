//! Acceptance checks of the engine issue: physics against analytic results, and the
//! autopilot's takeoff, waypoint and RTL accuracy through the whole simulated stack.

use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::{Mission, MissionItem};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_engine::autopilot::control::{Controller, EstimatedState, Setpoint};
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::preset::Preset;
use sadesim_engine::protocol::DroneSnapshot;
use sadesim_engine::vehicle::{Airframe, GRAVITY_MPS2, Motor, RigidState, wrench};
use sadesim_integration_tests::{environment, median, over_seeds, plan};

const DT: f64 = 0.001;

// ---------------------------------------------------------------------------------------
// Physics
// ---------------------------------------------------------------------------------------

#[test]
fn hover_needs_thrust_equal_to_weight_within_two_percent() {
    for name in ["x500", "mini250"] {
        let airframe = physics_of(name);
        let mut controller = Controller::for_airframe(&airframe).unwrap();
        let mut motors = Motor::for_airframe(&airframe);
        let mut state = RigidState::at_rest(Vector3::new(0.0, 0.0, 20.0));
        let hold =
            Setpoint::Position { position_enu_m: state.position_enu_m, yaw_rad: 0.0, velocity_ff: Vector3::zeros() };
        for _ in 0..10_000 {
            let out = controller.update(hold, &EstimatedState::from(&state), DT);
            for (m, u) in motors.iter_mut().zip(&out.motor_commands) {
                m.step(*u, DT);
            }
            let w = wrench(
                &airframe,
                &motors,
                &state.attitude,
                &state.velocity_enu_mps,
                &state.rate_body_rps,
                &Vector3::zeros(),
            );
            state.integrate(&airframe, &w, DT);
        }
        let thrust: f64 = motors.iter().map(Motor::thrust_n).sum();
        let weight = airframe.mass_kg * GRAVITY_MPS2;
        assert!((thrust - weight).abs() / weight < 0.02, "{name}: thrust {thrust:.3} N vs weight {weight:.3} N");
        assert!((state.position_enu_m.z - 20.0).abs() < 0.05, "{name} holds its altitude");
    }
}

/// Seconds for `airframe`, motors stopped, to fall `height_m` from rest in still air.
fn fall_time_s(airframe: &sadesim_engine::vehicle::Airframe, height_m: f64) -> f64 {
    let motors = Motor::for_airframe(airframe);
    let mut state = RigidState::at_rest(Vector3::new(0.0, 0.0, height_m));
    let mut t = 0.0;
    while state.position_enu_m.z > 0.0 {
        let w = wrench(
            airframe,
            &motors,
            &state.attitude,
            &state.velocity_enu_mps,
            &state.rate_body_rps,
            &Vector3::zeros(),
        );
        state.integrate(airframe, &w, DT);
        t += DT;
    }
    t
}

#[test]
fn a_twenty_metre_free_fall_takes_the_analytic_time() {
    // Drag off: the analytic time is sqrt(2 h / g).
    let mut airframe = physics_of("x500");
    airframe.drag_coeff_linear = Vector3::zeros();
    airframe.drag_coeff_quadratic = Vector3::zeros();
    let t = fall_time_s(&airframe, 20.0);
    let analytic = (2.0 * 20.0 / GRAVITY_MPS2).sqrt();
    assert!((t - analytic).abs() / analytic < 0.01, "fell in {t:.4} s, analytic {analytic:.4} s");
    // With the airframe's drag the same fall is slower, never faster.
    let t_drag = fall_time_s(&physics_of("x500"), 20.0);
    assert!(t_drag > t, "drag {t_drag:.3} s vs vacuum {t:.3} s");
}

#[test]
fn without_control_a_drone_drifts_downwind() {
    let airframe = physics_of("x500");
    let mut motors = Motor::for_airframe(&airframe);
    for m in &mut motors {
        m.set_omega(airframe.hover_omega_rad_s());
    }
    let mut state = RigidState::at_rest(Vector3::new(0.0, 0.0, 50.0));
    let wind_from_west = Vector3::new(10.0, 0.0, 0.0); // blowing toward +east
    for _ in 0..5_000 {
        let w =
            wrench(&airframe, &motors, &state.attitude, &state.velocity_enu_mps, &state.rate_body_rps, &wind_from_west);
        state.integrate(&airframe, &w, DT);
    }
    assert!(state.position_enu_m.x > 10.0, "after 5 s in a 10 m/s wind: {:?}", state.position_enu_m);
    assert!(state.velocity_enu_mps.x > 3.0 && state.position_enu_m.y.abs() < 1.0, "{state:?}");
}

// ---------------------------------------------------------------------------------------
// Whole stack: shard with world, environment, sensors, estimator, navigator, control
// ---------------------------------------------------------------------------------------

/// Drone 0's events and true state every 10 ms.
fn fly(run: &sadesim_crds::SimulationRun, seconds: u64) -> (Vec<Event>, Vec<DroneSnapshot>) {
    sadesim_integration_tests::fly(run, seconds, 10)
}

fn horizontal(a: [f64; 3], e: f64, n: f64) -> f64 {
    (a[0] - e).hypot(a[1] - n)
}

#[test]
fn takeoff_to_30_m_settles_within_half_a_metre() {
    // Judged over ten noise realizations (`SEEDS`): the median flight settles within
    // 0.5 m, and no realization strays twice as far. What remains is mostly the height
    // estimate's error at arming (home altitude), which the arming check bounds.
    let worst = over_seeds(|seed| {
        let run = RunBuilder::test()
            .with_seed(seed)
            .with(|r| {
                r.spec.fleet[0].mission = Some(Mission {
                    items: vec![MissionItem::Takeoff { altitude_agl_m: 30.0 }, MissionItem::Loiter { hold_s: 60.0 }],
                    speed_mps: None,
                })
            })
            .build();
        let (_, track) = fly(&run, 50);
        // Takeoff climbs at 1.5 m/s: 20 s. From 30 s on, the altitude has settled.
        track[3000..].iter().map(|s| (s.height_agl_m - 30.0).abs()).fold(0.0, f64::max)
    });
    let m = median(&worst);
    assert!(m < 0.5, "altitude above ground strays a median {m:.2} m from 30 m after settling: {worst:.2?}");
    assert!(worst.iter().all(|w| *w < 1.0), "one realization strays 1 m or more: {worst:.2?}");
}

#[test]
fn a_four_waypoint_mission_visits_each_waypoint_within_one_and_a_half_metres_and_rtl_lands_home() {
    // Judged over ten noise realizations (`SEEDS`, each with its own home): every flight
    // visits every waypoint and lands; the median closest approach to each waypoint is
    // within 1.5 m and the median landing within 2 m of home (GNSS noise 0.5 m and a
    // wandering bias move each single flight by about as much).
    // The fixture's park reaches 500 m from its centre, as far as homes go: 100 m more
    // keeps every home's square clear of buildings.
    let wider_park = |r: &mut sadesim_crds::SimulationRun| {
        if let Some(world) = &mut r.spec.world {
            world.open_areas[0].radius_m = 600.0;
        }
    };
    let flights = over_seeds(|seed| {
        let run0 = RunBuilder::test().with_seed(seed).with(wider_park).build();
        let p0 = plan(&run0);
        let home = p0.drones[0].home.local;
        let frame = LocalFrame::new(run0.spec.origin.geo());
        // A 60 m square around home (the home area is kept free of buildings).
        let corners = [(40.0, 0.0), (40.0, 60.0), (-20.0, 60.0), (-20.0, 0.0)];
        let targets: Vec<(f64, f64)> = corners.iter().map(|(de, dn)| (home.east_m + de, home.north_m + dn)).collect();
        let mut items = vec![MissionItem::Takeoff { altitude_agl_m: 25.0 }];
        for (e, n) in &targets {
            let g = frame.to_geodetic(Enu::new(*e, *n, 0.0));
            items.push(MissionItem::Waypoint {
                latitude_deg: g.latitude_deg,
                longitude_deg: g.longitude_deg,
                altitude_agl_m: 25.0,
                hold_s: None,
            });
        }
        items.push(MissionItem::ReturnToLaunch {});
        let run = RunBuilder::test()
            .with_seed(seed)
            .with(wider_park)
            .with(|r| r.spec.fleet[0].mission = Some(Mission { items, speed_mps: Some(6.0) }))
            .build();
        let (events, track) = fly(&run, 150);
        assert!(!events.iter().any(|e| matches!(e.kind, EventKind::Crashed { .. })), "seed {seed}: {events:?}");
        let closest: Vec<f64> = targets
            .iter()
            .enumerate()
            .map(|(i, (e, n))| {
                assert!(
                    events.iter().any(|ev| ev.kind == EventKind::WaypointReached { seq: i as u32 + 1 }),
                    "seed {seed}: waypoint {i} reached"
                );
                track.iter().map(|s| horizontal(s.position_enu_m, *e, *n)).fold(f64::INFINITY, f64::min)
            })
            .collect();
        let last = track.last().unwrap();
        assert!(last.on_ground && !last.armed, "seed {seed}: landed and disarmed: {last:?}");
        (closest, horizontal(last.position_enu_m, home.east_m, home.north_m))
    });
    for i in 0..4 {
        let closest = median(&flights.iter().map(|f| f.0[i]).collect::<Vec<_>>());
        assert!(closest < 1.5, "waypoint {i}: median closest approach {closest:.2} m ({flights:.2?})");
    }
    let from_home = median(&flights.iter().map(|f| f.1).collect::<Vec<_>>());
    assert!(from_home < 2.0, "RTL landed a median {from_home:.2} m from home ({flights:.2?})");
}

#[test]
fn hold_in_a_steady_ten_metre_per_second_wind_stays_within_two_metres() {
    let run = RunBuilder::test()
        .with(|r| {
            r.spec.fleet[0].mission = Some(Mission {
                items: vec![MissionItem::Takeoff { altitude_agl_m: 30.0 }, MissionItem::Loiter { hold_s: 120.0 }],
                speed_mps: None,
            });
            r.spec.environment =
                Some(environment(serde_json::json!({"wind": {"speedMps": 10, "directionFromDeg": 270}})));
        })
        .build();
    let home = plan(&run).drones[0].home.local;
    let (_, track) = fly(&run, 80);
    // The hold point is above home; judge from 40 s (climb done, integrators settled).
    let worst =
        track[4000..].iter().map(|s| horizontal(s.position_enu_m, home.east_m, home.north_m)).fold(0.0, f64::max);
    assert!(worst < 2.0, "strayed {worst:.2} m from the hold point in a 10 m/s wind");
    // And the wind is really pushing: the drone leans west into it.
    let s = &track[6000];
    let [w, x, y, z] = s.attitude_wxyz;
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    assert!((q * Vector3::z()).x < -0.05, "body z axis {:?}", q * Vector3::z());
}

/// The physics of preset `name`.
fn physics_of(name: &str) -> Airframe {
    Preset::named(name).unwrap_or_else(|| panic!("no preset {name}")).airframe
}
