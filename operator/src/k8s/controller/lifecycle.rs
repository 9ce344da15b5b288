//! The run's phase machine (pure): from the run, its plan, what was observed of its
//! children and the queue's answer, decide what to apply, archive and delete, the new
//! status and the Events to record. No I/O and no clock: `now` is an input.
//!
//! Phases (DESIGN §4): `Pending -> Queued -> GeneratingAssets -> Starting -> Running ->
//! Archiving -> Succeeded | Failed | Aborted`. An invalid run goes straight to `Failed`
//! with `Valid=False` and no children. Every other end (criteria judged, a role failed,
//! `spec.abort`, deletion) passes through `Archiving`, which stops the pilot, asks a
//! coordinator still running the run to end it (bounded), stops the shards, waits (bounded)
//! for the coordinator to write and upload the run, archives every role's pod log, and only
//! then removes the workloads. The pilot Job's end is not an end by itself: with `onExit:
//! endRun` it asks the coordinator to end the run, whose summary then ends it.
//!
//! # Guarantees
//! - A terminal phase is never left.
//! - Pod logs are archived before the workload that owns them is deleted, and the
//!   finalizer is removed only once archiving is done.
//! - Applied children never carry `spec.suspend`.
//! - With Kueue, nothing but the run's Workload exists until Kueue admits the whole run; an
//!   eviction ends the run (a simulation cannot be paused and resumed elsewhere).

use std::time::Duration;

use k8s_openapi::apimachinery::pkg::apis::meta::v1::{Condition, Time};
use k8s_openapi::jiff::Timestamp;
use sadesim_crds::SimulationRun;
use sadesim_crds::outcome::assets::AssetsOutcome;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::PilotExit;
use sadesim_crds::status::{Endpoints, Phase, ShardStatus, SimulationRunStatus, condition_types as ct};

use super::observe::{Observed, WorkState};
use super::queue::Admission;
use crate::k8s::children::{self, Child, ClusterSettings, Kind, Role, RunFolder, Stage, names};

mod archiving;
#[cfg(test)]
mod pilot_tests;
#[cfg(test)]
mod tests;

pub use archiving::{ARCHIVE_FAILED, archive_failed};
use archiving::{archive_folder, archive_step};

/// The finalizer that keeps a run until its evidence is archived.
pub const FINALIZER: &str = "sadesim.io/archive";

/// How long `Archiving` waits for the coordinator to write and upload the run after the
/// shards stopped, seconds; then its log is archived and it is deleted anyway.
pub const COORDINATOR_GRACE_S: i64 = 120;

/// How long Archiving waits, after the pilot is gone, for a running coordinator to end the
/// run on request (the stop annotation) before the shards are deleted under it, seconds.
pub const STOP_GRACE_S: i64 = 60;

/// Requeue periods: polls while children move (they also wake the controller by watch).
const REQUEUE_QUEUED: Duration = Duration::from_secs(15);
const REQUEUE_ACTIVE: Duration = Duration::from_secs(5);
const REQUEUE_RUNNING: Duration = Duration::from_secs(10);
const REQUEUE_ARCHIVING: Duration = Duration::from_secs(2);

/// How a run's Running condition ends (the condition's reason); the final phase follows
/// from it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunEnd {
    /// The coordinator finished the run: the verdict decides Succeeded or Failed.
    Finished,
    /// A role failed (the paper's rule: any role failing fails the run).
    RoleFailed,
    /// The spec no longer plans (the CEL rule normally refuses such an update).
    InvalidSpec,
    /// `spec.abort: true`.
    Aborted,
    /// The run was deleted before it ended.
    Deleted,
    /// Kueue evicted the run's Workload (preemption, deactivation, a time limit).
    Evicted,
    /// The coordinator ended the run because the pilot sent no MAVLink within
    /// `spec.pilot.connectTimeoutS` of the release (`endReason` `pilotNotConnected`).
    PilotNotConnected,
}

impl RunEnd {
    const ALL: [RunEnd; 7] = [
        RunEnd::Finished,
        RunEnd::RoleFailed,
        RunEnd::InvalidSpec,
        RunEnd::Aborted,
        RunEnd::Deleted,
        RunEnd::Evicted,
        RunEnd::PilotNotConnected,
    ];

