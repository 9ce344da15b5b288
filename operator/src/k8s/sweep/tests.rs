//! Sweep controller tests: the pure decision over a sweep and its runs in every state, then
//! the reconcile against kube's `tower_test` mock API server, asserting each request
//! (method, path, query, content type, body) in order.

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use http::{Method, Request, Response};
use k8s_openapi::apimachinery::pkg::apis::meta::v1::{Condition, Time};
use k8s_openapi::jiff::Timestamp;
use kube::Client;
use kube::client::Body;
use sadesim_crds::criteria::Criterion;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::outcome::verdict::{CriterionResult, RunVerdict};
use sadesim_crds::run::Archive;
use sadesim_crds::status::ArchiveStatus;
use sadesim_crds::status::{SimulationRunStatus, Verdict};
use sadesim_crds::sweep::condition_types as ct;
use sadesim_crds::sweep::{
    CELL_LABEL, Parameter, REPETITION_LABEL, SWEEP_LABEL, SimulationSweep, SimulationSweepSpec, SimulationSweepStatus,
    SweepBase, SweepPhase,
};
use sadesim_crds::{Phase, SimulationRun};
use serde_json::{Value, json};
use tower_test::mock;

use super::lifecycle::{SweepDecision, decide, expansion_of};
use super::reconcile::{Context, reconcile};
use super::report;
use crate::k8s::controller::metrics::Metrics;
use crate::k8s::controller::reconcile::MANAGER;
use crate::k8s::fake_api::Seen;

const NS: &str = "team-a";
const RUNS: &str = "/apis/sadesim.io/v1alpha1/namespaces/team-a/simulationruns";
const SWEEP_STATUS: &str = "/apis/sadesim.io/v1alpha1/namespaces/team-a/simulationsweeps/wind/status";

fn t0() -> Timestamp {
    Timestamp::from_second(1_800_000_000).unwrap()
}

/// Sweep `wind` in `team-a`: the fixture run (criterion `noCrashes`) with 1, 2 and 3 drones (three cells), two
/// repetitions each: six runs, default parallelism (4).
fn sweep() -> SimulationSweep {
    let mut base = RunBuilder::test().build().spec;
    base.criteria = vec![Criterion::NoCrashes {}];
    let spec = SimulationSweepSpec {
        base: SweepBase { spec: Some(Box::new(base)), file: None },
        overrides: Vec::new(),
        parameters: vec![Parameter {
            name: "drones".into(),
            field: "spec.fleet[0].count".into(),
            values: Some(vec![json!(1), json!(2), json!(3)]),
            range: None,
            random: None,
        }],
        repetitions: Some(2),
        parallelism: None,
        seed: None,
        queue: None,
        report: None,
    };
    let mut sweep = SimulationSweep::new("wind", spec);
    sweep.metadata.namespace = Some(NS.into());
    sweep.metadata.uid = Some("sweep-uid".into());
    sweep.metadata.generation = Some(1);
    sweep
}

/// The sweep's runs in expansion order (c0-r0, c0-r1, c1-r0, ...), as created.
fn runs_of(sweep: &SimulationSweep) -> Vec<SimulationRun> {
    expansion_of(sweep).unwrap().runs.into_iter().map(|r| r.run).collect()
}

/// `run` in `phase`, with a verdict when `passed` is given.
fn in_phase(mut run: SimulationRun, phase: Phase, passed: Option<bool>) -> SimulationRun {
    let verdict = passed.map(|passed| Verdict {
        passed,
        failures: if passed { vec![] } else { vec!["every drone lands: 1 did not".into()] },
        unauthorized_entries: None,
        crashes: None,
    });
    run.status = Some(SimulationRunStatus { phase: Some(phase), verdict, ..Default::default() });
    run
}

fn decide_now(sweep: &SimulationSweep, existing: &[SimulationRun]) -> SweepDecision {
    decide(sweep, &expansion_of(sweep), existing, t0())
}

fn names(runs: &[SimulationRun]) -> Vec<&str> {
    runs.iter().map(|r| r.metadata.name.as_deref().unwrap()).collect()
}

fn condition<'a>(status: &'a SimulationSweepStatus, type_: &str) -> Option<&'a Condition> {
    status.conditions.iter().find(|c| c.type_ == type_)
}

