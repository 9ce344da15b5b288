//! Archiving, the phase every end passes through: where the run's evidence goes (only an
//! object store on a cluster), the steps that stop the pilot, the shards and the rest with
//! each role's log archived first, and the status while the archive cannot be written.

use std::time::Duration;

use k8s_openapi::apimachinery::pkg::apis::meta::v1::Time;
use k8s_openapi::jiff::Timestamp;
use sadesim_crds::status::{ArchiveStatus, Phase, SimulationRunStatus, condition_types as ct};

use super::super::observe::WorkState;
use super::{
    COORDINATOR_GRACE_S, Decision, Delete, Input, Note, REQUEUE_ARCHIVING, RunEnd, STOP_GRACE_S, children_for,
    children_may_exist, condition, kueue_mode, set_condition,
};
use crate::k8s::children::{Child, Kind, Role, RunFolder, Stage};

#[cfg(test)]
mod tests;

/// The archive URL of the run: `spec.archive.url`, else the operator's default.
fn archive_url<'a>(input: &'a Input) -> Option<&'a str> {
    let run = input.run;
    run.spec.archive.as_ref().map(|a| a.url.as_str()).or(input.settings.default_archive_url.as_deref())
}

/// The archive folder of the run, in its object store ([`archive_url`]). A `file://` archive
/// is a folder inside a pod on a cluster (the operator's own root is read-only, the
/// coordinator's is lost with it): nothing is archived there, as the run's `Valid` warning
/// says (`children::problems`), unless the settings allow `file_archives` (tests).
pub(super) fn archive_folder(input: &Input) -> Option<RunFolder> {
    let meta = &input.run.metadata;
    let writable = |u: &&str| input.settings.file_archives || sadesim_evidence::archive::is_object_store(u);
    let url = archive_url(input).filter(writable)?;
    Some(RunFolder::new(
        url,
        meta.namespace.as_deref().unwrap_or("default"),
        meta.name.as_deref().unwrap_or_default(),
        meta.uid.as_deref().unwrap_or("unknown-uid"),
    ))
}

/// The status to write when the pod logs could not be written to the archive at `url`
/// (`error`), instead of `decided`: the run stays in Archiving, whatever phase `decided`
/// reached (never a terminal phase while evidence is missing), with its archive as
/// `previous` had it and `Archived=False` (`ArchiveFailed`) naming the archive and the
/// error. Also the wait before the next attempt: half the time since Archiving began,
/// between 2 s and 60 s, so that attempts back off about exponentially.
pub fn archive_failed(
    previous: &SimulationRunStatus,
    decided: &SimulationRunStatus,
    url: &str,
    error: &str,
    now: Timestamp,
    generation: Option<i64>,
) -> (SimulationRunStatus, Duration) {
    let since = condition(previous, ct::ARCHIVED).map_or(now, |c| c.last_transition_time.0);
    let waited_s = u64::try_from((now.as_nanosecond() - since.as_nanosecond()) / 1_000_000_000).unwrap_or(0);
    let wait = Duration::from_secs((waited_s / 2).clamp(ARCHIVE_RETRY_MIN_S, ARCHIVE_RETRY_MAX_S));
    let mut status = decided.clone();
    status.phase = Some(Phase::Archiving);
    status.completion_time = previous.completion_time.clone();
    status.archive = previous.archive.clone();
    let message = format!("cannot write to the archive {url}; retrying in {} s: {error}", wait.as_secs());
    status.message = Some(message.clone());
    set_condition(&mut status.conditions, ct::ARCHIVED, false, ARCHIVE_FAILED, &message, now, generation);
    (status, wait)
}

/// The reason of `Archived=False` while the archive cannot be written.
pub const ARCHIVE_FAILED: &str = "ArchiveFailed";
/// Bounds of the wait between two attempts to write to an archive that failed.
const ARCHIVE_RETRY_MIN_S: u64 = 2;
const ARCHIVE_RETRY_MAX_S: u64 = 60;

