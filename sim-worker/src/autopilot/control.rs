//! Cascaded multicopter control, PX4 style: position → velocity → attitude → rate → mixer.
//!
//! Every stage is a plain struct with public gains and an `update` method (copper-rs style),
//! so each term can be logged and tested without a runtime; [`Controller`] wires them.
//!
//! # Frames and units
//! World ENU (m, m/s, m/s²), body FLU, attitude rotates body → world, rates in body axes
//! (rad/s), thrust in N, torques in N m. Yaw `ψ` is the ENU heading of body x: 0 = east,
//! π/2 = north (MAVLink's NED yaw converts at the MAVLink edge: `ψ_enu = π/2 − ψ_ned`).
//!
//! # Rates
//! PX4 runs the rate loop at the gyro rate (~1 kHz), attitude at ~250 Hz and position /
//! velocity at the estimator rate (~50-100 Hz). Here every stage runs at the physics step
//! (1 kHz by default): one code path, no resampling, at least as stable as the original.
//!
//! # Gains
//! [`Gains::px4_default`] are PX4's multicopter defaults where they exist in SI-like units
//! (`MPC_*`, `MC_*_P`). PX4's rate gains are in normalised torque; ours are angular
//! acceleration per rate error (rad/s² per rad/s) and the inertia converts them to torque,
//! so the same numbers fly any airframe. [`Gains::for_airframe`] adds per-preset tuning.

use nalgebra::{Matrix3, Matrix4, Quaternion, Rotation3, UnitQuaternion, Vector3, Vector4};

use crate::vehicle::{Airframe, GRAVITY_MPS2, RigidState};

/// Why a controller cannot be built for an airframe.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ControlError {
    /// The rotors cannot produce independent thrust, roll, pitch and yaw (for example all
    /// spin the same way, or they sit on one line).
    #[error("failed to build the mixer for airframe {0}: rotor layout cannot control thrust, roll, pitch and yaw")]
    Unallocatable(String),
}

// ---------------------------------------------------------------------------------------
// PID
// ---------------------------------------------------------------------------------------

/// Gains and limits of one PID axis (output units per error unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidGains {
    pub kp: f64,
    /// Per second.
    pub ki: f64,
    /// Seconds; applied to the measurement's rate of change, not the error's.
    pub kd: f64,
    /// Bound on the integral term's contribution (output units).
    pub integral_limit: f64,
    /// Bound on `|output|`.
    pub output_limit: f64,
}

/// The terms of the last [`Pid::update`], for logging.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PidTerms {
    pub p: f64,
    pub i: f64,
    pub d: f64,
    pub output: f64,
}

/// `out = kp e + ki ∫e − kd d(measurement)/dt`, clamped to `±output_limit`.
///
/// Anti-windup: the integral term is clamped to `±integral_limit` and is not integrated
/// while the output is saturated in the direction the error pushes (conditional
/// integration). Derivative on measurement: a setpoint step gives no derivative kick.
#[derive(Clone, Debug, PartialEq)]
pub struct Pid {
    pub gains: PidGains,
    integral: f64,
    prev_measurement: Option<f64>,
    last: PidTerms,
}

impl Pid {
    pub fn new(gains: PidGains) -> Self {
        Self { gains, integral: 0.0, prev_measurement: None, last: PidTerms::default() }
    }

    /// One step: `error = setpoint − measurement`; `dt_s > 0`.
    pub fn update(&mut self, error: f64, measurement: f64, dt_s: f64) -> f64 {
        let g = &self.gains;
        let p = g.kp * error;
        let d = match self.prev_measurement {
            Some(prev) if dt_s > 0.0 => -g.kd * (measurement - prev) / dt_s,
            _ => 0.0,
        };
        self.prev_measurement = Some(measurement);
        let unsaturated = p + self.integral + d;
        let pushing_into_limit =
            (unsaturated >= g.output_limit && error > 0.0) || (unsaturated <= -g.output_limit && error < 0.0);
        if !pushing_into_limit {
            self.integral = (self.integral + g.ki * error * dt_s).clamp(-g.integral_limit, g.integral_limit);
        }
        let output = (p + self.integral + d).clamp(-g.output_limit, g.output_limit);
        self.last = PidTerms { p, i: self.integral, d, output };
        output
    }

