//! Run events: the types are contracts (`sadesim_crds::outcome::events`), shared with the
//! report and the Kubernetes controller; re-exported here for the engine.

pub use sadesim_crds::outcome::ending::{CrashCause, EndReason};
pub use sadesim_crds::outcome::events::*;