    /// The Running condition's reason (and the Event's, for a warning).
    pub fn reason(self) -> &'static str {
        match self {
            RunEnd::Finished => "Finished",
            RunEnd::RoleFailed => "RoleFailed",
            RunEnd::InvalidSpec => "InvalidSpec",
            RunEnd::Aborted => "Aborted",
            RunEnd::Deleted => "Deleted",
            RunEnd::Evicted => "Evicted",
            RunEnd::PilotNotConnected => "PilotNotConnected",
        }
    }

    /// The end a Running condition's reason names (`None` while the run goes on).
    pub fn of_reason(reason: &str) -> Option<RunEnd> {
        Self::ALL.into_iter().find(|end| end.reason() == reason)
    }

    /// The `endReason` a coordinator still running is asked to end the run with (the stop
    /// annotation's value); `None` when the coordinator ended the run itself.
    pub fn stop_reason(self) -> Option<EndReason> {
        match self {
            RunEnd::Finished | RunEnd::PilotNotConnected => None,
            RunEnd::RoleFailed => Some(EndReason::RoleFailed),
            RunEnd::InvalidSpec => Some(EndReason::InvalidSpec),
            RunEnd::Aborted => Some(EndReason::Aborted),
            RunEnd::Deleted => Some(EndReason::Deleted),
            RunEnd::Evicted => Some(EndReason::Evicted),
        }
    }

    /// Ends that fail the run for a reason outside it, recorded as a Warning Event.
    fn warns(self) -> bool {
        matches!(self, RunEnd::RoleFailed | RunEnd::InvalidSpec | RunEnd::Evicted | RunEnd::PilotNotConnected)
    }
}

/// The Running condition's reason while the run goes on after the pilot Job ended (it stays
/// True with this reason until the coordinator's summary arrives); not an end.
pub const PILOT_EXITED: &str = "PilotExited";

/// A simulated time seen at a wall-clock time: the base of the real-time factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub sim_time_s: f64,
    pub at: Timestamp,
}

/// Everything the machine decides from.
#[derive(Debug)]
pub struct Input<'a> {
    pub run: &'a SimulationRun,
    /// The plan, or why the run does not plan (field paths and what is expected).
    pub plan: Result<&'a RunPlan, &'a super::planning::PlanFailure>,
    pub settings: &'a ClusterSettings,
    pub observed: &'a Observed,
    /// The queue's answer, computed for runs waiting without Kueue (`None` otherwise).
    pub admission: Option<Admission>,
    pub now: Timestamp,
    /// The previous progress sample of this run (kept in memory by the controller).
    pub last_sample: Option<Sample>,
}

/// Workloads deleted by label selector `sadesim.io/run=<run>[,sadesim.io/role=<role>]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delete {
    pub kind: Kind,
    /// Every role when `None`.
    pub role: Option<Role>,
}

/// A Kubernetes Event about the run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Note {
    pub warning: bool,
    /// PascalCase reason (the new phase, `InvalidSpec`, `RoleFailed`, ...).
    pub reason: String,
    pub message: String,
}

/// What to do, in this order: add the finalizer, apply, archive logs, delete, write the
/// status, record the events, remove the finalizer.
#[derive(Clone, Debug, PartialEq)]
pub struct Decision {
    pub add_finalizer: bool,
    /// Children to server-side apply, in order.
    pub apply: Vec<Child>,
    /// Pods whose logs go to `logs/<pod>.log` in the run's archive folder.
    pub archive_logs: Vec<String>,
    /// The run's archive folder, when it has an archive.
    pub archive: Option<RunFolder>,
    pub delete: Vec<Delete>,
    /// The full status (written only when it differs from the current one).
    pub status: SimulationRunStatus,
    pub events: Vec<Note>,
    pub remove_finalizer: bool,
    pub requeue: Option<Duration>,
    /// The progress sample to remember for the next real-time factor.
    pub sample: Option<Sample>,
    /// The run was admitted from the queue now (for the queue-wait metric).
    pub admitted: bool,
}