    /// Forgets the integral and the previous measurement.
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.prev_measurement = None;
        self.last = PidTerms::default();
    }

    pub fn terms(&self) -> PidTerms {
        self.last
    }
}

// ---------------------------------------------------------------------------------------
// Gains
// ---------------------------------------------------------------------------------------

/// Everything that tunes a [`Controller`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// Position error → velocity, 1/s (PX4 `MPC_XY_P`, `MPC_Z_P`).
    pub position_p_xy: f64,
    pub position_p_z: f64,
    /// Velocity error → acceleration, per horizontal axis (`MPC_XY_VEL_{P,I,D}_ACC`).
    pub velocity_xy: PidGains,
    /// Velocity error → acceleration, vertical (`MPC_Z_VEL_{P,I,D}_ACC`).
    pub velocity_z: PidGains,
    /// Vertical acceleration limits, m/s² (`MPC_ACC_UP_MAX`, `MPC_ACC_DOWN_MAX`).
    pub max_accel_up_mps2: f64,
    pub max_accel_down_mps2: f64,
    /// Collective thrust limits as fractions of the airframe's full thrust (`MPC_THR_MIN/MAX`).
    pub thrust_min_fraction: f64,
    pub thrust_max_fraction: f64,
    /// Attitude error → rate, 1/s (`MC_ROLL_P`, `MC_PITCH_P`, `MC_YAW_P`, `MC_YAW_WEIGHT`).
    pub attitude_p_roll_pitch: f64,
    pub attitude_p_yaw: f64,
    pub yaw_weight: f64,
    /// Body rate limits, rad/s (`MC_ROLLRATE_MAX`, `MC_YAWRATE_MAX`).
    pub max_rate_roll_pitch_rad_s: f64,
    pub max_rate_yaw_rad_s: f64,
    /// Rate error → angular acceleration, rad/s² per rad/s.
    pub rate_roll_pitch: PidGains,
    pub rate_yaw: PidGains,
}

impl Gains {
    /// PX4 v1.14 multicopter defaults (rate gains converted as explained in the module docs).
    pub fn px4_default() -> Self {
        Self {
            position_p_xy: 0.95,
            position_p_z: 1.0,
            velocity_xy: PidGains { kp: 1.8, ki: 0.4, kd: 0.2, integral_limit: 4.0, output_limit: 9.8 },
            velocity_z: PidGains { kp: 4.0, ki: 2.0, kd: 0.0, integral_limit: 4.0, output_limit: 4.0 },
            max_accel_up_mps2: 4.0,
            max_accel_down_mps2: 3.0,
            thrust_min_fraction: 0.12,
            thrust_max_fraction: 0.9,
            attitude_p_roll_pitch: 6.5,
            attitude_p_yaw: 2.8,
            yaw_weight: 0.4,
            max_rate_roll_pitch_rad_s: 220f64.to_radians(),
            max_rate_yaw_rad_s: 200f64.to_radians(),
            rate_roll_pitch: PidGains { kp: 20.0, ki: 10.0, kd: 0.0, integral_limit: 10.0, output_limit: 200.0 },
            rate_yaw: PidGains { kp: 10.0, ki: 5.0, kd: 0.0, integral_limit: 5.0, output_limit: 100.0 },
        }
    }

    /// The tuned gains for a preset (PX4 defaults for unknown names), with the horizontal
    /// acceleration limit `g tan(max_tilt)` taken from the airframe.
    pub fn for_airframe(airframe: &Airframe) -> Self {
        let mut g = Self::px4_default();
        g.velocity_xy.output_limit = GRAVITY_MPS2 * airframe.max_tilt_rad.tan();
        g
    }
}

// ---------------------------------------------------------------------------------------
// Position
// ---------------------------------------------------------------------------------------

