//! SADE-SIM contracts: the `SimulationRun` custom resource (spec, status), its validation,
//! the resolved `RunPlan` every role reads, and the pilot-facing fleet file.
//!
//! This crate does no I/O (like `kube-core`): parsing takes `&str`, validation and geodesy
//! are pure functions. Every other crate depends on it; it depends on none of them.

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
pub mod validate;
pub mod zones;

pub use document::{DocumentError, parse_run, parse_runs};
pub use run::{SimulationRun, SimulationRunSpec};
pub use status::{Phase, SimulationRunStatus};
pub use validate::{FieldError, ValidationErrors, validate};