/// (phase, created, inFlight, finished, passed, failed)
fn counts(s: &SimulationSweepStatus) -> (SweepPhase, u32, u32, u32, u32, u32) {
    let n = |v: Option<u32>| v.unwrap();
    (s.phase.unwrap(), n(s.created), n(s.in_flight), n(s.finished), n(s.passed), n(s.failed))
}

// ---- decide ------------------------------------------------------------------------

#[test]
fn a_new_sweep_creates_its_first_runs_up_to_the_default_parallelism_of_four() {
    let d = decide_now(&sweep(), &[]);
    assert_eq!(names(&d.create), ["wind-c0-r0", "wind-c0-r1", "wind-c1-r0", "wind-c1-r1"]);
    assert_eq!(d.status.runs, Some(6));
    assert_eq!(counts(&d.status), (SweepPhase::Running, 4, 4, 0, 0, 0));
    let valid = condition(&d.status, ct::VALID).unwrap();
    assert_eq!(valid.status, "True");
    assert_eq!(valid.message, "6 runs: 3 cells x 2 repetitions");
    assert_eq!(condition(&d.status, ct::COMPLETE).unwrap().status, "False");
    assert!(!d.report_due);
    // Labelled, in the sweep's namespace, with the cell's values and the repetition's seed.
    let run = &d.create[3];
    assert_eq!(run.metadata.namespace.as_deref(), Some(NS));
    let labels = run.metadata.labels.as_ref().unwrap();
    assert_eq!(labels[SWEEP_LABEL], "wind");
    assert_eq!(labels[CELL_LABEL], "1");
    assert_eq!(labels[REPETITION_LABEL], "1");
    assert_eq!(run.spec.fleet[0].count, 2);
    assert_eq!(run.spec.seed, Some(8), "the base's seed 7 + repetition 1");
}

#[test]
fn every_created_run_is_owned_by_the_sweep_so_deleting_the_sweep_deletes_it() {
    let d = decide_now(&sweep(), &[]);
    for run in &d.create {
        let owners = run.metadata.owner_references.as_ref().unwrap();
        assert_eq!(owners.len(), 1);
        let o = &owners[0];
        assert_eq!((o.api_version.as_str(), o.kind.as_str()), ("sadesim.io/v1alpha1", "SimulationSweep"));
        assert_eq!((o.name.as_str(), o.uid.as_str()), ("wind", "sweep-uid"));
        assert_eq!(o.controller, Some(true), "the sweep controls the run: its changes wake the sweep");
        assert_eq!(o.block_owner_deletion, Some(true));
    }
}

#[test]
fn no_more_runs_are_created_while_the_parallelism_is_used() {
    let sweep = sweep();
    let running: Vec<SimulationRun> =
        runs_of(&sweep).into_iter().take(4).map(|r| in_phase(r, Phase::Running, None)).collect();
    let d = decide_now(&sweep, &running);
    assert!(d.create.is_empty(), "{:?}", names(&d.create));
    assert_eq!(counts(&d.status), (SweepPhase::Running, 4, 4, 0, 0, 0));

    // A parallelism of 2 with one run in flight leaves room for one more.
    let mut narrow = sweep.clone();
    narrow.spec.parallelism = Some(2);
    let d = decide_now(&narrow, &running[..1]);
    assert_eq!(names(&d.create), ["wind-c0-r1"]);
    assert_eq!(counts(&d.status), (SweepPhase::Running, 2, 2, 0, 0, 0));
}

#[test]
fn as_runs_end_the_next_ones_are_created_in_expansion_order() {
    let sweep = sweep();
    let runs = runs_of(&sweep);
    let existing = vec![
        in_phase(runs[0].clone(), Phase::Succeeded, Some(true)),
        in_phase(runs[1].clone(), Phase::Failed, Some(false)),
        in_phase(runs[2].clone(), Phase::Running, None),
        in_phase(runs[3].clone(), Phase::Queued, None),
    ];
    let d = decide_now(&sweep, &existing);
    assert_eq!(names(&d.create), ["wind-c2-r0", "wind-c2-r1"]);
    assert_eq!(counts(&d.status), (SweepPhase::Running, 6, 4, 2, 1, 1));
    assert_eq!(d.status.message.as_deref(), Some("2 of 6 runs finished (1 passed, 1 failed), 4 in flight"));
    let c0 = &d.status.cells[0];
    assert_eq!((c0.label.as_str(), c0.finished, c0.passed, c0.pass_rate), ("drones=1", 2, 1, Some(0.5)));
    assert_eq!(d.status.cells[1].pass_rate, None, "no rate while none of the cell finished");
}