/// Position error → velocity setpoint: `v_sp = K ⊙ (p_sp − p) + v_ff`, limited.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionController {
    pub gain_xy: f64,
    pub gain_z: f64,
    pub max_horizontal_speed_mps: f64,
    pub max_climb_mps: f64,
    pub max_descent_mps: f64,
}

impl PositionController {
    /// Velocity setpoint, ENU m/s.
    pub fn update(
        &self,
        position_sp_enu_m: &Vector3<f64>,
        position_enu_m: &Vector3<f64>,
        velocity_ff_enu_mps: &Vector3<f64>,
    ) -> Vector3<f64> {
        let e = position_sp_enu_m - position_enu_m;
        let v = Vector3::new(self.gain_xy * e.x, self.gain_xy * e.y, self.gain_z * e.z) + velocity_ff_enu_mps;
        self.limit_velocity(&v)
    }

    /// Scales the horizontal part down to the speed limit (keeping its direction) and clamps
    /// the vertical part to `[−max_descent, max_climb]`.
    pub fn limit_velocity(&self, v: &Vector3<f64>) -> Vector3<f64> {
        let h = v.xy().norm();
        let s = if h > self.max_horizontal_speed_mps { self.max_horizontal_speed_mps / h } else { 1.0 };
        Vector3::new(v.x * s, v.y * s, v.z.clamp(-self.max_descent_mps, self.max_climb_mps))
    }
}

// ---------------------------------------------------------------------------------------
// Velocity
// ---------------------------------------------------------------------------------------

/// What the velocity loop asks of the attitude loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThrustSetpoint {
    /// The velocity PIDs' output (after the vertical limits), ENU m/s².
    pub accel_sp_enu_mps2: Vector3<f64>,
    /// Desired body +z axis (unit), ENU.
    pub thrust_axis_enu: Vector3<f64>,
    /// Collective thrust, N.
    pub thrust_n: f64,
}

/// Velocity error → acceleration (PID per axis) → thrust vector.
///
/// Following PX4's `PositionControl`: the thrust axis points along `(a_x, a_y, g)`, limited
/// to `max_tilt_rad` from vertical, and the collective thrust `m (a_z + g) / cos(tilt)` makes
/// the vertical acceleration exact whatever the tilt. When that exceeds the thrust limit,
/// vertical wins: the tilt shrinks until the vertical component fits (PX4's vertical
/// priority), so altitude holds while manoeuvring hard.
#[derive(Clone, Debug, PartialEq)]
pub struct VelocityController {
    pub x: Pid,
    pub y: Pid,
    pub z: Pid,
    pub mass_kg: f64,
    pub max_tilt_rad: f64,
    pub thrust_min_n: f64,
    pub thrust_max_n: f64,
    pub max_accel_up_mps2: f64,
    pub max_accel_down_mps2: f64,
}

impl VelocityController {
    pub fn update(
        &mut self,
        velocity_sp_enu_mps: &Vector3<f64>,
        velocity_enu_mps: &Vector3<f64>,
        dt_s: f64,
    ) -> ThrustSetpoint {
        let e = velocity_sp_enu_mps - velocity_enu_mps;
        let v = velocity_enu_mps;
        let a = Vector3::new(
            self.x.update(e.x, v.x, dt_s),
            self.y.update(e.y, v.y, dt_s),
            self.z.update(e.z, v.z, dt_s).clamp(-self.max_accel_down_mps2, self.max_accel_up_mps2),
        );
        self.thrust_from_accel(&a)
    }

