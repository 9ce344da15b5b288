//! Everything that tunes a [`super::Controller`]: PX4's multicopter defaults and the
//! derivation from an airframe's physics.

use super::pid::PidGains;
use crate::vehicle::{Airframe, GRAVITY_MPS2};

/// Everything that tunes a [`Controller`](super::Controller).
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
    /// mini250) unchanged. A preset flies its own record's gains
    /// ([`crate::preset::Preset::gains`], built with this function): per-preset tuning goes
    /// there, not here.
    pub fn for_airframe(airframe: &Airframe) -> Self {
        let mut g = Self::px4_default();
        g.velocity_xy.output_limit = GRAVITY_MPS2 * airframe.max_tilt_rad.tan();
        g
    }
}
