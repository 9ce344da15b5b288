//! The thin I/O shell around [`lifecycle::decide`]: read (children, coordinator log,
//! queue), decide (pure), then act in a fixed order — finalizer, server-side apply of the
//! children, log archival, deletes, status on the status subresource, Events, finalizer
//! removal. Each step is one kind of API call; the order is what the tests assert.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use k8s_openapi::NamespaceResourceScope;
use k8s_openapi::api::apps::v1::Deployment;
use k8s_openapi::api::batch::v1::Job;
use k8s_openapi::api::core::v1::{ConfigMap, Pod, ResourceQuota, Service};
use k8s_openapi::api::networking::v1::NetworkPolicy;
use k8s_openapi::jiff::Timestamp;
use kube::api::{Api, DeleteParams, ListParams, LogParams, Patch, PatchParams};
use kube::runtime::controller::Action;
use kube::runtime::events::{Event, EventType, Recorder};
use kube::{Client, Resource, ResourceExt};
use sadesim_crds::SimulationRun;
use sadesim_crds::status::Phase;
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::json;

use super::lifecycle::{self, Decision, FINALIZER, Input, Note, Sample};
use super::metrics::Metrics;
use super::observe::QueueObservation;
use super::observe::{Observed, WorkState};
use super::planning::{self, ObjectStoreFiles, PlanFailure, WorldFiles};
use super::progress::{self, TAIL_LINES};
use super::queue::{self, Gang, QueueView, QueuedRun};
use crate::k8s::children::{
    Child, ClusterSettings, FlavorPlacement, Kind, PendingWorkload, PendingWorkloadsSummary, ROLE_LABEL, RUN_LABEL,
    ResourceFlavor, Role, RunFolder, Workload, names, pending_workloads_path,
};
use sadesim_crds::plan::RunPlan;

/// Field manager of every server-side apply (children and status).
pub const MANAGER: &str = "sadesim-operator";

/// Folder of the run's archive the operator owns (pod logs).
pub const LOGS_PREFIX: &str = "logs/";

/// Why a reconcile failed (it is retried with backoff).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A call to the API server failed.
    #[error("failed to {what}: {source}")]
    Kube {
        what: String,
        #[source]
        source: kube::Error,
    },
    /// Pod logs could not be written to the run's archive.
    #[error("failed to archive pod logs to {folder}: {source}")]
    Archive {
        folder: String,
        #[source]
        source: sadesim_evidence::archive::ArchiveError,
    },
    /// The blocking task that writes the archive panicked or was cancelled.
    #[error("the task archiving pod logs to {folder} did not finish: {source}")]
    ArchiveTask {
        folder: String,
        #[source]
        source: tokio::task::JoinError,
    },
    /// The run has no namespace (SimulationRuns are namespaced; the watch always sets it).
    #[error("run {0} has no namespace")]
    NoNamespace(String),
    /// A world file could not be fetched for a reason that may pass (network, throttling,
    /// credentials being rotated): retried, not a verdict on the spec.
    #[error("failed to plan {run}: {source}")]
    WorldFiles {
        run: String,
        #[source]
        source: PlanFailure,
    },
}

impl Error {
    /// Short label for the failure metric.
    pub fn metric_label(&self) -> &'static str {
        match self {
            Error::Kube { .. } => "kube",
            Error::Archive { .. } | Error::ArchiveTask { .. } => "archive",
            Error::NoNamespace(_) => "no_namespace",
            Error::WorldFiles { .. } => "world_files",
        }
    }
}

fn kube_err(what: impl Into<String>) -> impl FnOnce(kube::Error) -> Error {
    let what = what.into();
    move |source| Error::Kube { what, source }
}

/// What every reconcile shares.
pub struct Context {
    pub client: Client,
    pub settings: ClusterSettings,
    /// Active runs per namespace without Kueue; 0 = unlimited.
    pub max_concurrent_runs: u32,
    pub metrics: Arc<Metrics>,
    pub recorder: Recorder,
    /// Last progress sample per run uid (base of the real-time factor).
    pub samples: Mutex<HashMap<String, Sample>>,
    /// The plan of each run, per uid, for one generation (see [`Context::plan_of`]).
    plans: Mutex<HashMap<String, CachedPlan>>,
    /// Reads the files of mapped worlds (object storage; fixtures in tests).
    pub world_files: Arc<dyn WorldFiles>,
    /// The wall clock (fixed in tests).
    pub clock: Box<dyn Fn() -> Timestamp + Send + Sync>,
}

