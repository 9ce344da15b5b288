//! The pure core of the sweep controller: from a sweep, its expansion and the runs of it
//! that exist, which runs to create next and the sweep's status. No I/O; the time is passed
//! in.
//!
//! # Guarantees
//! - Runs are created in expansion order (cell by cell, repetitions in order), and never
//!   so many that the sweep's runs in flight (existing and not in a terminal phase) exceed
//!   its parallelism.
//! - Every created run carries the sweep as its controlling owner (`controller: true`,
//!   `blockOwnerDeletion: true`): deleting the sweep deletes its runs through Kubernetes'
//!   garbage collector, and each run's own finalizer archives its evidence first.
//! - Idempotent: when every run exists, nothing is created, whatever the number of
//!   reconciles (a sweep re-applied by GitOps makes no new runs).
//! - An invalid sweep creates no run: phase `Failed`, condition `Valid=False` naming each
//!   problem's field.

use std::collections::HashMap;

use k8s_openapi::apimachinery::pkg::apis::meta::v1::OwnerReference;
use k8s_openapi::jiff::Timestamp;
use kube::Resource;
use sadesim_crds::sweep::condition_types as ct;
use sadesim_crds::sweep::{CellStatus, Expansion, SimulationSweep, SimulationSweepStatus, SweepPhase, expand};
use sadesim_crds::{FieldError, Phase, SimulationRun, ValidationErrors};

use crate::k8s::controller::lifecycle::set_condition;

/// Runs in flight at once when `spec.parallelism` is unset (on Kubernetes).
pub const DEFAULT_PARALLELISM: u32 = 4;

/// Why `spec.base.file` is refused on a cluster (the operator has no file to read).
pub const BASE_FILE_UNSUPPORTED: &str = "not supported on Kubernetes: give the base run inline as spec.base.spec";

/// What one reconcile of a sweep does.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepDecision {
    /// Runs to create, in expansion order, each owned by the sweep.
    pub create: Vec<SimulationRun>,
    /// The sweep's status after the creations.
    pub status: SimulationSweepStatus,
    /// Every run ended and no report is recorded in the status: the reconciler calls the
    /// report hook ([`super::reconcile`]).
    pub report_due: bool,
}

/// The sweep's runs as the operator can make them: [`expand`] over the inline base run.
///
/// # Errors
/// `spec.base.file` given (there is no file to read on a cluster) or no inline base
/// (`spec.base.spec`); otherwise every problem [`expand`] finds, each naming its field.
pub fn expansion_of(sweep: &SimulationSweep) -> Result<Expansion, ValidationErrors> {
    let base = &sweep.spec.base;
    if base.file.is_some() {
        return Err(ValidationErrors(vec![FieldError {
            path: "spec.base.file".into(),
            message: BASE_FILE_UNSUPPORTED.into(),
        }]));
    }
    match &base.spec {
        Some(spec) => expand(sweep, spec),
        None => Err(ValidationErrors(vec![FieldError {
            path: "spec.base.spec".into(),
            message: "is required on Kubernetes: the base run, inline".into(),
        }])),
    }
}

/// The sweep's runs in flight at once: `spec.parallelism`, default [`DEFAULT_PARALLELISM`].
pub fn parallelism(sweep: &SimulationSweep) -> u32 {
    sweep.spec.parallelism.unwrap_or(DEFAULT_PARALLELISM)
}

