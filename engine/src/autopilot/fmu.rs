//! The flight management unit of one drone (PX4's FMU): estimator, navigator and
//! controller wired together, fed by the sensors each physics step.
//!
//! # Loop rates
//! The loops run at PX4's default rates, not all at the physics rate:
//! - the rate loop and the mixer every physics step (PX4 runs them on every gyro sample,
//!   400-800 Hz; our gyro is sampled at the physics rate, 1 kHz by default);
//! - the attitude loop at [`ATTITUDE_LOOP_HZ`] (PX4 runs `mc_att_control` on each
//!   `vehicle_attitude`, published at `IMU_INTEG_RATE`, default 200 Hz);
//! - the navigator and the position and velocity loops at [`POSITION_LOOP_HZ`] (PX4's
//!   `mc_pos_control` takes every other `vehicle_local_position`: 50 Hz);
//! - the estimator every physics step.
//!
//! Each rate becomes the nearest whole number of physics steps (at least one); the setpoint
//! a slower loop computed is held until its next run. Every drone runs its slower loops on
//! the same step indices, so a run stays deterministic and independent of sharding.

use nalgebra::{UnitQuaternion, Vector3};

use crate::autopilot::control::{AttitudeTarget, ControlError, Controller, EstimatedState, Gains};
use crate::autopilot::estimator::{Estimate, Estimator, GnssFusion, GnssMeasurement};
use crate::autopilot::navigator::{Command, Navigator, NavigatorConfig, Rejection, VehicleStatus};
use crate::events::{EventKind, FlightMode};
use crate::sensors::{BaroSample, GnssFix, ImuSample};
use crate::vehicle::Airframe;

/// What the sensors delivered this step.
#[derive(Clone, Copy, Debug)]
pub struct SensorFrame<'a> {
    pub imu: &'a ImuSample,
    /// A fresh GNSS report (fix or no-fix) when one is due.
    pub gnss: Option<&'a GnssFix>,
    /// A fresh barometer reading when one is due.
    pub baro: Option<&'a BaroSample>,
}

/// The attitude loop's rate, Hz (PX4's `IMU_INTEG_RATE` default).
pub const ATTITUDE_LOOP_HZ: f64 = 200.0;
/// The navigator's and the position/velocity loops' rate, Hz (PX4's `mc_pos_control`).
pub const POSITION_LOOP_HZ: f64 = 50.0;

/// A loop's period in physics steps of `dt_s` seconds: the nearest whole number, at least 1.
fn steps_per_run(dt_s: f64, loop_hz: f64) -> u64 {
    ((1.0 / (dt_s * loop_hz)).round() as u64).max(1)
}

/// Estimator + navigator + controller.
#[derive(Debug)]
pub struct Fmu {
    estimator: Estimator,
    navigator: Navigator,
    controller: Controller,
    /// Ground altitude MSL at the run origin, to turn baro MSL altitude into ENU up.
    origin_alt_msl_m: f64,
    time_s: f64,
    /// What the outer loops last asked of the attitude loop; `None` while idle (motors
    /// stopped) and before their first run.
    target: Option<AttitudeTarget>,
    /// The attitude loop's last body rate setpoint, rad/s.
    rate_sp_body_rps: Vector3<f64>,
    /// The last motor commands, in [0, 1], rotor order.
    motor_commands: Vec<f64>,
    /// The step size (bits) the loop periods were computed for, and the periods in steps
    /// of the position and attitude loops; `None` before the first step (when the outer
    /// loops run, whatever the step's index).
    periods: Option<(u64, u64, u64)>,
}

impl Fmu {
    /// A drone of `airframe` whose controller flies `gains` (its preset's,
    /// [`crate::preset::Preset::gains`]).
    ///
    /// # Errors
    /// When no mixer exists for the airframe's rotor layout.
    pub fn new(
        airframe: &Airframe,
        gains: &Gains,
        home_enu_m: Vector3<f64>,
        config: NavigatorConfig,
        origin_alt_msl_m: f64,
    ) -> Result<Self, ControlError> {
        Ok(Self {
            estimator: Estimator::default(),
            navigator: Navigator::new(config, home_enu_m),
            controller: Controller::new(airframe, gains)?,
            origin_alt_msl_m,
            time_s: 0.0,
            target: None,
            rate_sp_body_rps: Vector3::zeros(),
            motor_commands: vec![0.0; airframe.rotors.len()],
            periods: None,
        })
    }

    pub fn mode(&self) -> FlightMode {
        self.navigator.mode()
    }
    pub fn is_armed(&self) -> bool {
        self.navigator.is_armed()
    }
    pub fn estimate(&self) -> Option<Estimate> {
        self.estimator.estimate()
    }
    /// Ready for a pilot: a position estimate whose height reference has settled (what
    /// the arming check asks, short of the battery and being on the ground).
    pub fn is_ready(&self) -> bool {
        self.estimator.estimate().is_some() && self.estimator.height_settled()
    }
    /// The flight controller (its stages' gains and limits, for inspection).
    pub fn controller(&self) -> &Controller {
        &self.controller
    }
    pub fn navigator(&self) -> &Navigator {
        &self.navigator
    }
    pub fn take_events(&mut self) -> Vec<EventKind> {
        self.navigator.take_events()
    }

    /// Whether [`Fmu::take_events`] has anything.
    pub fn has_events(&self) -> bool {
        self.navigator.has_events()
    }

