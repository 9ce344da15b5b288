use nalgebra::{UnitQuaternion, Vector3};

use super::*;
use crate::vehicle::{Airframe, GRAVITY_MPS2, Motor, RigidState, Wrench, preset, wrench, yaw_of};
use std::f64::consts::FRAC_PI_2;

const DT_S: f64 = 1e-3;
const PRESETS: [&str; 2] = ["x500", "mini250"];

/// Closed loop: perfect state → controller → motor lag → wrench → reference integrator.
struct Sim {
    airframe: Airframe,
    controller: Controller,
    motors: Vec<Motor>,
    state: RigidState,
    wind_enu_mps: Vector3<f64>,
    time_s: f64,
}

impl Sim {
    /// Hovering (motors at hover speed), level, facing east, at `position_enu_m`.
    fn hovering(name: &str, position_enu_m: Vector3<f64>) -> Self {
        let airframe = preset(name).unwrap();
        Self::hovering_with(&Gains::for_airframe(&airframe), name, position_enu_m)
    }

    fn hovering_with(gains: &Gains, name: &str, position_enu_m: Vector3<f64>) -> Self {
        let airframe = preset(name).unwrap();
        let mut motors = Motor::for_airframe(&airframe);
        motors.iter_mut().for_each(|m| m.set_omega(airframe.hover_omega_rad_s()));
        Self {
            controller: Controller::new(&airframe, gains).unwrap(),
            airframe,
            motors,
            state: RigidState::at_rest(position_enu_m),
            wind_enu_mps: Vector3::zeros(),
            time_s: 0.0,
        }
    }

    fn step(&mut self, setpoint: Setpoint) -> ControlOutput {
        let out = self.controller.update(setpoint, &EstimatedState::from(&self.state), DT_S);
        for (m, u) in self.motors.iter_mut().zip(&out.motor_commands) {
            m.step(*u, DT_S);
        }
        let s = &self.state;
        let w: Wrench = wrench(
            &self.airframe,
            &self.motors,
            &s.attitude,
            &s.velocity_enu_mps,
            &s.rate_body_rps,
            &self.wind_enu_mps,
        );
        self.state.integrate(&self.airframe, &w, DT_S);
        self.time_s += DT_S;
        out
    }

    /// Runs `duration_s`, calling `observe(time, state)` after every step.
    fn run(&mut self, setpoint: Setpoint, duration_s: f64, mut observe: impl FnMut(f64, &RigidState)) {
        let steps = (duration_s / DT_S).round() as usize;
        for _ in 0..steps {
            self.step(setpoint);
            observe(self.time_s, &self.state);
        }
    }
}

fn hold(position_enu_m: Vector3<f64>, yaw_rad: f64) -> Setpoint {
    Setpoint::Position { position_enu_m, yaw_rad, velocity_ff: Vector3::zeros() }
}

