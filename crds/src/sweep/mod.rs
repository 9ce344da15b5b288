//! The `SimulationSweep` custom resource: one document that runs a base `SimulationRun`
//! across a parameter space (wind speed, GNSS degradation, seeds, fleet size, pilot
//! versions ...), several repetitions per cell, and reports the pass rate per cell.
//!
//! - this module: the resource, its spec and status;
//! - `path`: field paths (`spec.environment.wind.speedMps`, `spec.fleet[1].count`) read and
//!   written on a run's JSON;
//! - `space`: the parameter space (lists, ranges, seeded random samples) and its cells;
//! - `expand`: the sweep's runs, each a complete `SimulationRun`, validated as one;
//! - `document`: reading a sweep from YAML or JSON with field paths.
//!
//! Everything here is pure: the CLI and the operator resolve `spec.base.file` and run
//! what [`expand::expand`] returns.

pub mod document;
pub mod expand;
pub mod path;
pub mod space;

use k8s_openapi::apimachinery::pkg::apis::meta::v1::Condition;
use kube::{CustomResource, KubeSchema};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::run::SimulationRunSpec;

pub use document::parse_sweep;
pub use expand::{Expansion, SweepRun, expand};
pub use space::Cell;

/// Most runs one sweep may hold (cells x repetitions).
pub const MAX_SWEEP_RUNS: usize = 10_000;
/// Most repetitions per cell.
pub const MAX_REPETITIONS: u32 = 999;
/// Longest sweep name: its runs are named `<sweep>-c<cell>-r<repetition>` and must fit the
/// run name limit (40).
pub const MAX_SWEEP_NAME_LEN: usize = 28;
/// Label on every run of a sweep: the sweep's name.
pub const SWEEP_LABEL: &str = "sadesim.io/sweep";
/// Label on every run of a sweep: its cell index.
pub const CELL_LABEL: &str = "sadesim.io/sweep-cell";
/// Label on every run of a sweep: its repetition index.
pub const REPETITION_LABEL: &str = "sadesim.io/sweep-repetition";

/// Specification of a sweep: a base run, the parameters varied over it, how many times
/// each combination runs, how many runs may be in flight, and what to report.
#[derive(CustomResource, KubeSchema, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[kube(
    group = "sadesim.io",
    version = "v1alpha1",
    kind = "SimulationSweep",
    plural = "simulationsweeps",
    namespaced,
    shortname = "simsweep",
    category = "sadesim",
    status = "SimulationSweepStatus",
    derive = "PartialEq",
    doc = "A SADE-SIM sweep: a base SimulationRun flown across a parameter space, several repetitions per cell, with the pass rate per cell.",
    printcolumn = r#"{"name":"Phase","type":"string","jsonPath":".status.phase"}"#,
    printcolumn = r#"{"name":"Runs","type":"integer","jsonPath":".status.runs"}"#,
    printcolumn = r#"{"name":"Finished","type":"integer","jsonPath":".status.finished"}"#,
    printcolumn = r#"{"name":"Passed","type":"integer","jsonPath":".status.passed"}"#,
    printcolumn = r#"{"name":"Age","type":"date","jsonPath":".metadata.creationTimestamp"}"#
)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
#[x_kube(validation = Rule::new("self == oldSelf").message("a sweep's spec is immutable: its runs were made from it (create a new sweep instead)"))]
pub struct SimulationSweepSpec {
    /// The run every run of the sweep starts from.
    pub base: SweepBase,
    /// Fields set to one value in every run of the sweep, before the parameters (the clock
    /// `asFastAsPossible` for a sweep of a real-time scenario, a shorter duration).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub overrides: Vec<Override>,
    /// The fields varied, each over its own values. The sweep runs every combination (the
    /// cells of a full grid), in the order of this list (the last parameter varies fastest).
    pub parameters: Vec<Parameter>,
    /// Runs per cell (default 1). Repetition `r` runs with `spec.seed` = the base's seed
    /// (default 0) + `r`, so every cell meets the same seeds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repetitions: Option<u32>,
    /// Most runs in flight at once (default: locally the machine's cores or `--jobs`, on
    /// Kubernetes 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parallelism: Option<u32>,
    /// Seeds the random samples of `parameters[].random` (default 0). Not the runs' seed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The Kueue LocalQueue every run of the sweep is submitted to (Kubernetes only; sets
    /// each run's `spec.queue`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub queue: Option<String>,
    /// What the sweep's report shows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<SweepReportSpec>,
}