    /// Thrust axis and collective thrust for an acceleration setpoint (see the type docs).
    pub fn thrust_from_accel(&self, accel_sp_enu_mps2: &Vector3<f64>) -> ThrustSetpoint {
        let a = accel_sp_enu_mps2;
        let mut axis = limit_tilt(&Vector3::new(a.x, a.y, GRAVITY_MPS2).normalize(), self.max_tilt_rad);
        let vertical_n = self.mass_kg * (a.z + GRAVITY_MPS2);
        let mut thrust_n = vertical_n / axis.z;
        if thrust_n > self.thrust_max_n {
            thrust_n = self.thrust_max_n;
            axis = limit_tilt(&axis, (vertical_n / self.thrust_max_n).clamp(-1.0, 1.0).acos());
        }
        ThrustSetpoint { accel_sp_enu_mps2: *a, thrust_axis_enu: axis, thrust_n: thrust_n.max(self.thrust_min_n) }
    }

    pub fn reset(&mut self) {
        self.x.reset();
        self.y.reset();
        self.z.reset();
    }
}

/// Tilts a unit vector back toward +z so its angle from +z is at most `max_tilt_rad`.
fn limit_tilt(axis: &Vector3<f64>, max_tilt_rad: f64) -> Vector3<f64> {
    if axis.z >= max_tilt_rad.cos() {
        return *axis;
    }
    let h = axis.xy();
    let hn = h.norm();
    if hn < 1e-12 {
        return Vector3::z();
    }
    let (s, c) = max_tilt_rad.sin_cos();
    Vector3::new(h.x / hn * s, h.y / hn * s, c)
}

/// The attitude whose body +z is `thrust_axis_enu` and whose body x points along yaw `ψ`
/// as far as the tilt allows (PX4 `bodyzToAttitude`: `x_b = y_c × z_b` with
/// `y_c = (−sin ψ, cos ψ, 0)`).
pub fn attitude_from_thrust_axis(thrust_axis_enu: &Vector3<f64>, yaw_rad: f64) -> UnitQuaternion<f64> {
    let z = thrust_axis_enu.normalize();
    let (s, c) = yaw_rad.sin_cos();
    let x = Vector3::new(-s, c, 0.0).cross(&z);
    // Only degenerate when the thrust axis is horizontal, which the tilt limit excludes.
    let x = if x.norm() > 1e-9 { x.normalize() } else { Vector3::new(c, s, 0.0) };
    let y = z.cross(&x);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z])))
}

/// ENU yaw of an attitude: heading of body x projected on the horizontal plane, rad.
pub fn yaw_of(attitude: &UnitQuaternion<f64>) -> f64 {
    let x = attitude * Vector3::x();
    x.y.atan2(x.x)
}

// ---------------------------------------------------------------------------------------
// Attitude
// ---------------------------------------------------------------------------------------

/// Quaternion attitude error → body rate setpoint (PX4 `AttitudeControl`).
///
/// First the shortest rotation that aligns the thrust axis (roll/pitch, "reduced
/// attitude"), then only `yaw_weight` of the remaining yaw rotation is mixed in, so a yaw
/// error never disturbs the thrust direction; the yaw gain is divided by the weight to
/// compensate. Error `e = 2 · sign(q_e.w) · imag(q_e)`, `q_e = q⁻¹ q_sp`, rates `K ⊙ e`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeController {
    pub gain_roll_pitch: f64,
    pub gain_yaw: f64,
    pub yaw_weight: f64,
    pub max_rate_roll_pitch_rad_s: f64,
    pub max_rate_yaw_rad_s: f64,
}

