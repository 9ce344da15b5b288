//! The SADE-SIM case-study pilot (the paper's §4): one program flying every drone of the
//! Chicago museum scenario over MAVLink and asking the airspace authority before entering
//! its zone.
//!
//! - [`pilot`]: [`pilot::run`] is the whole program: fleet file and zones in, every drone
//!   flown;
//! - [`plan`] decides once who flies where (hold points, watch points, spots, parks);
//! - [`flight`] flies one drone through its task on its own thread, timed by the drone's
//!   clock;
//! - [`link`] is the MAVLink link to a drone, [`airspace`] and [`http`] the authority's
//!   API, [`zones`] and [`geometry`] the zones on the run's local plane;
//! - [`rng`] is the small seeded generator of the hobbyists' waypoints.

pub mod airspace;
pub mod flight;
pub mod geometry;
pub mod http;
pub mod link;
pub mod pilot;
pub mod plan;
pub mod rng;
pub mod zones;