/// Decides which runs to create and the sweep's status.
///
/// `expansion` is [`expansion_of`] the sweep; `existing` the runs of the sweep that exist
/// (listed by the label `sadesim.io/sweep=<name>`; matched to the expansion by name, others
/// ignored); `now` stamps conditions that change.
///
/// # Assumptions
/// A run of the expansion that does not exist was never created or was deleted by hand;
/// either way it is (re)created in its turn.
pub fn decide(
    sweep: &SimulationSweep,
    expansion: &Result<Expansion, ValidationErrors>,
    existing: &[SimulationRun],
    now: Timestamp,
) -> SweepDecision {
    let previous = sweep.status.clone().unwrap_or_default();
    let generation = sweep.metadata.generation;
    let expansion = match expansion {
        Ok(e) => e,
        Err(problems) => return invalid(previous, problems, now, generation),
    };

    let by_name: HashMap<&str, &SimulationRun> =
        existing.iter().filter_map(|r| r.metadata.name.as_deref().map(|n| (n, r))).collect();
    let mut cells: Vec<CellStatus> =
        expansion.cells.iter().map(|c| CellStatus { index: c.index, label: c.label(), ..Default::default() }).collect();
    let mut counts = Counts::default();
    let mut missing = Vec::new();
    for sweep_run in &expansion.runs {
        let Some(run) = by_name.get(sweep_run.name()) else {
            missing.push(&sweep_run.run);
            continue;
        };
        counts.created += 1;
        let status = run.status.as_ref();
        if !status.and_then(|s| s.phase).is_some_and(Phase::is_terminal) {
            counts.in_flight += 1;
            continue;
        }
        counts.finished += 1;
        let passed = status.and_then(|s| s.verdict.as_ref()).is_some_and(|v| v.passed);
        let cell = cells.iter_mut().find(|c| c.index == sweep_run.cell).expect("every run's cell is a cell");
        cell.finished += 1;
        if passed {
            counts.passed += 1;
            cell.passed += 1;
        }
    }
    for cell in &mut cells {
        cell.pass_rate = (cell.finished > 0).then(|| f64::from(cell.passed) / f64::from(cell.finished));
    }

    // Fill the free slots, in expansion order; none while the sweep is being deleted.
    let deleting = sweep.metadata.deletion_timestamp.is_some();
    let slots = if deleting { 0 } else { parallelism(sweep).saturating_sub(counts.in_flight) as usize };
    let owner = owner(sweep);
    let create: Vec<SimulationRun> = missing
        .into_iter()
        .take(slots)
        .map(|run| {
            let mut run = run.clone();
            run.metadata.owner_references = Some(vec![owner.clone()]);
            run
        })
        .collect();
    counts.created += create.len() as u32;
    counts.in_flight += create.len() as u32;

    let total = expansion.runs.len() as u32;
    let complete = counts.finished == total;
    let mut status = previous;
    status.phase = Some(if complete { SweepPhase::Completed } else { SweepPhase::Running });
    status.observed_generation = generation;
    status.runs = Some(total);
    status.created = Some(counts.created);
    status.in_flight = Some(counts.in_flight);
    status.finished = Some(counts.finished);
    status.passed = Some(counts.passed);
    status.failed = Some(counts.finished - counts.passed);
    status.cells = cells;
    let repetitions = sweep.spec.repetitions();
    let shape = format!("{total} runs: {} cells x {repetitions} repetitions", expansion.cells.len());
    set_condition(&mut status.conditions, ct::VALID, true, "Expanded", &shape, now, generation);
    let progress = format!(
        "{} of {total} runs finished ({} passed, {} failed), {} in flight",
        counts.finished,
        counts.passed,
        counts.finished - counts.passed,
        counts.in_flight
    );
    let reason = if complete { "AllRunsFinished" } else { "RunsInFlight" };
    set_condition(&mut status.conditions, ct::COMPLETE, complete, reason, &progress, now, generation);
    status.message = Some(progress);
    let report_due = complete && status.report.is_none();
    SweepDecision { create, status, report_due }
}

/// Records the sweep's report at `url` (the folder [`super::report::write`] wrote):
/// `status.report` and the condition `Reported=True`.
pub fn reported(status: &mut SimulationSweepStatus, url: &str, now: Timestamp, generation: Option<i64>) {
    status.report = Some(url.into());
    set_condition(&mut status.conditions, ct::REPORTED, true, "Archived", &format!("report at {url}"), now, generation);
}

/// Records that the sweep's report was not written, and why: the condition
/// `Reported=False` with `reason` (`NoArchive`, `ArchiveFailed`) and `message`;
/// `status.report` stays unset.
pub fn not_reported(
    status: &mut SimulationSweepStatus,
    reason: &str,
    message: &str,
    now: Timestamp,
    generation: Option<i64>,
) {
    set_condition(&mut status.conditions, ct::REPORTED, false, reason, message, now, generation);
}

/// The sweep as controlling owner of its runs: deleting the sweep deletes them (the garbage
/// collector; each run's finalizer archives it first), and `blockOwnerDeletion` keeps a
/// foreground deletion of the sweep waiting for them.
pub fn owner(sweep: &SimulationSweep) -> OwnerReference {
    OwnerReference {
        api_version: SimulationSweep::api_version(&()).into_owned(),
        kind: SimulationSweep::kind(&()).into_owned(),
        name: sweep.metadata.name.clone().unwrap_or_default(),
        uid: sweep.metadata.uid.clone().unwrap_or_default(),
        controller: Some(true),
        block_owner_deletion: Some(true),
    }
}

/// Run counts of a sweep.
#[derive(Default)]
struct Counts {
    created: u32,
    in_flight: u32,
    finished: u32,
    passed: u32,
}

/// The status of a sweep that cannot run: `Failed`, `Valid=False` with every problem.
fn invalid(
    mut status: SimulationSweepStatus,
    problems: &ValidationErrors,
    now: Timestamp,
    generation: Option<i64>,
) -> SweepDecision {
    let listed = problems.0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ");
    status.phase = Some(SweepPhase::Failed);
    status.observed_generation = generation;
    status.message = Some(format!("invalid sweep: {listed}"));
    set_condition(&mut status.conditions, ct::VALID, false, "InvalidSpec", &listed, now, generation);
    SweepDecision { create: Vec::new(), status, report_due: false }
}
