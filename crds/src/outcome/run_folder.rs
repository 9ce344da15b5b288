//! The files of a run folder (`runs/<namespace>/<run>/<timestamp>/` locally, the same
//! names under the archive URL on a cluster). One list, so that the runner, the coordinator
//! role, the report and the archive agree on every name.

/// The resolved plan (`RunPlan` JSON), written before the roles start.
pub const PLAN: &str = "plan.json";
/// The run's totals and verdict (`outcome::summary::RunSummary`), written at the end.
pub const SUMMARY: &str = "summary.json";
/// One JSON event a line (`outcome::events::Event`), flushed as the run goes.
pub const EVENTS: &str = "events.jsonl";
/// The airspace authority's requests and leases and the monitor's records.
pub const AIRSPACE: &str = "airspace.json";
/// What happened to the pilot process (`outcome::pilot::PilotRecord`), local runs.
pub const PILOT_RECORD: &str = "pilot.json";
/// The pilot's stdout and stderr, interleaved, local runs.
pub const PILOT_LOG: &str = "pilot.log";
/// The fleet file given to the pilot (path in `SADESIM_FLEET`).
pub const FLEET: &str = "fleet.json";
/// The human-readable report (`sadesim report`).
pub const REPORT: &str = "report.html";
/// Why `report.html` could not be written, when it could not (the run's other files are
/// kept: a report failure never loses evidence).
pub const REPORT_ERROR: &str = "report-error.txt";
/// The archive manifest with every file's checksum, written last.
pub const MANIFEST: &str = "manifest.json";

/// Each drone's GNSS receiver in flight once a second (`time_s,drone,fix_type,satellites,
/// hdop,fix_error_m,estimate_error_m`; errors are horizontal metres from the truth, empty
/// when there is no fix or estimate): runs with a GNSS constellation only.
pub const GNSS: &str = "gnss.csv";
