//! Airframe physics: mass, inertia, rotor geometry, motor and drag constants, flight limits.
//!
//! The physics of each preset is built here; the preset record itself (physics, PX4 id,
//! controller gains, parameter overrides) is `crate::preset::Preset`, a layer above.
//!
//! Frames: body **FLU** (x forward, y left, z up), origin at the centre of mass. Rotor
//! positions, inertia and drag coefficients are body-axis quantities.
//!
//! Motor model shared by all presets (see `motor.rs`): rotor thrust `T = k_f ω²` along body
//! +z, reaction (drag) torque `Q = k_m T` about body z, opposite to the rotor's spin.

use std::f64::consts::{PI, SQRT_2};

use nalgebra::Vector3;

/// Standard gravity, m/s² (the value PX4 uses as `CONSTANTS_ONE_G`).
pub const GRAVITY_MPS2: f64 = 9.80665;

/// Sea-level air density of the ISA, kg/m³ (used only to derive preset coefficients).
const AIR_DENSITY_KG_M3: f64 = 1.225;

/// Rotor spin direction, seen from above (looking down body -z).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spin {
    /// Counter-clockwise: rotation vector along body +z.
    Ccw,
    /// Clockwise: rotation vector along body -z.
    Cw,
}

impl Spin {
    /// Sign of the reaction torque the rotor puts on the body about body +z.
    ///
    /// The air brakes the rotor, so the motor pushes the body the other way: a CCW rotor
    /// (spinning +z) yaws the body toward -z (clockwise seen from above), a CW rotor toward +z.
    pub fn reaction_sign(self) -> f64 {
        match self {
            Spin::Ccw => -1.0,
            Spin::Cw => 1.0,
        }
    }
}

/// One rotor: where it is and which way it turns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotor {
    /// Rotor hub relative to the centre of mass, body FLU, m.
    pub position_body_m: Vector3<f64>,
    pub spin: Spin,
}

/// The flight battery.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatterySpec {
    /// Rated capacity, mAh.
    pub capacity_mah: f64,
    /// Cells in series (LiPo, 4.2 V full / 3.3 V empty each).
    pub cells: u32,
    /// Whole-pack internal resistance, Ω (voltage sag `I·R`).
    pub internal_resistance_ohm: f64,
    /// Constant electrical load of everything that is not a motor (FC, radio, camera), W.
    pub avionics_power_w: f64,
    /// Electrical-to-shaft efficiency of ESC + motor (rotor mechanical power / electrical).
    pub propulsion_efficiency: f64,
}

/// A multirotor's physical parameters and flight limits.
#[derive(Clone, Debug, PartialEq)]
pub struct Airframe {
    /// Preset name (`sadesim_crds::airframe::AIRFRAME_PRESETS`).
    pub name: String,
    pub mass_kg: f64,
    /// Principal moments of inertia about body x, y, z (diagonal tensor), kg m².
    pub inertia_kg_m2: Vector3<f64>,
    /// Rotors in the order of the motor outputs (PX4 order for the presets).
    pub rotors: Vec<Rotor>,
    /// `k_f` in `T = k_f ω²`, N/(rad/s)².
    pub thrust_coeff_n_per_rad_s2: f64,
    /// `k_m` in `Q = k_m T`, m.
    pub torque_coeff_m: f64,
    /// Rotor speed at full command, rad/s.
    pub max_omega_rad_s: f64,
    /// Motor lag time constant while speeding up, s.
    pub motor_time_constant_up_s: f64,
    /// Motor lag time constant while slowing down, s.
    pub motor_time_constant_down_s: f64,
    /// Linear drag per body axis: `F_i = -c_i v_i`, N per m/s (air-relative velocity).
    pub drag_coeff_linear: Vector3<f64>,
    /// Quadratic drag per body axis: `F_i = -c_i |v_i| v_i`, N per (m/s)².
    pub drag_coeff_quadratic: Vector3<f64>,
    /// Lumped rotational damping per body axis: `τ_i = -c_i ω_i`, N m per rad/s. Small.
    pub rotational_drag_coeff_nm_per_rad_s: Vector3<f64>,
    pub battery: BatterySpec,
    /// Largest tilt of the thrust axis the autopilot commands, rad.
    pub max_tilt_rad: f64,
    pub max_horizontal_speed_mps: f64,
    pub max_climb_mps: f64,
    pub max_descent_mps: f64,
}