/// Time after which `error(t)` stays within `band`, given samples `(t, error)`.
fn settling_time_s(samples: &[(f64, f64)], band: f64) -> f64 {
    samples.iter().rev().find(|(_, e)| e.abs() > band).map_or(0.0, |(t, _)| *t)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    (a - b + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

// --- closed loop, both presets, 1 kHz --------------------------------------------------

#[test]
fn control_position_step_20m_east() {
    for name in PRESETS {
        let start = Vector3::new(0.0, 0.0, 30.0);
        let target = Vector3::new(20.0, 0.0, 30.0);
        let mut sim = Sim::hovering(name, start);
        let (mut err, mut overshoot_m, mut alt_dev_m, mut cross_m) = (Vec::new(), f64::MIN, 0.0f64, 0.0f64);
        sim.run(hold(target, 0.0), 15.0, |t, s| {
            let p = s.position_enu_m;
            err.push((t, (p - target).norm()));
            overshoot_m = overshoot_m.max(p.x - target.x);
            alt_dev_m = alt_dev_m.max((p.z - target.z).abs());
            cross_m = cross_m.max(p.y.abs());
        });
        let settle_s = settling_time_s(&err, 1.0);
        println!(
            "{name}: 20 m east: within 1 m after {settle_s:.2} s, overshoot {overshoot_m:.2} m, \
             altitude dev {alt_dev_m:.3} m, cross-track {cross_m:.3} m, final error {:.3} m",
            err.last().unwrap().1
        );
        assert!(settle_s < 10.0, "{name}: settled after {settle_s} s");
        assert!(overshoot_m < 2.0, "{name}: overshoot {overshoot_m} m");
        assert!(alt_dev_m < 1.0, "{name}: altitude deviation {alt_dev_m} m");
        assert!(err.last().unwrap().1 < 0.1);
    }
}

#[test]
fn control_climb_from_half_a_metre_to_30m() {
    for name in PRESETS {
        let target = Vector3::new(0.0, 0.0, 30.0);
        let mut sim = Sim::hovering(name, Vector3::new(0.0, 0.0, 0.5));
        let (mut err, mut overshoot_m, mut max_climb) = (Vec::new(), f64::MIN, 0.0f64);
        sim.run(hold(target, 0.0), 25.0, |t, s| {
            err.push((t, s.position_enu_m.z - target.z));
            overshoot_m = overshoot_m.max(s.position_enu_m.z - target.z);
            max_climb = max_climb.max(s.velocity_enu_mps.z);
        });
        let settle_s = settling_time_s(&err, 0.5);
        println!(
            "{name}: climb 0.5 -> 30 m: within 0.5 m after {settle_s:.2} s, overshoot {overshoot_m:.3} m, \
             peak climb {max_climb:.2} m/s (limit {})",
            sim.airframe.max_climb_mps
        );
        assert!(settle_s < 20.0, "{name}: settled after {settle_s} s");
        assert!(overshoot_m < 0.5, "{name}: overshoot {overshoot_m} m");
        assert!(max_climb < sim.airframe.max_climb_mps * 1.05);
    }
}

#[test]
fn control_yaw_step_90_degrees() {
    for name in PRESETS {
        let p = Vector3::new(0.0, 0.0, 30.0);
        let mut sim = Sim::hovering(name, p);
        let (mut err, mut overshoot_deg, mut drift_m) = (Vec::new(), 0.0f64, 0.0f64);
        sim.run(hold(p, FRAC_PI_2), 5.0, |t, s| {
            let e = angle_diff(yaw_of(&s.attitude), FRAC_PI_2).to_degrees();
            err.push((t, e));
            overshoot_deg = overshoot_deg.max(e);
            drift_m = drift_m.max((s.position_enu_m - p).norm());
        });
        let settle_s = settling_time_s(&err, 5.0);
        println!(
            "{name}: yaw 0 -> 90 deg: within 5 deg after {settle_s:.2} s, overshoot {overshoot_deg:.2} deg, \
             position drift {drift_m:.3} m"
        );
        assert!(settle_s < 3.0, "{name}: settled after {settle_s} s");
        assert!(err.last().unwrap().1.abs() < 0.5);
        assert!(drift_m < 0.3, "{name}: drift {drift_m} m");
    }
}

#[test]
fn control_hover_in_5_mps_wind() {
    for name in PRESETS {
        let p = Vector3::new(0.0, 0.0, 30.0);
        let mut sim = Sim::hovering(name, p);
        // 5 m/s from the south-west, blowing toward the north-east.
        sim.wind_enu_mps = Vector3::new(3.0, 4.0, 0.0);
        let (mut onset_peak_m, mut hold_peak_m) = (0.0f64, 0.0f64);
        let warmup_s = 10.0;
        sim.run(hold(p, 0.0), warmup_s + 30.0, |t, s| {
            let e = (s.position_enu_m - p).norm();
            if t <= warmup_s { onset_peak_m = onset_peak_m.max(e) } else { hold_peak_m = hold_peak_m.max(e) }
        });
        let i = Vector3::new(sim.controller.velocity.x.terms().i, sim.controller.velocity.y.terms().i, 0.0);
        println!(
            "{name}: 5 m/s wind: peak {onset_peak_m:.3} m at gust onset (first {warmup_s} s), \
             then {hold_peak_m:.4} m over 30 s; velocity I-term {:.3} m/s^2 toward {:.0} deg",
            i.norm(),
            i.y.atan2(i.x).to_degrees()
        );
        assert!(hold_peak_m < 0.3, "{name}: drifted {hold_peak_m} m");
        // The integrator carries the drag (pointing upwind), not a position offset.
        assert!(i.dot(&sim.wind_enu_mps) < 0.0);
    }
}

#[test]
fn control_wind_needs_the_integrator() {
    // Same wind without the velocity I-term: a steady offset d / (K_v K_p) remains.
    let name = "x500";
    let mut gains = Gains::for_airframe(&preset(name).unwrap());
    gains.velocity_xy.ki = 0.0;
    let p = Vector3::new(0.0, 0.0, 30.0);
    let mut sim = Sim::hovering_with(&gains, name, p);
    sim.wind_enu_mps = Vector3::new(3.0, 4.0, 0.0);
    sim.run(hold(p, 0.0), 15.0, |_, _| ());
    let offset_m = (sim.state.position_enu_m - p).norm();
    println!("{name}: 5 m/s wind without velocity I-term: steady offset {offset_m:.3} m");
    assert!(offset_m > 0.3, "{offset_m}");
}

#[test]
fn control_velocity_8_mps_north() {
    for name in PRESETS {
        let v_sp = Vector3::new(0.0, 8.0, 0.0);
        let mut sim = Sim::hovering(name, Vector3::new(0.0, 0.0, 30.0));
        let (mut err, mut late_max, mut alt_dev_m) = (Vec::new(), 0.0f64, 0.0f64);
        sim.run(Setpoint::Velocity { velocity_enu_mps: v_sp, yaw_rad: FRAC_PI_2 }, 10.0, |t, s| {
            let e = (s.velocity_enu_mps - v_sp).norm();
            err.push((t, e));
            if t >= 5.0 {
                late_max = late_max.max(e);
            }
            alt_dev_m = alt_dev_m.max((s.position_enu_m.z - 30.0).abs());
        });
        let settle_s = settling_time_s(&err, 0.5);
        println!(
            "{name}: 8 m/s north: within 0.5 m/s after {settle_s:.2} s, max error after 5 s {late_max:.3} m/s, \
             altitude dev {alt_dev_m:.3} m"
        );
        assert!(late_max < 0.5, "{name}: velocity error {late_max} m/s after 5 s");
    }
}

// --- stages -----------------------------------------------------------------------------

fn pid(kp: f64, ki: f64, kd: f64) -> Pid {
    Pid::new(PidGains { kp, ki, kd, integral_limit: 1.0, output_limit: 2.0 })
}

#[test]
fn control_pid_terms_and_anti_windup() {
    let mut p = pid(1.0, 10.0, 0.5);
    let out = p.update(0.5, 0.0, 0.01);
    assert_eq!(p.terms(), PidTerms { p: 0.5, i: 0.05, d: 0.0, output: 0.55 });
    assert_eq!(out, 0.55);
    // Derivative acts on the measurement: it rose by 0.1 in 0.01 s → −0.5 · 10.
    p.update(0.5, 0.1, 0.01);
    assert!((p.terms().d + 5.0).abs() < 1e-12);
    // Saturated output: integral frozen, output clamped.
    let mut p = pid(1.0, 10.0, 0.0);
    for _ in 0..1000 {
        p.update(5.0, 0.0, 0.01);
    }
    assert_eq!(p.terms().output, 2.0);
    assert!(p.terms().i < 0.1, "integral wound up to {}", p.terms().i);
    // Unsaturated but persistent: integral clamped at its limit.
    let mut p = pid(0.0, 10.0, 0.0);
    for _ in 0..1000 {
        p.update(0.5, 0.0, 0.01);
    }
    assert_eq!(p.terms().i, 1.0);
    p.reset();
    assert_eq!(p.terms(), PidTerms::default());
}

#[test]
fn control_position_limits_speed_keeping_direction() {
    let a = preset("x500").unwrap();
    let c = Controller::for_airframe(&a).unwrap();
    let v = c.position.update(&Vector3::new(300.0, 400.0, -100.0), &Vector3::zeros(), &Vector3::zeros());
    assert!((v.xy().norm() - a.max_horizontal_speed_mps).abs() < 1e-9);
    assert!((v.y / v.x - 4.0 / 3.0).abs() < 1e-12);
    assert_eq!(v.z, -a.max_descent_mps);
    let v = c.position.update(&Vector3::new(1.0, 0.0, 0.0), &Vector3::zeros(), &Vector3::new(0.5, 0.0, 0.1));
    assert!((v - Vector3::new(0.95 + 0.5, 0.0, 0.1)).norm() < 1e-12);
}

#[test]
fn control_thrust_vector_tilt_limit_and_vertical_priority() {
    for name in PRESETS {
        let a = preset(name).unwrap();
        let c = Controller::for_airframe(&a).unwrap();
        let hover = c.velocity.thrust_from_accel(&Vector3::zeros());
        assert!((hover.thrust_n - a.weight_n()).abs() < 1e-9);
        assert_eq!(hover.thrust_axis_enu, Vector3::z());
        // A huge horizontal demand: tilt capped, vertical component still carries the weight.
        let t = c.velocity.thrust_from_accel(&Vector3::new(100.0, 0.0, 0.0));
        let tilt = t.thrust_axis_enu.z.acos();
        assert!(tilt <= a.max_tilt_rad + 1e-9 && tilt > a.max_tilt_rad * 0.99, "{name}: tilt {tilt}");
        assert!((t.thrust_n * t.thrust_axis_enu.z - a.weight_n()).abs() < 1e-9);
        assert!(t.thrust_axis_enu.x > 0.0);
        // Climbing hard while tilted beyond the thrust limit: tilt gives way, not altitude.
        let t = c.velocity.thrust_from_accel(&Vector3::new(100.0, 0.0, 4.0));
        assert!(t.thrust_n <= c.velocity.thrust_max_n + 1e-9);
        let vertical = t.thrust_n * t.thrust_axis_enu.z;
        assert!((vertical - a.mass_kg * (4.0 + GRAVITY_MPS2)).abs() < 1e-6, "{name}: {vertical}");
        // Falling faster than gravity is not possible: minimum thrust.
        let t = c.velocity.thrust_from_accel(&Vector3::new(0.0, 0.0, -20.0));
        assert_eq!(t.thrust_n, c.velocity.thrust_min_n);
    }
}

#[test]
fn control_attitude_from_thrust_axis_and_yaw() {
    let q = attitude_from_thrust_axis(&Vector3::z(), FRAC_PI_2);
    assert!((q * Vector3::x() - Vector3::y()).norm() < 1e-12, "level, facing north");
    let axis = Vector3::new(0.3, -0.2, 1.0).normalize();
    for yaw in [-3.0, -1.0, 0.0, 0.5, 2.0] {
        let q = attitude_from_thrust_axis(&axis, yaw);
        assert!((q * Vector3::z() - axis).norm() < 1e-12);
        assert!(angle_diff(yaw_of(&q), yaw).abs() < 1e-9, "yaw {yaw} -> {}", yaw_of(&q));
    }
}

#[test]
fn control_attitude_error_rotates_the_right_way() {
    let c = Controller::for_airframe(&preset("x500").unwrap()).unwrap().attitude;
    let level = UnitQuaternion::identity();
    // Setpoint rolled right (about +x by a small angle): positive roll rate.
    let rate = c.update(&UnitQuaternion::from_euler_angles(0.1, 0.0, 0.0), &level);
    assert!((rate.x - 6.5 * 2.0 * 0.05f64.sin()).abs() < 1e-9 && rate.y.abs() < 1e-12, "{rate}");
    // Yaw-only error: yaw rate ≈ MC_YAW_P · error for small angles, no roll/pitch.
    let rate = c.update(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05), &level);
    assert!((rate.z - 2.8 * 0.05).abs() < 1e-3 && rate.xy().norm() < 1e-12, "{rate}");
    // Large errors are rate limited.
    let rate = c.update(&UnitQuaternion::from_euler_angles(1.5, 0.0, 3.0), &level);
    assert!(rate.x.abs() <= c.max_rate_roll_pitch_rad_s && rate.z.abs() <= c.max_rate_yaw_rad_s);
    // Upside-down setpoint (antiparallel thrust axes) still gives a finite command.
    let rate = c.update(&UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0), &level);
    assert!(rate.iter().all(|r| r.is_finite()) && rate.norm() > 1.0);
}

