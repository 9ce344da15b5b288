//! The verdict of a run: each of `spec.criteria` judged at the end (`summary.json`
//! `verdict`, the report, the Kubernetes status).

use serde::{Deserialize, Serialize};

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
    /// without a lease from 312.40 s for 18.20 s at 41.88011 N 87.62301 W, 104.2 m AGL".
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
