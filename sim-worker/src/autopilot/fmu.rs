//! The flight management unit of one drone (PX4's FMU): estimator, navigator and
//! controller wired together, fed by the sensors each physics step.

use nalgebra::{UnitQuaternion, Vector3};

use crate::autopilot::control::{ControlError, ControlOutput, Controller, EstimatedState, Gains};
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

/// Estimator + navigator + controller.
#[derive(Debug)]
pub struct Fmu {
    estimator: Estimator,
    navigator: Navigator,
    controller: Controller,
    /// Ground altitude MSL at the run origin, to turn baro MSL altitude into ENU up.
    origin_alt_msl_m: f64,
    time_s: f64,
}

impl Fmu {
    /// A drone of `airframe` whose controller flies `gains` (its preset's,
    /// [`crate::vehicle::Preset::gains`]).
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

    fn status(&self, on_ground: bool, battery_remaining: f64) -> VehicleStatus {
        VehicleStatus { on_ground, battery_remaining, gnss_healthy: self.estimator.gnss_healthy(self.time_s) }
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

    /// One control step at sim time `time_s`: fuse the sensors, advance the modes, run the
    /// control cascade. `attitude` is the AHRS attitude (see the estimator's notes).
    pub fn step(
        &mut self,
        time_s: f64,
        dt_s: f64,
        sensors: SensorFrame<'_>,
        attitude: UnitQuaternion<f64>,
        on_ground: bool,
        battery_remaining: f64,
    ) -> ControlOutput {
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
            self.estimator.fuse_baro(baro.alt_msl_m - self.origin_alt_msl_m);
        }
        let est = self.estimator.estimate();
        let status = self.status(on_ground, battery_remaining);
        let setpoint = self.navigator.update(time_s, est.as_ref(), &status);
        let state = match est {
            Some(e) => EstimatedState::from(&e),
            None => EstimatedState {
                position_enu_m: Vector3::zeros(),
                velocity_enu_mps: Vector3::zeros(),
                attitude,
                rate_body_rps: sensors.imu.gyro_body_rps,
            },
        };
        self.controller.update(setpoint, &state, dt_s)
    }
}