/// Seconds since Archiving began (the Archived condition's transition).
fn since_s(d: &Decision, now: Timestamp) -> i128 {
    let since = condition(&d.status, ct::ARCHIVED).map_or(now, |c| c.last_transition_time.0);
    (now.as_nanosecond() - since.as_nanosecond()) / 1_000_000_000
}

/// The coordinator Pod with the stop annotation, while a run that ended without the
/// coordinator (abort, deletion, another role's failure) should first be ended by it: its
/// summary then says why (`endReason: aborted`) instead of blaming the shards deleted
/// under it. `None` once the coordinator has finished or failed, is not live, never
/// released the pilots (it is still waiting for shards and does not read requests yet),
/// or did not answer within [`STOP_GRACE_S`] of Archiving's start.
fn coordinator_to_stop(input: &Input, status: &SimulationRunStatus, waited_s: i128) -> Option<Child> {
    let observed = input.observed;
    let report = observed.coordinator.clone().unwrap_or_default();
    let live = matches!(observed.coordinator_state(), Some(WorkState::Running));
    if !live || !report.pilots_released || report.finished.is_some() || report.failed.is_some() {
        return None;
    }
    if waited_s >= i128::from(STOP_GRACE_S) {
        return None;
    }
    let ended = match condition(status, ct::RUNNING) {
        Some(c) => RunEnd::of_reason(&c.reason)?,
        None => RunEnd::Aborted,
    };
    let reason = ended.stop_reason()?;
    let plan = input.plan.as_ref().ok()?;
    let stage = Stage { assets_job: false, pilot: false, stop: Some(reason) };
    children_for(input, plan, stage, |r| r == Role::Coordinator).into_iter().find(|c| c.kind() == Kind::Pod)
}

