//! Airframes, motors and the forces on a multirotor.
//!
//! `preset` holds one record per airframe preset (physics, PX4 id, controller gains,
//! parameter overrides), `airframe` the presets' physics, `motor` the rotor speed lag, `battery`
//! the charge and voltage, `dynamics` the wrench (rotors + drag against the air + gravity)
//! and a reference rigid-body integrator. Frames: world ENU, body FLU (see the crate docs).

pub mod airframe;
pub mod battery;
pub mod dynamics;
pub mod ground;
pub mod motor;
pub mod preset;

pub use airframe::{Airframe, BatterySpec, GRAVITY_MPS2, Rotor, Spin, preset};
pub use battery::Battery;
pub use dynamics::{RigidState, Wrench, wrench};
pub use motor::Motor;
pub use preset::Preset;
