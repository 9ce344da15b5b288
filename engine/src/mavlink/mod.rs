//! MAVLink as the drone speaks it, without sockets: PX4's flight-mode encoding, framing,
//! message signing, the per-drone session state machine (missions, parameters, commands,
//! telemetry streams). The sockets that carry the frames are `sim_worker::mavlink`.
//!
//! Frames at this edge are MAVLink's: NED (x north, y east, z down) for local positions,
//! WGS84 lat/lon in 1e-7 degrees, altitudes in metres AMSL or relative to home. The engine
//! inside is ENU; conversions happen here (`telemetry`) and nowhere else.

pub mod frame;
pub mod mission_protocol;
pub mod params;
pub mod px4_mode;
pub mod session;
pub mod signing;
pub mod streams;
pub mod telemetry;

#[cfg(test)]
mod fuzz_seeds;
#[cfg(test)]
mod gcs_messages;