impl AttitudeController {
    /// Body rate setpoint, rad/s.
    pub fn update(&self, attitude_sp: &UnitQuaternion<f64>, attitude: &UnitQuaternion<f64>) -> Vector3<f64> {
        let (q, qd) = (attitude, attitude_sp);
        let e_z = q * Vector3::z();
        let e_z_d = qd * Vector3::z();
        // Antiparallel thrust axes: fall back to full attitude control (PX4 does the same).
        let qd_red = UnitQuaternion::rotation_between(&e_z, &e_z_d).map_or(*qd, |r| r * q);
        let mut q_mix = (qd_red.inverse() * qd).into_inner();
        if q_mix.w < 0.0 {
            q_mix = -q_mix;
        }
        let w = self.yaw_weight.clamp(0.0, 1.0);
        let half_yaw_cos = (w * q_mix.w.clamp(-1.0, 1.0).acos()).cos();
        let half_yaw_sin = (w * q_mix.k.clamp(-1.0, 1.0).asin()).sin();
        let yaw_part = UnitQuaternion::new_normalize(Quaternion::new(half_yaw_cos, 0.0, 0.0, half_yaw_sin));
        let qe = q.inverse() * (qd_red * yaw_part);
        let sign = if qe.w < 0.0 { -1.0 } else { 1.0 };
        let e = qe.imag() * (2.0 * sign);
        let k_yaw = if w > 1e-4 { self.gain_yaw / w } else { self.gain_yaw };
        let (rp, y) = (self.max_rate_roll_pitch_rad_s, self.max_rate_yaw_rad_s);
        Vector3::new(
            (self.gain_roll_pitch * e.x).clamp(-rp, rp),
            (self.gain_roll_pitch * e.y).clamp(-rp, rp),
            (k_yaw * e.z).clamp(-y, y),
        )
    }
}

// ---------------------------------------------------------------------------------------
// Rate
// ---------------------------------------------------------------------------------------

/// Body rate error → torque: `τ = J ⊙ α_sp + ω × Jω`, with `α_sp` from one PID per axis
/// (rad/s² per rad/s) and the gyroscopic term fed forward, so gains are airframe-free.
#[derive(Clone, Debug, PartialEq)]
pub struct RateController {
    pub roll: Pid,
    pub pitch: Pid,
    pub yaw: Pid,
    pub inertia_kg_m2: Vector3<f64>,
}

impl RateController {
    /// Torque setpoint, body N m.
    pub fn update(&mut self, rate_sp_body_rps: &Vector3<f64>, rate_body_rps: &Vector3<f64>, dt_s: f64) -> Vector3<f64> {
        let e = rate_sp_body_rps - rate_body_rps;
        let w = rate_body_rps;
        let alpha = Vector3::new(
            self.roll.update(e.x, w.x, dt_s),
            self.pitch.update(e.y, w.y, dt_s),
            self.yaw.update(e.z, w.z, dt_s),
        );
        let j = &self.inertia_kg_m2;
        j.component_mul(&alpha) + w.cross(&j.component_mul(w))
    }

    pub fn reset(&mut self) {
        self.roll.reset();
        self.pitch.reset();
        self.yaw.reset();
    }
}

// ---------------------------------------------------------------------------------------
// Mixer
// ---------------------------------------------------------------------------------------

/// Per-rotor thrusts of one allocation and how much of the request survived saturation.
#[derive(Clone, Debug, PartialEq)]
pub struct Allocation {
    pub rotor_thrust_n: Vec<f64>,
    /// Factor applied to the roll/pitch torque (1 = as requested).
    pub roll_pitch_scale: f64,
    /// Factor applied to the yaw torque (1 = as requested).
    pub yaw_scale: f64,
}

/// Collective thrust + body torques → per-rotor commands, for any rotor layout.
///
/// The effectiveness matrix `B` (4 × n) maps rotor thrusts to (thrust, τx, τy, τz): column
/// `i` is `(1, r_y, −r_x, s_i k_m)` (`r × T ẑ` plus the reaction torque, `s_i` from
/// [`crate::vehicle::Spin::reaction_sign`]). The mixer uses the pseudo-inverse
/// `B⁺ = Bᵀ (B Bᵀ)⁻¹` (the exact inverse for a quad).
///
/// Saturation, in priority order: roll/pitch first (scaled down only if they alone do not
/// fit in `[0, T_max]`), then collective thrust (shifted to make room), then yaw (clipped
/// to what headroom is left). Commands invert `T = k_f (u ω_max)²`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mixer {
    /// Row `i` of `B⁺`: rotor `i`'s thrust per unit of (thrust, τx, τy, τz).
    pinv: Vec<[f64; 4]>,
    pub thrust_coeff_n_per_rad_s2: f64,
    pub max_omega_rad_s: f64,
    pub max_rotor_thrust_n: f64,
}

