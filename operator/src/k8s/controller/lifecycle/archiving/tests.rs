//! Archiving, transition by transition: the order of the stops, the coordinator asked to end
//! the run first, the grace periods, deletion, archives that cannot be written.

use std::time::Duration;

use sadesim_crds::status::{ArchiveStatus, Phase, SimulationRunStatus, condition_types as ct};

use super::super::tests::*;
use super::super::*;
use crate::k8s::controller::observe::{Observed, WorkState};
use crate::k8s::controller::progress::CoordinatorReport;

#[test]
fn a_finished_run_archives_pilot_then_shards_then_the_rest_and_succeeds() {
    let mut run = with_phase(pilot_run(), Phase::Running, true);
    run.status.as_mut().unwrap().start_time = Some(Time(t0()));
    let mut observed = workers(WorkState::Running);
    observed.jobs.push(job("pilot", WorkState::Running));
    observed.pods.push(pod("test-run-pilot-abcde", "pilot", WorkState::Running, true));
    observed.coordinator = Some(finished(true));
    let steps = archive_to_the_end(run, observed, later(60));

    let first = &steps[0];
    assert_eq!(first.status.phase, Some(Phase::Archiving));
    assert_eq!(cond(first, ct::RUNNING).reason, RunEnd::Finished.reason());
    assert_eq!(first.status.sim_time_s, Some(120.0));
    assert_eq!(first.status.real_time_factor, Some(3.5));
    assert_eq!(first.archive_logs, ["test-run-pilot-abcde"]);
    assert_eq!(first.delete, [Delete { kind: Kind::Job, role: Some(Role::Pilot) }]);
    assert!(first.apply.is_empty());

    let second = &steps[1];
    assert_eq!(second.archive_logs, ["test-run-shard-0"]);
    assert_eq!(second.delete, [Delete { kind: Kind::Job, role: Some(Role::Shard) }]);

    let last = steps.last().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Succeeded));
    assert_eq!(cond(last, ct::ARCHIVED).status, "True");
    assert_eq!(last.archive_logs, ["test-run-coordinator", "test-run-router-0"]);
    assert_eq!(last.delete.len(), 4);
    assert_eq!(last.status.archive.as_ref().unwrap().url, format!("{ARCHIVE}/default/test-run/uid-1/"));
    assert!(last.status.completion_time.is_some());
    assert!(reasons(last).contains(&"Succeeded"));
    assert!(!last.remove_finalizer, "the finalizer stays until the run is deleted");
}

#[test]
fn a_file_archive_is_not_written_on_a_cluster_and_the_run_still_ends() {
    // examples/chicago-museum.yaml archives to file://runs for local runs: on a cluster that is
    // a folder inside the pods. The operator writes no pod logs there (its root is read-only)
    // and says so; the run ends by its verdict.
    let mut run = with_phase(new_run(), Phase::Running, true);
    run.spec.archive = Some(sadesim_crds::run::Archive { url: "file://runs".into() });
    let mut observed = workers(WorkState::Running);
    observed.coordinator = Some(finished(true));
    let steps = archive_to_the_end(run, observed, later(60));
    assert!(steps.iter().all(|d| d.archive.is_none()), "no archive folder for file://runs");
    let last = steps.last().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Succeeded));
    let archived = cond(last, ct::ARCHIVED);
    assert_eq!((archived.status.as_str(), archived.reason.as_str()), ("False", "NoArchive"));
    assert!(archived.message.contains("\"file://runs\" is not an object store"), "{}", archived.message);
    assert!(last.status.archive.is_none());
    assert!(reasons(last).contains(&"NoArchive"));
}

#[test]
fn failed_criteria_fail_the_run_after_archiving() {
    let run = with_phase(new_run(), Phase::Running, true);
    let mut observed = workers(WorkState::Running);
    observed.coordinator = Some(finished(false));
    let last = archive_to_the_end(run, observed, later(60)).pop().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Failed));
    assert!(last.status.message.as_ref().unwrap().contains("noCrashes"));
    assert_eq!(last.status.verdict.as_ref().map(|v| v.passed), Some(false));
}

