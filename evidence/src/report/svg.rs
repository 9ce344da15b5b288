//! The report's plots as SVG text: the trajectory map (the paper's Fig. 4A: every drone's
//! path coloured by group, the zones drawn over the city) and the altitude timeline (Fig.
//! 4G: height above ground against sim time, one panel per group, with the zones' and
//! the groups' altitude limits), and for runs with a GNSS constellation the GNSS timeline
//! (satellites, HDOP and estimate error per group) and the map of the estimate error.
//!
//! Pure functions of the run's data: no I/O, the same input gives the same bytes. Text
//! uses the font family `DejaVu Sans` (embedded for the PNGs, see `png.rs`). Map
//! coordinates are metres east and north of the run's origin (`spec.origin`), the frame
//! of `trajectory.csv`; screen y grows downwards, so north is flipped.

mod altitude;
mod draw;
mod gnss;
mod gnss_map;
mod map;
mod wind_map;

pub use altitude::altitude;
#[cfg(test)]
pub(super) use draw::path_data;
pub use draw::{FONT, esc};
pub use gnss::gnss;
pub use gnss_map::gnss_map;
pub use map::{Footprint, map};
pub use wind_map::{ClassCounts, WindSlice, wind_map};