#[test]
fn a_sweep_whose_runs_all_ended_is_completed_with_per_cell_pass_rates_and_no_report_claimed() {
    let sweep = sweep();
    let runs = runs_of(&sweep);
    // Cell 0: both pass; cell 1: one passes, one fails its criteria; cell 2: one aborted
    // (no verdict), one fails.
    let existing = vec![
        in_phase(runs[0].clone(), Phase::Succeeded, Some(true)),
        in_phase(runs[1].clone(), Phase::Succeeded, Some(true)),
        in_phase(runs[2].clone(), Phase::Succeeded, Some(true)),
        in_phase(runs[3].clone(), Phase::Failed, Some(false)),
        in_phase(runs[4].clone(), Phase::Aborted, None),
        in_phase(runs[5].clone(), Phase::Failed, Some(false)),
    ];
    let d = decide_now(&sweep, &existing);
    assert!(d.create.is_empty());
    assert_eq!(counts(&d.status), (SweepPhase::Completed, 6, 0, 6, 3, 3));
    let rates: Vec<(&str, u32, u32, Option<f64>)> =
        d.status.cells.iter().map(|c| (c.label.as_str(), c.finished, c.passed, c.pass_rate)).collect();
    assert_eq!(rates, [("drones=1", 2, 2, Some(1.0)), ("drones=2", 2, 1, Some(0.5)), ("drones=3", 2, 0, Some(0.0))]);
    let complete = condition(&d.status, ct::COMPLETE).unwrap();
    assert_eq!((complete.status.as_str(), complete.reason.as_str()), ("True", "AllRunsFinished"));
    // The report hook is due; nothing claims a report yet.
    assert!(d.report_due);
    assert_eq!(d.status.report, None);
    assert!(condition(&d.status, ct::REPORTED).is_none());
}

#[test]
fn re_deciding_a_sweep_whose_runs_all_exist_creates_nothing() {
    let sweep = sweep();
    let existing: Vec<SimulationRun> = runs_of(&sweep).into_iter().map(|r| in_phase(r, Phase::Running, None)).collect();
    let mut again = sweep.clone();
    again.status = Some(decide_now(&sweep, &existing).status);
    let d = decide_now(&again, &existing);
    assert!(d.create.is_empty());
    assert_eq!(Some(&d.status), again.status.as_ref(), "the status is stable: no write");
    // Runs of other sweeps (or hand-made ones with the label) are neither counted nor in the way.
    let mut stranger = RunBuilder::test().build();
    stranger.metadata.name = Some("wind-extra".into());
    let d = decide_now(&again, &[existing.clone(), vec![stranger]].concat());
    assert!(d.create.is_empty());
    assert_eq!(d.status.created, Some(6));
}

#[test]
fn a_sweep_being_deleted_creates_no_more_runs() {
    let mut sweep = sweep();
    sweep.metadata.deletion_timestamp = Some(Time(t0()));
    let d = decide_now(&sweep, &[]);
    assert!(d.create.is_empty());
}

#[test]
fn the_sweeps_queue_reaches_every_runs_spec_queue() {
    let mut sweep = sweep();
    sweep.spec.queue = Some("sweeps".into());
    sweep.spec.parallelism = Some(10);
    let d = decide_now(&sweep, &[]);
    assert_eq!(d.create.len(), 6);
    assert!(d.create.iter().all(|r| r.spec.queue.as_deref() == Some("sweeps")));
}

#[test]
fn a_base_file_is_refused_on_kubernetes_naming_spec_base_file() {
    let mut sweep = sweep();
    sweep.spec.base = SweepBase { spec: None, file: Some("scenario.yaml".into()) };
    let d = decide_now(&sweep, &[]);
    assert!(d.create.is_empty());
    assert_eq!(d.status.phase, Some(SweepPhase::Failed));
    let valid = condition(&d.status, ct::VALID).unwrap();
    assert_eq!((valid.status.as_str(), valid.reason.as_str()), ("False", "InvalidSpec"));
    assert_eq!(
        valid.message,
        "spec.base.file: not supported on Kubernetes: give the base run inline as spec.base.spec"
    );
    assert!(d.status.message.unwrap().contains("spec.base.file"));
    assert!(!d.report_due);
}

