//! Reconcile tests against kube's `tower_test` mock API server (controller-rs style): a
//! fake API server answers every request from the test's objects and records it; each
//! test then asserts the requests made — method, path, query (fieldManager, force,
//! labelSelector, tailLines), content type and body — in order.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use http::{Method, Request, Response};
use k8s_openapi::api::batch::v1::{Job, JobCondition, JobStatus};
use k8s_openapi::api::core::v1::{
    ContainerState, ContainerStateTerminated, ContainerStatus, Pod, PodStatus, ResourceQuota, ResourceQuotaStatus,
};
use k8s_openapi::apimachinery::pkg::api::resource::Quantity;
use k8s_openapi::apimachinery::pkg::apis::meta::v1::{Condition, OwnerReference, Time};
use k8s_openapi::jiff::{SignedDuration, Timestamp};
use kube::Client;
use kube::client::Body;
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::status::{Phase, SimulationRunStatus, condition_types as ct};
use sadesim_sources::world::WorldReadError;
use sadesim_world::WorldData;
use serde_json::{Value, json};
use tower_test::mock;

use super::lifecycle::FINALIZER;
use super::metrics::Metrics;
use super::planning::{WorldFiles, fixture};
use super::reconcile::{Context, MANAGER, reconcile};
use crate::k8s::children::{ClusterSettings, KUEUE_QUEUE_LABEL, ROLE_LABEL, RUN_LABEL};
use crate::k8s::fake_api::Seen;

mod archiving;
mod kueue;

const NS: &str = "team-a";
const RUNS: &str = "/apis/sadesim.io/v1alpha1/namespaces/team-a/simulationruns";

/// What the fake API server holds.
#[derive(Clone, Default)]
struct Cluster {
    run: Option<SimulationRun>,
    jobs: Vec<Job>,
    pods: Vec<Pod>,
    /// Log text per pod name.
    logs: BTreeMap<String, String>,
    runs: Vec<SimulationRun>,
    quotas: Vec<ResourceQuota>,
    /// Where the operator reads mapped worlds' files (default: object storage).
    world_files: Option<Arc<dyn WorldFiles>>,
    /// The run's Kueue Workload as Kueue has it (404 when `None`).
    workload: Option<Value>,
    /// Kueue's visibility API answer for the LocalQueue (404 when `None`: not installed).
    pending: Option<Value>,
    /// ResourceFlavors by name.
    flavors: BTreeMap<String, Value>,
}

fn list(kind: &str, items: Vec<Value>) -> Value {
    json!({"apiVersion": "v1", "kind": kind, "metadata": {"resourceVersion": "1"}, "items": items})
}

fn to_values<T: serde::Serialize>(items: &[T]) -> Vec<Value> {
    items.iter().map(|i| serde_json::to_value(i).unwrap()).collect()
}

fn not_found() -> (u16, Vec<u8>) {
    let status = json!({"kind": "Status", "apiVersion": "v1", "status": "Failure", "code": 404, "reason": "NotFound", "message": "not found"});
    (404, serde_json::to_vec(&status).unwrap())
}

