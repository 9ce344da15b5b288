//! The phase machine, transition by transition.

use k8s_openapi::apimachinery::pkg::apis::meta::v1::Time;
use k8s_openapi::jiff::{SignedDuration, Timestamp};
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::status::{Phase, SimulationRunStatus, Verdict, condition_types as ct};

use super::*;
use crate::k8s::children::{ClusterSettings, KUEUE_QUEUE_LABEL};
use crate::k8s::controller::observe::{Observed, WorkState, Workload};
use crate::k8s::controller::progress::{CoordinatorReport, Finished};
use crate::k8s::controller::queue::Admission;

pub(super) const ARCHIVE: &str = "s3://sadesim-runs/team";

pub(super) fn t0() -> Timestamp {
    Timestamp::from_second(1_800_000_000).unwrap()
}

pub(super) fn later(s: i64) -> Timestamp {
    t0() + SignedDuration::from_secs(s)
}

pub(super) fn settings() -> ClusterSettings {
    ClusterSettings { default_archive_url: Some(ARCHIVE.into()), ..Default::default() }
}

/// A valid run as the API server returns it (uid, generation, creation time).
pub(super) fn new_run() -> SimulationRun {
    RunBuilder::test()
        .with(|r| {
            r.metadata.uid = Some("uid-1".into());
            r.metadata.generation = Some(1);
            r.metadata.creation_timestamp = Some(Time(t0()));
        })
        .build()
}

pub(super) fn pilot_run() -> SimulationRun {
    let mut run = RunBuilder::test().with_pilot(&["python3", "pilot.py"]).build();
    run.spec.pilot.as_mut().unwrap().image = Some("example.com/pilot:1".into());
    run.metadata = new_run().metadata;
    run
}

pub(super) fn with_phase(mut run: SimulationRun, phase: Phase, finalized: bool) -> SimulationRun {
    run.status = Some(SimulationRunStatus { phase: Some(phase), ..Default::default() });
    if finalized {
        run.metadata.finalizers = Some(vec![FINALIZER.into()]);
    }
    run
}

pub(super) fn decide_with(
    run: &SimulationRun,
    observed: &Observed,
    admission: Option<Admission>,
    now: Timestamp,
) -> Decision {
    decide_full(run, &settings(), observed, admission, now, None)
}

pub(super) fn decide_full(
    run: &SimulationRun,
    settings: &ClusterSettings,
    observed: &Observed,
    admission: Option<Admission>,
    now: Timestamp,
    last_sample: Option<Sample>,
) -> Decision {
    // As the operator plans (a mapped world's files refused when local; fetched ones are
    // the reconcile tests' business).
    let plan = match super::super::planning::local_file(&run.spec) {
        Some(failure) => Err(failure),
        None => sadesim_planner::plan(run).map_err(super::super::planning::PlanFailure::from),
    };
    decide(&Input { run, plan: plan.as_ref(), settings, observed, admission, now, last_sample })
}

/// The role labelled `label` (the tests name roles as the cluster's labels do).
pub(super) fn role(label: &str) -> Role {
    Role::from_label(label).unwrap_or_else(|| panic!("{label:?} is not a role"))
}

pub(super) fn job(label: &str, state: WorkState) -> Workload {
    Workload {
        kind: Kind::Job,
        name: format!("test-run-{label}"),
        role: Some(role(label)),
        state,
        job_owned: false,
        ready: false,
        index: None,
        message: None,
    }
}

pub(super) fn pod(name: &str, label: &str, state: WorkState, job_owned: bool) -> Workload {
    Workload {
        kind: Kind::Pod,
        name: name.into(),
        role: Some(role(label)),
        state,
        job_owned,
        ready: true,
        index: None,
        message: None,
    }
}

/// The workers of a started run: shard Job with one pod, coordinator, one router.
pub(super) fn workers(coordinator: WorkState) -> Observed {
    let mut shard = pod("test-run-shard-0", "shard", WorkState::Running, true);
    shard.index = Some(0);
    Observed {
        jobs: vec![job("assets", WorkState::Succeeded), job("shard", WorkState::Running)],
        pods: vec![
            shard,
            pod("test-run-coordinator", "coordinator", coordinator, false),
            pod("test-run-router-0", "router", WorkState::Running, false),
        ],
        ..Default::default()
    }
}