impl std::fmt::Debug for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Context").field("settings", &self.settings).finish_non_exhaustive()
    }
}

impl Context {
    pub fn new(client: Client, settings: ClusterSettings, max_concurrent_runs: u32, metrics: Arc<Metrics>) -> Self {
        let recorder = Recorder::new(client.clone(), MANAGER.into());
        Self {
            client,
            settings,
            max_concurrent_runs,
            metrics,
            recorder,
            samples: Mutex::default(),
            plans: Mutex::default(),
            world_files: Arc::new(ObjectStoreFiles),
            clock: Box::new(Timestamp::now),
        }
    }

    /// The plan of `run`, planned once per (uid, generation). Planning generates the city
    /// (for a mapped world: reads its files from object storage, see [`planning`]) and
    /// places every drone; a run is reconciled every few seconds while it lives, and the
    /// queue view needs the plans of every run of the namespace that holds resources. The
    /// plan depends only on the spec (whose every change bumps `metadata.generation`), on
    /// name, namespace and uid (fixed for a uid), and on the world files' bytes.
    ///
    /// # Errors
    /// [`Error::WorldFiles`] when a world file could not be fetched for a reason that may
    /// pass (the store unreachable, a server error): nothing is cached and the reconcile is
    /// retried. A file that is not there or not a map is a planning failure, cached.
    pub async fn plan_of(&self, run: &SimulationRun) -> Result<Arc<Result<RunPlan, PlanFailure>>, Error> {
        let key = plan_key(run);
        let generation = run.metadata.generation;
        let cached = |plans: &HashMap<String, CachedPlan>| {
            plans.get(&key).filter(|c| c.generation == generation).map(|c| c.plan.clone())
        };
        if let Some(plan) = cached(&self.plans.lock().unwrap_or_else(|e| e.into_inner())) {
            return Ok(plan);
        }
        self.metrics.plans.inc();
        let planned = match planning::plan(run, self.world_files.clone()).await {
            Err(failure) if failure.may_pass() => {
                return Err(Error::WorldFiles { run: run.name_any(), source: failure });
            }
            planned => planned,
        };
        let plan = Arc::new(planned);
        self.plans.lock().unwrap_or_else(|e| e.into_inner()).insert(key, CachedPlan { generation, plan: plan.clone() });
        Ok(plan)
    }

    /// Forgets the plan of a run that ended (a terminal run is not planned again unless it
    /// changes).
    fn forget_plan(&self, run: &SimulationRun) {
        self.plans.lock().unwrap_or_else(|e| e.into_inner()).remove(&plan_key(run));
    }
}

/// A plan and the generation of the spec it was planned from.
struct CachedPlan {
    generation: Option<i64>,
    plan: Arc<Result<RunPlan, PlanFailure>>,
}

/// The uid, or `namespace/name` for a run without one (never from the API server).
fn plan_key(run: &SimulationRun) -> String {
    run.uid().unwrap_or_else(|| format!("{}/{}", run.namespace().unwrap_or_default(), run.name_any()))
}

fn selector(run: &str, role: Option<Role>) -> String {
    match role {
        Some(role) => format!("{RUN_LABEL}={run},{ROLE_LABEL}={role}"),
        None => format!("{RUN_LABEL}={run}"),
    }
}