/// The fake API server's answer to `seen`.
fn answer(cluster: &Cluster, seen: &Seen) -> (u16, Vec<u8>) {
    let json = |v: Value| (200, serde_json::to_vec(&v).unwrap());
    let p = seen.path.as_str();
    match seen.method {
        Method::GET if p.ends_with("/log") => {
            let pod = p.trim_end_matches("/log").rsplit('/').next().unwrap();
            match cluster.logs.get(pod) {
                Some(text) => (200, text.clone().into_bytes()),
                None => (
                    404,
                    serde_json::to_vec(&json!({"kind": "Status", "apiVersion": "v1", "status": "Failure", "code": 404, "reason": "NotFound", "message": "no log"}))
                        .unwrap(),
                ),
            }
        }
        Method::GET if p.contains("/workloads/") => match &cluster.workload {
            Some(w) => json(w.clone()),
            None => not_found(),
        },
        Method::GET if p.ends_with("/pendingworkloads") => match &cluster.pending {
            Some(summary) => json(summary.clone()),
            None => not_found(),
        },
        Method::GET if p.contains("/resourceflavors/") => match cluster.flavors.get(p.rsplit('/').next().unwrap()) {
            Some(f) => json(f.clone()),
            None => not_found(),
        },
        Method::GET if p.ends_with("/jobs") => json(list("JobList", to_values(&cluster.jobs))),
        Method::GET if p.ends_with("/pods") => json(list("PodList", to_values(&cluster.pods))),
        Method::GET if p.ends_with("/resourcequotas") => json(list("ResourceQuotaList", to_values(&cluster.quotas))),
        Method::GET if p == RUNS => json(list("SimulationRunList", to_values(&cluster.runs))),
        Method::DELETE => json(json!({"kind": "Status", "apiVersion": "v1", "status": "Success", "metadata": {}})),
        Method::PATCH if p.starts_with(RUNS) => {
            let mut run = serde_json::to_value(cluster.run.as_ref().unwrap()).unwrap();
            if let Some(status) = seen.body.get("status") {
                run["status"] = status.clone();
            }
            json(run)
        }
        // Server-side applies and created Events: the object as sent.
        Method::PATCH | Method::POST => json(seen.body.clone()),
        _ => panic!("unexpected request {} {}", seen.method, seen.path),
    }
}

/// Runs one reconcile of `cluster.run` against the fake server; returns the requests.
async fn reconcile_once(cluster: Cluster, settings: ClusterSettings, now: Timestamp) -> (Vec<Seen>, Arc<Metrics>) {
    let run = cluster.run.clone().unwrap();
    reconcile_each(cluster, settings, now, vec![run]).await
}

/// Reconciles each of `runs` in turn with one controller context (as the controller does
/// when a run changes or is requeued); the fake server answers from `cluster`.
async fn reconcile_each(
    cluster: Cluster,
    settings: ClusterSettings,
    now: Timestamp,
    runs: Vec<SimulationRun>,
) -> (Vec<Seen>, Arc<Metrics>) {
    let (service, mut handle) = mock::pair::<Request<Body>, Response<Body>>();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let server = {
        let seen = seen.clone();
        let cluster = cluster.clone();
        tokio::spawn(async move {
            while let Some((request, send)) = handle.next_request().await {
                let s = Seen::read(request).await;
                let (code, body) = answer(&cluster, &s);
                seen.lock().unwrap().push(s);
                send.send_response(Response::builder().status(code).body(Body::from(body)).unwrap());
            }
        })
    };
    let client = Client::new(service, NS);
    let metrics = Arc::new(Metrics::default());
    let mut ctx = Context::new(client, settings, 0, metrics.clone());
    ctx.clock = Box::new(move || now);
    if let Some(files) = cluster.world_files.clone() {
        ctx.world_files = files;
    }
    let ctx = Arc::new(ctx);
    for run in runs {
        tokio::time::timeout(Duration::from_secs(10), reconcile(Arc::new(run), ctx.clone()))
            .await
            .expect("reconcile finished")
            .expect("reconcile succeeded");
    }
    drop(ctx);
    // Every request was answered: the server ends when the client is gone.
    tokio::time::timeout(Duration::from_secs(1), server).await.expect("mock server ended").unwrap();
    let seen = seen.lock().unwrap().clone();
    (seen, metrics)
}

fn t0() -> Timestamp {
    Timestamp::from_second(1_800_000_000).unwrap()
}

fn s3_settings() -> ClusterSettings {
    ClusterSettings { default_archive_url: Some("s3://sadesim-runs".into()), ..Default::default() }
}

fn run_in_ns(run: SimulationRun) -> SimulationRun {
    let mut run = run;
    run.metadata.namespace = Some(NS.into());
    run.metadata.uid = Some("uid-1".into());
    run.metadata.generation = Some(1);
    run.metadata.resource_version = Some("42".into());
    run.metadata.creation_timestamp = Some(Time(t0()));
    run
}

fn new_run() -> SimulationRun {
    run_in_ns(RunBuilder::test().build())
}

fn pilot_run() -> SimulationRun {
    let mut run = RunBuilder::test().with_pilot(&["python3", "pilot.py"]).build();
    run.spec.pilot.as_mut().unwrap().image = Some("example.com/pilot:1".into());
    run_in_ns(run)
}