#[test]
fn an_invalid_sweep_fails_with_every_problem_named_and_no_runs() {
    let mut sweep = sweep();
    sweep.spec.repetitions = Some(0);
    sweep.spec.parameters[0].field = "spec.nosuchfield".into();
    sweep.spec.parallelism = Some(0);
    let d = decide_now(&sweep, &[]);
    assert!(d.create.is_empty());
    assert_eq!(d.status.phase, Some(SweepPhase::Failed));
    assert_eq!(d.status.runs, None);
    let valid = condition(&d.status, ct::VALID).unwrap();
    assert_eq!(valid.status, "False");
    for field in ["spec.repetitions", "spec.parallelism"] {
        assert!(valid.message.contains(field), "{field} in {}", valid.message);
    }
}

// ---- the report --------------------------------------------------------------------

/// A fresh, empty temporary folder for one test.
fn tempdir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-sweep-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A finished run's `summary.json`, judged `passed`.
fn summary_of(run: &str, passed: bool) -> RunSummary {
    let criterion = CriterionResult {
        path: "spec.criteria[0]".into(),
        criterion: "noCrashes".into(),
        passed,
        summary: if passed { "no drone crashed".into() } else { "1 drone crashed".into() },
        failures: vec![],
    };
    RunSummary {
        run: run.into(),
        verdict: Some(RunVerdict { passed, criteria: vec![criterion] }),
        ..Default::default()
    }
}

/// Archives `run` under `archive` as the coordinator would (`<ns>/<run>/<uid>/` with a
/// manifest), with `summary` as its `summary.json` when given; returns the run, `Succeeded`
/// or `Failed` as `summary` says, its `status.archive.url` pointing at the folder.
fn archived(archive: &std::path::Path, run: SimulationRun, summary: Option<&RunSummary>) -> SimulationRun {
    let name = run.metadata.name.clone().unwrap();
    let dir = archive.join(NS).join(&name).join("uid-1");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("events.jsonl"), "{}\n").unwrap();
    if let Some(summary) = summary {
        std::fs::write(dir.join("summary.json"), serde_json::to_vec(summary).unwrap()).unwrap();
    }
    sadesim_evidence::archive::write_manifest(&dir, NS, &name, "uid-1").unwrap();
    let passed = summary.and_then(|s| s.verdict.as_ref()).is_some_and(|v| v.passed);
    let mut run = in_phase(run, if passed { Phase::Succeeded } else { Phase::Failed }, Some(passed));
    run.status.as_mut().unwrap().archive =
        Some(ArchiveStatus { url: format!("file://{}", dir.display()), files: None, bytes: None });
    run
}

#[test]
fn the_report_of_an_ended_sweep_is_archived_beside_its_runs_from_their_summaries() {
    let root = tempdir("report");
    let mut sweep = sweep();
    let base_url = format!("file://{}", root.display());
    sweep.spec.base.spec.as_mut().unwrap().archive = Some(Archive { url: base_url.clone() });
    let runs = runs_of(&sweep);
    // c0-r0 passed, c0-r1 failed, c1-r0 archived without a summary, the rest ended
    // without an archive (aborted before the upload).
    let existing = vec![
        archived(&root, runs[0].clone(), Some(&summary_of("wind-c0-r0", true))),
        archived(&root, runs[1].clone(), Some(&summary_of("wind-c0-r1", false))),
        archived(&root, runs[2].clone(), None),
        in_phase(runs[3].clone(), Phase::Aborted, None),
        in_phase(runs[4].clone(), Phase::Aborted, None),
        in_phase(runs[5].clone(), Phase::Aborted, None),
    ];
    let expansion = expansion_of(&sweep).unwrap();

    let url = report::write(&sweep, &expansion, &existing).unwrap().expect("the base run has an archive");
    assert_eq!(url, format!("{base_url}/{NS}/wind"));
    let folder = root.join(NS).join("wind");
    let written = sadesim_evidence::sweep::read(&folder).unwrap();
    assert_eq!((written.totals.expected, written.totals.rate.finished, written.totals.rate.passed), (6, 2, 1));
    let cells: Vec<(u32, u32)> = written.cells.iter().map(|c| (c.rate.finished, c.rate.passed)).collect();
    assert_eq!(cells, [(2, 1), (0, 0), (0, 0)]);
    let html = std::fs::read_to_string(folder.join(sadesim_evidence::sweep::SWEEP_HTML)).unwrap();
    assert!(html.contains("wind"), "the page names the sweep");

    // Each run's record says where it is and why it has no summary.
    let records = report::records(&expansion, &existing, report::read_summary);
    assert_eq!(records[0].folder, existing[0].status.as_ref().unwrap().archive.as_ref().unwrap().url);
    assert_eq!(records[0].summary, Some(summary_of("wind-c0-r0", true)));
    assert_eq!(records[0].error, None);
    let error = records[2].error.as_deref().unwrap();
    assert!(error.contains("lists no summary.json"), "{error}");
    assert_eq!((records[3].folder.as_str(), records[3].error.as_deref()), ("", Some("not archived")));
}

