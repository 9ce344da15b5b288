//! SADE-SIM contracts: the `SimulationRun` custom resource (spec, status), its validation,
//! the resolved `RunPlan` every role reads, the pilot-facing fleet file, and what a run
//! writes and reports.
//!
//! This crate does no I/O (like `kube-core`): parsing takes `&str`, validation and geodesy
//! are pure functions. It depends on no other crate of the workspace.
//!
//! - `run`: the `SimulationRun` resource and its spec (origin, clock, world, sharding, ...);
//! - `status`: its status (phase, conditions, progress), written by the operator or the runner;
//! - `fleet`: fleet groups (count, airframe, operator, homes, limits, who flies them);
//! - `airframe`: the names of the airframe presets a group may use;
//! - `camera`: onboard cameras and the ground markers they can see;
//! - `environment`: environment factors (wind, GNSS) as the scenario declares them;
//! - `zones`: airspace zones (polygon, floor, ceiling) and their entry policy;
//! - `ground_stations`: who outside the run may reach its MAVLink and airspace endpoints;
//! - `criteria`: the pass/fail criteria judged when a run ends;
//! - `sweep`: the `SimulationSweep` resource (a base run over a parameter space) and its
//!   expansion into runs;
//! - `document`: reading scenario documents (YAML, JSON, `kind: List`) with field paths;
//! - `validate`: everything the schema cannot check, every problem at once;
//! - `crd`: the generated CustomResourceDefinition and a structural-schema checker;
//! - `plan`: the `RunPlan`, the fully resolved run every role reads;
//! - `fleet_file`: the fleet file a pilot reads (`SADESIM_FLEET`);
//! - `outcome`: what a run writes and reports (events, end reasons, verdict, summary,
//!   the coordinator's report lines, stop requests, run-folder file names);
//! - `parts`: a file too big for one ConfigMap, stored and joined as parts;
//! - `geo`: WGS84 geodesy (geodetic, ECEF, local ENU/NED);
//! - `polygon`: planar polygon geometry on the local ENU plane;
//! - `random`: the deterministic random streams `(seed, drone, purpose)`;
//! - `fixtures`: chainable builders for tests (feature `fixtures`).

pub mod airframe;
pub mod camera;
pub mod crd;
pub mod criteria;
pub mod document;
pub mod environment;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod fleet;
pub mod fleet_file;
pub mod geo;
pub mod ground_stations;
pub mod outcome;
pub mod parts;
pub mod plan;
pub mod polygon;
pub mod random;
pub mod run;
pub mod status;
pub mod sweep;
pub mod validate;
pub mod zones;

pub use document::{DocumentError, parse_run, parse_runs};
pub use run::{SimulationRun, SimulationRunSpec};
pub use status::{Phase, SimulationRunStatus};
pub use sweep::{SimulationSweep, SimulationSweepSpec};
pub use validate::{FieldError, ValidationErrors, validate};