fn in_phase(mut run: SimulationRun, phase: Phase) -> SimulationRun {
    run.metadata.finalizers = Some(vec![FINALIZER.into()]);
    run.status = Some(SimulationRunStatus { phase: Some(phase), ..Default::default() });
    run
}

fn labels(role: &str) -> Option<BTreeMap<String, String>> {
    Some(BTreeMap::from([(RUN_LABEL.to_string(), "test-run".to_string()), (ROLE_LABEL.to_string(), role.to_string())]))
}

fn job(role: &str, condition: Option<&str>, active: i32) -> Job {
    let mut j = Job::default();
    j.metadata.name = Some(format!("test-run-{role}"));
    j.metadata.labels = labels(role);
    j.status = Some(JobStatus {
        active: Some(active),
        conditions: condition.map(|c| {
            vec![JobCondition {
                type_: c.into(),
                status: "True".into(),
                reason: Some(format!("{c}Reason")),
                ..Default::default()
            }]
        }),
        ..Default::default()
    });
    j
}

fn pod(name: &str, role: &str, phase: &str, job_owned: bool) -> Pod {
    let mut p = Pod::default();
    p.metadata.name = Some(name.into());
    p.metadata.labels = labels(role);
    if job_owned {
        p.metadata.owner_references =
            Some(vec![OwnerReference { kind: "Job".into(), name: format!("test-run-{role}"), ..Default::default() }]);
    }
    p.status = Some(PodStatus { phase: Some(phase.into()), ..Default::default() });
    p
}

fn status_of(seen: &Seen) -> SimulationRunStatus {
    serde_json::from_value(seen.body["status"].clone()).unwrap()
}

fn condition<'a>(status: &'a SimulationRunStatus, type_: &str) -> &'a Condition {
    status.conditions.iter().find(|c| c.type_ == type_).unwrap_or_else(|| panic!("no {type_}"))
}

/// Asserts a server-side apply: PATCH, apply-patch content type, our field manager, forced.
fn assert_apply(s: &Seen) {
    assert_eq!(s.method, Method::PATCH, "{s:?}");
    assert_eq!(s.content_type, "application/apply-patch+yaml", "{}", s.path);
    assert_eq!(s.query.get("fieldManager").map(String::as_str), Some(MANAGER), "{}", s.path);
    assert_eq!(s.query.get("force").map(String::as_str), Some("true"), "{}", s.path);
}

/// The status write: server-side apply on the status subresource. Returns the status.
fn the_status_write(seen: &[Seen]) -> SimulationRunStatus {
    let writes: Vec<&Seen> = seen.iter().filter(|s| s.path.ends_with("/status")).collect();
    assert_eq!(writes.len(), 1, "one status write: {:?}", paths(seen));
    let w = writes[0];
    assert_eq!(w.path, format!("{RUNS}/test-run/status"));
    assert_apply(w);
    assert_eq!(w.body["apiVersion"], "sadesim.io/v1alpha1");
    assert_eq!(w.body["kind"], "SimulationRun");
    assert!(w.body.get("spec").is_none(), "the status write never touches the spec");
    status_of(w)
}

fn event_reasons(seen: &[Seen]) -> Vec<String> {
    seen.iter()
        .filter(|s| s.is(Method::POST, &format!("/apis/events.k8s.io/v1/namespaces/{NS}/events")))
        .map(|s| s.body["reason"].as_str().unwrap().to_string())
        .collect()
}

fn paths(seen: &[Seen]) -> Vec<String> {
    seen.iter().map(|s| format!("{} {}", s.method, s.path)).collect()
}

fn applies(seen: &[Seen]) -> Vec<&Seen> {
    seen.iter()
        .filter(|s| {
            s.method == Method::PATCH
                && s.content_type == "application/apply-patch+yaml"
                && !s.path.ends_with("/status")
        })
        .collect()
}

fn finalizer_patches(seen: &[Seen]) -> Vec<&Seen> {
    seen.iter().filter(|s| s.is(Method::PATCH, &format!("{RUNS}/test-run"))).collect()
}