impl Airframe {
    /// Weight `m g`, N.
    pub fn weight_n(&self) -> f64 {
        self.mass_kg * GRAVITY_MPS2
    }

    /// Thrust of one rotor at full speed, N.
    pub fn max_rotor_thrust_n(&self) -> f64 {
        self.thrust_coeff_n_per_rad_s2 * self.max_omega_rad_s * self.max_omega_rad_s
    }

    /// Thrust of all rotors at full speed, N.
    pub fn max_thrust_n(&self) -> f64 {
        self.max_rotor_thrust_n() * self.rotors.len() as f64
    }

    /// Full-throttle thrust over weight.
    pub fn thrust_to_weight(&self) -> f64 {
        self.max_thrust_n() / self.weight_n()
    }

    /// Rotor speed at which all rotors together carry the weight, rad/s.
    pub fn hover_omega_rad_s(&self) -> f64 {
        (self.weight_n() / (self.rotors.len() as f64 * self.thrust_coeff_n_per_rad_s2)).sqrt()
    }
}

/// For the vehicle's tests: the physics of a preset ([`crate::preset::Preset::airframe`]),
/// `None` for an unknown name.
#[cfg(test)]
pub(crate) fn preset(name: &str) -> Option<Airframe> {
    crate::preset::Preset::named(name).map(|p| p.airframe)
}

/// Holybro X500 V2 as PX4 simulates it: `Tools/simulation/gz/models/x500/model.sdf`.
///
/// Taken verbatim from the model: base mass 2.0 kg, ixx = iyy = 0.0216667, izz = 0.04;
/// rotors at (±0.174, ±0.174, 0.06) m; motorConstant 8.54858e-6; momentConstant 0.016;
/// maxRotVelocity 1000 rad/s; timeConstantUp/Down 0.0125/0.025 s. Rotor order and spin are
/// PX4's quad-X: 0 front-right CCW, 1 rear-left CCW, 2 front-left CW, 3 rear-right CW.
/// Full thrust 4 · 8.549 N = 34.2 N, so thrust/weight = 1.74 and hover is at 76 % of max ω.
///
/// Not in the model (it only has rotor drag): body drag chosen so that 12 m/s needs ~21°
/// of tilt (7.3 N), and vertical drag from the larger top area. Battery: the X500 kit's 4S
/// 5000 mAh LiPo, ~20 mΩ pack. Limits are PX4 defaults: MPC_TILTMAX_AIR 45°,
/// MPC_XY_VEL_MAX 12 m/s, MPC_Z_VEL_MAX_UP 3 m/s, MPC_Z_VEL_MAX_DN 1.5 m/s.
pub(crate) fn x500() -> Airframe {
    let a = 0.174;
    let h = 0.06;
    let rotor = |x: f64, y: f64, spin| Rotor { position_body_m: Vector3::new(x, y, h), spin };
    Airframe {
        name: "x500".to_owned(),
        mass_kg: 2.0,
        inertia_kg_m2: Vector3::new(0.0216667, 0.0216667, 0.04),
        rotors: vec![rotor(a, -a, Spin::Ccw), rotor(-a, a, Spin::Ccw), rotor(a, a, Spin::Cw), rotor(-a, -a, Spin::Cw)],
        thrust_coeff_n_per_rad_s2: 8.54858e-6,
        torque_coeff_m: 0.016,
        max_omega_rad_s: 1000.0,
        motor_time_constant_up_s: 0.0125,
        motor_time_constant_down_s: 0.025,
        drag_coeff_linear: Vector3::new(0.25, 0.25, 0.3),
        drag_coeff_quadratic: Vector3::new(0.03, 0.03, 0.06),
        rotational_drag_coeff_nm_per_rad_s: Vector3::new(2e-3, 2e-3, 1e-3),
        battery: BatterySpec {
            capacity_mah: 5000.0,
            cells: 4,
            internal_resistance_ohm: 0.02,
            avionics_power_w: 5.0,
            propulsion_efficiency: 0.7,
        },
        max_tilt_rad: 45f64.to_radians(),
        max_horizontal_speed_mps: 12.0,
        max_climb_mps: 3.0,
        max_descent_mps: 1.5,
    }
}

