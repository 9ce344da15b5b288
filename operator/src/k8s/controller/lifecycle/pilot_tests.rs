//! A pilot Job that fails fails the run (`spec.pilot.expectedExit`), as `sadesim run` does:
//! the `Pilot` condition names its exit code and the last lines of its log, the verdict and
//! the final phase fail; an expected failure passes.

use sadesim_crds::run::ExpectedExit;
use sadesim_crds::status::{Phase, condition_types as ct};

use super::tests::{
    archive_to_the_end, cond, coordinator_stop, decide_with, finished, later, pilot_observed, pilot_run, reasons,
    with_phase,
};
use super::*;
use crate::k8s::controller::observe::{Observed, WorkState};

/// A Running pilot run whose pilot Job failed with `code`, its log ending in a traceback
/// (the termination message `FallbackToLogsOnError` fills from the log).
fn failed_pilot(code: i32) -> Observed {
    let job = WorkState::Failed("BackoffLimitExceeded: Job has reached the specified backoff limit".into());
    let mut observed = pilot_observed(job, WorkState::Failed(format!("container pilot Error (exit code {code})")));
    let pod = observed.pods.iter_mut().find(|p| p.role == Some(Role::Pilot)).unwrap();
    pod.message =
        Some("starting\nTraceback (most recent call last):\nModuleNotFoundError: No module named 'cv2'\n".into());
    observed
}

fn run_expecting(expected: Option<ExpectedExit>) -> SimulationRun {
    let mut run = with_phase(pilot_run(), Phase::Running, true);
    run.spec.pilot.as_mut().unwrap().expected_exit = expected;
    run
}

#[test]
fn a_pilot_job_that_exits_1_fails_the_run_naming_its_code_and_log_tail() {
    let mut run = run_expecting(None);
    let observed = failed_pilot(1);
    let d = decide_with(&run, &observed, None, later(300));
    assert_eq!(coordinator_stop(&d).as_deref(), Some("pilotExited"), "it still ends the run (onExit: endRun)");
    let pilot = cond(&d, ct::PILOT);
    assert_eq!((pilot.status.as_str(), pilot.reason.as_str()), ("False", PILOT_FAILED));
    assert!(
        pilot.message.starts_with(
            "the pilot exited with code 1 before the run ended; spec.pilot.expectedExit is success (exited with code 1 (Job test-run-pilot failed: BackoffLimitExceeded"
        ),
        "{}",
        pilot.message
    );
    assert!(pilot.message.ends_with("the last lines of its log:\nstarting\nTraceback (most recent call last):\nModuleNotFoundError: No module named 'cv2'"), "{}", pilot.message);
    assert_eq!(reasons(&d), ["PilotExited", PILOT_FAILED]);

    // The coordinator's summary passes its criteria; the run fails all the same.
    run.status = Some(d.status.clone());
    let mut observed = observed;
    let mut done = finished(true);
    done.finished.as_mut().unwrap().end_reason = EndReason::PilotExited;
    observed.coordinator = Some(done);
    let steps = archive_to_the_end(run, observed, later(304));
    let last = steps.last().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Failed));
    let verdict = last.status.verdict.as_ref().unwrap();
    assert!(!verdict.passed);
    assert_eq!(verdict.failures.len(), 1, "{verdict:?}");
    assert!(verdict.failures[0].starts_with("spec.pilot.expectedExit: the pilot exited with code 1"), "{verdict:?}");
    let message = last.status.message.as_deref().unwrap();
    assert!(message.starts_with("the pilot failed: the pilot exited with code 1"), "{message}");
    assert!(message.contains("No module named 'cv2'"), "{message}");
    // Judged once: one PilotFailed Event over the whole run.
    let failed_events = steps.iter().flat_map(|d| &d.events).filter(|e| e.reason == PILOT_FAILED).count();
    assert_eq!(failed_events, 0, "the first decision above had it");
}

#[test]
fn an_expected_failure_passes_and_an_unexpected_success_fails() {
    // `failure`: exit 3 is as expected, the run succeeds.
    let mut run = run_expecting(Some(ExpectedExit::Failure));
    let mut observed = failed_pilot(3);
    let d = decide_with(&run, &observed, None, later(300));
    assert_eq!((cond(&d, ct::PILOT).status.as_str(), cond(&d, ct::PILOT).reason.as_str()), ("True", "AsExpected"));
    assert!(!reasons(&d).contains(&PILOT_FAILED));
    run.status = Some(d.status.clone());
    observed.coordinator = Some(finished(true));
    assert_eq!(archive_to_the_end(run, observed, later(304)).pop().unwrap().status.phase, Some(Phase::Succeeded));

    // `failure`, and the Job completes (exit 0): the run fails.
    let run = run_expecting(Some(ExpectedExit::Failure));
    let observed = pilot_observed(WorkState::Succeeded, WorkState::Succeeded);
    let d = decide_with(&run, &observed, None, later(300));
    let pilot = cond(&d, ct::PILOT);
    assert_eq!(pilot.status, "False");
    assert!(
        pilot
            .message
            .starts_with("the pilot exited with code 0 before the run ended; spec.pilot.expectedExit is failure"),
        "{}",
        pilot.message
    );

    // `any`: not judged as a failure.
    let run = run_expecting(Some(ExpectedExit::Any));
    let d = decide_with(&run, &failed_pilot(1), None, later(300));
    assert_eq!(cond(&d, ct::PILOT).status, "True");
}

#[test]
fn a_pilot_still_running_at_the_end_passes_unless_a_failure_was_expected() {
    for (expected, passes) in [(None, true), (Some(ExpectedExit::Failure), false)] {
        let mut run = run_expecting(expected);
        run.status.as_mut().unwrap().start_time = Some(k8s_openapi::apimachinery::pkg::apis::meta::v1::Time(later(0)));
        let mut observed = pilot_observed(WorkState::Running, WorkState::Running);
        // The run reaches its duration with the pilot still flying.
        observed.coordinator = Some(finished(true));
        let last = archive_to_the_end(run, observed, later(600)).pop().unwrap();
        let pilot = condition(&last.status, ct::PILOT).expect("judged before the Job was deleted");
        assert_eq!(pilot.status == "True", passes, "{expected:?}: {pilot:?}");
        assert!(pilot.message.contains("still running when the run ended"), "{}", pilot.message);
        let phase = if passes { Phase::Succeeded } else { Phase::Failed };
        assert_eq!(last.status.phase, Some(phase), "{expected:?}");
    }
}
