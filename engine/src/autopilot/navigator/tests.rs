use nalgebra::{UnitQuaternion, Vector2, Vector3};

use super::*;

/// A perfect, speed-limited vehicle: moves toward the position setpoint at up to 8 m/s and
/// rests on flat ground at z = 0. Enough to exercise the mode logic without physics.
struct Follower {
    p: Vector3<f64>,
    battery: f64,
    gnss: bool,
}

impl Follower {
    fn estimate(&self) -> Estimate {
        Estimate {
            position_enu_m: self.p,
            velocity_enu_mps: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            rate_body_rps: Vector3::zeros(),
            eph_m: 0.5,
            epv_m: 0.8,
        }
    }
    fn status(&self) -> VehicleStatus {
        VehicleStatus {
            on_ground: self.p.z <= 0.01,
            battery_remaining: self.battery,
            gnss_healthy: self.gnss,
            height_settled: true,
        }
    }
    fn track(&mut self, sp: &Setpoint, dt: f64) {
        if let Setpoint::Position { position_enu_m, .. } = sp {
            let d = position_enu_m - self.p;
            let step = d.norm().min(8.0 * dt);
            if d.norm() > 1e-12 {
                self.p += d / d.norm() * step;
            }
            self.p.z = self.p.z.max(0.0);
        }
    }
}

/// Runs `nav` for `seconds` at 100 Hz from `t0`, returning the end time and all events.
fn fly(nav: &mut Navigator, v: &mut Follower, t0: f64, seconds: f64) -> (f64, Vec<EventKind>) {
    let dt = 0.01;
    let mut t = t0;
    let mut events = Vec::new();
    while t < t0 + seconds {
        let sp = nav.update(t, Some(&v.estimate()), &v.status());
        v.track(&sp, dt);
        events.extend(nav.take_events());
        t += dt;
    }
    (t, events)
}

fn ready() -> (Navigator, Follower) {
    (
        Navigator::new(NavigatorConfig::default(), Vector3::zeros()),
        Follower { p: Vector3::zeros(), battery: 1.0, gnss: true },
    )
}

#[test]
fn arming_checks_refuse_with_a_reason() {
    let (mut nav, v) = ready();
    let err = nav.command(Command::Arm, 0.0, None, &v.status()).unwrap_err();
    assert!(err.to_string().contains("GNSS fix"), "{err}");
    let no_fix = VehicleStatus { gnss_healthy: false, ..v.status() };
    assert!(nav.command(Command::Arm, 0.0, Some(&v.estimate()), &no_fix).is_err());
    let unsettled = VehicleStatus { height_settled: false, ..v.status() };
    let err = nav.command(Command::Arm, 0.0, Some(&v.estimate()), &unsettled).unwrap_err();
    assert!(err.to_string().contains("height estimate not settled"), "{err}");
    let low = VehicleStatus { battery_remaining: 0.1, ..v.status() };
    assert!(nav.command(Command::Arm, 0.0, Some(&v.estimate()), &low).unwrap_err().to_string().contains("battery"));
    assert_eq!(
        nav.command(Command::Takeoff { altitude_rel_home_m: 10.0 }, 0.0, Some(&v.estimate()), &v.status()),
        Err(Rejection::NotArmed)
    );
    nav.command(Command::Arm, 0.0, Some(&v.estimate()), &v.status()).unwrap();
    assert!(nav.is_armed());
    assert_eq!(
        nav.take_events(),
        vec![EventKind::Armed, EventKind::ModeChanged { from: FlightMode::Idle, to: FlightMode::Hold }]
    );
}

#[test]
fn a_mission_flies_its_items_in_order_and_lands_disarmed() {
    let (mut nav, mut v) = ready();
    let plan = MissionPlan {
        items: vec![
            MissionItem::Takeoff { alt_rel_home_m: 20.0 },
            MissionItem::Waypoint { target_en_m: Vector2::new(50.0, 0.0), alt_rel_home_m: 25.0, hold_s: 1.0 },
            MissionItem::Loiter { hold_s: 2.0 },
            MissionItem::ReturnToLaunch,
        ],
        speed_mps: 5.0,
    };
    let s = v.status();
    nav.command(Command::Arm, 0.0, Some(&v.estimate()), &s).unwrap();
    nav.command(Command::LoadMission(plan), 0.0, Some(&v.estimate()), &s).unwrap();
    nav.command(Command::StartMission, 0.0, Some(&v.estimate()), &s).unwrap();
    let (_, events) = fly(&mut nav, &mut v, 0.0, 120.0);
    let reached: Vec<u32> = events
        .iter()
        .filter_map(|e| if let EventKind::WaypointReached { seq } = e { Some(*seq) } else { None })
        .collect();
    assert_eq!(reached, vec![0, 1, 2], "{events:?}");
    assert!(events.contains(&EventKind::Takeoff));
    assert!(events.contains(&EventKind::ModeChanged { from: FlightMode::Mission, to: FlightMode::ReturnToLaunch }));
    assert_eq!(
        &events[events.len() - 3..],
        &[
            EventKind::Landed,
            EventKind::Disarmed,
            // PX4 stays in AUTO.RTL through its final descent.
            EventKind::ModeChanged { from: FlightMode::ReturnToLaunch, to: FlightMode::Idle }
        ][..],
        "{events:?}"
    );
    assert!(!nav.is_armed());
    assert!(v.p.xy().norm() < 1.0, "landed back home: {:?}", v.p);
}

