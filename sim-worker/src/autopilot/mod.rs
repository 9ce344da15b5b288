//! The built-in flight controller: estimator, cascaded control, modes, failsafes.

pub mod estimator;
pub mod mission;