/// Reconciles one run (the controller's entry point).
///
/// # Errors
/// See [`Error`]; the controller retries with backoff.
pub async fn reconcile(run: Arc<SimulationRun>, ctx: Arc<Context>) -> Result<Action, Error> {
    ctx.metrics.reconciles.inc();
    let name = run.name_any();
    let ns = run.namespace().ok_or_else(|| Error::NoNamespace(name.clone()))?;
    let uid = run.uid().unwrap_or_default();
    let now = (ctx.clock)();
    let status = run.status.clone().unwrap_or_default();
    let phase = status.phase.unwrap_or(Phase::Pending);
    let deleting = run.metadata.deletion_timestamp.is_some();
    let kueue = ctx.settings.kueue && run.spec.queue.is_some();

    let planned = ctx.plan_of(&run).await?;
    let plan = planned.as_ref().as_ref();
    let waiting = matches!(phase, Phase::Pending | Phase::Queued);
    let observe =
        if deleting { !phase.is_terminal() } else { !phase.is_terminal() && (!waiting || kueue || run.spec.abort) };
    let mut observed = if observe { observe_children(&ctx.client, &ns, &name).await? } else { Observed::default() };
    if kueue && !phase.is_terminal() {
        observed.queue =
            observe_workload(&ctx.client, &ns, &name, run.spec.queue.as_deref().unwrap_or_default()).await?;
    }
    let admission = match plan {
        Ok(p) if !deleting && waiting && !kueue && !run.spec.abort => {
            let view = queue_view(&ctx, &ns).await?;
            Some(queue::admit(&name, run.metadata.creation_timestamp.as_ref().map(|t| t.0), Gang::of(p), &view))
        }
        _ => None,
    };
    let last_sample = ctx.samples.lock().unwrap_or_else(|e| e.into_inner()).get(&uid).copied();
    let input = Input { run: &run, plan, settings: &ctx.settings, observed: &observed, admission, now, last_sample };
    let decision = lifecycle::decide(&input);
    execute(&run, &ns, &ctx, decision, now).await
}

/// Lists the run's Jobs and Pods and reads the coordinator's log tail.
async fn observe_children(client: &Client, ns: &str, run: &str) -> Result<Observed, Error> {
    let lp = ListParams::default().labels(&selector(run, None));
    let jobs: Api<Job> = Api::namespaced(client.clone(), ns);
    let pods: Api<Pod> = Api::namespaced(client.clone(), ns);
    let job_list = jobs.list(&lp).await.map_err(kube_err(format!("list Jobs of {ns}/{run}")))?;
    let pod_list = pods.list(&lp).await.map_err(kube_err(format!("list Pods of {ns}/{run}")))?;
    let mut observed = Observed::from_objects(&job_list.items, &pod_list.items, None);
    let coordinator = names::coordinator_pod(run);
    let started = observed
        .pods
        .iter()
        .any(|p| p.name == coordinator && !matches!(p.state, WorkState::Pending | WorkState::Suspended));
    if started {
        let lp = LogParams { tail_lines: Some(TAIL_LINES), ..Default::default() };
        // A log that cannot be read yet (container restarting) is not an error of the run.
        if let Ok(text) = pods.logs(&coordinator, &lp).await {
            observed.coordinator = Some(progress::parse_tail(&text));
        }
    }
    Ok(observed)
}

/// How long a reconcile waits for Kueue's visibility API (a queue position).
const VISIBILITY_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// The run's Kueue Workload; while it waits, its place in the LocalQueue (Kueue's
/// visibility API; left out when that API does not answer: it is optional in Kueue and
/// needs its own RBAC); once admitted, the ResourceFlavors its admission names.
async fn observe_workload(
    client: &Client,
    ns: &str,
    run: &str,
    queue: &str,
) -> Result<Option<QueueObservation>, Error> {
    let workloads: Api<Workload> = Api::namespaced(client.clone(), ns);
    let name = names::workload(run);
    let Some(workload) =
        workloads.get_opt(&name).await.map_err(kube_err(format!("read the Kueue Workload {ns}/{name}")))?
    else {
        return Ok(None);
    };
    let mut observation = QueueObservation { workload, pending: None, flavors: Default::default() };
    let admission = observation.workload.status.as_ref().and_then(|s| s.admission.clone());
    match admission {
        None => {
            let request = http::Request::get(pending_workloads_path(ns, queue)).body(Vec::new());
            if let Ok(request) = request {
                // The client retries a server error with backoff for minutes: the position is
                // worth waiting for only briefly, the reconcile goes on without it.
                let answer = tokio::time::timeout(VISIBILITY_WAIT, client.request::<PendingWorkloadsSummary>(request));
                match answer.await {
                    Ok(Ok(summary)) => {
                        observation.pending = summary
                            .items
                            .into_iter()
                            .find(|p: &PendingWorkload| p.metadata.name.as_deref() == Some(&name));
                    }
                    Ok(Err(e)) => super::log::info(
                        "no queue position from Kueue's visibility API",
                        &[("run", &format!("{ns}/{run}")), ("error", &e.to_string())],
                    ),
                    Err(_) => super::log::info(
                        "no queue position from Kueue's visibility API",
                        &[
                            ("run", &format!("{ns}/{run}")),
                            ("error", &format!("no answer within {} s", VISIBILITY_WAIT.as_secs())),
                        ],
                    ),
                }
            }
        }
        Some(admission) => {
            let flavors: Api<ResourceFlavor> = Api::all(client.clone());
            let mut wanted: Vec<String> =
                admission.pod_set_assignments.iter().flat_map(|a| a.flavors.values().cloned()).collect();
            wanted.sort();
            wanted.dedup();
            for flavor in wanted {
                let found =
                    flavors.get_opt(&flavor).await.map_err(kube_err(format!("read the ResourceFlavor {flavor}")))?;
                if let Some(f) = found {
                    observation.flavors.insert(flavor, FlavorPlacement::clone(&f.spec));
                }
            }
        }
    }
    Ok(Some(observation))
}