impl Decision {
    fn new(status: SimulationRunStatus) -> Self {
        Self {
            add_finalizer: false,
            apply: Vec::new(),
            archive_logs: Vec::new(),
            archive: None,
            delete: Vec::new(),
            status,
            events: Vec::new(),
            remove_finalizer: false,
            requeue: None,
            sample: None,
            admitted: false,
        }
    }

    fn phase(&self) -> Phase {
        self.status.phase.unwrap_or(Phase::Pending)
    }

    /// Moves to `phase` with an Event (Warning for Failed).
    fn enter(&mut self, phase: Phase, message: impl Into<String>) {
        if self.status.phase == Some(phase) {
            return;
        }
        let message = message.into();
        self.status.phase = Some(phase);
        self.status.message = Some(message.clone());
        self.events.push(Note { warning: phase == Phase::Failed, reason: format!("{phase:?}"), message });
    }

    fn condition(
        &mut self,
        type_: &str,
        ok: bool,
        reason: &str,
        message: impl Into<String>,
        at: Timestamp,
        generation: Option<i64>,
    ) {
        set_condition(&mut self.status.conditions, type_, ok, reason, &message.into(), at, generation);
    }

    fn requeue_at_most(&mut self, d: Duration) {
        self.requeue = Some(self.requeue.map_or(d, |r| r.min(d)));
    }
}

/// Sets a condition, keeping `lastTransitionTime` while its status does not change.
pub fn set_condition(
    conditions: &mut Vec<Condition>,
    type_: &str,
    ok: bool,
    reason: &str,
    message: &str,
    at: Timestamp,
    generation: Option<i64>,
) {
    let status = if ok { "True" } else { "False" };
    let message: String = message.chars().take(32_768).collect();
    match conditions.iter_mut().find(|c| c.type_ == type_) {
        Some(c) => {
            if c.status != status {
                c.last_transition_time = Time(at);
            }
            c.status = status.into();
            c.reason = reason.into();
            c.message = message;
            c.observed_generation = generation;
        }
        None => conditions.push(Condition {
            type_: type_.into(),
            status: status.into(),
            reason: reason.into(),
            message,
            last_transition_time: Time(at),
            observed_generation: generation,
        }),
    }
}

/// The condition `type_`, when set.
pub fn condition<'a>(status: &'a SimulationRunStatus, type_: &str) -> Option<&'a Condition> {
    status.conditions.iter().find(|c| c.type_ == type_)
}

/// The children of `plan` at `stage` whose role `keep` accepts, Jobs without `spec.suspend`;
/// with Kueue, each pod on the ResourceFlavor Kueue admitted its role to.
fn children_for(input: &Input, plan: &RunPlan, stage: Stage, keep: impl Fn(Role) -> bool) -> Vec<Child> {
    let mut out: Vec<Child> = children::children(input.run, plan, input.settings, stage)
        .into_iter()
        .filter(|c| c.role().is_some_and(&keep))
        .map(|c| match c {
            Child::Job(mut job) => {
                // The run is admitted as a whole (or by the built-in queue) before any Job
                // exists: a suspended Job would never start.
                if let Some(spec) = job.spec.as_mut() {
                    spec.suspend = None;
                }
                Child::Job(job)
            }
            other => other,
        })
        .collect();
    if let Some(queue) = &input.observed.queue
        && let Some(admission) = queue.workload.status.as_ref().and_then(|s| s.admission.as_ref())
    {
        children::place(&mut out, &admission.pod_set_assignments, &queue.flavors);
    }
    out
}

fn kueue_mode(input: &Input) -> bool {
    input.settings.kueue && input.run.spec.queue.is_some()
}

/// The run may have children: it was admitted (Scheduled set to True once) or handed to
/// Kueue, or something was observed.
fn children_may_exist(status: &SimulationRunStatus, observed: &Observed) -> bool {
    !observed.is_empty()
        || condition(status, ct::SCHEDULED).is_some_and(|c| c.status == "True" || c.reason == "KueuePending")
}

