//! Airframes, motors and the forces on a multirotor.
//!
//! `airframe` holds each preset's physics, `motor` the rotor speed lag, `battery` the
//! charge and voltage, `dynamics` the wrench (rotors + drag against the air + gravity), a
//! reference rigid-body integrator and the heading of an attitude, `ground` the contact
//! with the ground. The preset records that pair physics with controller gains are
//! `crate::preset`, a layer above. Frames: world ENU, body FLU (see the crate docs).

pub mod airframe;
pub mod battery;
pub mod dynamics;
pub mod ground;
pub mod motor;

#[cfg(test)]
pub(crate) use airframe::preset;
pub use airframe::{Airframe, BatterySpec, GRAVITY_MPS2, Rotor, Spin};
pub use battery::Battery;
pub use dynamics::{RigidState, Wrench, wrench, yaw_of};
pub use motor::Motor;