/// One step of Archiving, driven by what still exists: pilot, then (after asking the
/// coordinator to end the run) shards, then (after the coordinator ended or its grace
/// passed) everything else.
pub(super) fn archive_step(d: &mut Decision, input: &Input) {
    let (now, generation) = (input.now, input.run.metadata.generation);
    let observed = input.observed;
    let pods_of = |role: Role| observed.pods_of(role).map(|p| p.name.clone()).collect::<Vec<_>>();
    d.status.endpoints = None;
    if observed.has_job(Role::Pilot) {
        // Judged before the Job goes: a pilot still running now is stopped by the run.
        if let Ok(plan) = input.plan {
            super::judge_pilot(d, input, plan, true);
        }
        d.archive_logs = pods_of(Role::Pilot);
        d.delete = vec![Delete { kind: Kind::Job, role: Some(Role::Pilot) }];
        d.condition(ct::ARCHIVED, false, "Archiving", "stopping the pilot", now, generation);
        d.requeue_at_most(REQUEUE_ARCHIVING);
        return;
    }
    if observed.has_job(Role::Shard) {
        if let Some(coordinator) = coordinator_to_stop(input, &d.status, since_s(d, now)) {
            d.apply = vec![coordinator];
            d.condition(
                ct::ARCHIVED,
                false,
                "Archiving",
                "asking the coordinator to end the run before the shards stop",
                now,
                generation,
            );
            d.requeue_at_most(REQUEUE_ARCHIVING);
            return;
        }
        d.archive_logs = pods_of(Role::Shard);
        d.delete = vec![Delete { kind: Kind::Job, role: Some(Role::Shard) }];
        d.condition(ct::ARCHIVED, false, "Archiving", "stopping the shards", now, generation);
        d.requeue_at_most(REQUEUE_ARCHIVING);
        return;
    }
    let waited_s = since_s(d, now);
    let coordinator_live = matches!(observed.coordinator_state(), Some(WorkState::Pending | WorkState::Running));
    if coordinator_live && waited_s < i128::from(COORDINATOR_GRACE_S) {
        d.condition(
            ct::ARCHIVED,
            false,
            "Archiving",
            "waiting for the coordinator to write and upload the run",
            now,
            generation,
        );
        d.requeue_at_most(Duration::from_secs(5));
        return;
    }
    let rest = |p: &&super::super::observe::Workload| !matches!(p.role, Some(Role::Pilot | Role::Shard));
    d.archive_logs = observed.pods.iter().filter(rest).map(|p| p.name.clone()).collect();
    if children_may_exist(&d.status, observed) {
        d.delete = [Kind::Job, Kind::Pod, Kind::Deployment, Kind::Service]
            .into_iter()
            .map(|kind| Delete { kind, role: None })
            .collect();
    }
    // The Workload goes last: Kueue gives the run's quota back to the queue when it is
    // deleted (no pod of the run is left to use it).
    if kueue_mode(input) && (observed.queue.is_some() || children_may_exist(&d.status, observed)) {
        d.delete.push(Delete { kind: Kind::Workload, role: None });
    }
    match d.archive.clone() {
        Some(folder) => {
            let folder = folder.url();
            d.status.archive = Some(ArchiveStatus { url: folder.clone(), files: None, bytes: None });
            d.condition(ct::ARCHIVED, true, "Archived", "pod logs and recordings are in the archive", now, generation);
            d.events.push(Note { warning: false, reason: "Archived".into(), message: format!("evidence in {folder}") });
        }
        None => {
            let why = match archive_url(input) {
                Some(url) => format!(
                    "the archive {url:?} is not an object store (s3://, gs:// or az://), and a folder inside the pods is lost with them"
                ),
                None => "no archive URL (spec.archive.url or --default-archive-url)".to_string(),
            };
            d.condition(ct::ARCHIVED, false, "NoArchive", format!("{why}: nothing was archived"), now, generation);
            d.events.push(Note {
                warning: true,
                reason: "NoArchive".into(),
                message: format!("{why}: the run's evidence was not kept"),
            });
        }
    }
    let ended = condition(&d.status, ct::RUNNING).map(|c| (c.reason.clone(), c.message.clone()));
    let (end, message) = match ended {
        Some((reason, message)) => (RunEnd::of_reason(&reason), message),
        None => (Some(RunEnd::Aborted), "the run ended".to_string()),
    };
    super::pilot_failure_into_verdict(&mut d.status);
    let pilot_failed = condition(&d.status, ct::PILOT).filter(|c| c.status == "False").map(|c| c.message.clone());
    let phase = match end {
        Some(RunEnd::Finished) => {
            let passed = match &d.status.verdict {
                Some(v) => v.passed,
                None => input.run.spec.criteria.is_empty(),
            };
            if passed && pilot_failed.is_none() { Phase::Succeeded } else { Phase::Failed }
        }
        Some(RunEnd::Aborted | RunEnd::Deleted) => Phase::Aborted,
        _ => Phase::Failed,
    };
    let message = match (phase, &d.status.verdict) {
        (Phase::Failed, verdict) if end == Some(RunEnd::Finished) && pilot_failed.is_some() => {
            let path = sadesim_crds::outcome::pilot::EXPECTED_EXIT_PATH;
            let others: Vec<&str> =
                verdict.iter().flat_map(|v| &v.failures).map(String::as_str).filter(|f| !f.starts_with(path)).collect();
            let mut message = format!("the pilot failed: {}", pilot_failed.unwrap_or_default());
            if !others.is_empty() {
                message = format!("criteria failed: {}; {message}", others.join("; "));
            }
            message
        }
        (Phase::Failed, Some(v)) if end == Some(RunEnd::Finished) && !v.failures.is_empty() => {
            format!("criteria failed: {}", v.failures.join("; "))
        }
        (Phase::Failed, None) if end == Some(RunEnd::Finished) => "the criteria were not judged".to_string(),
        _ => message,
    };
    d.status.completion_time = Some(Time(now));
    d.enter(phase, message);
}
