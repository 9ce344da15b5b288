//! The built-in flight controller: estimator, cascaded control, modes, failsafes.

pub mod control;
pub mod estimator;
pub mod fmu;
pub mod geofence;
pub mod mission;
pub mod navigator;

pub use control::{ControlOutput, Controller, EstimatedState, Setpoint};