/// Where the base run comes from: exactly one of `spec` and `file`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct SweepBase {
    /// The base run's spec, inline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec: Option<Box<SimulationRunSpec>>,
    /// A scenario file holding one SimulationRun, relative to the sweep's file (local runs
    /// only: on Kubernetes give the spec inline).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
}

/// A field set to one value in every run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Override {
    /// The run field, as in `parameters[].field`.
    pub field: String,
    /// Its value.
    #[schemars(schema_with = "any_value")]
    pub value: Value,
}

/// One varied field and its values: exactly one of `values`, `range` and `random`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Parameter {
    /// Short name for reports and cell labels (`wind`), a DNS label.
    pub name: String,
    /// The run field it sets, as validation errors name fields:
    /// `spec.environment.wind.speedMps`, `spec.fleet[1].count`, `spec.pilot.command`.
    pub field: String,
    /// The values, in order (numbers, strings, lists or objects: whatever the field takes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(schema_with = "any_values")]
    pub values: Option<Vec<Value>>,
    /// Evenly spaced numbers `from`, `from + step`, ... up to `to` (inclusive).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range: Option<NumberRange>,
    /// `count` numbers drawn uniformly in `[min, max)` with the sweep's `seed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random: Option<RandomSample>,
}

/// Evenly spaced numbers.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct NumberRange {
    pub from: f64,
    pub to: f64,
    /// Positive.
    pub step: f64,
}

/// Numbers drawn uniformly at random (seeded).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct RandomSample {
    pub min: f64,
    pub max: f64,
    /// How many values (1..=1000).
    pub count: u32,
    /// Round each draw down to a whole number (for counts and seeds). Default false.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integer: Option<bool>,
}

/// What the sweep's report shows.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct SweepReportSpec {
    /// The parameter on the x axis of the pass-rate plot (default: the first).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<String>,
    /// Two parameters for the pass-rate heat map (default: the first two, when there are
    /// two or more).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heat_map: Option<Vec<String>>,
    /// Confidence level of the pass-rate intervals (default 0.95).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub confidence: Option<f64>,
}

fn any_value(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
    schemars::json_schema!({"x-kubernetes-preserve-unknown-fields": true})
}

fn any_values(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
    schemars::json_schema!({
        "type": "array",
        "items": {"x-kubernetes-preserve-unknown-fields": true}
    })
}

/// Lifecycle of a sweep.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash, JsonSchema)]
pub enum SweepPhase {
    /// Accepted, not yet looked at.
    Pending,
    /// Runs being created and followed.
    Running,
    /// Every run ended (whatever the runs' verdicts). The condition `Reported` says whether
    /// the report is archived (`status.report`), not yet (retried) or cannot be (no archive).
    Completed,
    /// The sweep is invalid: it runs nothing.
    Failed,
}

/// Condition types of a sweep.
pub mod condition_types {
    pub const VALID: &str = "Valid";
    pub const COMPLETE: &str = "Complete";
    pub const REPORTED: &str = "Reported";
}

/// Observed state of a sweep.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct SimulationSweepStatus {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase: Option<SweepPhase>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub conditions: Vec<Condition>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observed_generation: Option<i64>,
    /// Runs in the sweep (cells x repetitions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub runs: Option<u32>,
    /// Runs created so far.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub created: Option<u32>,
    /// Runs created and not yet in a terminal phase.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub in_flight: Option<u32>,
    /// Runs in a terminal phase.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub finished: Option<u32>,
    /// Finished runs whose criteria passed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passed: Option<u32>,
    /// Finished runs that failed (a criterion, a role, or aborted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failed: Option<u32>,
    /// Per cell: its values, runs finished and passed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cells: Vec<CellStatus>,
    /// Where the sweep's report (`sweep.json`, `sweep.html`) was archived.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
}

/// One cell's progress.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct CellStatus {
    pub index: u32,
    /// `name=value` of each parameter, comma-separated.
    pub label: String,
    pub finished: u32,
    pub passed: u32,
    /// `passed / finished` (absent while none finished).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pass_rate: Option<f64>,
}

impl SimulationSweepSpec {
    /// Runs per cell.
    pub fn repetitions(&self) -> u32 {
        self.repetitions.unwrap_or(1)
    }
}

#[cfg(test)]
mod tests;
