//! Satellite navigation geometry: where the GNSS satellites are at a simulated time, how a
//! receiver sees them, and how good the geometry of a set of them is.
//!
//! Pure: orbit files are read at the I/O edge and parsed here from their text.
//!
//! - [`orbits`]: a constellation from an orbit file (TLE or OMM, as CelesTrak and
//!   Space-Track publish them), propagated with SGP4 to Earth-fixed positions.
//! - [`omm`]: Orbit Mean-Elements Messages in KVN, XML, JSON and CSV.
//! - [`sky`]: azimuth, elevation and range of a satellite from a receiver.
//! - [`dop`]: dilution of precision (GDOP, PDOP, HDOP, VDOP, TDOP) of a satellite set.
//! - [`run_sky`]: the satellites in the run's ENU frame at simulated times (cached per
//!   epoch, shared by a shard's receivers).
//! - [`signal`]: line of sight, single facade reflections (NLOS) and C/N0 among the
//!   world's buildings and terrain.
//! - [`receiver`]: pseudoranges with their errors and the least-squares fix.
//! - [`grid`]: the sky grid: per voxel and time slice, satellites in sight and reflected,
//!   and HDOP (precomputed for inspection).
//! - [`synthetic`]: a GPS-like Walker constellation for tests and demonstrations.
//!
//! Frames and units: Earth-fixed positions are WGS84 ECEF metres (`sadesim_crds::geo::Ecef`);
//! look angles are degrees (azimuth clockwise from true north, elevation above the
//! ellipsoid's tangent plane at the receiver); times are UNIX seconds (UTC, leap seconds
//! ignored, as SGP4's element epochs are).

/// The vector types of this crate's API.
pub use nalgebra;

pub mod dop;
pub mod grid;
pub mod omm;
pub mod orbits;
pub mod receiver;
pub mod run_sky;
pub mod signal;
pub mod sky;
pub mod synthetic;

#[cfg(test)]
mod fuzz_seeds;

pub use dop::Dop;
pub use orbits::{Constellation, OrbitError, Satellite, System};
pub use receiver::{RangingReceiver, ReceiverEpoch, Solution};
pub use run_sky::{RunSky, SatelliteState};
pub use signal::SignalPath;
pub use sky::LookAngles;

/// A UTC time as UNIX seconds from RFC 3339 text (`2026-05-01T14:30:00Z`, fractional
/// seconds and offsets allowed).
///
/// # Errors
/// The text is not an RFC 3339 time (the message says what is expected).
pub fn parse_utc(text: &str) -> Result<f64, String> {
    sgp4::chrono::DateTime::parse_from_rfc3339(text.trim())
        .map(|t| t.timestamp_micros() as f64 * 1e-6)
        .map_err(|e| format!("{text:?}: expected an RFC 3339 time such as 2026-05-01T14:30:00Z ({e})"))
}