    fn status(&self, on_ground: bool, battery_remaining: f64) -> VehicleStatus {
        VehicleStatus {
            on_ground,
            battery_remaining,
            gnss_healthy: self.estimator.gnss_healthy(self.time_s),
            height_settled: self.estimator.height_settled(),
        }
    }

    /// Arming checks pass (what SYS_STATUS reports as the pre-arm check).
    pub fn armable(&self, on_ground: bool, battery_remaining: f64) -> bool {
        if !on_ground || self.navigator.is_armed() {
            return false; // asked every 10 ms of flight: skip the checks' message formatting
        }
        let est = self.estimator.estimate();
        self.navigator.arming_check(est.as_ref(), &self.status(on_ground, battery_remaining)).is_ok()
    }
    pub fn navigator_mut(&mut self) -> &mut Navigator {
        &mut self.navigator
    }

    /// Handles a pilot command.
    ///
    /// # Errors
    /// The navigator's [`Rejection`].
    pub fn command(&mut self, cmd: Command, on_ground: bool, battery_remaining: f64) -> Result<(), Rejection> {
        let est = self.estimator.estimate();
        let status = self.status(on_ground, battery_remaining);
        self.navigator.command(cmd, self.time_s, est.as_ref(), &status)
    }

    /// One physics step, the `step`-th, ending at sim time `time_s`: fuse the sensors, and
    /// run each loop whose turn it is (see the module's notes on loop rates). Returns the
    /// motor commands in [0, 1], rotor order. `attitude` is the AHRS attitude (see the
    /// estimator's notes).
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        step: u64,
        time_s: f64,
        dt_s: f64,
        sensors: SensorFrame<'_>,
        attitude: UnitQuaternion<f64>,
        on_ground: bool,
        battery_remaining: f64,
    ) -> &[f64] {
        self.time_s = time_s;
        self.estimator.predict(sensors.imu.accel_body_mps2, sensors.imu.gyro_body_rps, attitude, dt_s);
        if let Some(fix) = sensors.gnss.filter(|f| f.has_3d_fix()) {
            let fusion = self.estimator.fuse_gnss(
                time_s,
                &GnssMeasurement {
                    position_enu_m: fix.position_enu_m,
                    velocity_enu_mps: fix.velocity_enu_mps,
                    eph_m: fix.eph_m,
                    epv_m: fix.epv_m,
                    velocity_sigma_mps: fix.velocity_sigma_mps,
                },
            );
            if let GnssFusion::Reset(delta) = fusion {
                self.navigator.shift_for_estimate_reset(delta);
            }
        }
        if let Some(baro) = sensors.baro {
            self.estimator.fuse_baro(time_s, baro.alt_msl_m - self.origin_alt_msl_m);
        }
        let est = self.estimator.estimate();
        let state = match est {
            Some(e) => EstimatedState::from(&e),
            None => EstimatedState {
                position_enu_m: Vector3::zeros(),
                velocity_enu_mps: Vector3::zeros(),
                attitude,
                rate_body_rps: sensors.imu.gyro_body_rps,
            },
        };
        let first_step = self.periods.is_none();
        let (position_every, attitude_every) = match self.periods {
            Some((bits, position_every, attitude_every)) if bits == dt_s.to_bits() => (position_every, attitude_every),
            _ => {
                let periods = (steps_per_run(dt_s, POSITION_LOOP_HZ), steps_per_run(dt_s, ATTITUDE_LOOP_HZ));
                self.periods = Some((dt_s.to_bits(), periods.0, periods.1));
                periods
            }
        };
        let outer_turn = first_step || step.is_multiple_of(position_every);
        if outer_turn {
            let status = self.status(on_ground, battery_remaining);
            let setpoint = self.navigator.update(time_s, est.as_ref(), &status);
            self.target = self.controller.outer_loops(setpoint, &state, dt_s * position_every as f64);
        }
        let Some(target) = self.target else {
            self.motor_commands.iter_mut().for_each(|u| *u = 0.0);
            return &self.motor_commands;
        };
        // A new attitude setpoint is acted on at once (PX4's attitude loop runs on the next
        // attitude sample, at most one physics step later).
        if outer_turn || step.is_multiple_of(attitude_every) {
            self.rate_sp_body_rps = self.controller.attitude_loop(&target, &state);
        }
        self.controller.rate_loop(
            &self.rate_sp_body_rps,
            target.thrust_n,
            &state.rate_body_rps,
            dt_s,
            &mut self.motor_commands,
        );
        &self.motor_commands
    }
}

#[cfg(test)]
mod tests {
    use super::{ATTITUDE_LOOP_HZ, POSITION_LOOP_HZ, steps_per_run};

    #[test]
    fn loop_periods_are_whole_physics_steps() {
        // 1 kHz physics: attitude every 5 steps (200 Hz), position every 20 (50 Hz).
        assert_eq!(steps_per_run(0.001, ATTITUDE_LOOP_HZ), 5);
        assert_eq!(steps_per_run(0.001, POSITION_LOOP_HZ), 20);
        // 250 Hz physics: the attitude loop at the physics rate, position every 5 steps.
        assert_eq!(steps_per_run(0.004, ATTITUDE_LOOP_HZ), 1);
        assert_eq!(steps_per_run(0.004, POSITION_LOOP_HZ), 5);
        // Slower physics than a loop: the loop runs every step, never less.
        assert_eq!(steps_per_run(0.05, POSITION_LOOP_HZ), 1);
    }
}