pub(super) fn cond<'a>(d: &'a Decision, type_: &str) -> &'a k8s_openapi::apimachinery::pkg::apis::meta::v1::Condition {
    condition(&d.status, type_).unwrap_or_else(|| panic!("no {type_} condition in {:?}", d.status.conditions))
}

pub(super) fn roles(children: &[Child]) -> Vec<String> {
    children.iter().map(|c| format!("{} {}", c.kind(), c.role().map_or("unlabelled", Role::label))).collect()
}

pub(super) fn reasons(d: &Decision) -> Vec<&str> {
    d.events.iter().map(|e| e.reason.as_str()).collect()
}

#[test]
fn a_new_valid_run_is_queued_with_a_finalizer_and_no_children_until_admitted() {
    let run = new_run();
    let waiting = Admission::Waiting { reason: "QuotaExceeded", message: "ResourceQuota team: no room".into() };
    let d = decide_with(&run, &Observed::default(), Some(waiting), t0());
    assert_eq!(d.status.phase, Some(Phase::Queued));
    assert!(d.add_finalizer);
    assert!(d.apply.is_empty() && d.delete.is_empty() && d.archive_logs.is_empty());
    assert_eq!(cond(&d, ct::VALID).status, "True");
    assert_eq!(cond(&d, ct::SCHEDULED).status, "False");
    assert_eq!(cond(&d, ct::SCHEDULED).reason, "QuotaExceeded");
    assert_eq!(d.status.observed_generation, Some(1));
    assert_eq!(d.status.drones, Some(1));
    assert_eq!(reasons(&d), ["Queued"]);
    assert!(d.requeue.is_some());
}

#[test]
fn an_admitted_run_creates_its_config_and_assets_job_first() {
    let run = new_run();
    let d = decide_with(&run, &Observed::default(), Some(Admission::Admitted), t0());
    assert_eq!(d.status.phase, Some(Phase::GeneratingAssets));
    assert!(d.admitted);
    assert_eq!(cond(&d, ct::SCHEDULED).reason, "Admitted");
    assert_eq!(cond(&d, ct::ASSETS_READY).status, "False");
    assert_eq!(roles(&d.apply), ["ConfigMap config", "ConfigMap config", "Job assets"]);
    assert_eq!(reasons(&d), ["Queued", "GeneratingAssets"]);
}

#[test]
fn an_invalid_run_fails_with_valid_false_and_no_children() {
    let mut run = new_run();
    run.spec.fleet[0].count = 0;
    let d = decide_with(&run, &Observed::default(), None, t0());
    assert_eq!(d.status.phase, Some(Phase::Failed));
    assert_eq!(cond(&d, ct::VALID).status, "False");
    assert_eq!(cond(&d, ct::VALID).reason, "InvalidSpec");
    assert!(cond(&d, ct::VALID).message.contains("fleet[0].count"), "{}", cond(&d, ct::VALID).message);
    assert!(d.apply.is_empty() && !d.add_finalizer);
    assert!(d.events.iter().any(|e| e.warning && e.reason == "InvalidSpec"));
    assert!(d.status.completion_time.is_some());
}

#[test]
fn a_pilot_without_an_image_cannot_run_on_a_cluster() {
    let mut run = pilot_run();
    run.spec.pilot.as_mut().unwrap().image = None;
    let d = decide_with(&run, &Observed::default(), Some(Admission::Admitted), t0());
    assert_eq!(d.status.phase, Some(Phase::Failed));
    assert!(cond(&d, ct::VALID).message.contains("spec.pilot.image"));
    assert!(d.apply.is_empty());
}

#[test]
fn a_mapped_world_on_a_local_path_is_refused_on_a_cluster() {
    let mut run = new_run();
    run.spec.world = Some(sadesim_crds::run::World {
        source: sadesim_crds::run::WorldSource::Osm,
        osm: Some(sadesim_crds::run::OsmExtract { file: "/data/helsinki.osm.pbf".into(), default_height_m: None }),
        ..Default::default()
    });
    let d = decide_with(&run, &Observed::default(), Some(Admission::Admitted), t0());
    assert_eq!(d.status.phase, Some(Phase::Failed));
    let message = &cond(&d, ct::VALID).message;
    assert!(message.starts_with("spec.world.osm.file: \"/data/helsinki.osm.pbf\" is a path"), "{message}");
    assert!(message.contains("object storage"), "{message}");
    assert!(d.apply.is_empty());
}

