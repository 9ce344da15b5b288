//! The run's verdict: each of the scenario's `criteria` judged on the compliance report
//! and the authority's request log when the run ends. A run passes when every criterion
//! does; `sadesim run` then exits 0, else 1 (so CI pipelines can gate on it).

use serde::{Deserialize, Serialize};

use sadesim_crds::plan::RunPlan;

use super::authority::RequestRecord;
use super::monitor::ComplianceReport;

/// One criterion's result.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct CriterionResult {
    /// `spec.criteria[i]`.
    pub path: String,
    /// The criterion's kind as written (`noUnauthorizedEntries`, ...).
    pub criterion: String,
    pub passed: bool,
    /// One line on what was checked, e.g. "5 of 5 drones of public-safety were granted".
    pub summary: String,
    /// Each failure with drone, time and place, e.g. "journalists-3 inside museum-tfr
    /// without a lease from 312.40 s for 18.2 s at 41.88011 N 87.62301 W, 104.2 m AGL".
    pub failures: Vec<String>,
}

/// The verdict of a run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RunVerdict {
    /// Every criterion passed (true when there are none).
    pub passed: bool,
    pub criteria: Vec<CriterionResult>,
}

/// Judges `plan.spec.criteria`.
pub fn evaluate(plan: &RunPlan, report: &ComplianceReport, requests: &[RequestRecord], end_s: f64) -> RunVerdict {
    let _ = (plan, report, requests, end_s);
    unimplemented!("airspace::criteria")
}