#[tokio::test]
async fn a_new_valid_run_gets_the_finalizer_children_by_server_side_apply_and_a_status() {
    let cluster = Cluster { run: Some(new_run()), runs: vec![new_run()], ..Default::default() };
    let (seen, metrics) = reconcile_once(cluster, s3_settings(), t0()).await;

    // Read the queue first: the namespace's runs and quotas.
    assert!(seen[0].is(Method::GET, RUNS), "{:?}", paths(&seen));
    assert!(seen[1].is(Method::GET, &format!("/api/v1/namespaces/{NS}/resourcequotas")));
    // Then the finalizer, as a merge patch guarded by the resourceVersion.
    let f = &seen[2];
    assert!(f.is(Method::PATCH, &format!("{RUNS}/test-run")));
    assert_eq!(f.content_type, "application/merge-patch+json");
    assert_eq!(f.body, json!({"metadata": {"finalizers": [FINALIZER], "resourceVersion": "42"}}));
    // Then the first stage's children: the two ConfigMaps and the assets Job.
    let a = applies(&seen);
    let targets: Vec<&str> = a.iter().map(|s| s.path.as_str()).collect();
    assert_eq!(
        targets,
        [
            "/api/v1/namespaces/team-a/configmaps/test-run-config",
            "/api/v1/namespaces/team-a/configmaps/test-run-fleet",
            "/apis/batch/v1/namespaces/team-a/jobs/test-run-assets",
        ]
    );
    for s in &a {
        assert_apply(s);
        assert_eq!(s.body["metadata"]["labels"][RUN_LABEL], "test-run");
        assert_eq!(s.body["metadata"]["ownerReferences"][0]["kind"], "SimulationRun");
    }
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::GeneratingAssets));
    assert_eq!(condition(&status, ct::VALID).status, "True");
    assert_eq!(condition(&status, ct::SCHEDULED).status, "True");
    assert_eq!(status.observed_generation, Some(1));
    assert_eq!(event_reasons(&seen), ["Queued", "GeneratingAssets"]);
    assert!(metrics.encode().contains("sadesim_operator_queue_wait_seconds_count 1"));
}

#[tokio::test]
async fn an_invalid_run_gets_valid_false_and_no_children() {
    let mut run = new_run();
    run.spec.fleet[0].count = 0;
    let cluster = Cluster { run: Some(run), ..Default::default() };
    let (seen, _) = reconcile_once(cluster, s3_settings(), t0()).await;
    assert!(applies(&seen).is_empty(), "{:?}", paths(&seen));
    assert!(finalizer_patches(&seen).is_empty(), "no finalizer on a run without children");
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Failed));
    let valid = condition(&status, ct::VALID);
    assert_eq!((valid.status.as_str(), valid.reason.as_str()), ("False", "InvalidSpec"));
    assert!(valid.message.contains("fleet[0].count"), "{}", valid.message);
    assert_eq!(event_reasons(&seen), ["InvalidSpec", "Failed"]);
    // Nothing but the status and the Events.
    assert_eq!(seen.len(), 3, "{:?}", paths(&seen));
}

#[tokio::test]
async fn a_run_waiting_in_queue_creates_nothing() {
    let run = new_run();
    let mut quota = ResourceQuota::default();
    quota.metadata.name = Some("team-a".into());
    let q = |v: &str| Quantity(v.into());
    quota.status = Some(ResourceQuotaStatus {
        hard: Some(BTreeMap::from([("requests.cpu".to_string(), q("1"))])),
        used: Some(BTreeMap::from([("requests.cpu".to_string(), q("900m"))])),
    });
    let cluster = Cluster { run: Some(run.clone()), runs: vec![run], quotas: vec![quota], ..Default::default() };
    let (seen, _) = reconcile_once(cluster, s3_settings(), t0()).await;
    assert!(applies(&seen).is_empty(), "{:?}", paths(&seen));
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Queued));
    let scheduled = condition(&status, ct::SCHEDULED);
    assert_eq!((scheduled.status.as_str(), scheduled.reason.as_str()), ("False", "QuotaExceeded"));
    assert!(scheduled.message.contains("ResourceQuota team-a"), "{}", scheduled.message);
    assert_eq!(finalizer_patches(&seen).len(), 1, "the finalizer is added while queued");
    assert_eq!(event_reasons(&seen), ["Queued"]);
}