#[test]
fn control_mixer_reproduces_unsaturated_wrench() {
    for name in PRESETS {
        let a = preset(name).unwrap();
        let m = Mixer::new(&a).unwrap();
        let torque = Vector3::new(0.01, -0.02, 0.005) * a.mass_kg;
        let alloc = m.allocate(a.weight_n(), &torque);
        assert_eq!((alloc.roll_pitch_scale, alloc.yaw_scale), (1.0, 1.0));
        let mut motors = Motor::for_airframe(&a);
        for (mo, u) in motors.iter_mut().zip(m.mix(a.weight_n(), &torque)) {
            mo.set_omega(u * a.max_omega_rad_s);
        }
        let w =
            wrench(&a, &motors, &UnitQuaternion::identity(), &Vector3::zeros(), &Vector3::zeros(), &Vector3::zeros());
        assert!(w.force_world_n.norm() < 1e-9, "{name}: {}", w.force_world_n);
        assert!((w.torque_body_nm - torque).norm() < 1e-12, "{name}: {}", w.torque_body_nm);
    }
}

#[test]
fn control_mixer_gives_up_yaw_before_roll_and_pitch() {
    let a = preset("x500").unwrap();
    let m = Mixer::new(&a).unwrap();
    let tau = Vector3::new(1.0, 0.0, 5.0); // roll fits at hover thrust, this much yaw does not
    let alloc = m.allocate(a.weight_n(), &tau);
    assert_eq!(alloc.roll_pitch_scale, 1.0);
    assert!(alloc.yaw_scale < 0.1);
    let t = &alloc.rotor_thrust_n();
    let roll: f64 = t.iter().zip(&a.rotors).map(|(t, r)| t * r.position_body_m.y).sum();
    assert!((roll - 1.0).abs() < 1e-9, "roll torque kept: {roll}");
    // Too much roll even for the full range: scaled, sign kept, thrust shifted to fit.
    let alloc = m.allocate(a.weight_n(), &Vector3::new(10.0, 0.0, 0.0));
    assert!(alloc.roll_pitch_scale < 1.0);
    assert!(alloc.rotor_thrust_n().iter().all(|t| (0.0..=m.max_rotor_thrust_n + 1e-12).contains(t)));
    let roll: f64 = alloc.rotor_thrust_n().iter().zip(&a.rotors).map(|(t, r)| t * r.position_body_m.y).sum();
    assert!(roll > 0.9 * 2.0 * 0.174 * m.max_rotor_thrust_n, "full authority used: {roll}");
}

