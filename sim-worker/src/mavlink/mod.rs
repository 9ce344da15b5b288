//! The MAVLink edge of a drone: PX4's flight-mode encoding, framing, message signing, the
//! per-drone session state machine (pure), the socket endpoint that carries it, and the
//! fleet router.
//!
//! Frames at this edge are MAVLink's: NED (x north, y east, z down) for local positions,
//! WGS84 lat/lon in 1e-7 degrees, altitudes in metres AMSL or relative to home. The engine
//! inside is ENU; conversions happen here and nowhere else.

pub mod endpoint;
pub mod frame;
pub mod mission_protocol;
pub mod params;
pub mod px4_mode;
pub mod router;
pub mod session;
pub mod signing;
pub mod streams;
pub mod telemetry;
pub mod uplink;