/// Decides one reconcile of the run.
pub fn decide(input: &Input) -> Decision {
    let run = input.run;
    let prev = run.status.clone().unwrap_or_default();
    let prev_phase = prev.phase.unwrap_or(Phase::Pending);
    let mut d = Decision::new(prev.clone());
    let generation = run.metadata.generation;
    let now = input.now;
    let has_finalizer = run.metadata.finalizers.iter().flatten().any(|f| f == FINALIZER);
    d.archive = archive_folder(input);

    if run.metadata.deletion_timestamp.is_some() {
        if !has_finalizer {
            return d;
        }
        if prev_phase.is_terminal() {
            d.remove_finalizer = true;
            return d;
        }
        if !children_may_exist(&prev, input.observed) {
            d.condition(
                ct::RUNNING,
                false,
                RunEnd::Deleted.reason(),
                "the run was deleted before it started",
                now,
                generation,
            );
            d.enter(Phase::Aborted, "the run was deleted before it started");
            d.status.completion_time = Some(Time(now));
            d.remove_finalizer = true;
            return d;
        }
        if prev_phase != Phase::Archiving {
            end(&mut d, input, RunEnd::Deleted, "the run was deleted: stopping it and archiving its evidence");
        }
        archive_step(&mut d, input);
        d.remove_finalizer = d.phase().is_terminal();
        return d;
    }
    if prev_phase.is_terminal() {
        return d;
    }
    d.status.observed_generation = generation;
    if let Some(q) = &input.observed.queue {
        d.status.kueue = Some(children::status_of(&q.workload, q.pending.as_ref()));
    }

    // Valid locally is not enough: a cluster needs e.g. a pilot image (children::problems).
    let problems = input.plan.as_ref().map(|p| children::problems(p, input.settings)).unwrap_or_default();
    let fatal: Vec<String> = problems.iter().filter(|p| p.fatal).map(ToString::to_string).collect();
    let warnings: Vec<String> = problems.iter().filter(|p| !p.fatal).map(ToString::to_string).collect();
    let planned = match &input.plan {
        Ok(plan) if fatal.is_empty() => Ok(*plan),
        Ok(_) => Err(fatal.join("; ")),
        Err(e) => Err(e.to_string()),
    };
    let plan = match (&planned, prev_phase) {
        (Ok(plan), _) => *plan,
        (Err(message), Phase::Archiving) => {
            let _ = message;
            archive_step(&mut d, input);
            return d;
        }
        (Err(message), _) if !children_may_exist(&prev, input.observed) => {
            d.condition(ct::VALID, false, "InvalidSpec", message.clone(), now, generation);
            d.events.push(Note { warning: true, reason: "InvalidSpec".into(), message: message.clone() });
            d.enter(Phase::Failed, format!("invalid: {message}"));
            d.status.completion_time = Some(Time(now));
            d.remove_finalizer = has_finalizer;
            return d;
        }
        (Err(message), _) => {
            d.condition(ct::VALID, false, "InvalidSpec", message.clone(), now, generation);
            end(&mut d, input, RunEnd::InvalidSpec, format!("the spec no longer plans: {message}"));
            archive_step(&mut d, input);
            return d;
        }
    };
    let mut valid = format!(
        "{} drones in {} shards, {} router segments",
        plan.drones.len(),
        plan.shards.len(),
        plan.segments.len()
    );
    for w in &warnings {
        valid.push_str(&format!("; warning: {w}"));
    }
    d.condition(ct::VALID, true, "Planned", valid, now, generation);
    if prev_phase == Phase::Pending {
        for w in &warnings {
            d.events.push(Note { warning: true, reason: "SpecWarning".into(), message: w.clone() });
        }
    }
    d.status.drones = Some(plan.drones.len() as u32);
    d.status.shard_count = Some(plan.shards.len() as u32);
    d.add_finalizer = !has_finalizer;

    if prev_phase == Phase::Archiving {
        archive_step(&mut d, input);
        return d;
    }
    if run.spec.abort {
        end(&mut d, input, RunEnd::Aborted, "spec.abort is true: stopping the pilot, then the shards, then archiving");
        archive_step(&mut d, input);
        return d;
    }

    if prev_phase == Phase::Pending {
        d.enter(Phase::Queued, "valid; waiting for admission");
    }
    if d.phase() == Phase::Queued {
        queued(&mut d, input, plan);
    }
    if d.phase() == Phase::GeneratingAssets {
        generating_assets(&mut d, input, plan);
    }
    if matches!(d.phase(), Phase::Starting | Phase::Running) {
        live(&mut d, input, plan);
    }
    if d.phase() == Phase::Archiving {
        archive_step(&mut d, input);
    }
    d
}