#[test]
fn a_sweep_whose_base_run_has_no_archive_writes_no_report() {
    let sweep = sweep();
    assert!(sweep.spec.base.spec.as_ref().unwrap().archive.is_none());
    let existing: Vec<SimulationRun> =
        runs_of(&sweep).into_iter().map(|r| in_phase(r, Phase::Succeeded, Some(true))).collect();
    assert_eq!(report::write(&sweep, &expansion_of(&sweep).unwrap(), &existing), Ok(None));
}

#[test]
fn a_report_that_cannot_be_written_is_an_error_naming_the_archive() {
    let root = tempdir("report-unwritable");
    // The archive "folder" is a file: nothing can be written under it.
    std::fs::write(root.join("not-a-folder"), "").unwrap();
    let mut sweep = sweep();
    let base_url = format!("file://{}/not-a-folder", root.display());
    sweep.spec.base.spec.as_mut().unwrap().archive = Some(Archive { url: base_url.clone() });
    let existing: Vec<SimulationRun> = runs_of(&sweep).into_iter().map(|r| in_phase(r, Phase::Aborted, None)).collect();
    let error = report::write(&sweep, &expansion_of(&sweep).unwrap(), &existing).unwrap_err();
    assert!(error.contains(&format!("{base_url}/{NS}/wind/sweep.json")), "{error}");
}

// ---- reconcile against a mock API server --------------------------------------------

/// What the fake API server holds.
#[derive(Clone, Default)]
struct Cluster {
    runs: Vec<SimulationRun>,
    /// Names of runs whose creation answers 409 AlreadyExists.
    exists: BTreeSet<String>,
}

fn answer(cluster: &Cluster, sweep: &SimulationSweep, seen: &Seen) -> (u16, Value) {
    let (method, path) = (&seen.method, seen.path.as_str());
    if method == Method::GET && path == RUNS {
        let items: Vec<Value> = cluster.runs.iter().map(|r| serde_json::to_value(r).unwrap()).collect();
        (200, json!({"apiVersion": "v1", "kind": "SimulationRunList", "metadata": {}, "items": items}))
    } else if method == Method::POST && path == RUNS {
        let name = seen.body["metadata"]["name"].as_str().unwrap();
        if cluster.exists.contains(name) {
            let status = json!({"kind": "Status", "apiVersion": "v1", "status": "Failure", "code": 409, "reason": "AlreadyExists", "message": "exists"});
            (409, status)
        } else {
            (201, seen.body.clone())
        }
    } else if method == Method::PATCH && path == SWEEP_STATUS {
        let mut sweep = serde_json::to_value(sweep).unwrap();
        sweep["status"] = seen.body["status"].clone();
        (200, sweep)
    } else {
        panic!("unexpected request {method} {path}")
    }
}

/// Reconciles `sweep` once against the fake server; returns the requests.
async fn reconcile_once(cluster: Cluster, sweep: SimulationSweep) -> Vec<Seen> {
    let (service, mut handle) = mock::pair::<Request<Body>, Response<Body>>();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let server = {
        let (seen, sweep) = (seen.clone(), sweep.clone());
        tokio::spawn(async move {
            while let Some((request, send)) = handle.next_request().await {
                let s = Seen::read(request).await;
                let (code, body) = answer(&cluster, &sweep, &s);
                seen.lock().unwrap().push(s);
                let body = Body::from(serde_json::to_vec(&body).unwrap());
                send.send_response(Response::builder().status(code).body(body).unwrap());
            }
        })
    };
    let mut ctx = Context::new(Client::new(service, NS), Arc::new(Metrics::default()));
    ctx.clock = Box::new(t0);
    let ctx = Arc::new(ctx);
    tokio::time::timeout(Duration::from_secs(10), reconcile(Arc::new(sweep), ctx.clone()))
        .await
        .expect("reconcile finished")
        .expect("reconcile succeeded");
    drop(ctx);
    // Every request was answered: the server ends when the client is gone.
    tokio::time::timeout(Duration::from_secs(1), server).await.expect("mock server ended").unwrap();
    seen.lock().unwrap().clone()
}