/// The namespace's runs and ResourceQuotas.
async fn queue_view(ctx: &Context, ns: &str) -> Result<QueueView, Error> {
    let runs: Api<SimulationRun> = Api::namespaced(ctx.client.clone(), ns);
    let quotas: Api<ResourceQuota> = Api::namespaced(ctx.client.clone(), ns);
    let run_list = runs.list(&ListParams::default()).await.map_err(kube_err(format!("list SimulationRuns in {ns}")))?;
    let quota_list =
        quotas.list(&ListParams::default()).await.map_err(kube_err(format!("list ResourceQuotas in {ns}")))?;
    let mut runs = Vec::with_capacity(run_list.items.len());
    for r in &run_list.items {
        let phase = r.status.as_ref().and_then(|s| s.phase).unwrap_or(Phase::Pending);
        // A run generating assets holds its gang; one whose plan cannot be had now holds
        // nothing we can count (its own reconcile retries).
        let gang = match phase {
            Phase::GeneratingAssets => ctx.plan_of(r).await.ok().and_then(|p| p.as_ref().as_ref().ok().map(Gang::of)),
            _ => None,
        };
        runs.push(QueuedRun {
            name: r.name_any(),
            created: r.metadata.creation_timestamp.as_ref().map(|t| t.0),
            phase,
            kueue: ctx.settings.kueue && r.spec.queue.is_some(),
            gang,
        });
    }
    Ok(QueueView { runs, quotas: quota_list.items, max_concurrent_runs: ctx.max_concurrent_runs })
}

async fn apply_one<K>(client: &Client, ns: &str, obj: &K) -> Result<(), Error>
where
    K: Resource<Scope = NamespaceResourceScope, DynamicType = ()>
        + Serialize
        + DeserializeOwned
        + Clone
        + std::fmt::Debug,
{
    let api: Api<K> = Api::namespaced(client.clone(), ns);
    let name = obj.meta().name.clone().unwrap_or_default();
    let params = PatchParams::apply(MANAGER).force();
    api.patch(&name, &params, &Patch::Apply(obj))
        .await
        .map_err(kube_err(format!("apply {} {ns}/{name}", K::kind(&()))))?;
    Ok(())
}

/// Server-side applies one child.
async fn apply_child(client: &Client, ns: &str, child: &Child) -> Result<(), Error> {
    match child {
        Child::ConfigMap(o) => apply_one::<ConfigMap>(client, ns, o).await,
        Child::Job(o) => apply_one::<Job>(client, ns, o).await,
        Child::Service(o) => apply_one::<Service>(client, ns, o).await,
        Child::Pod(o) => apply_one::<Pod>(client, ns, o).await,
        Child::Deployment(o) => apply_one::<Deployment>(client, ns, o).await,
        Child::NetworkPolicy(o) => apply_one::<NetworkPolicy>(client, ns, o).await,
        Child::Workload(o) => apply_one::<Workload>(client, ns, o).await,
    }
}

async fn delete_collection<K>(client: &Client, ns: &str, labels: &str) -> Result<(), Error>
where
    K: Resource<Scope = NamespaceResourceScope, DynamicType = ()> + DeserializeOwned + Clone + std::fmt::Debug,
{
    let api: Api<K> = Api::namespaced(client.clone(), ns);
    api.delete_collection(&DeleteParams::background(), &ListParams::default().labels(labels))
        .await
        .map_err(kube_err(format!("delete {}s {labels} in {ns}", K::kind(&()))))?;
    Ok(())
}