#[test]
fn a_failed_role_fails_the_run_naming_the_role_and_reason() {
    let run = with_phase(new_run(), Phase::Running, true);
    let mut observed = workers(WorkState::Running);
    observed.jobs[1].state =
        WorkState::Failed("BackoffLimitExceeded: Job has reached the specified backoff limit".into());
    let steps = archive_to_the_end(run, observed, later(60));
    let first = &steps[0];
    assert_eq!(first.status.phase, Some(Phase::Archiving));
    assert_eq!(cond(first, ct::RUNNING).reason, RunEnd::RoleFailed.reason());
    assert!(cond(first, ct::RUNNING).message.contains("role shard failed: Job test-run-shard: BackoffLimitExceeded"));
    assert!(first.events.iter().any(|e| e.warning && e.reason == "RoleFailed"));
    let last = steps.last().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Failed));
    assert!(last.status.message.as_ref().unwrap().contains("role shard failed"));
}

#[test]
fn abort_stops_the_pilot_then_the_shards_then_archives() {
    let mut run = with_phase(pilot_run(), Phase::Running, true);
    run.spec.abort = true;
    let mut observed = workers(WorkState::Running);
    observed.jobs.push(job("pilot", WorkState::Running));
    observed.pods.push(pod("test-run-pilot-abcde", "pilot", WorkState::Running, true));
    let steps = archive_to_the_end(run, observed, later(60));
    assert_eq!(cond(&steps[0], ct::RUNNING).reason, RunEnd::Aborted.reason());
    assert_eq!(steps[0].delete, [Delete { kind: Kind::Job, role: Some(Role::Pilot) }]);
    assert_eq!(steps[1].delete, [Delete { kind: Kind::Job, role: Some(Role::Shard) }]);
    let last = steps.last().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Aborted));
    assert_eq!(cond(last, ct::ARCHIVED).status, "True");
}

/// Aborting a running run: the pilot goes first, then the coordinator is asked to end the
/// run, so its summary says `aborted`, and only then are the shards deleted.
#[test]
fn abort_asks_the_running_coordinator_to_end_the_run_before_the_shards_go() {
    let mut run = with_phase(pilot_run(), Phase::Running, true);
    run.spec.abort = true;
    let observed = pilot_observed(WorkState::Running, WorkState::Running);
    let steps = archive_to_the_end(run, observed, later(60));
    assert_eq!(steps[0].delete, [Delete { kind: Kind::Job, role: Some(Role::Pilot) }]);
    assert_eq!(coordinator_stop(&steps[0]), None, "the pilot stops first");
    assert_eq!(coordinator_stop(&steps[1]).as_deref(), Some("aborted"));
    assert_eq!(roles(&steps[1].apply), ["Pod coordinator"], "only the coordinator Pod is applied");
    assert!(steps[1].delete.is_empty(), "the shards stay until the coordinator has ended the run");
    assert!(cond(&steps[1], ct::ARCHIVED).message.contains("asking the coordinator"));
    // The coordinator answered (the helper's `finished` line): now the shards go.
    assert!(steps[2].apply.is_empty());
    assert_eq!(steps[2].delete, [Delete { kind: Kind::Job, role: Some(Role::Shard) }]);
    assert_eq!(steps.last().unwrap().status.phase, Some(Phase::Aborted));
}

#[test]
fn a_coordinator_that_does_not_end_the_run_on_request_is_not_waited_for_long() {
    let mut run = with_phase(new_run(), Phase::Running, true);
    run.metadata.deletion_timestamp = Some(Time(later(5)));
    let mut observed = workers(WorkState::Running);
    observed.coordinator =
        Some(CoordinatorReport { sim_time_s: Some(80.0), pilots_released: true, ..Default::default() });
    let d = decide_with(&run, &observed, None, later(10));
    assert_eq!(coordinator_stop(&d).as_deref(), Some("deleted"));
    run.status = Some(d.status);
    // An old worker image without --control-file never answers.
    let d = decide_with(&run, &observed, None, later(10 + STOP_GRACE_S - 1));
    assert!(coordinator_stop(&d).is_some() && d.delete.is_empty());
    let d = decide_with(&run, &observed, None, later(10 + STOP_GRACE_S));
    assert_eq!(coordinator_stop(&d), None);
    assert_eq!(d.delete, [Delete { kind: Kind::Job, role: Some(Role::Shard) }]);
}

