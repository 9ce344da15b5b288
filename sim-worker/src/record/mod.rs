//! Evidence of a run, written incrementally so an interrupted run keeps what it had:
//! events as JSON lines, the trajectory as CSV (every drone, at a fixed rate) and GeoJSON
//! (one line per drone, for any map tool), and a summary. MCAP and ULog come with the
//! evidence issue and plug in as further writers of the same observer.

mod events;
mod recorder;
mod summary;
mod trajectory;

pub use events::EventLog;
pub use recorder::{Recorder, RecorderOptions};
pub use summary::{DroneSummary, RunSummary};
pub use trajectory::{TRAJECTORY_CSV_HEADER, TrajectoryCsv, TrajectoryGeoJson};