#[test]
fn assets_built_start_every_worker_and_the_pilot_held_by_its_init_container() {
    let run = with_phase(pilot_run(), Phase::GeneratingAssets, true);
    let observed = Observed { jobs: vec![job("assets", WorkState::Succeeded)], ..Default::default() };
    let d = decide_with(&run, &observed, None, t0());
    assert_eq!(d.status.phase, Some(Phase::Starting));
    assert_eq!(cond(&d, ct::ASSETS_READY).status, "True");
    let applied = roles(&d.apply);
    assert!(applied.contains(&"Pod coordinator".to_string()), "{applied:?}");
    assert!(applied.contains(&"Job shard".to_string()), "{applied:?}");
    // The pilot is never started late: its Job comes now, with the shards, and waits in
    // its init container for the release instead of being created after it.
    assert!(applied.contains(&"Job pilot".to_string()), "{applied:?}");
    assert!(!applied.iter().any(|r| r.ends_with("assets")), "{applied:?}");
    assert_eq!(cond(&d, ct::RUNNING).reason, "Starting");
}

/// The assets role says in its termination message whether the bundle was in the cache:
/// the condition's reason is `CacheHit` or `Built`, with the role's words as its message.
#[test]
fn the_assets_ready_condition_says_cache_hit_or_built() {
    let run = with_phase(pilot_run(), Phase::GeneratingAssets, true);
    let url = "s3://sadesim-runs/team-a/assets/k/world/";
    let outcome_of = |message: &str| {
        let mut assets = pod("test-run-assets-x7k2p", "assets", WorkState::Succeeded, true);
        assets.message = Some(message.into());
        let observed =
            Observed { jobs: vec![job("assets", WorkState::Succeeded)], pods: vec![assets], ..Default::default() };
        let d = decide_with(&run, &observed, None, t0());
        assert_eq!(d.status.phase, Some(Phase::Starting));
        let c = cond(&d, ct::ASSETS_READY);
        (c.status.clone(), c.reason.clone(), c.message.clone())
    };
    let hit = outcome_of(&format!(r#"{{"outcome":"cacheHit","url":"{url}"}}"#));
    assert_eq!(hit, ("True".into(), "CacheHit".into(), format!("asset cache hit: {url}")));
    let built = outcome_of(&format!(r#"{{"outcome":"built","url":"{url}","buildings":225}}"#));
    assert_eq!(built, ("True".into(), "Built".into(), format!("assets built: 225 buildings -> {url}")));
    // An older worker image that wrote no outcome: built, in general words.
    let unknown = outcome_of("some log line");
    assert_eq!((unknown.1.as_str(), unknown.2.as_str()), ("Built", "the assets Job finished"));
}

#[test]
fn assets_still_building_keep_the_phase() {
    let run = with_phase(new_run(), Phase::GeneratingAssets, true);
    let observed = Observed { jobs: vec![job("assets", WorkState::Running)], ..Default::default() };
    let d = decide_with(&run, &observed, None, t0());
    assert_eq!(d.status.phase, Some(Phase::GeneratingAssets));
    assert!(d.events.is_empty());
}

#[test]
fn released_pilots_start_running_and_create_the_pilot_job() {
    let run = with_phase(pilot_run(), Phase::Starting, true);
    let mut observed = workers(WorkState::Running);
    observed.coordinator =
        Some(CoordinatorReport { sim_time_s: Some(0.01), pilots_released: true, ..Default::default() });
    let d = decide_with(&run, &observed, None, t0());
    assert_eq!(d.status.phase, Some(Phase::Running));
    assert_eq!(cond(&d, ct::RUNNING).status, "True");
    assert_eq!(d.status.start_time, Some(Time(t0())));
    assert!(roles(&d.apply).contains(&"Job pilot".to_string()));
    assert_eq!(d.status.shards.len(), 1);
    assert!(d.status.shards[0].ready);
    assert!(d.status.endpoints.as_ref().unwrap().airspace.as_ref().unwrap().contains("test-run-airspace.default.svc"));
    assert_eq!(d.status.endpoints.as_ref().unwrap().cameras, None, "no cameras, no camera endpoint");
}

#[test]
fn a_run_with_onboard_cameras_lists_their_frames_among_its_endpoints() {
    let run = RunBuilder::test().with_camera(sadesim_crds::fixtures::down_camera()).build();
    let plan = sadesim_planner::plan(&run).unwrap();
    let e = endpoints(&plan);
    assert_eq!(e.cameras.as_deref(), Some("http://test-run-airspace.default.svc:8490/cameras"));
    assert_eq!(e.renderer.as_deref(), Some("http://test-run-renderer.default.svc:8490"));
}

/// The coordinator Pod among the applied children, with its annotations.
pub(super) fn coordinator_stop(d: &Decision) -> Option<String> {
    d.apply.iter().find_map(|c| match c {
        Child::Pod(p) if c.role() == Some(Role::Coordinator) => {
            Some(p.metadata.annotations.as_ref()?.get(crate::k8s::children::STOP_ANNOTATION)?.clone())
        }
        _ => None,
    })
}

/// A Running pilot run whose pilot Job is in `state`, its pod `pod_state`.
pub(super) fn pilot_observed(state: WorkState, pod_state: WorkState) -> Observed {
    let mut observed = workers(WorkState::Running);
    observed.jobs.push(job("pilot", state));
    observed.pods.push(pod("test-run-pilot-abcde", "pilot", pod_state, true));
    observed.coordinator =
        Some(CoordinatorReport { sim_time_s: Some(300.0), pilots_released: true, ..Default::default() });
    observed
}

#[test]
fn a_pilot_job_that_completes_asks_the_coordinator_to_end_the_run() {
    let mut run = with_phase(pilot_run(), Phase::Running, true);
    run.status.as_mut().unwrap().start_time = Some(Time(t0()));
    // While the pilot runs, the coordinator Pod carries no stop.
    let flying = decide_with(&run, &pilot_observed(WorkState::Running, WorkState::Running), None, later(100));
    assert_eq!(coordinator_stop(&flying), None);

    let observed = pilot_observed(WorkState::Succeeded, WorkState::Succeeded);
    let d = decide_with(&run, &observed, None, later(300));
    assert_eq!(d.status.phase, Some(Phase::Running), "the coordinator's summary ends the run, not the Job");
    assert_eq!(coordinator_stop(&d).as_deref(), Some("pilotExited"));
    let running = cond(&d, ct::RUNNING);
    assert_eq!((running.status.as_str(), running.reason.as_str()), ("True", PILOT_EXITED));
    assert!(running.message.contains("Job test-run-pilot complete"), "{}", running.message);
    assert!(running.message.contains("onExit: endRun"), "{}", running.message);
    assert_eq!(reasons(&d), ["PilotExited"]);
    assert!(!d.events[0].warning);
    assert!(d.delete.is_empty(), "the pilot's log is archived in Archiving, as for every end");

    // The next reconcile applies the same Pod and records no second Event.
    run.status = Some(d.status.clone());
    let again = decide_with(&run, &observed, None, later(302));
    assert_eq!(coordinator_stop(&again).as_deref(), Some("pilotExited"));
    assert!(again.events.is_empty(), "{:?}", again.events);

    // The coordinator ended the run: the usual end, through Archiving.
    let mut observed = observed;
    let mut done = finished(true);
    done.finished.as_mut().unwrap().end_reason = EndReason::PilotExited;
    observed.coordinator = Some(done);
    let last = archive_to_the_end(run, observed, later(304)).pop().unwrap();
    assert_eq!(last.status.phase, Some(Phase::Succeeded));
}

#[test]
fn a_failed_pilot_job_ends_the_run_as_a_finding_not_a_role_failure() {
    let run = with_phase(pilot_run(), Phase::Running, true);
    let failed = WorkState::Failed("BackoffLimitExceeded: Job has reached the specified backoff limit".into());
    let observed = pilot_observed(failed, WorkState::Failed("container pilot Error (exit code 3)".into()));
    let d = decide_with(&run, &observed, None, later(300));
    assert_eq!(d.status.phase, Some(Phase::Running));
    assert_eq!(coordinator_stop(&d).as_deref(), Some("pilotExited"));
    // Its exit code 3 is not the expected success: the run will fail (lifecycle/pilot_tests.rs).
    assert_eq!(reasons(&d), ["PilotExited", "PilotFailed"]);
    assert!(d.events[0].warning, "a failed pilot is worth a Warning");
    assert!(d.events[0].message.contains("Job test-run-pilot failed: BackoffLimitExceeded"), "{:?}", d.events);
}

#[test]
fn with_on_exit_continue_the_run_goes_on_after_the_pilot_job() {
    let mut run = with_phase(pilot_run(), Phase::Running, true);
    run.spec.pilot.as_mut().unwrap().on_exit = Some(sadesim_crds::run::PilotExit::Continue);
    let d = decide_with(&run, &pilot_observed(WorkState::Succeeded, WorkState::Succeeded), None, later(300));
    assert_eq!(d.status.phase, Some(Phase::Running));
    assert_eq!(coordinator_stop(&d), None);
    assert_eq!(cond(&d, ct::RUNNING).reason, PILOT_EXITED);
    assert!(cond(&d, ct::RUNNING).message.contains("goes on until spec.duration"));
    assert_eq!(reasons(&d), ["PilotExited"]);
}

#[test]
fn a_pilot_image_that_cannot_be_pulled_fails_the_run() {
    let run = with_phase(pilot_run(), Phase::Running, true);
    let observed = pilot_observed(WorkState::Running, WorkState::Failed("ImagePullBackOff: no such image".into()));
    let d = decide_with(&run, &observed, None, later(30));
    assert_eq!(d.status.phase, Some(Phase::Archiving));
    assert_eq!(cond(&d, ct::RUNNING).reason, RunEnd::RoleFailed.reason());
    assert!(cond(&d, ct::RUNNING).message.contains("role pilot failed: Pod test-run-pilot-abcde: ImagePullBackOff"));
}

#[test]
fn running_reports_sim_time_and_real_time_factor() {
    let mut run = with_phase(new_run(), Phase::Running, true);
    run.status.as_mut().unwrap().start_time = Some(Time(t0()));
    let mut observed = workers(WorkState::Running);
    observed.coordinator =
        Some(CoordinatorReport { sim_time_s: Some(30.0), pilots_released: true, ..Default::default() });
    let last = Sample { sim_time_s: 10.0, at: later(10) };
    let d = decide_full(&run, &settings(), &observed, None, later(20), Some(last));
    assert_eq!(d.status.phase, Some(Phase::Running));
    assert_eq!(d.status.sim_time_s, Some(30.0));
    assert_eq!(d.status.real_time_factor, Some(2.0)); // 20 sim s in 10 wall s
    assert_eq!(d.sample, Some(Sample { sim_time_s: 30.0, at: later(20) }));
    assert!(d.events.is_empty());
}

pub(super) fn finished(passed: bool) -> CoordinatorReport {
    CoordinatorReport {
        sim_time_s: Some(120.0),
        pilots_released: true,
        finished: Some(Finished {
            sim_time_s: 120.0,
            real_time_factor: 3.5,
            end_reason: EndReason::Duration,
            verdict: Some(Verdict {
                passed,
                failures: if passed { vec![] } else { vec!["spec.criteria[0] noCrashes: 1 crash".into()] },
                unauthorized_entries: None,
                crashes: Some(u32::from(!passed)),
            }),
        }),
        failed: None,
    }
}

/// Drives a run through Archiving as the cluster would: pilot, shards, coordinator, rest.
pub(super) fn archive_to_the_end(mut run: SimulationRun, mut observed: Observed, start: Timestamp) -> Vec<Decision> {
    let mut steps = Vec::new();
    for i in 0..6 {
        let d = decide_with(&run, &observed, None, start + SignedDuration::from_secs(i));
        run.status = Some(d.status.clone());
        // What the deletes do.
        for del in &d.delete {
            match del.role {
                Some(role) => {
                    observed.jobs.retain(|j| j.role != Some(role));
                    observed.pods.retain(|p| p.role != Some(role));
                }
                None => {
                    observed.jobs.clear();
                    observed.pods.clear();
                }
            }
        }
        // A running coordinator asked to stop ends the run with that reason.
        if let Some(reason) = coordinator_stop(&d)
            && let Some(report) = observed.coordinator.as_mut()
            && report.finished.is_none()
        {
            let sim_time_s = report.sim_time_s.unwrap_or_default();
            report.finished = Some(Finished {
                sim_time_s,
                real_time_factor: 1.0,
                end_reason: EndReason::from(reason.as_str()),
                verdict: None,
            });
        }
        // The coordinator finishes its upload and exits once the shards are gone.
        if !observed.has_job(Role::Shard) {
            for p in observed.pods.iter_mut().filter(|p| p.role == Some(Role::Coordinator)) {
                p.state = WorkState::Succeeded;
            }
        }
        let done = d.status.phase.is_some_and(Phase::is_terminal);
        steps.push(d);
        if done {
            break;
        }
    }
    steps
}

#[test]
fn a_terminal_phase_is_never_left() {
    for phase in [Phase::Succeeded, Phase::Failed, Phase::Aborted] {
        let mut run = with_phase(new_run(), phase, true);
        run.spec.abort = true;
        let d = decide_with(&run, &workers(WorkState::Running), Some(Admission::Admitted), t0());
        assert_eq!(d.status.phase, Some(phase));
        assert!(d.apply.is_empty() && d.delete.is_empty() && d.events.is_empty());
    }
}

pub(super) fn kueue_run() -> (SimulationRun, ClusterSettings) {
    let mut run = pilot_run();
    run.spec.queue = Some("team-a".into());
    (run, ClusterSettings { kueue: true, ..settings() })
}

/// The run's Workload as Kueue would show it: `conditions` as `(type, status, reason,
/// message)`, admitted to `team-cq` with the flavor `default-flavor` when `Admitted`.
pub(super) fn kueue_observed(conditions: &[(&str, &str, &str, &str)], pending: Option<(i32, i32)>) -> Observed {
    use crate::k8s::children::kueue::{WorkloadAdmission, WorkloadSpec, WorkloadStatus};
    use crate::k8s::children::{PendingWorkload, PodSetAssignment, Workload as KueueWorkload};
    use k8s_openapi::apimachinery::pkg::apis::meta::v1::{Condition, ObjectMeta};
    let admitted = conditions.iter().any(|c| c.0 == "QuotaReserved" && c.1 == "True");
    let status = WorkloadStatus {
        conditions: conditions
            .iter()
            .map(|(t, st, r, m)| Condition {
                type_: t.to_string(),
                status: st.to_string(),
                reason: r.to_string(),
                message: m.to_string(),
                last_transition_time: Time(t0()),
                observed_generation: None,
            })
            .collect(),
        admission: admitted.then(|| WorkloadAdmission {
            cluster_queue: "team-cq".into(),
            pod_set_assignments: vec![PodSetAssignment {
                name: "shard".into(),
                flavors: [("cpu".into(), "default-flavor".into())].into(),
            }],
        }),
    };
    let workload = KueueWorkload {
        metadata: ObjectMeta { name: Some("test-run".into()), ..Default::default() },
        spec: WorkloadSpec { queue_name: "team-a".into(), pod_sets: Vec::new(), priority: 0 },
        status: Some(status),
    };
    let pending = pending.map(|(local, cluster)| PendingWorkload {
        position_in_local_queue: local,
        position_in_cluster_queue: cluster,
        ..Default::default()
    });
    Observed {
        queue: Some(crate::k8s::controller::observe::QueueObservation {
            workload,
            pending,
            flavors: Default::default(),
        }),
        ..Default::default()
    }
}

/// With Kueue the run is only its Workload until Kueue admits it as a whole: no ConfigMap,
/// no Job, no Pod. The status says where it waits.
#[test]
fn with_kueue_only_the_workload_exists_until_the_whole_run_is_admitted() {
    let (run, settings) = kueue_run();
    let d = decide_full(&run, &settings, &Observed::default(), None, t0(), None);
    assert_eq!(d.status.phase, Some(Phase::Queued));
    assert_eq!(roles(&d.apply), ["Workload queue"]);
    let Child::Workload(w) = &d.apply[0] else { unreachable!() };
    let sets: Vec<_> = w.spec.pod_sets.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(sets, ["assets", "coordinator", "router", "shard", "pilot"], "the pilot is in the gang");
    assert_eq!(cond(&d, ct::SCHEDULED).reason, "KueuePending");
    assert!(cond(&d, ct::SCHEDULED).message.contains("creating its Workload"));

    // Pending in the queue: the position and Kueue's reason are in the status.
    let run = with_phase(run, Phase::Queued, true);
    let waiting = kueue_observed(
        &[(
            "QuotaReserved",
            "False",
            "Pending",
            "couldn't assign flavors to pod set shard: insufficient quota for cpu",
        )],
        Some((1, 3)),
    );
    let d = decide_full(&run, &settings, &waiting, None, t0(), None);
    assert_eq!(d.status.phase, Some(Phase::Queued));
    assert_eq!(roles(&d.apply), ["Workload queue"]);
    let k = d.status.kueue.as_ref().unwrap();
    assert_eq!(
        (k.state.as_str(), k.position_in_local_queue, k.position_in_cluster_queue),
        ("Pending", Some(1), Some(3))
    );
    let message = &cond(&d, ct::SCHEDULED).message;
    assert!(message.contains("position 1 in the LocalQueue, 3 in the ClusterQueue"), "{message}");
    assert!(message.contains("insufficient quota for cpu"), "{message}");
    assert!(!d.admitted);

    // Quota reserved but admission checks pending: still waiting.
    let reserved = kueue_observed(&[("QuotaReserved", "True", "QuotaReserved", "")], None);
    let d = decide_full(&run, &settings, &reserved, None, t0(), None);
    assert_eq!(d.status.phase, Some(Phase::Queued));
    assert_eq!(d.status.kueue.as_ref().unwrap().state, "QuotaReserved");

    // Admitted: every role starts from here (config and assets first, then the workers
    // with the pilot, none of them queued by itself).
    let admitted =
        kueue_observed(&[("QuotaReserved", "True", "QuotaReserved", ""), ("Admitted", "True", "Admitted", "")], None);
    let d = decide_full(&run, &settings, &admitted, None, t0(), None);
    assert_eq!(d.status.phase, Some(Phase::GeneratingAssets));
    assert_eq!(cond(&d, ct::SCHEDULED).reason, "AdmittedByKueue");
    assert!(d.admitted);
    let k = d.status.kueue.as_ref().unwrap();
    assert_eq!((k.state.as_str(), k.cluster_queue.as_deref()), ("Admitted", Some("team-cq")));
    let applied = roles(&d.apply);
    assert!(
        applied.contains(&"Job assets".to_string()) && !applied.contains(&"Workload queue".to_string()),
        "{applied:?}"
    );
    for c in &d.apply {
        assert!(c.labels().unwrap().get(KUEUE_QUEUE_LABEL).is_none(), "{}", c.name());
    }
    let started = with_phase(run.clone(), Phase::Starting, true);
    let d = decide_full(&started, &settings, &admitted, None, t0(), None);
    let applied = roles(&d.apply);
    assert!(applied.contains(&"Job shard".to_string()) && applied.contains(&"Job pilot".to_string()), "{applied:?}");
    assert!(!applied.contains(&"Workload queue".to_string()), "{applied:?}");
}

/// Kueue evicting the Workload (a higher-priority run preempts it) ends the run: it is
/// stopped and archived, fails with the reason, and its Workload is deleted last.
#[test]
fn an_evicted_run_is_stopped_archived_and_gives_its_workload_back() {
    let (run, settings) = kueue_run();
    let run = with_phase(run, Phase::Running, true);
    let mut observed = kueue_observed(
        &[
            ("QuotaReserved", "False", "Preempted", ""),
            ("Admitted", "False", "Preempted", ""),
            (
                "Evicted",
                "True",
                "Preempted",
                "Preempted to accommodate a workload (UID: 42) due to prioritization in the ClusterQueue",
            ),
        ],
        None,
    );
    let queue = observed.queue.take();
    observed = Observed { queue, ..workers(WorkState::Running) };
    let d = decide_full(&run, &settings, &observed, None, t0(), None);
    assert_eq!(d.status.phase, Some(Phase::Archiving));
    let running = cond(&d, ct::RUNNING);
    assert_eq!(running.reason, "Evicted");
    assert!(running.message.contains("Preempted to accommodate"), "{}", running.message);
    assert_eq!(d.status.kueue.as_ref().unwrap().state, "Evicted");
    // Archiving to the end: nothing of the run left but the Workload, deleted last.
    let archiving = Decision { status: d.status.clone(), ..d };
    let mut run = run;
    run.status = Some(archiving.status);
    observed.jobs.clear();
    observed.pods.clear();
    let end = decide_full(&run, &settings, &observed, None, later(200), None);
    assert_eq!(end.status.phase, Some(Phase::Failed));
    assert_eq!(end.delete.last().map(|d| d.kind), Some(Kind::Workload));
}

#[test]
fn set_condition_keeps_the_transition_time_while_the_status_holds() {
    let mut conds = Vec::new();
    set_condition(&mut conds, "Running", false, "Starting", "a", t0(), Some(1));
    set_condition(&mut conds, "Running", false, "Starting", "b", later(5), Some(1));
    assert_eq!(conds[0].last_transition_time, Time(t0()));
    assert_eq!(conds[0].message, "b");
    set_condition(&mut conds, "Running", true, "PilotsReleased", "c", later(9), Some(1));
    assert_eq!(conds[0].last_transition_time, Time(later(9)));
}