impl Mixer {
    /// # Errors
    /// [`ControlError::Unallocatable`] when `B Bᵀ` is singular or some rotor would not
    /// contribute to collective thrust.
    pub fn new(airframe: &Airframe) -> Result<Self, ControlError> {
        let km = airframe.torque_coeff_m;
        let columns: Vec<Vector4<f64>> = airframe
            .rotors
            .iter()
            .map(|r| {
                let p = r.position_body_m;
                Vector4::new(1.0, p.y, -p.x, r.spin.reaction_sign() * km)
            })
            .collect();
        let bbt: Matrix4<f64> = columns.iter().map(|c| c * c.transpose()).sum();
        let err = || ControlError::Unallocatable(airframe.name.clone());
        let inv = bbt.try_inverse().ok_or_else(err)?;
        let pinv: Vec<[f64; 4]> = columns.iter().map(|c| (inv * c).into()).collect();
        if pinv.iter().any(|row| row[0] <= 1e-9) || !pinv.iter().flatten().all(|x| x.is_finite()) {
            return Err(err());
        }
        Ok(Self {
            pinv,
            thrust_coeff_n_per_rad_s2: airframe.thrust_coeff_n_per_rad_s2,
            max_omega_rad_s: airframe.max_omega_rad_s,
            max_rotor_thrust_n: airframe.max_rotor_thrust_n(),
        })
    }

    /// Rotor thrusts for a collective thrust (N) and body torque (N m), saturation handled.
    pub fn allocate(&self, thrust_n: f64, torque_body_nm: &Vector3<f64>) -> Allocation {
        let t_max = self.max_rotor_thrust_n;
        let tau = torque_body_nm;
        // Roll/pitch thrust per unit of collective share, per rotor.
        let rp: Vec<f64> = self.pinv.iter().map(|r| r[1] * tau.x + r[2] * tau.y).collect();
        let ratio: Vec<f64> = rp.iter().zip(&self.pinv).map(|(rp, r)| rp / r[0]).collect();
        // Some collective F keeps F c0_i + s rp_i in [0, T_max] for all i iff, for all i, j,
        // s (ratio_j − ratio_i) ≤ T_max / c0_j: take the largest such s ≤ 1.
        let mut s: f64 = 1.0;
        for (j, row) in self.pinv.iter().enumerate() {
            for ri in &ratio {
                let spread = ratio[j] - ri;
                if spread > 0.0 {
                    s = s.min(t_max / row[0] / spread);
                }
            }
        }
        let lo = ratio.iter().map(|r| -s * r).fold(f64::NEG_INFINITY, f64::max);
        let hi = ratio.iter().zip(&self.pinv).map(|(r, row)| t_max / row[0] - s * r).fold(f64::INFINITY, f64::min);
        let f = if lo <= hi { thrust_n.clamp(lo, hi) } else { 0.5 * (lo + hi) };
        let mut t: Vec<f64> = rp.iter().zip(&self.pinv).map(|(rp, row)| f * row[0] + s * rp).collect();
        // Yaw gets what headroom is left.
        let mut k: f64 = 1.0;
        for (ti, row) in t.iter().zip(&self.pinv) {
            let y = row[3] * tau.z;
            if y > 0.0 {
                k = k.min((t_max - ti) / y);
            } else if y < 0.0 {
                k = k.min(-ti / y);
            }
        }
        let k = k.max(0.0);
        for (ti, row) in t.iter_mut().zip(&self.pinv) {
            *ti = (*ti + k * row[3] * tau.z).clamp(0.0, t_max);
        }
        Allocation { rotor_thrust_n: t, roll_pitch_scale: s, yaw_scale: k }
    }

    /// Normalised command in [0, 1] for one rotor's thrust: `sqrt(T / k_f) / ω_max`.
    pub fn command_for_thrust(&self, rotor_thrust_n: f64) -> f64 {
        ((rotor_thrust_n.max(0.0) / self.thrust_coeff_n_per_rad_s2).sqrt() / self.max_omega_rad_s).clamp(0.0, 1.0)
    }

