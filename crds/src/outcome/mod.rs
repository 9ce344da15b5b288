//! What a run produces and reports, as the roles write it and the CLI, the report and the
//! Kubernetes controller read it: events, why a run ended and why a drone crashed, airspace
//! records, the verdict, the summary, the coordinator's stdout lines, the stop requests, the
//! pilot record, the assets role's outcome and the run folder's file names. Plain serde
//! types: no I/O.

pub mod assets;
pub mod compliance;
pub mod control;
pub mod coordinator;
pub mod ending;
pub mod events;
pub mod pilot;
pub mod run_folder;
pub mod summary;
pub mod verdict;