proptest::proptest! {
    /// Whatever is asked, rotor thrusts stay in range and the delivered torque is the
    /// requested one with roll/pitch and yaw each scaled by the reported factor.
    #[test]
    fn control_mixer_scales_but_never_distorts(
        frame in 0usize..2,
        thrust_fraction in 0.0f64..1.2,
        tx in -3.0f64..3.0, ty in -3.0f64..3.0, tz in -0.5f64..0.5,
    ) {
        let a = preset(PRESETS[frame]).unwrap();
        let m = Mixer::new(&a).unwrap();
        let scale = a.mass_kg / 2.0; // x500-sized torques for the x500, smaller for the mini
        let tau = Vector3::new(tx, ty, tz) * scale;
        let alloc = m.allocate(thrust_fraction * a.max_thrust_n(), &tau);
        let t = &alloc.rotor_thrust_n();
        proptest::prop_assert!(t.iter().all(|t| (0.0..=m.max_rotor_thrust_n).contains(t)));
        let mut delivered = Vector3::zeros();
        for (t, r) in t.iter().zip(&a.rotors) {
            delivered += r.position_body_m.cross(&Vector3::new(0.0, 0.0, *t));
            delivered.z += r.spin.reaction_sign() * a.torque_coeff_m * t;
        }
        let s = alloc.roll_pitch_scale;
        let expected = Vector3::new(s * tau.x, s * tau.y, alloc.yaw_scale * tau.z);
        proptest::prop_assert!((delivered - expected).norm() < 1e-9, "{} vs {}", delivered, expected);
        proptest::prop_assert!((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&alloc.yaw_scale));
    }

    /// The mixer's one-pass roll/pitch scale is bit for bit the scale of the definition,
    /// the minimum over every rotor pair (i, j) of `T_max / c0_j / (ratio_j − ratio_i)`.
    #[test]
    fn control_mixer_scale_equals_the_pairwise_definition(
        frame in 0usize..2,
        tx in -30.0f64..30.0, ty in -30.0f64..30.0,
    ) {
        let a = preset(PRESETS[frame]).unwrap();
        let m = Mixer::new(&a).unwrap();
        let tau = Vector3::new(tx, ty, 0.0);
        let ratio = |row: &[f64; 4]| (row[1] * tau.x + row[2] * tau.y) / row[0];
        let mut pairwise: f64 = 1.0;
        for row_j in &m.pinv {
            for row_i in &m.pinv {
                let spread = ratio(row_j) - ratio(row_i);
                if spread > 0.0 {
                    pairwise = pairwise.min(m.max_rotor_thrust_n / row_j[0] / spread);
                }
            }
        }
        let s = m.allocate(a.weight_n(), &tau).roll_pitch_scale;
        proptest::prop_assert_eq!(s.to_bits(), pairwise.to_bits(), "{} vs {}", s, pairwise);
    }
}