fn paths(seen: &[Seen]) -> Vec<String> {
    seen.iter().map(|s| format!("{} {}", s.method, s.path)).collect()
}

/// Asserts the list of the sweep's runs by its label.
fn assert_lists_runs(s: &Seen) {
    assert_eq!((s.method.clone(), s.path.as_str()), (Method::GET, RUNS));
    assert_eq!(s.query.get("labelSelector").map(String::as_str), Some("sadesim.io/sweep=wind"));
}

/// Asserts the status write (server-side apply on the status subresource, forced, our
/// field manager) and returns the status.
fn assert_status_write(s: &Seen) -> SimulationSweepStatus {
    assert_eq!((s.method.clone(), s.path.as_str()), (Method::PATCH, SWEEP_STATUS));
    assert_eq!(s.content_type, "application/apply-patch+yaml");
    assert_eq!(s.query.get("fieldManager").map(String::as_str), Some(MANAGER));
    assert_eq!(s.query.get("force").map(String::as_str), Some("true"));
    assert_eq!(
        (s.body["apiVersion"].as_str(), s.body["kind"].as_str()),
        (Some("sadesim.io/v1alpha1"), Some("SimulationSweep"))
    );
    assert!(s.body.get("spec").is_none(), "the status write never touches the spec");
    serde_json::from_value(s.body["status"].clone()).unwrap()
}

#[tokio::test]
async fn reconciling_a_new_sweep_lists_its_runs_creates_four_and_writes_its_status() {
    let seen = reconcile_once(Cluster::default(), sweep()).await;
    assert_eq!(seen.len(), 6, "{:?}", paths(&seen));
    assert_lists_runs(&seen[0]);
    let created: Vec<&str> = seen[1..5].iter().map(|s| s.body["metadata"]["name"].as_str().unwrap()).collect();
    assert_eq!(created, ["wind-c0-r0", "wind-c0-r1", "wind-c1-r0", "wind-c1-r1"]);
    for s in &seen[1..5] {
        assert_eq!((s.method.clone(), s.path.as_str()), (Method::POST, RUNS));
        assert_eq!(s.query.get("fieldManager").map(String::as_str), Some(MANAGER));
        assert_eq!(s.body["metadata"]["ownerReferences"][0]["kind"], "SimulationSweep");
        assert_eq!(s.body["metadata"]["ownerReferences"][0]["controller"], true);
        assert_eq!(s.body["metadata"]["labels"][SWEEP_LABEL], "wind");
    }
    let status = assert_status_write(&seen[5]);
    assert_eq!(counts(&status), (SweepPhase::Running, 4, 4, 0, 0, 0));
}

#[tokio::test]
async fn reconciling_again_when_the_runs_exist_creates_nothing_and_writes_nothing() {
    let sweep = sweep();
    let runs: Vec<SimulationRun> = runs_of(&sweep).into_iter().map(|r| in_phase(r, Phase::Running, None)).collect();
    let mut applied = sweep.clone();
    applied.status = Some(decide_now(&sweep, &runs).status);
    let seen = reconcile_once(Cluster { runs, ..Default::default() }, applied).await;
    assert_eq!(seen.len(), 1, "only the list: {:?}", paths(&seen));
    assert_lists_runs(&seen[0]);
}

#[tokio::test]
async fn a_run_that_already_exists_when_created_is_no_error() {
    // The watch has not shown the first run yet: its creation answers AlreadyExists.
    let cluster = Cluster { exists: BTreeSet::from(["wind-c0-r0".to_string()]), ..Default::default() };
    let seen = reconcile_once(cluster, sweep()).await;
    assert_eq!(seen.iter().filter(|s| s.method == Method::POST).count(), 4);
    assert_status_write(seen.last().unwrap());
}

