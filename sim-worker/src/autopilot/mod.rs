//! The built-in flight controller: estimator, cascaded control, modes, failsafes.
