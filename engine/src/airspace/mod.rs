//! Airspace management (DESIGN §6 `airspace`, the paper's SADE Zones and DO3), as pure
//! functions of the zones, the requests and simulated time. The HTTP API and the runtime
//! around a run are `sim_worker::airspace`.
//!
//! - [`volume`]: zones as volumes in the run's local ENU frame (polygon, floor and ceiling
//!   AGL or MSL, time window) with point and segment queries;
//! - [`authority`]: the airspace authority's decisions on entry requests (credentials,
//!   capacity, altitude, activity) and its lease table: a function of (zone policy,
//!   leases, request, sim time);
//! - [`monitor`]: the compliance monitor on ground truth, every coordinator window
//!   (100 Hz at the default 1 kHz physics and 10-step windows): zone entries and exits,
//!   entries without a lease, constraint and altitude-limit breaches, separation;
//! - [`criteria`]: the run's pass/fail verdict from the scenario's `criteria`.
//!
//! Time is simulated seconds since the start of the run everywhere in this module.
//! Positions are world ENU metres (x east, y north, z up from the origin's ground).

pub mod authority;
pub mod criteria;
pub mod monitor;
pub mod volume;