#[test]
fn control_mixer_rejects_rotors_that_cannot_yaw() {
    let mut a = preset("x500").unwrap();
    a.rotors.iter_mut().for_each(|r| r.spin = crate::vehicle::Spin::Cw);
    assert_eq!(Mixer::new(&a), Err(ControlError::Unallocatable("x500".to_owned())));
}

#[test]
fn control_mixer_refuses_more_rotors_than_it_carries() {
    let mut a = preset("x500").unwrap();
    let extra: Vec<_> = a.rotors.iter().chain(&a.rotors).cloned().collect();
    a.rotors = a.rotors.iter().chain(&extra).cloned().collect(); // 12 rotors
    let e = Mixer::new(&a).unwrap_err();
    assert_eq!(e, ControlError::TooManyRotors { name: "x500".into(), rotors: 12 });
    assert!(e.to_string().contains("12 rotors, at most 8"), "{e}");
}

#[test]
fn control_idle_stops_motors_and_resets() {
    let mut sim = Sim::hovering("mini250", Vector3::new(0.0, 0.0, 10.0));
    sim.run(hold(Vector3::new(1.0, 0.0, 10.0), 0.0), 1.0, |_, _| ());
    let out = sim.step(Setpoint::Idle);
    assert!(out.motor_commands.iter().all(|u| *u == 0.0));
    assert_eq!(sim.controller.velocity.x.terms(), PidTerms::default());
}

#[test]
fn control_attitude_setpoint_levels_and_holds_thrust() {
    let mut sim = Sim::hovering("x500", Vector3::new(0.0, 0.0, 30.0));
    sim.state.attitude = UnitQuaternion::from_euler_angles(0.3, -0.2, 0.0);
    let weight = sim.airframe.weight_n();
    let sp = Setpoint::Attitude { attitude: UnitQuaternion::identity(), thrust_n: weight };
    sim.run(sp, 2.0, |_, _| ());
    assert!(sim.state.attitude.angle() < 1e-3, "{}", sim.state.attitude.angle());
    let out = sim.step(sp);
    assert_eq!(out.accel_sp_enu_mps2, None);
    assert!(sim.state.velocity_enu_mps.z.abs() < 0.5);
}