/// The config and assets children (the first stage).
fn first_stage(input: &Input, plan: &RunPlan) -> Vec<Child> {
    children_for(input, plan, Stage { assets_job: true, pilot: false, stop: None }, |r| {
        matches!(r, Role::Config | Role::Assets)
    })
}

fn queued(d: &mut Decision, input: &Input, plan: &RunPlan) {
    let (now, generation) = (input.now, input.run.metadata.generation);
    if kueue_mode(input) {
        // Only the Workload until Kueue admits the whole run.
        d.apply = children::workload(input.run, plan, input.settings).into_iter().collect();
        let queue = input.run.spec.queue.as_deref().unwrap_or_default();
        match &input.observed.queue {
            Some(q) if q.admitted() => {
                let cq = d.status.kueue.as_ref().and_then(|k| k.cluster_queue.clone()).unwrap_or_default();
                let message = format!("admitted by Kueue as one gang (LocalQueue {queue}, ClusterQueue {cq})");
                d.condition(ct::SCHEDULED, true, "AdmittedByKueue", message.clone(), now, generation);
                d.enter(Phase::GeneratingAssets, message);
                d.admitted = true;
                d.apply.clear();
            }
            observed => {
                let mut message = format!("waiting for Kueue LocalQueue {queue} to admit the whole run");
                if let Some(k) = &d.status.kueue {
                    if let Some(p) = k.position_in_local_queue {
                        message.push_str(&format!(" (position {p} in the LocalQueue"));
                        if let Some(c) = k.position_in_cluster_queue {
                            message.push_str(&format!(", {c} in the ClusterQueue"));
                        }
                        message.push(')');
                    }
                    if let Some(said) = &k.message {
                        message.push_str(&format!(": {said}"));
                    }
                } else if observed.is_none() {
                    message.push_str(": creating its Workload");
                }
                d.condition(ct::SCHEDULED, false, "KueuePending", message.clone(), now, generation);
                d.status.message = Some(format!("queued: {message}"));
                d.requeue_at_most(REQUEUE_QUEUED);
            }
        }
        return;
    }
    match &input.admission {
        Some(Admission::Admitted) => {
            d.condition(ct::SCHEDULED, true, "Admitted", "the whole gang fits the namespace's quota", now, generation);
            d.enter(Phase::GeneratingAssets, "admitted: the whole gang fits");
            d.admitted = true;
        }
        Some(Admission::Waiting { reason, message }) => {
            d.condition(ct::SCHEDULED, false, reason, message.clone(), now, generation);
            d.status.message = Some(format!("queued: {message}"));
            d.requeue_at_most(REQUEUE_QUEUED);
        }
        None => d.requeue_at_most(REQUEUE_QUEUED),
    }
}

/// Kueue took the run's quota back (`Evicted`, or `Admitted` no longer true): the run ends.
fn evicted(d: &mut Decision, input: &Input) -> bool {
    if !kueue_mode(input) {
        return false;
    }
    let Some(queue) = &input.observed.queue else { return false };
    let why = match queue.evicted() {
        Some(why) => why,
        None if !queue.admitted() => "the Workload is no longer admitted".to_string(),
        None => return false,
    };
    end(
        d,
        input,
        RunEnd::Evicted,
        format!("evicted by Kueue ({why}): a simulation cannot be paused; stopping and archiving"),
    );
    true
}

