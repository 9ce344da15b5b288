//! The whole cascade for one vehicle: setpoint → position → velocity → attitude → rate →
//! mixer, with the intermediate setpoints of every step for logging.

use nalgebra::{UnitQuaternion, Vector3};

use super::attitude_control::AttitudeController;
use super::control_allocation::{ControlError, Mixer};
use super::gains::Gains;
use super::pid::Pid;
use super::position_control::{PositionController, VelocityController, attitude_from_thrust_axis};
use super::rate_control::RateController;
use crate::vehicle::{Airframe, RigidState};

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

    /// One control step of `dt_s` seconds: every loop of the cascade at one rate (the
    /// controller's own tests fly it this way; the FMU runs the loops at PX4's rates with
    /// [`Controller::outer_loops`], [`Controller::attitude_loop`] and
    /// [`Controller::rate_loop`]).
    pub fn update(&mut self, setpoint: Setpoint, state: &EstimatedState, dt_s: f64) -> ControlOutput {
        let Some(target) = self.outer_loops(setpoint, state, dt_s) else {
            return ControlOutput {
                motor_commands: vec![0.0; self.mixer.pinv.len()],
                thrust_n: 0.0,
                torque_body_nm: Vector3::zeros(),
                attitude_sp: state.attitude,
                rate_sp_body_rps: Vector3::zeros(),
                velocity_sp_enu_mps: None,
                accel_sp_enu_mps2: None,
            };
        };
        let rate_sp = self.attitude_loop(&target, state);
        let mut motor_commands = vec![0.0; self.mixer.pinv.len()];
        let torque = self.rate_loop(&rate_sp, target.thrust_n, &state.rate_body_rps, dt_s, &mut motor_commands);
        ControlOutput {
            motor_commands,
            thrust_n: target.thrust_n,
            torque_body_nm: torque,
            attitude_sp: target.attitude_sp,
            rate_sp_body_rps: rate_sp,
            velocity_sp_enu_mps: target.velocity_sp_enu_mps,
            accel_sp_enu_mps2: target.accel_sp_enu_mps2,
        }
    }

    /// The outer loops (PX4's `mc_pos_control`): position → velocity → thrust vector →
    /// attitude setpoint, `dt_s` seconds after their previous run. `None` for
    /// [`Setpoint::Idle`]: motors stopped, every integrator reset.
    pub fn outer_loops(&mut self, setpoint: Setpoint, state: &EstimatedState, dt_s: f64) -> Option<AttitudeTarget> {
        let (velocity_sp, thrust_sp, yaw_rad) = match setpoint {
            Setpoint::Idle => {
                self.reset();
                return None;
            }
            Setpoint::Attitude { attitude, thrust_n } => {
                self.velocity.reset();
                return Some(AttitudeTarget {
                    attitude_sp: attitude,
                    thrust_n: thrust_n.max(0.0),
                    velocity_sp_enu_mps: None,
                    accel_sp_enu_mps2: None,
                });
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
        Some(AttitudeTarget {
            attitude_sp: attitude_from_thrust_axis(&thrust_sp.thrust_axis_enu, yaw_rad),
            thrust_n: thrust_sp.thrust_n,
            velocity_sp_enu_mps: Some(velocity_sp),
            accel_sp_enu_mps2: Some(thrust_sp.accel_sp_enu_mps2),
        })
    }

    /// The attitude loop (PX4's `mc_att_control`): body rate setpoint, rad/s.
    pub fn attitude_loop(&self, target: &AttitudeTarget, state: &EstimatedState) -> Vector3<f64> {
        self.attitude.update(&target.attitude_sp, &state.attitude)
    }

    /// The rate loop and the mixer (PX4's `mc_rate_control` and `control_allocator`):
    /// each rotor's command in [0, 1] into `motor_commands` (rotor order); returns the
    /// torque setpoint, body N m.
    pub fn rate_loop(
        &mut self,
        rate_sp_body_rps: &Vector3<f64>,
        thrust_n: f64,
        rate_body_rps: &Vector3<f64>,
        dt_s: f64,
        motor_commands: &mut [f64],
    ) -> Vector3<f64> {
        let torque = self.rate.update(rate_sp_body_rps, rate_body_rps, dt_s);
        let allocation = self.mixer.allocate(thrust_n, &torque);
        self.rate.set_mixer_saturation(&torque, &allocation);
        self.mixer.commands_into(&allocation, motor_commands);
        torque
    }
}

/// What the outer loops hand to the attitude loop (PX4's `vehicle_attitude_setpoint`),
/// held between their runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeTarget {
    /// Body → world.
    pub attitude_sp: UnitQuaternion<f64>,
    /// Collective thrust, N.
    pub thrust_n: f64,
    /// `None` when the setpoint bypasses the velocity loop (attitude).
    pub velocity_sp_enu_mps: Option<Vector3<f64>>,
    /// `None` when the setpoint bypasses the velocity loop (attitude).
    pub accel_sp_enu_mps2: Option<Vector3<f64>>,
}
