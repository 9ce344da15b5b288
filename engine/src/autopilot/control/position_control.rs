//! Position and velocity control, PX4's `mc_pos_control` `PositionControl` (and the
//! `ControlMath` helpers that turn its thrust vector into an attitude setpoint).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::pid::Pid;
use crate::vehicle::GRAVITY_MPS2;

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