fn generating_assets(d: &mut Decision, input: &Input, plan: &RunPlan) {
    let (now, generation) = (input.now, input.run.metadata.generation);
    if evicted(d, input) {
        return;
    }
    let apply = first_stage(input, plan);
    let has_assets_job = apply.iter().any(|c| c.kind() == Kind::Job && c.role() == Some(Role::Assets));
    d.apply = apply;
    if !has_assets_job {
        d.condition(
            ct::ASSETS_READY,
            true,
            "NoCache",
            "no object-store archive to cache assets in: each shard builds the world",
            now,
            generation,
        );
        d.enter(Phase::Starting, "starting the coordinator, routers and shards");
        return;
    }
    match input.observed.jobs_of(Role::Assets).map(|w| w.state.clone()).next() {
        Some(WorkState::Succeeded) => {
            // The role's outcome line (its pod's termination message): hit or built.
            let outcome = input
                .observed
                .pods_of(Role::Assets)
                .filter_map(|p| p.message.as_deref())
                .find_map(|m| serde_json::from_str::<AssetsOutcome>(m.trim()).ok());
            let (reason, message) = match &outcome {
                Some(o) => (o.reason(), o.to_string()),
                None => ("Built", "the assets Job finished".to_string()),
            };
            d.condition(ct::ASSETS_READY, true, reason, message, now, generation);
            d.enter(Phase::Starting, "assets ready; starting the coordinator, routers and shards");
        }
        Some(WorkState::Failed(reason)) => {
            d.condition(ct::ASSETS_READY, false, "Failed", reason.clone(), now, generation);
            end(
                d,
                input,
                RunEnd::RoleFailed,
                format!("role assets failed: Job {}: {reason}", names::assets_job(&plan.run.name)),
            );
        }
        Some(WorkState::Suspended) => {
            d.condition(ct::ASSETS_READY, false, "Generating", "the assets Job waits for Kueue", now, generation);
            d.requeue_at_most(REQUEUE_ACTIVE);
        }
        _ => {
            d.condition(ct::ASSETS_READY, false, "Generating", "the assets Job builds the world", now, generation);
            d.requeue_at_most(REQUEUE_ACTIVE);
        }
    }
}

/// Starting and Running: apply the workers (and the pilot once released), follow the
/// coordinator, end the run on its summary or on any role's failure.
fn live(d: &mut Decision, input: &Input, plan: &RunPlan) {
    let (now, generation) = (input.now, input.run.metadata.generation);
    let observed = input.observed;
    if evicted(d, input) {
        return;
    }
    let coordinator_failure = observed.coordinator.as_ref().and_then(|r| r.failed.clone());
    if let Some((role, reason)) = coordinator_failure.or_else(|| observed.failure()) {
        end(d, input, RunEnd::RoleFailed, format!("role {role} failed: {reason}"));
        return;
    }
    let report = observed.coordinator.clone().unwrap_or_default();
    if d.phase() == Phase::Starting && (report.pilots_released || report.finished.is_some()) {
        d.condition(ct::RUNNING, true, "PilotsReleased", "simulated time advances; pilot released", now, generation);
        d.status.start_time = Some(Time(now));
        d.enter(Phase::Running, "every shard is ready; the pilot is released");
    }
    let running = d.phase() == Phase::Running;
    let stop = if running { pilot_exited(d, input, plan) } else { None };
    if running {
        judge_pilot(d, input, plan, false);
    }
    // The pilot Job comes with the other workers: its pod is scheduled and its image pulled
    // while the shards start, and its init container releases it with the pilots.
    d.apply = children_for(input, plan, Stage { assets_job: false, pilot: true, stop }, |r| r != Role::Assets);
    d.status.endpoints = Some(endpoints(plan));

    // Progress.
    let shard_pods: Vec<_> = observed.pods_of(Role::Shard).collect();
    d.status.shards = plan
        .shards
        .iter()
        .map(|s| ShardStatus {
            index: s.index,
            drones: s.drone_count,
            ready: shard_pods.iter().any(|p| p.index == Some(s.index) && p.ready),
            sim_time_s: report.sim_time_s.filter(|_| running),
        })
        .collect();
    if let Some(sim) = report.sim_time_s.filter(|_| running) {
        let base =
            input.last_sample.or_else(|| d.status.start_time.as_ref().map(|t| Sample { sim_time_s: 0.0, at: t.0 }));
        if let Some(base) = base {
            let wall_s = (now.as_nanosecond() - base.at.as_nanosecond()) as f64 * 1e-9;
            if wall_s > 0.0 && sim >= base.sim_time_s && sim != base.sim_time_s {
                d.status.real_time_factor = Some(round3((sim - base.sim_time_s) / wall_s));
            }
        }
        if input.last_sample.map(|s| s.sim_time_s) != Some(sim) {
            d.sample = Some(Sample { sim_time_s: sim, at: now });
        } else {
            d.sample = input.last_sample;
        }
        d.status.sim_time_s = Some(sim);
    }
    if !running {
        let ready = d.status.shards.iter().filter(|s| s.ready).count();
        d.condition(
            ct::RUNNING,
            false,
            "Starting",
            format!("{ready} of {} shards ready; waiting for the coordinator to release the pilots", plan.shards.len()),
            now,
            generation,
        );
    }

    if let Some(finished) = &report.finished {
        d.status.sim_time_s = Some(finished.sim_time_s);
        d.status.real_time_factor = Some(round3(finished.real_time_factor));
        d.status.verdict = finished.verdict.clone();
        pilot_failure_into_verdict(&mut d.status);
        // The run failed before anything flew: its reason, not a verdict, says why.
        if let EndReason::PilotNotConnected(why) = &finished.end_reason {
            end(d, input, RunEnd::PilotNotConnected, why.clone());
            return;
        }
        end(d, input, RunEnd::Finished, format!("the coordinator finished the run ({})", finished.end_reason));
        return;
    }
    match observed.coordinator_state() {
        Some(WorkState::Succeeded) => {
            end(d, input, RunEnd::RoleFailed, "role coordinator failed: it exited without a summary".to_string());
        }
        _ => d.requeue_at_most(if running { REQUEUE_RUNNING } else { REQUEUE_ACTIVE }),
    }
}

