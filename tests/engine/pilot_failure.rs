//! A pilot that fails fails the run: a pilot process that exits non-zero or is killed by a
//! signal before the run ends makes the verdict fail, with its exit and the last lines of
//! its log in `summary.json` (`pilot`) and an `expectedExit` entry in the verdict, unless
//! `spec.pilot.expectedExit` says that end is expected. With threads and with worker
//! processes (where the coordinator process writes `summary.json` first).
//!
//! The pilots are shell scripts flying nothing: the drones fly scripted missions without
//! MAVLink.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunReport, run_local};
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::outcome::pilot::EXPECTED_EXIT_PATH;
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::run::{Clock, ClockMode, ExpectedExit, Pilot};

/// Two scripted drones, a `noCrashes` criterion, and `script` (sh) as the pilot.
fn scenario(script: &str, expected_exit: Option<ExpectedExit>) -> SimulationRun {
    RunBuilder::test()
        .with_drones(2)
        .with(|r| {
            r.spec.duration = "10m".parse().unwrap();
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            r.spec.criteria = vec![sadesim_crds::criteria::Criterion::NoCrashes {}];
            r.spec.pilot = Some(Pilot {
                command: vec!["sh".into(), "-c".into(), script.into()],
                expected_exit,
                ..Pilot::default()
            });
        })
        .build()
}

fn run(name: &str, r: &SimulationRun, processes: bool) -> (PathBuf, RunReport) {
    let root =
        crate::local::scratch("pilot-failure", &format!("{name}-{}", if processes { "processes" } else { "threads" }));
    let options = crate::local::options(&root, processes);
    let report = run_local(r, &options, Arc::new(AtomicBool::new(false))).expect("the run completes");
    (root, report)
}

/// `summary.json` as written in the run folder: the same as the report's.
fn summary_on_disk(report: &RunReport) -> RunSummary {
    let text = std::fs::read_to_string(report.out_dir.join("summary.json")).unwrap();
    let on_disk: RunSummary = serde_json::from_str(&text).unwrap();
    assert_eq!(on_disk, report.summary);
    on_disk
}

/// Like the README's precision-landing pilot without OpenCV: a traceback, then exit 1.
const DIES_AT_ONCE: &str = r#"
echo "precision landing: starting"
echo "Traceback (most recent call last):" >&2
echo "ModuleNotFoundError: No module named 'cv2'" >&2
exit 1
"#;

fn a_pilot_that_exits_1_at_once_fails_the_run(processes: bool) {
    let (root, report) = run("exit-1", &scenario(DIES_AT_ONCE, None), processes);
    let s = summary_on_disk(&report);
    // It ended the run (onExit: endRun), as before.
    assert_eq!(s.end_reason, EndReason::PilotExited);
    let pilot = s.pilot.as_ref().expect("summary.json has the pilot");
    assert_eq!((pilot.exit_code, pilot.signal, pilot.as_expected), (Some(1), None, false), "{pilot:?}");
    assert_eq!(pilot.expected_exit, ExpectedExit::Success);
    assert!(pilot.exited_at_s.is_some() && pilot.exited_at_wall_s.is_some_and(|w| w > 0.0), "{pilot:?}");
    assert_eq!(pilot.log_tail.last().map(String::as_str), Some("ModuleNotFoundError: No module named 'cv2'"));
    assert_eq!(pilot.log_tail.len(), 3, "{pilot:?}");
    assert_eq!(
        pilot.failure.as_deref(),
        Some("the pilot exited with code 1 before the run ended; spec.pilot.expectedExit is success")
    );
    // The verdict fails on it, though the criterion passed.
    let verdict = s.verdict.as_ref().expect("judged");
    assert!(!verdict.passed);
    assert!(verdict.criteria[0].passed, "noCrashes: {verdict:?}");
    let entry = &verdict.criteria[1];
    assert_eq!(
        (entry.path.as_str(), entry.criterion.as_str(), entry.passed),
        (EXPECTED_EXIT_PATH, "expectedExit", false)
    );
    // The manifest was written after: the rewritten summary.json verifies.
    let verified = sadesim_evidence::archive::verify(report.out_dir.to_str().unwrap()).unwrap();
    assert!(verified.passed(), "{:?}", verified.problems);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_pilot_that_exits_1_at_once_fails_the_run_with_its_exit_and_log_tail() {
    a_pilot_that_exits_1_at_once_fails_the_run(false);
}

#[test]
fn a_pilot_that_exits_1_at_once_fails_the_run_with_processes_too() {
    a_pilot_that_exits_1_at_once_fails_the_run(true);
}

#[test]
fn a_pilot_killed_by_a_signal_fails_the_run() {
    let (root, report) = run("signal", &scenario("echo about to be killed; kill -KILL $$", None), false);
    let pilot = summary_on_disk(&report).pilot.expect("summary.json has the pilot");
    assert_eq!((pilot.exit_code, pilot.signal, pilot.as_expected), (None, Some(9), false), "{pilot:?}");
    assert!(pilot.failure.as_deref().unwrap().contains("exited with SIGKILL"), "{pilot:?}");
    assert_eq!(pilot.log_tail, ["about to be killed"]);
    assert!(!report.summary.verdict.unwrap().passed);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn an_expected_failure_declared_in_the_scenario_passes_and_an_unexpected_success_fails() {
    // Expected: exit 1 passes, and so does anything with `any`.
    for (name, script, expected) in
        [("expected-1", "exit 1", ExpectedExit::Failure), ("any-1", "exit 1", ExpectedExit::Any)]
    {
        let (root, report) = run(name, &scenario(script, Some(expected)), false);
        let s = summary_on_disk(&report);
        let pilot = s.pilot.as_ref().unwrap();
        assert_eq!((pilot.exit_code, pilot.as_expected, pilot.expected_exit), (Some(1), true, expected), "{pilot:?}");
        let verdict = s.verdict.unwrap();
        assert!(verdict.passed && verdict.criteria.len() == 1, "{name}: {verdict:?}");
        std::fs::remove_dir_all(&root).unwrap();
    }
    // `failure` and exit 0: the pilot did not refuse as it was meant to.
    let (root, report) = run("expected-0", &scenario("exit 0", Some(ExpectedExit::Failure)), false);
    let s = summary_on_disk(&report);
    assert_eq!(
        s.pilot.unwrap().failure.as_deref(),
        Some("the pilot exited with code 0 before the run ended; spec.pilot.expectedExit is failure")
    );
    assert!(!s.verdict.unwrap().passed);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_pilot_that_exits_0_passes_as_before() {
    let (root, report) = run("exit-0", &scenario("echo done", None), false);
    let s = summary_on_disk(&report);
    assert_eq!(s.end_reason, EndReason::PilotExited);
    let pilot = s.pilot.unwrap();
    assert_eq!((pilot.exit_code, pilot.as_expected, pilot.failure), (Some(0), true, None));
    assert_eq!(pilot.log_tail, ["done"]);
    let verdict = s.verdict.unwrap();
    assert!(verdict.passed && verdict.criteria.len() == 1, "{verdict:?}");
    std::fs::remove_dir_all(&root).unwrap();
}
