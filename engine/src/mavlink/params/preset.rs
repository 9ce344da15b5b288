//! The parameter values a drone's [`Preset`] determines: what its controller flies with,
//! under PX4's names and in PX4's units, its airframe id and its airframe file's overrides.
//!
//! Every value is read from the preset's [`Gains`](crate::autopilot::control::Gains) and
//! [`Airframe`](crate::vehicle::Airframe), the same values `Controller::new` builds the
//! drone's controller from; nothing here is a second copy of a gain.
//!
//! # Units
//! PX4 keeps angles and angular rates in degrees (MPC_TILTMAX_AIR, MC_*RATE_MAX), speeds in
//! m/s, the position and velocity gains in 1/s and (m/s²)/(m/s), as ours. PX4's rate gains
//! (MC_*RATE_P) are in normalised torque per rad/s; ours are angular acceleration per rad/s,
//! so they are converted with the airframe (see [`normalised_rate_gain`]).
//!
//! # Caveats
//! The x500's yaw loop is stiffer than PX4's: its MC_YAWRATE_P (≈ 1.46) is above PX4's
//! documented maximum 0.6. It is reported as flown; a write must still be inside PX4's range.

use crate::preset::Preset;
use crate::vehicle::Airframe;

/// `(PX4 name, value in PX4's unit)` of every parameter the preset determines, the preset's
/// airframe-file overrides last (an INT32 parameter takes the integer part).
pub fn values(preset: &Preset) -> Vec<(&'static str, f64)> {
    let (a, g) = (&preset.airframe, &preset.gains);
    let [roll_nm, pitch_nm, yaw_nm] = full_torques_nm(a);
    let mut values = vec![
        ("SYS_AUTOSTART", f64::from(preset.sys_autostart)),
        // Battery.
        ("BAT1_CAPACITY", a.battery.capacity_mah),
        ("BAT1_N_CELLS", f64::from(a.battery.cells)),
        // Attitude control (mc_att_control).
        ("MC_ROLL_P", g.attitude_p_roll_pitch),
        ("MC_PITCH_P", g.attitude_p_roll_pitch),
        ("MC_YAW_P", g.attitude_p_yaw),
        // Rate control (mc_rate_control).
        ("MC_ROLLRATE_MAX", g.max_rate_roll_pitch_rad_s.to_degrees()),
        ("MC_PITCHRATE_MAX", g.max_rate_roll_pitch_rad_s.to_degrees()),
        ("MC_YAWRATE_MAX", g.max_rate_yaw_rad_s.to_degrees()),
        ("MC_ROLLRATE_P", normalised_rate_gain(g.rate_roll_pitch.kp, a.inertia_kg_m2.x, roll_nm)),
        ("MC_PITCHRATE_P", normalised_rate_gain(g.rate_roll_pitch.kp, a.inertia_kg_m2.y, pitch_nm)),
        ("MC_YAWRATE_P", normalised_rate_gain(g.rate_yaw.kp, a.inertia_kg_m2.z, yaw_nm)),
        // Position control (mc_pos_control).
        ("MPC_XY_P", g.position_p_xy),
        ("MPC_Z_P", g.position_p_z),
        ("MPC_XY_VEL_P_ACC", g.velocity_xy.kp),
        ("MPC_Z_VEL_P_ACC", g.velocity_z.kp),
        ("MPC_TILTMAX_AIR", a.max_tilt_rad.to_degrees()),
        ("MPC_XY_VEL_MAX", a.max_horizontal_speed_mps),
        ("MPC_Z_VEL_MAX_UP", a.max_climb_mps),
        ("MPC_Z_VEL_MAX_DN", a.max_descent_mps),
    ];
    values.extend(preset.param_overrides.iter().copied());
    values
}

/// Torque about body x, y, z when the rotors that push that way run at full thrust and the
/// others are off, N m: `½ Σ |r_y| T_max`, `½ Σ |r_x| T_max`, `½ Σ k_m T_max` (half the
/// rotors of a symmetric layout push each way). PX4's normalised torque 1 on that axis.
fn full_torques_nm(airframe: &Airframe) -> [f64; 3] {
    let t_max = airframe.max_rotor_thrust_n();
    let sum = |arm_m: &dyn Fn(&crate::vehicle::Rotor) -> f64| {
        0.5 * airframe.rotors.iter().map(|r| arm_m(r).abs() * t_max).sum::<f64>()
    };
    [sum(&|r| r.position_body_m.y), sum(&|r| r.position_body_m.x), sum(&|_| airframe.torque_coeff_m)]
}

/// PX4's rate P gain (normalised torque per rad/s) of our gain `kp_per_s` (rad/s² per rad/s)
/// on an axis of inertia `inertia_kg_m2` whose full torque is `full_torque_nm`:
/// `τ = J kp e`, normalised `τ / τ_full`. The x500's roll gives 0.146 (PX4's default: 0.15).
pub fn normalised_rate_gain(kp_per_s: f64, inertia_kg_m2: f64, full_torque_nm: f64) -> f64 {
    inertia_kg_m2 * kp_per_s / full_torque_nm
}