/// A sub-250 g folding quad (DJI Mini 2 class). No published model exists; derivation:
///
/// * Geometry: 213 mm motor-to-motor diagonal (DJI Mini 2 spec), taken as a square X, so each
///   rotor sits 0.1065 m from the centre at (±0.0753, ±0.0753) m. Same rotor order/spin as x500.
/// * Mass 0.249 kg split into a body box (fuselage, 2S battery, gimbal) of 0.161 kg,
///   0.14 × 0.08 × 0.055 m; four motor+prop point masses of 0.015 kg at the rotor hubs; four
///   0.007 kg arms as thin rods from the centre to the hub. Inertia = sum of the parts:
///   ≈ (5.2e-4, 7.0e-4, 1.14e-3) kg m² (computed below, not typed in).
/// * Thrust: 4726 props (D = 0.12 m), static thrust coefficient C_T ≈ 0.10 (typical small
///   two-blade prop, T = C_T ρ n² D⁴ with n in rev/s) gives k_f = C_T ρ D⁴ / (4π²) = 6.43e-7.
///   Hover then needs 974 rad/s (9,300 rpm); max ω = 1620 rad/s puts hover at 60 % of max ω
///   (thrust/weight 2.77; a thrust/weight of 2.0 would put hover at 71 % of max ω).
/// * Yaw: C_Q/C_T ≈ 0.07, so k_m = 0.07 · D = 0.0084 m (x500's 10" props: 0.016/0.254 = 0.063).
/// * Motors: lighter rotors than x500, time constants 10/20 ms up/down.
/// * Drag: 15 m/s needs ~26° of tilt (1.2 N, DJI's sport-mode top speed is 16 m/s).
/// * Battery: 2S 2450 mAh (Mini 3 class), ~60 mΩ; hover draws ~34 W, i.e. ~32 min.
/// * Limits: 35° tilt, 15 m/s, climb 5 m/s, descent 3.5 m/s (DJI Mini 2 published limits).
pub(crate) fn mini250() -> Airframe {
    let arm_m = 0.213 / 2.0;
    let xy = arm_m / SQRT_2;
    let (body_kg, body_m) = (0.161, Vector3::new(0.14, 0.08, 0.055));
    let (motor_kg, arm_rod_kg) = (0.015, 0.007);
    let rotors = vec![
        Rotor { position_body_m: Vector3::new(xy, -xy, 0.0), spin: Spin::Ccw },
        Rotor { position_body_m: Vector3::new(-xy, xy, 0.0), spin: Spin::Ccw },
        Rotor { position_body_m: Vector3::new(xy, xy, 0.0), spin: Spin::Cw },
        Rotor { position_body_m: Vector3::new(-xy, -xy, 0.0), spin: Spin::Cw },
    ];
    // Solid box: I_x = m (b² + c²) / 12, etc.
    let d2 = body_m.component_mul(&body_m);
    let mut inertia = Vector3::new(d2.y + d2.z, d2.x + d2.z, d2.x + d2.y) * (body_kg / 12.0);
    for r in &rotors {
        let p = r.position_body_m;
        let point = Vector3::new(p.y * p.y + p.z * p.z, p.x * p.x + p.z * p.z, p.x * p.x + p.y * p.y);
        // Point mass at the hub plus a thin rod from the centre to it (∫ over the rod = 1/3).
        inertia += point * (motor_kg + arm_rod_kg / 3.0);
    }
    let prop_diameter_m: f64 = 0.12;
    let thrust_coeff = 0.10 * AIR_DENSITY_KG_M3 * prop_diameter_m.powi(4) / (4.0 * PI * PI);
    Airframe {
        name: "mini250".to_owned(),
        mass_kg: body_kg + 4.0 * (motor_kg + arm_rod_kg),
        inertia_kg_m2: inertia,
        rotors,
        thrust_coeff_n_per_rad_s2: thrust_coeff,
        torque_coeff_m: 0.07 * prop_diameter_m,
        max_omega_rad_s: 1620.0,
        motor_time_constant_up_s: 0.010,
        motor_time_constant_down_s: 0.020,
        drag_coeff_linear: Vector3::new(0.02, 0.02, 0.03),
        drag_coeff_quadratic: Vector3::new(0.004, 0.004, 0.008),
        rotational_drag_coeff_nm_per_rad_s: Vector3::new(2e-5, 2e-5, 1e-5),
        battery: BatterySpec {
            capacity_mah: 2450.0,
            cells: 2,
            internal_resistance_ohm: 0.06,
            avionics_power_w: 5.0,
            propulsion_efficiency: 0.7,
        },
        max_tilt_rad: 35f64.to_radians(),
        max_horizontal_speed_mps: 15.0,
        max_climb_mps: 5.0,
        max_descent_mps: 3.5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> Vec<Airframe> {
        crate::preset::Preset::all().into_iter().map(|p| p.airframe).collect()
    }

    #[test]
    fn every_crds_preset_has_parameters() {
        // The one list of presets (`Preset::all`) covers the crds list, in the same order.
        let names: Vec<String> = all().into_iter().map(|a| a.name).collect();
        let crds: Vec<&str> = sadesim_crds::airframe::AIRFRAME_PRESETS.iter().map(|p| p.name).collect();
        assert_eq!(names, crds);
        for p in sadesim_crds::airframe::AIRFRAME_PRESETS {
            let a = preset(p.name).unwrap_or_else(|| panic!("no parameters for preset {}", p.name));
            assert_eq!(a.name, p.name);
        }
        assert!(preset("no-such-frame").is_none());
    }

    #[test]
    fn presets_can_hover_with_margin() {
        for a in all() {
            let tw = a.thrust_to_weight();
            let hover_fraction = a.hover_omega_rad_s() / a.max_omega_rad_s;
            assert!((1.6..=3.0).contains(&tw), "{}: thrust/weight {tw}", a.name);
            assert!((0.55..=0.8).contains(&hover_fraction), "{}: hover at {hover_fraction} of max ω", a.name);
        }
    }

    #[test]
    fn rotors_are_balanced_and_spins_cancel() {
        for a in all() {
            let centroid: Vector3<f64> = a.rotors.iter().map(|r| r.position_body_m).sum::<Vector3<f64>>();
            assert!(centroid.xy().norm() < 1e-9, "{}", a.name);
            let spin_sum: f64 = a.rotors.iter().map(|r| r.spin.reaction_sign()).sum();
            assert_eq!(spin_sum, 0.0, "{}", a.name);
        }
    }

    #[test]
    fn mini250_is_sub_250_g_with_plausible_inertia() {
        let a = preset("mini250").unwrap();
        assert!((a.mass_kg - 0.249).abs() < 1e-9, "{}", a.mass_kg);
        let i = a.inertia_kg_m2;
        assert!(i.x > 4e-4 && i.x < 7e-4 && i.y > 5e-4 && i.y < 9e-4 && i.z > 9e-4 && i.z < 1.4e-3, "{i}");
        // Perpendicular-axis theorem bound for a flat-ish body: Izz <= Ixx + Iyy.
        assert!(i.z <= i.x + i.y);
        let diagonal_m = 2.0 * a.rotors[0].position_body_m.xy().norm();
        assert!((diagonal_m - 0.213).abs() < 1e-9);
    }
}