/// Admission without Kueue across two runs of a namespace: while the first run's pods hold
/// the quota, the second waits whole (no child); once the first has ended and its pods are
/// gone, the second is admitted and starts.
#[tokio::test]
async fn quota_admission_holds_a_second_run_until_the_first_ends() {
    let q = |v: &str| Quantity(v.into());
    let quota = |used: &str| {
        let mut quota = ResourceQuota::default();
        quota.metadata.name = Some("team-a".into());
        quota.status = Some(ResourceQuotaStatus {
            hard: Some(BTreeMap::from([("requests.cpu".to_string(), q("2"))])),
            used: Some(BTreeMap::from([("requests.cpu".to_string(), q(used))])),
        });
        quota
    };
    let mut first = in_phase(new_run(), Phase::Running);
    first.metadata.name = Some("first-run".into());
    let mut second = new_run();
    second.metadata.creation_timestamp = Some(Time(t0() + SignedDuration::from_secs(60)));

    // The first run's pods use 1.5 of 2 CPUs; the second's gang needs more than the rest.
    let cluster = Cluster {
        run: Some(second.clone()),
        runs: vec![first.clone(), second.clone()],
        quotas: vec![quota("1500m")],
        ..Default::default()
    };
    let (seen, _) = reconcile_once(cluster, s3_settings(), t0()).await;
    assert!(applies(&seen).is_empty(), "{:?}", paths(&seen));
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Queued));
    assert_eq!(condition(&status, ct::SCHEDULED).reason, "QuotaExceeded");

    // The first run ended: its pods are deleted and the quota is free again.
    first.status.as_mut().unwrap().phase = Some(Phase::Succeeded);
    let waiting = in_phase(second.clone(), Phase::Queued);
    let cluster = Cluster {
        run: Some(waiting.clone()),
        runs: vec![first, waiting],
        quotas: vec![quota("0")],
        ..Default::default()
    };
    let (seen, metrics) = reconcile_once(cluster, s3_settings(), t0()).await;
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::GeneratingAssets));
    assert_eq!(condition(&status, ct::SCHEDULED).reason, "Admitted");
    assert!(applies(&seen).iter().any(|s| s.path.ends_with("/jobs/test-run-assets")), "{:?}", paths(&seen));
    assert!(metrics.encode().contains("sadesim_operator_queue_wait_seconds_count 1"));
}

#[tokio::test]
async fn assets_ready_moves_to_starting_and_applies_the_workers() {
    let run = in_phase(new_run(), Phase::GeneratingAssets);
    // The assets pod's container ended with the role's outcome line as its termination
    // message (a cache hit).
    let mut assets = pod("test-run-assets-4kq9z", "assets", "Succeeded", true);
    let hit = r#"{"outcome":"cacheHit","url":"s3://sadesim-runs/team-a/assets/k/world/"}"#;
    assets.status.as_mut().unwrap().container_statuses = Some(vec![ContainerStatus {
        name: "assets".into(),
        state: Some(ContainerState {
            terminated: Some(ContainerStateTerminated {
                exit_code: 0,
                message: Some(hit.into()),
                ..Default::default()
            }),
            ..Default::default()
        }),
        ..Default::default()
    }]);
    let cluster = Cluster {
        run: Some(run),
        jobs: vec![job("assets", Some("Complete"), 0)],
        pods: vec![assets],
        ..Default::default()
    };
    let (seen, _) = reconcile_once(cluster, s3_settings(), t0()).await;
    let lists: Vec<&Seen> = seen.iter().filter(|s| s.method == Method::GET).collect();
    assert_eq!(lists[0].path, format!("/apis/batch/v1/namespaces/{NS}/jobs"));
    assert_eq!(lists[0].query.get("labelSelector").map(String::as_str), Some("sadesim.io/run=test-run"));
    assert_eq!(lists[1].path, format!("/api/v1/namespaces/{NS}/pods"));
    let targets: Vec<String> = applies(&seen).iter().map(|s| s.path.rsplit('/').next().unwrap().to_string()).collect();
    assert!(targets.contains(&"test-run-coordinator".to_string()), "{targets:?}");
    assert!(targets.contains(&"test-run-shard".to_string()), "{targets:?}");
    assert!(!targets.contains(&"test-run-assets".to_string()), "{targets:?}");
    assert!(!targets.contains(&"test-run-pilot".to_string()), "{targets:?}");
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Starting));
    let ready = condition(&status, ct::ASSETS_READY);
    assert_eq!((ready.status.as_str(), ready.reason.as_str()), ("True", "CacheHit"));
    assert_eq!(ready.message, "asset cache hit: s3://sadesim-runs/team-a/assets/k/world/");
    assert_eq!(event_reasons(&seen), ["Starting"]);
}