    /// Per-rotor normalised commands for a collective thrust (N) and body torque (N m).
    pub fn mix(&self, thrust_n: f64, torque_body_nm: &Vector3<f64>) -> Vec<f64> {
        let mut a = self.allocate(thrust_n, torque_body_nm);
        a.rotor_thrust_n.iter_mut().for_each(|t| *t = self.command_for_thrust(*t));
        a.rotor_thrust_n
    }
}

// ---------------------------------------------------------------------------------------
// The cascade
// ---------------------------------------------------------------------------------------

/// What the flight mode asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Setpoint {
    /// Hold or go to a position (ENU m) with a yaw (ENU rad) and a velocity feed-forward
    /// (ENU m/s, zero when holding).
    Position { position_enu_m: Vector3<f64>, yaw_rad: f64, velocity_ff: Vector3<f64> },
    /// Track a velocity (ENU m/s, limited to the airframe's speeds) with a yaw (ENU rad).
    Velocity { velocity_enu_mps: Vector3<f64>, yaw_rad: f64 },
    /// Track an attitude (body → world) with a collective thrust (N).
    Attitude { attitude: UnitQuaternion<f64>, thrust_n: f64 },
    /// Motors stopped, all integrators reset (disarmed, landed).
    Idle,
}

/// The state the controller acts on (from the estimator, or the truth in tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatedState {
    pub position_enu_m: Vector3<f64>,
    pub velocity_enu_mps: Vector3<f64>,
    /// Body → world.
    pub attitude: UnitQuaternion<f64>,
    pub rate_body_rps: Vector3<f64>,
}

impl From<&RigidState> for EstimatedState {
    /// Perfect state: the simulation truth.
    fn from(s: &RigidState) -> Self {
        Self {
            position_enu_m: s.position_enu_m,
            velocity_enu_mps: s.velocity_enu_mps,
            attitude: s.attitude,
            rate_body_rps: s.rate_body_rps,
        }
    }
}

/// One control step's outputs and intermediate setpoints (for logging).
#[derive(Clone, Debug, PartialEq)]
pub struct ControlOutput {
    /// Per rotor, in [0, 1], rotor order of the airframe.
    pub motor_commands: Vec<f64>,
    /// Collective thrust setpoint before the mixer, N.
    pub thrust_n: f64,
    /// Torque setpoint before the mixer, body N m.
    pub torque_body_nm: Vector3<f64>,
    pub attitude_sp: UnitQuaternion<f64>,
    pub rate_sp_body_rps: Vector3<f64>,
    /// `None` when the setpoint bypasses the velocity loop (attitude, idle).
    pub velocity_sp_enu_mps: Option<Vector3<f64>>,
    /// `None` when the setpoint bypasses the velocity loop (attitude, idle).
    pub accel_sp_enu_mps2: Option<Vector3<f64>>,
}

/// The whole cascade for one vehicle. Each stage is public for inspection and tuning.
#[derive(Clone, Debug, PartialEq)]
pub struct Controller {
    pub position: PositionController,
    pub velocity: VelocityController,
    pub attitude: AttitudeController,
    pub rate: RateController,
    pub mixer: Mixer,
}

