//! What the coordinator prints on stdout, one JSON object a line: the local runner and the
//! Kubernetes controller (from the Pod's log) follow a run through these.

use serde::{Deserialize, Serialize};

use super::summary::{FleetCounts, RunSummary};

/// Exit status of `sim-worker coordinator --finish-run` (the coordinator pod) when the run
/// itself finished but its upload to the archive failed: the operator reports the run's
/// outcome and an archive failure, not a failed run. A failed run exits 2.
pub const UPLOAD_FAILED_EXIT: u8 = 3;

/// One line of the coordinator's stdout.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Report {
    /// Bound and waiting for shards; the airspace API listens at `airspace`.
    Listening {
        address: String,
        airspace: String,
        /// The live view's address (`host:port`), with `spec.rendering.enabled`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        view: Option<String>,
    },
    /// Progress, about once per simulated second.
    Progress {
        sim_time_s: f64,
        /// Flattened: the line reads `{"type":"progress","simTimeS":..,"airborne":..,...}`.
        #[serde(flatten)]
        counts: FleetCounts,
    },
    /// The pilots were released at `sim_time_s` (the `pilotsReleased` event, already in
    /// `events.jsonl`): time to start the pilot process.
    PilotsReleased { sim_time_s: f64 },
    /// The run is over and its files are written.
    Finished { summary: RunSummary },
    /// The run failed; the process exits non-zero after this line.
    ///
    /// `role: shard`: shard `shard` (at `address`) failed mid-run, `reason` says how;
    /// the run's files are written up to the failure and `summary` is `summary.json`
    /// (`endReason: "shardFailed: ..."`). `role: coordinator`: this process could not
    /// start or go on (listen, accept, record); no `summary`.
    Failed {
        role: FailedRole,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        shard: Option<u32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        address: Option<String>,
        reason: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        summary: Option<RunSummary>,
    },
}

/// Which role a [`Report::Failed`] blames.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub enum FailedRole {
    Shard,
    Coordinator,
}