#[tokio::test]
async fn released_pilots_are_read_from_the_coordinator_log_and_start_the_pilot_job() {
    let run = in_phase(pilot_run(), Phase::Starting);
    let cluster = Cluster {
        run: Some(run),
        jobs: vec![job("shard", None, 1)],
        pods: vec![pod("test-run-coordinator", "coordinator", "Running", false)],
        logs: BTreeMap::from([(
            "test-run-coordinator".to_string(),
            "{\"type\":\"pilotsReleased\",\"simTimeS\":0.01}\n".to_string(),
        )]),
        ..Default::default()
    };
    let (seen, _) = reconcile_once(cluster, s3_settings(), t0()).await;
    let log = seen.iter().find(|s| s.path.ends_with("/log")).expect("log read");
    assert_eq!(log.path, format!("/api/v1/namespaces/{NS}/pods/test-run-coordinator/log"));
    assert_eq!(log.query.get("tailLines").map(String::as_str), Some("20"));
    let pilot = applies(&seen).into_iter().find(|s| s.path.ends_with("/jobs/test-run-pilot")).expect("pilot applied");
    assert_eq!(pilot.body["spec"]["template"]["spec"]["containers"][0]["image"], "example.com/pilot:1");
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Running));
    assert_eq!(status.start_time, Some(Time(t0())));
    assert_eq!(event_reasons(&seen), ["Running"]);
}

/// The pilot Job completed: the coordinator Pod is applied again, now with the stop
/// annotation, and nothing is deleted yet (the coordinator's summary ends the run).
#[tokio::test]
async fn a_completed_pilot_job_annotates_the_coordinator_pod_to_end_the_run() {
    let mut run = in_phase(pilot_run(), Phase::Running);
    run.status.as_mut().unwrap().start_time = Some(Time(t0()));
    let cluster = Cluster {
        run: Some(run),
        jobs: vec![job("shard", None, 1), job("pilot", Some("Complete"), 0)],
        pods: vec![
            pod("test-run-shard-0", "shard", "Running", true),
            pod("test-run-pilot-x1", "pilot", "Succeeded", true),
            pod("test-run-coordinator", "coordinator", "Running", false),
        ],
        logs: BTreeMap::from([(
            "test-run-coordinator".to_string(),
            "{\"type\":\"progress\",\"simTimeS\":412.0,\"airborne\":0,\"onGround\":1,\"crashed\":0}\n".to_string(),
        )]),
        ..Default::default()
    };
    let (seen, _) = reconcile_once(cluster, s3_settings(), t0() + SignedDuration::from_secs(200)).await;
    let coordinator = applies(&seen)
        .into_iter()
        .find(|s| s.path == format!("/api/v1/namespaces/{NS}/pods/test-run-coordinator"))
        .expect("coordinator pod applied");
    assert_apply(coordinator);
    assert_eq!(coordinator.body["metadata"]["annotations"]["sadesim.io/stop"], "pilotExited");
    assert!(seen.iter().all(|s| s.method != Method::DELETE), "{:?}", paths(&seen));
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Running));
    assert_eq!(condition(&status, ct::RUNNING).reason, "PilotExited");
    assert_eq!(event_reasons(&seen), ["PilotExited"]);
}

/// An SRTM tile as the object store would hand it out, counting the reads.
#[derive(Default)]
struct TileInTheBucket {
    reads: std::sync::atomic::AtomicUsize,
}