#[test]
fn a_coordinator_still_waiting_for_shards_is_not_asked_to_stop() {
    let mut run = with_phase(new_run(), Phase::Starting, true);
    run.spec.abort = true;
    let mut observed = workers(WorkState::Running);
    observed.coordinator = Some(CoordinatorReport::default());
    let d = decide_with(&run, &observed, None, later(10));
    assert_eq!(coordinator_stop(&d), None, "it reads requests only once the run started");
    assert_eq!(d.delete, [Delete { kind: Kind::Job, role: Some(Role::Shard) }]);
}

#[test]
fn archiving_waits_for_the_coordinator_but_not_forever() {
    let mut run = with_phase(new_run(), Phase::Running, true);
    run.spec.abort = true;
    let observed = Observed {
        pods: vec![pod("test-run-coordinator", "coordinator", WorkState::Running, false)],
        ..Default::default()
    };
    let d = decide_with(&run, &observed, None, later(10));
    assert_eq!(d.status.phase, Some(Phase::Archiving));
    assert!(d.archive_logs.is_empty() && d.delete.is_empty());
    run.status = Some(d.status);
    let d = decide_with(&run, &observed, None, later(10 + COORDINATOR_GRACE_S));
    assert_eq!(d.status.phase, Some(Phase::Aborted));
    assert_eq!(d.archive_logs, ["test-run-coordinator"]);
}

#[test]
fn deletion_archives_before_the_finalizer_goes() {
    let mut run = with_phase(new_run(), Phase::Running, true);
    run.metadata.deletion_timestamp = Some(Time(later(5)));
    let observed = workers(WorkState::Running);
    let steps = archive_to_the_end(run, observed, later(60));
    assert_eq!(cond(&steps[0], ct::RUNNING).reason, RunEnd::Deleted.reason());
    assert!(steps[..steps.len() - 1].iter().all(|d| !d.remove_finalizer));
    let last = steps.last().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Aborted));
    assert!(last.remove_finalizer);
    assert!(!last.archive_logs.is_empty());
}

#[test]
fn deleting_a_finished_or_never_started_run_just_removes_the_finalizer() {
    let mut done = with_phase(new_run(), Phase::Succeeded, true);
    done.metadata.deletion_timestamp = Some(Time(later(5)));
    let d = decide_with(&done, &Observed::default(), None, later(6));
    assert!(d.remove_finalizer && d.apply.is_empty() && d.delete.is_empty());
    assert_eq!(d.status, done.status.clone().unwrap());

    let mut queued = with_phase(new_run(), Phase::Queued, true);
    queued.metadata.deletion_timestamp = Some(Time(later(5)));
    let d = decide_with(&queued, &Observed::default(), None, later(6));
    assert!(d.remove_finalizer && d.delete.is_empty());
    assert_eq!(d.status.phase, Some(Phase::Aborted));
}

#[test]
fn an_archive_that_cannot_be_written_keeps_the_run_archiving_and_backs_off() {
    // Archiving began at t0; the decision had reached Succeeded with the archive filled in.
    let mut previous = SimulationRunStatus { phase: Some(Phase::Archiving), ..Default::default() };
    set_condition(&mut previous.conditions, ct::ARCHIVED, false, "Archiving", "stopping the shards", t0(), Some(1));
    let mut decided = previous.clone();
    decided.phase = Some(Phase::Succeeded);
    decided.completion_time = Some(Time(later(3)));
    decided.archive = Some(ArchiveStatus { url: format!("{ARCHIVE}/x/"), files: Some(3), bytes: Some(9) });

    let (status, wait) = archive_failed(&previous, &decided, ARCHIVE, "connection refused", later(3), Some(1));
    assert_eq!(status.phase, Some(Phase::Archiving));
    assert_eq!(status.completion_time, None);
    assert_eq!(status.archive, None);
    let archived = condition(&status, ct::ARCHIVED).unwrap();
    assert_eq!((archived.status.as_str(), archived.reason.as_str()), ("False", ARCHIVE_FAILED));
    assert!(
        archived.message.contains(ARCHIVE) && archived.message.contains("connection refused"),
        "{}",
        archived.message
    );
    assert_eq!(wait, Duration::from_secs(2));

    // The wait grows with the time since Archiving began, up to a minute.
    assert_eq!(archive_failed(&previous, &decided, ARCHIVE, "e", later(40), Some(1)).1, Duration::from_secs(20));
    assert_eq!(archive_failed(&previous, &decided, ARCHIVE, "e", later(600), Some(1)).1, Duration::from_secs(60));
}