#[test]
fn the_rtl_climbs_to_its_altitude_before_returning() {
    let (mut nav, mut v) = ready();
    let s = v.status();
    nav.command(Command::Arm, 0.0, Some(&v.estimate()), &s).unwrap();
    nav.command(Command::Takeoff { altitude_rel_home_m: 10.0 }, 0.0, Some(&v.estimate()), &s).unwrap();
    let (t, _) = fly(&mut nav, &mut v, 0.0, 10.0);
    nav.command(
        Command::GoTo { target_en_m: Vector2::new(40.0, 0.0), altitude_rel_home_m: 10.0 },
        t,
        Some(&v.estimate()),
        &v.status(),
    )
    .unwrap();
    let (t, _) = fly(&mut nav, &mut v, t, 15.0);
    assert!((v.p.x - 40.0).abs() < 1.0);
    nav.command(Command::ReturnToLaunch, t, Some(&v.estimate()), &v.status()).unwrap();
    let (t, _) = fly(&mut nav, &mut v, t, 15.0);
    assert!(v.p.z > 29.0, "climbed to RTL altitude first: {:?}", v.p);
    fly(&mut nav, &mut v, t, 60.0);
    assert!(!nav.is_armed() && v.p.xy().norm() < 1.0);
}

#[test]
fn offboard_follows_setpoints_and_falls_back_to_hold_when_they_stop() {
    let (mut nav, mut v) = ready();
    let s = v.status();
    nav.command(Command::Arm, 0.0, Some(&v.estimate()), &s).unwrap();
    let target = Setpoint::Position {
        position_enu_m: Vector3::new(5.0, 5.0, 10.0),
        yaw_rad: 0.0,
        velocity_ff: Vector3::zeros(),
    };
    assert_eq!(
        nav.command(Command::StartOffboard, 0.0, Some(&v.estimate()), &s),
        Err(Rejection::NoOffboardSetpoint(1.0)),
        "no setpoint stream yet"
    );
    let mut t = 0.0;
    while t < 5.0 {
        nav.command(Command::OffboardSetpoint(target), t, Some(&v.estimate()), &v.status()).unwrap();
        if nav.mode() != FlightMode::Offboard {
            nav.command(Command::StartOffboard, t, Some(&v.estimate()), &v.status()).unwrap();
        }
        let sp = nav.update(t, Some(&v.estimate()), &v.status());
        v.track(&sp, 0.01);
        t += 0.01;
    }
    assert_eq!(nav.mode(), FlightMode::Offboard);
    assert!((v.p - Vector3::new(5.0, 5.0, 10.0)).norm() < 0.1);
    let (_, events) = fly(&mut nav, &mut v, t, 2.0);
    assert!(
        events.contains(&EventKind::Failsafe { reason: "offboardLost".into(), action: FlightMode::Hold }),
        "{events:?}"
    );
    assert_eq!(nav.mode(), FlightMode::Hold);
}

#[test]
fn gnss_loss_lands_and_low_battery_returns_once() {
    let (mut nav, mut v) = ready();
    let s = v.status();
    nav.command(Command::Arm, 0.0, Some(&v.estimate()), &s).unwrap();
    nav.command(Command::Takeoff { altitude_rel_home_m: 10.0 }, 0.0, Some(&v.estimate()), &s).unwrap();
    let (t, _) = fly(&mut nav, &mut v, 0.0, 10.0);
    v.battery = 0.12;
    let (t, events) = fly(&mut nav, &mut v, t, 1.0);
    let rtl = EventKind::Failsafe { reason: "batteryLow".into(), action: FlightMode::ReturnToLaunch };
    assert_eq!(events.iter().filter(|e| **e == rtl).count(), 1, "{events:?}");
    assert_eq!(nav.mode(), FlightMode::ReturnToLaunch);
    v.gnss = false;
    let (_, events) = fly(&mut nav, &mut v, t, 1.0);
    assert!(
        events.contains(&EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land }),
        "{events:?}"
    );
    assert_eq!(nav.mode(), FlightMode::Land);
}