impl WorldFiles for TileInTheBucket {
    fn read(&self, spec: &sadesim_crds::run::SimulationRunSpec) -> Result<WorldData, WorldReadError> {
        self.reads.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        assert_eq!(spec.world().terrain.expect("a DEM").dem.file, fixture::TILE_URL);
        Ok(WorldData { dem: Some(fixture::tile()), osm: None })
    }
}

/// A run over a DEM in object storage: the operator reads the tile (once, however often
/// the run is reconciled), plans over it (the plan's homes stand on the DEM's ground and its
/// asset key hashes the tile) and starts the assets Job, which builds the bundle from the
/// same URL with the object-store credentials.
#[tokio::test]
async fn a_world_from_object_storage_is_read_once_and_planned_over() {
    let run = fixture::over_tile(new_run());
    let files = Arc::new(TileInTheBucket::default());
    let cluster = Cluster {
        run: Some(run.clone()),
        runs: vec![run.clone()],
        world_files: Some(files.clone()),
        ..Default::default()
    };
    let settings = ClusterSettings { object_store_secret: Some("sadesim-object-store".into()), ..s3_settings() };
    let (seen, metrics) = reconcile_each(cluster, settings, t0(), vec![run.clone(), run]).await;
    let writes: Vec<&Seen> = seen.iter().filter(|s| s.path.ends_with("/status")).collect();
    let status = status_of(writes[0]);
    assert_eq!(files.reads.load(std::sync::atomic::Ordering::SeqCst), 1, "read once per generation: {status:?}");
    assert_eq!(metrics.plans.get(), 1);
    assert_eq!(status.phase, Some(Phase::GeneratingAssets));
    assert_eq!(condition(&status, ct::VALID).status, "True", "{}", condition(&status, ct::VALID).message);
    let config =
        applies(&seen).into_iter().find(|s| s.path.ends_with("/configmaps/test-run-config")).expect("the plan");
    let plan: RunPlan = serde_json::from_str(config.body["data"]["plan.json"].as_str().unwrap()).unwrap();
    let procedural = sadesim_planner::plan(&new_run()).unwrap();
    assert_ne!(plan.asset_cache_key, procedural.asset_cache_key, "the tile is part of the key");
    let ground = plan.drones[0].home.global.altitude_msl_m;
    assert!(ground > 150.0 && ground < 1351.0, "the home stands on the tile's ground: {ground}");
    let assets =
        applies(&seen).into_iter().find(|s| s.path.ends_with("/jobs/test-run-assets")).expect("the assets Job");
    let container = &assets.body["spec"]["template"]["spec"]["containers"][0];
    assert_eq!(container["envFrom"][0]["secretRef"]["name"], "sadesim-object-store", "{container}");
}

/// A fresh folder under the system temp dir for a file:// archive.
/// Planning generates the city: a run is planned once per generation of its spec, however
/// often it is reconciled, also when the queue view needs the plans of the namespace's
/// other runs.
#[tokio::test]
async fn a_run_is_planned_once_per_generation_of_its_spec() {
    let waiting = new_run();
    let mut holding = in_phase(new_run(), Phase::GeneratingAssets);
    holding.metadata.name = Some("other-run".into());
    holding.metadata.uid = Some("uid-2".into());
    let cluster = Cluster { run: Some(waiting.clone()), runs: vec![waiting.clone(), holding], ..Default::default() };
    let mut changed = waiting.clone();
    changed.metadata.generation = Some(2);

    let (seen, metrics) = reconcile_each(cluster.clone(), s3_settings(), t0(), vec![waiting.clone()]).await;
    assert!(seen.iter().any(|s| s.is(Method::GET, RUNS)), "the queue view was read: {:?}", paths(&seen));
    assert_eq!(metrics.plans.get(), 2, "the run and the other run holding resources");

    let (_, metrics) = reconcile_each(cluster.clone(), s3_settings(), t0(), vec![waiting.clone(); 3]).await;
    assert_eq!(metrics.plans.get(), 2, "three reconciles, one plan each");

    let (_, metrics) = reconcile_each(cluster, s3_settings(), t0(), vec![waiting.clone(), changed, waiting]).await;
    assert_eq!(metrics.plans.get(), 4, "a new generation is planned again (and so is the old one when it comes back)");
}

fn tempdir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-controller-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
