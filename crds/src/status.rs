//! Status of a `SimulationRun`, written by the operator on the status subresource (server-
//! side apply) or by the local runner into `status.json`.

use k8s_openapi::apimachinery::pkg::apis::meta::v1::{Condition, Time};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Lifecycle phase (DESIGN §4). The paper's Built/Started/Completed/Aborted map onto
/// Starting/Running/Succeeded|Failed/Aborted.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash, JsonSchema)]
pub enum Phase {
    /// Accepted, not yet looked at.
    Pending,
    /// Valid; waiting for capacity (ResourceQuota, Kueue, maxConcurrentRuns).
    Queued,
    /// Building or fetching the world assets.
    GeneratingAssets,
    /// Shards, coordinator and router starting; pilot not yet released.
    Starting,
    /// Simulated time advancing; pilot released.
    Running,
    /// Run over; logs and recordings being archived.
    Archiving,
    /// Finished and every criterion passed.
    Succeeded,
    /// Invalid, a role failed, or a criterion failed.
    Failed,
    /// Stopped by `spec.abort` or deletion; evidence archived.
    Aborted,
}

impl Phase {
    /// A finished run never leaves a terminal phase.
    pub fn is_terminal(self) -> bool {
        matches!(self, Phase::Succeeded | Phase::Failed | Phase::Aborted)
    }
}

/// Condition types the operator maintains.
pub mod condition_types {
    pub const VALID: &str = "Valid";
    pub const ASSETS_READY: &str = "AssetsReady";
    pub const SCHEDULED: &str = "Scheduled";
    pub const RUNNING: &str = "Running";
    pub const ARCHIVED: &str = "Archived";
    /// Set once the pilot Job has ended (or the run ended with it still running): `True`
    /// when its end is what `spec.pilot.expectedExit` allows, else `False` with reason
    /// `PilotFailed`, the exit code and the last lines of its log; a `False` fails the run.
    pub const PILOT: &str = "Pilot";
}

/// Observed state of a run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct SimulationRunStatus {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase: Option<Phase>,
    /// Latest observations (types: Valid, AssetsReady, Scheduled, Running, Archived, Pilot).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub conditions: Vec<Condition>,
    /// The `metadata.generation` this status describes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observed_generation: Option<i64>,
    /// When the run entered Running.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_time: Option<Time>,
    /// When the run reached a terminal phase.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub completion_time: Option<Time>,
    /// Drones in the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drones: Option<u32>,
    /// Physics shards in the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard_count: Option<u32>,
    /// Per-shard progress.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shards: Vec<ShardStatus>,
    /// Simulated seconds elapsed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sim_time_s: Option<f64>,
    /// Simulated seconds per wall-clock second, averaged over the last report interval.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub real_time_factor: Option<f64>,
    /// Where to connect while the run is live.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub endpoints: Option<Endpoints>,
    /// The run's Kueue Workload (runs with `spec.queue` under an operator with Kueue on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kueue: Option<KueueStatus>,
    /// Where the evidence is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub archive: Option<ArchiveStatus>,
    /// Outcome of the criteria.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verdict: Option<Verdict>,
    /// Human-readable reason for the current phase (e.g. which role failed and why).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
}

/// Progress of one shard.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct ShardStatus {
    pub index: u32,
    /// Drones the shard owns.
    pub drones: u32,
    /// The shard has built its world and reported ready.
    pub ready: bool,
    /// Simulated seconds the shard has completed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sim_time_s: Option<f64>,
}

/// Live endpoints.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct Endpoints {
    /// Airspace authority HTTP base URL.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub airspace: Option<String>,
    /// MAVLink GCS endpoints, one per router segment (`udp://host:14550`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mavlink: Vec<String>,
    /// Renderer URL when rendering is on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub renderer: Option<String>,
    /// The onboard cameras' frame listing (`.../cameras`, JSON with each drone's camera
    /// URLs) when the run has cameras; pilots find the same URLs in their fleet file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cameras: Option<String>,
}

/// The whole run as one Kueue Workload: its state, and while it waits, its place in the
/// queue.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct KueueStatus {
    /// Name of the Workload (`kubectl get workload <name>`).
    pub workload: String,
    /// `Pending` (no quota reserved yet), `QuotaReserved`, `Admitted`, `Evicted` or
    /// `Finished`, from the Workload's conditions.
    pub state: String,
    /// The ClusterQueue that reserved quota, once one did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster_queue: Option<String>,
    /// 0-based place among the LocalQueue's pending Workloads (Kueue's visibility API),
    /// while pending.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_in_local_queue: Option<i32>,
    /// 0-based place among the ClusterQueue's pending Workloads, while pending.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_in_cluster_queue: Option<i32>,
    /// Kueue's latest word (why it waits, who evicted it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
}

/// The run's archive.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct ArchiveStatus {
    /// URL of the run's folder (`<prefix>/<namespace>/<run>/<uid>/`).
    pub url: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub files: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bytes: Option<u64>,
}

/// Summary of the criteria's outcome.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct Verdict {
    pub passed: bool,
    /// One line per failed criterion.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failures: Vec<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unauthorized_entries: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crashes: Option<u32>,
}
