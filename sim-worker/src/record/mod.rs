//! Evidence of a run, written incrementally so an interrupted run keeps what it had:
//! events as JSON lines, the trajectory as CSV (every drone, at a fixed rate) and GeoJSON
//! (one line per drone, for any map tool), a summary, `recording.mcap` (Foxglove schemas)
//! and one PX4 ULog per drone (`spec.recording` turns the last two off).

mod camera_images;
mod cost;
pub mod disk;
mod events;
mod fixed;
mod gnss_tally;
pub mod mcap_file;
mod recorder;
mod sampler;
mod streams;
mod summary;
#[cfg(test)]
pub(crate) mod test_dir;
mod trajectory;
pub mod ulog_file;

pub use camera_images::{CameraImage, CameraStream, optical_frame};
pub use cost::{Lap, RecordingCost};
pub use events::EventLog;
pub use mcap_file::{MCAP_FILE, McapRecorder};
pub use recorder::{Recorder, RecorderOptions};
pub use sampler::Sampler;
pub use streams::{BATCH_WINDOWS, QUEUE_BATCHES, StreamWriter};
pub use summary::{DroneSummary, RunSummary};
pub use trajectory::{TRAJECTORY_CSV_HEADER, TrajectoryCsv, TrajectoryGeoJson};
pub use ulog_file::{ULOG_DIR, UlogRecorder};