impl Controller {
    /// # Errors
    /// See [`Mixer::new`].
    pub fn new(airframe: &Airframe, gains: &Gains) -> Result<Self, ControlError> {
        let g = gains;
        Ok(Self {
            position: PositionController {
                gain_xy: g.position_p_xy,
                gain_z: g.position_p_z,
                max_horizontal_speed_mps: airframe.max_horizontal_speed_mps,
                max_climb_mps: airframe.max_climb_mps,
                max_descent_mps: airframe.max_descent_mps,
            },
            velocity: VelocityController {
                x: Pid::new(g.velocity_xy),
                y: Pid::new(g.velocity_xy),
                z: Pid::new(g.velocity_z),
                mass_kg: airframe.mass_kg,
                max_tilt_rad: airframe.max_tilt_rad,
                thrust_min_n: g.thrust_min_fraction * airframe.max_thrust_n(),
                thrust_max_n: g.thrust_max_fraction * airframe.max_thrust_n(),
                max_accel_up_mps2: g.max_accel_up_mps2,
                max_accel_down_mps2: g.max_accel_down_mps2,
            },
            attitude: AttitudeController {
                gain_roll_pitch: g.attitude_p_roll_pitch,
                gain_yaw: g.attitude_p_yaw,
                yaw_weight: g.yaw_weight,
                max_rate_roll_pitch_rad_s: g.max_rate_roll_pitch_rad_s,
                max_rate_yaw_rad_s: g.max_rate_yaw_rad_s,
            },
            rate: RateController {
                roll: Pid::new(g.rate_roll_pitch),
                pitch: Pid::new(g.rate_roll_pitch),
                yaw: Pid::new(g.rate_yaw),
                inertia_kg_m2: airframe.inertia_kg_m2,
            },
            mixer: Mixer::new(airframe)?,
        })
    }

    /// With [`Gains::for_airframe`].
    ///
    /// # Errors
    /// See [`Mixer::new`].
    pub fn for_airframe(airframe: &Airframe) -> Result<Self, ControlError> {
        Self::new(airframe, &Gains::for_airframe(airframe))
    }

    /// Forgets every integrator and derivative memory.
    pub fn reset(&mut self) {
        self.velocity.reset();
        self.rate.reset();
    }

    /// One control step of `dt_s` seconds.
    pub fn update(&mut self, setpoint: Setpoint, state: &EstimatedState, dt_s: f64) -> ControlOutput {
        let (velocity_sp, thrust_sp, yaw_rad) = match setpoint {
            Setpoint::Idle => {
                self.reset();
                return ControlOutput {
                    motor_commands: vec![0.0; self.mixer.pinv.len()],
                    thrust_n: 0.0,
                    torque_body_nm: Vector3::zeros(),
                    attitude_sp: state.attitude,
                    rate_sp_body_rps: Vector3::zeros(),
                    velocity_sp_enu_mps: None,
                    accel_sp_enu_mps2: None,
                };
            }
            Setpoint::Attitude { attitude, thrust_n } => {
                self.velocity.reset();
                return self.inner_loops(attitude, thrust_n.max(0.0), state, dt_s);
            }
            Setpoint::Position { position_enu_m, yaw_rad, velocity_ff } => {
                let v = self.position.update(&position_enu_m, &state.position_enu_m, &velocity_ff);
                (v, self.velocity.update(&v, &state.velocity_enu_mps, dt_s), yaw_rad)
            }
            Setpoint::Velocity { velocity_enu_mps, yaw_rad } => {
                let v = self.position.limit_velocity(&velocity_enu_mps);
                (v, self.velocity.update(&v, &state.velocity_enu_mps, dt_s), yaw_rad)
            }
        };
        let attitude_sp = attitude_from_thrust_axis(&thrust_sp.thrust_axis_enu, yaw_rad);
        let mut out = self.inner_loops(attitude_sp, thrust_sp.thrust_n, state, dt_s);
        out.velocity_sp_enu_mps = Some(velocity_sp);
        out.accel_sp_enu_mps2 = Some(thrust_sp.accel_sp_enu_mps2);
        out
    }

    /// Attitude → rate → mixer.
    fn inner_loops(
        &mut self,
        attitude_sp: UnitQuaternion<f64>,
        thrust_n: f64,
        state: &EstimatedState,
        dt_s: f64,
    ) -> ControlOutput {
        let rate_sp = self.attitude.update(&attitude_sp, &state.attitude);
        let torque = self.rate.update(&rate_sp, &state.rate_body_rps, dt_s);
        ControlOutput {
            motor_commands: self.mixer.mix(thrust_n, &torque),
            thrust_n,
            torque_body_nm: torque,
            attitude_sp,
            rate_sp_body_rps: rate_sp,
            velocity_sp_enu_mps: None,
            accel_sp_enu_mps2: None,
        }
    }
}