/// Fetches the logs of `pods` and writes them to `logs/<pod>.log` in the run's archive.
/// Returns `(files, bytes)` of the run folder's manifest afterwards.
async fn archive_logs(client: &Client, ns: &str, pods: &[String], folder: &RunFolder) -> Result<(u32, u64), Error> {
    let api: Api<Pod> = Api::namespaced(client.clone(), ns);
    let mut files = Vec::new();
    for pod in pods {
        let text = match api.logs(pod, &LogParams::default()).await {
            Ok(text) => text,
            // The pod is gone or never started: say so in the archive rather than stop.
            Err(e) => format!("(sadesim operator: the log of pod {pod} could not be read: {e})\n"),
        };
        files.push((format!("{LOGS_PREFIX}{pod}.log"), text.into_bytes()));
    }
    let f = folder.clone();
    let manifest = tokio::task::spawn_blocking(move || {
        let archive = sadesim_evidence::archive::Archive::open(&f.archive)?;
        archive.add_files(&f.namespace, &f.run, &f.uid, LOGS_PREFIX, &files)
    })
    .await
    .map_err(|source| Error::ArchiveTask { folder: folder.url(), source })?
    .map_err(|source| Error::Archive { folder: folder.url(), source })?;
    Ok((manifest.file_count as u32, manifest.total_bytes))
}

/// Writes `status` on the run's status subresource (server-side apply, the operator's field
/// manager).
async fn write_status(
    runs: &Api<SimulationRun>,
    ns: &str,
    name: &str,
    status: &sadesim_crds::status::SimulationRunStatus,
) -> Result<(), Error> {
    let patch = json!({
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "status": status,
    });
    runs.patch_status(name, &PatchParams::apply(MANAGER).force(), &Patch::Apply(&patch))
        .await
        .map_err(kube_err(format!("write the status of {ns}/{name}")))?;
    Ok(())
}

/// Records `note` as an Event of the run (`action`: what the operator was doing). An Event
/// that cannot be written is logged, not worth failing the reconcile.
async fn record_event(ctx: &Context, run: &SimulationRun, note: &Note, action: &str) {
    let event = Event {
        type_: if note.warning { EventType::Warning } else { EventType::Normal },
        reason: note.reason.clone(),
        note: Some(note.message.chars().take(1000).collect()),
        action: action.into(),
        secondary: None,
    };
    if let Err(e) = ctx.recorder.publish(&event, &run.object_ref(&())).await {
        super::log::warn("failed to record an event", &[("run", &run.name_any()), ("error", &e.to_string())]);
    }
}

