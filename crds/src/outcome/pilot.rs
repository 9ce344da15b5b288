//! `pilot.json`: what happened to the pilot process of a local run.

use serde::{Deserialize, Serialize};

use crate::run::PilotExit;

/// What happened to the pilot: `pilot.json` in the output folder.
///
/// Simulated times are those the runner had seen when it acted: the end of the window in
/// which it noticed (in-process), or the coordinator's latest report, at most about one
/// simulated second old (`--processes`).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct PilotRecord {
    /// `spec.pilot.command`.
    pub command: Vec<String>,
    /// Working directory (the scenario file's folder).
    pub working_dir: String,
    pub on_exit: PilotExit,
    /// The log file, in the output folder.
    pub log: String,
    /// Process id while it ran.
    pub pid: Option<u32>,
    /// Simulated time at which the pilot was started, s; `None` when the run ended before
    /// the pilots were released.
    pub started_at_s: Option<f64>,
    /// Simulated time at which the pilot's exit was seen (or the runner stopped it), s.
    pub exited_at_s: Option<f64>,
    /// Exit code when the pilot exited normally.
    pub exit_code: Option<i32>,
    /// Signal number when a signal ended it (15 SIGTERM, 9 SIGKILL).
    pub signal: Option<i32>,
    /// True when the run ended first and the runner stopped the pilot.
    pub stopped_by_runner: bool,
}

impl PilotRecord {
    /// One line for the terminal, e.g. `exited with code 0 at 12.3 s`.
    pub fn describe(&self) -> String {
        let Some(started) = self.started_at_s else {
            return "not started: the run ended before the pilots were released".into();
        };
        let how = match (self.exit_code, self.signal) {
            (Some(code), _) => format!("code {code}"),
            (None, Some(15)) => "SIGTERM".into(),
            (None, Some(9)) => "SIGKILL".into(),
            (None, Some(s)) => format!("signal {s}"),
            (None, None) => "unknown status".into(),
        };
        let at = self.exited_at_s.unwrap_or(started);
        if self.stopped_by_runner {
            format!("started at {started:.2} s, still running at the end of the run, stopped ({how})")
        } else {
            format!("started at {started:.2} s, exited with {how} at {at:.2} s")
        }
    }
}
