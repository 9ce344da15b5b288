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
//! so the same numbers fly any airframe. [`Gains::for_airframe`] derives them from an airframe;
//! each preset's record (`preset::Preset::gains`) holds the gains its drones fly.
//!
//! # Modules (PX4's split)
//! [`pid`] the PID axis, [`gains`] the tuning, [`position_control`] position and velocity
//! (`mc_pos_control`), [`attitude_control`] (`mc_att_control`), [`rate_control`]
//! (`mc_rate_control`), [`control_allocation`] the mixer (`control_allocator`), [`cascade`]
//! the [`Controller`] that wires them.

pub mod attitude_control;
pub mod cascade;
pub mod control_allocation;
pub mod gains;
pub mod pid;
pub mod position_control;
pub mod rate_control;

#[cfg(test)]
mod tests;

pub use attitude_control::AttitudeController;
pub use cascade::{AttitudeTarget, ControlOutput, Controller, EstimatedState, Setpoint};
pub use control_allocation::{Allocation, ControlError, Mixer};
pub use gains::Gains;
pub use pid::{Pid, PidGains, PidTerms};
pub use position_control::{PositionController, ThrustSetpoint, VelocityController, attitude_from_thrust_axis};
pub use rate_control::RateController;