/// The pilot Job has ended (complete or failed) while the run is Running. With `onExit:
/// endRun` the coordinator is asked to end the run (`Some(EndReason::PilotExited)`, the stop
/// annotation on its Pod), as `sadesim run` ends it when the pilot process exits; the
/// coordinator's summary then ends the run. With `onExit: continue` the run goes on to
/// `duration`. Either way the Running condition says so and one Event records it (a
/// Warning when the Job failed).
fn pilot_exited(d: &mut Decision, input: &Input, plan: &RunPlan) -> Option<EndReason> {
    let end = input.observed.pilot_end()?;
    let (now, generation) = (input.now, input.run.metadata.generation);
    let ends_run = plan.spec.pilot.as_ref().is_some_and(|p| p.on_exit.unwrap_or_default() == PilotExit::EndRun);
    let how = match &end {
        Ok(how) | Err(how) => how,
    };
    let message = if ends_run {
        format!("the pilot exited ({how}); onExit: endRun, so the coordinator ends the run after the current window")
    } else {
        format!("the pilot exited ({how}); onExit: continue, so the run goes on until spec.duration")
    };
    let first = condition(&d.status, ct::RUNNING).is_none_or(|c| c.reason != PILOT_EXITED);
    if first {
        d.events.push(Note { warning: end.is_err(), reason: PILOT_EXITED.into(), message: message.clone() });
    }
    d.condition(ct::RUNNING, true, PILOT_EXITED, message, now, generation);
    ends_run.then_some(EndReason::PilotExited)
}

/// The `Pilot` condition's reason when the pilot's end is not what `spec.pilot.expectedExit`
/// allows (the run then fails).
pub const PILOT_FAILED: &str = "PilotFailed";