#[tokio::test]
async fn as_mocked_runs_end_the_reconcile_creates_the_next_ones() {
    let sweep = sweep();
    let runs = runs_of(&sweep);
    let existing = vec![
        in_phase(runs[0].clone(), Phase::Succeeded, Some(true)),
        in_phase(runs[1].clone(), Phase::Running, None),
        in_phase(runs[2].clone(), Phase::Running, None),
        in_phase(runs[3].clone(), Phase::Running, None),
    ];
    let seen = reconcile_once(Cluster { runs: existing, ..Default::default() }, sweep).await;
    let created: Vec<&str> = seen
        .iter()
        .filter(|s| s.method == Method::POST)
        .map(|s| s.body["metadata"]["name"].as_str().unwrap())
        .collect();
    assert_eq!(created, ["wind-c2-r0"]);
    let status = assert_status_write(seen.last().unwrap());
    assert_eq!(counts(&status), (SweepPhase::Running, 5, 4, 1, 1, 0));
}

#[tokio::test]
async fn reconciling_an_invalid_sweep_lists_and_creates_nothing_and_fails_it() {
    let mut sweep = sweep();
    sweep.spec.base.file = Some("scenario.yaml".into());
    sweep.spec.base.spec = None;
    let seen = reconcile_once(Cluster::default(), sweep).await;
    assert_eq!(seen.len(), 1, "{:?}", paths(&seen));
    let status = assert_status_write(&seen[0]);
    assert_eq!(status.phase, Some(SweepPhase::Failed));
    assert!(condition(&status, ct::VALID).unwrap().message.starts_with("spec.base.file: not supported on Kubernetes"));
}

#[tokio::test]
async fn reconciling_an_ended_sweep_without_an_archive_says_so_in_the_reported_condition() {
    let sweep = sweep();
    let runs: Vec<SimulationRun> =
        runs_of(&sweep).into_iter().map(|r| in_phase(r, Phase::Succeeded, Some(true))).collect();
    let seen = reconcile_once(Cluster { runs, ..Default::default() }, sweep).await;
    assert_eq!(seen.len(), 2, "the list and the status: {:?}", paths(&seen));
    let status = assert_status_write(&seen[1]);
    assert_eq!(status.phase, Some(SweepPhase::Completed));
    assert_eq!(status.report, None);
    let reported = condition(&status, ct::REPORTED).unwrap();
    assert_eq!((reported.status.as_str(), reported.reason.as_str()), ("False", "NoArchive"));
    assert_eq!(reported.message, report::NO_ARCHIVE);
}

#[tokio::test]
async fn reconciling_an_ended_sweep_archives_its_report_and_records_it() {
    let root = tempdir("reconcile-report");
    let mut sweep = sweep();
    sweep.spec.base.spec.as_mut().unwrap().archive = Some(Archive { url: format!("file://{}", root.display()) });
    let runs: Vec<SimulationRun> = runs_of(&sweep)
        .into_iter()
        .map(|r| {
            let name = r.metadata.name.clone().unwrap();
            archived(&root, r, Some(&summary_of(&name, true)))
        })
        .collect();
    // Inside the reconcile's runtime: the archive's own runtime runs on a blocking thread.
    let seen = reconcile_once(Cluster { runs, ..Default::default() }, sweep).await;
    let status = assert_status_write(seen.last().unwrap());
    let url = format!("file://{}/{NS}/wind", root.display());
    assert_eq!(status.report.as_deref(), Some(url.as_str()));
    let reported = condition(&status, ct::REPORTED).unwrap();
    assert_eq!((reported.status.as_str(), reported.reason.as_str()), ("True", "Archived"));
    let written = sadesim_evidence::sweep::read(&root.join(NS).join("wind")).unwrap();
    assert_eq!((written.totals.rate.finished, written.totals.rate.passed), (6, 6));
}

#[test]
fn the_report_goes_to_the_runs_archive_when_the_base_names_none() {
    use sadesim_crds::status::{ArchiveStatus, SimulationRunStatus};
    let sweep = sweep();
    assert!(sweep.spec.base.spec.as_ref().unwrap().archive.is_none());
    let mut runs = runs_of(&sweep);
    assert_eq!(report::archive_root(&sweep, &runs), None, "nothing archived yet");
    runs[1].status = Some(SimulationRunStatus {
        archive: Some(ArchiveStatus {
            url: "s3://bucket/prefix/team-a/lake-c0-r1/3f2a/".into(),
            files: None,
            bytes: None,
        }),
        ..Default::default()
    });
    assert_eq!(report::archive_root(&sweep, &runs).as_deref(), Some("s3://bucket/prefix"));
}
