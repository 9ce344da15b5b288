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
/// integration), whether by `output_limit` or by a downstream stage that reported it with
/// [`Pid::set_downstream_saturation`]. Derivative on measurement: a setpoint step gives no
/// derivative kick.
#[derive(Clone, Debug, PartialEq)]
pub struct Pid {
    pub gains: PidGains,
    integral: f64,
    prev_measurement: Option<f64>,
    /// Downstream saturation (upper, lower) reported after the last step.
    saturated: (bool, bool),
    last: PidTerms,
}

impl Pid {
    pub fn new(gains: PidGains) -> Self {
        Self { gains, integral: 0.0, prev_measurement: None, saturated: (false, false), last: PidTerms::default() }
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
        let (upper, lower) = self.saturated;
        let pushing_into_limit = ((upper || unsaturated >= g.output_limit) && error > 0.0)
            || ((lower || unsaturated <= -g.output_limit) && error < 0.0);
        if !pushing_into_limit {
            self.integral = (self.integral + g.ki * error * dt_s).clamp(-g.integral_limit, g.integral_limit);
        }
        let output = (p + self.integral + d).clamp(-g.output_limit, g.output_limit);
        self.last = PidTerms { p, i: self.integral, d, output };
        output
    }

    /// Tells the PID that what it drives could not deliver more (`upper`) or less (`lower`)
    /// than its last output, so the integral must not grow that way. Holds until changed.
    pub fn set_downstream_saturation(&mut self, upper: bool, lower: bool) {
        self.saturated = (upper, lower);
    }

    /// Forgets the integral, the previous measurement and any saturation.
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.prev_measurement = None;
        self.saturated = (false, false);
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
    /// PX4 v1.14 multicopter defaults for position, velocity, attitude and limits (`MPC_*`,
    /// `MC_*_P`, `MC_*RATE_MAX`); the rate gains are ours, in rad/s² per rad/s (PX4's are in
    /// normalised torque, see the module docs): rate-loop crossover ≈ 20 rad/s, well above
    /// the attitude loop's 6.5 rad/s and below the motors' 1/τ ≈ 40-100 rad/s.
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

    /// The gains for an airframe: [`Gains::px4_default`] with the horizontal acceleration
    /// limit `g tan(max_tilt)` taken from the airframe. Because the rate gains are scaled
    /// by the inertia, this one set passes the closed-loop tests for both presets (x500,
    /// mini250) unchanged; per-preset overrides go here, keyed on `airframe.name`.
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

    /// Stops the integrators winding up against the mixer: axes whose torque the mixer had
    /// to scale down (`scale < 1`) stop integrating in the direction of `torque_body_nm`.
    pub fn set_mixer_saturation(&mut self, torque_body_nm: &Vector3<f64>, allocation: &Allocation) {
        let flags = |tau: f64, scale: f64| (scale < 1.0 && tau > 0.0, scale < 1.0 && tau < 0.0);
        let (u, l) = flags(torque_body_nm.x, allocation.roll_pitch_scale);
        self.roll.set_downstream_saturation(u, l);
        let (u, l) = flags(torque_body_nm.y, allocation.roll_pitch_scale);
        self.pitch.set_downstream_saturation(u, l);
        let (u, l) = flags(torque_body_nm.z, allocation.yaw_scale);
        self.yaw.set_downstream_saturation(u, l);
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
        // Rank check on the correlation matrix (rows have different units: N vs N m).
        let d = bbt.diagonal().map(|x| if x > 0.0 { 1.0 / x.sqrt() } else { 0.0 });
        let correlation = Matrix4::from_diagonal(&d) * bbt * Matrix4::from_diagonal(&d);
        if correlation.symmetric_eigenvalues().min() < 1e-9 {
            return Err(err());
        }
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
        // Rotor i's roll/pitch thrust rp_i, and ratio_i = rp_i / c0_i (c0 = collective column).
        let rp = |row: &[f64; 4]| row[1] * tau.x + row[2] * tau.y;
        let ratio = |row: &[f64; 4]| rp(row) / row[0];
        // Some collective F keeps F c0_i + s rp_i in [0, T_max] for all i iff, for all i, j,
        // s (ratio_j − ratio_i) ≤ T_max / c0_j: take the largest such s ≤ 1.
        let mut s: f64 = 1.0;
        for row_j in &self.pinv {
            for row_i in &self.pinv {
                let spread = ratio(row_j) - ratio(row_i);
                if spread > 0.0 {
                    s = s.min(t_max / row_j[0] / spread);
                }
            }
        }
        let lo = self.pinv.iter().map(|row| -s * ratio(row)).fold(f64::NEG_INFINITY, f64::max);
        let hi = self.pinv.iter().map(|row| t_max / row[0] - s * ratio(row)).fold(f64::INFINITY, f64::min);
        let f = if lo <= hi { thrust_n.clamp(lo, hi) } else { 0.5 * (lo + hi) };
        let mut t: Vec<f64> = self.pinv.iter().map(|row| f * row[0] + s * rp(row)).collect();
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
        self.commands(self.allocate(thrust_n, torque_body_nm))
    }

    /// Normalised commands for an allocation's rotor thrusts (reuses its buffer).
    pub fn commands(&self, allocation: Allocation) -> Vec<f64> {
        let mut u = allocation.rotor_thrust_n;
        u.iter_mut().for_each(|t| *t = self.command_for_thrust(*t));
        u
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
        let allocation = self.mixer.allocate(thrust_n, &torque);
        self.rate.set_mixer_saturation(&torque, &allocation);
        ControlOutput {
            motor_commands: self.mixer.commands(allocation),
            thrust_n,
            torque_body_nm: torque,
            attitude_sp,
            rate_sp_body_rps: rate_sp,
            velocity_sp_enu_mps: None,
            accel_sp_enu_mps2: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vehicle::{Motor, Wrench, preset, wrench};
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
            let w = wrench(
                &a,
                &motors,
                &UnitQuaternion::identity(),
                &Vector3::zeros(),
                &Vector3::zeros(),
                &Vector3::zeros(),
            );
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
        let t = &alloc.rotor_thrust_n;
        let roll: f64 = t.iter().zip(&a.rotors).map(|(t, r)| t * r.position_body_m.y).sum();
        assert!((roll - 1.0).abs() < 1e-9, "roll torque kept: {roll}");
        // Too much roll even for the full range: scaled, sign kept, thrust shifted to fit.
        let alloc = m.allocate(a.weight_n(), &Vector3::new(10.0, 0.0, 0.0));
        assert!(alloc.roll_pitch_scale < 1.0);
        assert!(alloc.rotor_thrust_n.iter().all(|t| (0.0..=m.max_rotor_thrust_n + 1e-12).contains(t)));
        let roll: f64 = alloc.rotor_thrust_n.iter().zip(&a.rotors).map(|(t, r)| t * r.position_body_m.y).sum();
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
            let t = &alloc.rotor_thrust_n;
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
    }

    #[test]
    fn control_mixer_rejects_rotors_that_cannot_yaw() {
        let mut a = preset("x500").unwrap();
        a.rotors.iter_mut().for_each(|r| r.spin = crate::vehicle::Spin::Cw);
        assert_eq!(Mixer::new(&a), Err(ControlError::Unallocatable("x500".to_owned())));
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
}