/// Judges, once, how the pilot ended against `spec.pilot.expectedExit` into the `Pilot`
/// condition, as `sadesim run` does: when its Job has ended (exit code 0 when complete, the
/// pod's exit code when failed), or, with `run_over`, when the run ends with the Job still
/// there (still running). A failed expectation sets `Pilot=False` (`PilotFailed`) with the
/// exit code and the last lines of its log (the container's termination message, which
/// `FallbackToLogsOnError` fills from the log), and a Warning Event.
pub(super) fn judge_pilot(d: &mut Decision, input: &Input, plan: &RunPlan, run_over: bool) {
    use sadesim_crds::outcome::pilot::{PilotEnd, exit_words, log_tail};
    let Some(pilot) = plan.spec.pilot.as_ref() else { return };
    let observed = input.observed;
    if condition(&d.status, ct::PILOT).is_some() {
        return;
    }
    let (end, how) = match observed.pilot_end() {
        Some(Ok(how) | Err(how)) => {
            let code = observed.pilot_exit_code();
            (PilotEnd::Exited { code, signal: None }, format!("exited with {} ({how})", exit_words(code, None)))
        }
        None if run_over && observed.has_job(Role::Pilot) => {
            (PilotEnd::StillRunning, "still running when the run ended".to_string())
        }
        None => return,
    };
    let (now, generation) = (input.now, input.run.metadata.generation);
    let expected = pilot.expected_exit.unwrap_or_default();
    match expected.judge(&end) {
        None => {
            let message = format!("the pilot {how}; spec.pilot.expectedExit is {}", expected.as_str());
            d.condition(ct::PILOT, true, "AsExpected", message, now, generation);
        }
        Some(failure) => {
            let mut message = format!("{failure} ({how})");
            let tail = observed.pilot_message().map(log_tail).unwrap_or_default();
            if !tail.is_empty() {
                message.push_str("; the last lines of its log:\n");
                message.push_str(&tail.join("\n"));
            }
            d.events.push(Note { warning: true, reason: PILOT_FAILED.into(), message: message.clone() });
            d.condition(ct::PILOT, false, PILOT_FAILED, message, now, generation);
        }
    }
}

/// A `Pilot=False` condition fails the verdict (when the criteria were judged): one failure
/// line `spec.pilot.expectedExit: <why>`, added once.
pub(super) fn pilot_failure_into_verdict(status: &mut SimulationRunStatus) {
    use sadesim_crds::outcome::pilot::EXPECTED_EXIT_PATH;
    let Some(failed) = condition(status, ct::PILOT).filter(|c| c.status == "False") else { return };
    let line = format!("{EXPECTED_EXIT_PATH}: {}", failed.message.lines().next().unwrap_or_default());
    if let Some(v) = status.verdict.as_mut()
        && !v.failures.contains(&line)
    {
        v.passed = false;
        v.failures.push(line);
    }
}

fn round3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// Where to connect while the run is live: the in-cluster DNS names of the children's
/// Services (NodePort/LoadBalancer routers are also reachable at addresses the operator
/// does not know).
fn endpoints(plan: &RunPlan) -> Endpoints {
    let (run, ns) = (&plan.run.name, &plan.run.namespace);
    Endpoints {
        airspace: Some(format!("http://{}:{}", names::airspace_host(run, ns), plan.services.airspace_http)),
        mavlink: plan
            .segments
            .iter()
            .map(|s| format!("udp://{}.{ns}.svc:{}", names::mavlink_service(run, s.index), s.gcs_udp))
            .collect(),
        renderer: plan
            .spec
            .rendering()
            .enabled
            .then(|| format!("http://{}.{ns}.svc:{}", names::renderer(run), plan.services.renderer_http)),
        cameras: sadesim_planner::cluster_cameras_url(plan),
    }
}

/// Ends the run with `end` and enters Archiving.
fn end(d: &mut Decision, input: &Input, end: RunEnd, message: impl Into<String>) {
    let message = message.into();
    let (now, generation) = (input.now, input.run.metadata.generation);
    // Nothing more is created once the run ends.
    d.apply.clear();
    d.condition(ct::RUNNING, false, end.reason(), message.clone(), now, generation);
    d.condition(
        ct::ARCHIVED,
        false,
        "Archiving",
        "stopping the pilot, then the shards, then archiving",
        now,
        generation,
    );
    if end.warns() {
        d.events.push(Note { warning: true, reason: end.reason().into(), message: message.clone() });
    }
    d.enter(Phase::Archiving, message);
}