/// Carries out a decision, in the documented order.
async fn execute(
    run: &SimulationRun,
    ns: &str,
    ctx: &Context,
    mut d: Decision,
    now: Timestamp,
) -> Result<Action, Error> {
    let client = &ctx.client;
    let name = run.name_any();
    let runs: Api<SimulationRun> = Api::namespaced(client.clone(), ns);

    // 1. The finalizer before any child exists: deletion then always archives first.
    if d.add_finalizer {
        let mut finalizers = run.finalizers().to_vec();
        finalizers.push(FINALIZER.into());
        let patch = json!({"metadata": {"finalizers": finalizers, "resourceVersion": run.resource_version()}});
        runs.patch(&name, &PatchParams::default(), &Patch::Merge(&patch))
            .await
            .map_err(kube_err(format!("add the finalizer to {ns}/{name}")))?;
    }
    // 2. Children, one server-side apply each (idempotent; repairs drift).
    for child in &d.apply {
        apply_child(client, ns, child).await?;
    }
    // 3. Logs before the pods that hold them are deleted.
    if !d.archive_logs.is_empty()
        && let Some(archive) = &d.archive
    {
        match archive_logs(client, ns, &d.archive_logs, archive).await {
            Ok((files, bytes)) => {
                if let Some(a) = d.status.archive.as_mut() {
                    a.files = Some(files);
                    a.bytes = Some(bytes);
                }
            }
            // Nothing is deleted and no end is reported while the logs are not archived:
            // the run stays in Archiving under a condition that says why, and tries again.
            Err(e @ (Error::Archive { .. } | Error::ArchiveTask { .. })) => {
                let previous = run.status.clone().unwrap_or_default();
                let (status, wait) = lifecycle::archive_failed(
                    &previous,
                    &d.status,
                    &archive.url(),
                    &e.to_string(),
                    now,
                    run.metadata.generation,
                );
                ctx.metrics.failed(e.metric_label());
                super::log::warn("archiving failed", &[("run", &format!("{ns}/{name}")), ("error", &e.to_string())]);
                if status != previous {
                    write_status(&runs, ns, &name, &status).await?;
                }
                let note = Note {
                    warning: true,
                    reason: lifecycle::ARCHIVE_FAILED.into(),
                    message: status.message.clone().unwrap_or_default(),
                };
                record_event(ctx, run, &note, "Archive").await;
                return Ok(Action::requeue(wait));
            }
            Err(e) => return Err(e),
        }
    }
    // 4. Stop workloads: pilot, then shards, then the rest (by label selector).
    for del in &d.delete {
        let labels = selector(&name, del.role);
        match del.kind {
            Kind::ConfigMap => delete_collection::<ConfigMap>(client, ns, &labels).await?,
            Kind::Job => delete_collection::<Job>(client, ns, &labels).await?,
            Kind::Pod => delete_collection::<Pod>(client, ns, &labels).await?,
            Kind::Deployment => delete_collection::<Deployment>(client, ns, &labels).await?,
            Kind::NetworkPolicy => delete_collection::<NetworkPolicy>(client, ns, &labels).await?,
            Kind::Service => delete_collection::<Service>(client, ns, &labels).await?,
            Kind::Workload => delete_collection::<Workload>(client, ns, &labels).await?,
        }
    }
    // 5. Status, on the status subresource, only when it changed.
    let previous = run.status.clone().unwrap_or_default();
    if d.status != previous {
        write_status(&runs, ns, &name, &d.status).await?;
    }
    // 6. Events.
    for note in &d.events {
        record_event(ctx, run, note, "Reconcile").await;
    }
    // 7. The finalizer goes last, once the evidence is archived.
    if d.remove_finalizer {
        let finalizers: Vec<String> = run.finalizers().iter().filter(|f| *f != FINALIZER).cloned().collect();
        let patch = json!({"metadata": {"finalizers": finalizers, "resourceVersion": run.resource_version()}});
        runs.patch(&name, &PatchParams::default(), &Patch::Merge(&patch))
            .await
            .map_err(kube_err(format!("remove the finalizer of {ns}/{name}")))?;
    }

    // Bookkeeping.
    let uid = run.uid().unwrap_or_default();
    {
        let mut samples = ctx.samples.lock().unwrap_or_else(|e| e.into_inner());
        match d.sample {
            Some(s) => {
                samples.insert(uid.clone(), s);
            }
            None if d.phase_is_terminal() => {
                samples.remove(&uid);
            }
            None => {}
        }
    }
    if d.phase_is_terminal() || d.remove_finalizer {
        ctx.forget_plan(run);
    }
    if d.admitted
        && let Some(created) = &run.metadata.creation_timestamp
    {
        let waited = (now.as_nanosecond() - created.0.as_nanosecond()) as f64 * 1e-9;
        ctx.metrics.queue_wait.observe(waited.max(0.0));
    }
    let gone = d.remove_finalizer;
    ctx.metrics.set_phase(&uid, if gone { None } else { d.status.phase });
    if previous.phase != d.status.phase {
        let phase = d.status.phase.map(|p| format!("{p:?}")).unwrap_or_default();
        let message = d.status.message.clone().unwrap_or_default();
        super::log::info("phase", &[("run", &format!("{ns}/{name}")), ("phase", &phase), ("message", &message)]);
    }
    Ok(match d.requeue.take() {
        Some(after) => Action::requeue(after),
        None => Action::await_change(),
    })
}

impl Decision {
    fn phase_is_terminal(&self) -> bool {
        self.status.phase.is_some_and(Phase::is_terminal)
    }
}

/// What the controller does after a failed reconcile: count it, log it, retry.
pub fn error_policy(run: Arc<SimulationRun>, error: &Error, ctx: Arc<Context>) -> Action {
    ctx.metrics.failed(error.metric_label());
    super::log::warn(
        "reconcile failed",
        &[
            ("run", &format!("{}/{}", run.namespace().unwrap_or_default(), run.name_any())),
            ("error", &error.to_string()),
        ],
    );
    Action::requeue(Duration::from_secs(15))
}
