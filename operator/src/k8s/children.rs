//! The child objects of a SimulationRun (pure): what a run becomes on a cluster.
//!
//! | child | kind | name | why |
//! |---|---|---|---|
//! | config | ConfigMap | `<run>-config` (`-1`, `-2`, ...) | `plan.json`, read by every role, in parts when it is large |
//! | config | ConfigMap | `<run>-fleet` | `fleet.json` and `scenario.json`, read by the pilot |
//! | network | NetworkPolicy | `<run>-isolation` | only the run's pods and `spec.groundStations.allowFrom` reach its pods |
//! | assets | Job | `<run>-assets` | builds the world into the asset cache (cache miss only) |
//! | coordinator | Service | `<run>-airspace` | shard link (TCP 7400) and airspace API (HTTP 8480) |
//! | coordinator | Pod | `<run>-coordinator` | lockstep clock, recorder, airspace authority, archive upload; annotation `sadesim.io/stop` ends the run |
//! | router | Service, Pod | `<run>-mavlink-<s>`, `<run>-router-<s>` | one MAVLink GCS endpoint per segment |
//! | shard | Service (headless) | `<run>-shards` | DNS `<run>-shard-<i>.<run>-shards.<ns>.svc` per shard pod |
//! | shard | Job (Indexed) | `<run>-shard` | one pod per shard, `JOB_COMPLETION_INDEX` = shard |
//! | renderer | Service, Deployment | `<run>-renderer` | browser 3D view (rendering on only) |
//! | pilot | Job | `<run>-pilot` | the user's image; an init container holds it until the pilots are released |
//! | queue | Workload | `<run>` | the whole run as one Kueue gang (`spec.queue` with Kueue on) |
//!
//! The Service and host names are the ones the planner writes into the fleet file
//! ([`sadesim_planner::Addressing::Cluster`]), so a pilot and the router reach the same pods.
//!
//! # Guarantees
//! - Every child carries an ownerReference to the run (controller, blockOwnerDeletion) and
//!   the labels [`RUN_LABEL`] and [`ROLE_LABEL`]; pod templates carry them too.
//! - Every pod runs as uid/gid 65532, non-root, read-only root filesystem, no privilege
//!   escalation, every capability dropped, seccomp `RuntimeDefault`, no service-account
//!   token.
//! - No object sets `spec.suspend` or Kueue's queue label: with Kueue the run is admitted
//!   as a whole through its Workload before any of them exists (docs/kubernetes.md).
//! - The result depends only on the inputs (same run, same bytes).

mod config;
pub mod kueue;
mod network;
mod pilot;
mod pod;
mod workers;

use k8s_openapi::api::apps::v1::Deployment;
use k8s_openapi::api::batch::v1::Job;
use k8s_openapi::api::core::v1::{ConfigMap, Pod, Service};
use k8s_openapi::api::networking::v1::NetworkPolicy;
use sadesim_crds::SimulationRun;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::plan::RunPlan;
use serde::Serialize;

pub use config::{CONFIG_MAP_LIMIT_BYTES, config_map_sizes};
pub use kueue::condition as workload_condition;
pub use kueue::{
    FlavorPlacement, KUEUE_API_VERSION, KUEUE_QUEUE_LABEL, PendingWorkload, PendingWorkloadsSummary, PodSetAssignment,
    ResourceFlavor, Workload, kueue_queue, pending_workloads_path, place, status_of,
};
pub use pod::{CONFIG_DIR, CONTROL_FILE, FLEET_PATH, OUT_DIR, PLAN_PATH, RUN_AS_ID};
pub use sadesim_crds::outcome::control::STOP_ANNOTATION;

/// The role a child plays in the run (DESIGN §3): the value of [`ROLE_LABEL`], the
/// container name of its pod, and what the controller selects children by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Role {
    /// The ConfigMaps with `plan.json` and `fleet.json`.
    Config,
    /// The NetworkPolicy that isolates the run's pods.
    Network,
    /// The Job that builds the world into the asset cache.
    Assets,
    /// Lockstep clock, recorder, airspace authority, end of run (one Pod and its Service).
    Coordinator,
    /// One MAVLink router Pod and Service per segment.
    Router,
    /// The physics shards (an Indexed Job and its headless Service).
    Shard,
    /// The browser 3D view (Deployment and Service).
    Renderer,
    /// The user's pilot image (a Job).
    Pilot,
    /// The run's Kueue Workload (the whole run as one gang).
    Queue,
}

impl Role {
    /// Every role, in apply order.
    pub const ALL: [Role; 9] = [
        Role::Queue,
        Role::Config,
        Role::Network,
        Role::Assets,
        Role::Coordinator,
        Role::Router,
        Role::Shard,
        Role::Renderer,
        Role::Pilot,
    ];

    /// The label value (`config`, `network`, `assets`, `coordinator`, `router`, `shard`,
    /// `renderer`, `pilot`).
    pub const fn label(self) -> &'static str {
        match self {
            Role::Config => "config",
            Role::Network => "network",
            Role::Assets => "assets",
            Role::Coordinator => "coordinator",
            Role::Router => "router",
            Role::Shard => "shard",
            Role::Renderer => "renderer",
            Role::Pilot => "pilot",
            Role::Queue => "queue",
        }
    }

    /// The role whose label value is `label`; `None` for anything else (an object someone
    /// labelled by hand).
    pub fn from_label(label: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.label() == label)
    }
}

impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.label())
    }
}

/// The kinds of object a run's children are (and the controller lists and deletes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    ConfigMap,
    Job,
    Service,
    Pod,
    Deployment,
    NetworkPolicy,
    Workload,
}

impl Kind {
    /// The object's `kind`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Kind::ConfigMap => "ConfigMap",
            Kind::Job => "Job",
            Kind::Service => "Service",
            Kind::Pod => "Pod",
            Kind::Deployment => "Deployment",
            Kind::NetworkPolicy => "NetworkPolicy",
            Kind::Workload => "Workload",
        }
    }
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Label with the run's name on every child.
pub const RUN_LABEL: &str = "sadesim.io/run";
/// Label with the child's role (`config`, `assets`, `shard`, `coordinator`, `router`,
/// `renderer`, `pilot`).
pub const ROLE_LABEL: &str = "sadesim.io/role";
/// Label with the router segment index on router Pods and Services.
pub const SEGMENT_LABEL: &str = "sadesim.io/segment";
/// Annotation with the plan's asset cache key (ConfigMap and assets Job).
pub const ASSET_KEY_ANNOTATION: &str = "sadesim.io/asset-cache-key";
/// API version and kind of the owner.
pub const OWNER_API_VERSION: &str = "sadesim.io/v1alpha1";
pub const OWNER_KIND: &str = "SimulationRun";

/// Operator-wide settings that shape children (Helm values -> operator flags/env).
#[derive(Clone, Debug, PartialEq)]
pub struct ClusterSettings {
    /// Image of `sim-worker` (assets, shard, coordinator, router, renderer roles). It also
    /// holds `sadesim`, which the coordinator pod runs to upload the run folder.
    pub worker_image: String,
    /// The worker image with OpenFOAM installed (images/sim-worker-openfoam.Dockerfile): the
    /// assets Job uses it when the run's urban wind model is `openfoam`, because that Job
    /// runs OpenFOAM over the world's buildings. Every other pod keeps `worker_image`.
    pub openfoam_image: String,
    /// The worker image with Mesa's Vulkan drivers (images/sim-worker-camera.Dockerfile):
    /// the coordinator of a run with onboard cameras uses it, because it renders their
    /// frames through Vulkan (lavapipe on the CPU, or the node's GPU driver).
    pub camera_image: String,
    /// Archive URL used when `spec.archive` is absent (e.g. `s3://sadesim-runs`).
    pub default_archive_url: Option<String>,
    /// Secret whose keys become environment variables of roles that write the archive
    /// (AWS_*, GOOGLE_*, AZURE_*).
    pub object_store_secret: Option<String>,
    /// Service type of the MAVLink router Services: `ClusterIP`, `NodePort` or `LoadBalancer`.
    pub router_service_type: String,
    /// Kueue integration on: runs with `spec.queue` get Kueue's labels.
    pub kueue: bool,
    /// The operator writes pod logs into `file://` archives. Off in the operator (a pod's
    /// folder is not the run's pods' folder, and its root is read-only): runs archived to
    /// `file://` are not archived on a cluster. The controller's tests turn it on to archive
    /// into a temporary folder.
    pub file_archives: bool,
}

impl Default for ClusterSettings {
    fn default() -> Self {
        Self {
            worker_image: "ghcr.io/sadesim/sim-worker:0.1.0".into(),
            openfoam_image: "ghcr.io/sadesim/sim-worker-openfoam:0.1.0".into(),
            camera_image: "ghcr.io/sadesim/sim-worker-camera:0.1.0".into(),
            default_archive_url: None,
            object_store_secret: None,
            file_archives: false,
            router_service_type: "ClusterIP".into(),
            kueue: false,
        }
    }
}

/// Which optional children exist at this point of the run's life.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stage {
    /// The asset cache misses: create the assets Job.
    pub assets_job: bool,
    /// Create the pilot Job (its init container waits until the pilots are released).
    pub pilot: bool,
    /// Ask the coordinator to end the run with this reason (e.g. `pilotExited`): the
    /// coordinator Pod carries the annotation [`STOP_ANNOTATION`], which it reads through a
    /// downward-API file.
    pub stop: Option<EndReason>,
}

impl Stage {
    /// Everything (what `sadesim manifests` prints).
    pub const ALL: Stage = Stage { assets_job: true, pilot: true, stop: None };
}

/// One child object, typed. Serializes as the object itself (with apiVersion and kind).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Child {
    ConfigMap(ConfigMap),
    Job(Job),
    Service(Service),
    Pod(Pod),
    Deployment(Deployment),
    NetworkPolicy(NetworkPolicy),
    Workload(Workload),
}

impl Child {
    /// `kind` of the object.
    pub fn kind(&self) -> Kind {
        match self {
            Child::ConfigMap(_) => Kind::ConfigMap,
            Child::Job(_) => Kind::Job,
            Child::Service(_) => Kind::Service,
            Child::Pod(_) => Kind::Pod,
            Child::Deployment(_) => Kind::Deployment,
            Child::NetworkPolicy(_) => Kind::NetworkPolicy,
            Child::Workload(_) => Kind::Workload,
        }
    }

    /// The role the object's [`ROLE_LABEL`] names (every child has one).
    pub fn role(&self) -> Option<Role> {
        self.labels().and_then(|l| l.get(ROLE_LABEL)).and_then(|r| Role::from_label(r))
    }

    /// `metadata.name` of the object.
    pub fn name(&self) -> &str {
        let meta = match self {
            Child::ConfigMap(o) => &o.metadata,
            Child::Job(o) => &o.metadata,
            Child::Service(o) => &o.metadata,
            Child::Pod(o) => &o.metadata,
            Child::Deployment(o) => &o.metadata,
            Child::NetworkPolicy(o) => &o.metadata,
            Child::Workload(o) => &o.metadata,
        };
        meta.name.as_deref().unwrap_or_default()
    }

    /// `metadata.labels` of the object.
    pub fn labels(&self) -> Option<&std::collections::BTreeMap<String, String>> {
        match self {
            Child::ConfigMap(o) => o.metadata.labels.as_ref(),
            Child::Job(o) => o.metadata.labels.as_ref(),
            Child::Service(o) => o.metadata.labels.as_ref(),
            Child::Pod(o) => o.metadata.labels.as_ref(),
            Child::Deployment(o) => o.metadata.labels.as_ref(),
            Child::NetworkPolicy(o) => o.metadata.labels.as_ref(),
            Child::Workload(o) => o.metadata.labels.as_ref(),
        }
    }
}

/// Names of the children, in one place (the controller looks children up by these).
pub mod names {
    /// ConfigMap with `plan.json`.
    pub fn config(run: &str) -> String {
        format!("{run}-config")
    }
    /// ConfigMap with `fleet.json`.
    pub fn fleet(run: &str) -> String {
        format!("{run}-fleet")
    }
    /// The assets Job.
    pub fn assets_job(run: &str) -> String {
        format!("{run}-assets")
    }
    /// The shards' Indexed Job: its pods are `<run>-shard-<index>` (hostname too).
    pub fn shard_job(run: &str) -> String {
        format!("{run}-shard")
    }
    /// The shards' headless Service (the pods' DNS subdomain).
    pub fn shard_service(run: &str) -> String {
        format!("{run}-shards")
    }
    /// DNS name of shard `shard`'s pod, as in the fleet file.
    pub fn shard_host(run: &str, namespace: &str, shard: u32) -> String {
        format!("{run}-shard-{shard}.{}.{namespace}.svc", shard_service(run))
    }
    /// The router's `--drone-host` template: [`shard_host`] with `{run}` and `{shard}` left
    /// for the router to fill in.
    pub fn drone_host_template(namespace: &str) -> String {
        format!("{{run}}-shard-{{shard}}.{{run}}-shards.{namespace}.svc")
    }
    /// The coordinator Pod.
    pub fn coordinator_pod(run: &str) -> String {
        format!("{run}-coordinator")
    }
    /// The coordinator's Service: shard link and airspace API.
    pub fn airspace_service(run: &str) -> String {
        format!("{run}-airspace")
    }
    /// DNS name of the coordinator's Service.
    pub fn airspace_host(run: &str, namespace: &str) -> String {
        format!("{}.{namespace}.svc", airspace_service(run))
    }
    /// Router Pod of segment `segment`.
    pub fn router_pod(run: &str, segment: u32) -> String {
        format!("{run}-router-{segment}")
    }
    /// Router Service of segment `segment` (the fleet file's GCS URL host).
    pub fn mavlink_service(run: &str, segment: u32) -> String {
        format!("{run}-mavlink-{segment}")
    }
    /// Part `index` (1, 2, ...) of the ConfigMap `base` that holds a file too big for one.
    pub fn part(base: &str, index: usize) -> String {
        format!("{base}-{index}")
    }
    /// The run's NetworkPolicy.
    pub fn isolation(run: &str) -> String {
        format!("{run}-isolation")
    }

    /// Deployment and Service of the browser 3D view.
    pub fn renderer(run: &str) -> String {
        format!("{run}-renderer")
    }
    /// The pilot Job.
    pub fn pilot_job(run: &str) -> String {
        format!("{run}-pilot")
    }
    /// The run's Kueue Workload: the run's own name (`kubectl get workload <run>`).
    pub fn workload(run: &str) -> String {
        run.to_string()
    }
}

/// The archive URL of a run: `spec.archive.url`, else the operator's default.
pub fn archive_url<'a>(plan: &'a RunPlan, settings: &'a ClusterSettings) -> Option<&'a str> {
    plan.spec.archive.as_ref().map(|a| a.url.as_str()).or(settings.default_archive_url.as_deref())
}

/// The archive URL the coordinator uploads to: [`archive_url`] when it is an object store
/// (`s3://`, `gs://`, `az://`). A `file://` archive would be a folder inside the pod, lost
/// with it, so none is used (see [`problems`]).
pub fn upload_url<'a>(plan: &'a RunPlan, settings: &'a ClusterSettings) -> Option<&'a str> {
    archive_url(plan, settings).filter(|u| sadesim_evidence::archive::is_object_store(u))
}

/// A run's folder in an archive: `<archive>/<namespace>/<run>/<uid>/`, the layout of
/// `sadesim archive put` and of the coordinator's upload. The operator adds the pod logs
/// under `logs/` there.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunFolder {
    /// The archive URL without a trailing `/` (`s3://bucket/prefix`, `file:///srv/runs`).
    pub archive: String,
    pub namespace: String,
    pub run: String,
    pub uid: String,
}

impl RunFolder {
    pub fn new(archive: &str, namespace: &str, run: &str, uid: &str) -> Self {
        Self {
            archive: archive.trim_end_matches('/').to_string(),
            namespace: namespace.to_string(),
            run: run.to_string(),
            uid: uid.to_string(),
        }
    }

    /// The folder's URL, with a trailing `/`.
    pub fn url(&self) -> String {
        format!("{}/{}/{}/{}/", self.archive, self.namespace, self.run, self.uid)
    }
}

/// Where the run's evidence lands ([`RunFolder::url`]), when the run has an object-store
/// archive and a uid.
pub fn archive_location(plan: &RunPlan, settings: &ClusterSettings) -> Option<String> {
    let url = upload_url(plan, settings)?;
    let uid = plan.run.uid.as_deref()?;
    Some(RunFolder::new(url, &plan.run.namespace, &plan.run.name, uid).url())
}

/// Where the assets of `plan` are cached: `<archive>/assets/<asset cache key>/world/`
/// (written by `sadesim assets`).
pub fn asset_cache_location(plan: &RunPlan, settings: &ClusterSettings) -> Option<String> {
    let url = upload_url(plan, settings)?;
    Some(format!(
        "{}/{}/{}/{}/",
        url.trim_end_matches('/'),
        sadesim_sources::assets::ASSETS_NAMESPACE,
        plan.asset_cache_key,
        sadesim_sources::assets::WORLD_FOLDER
    ))
}

/// Something about a run that matters on a cluster.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// The field to change (`spec.pilot.image`).
    pub field: String,
    /// What is wrong and what to do.
    pub message: String,
    /// The run cannot work on a cluster (the operator fails it with `Valid=False` and
    /// creates nothing); otherwise it runs but loses something (e.g. no archive).
    pub fatal: bool,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.message)
    }
}

/// What keeps `plan` from running on a cluster with `settings` (fatal), or makes it lose
/// something (not fatal). Valid local runs can still fail here: a pilot needs an image, and
/// the plan must fit a ConfigMap.
pub fn problems(plan: &RunPlan, settings: &ClusterSettings) -> Vec<Problem> {
    let mut out = Vec::new();
    if let Some(pilot) = &plan.spec.pilot
        && pilot.image.is_none()
    {
        out.push(Problem {
            field: "spec.pilot.image".into(),
            message: "required on Kubernetes: the pilot runs as a Job from this image (`command` only overrides its entrypoint)".into(),
            fatal: true,
        });
    }
    let urban = plan.spec.environment().wind.and_then(|w| w.urban);
    if let Some(case) = urban.as_ref().and_then(|u| u.case.as_ref()) {
        // The pods cannot see a folder on the machine that applied the run.
        out.push(Problem {
            field: "spec.environment.wind.urban.case".into(),
            message: format!(
                "{:?} is a folder on the machine that applied the run, which the pods cannot read: importing a case is local-only so far. Use model: openfoam without case: the assets Job runs OpenFOAM (in the operator's OpenFOAM image, images/sim-worker-openfoam.Dockerfile) or finds the field that `sadesim assets build --asset-cache <the cluster's cache>` stored",
                case.dir
            ),
            fatal: true,
        });
    }
    if let Some(queue) = &plan.spec.queue
        && !settings.kueue
    {
        // Running it anyway would bypass the quota the team asked to be admitted under.
        out.push(Problem {
            field: "spec.queue".into(),
            message: format!(
                "names the Kueue LocalQueue {queue:?}, but this operator's Kueue integration is off (Helm value kueue.enabled=false, SADESIM_KUEUE): the run would not be queued. Remove spec.queue to run under the operator's own admission, or install Kueue and enable the integration"
            ),
            fatal: true,
        });
    }
    match archive_url(plan, settings) {
        None => out.push(Problem {
            field: "spec.archive.url".into(),
            message: "not set and the operator has no default archive: the run's evidence is not archived (only the coordinator's log remains)".into(),
            fatal: false,
        }),
        Some(url) if !sadesim_evidence::archive::is_object_store(url) => out.push(Problem {
            field: "spec.archive.url".into(),
            message: format!(
                "{url:?} is a folder inside the coordinator pod, lost with it: use s3://, gs:// or az:// on Kubernetes (or omit it to use the operator's default archive)"
            ),
            fatal: false,
        }),
        Some(_) => {}
    }
    out
}

/// The children of `run` (planned as `plan`) at `stage`, in apply order: ConfigMaps, the
/// NetworkPolicy, the assets Job, coordinator Service and Pod, router Services and Pods, the shards' headless
/// Service and Job, the renderer, the pilot Job.
///
/// The pilot Job is left out when `spec.pilot` has no image and the assets Job when the
/// run has no object-store archive to cache into; [`problems`] says why. A queued run's
/// Kueue Workload is not among them: see [`workload`].
pub fn children(run: &SimulationRun, plan: &RunPlan, settings: &ClusterSettings, stage: Stage) -> Vec<Child> {
    children_in(&pod::Context::new(run, plan, settings), stage)
}

/// The run's Kueue Workload, with `spec.queue` and Kueue on: a podSet per role of every
/// child of the run's life ([`Stage::ALL`]). It is the only object of a run Kueue has not
/// admitted yet, so it is built apart from [`children`], only while it is needed.
pub fn workload(run: &SimulationRun, plan: &RunPlan, settings: &ClusterSettings) -> Option<Child> {
    let queue = kueue_queue(plan, settings)?;
    let ctx = pod::Context::new(run, plan, settings);
    let pods = children_in(&ctx, Stage::ALL);
    let meta = ctx.meta(names::workload(&plan.run.name), Role::Queue);
    Some(Child::Workload(kueue::workload(queue, meta, &pods)))
}

fn children_in(ctx: &pod::Context, stage: Stage) -> Vec<Child> {
    let plan = ctx.plan;
    let mut out: Vec<Child> = config::plan_config_maps(ctx).into_iter().map(Child::ConfigMap).collect();
    out.extend(config::fleet_config_maps(ctx).into_iter().map(Child::ConfigMap));
    out.push(Child::NetworkPolicy(network::network_policy(ctx)));
    if stage.assets_job
        && let Some(job) = workers::assets_job(ctx)
    {
        out.push(Child::Job(job));
    }
    out.push(Child::Service(workers::airspace_service(ctx)));
    out.push(Child::Pod(workers::coordinator_pod(ctx, stage.stop.as_ref())));
    for segment in &plan.segments {
        out.push(Child::Service(workers::mavlink_service(ctx, segment)));
        out.push(Child::Pod(workers::router_pod(ctx, segment)));
    }
    out.push(Child::Service(workers::shard_service(ctx)));
    out.push(Child::Job(workers::shard_job(ctx)));
    if plan.spec.rendering().enabled {
        out.push(Child::Service(workers::renderer_service(ctx)));
        out.push(Child::Deployment(workers::renderer_deployment(ctx)));
    }
    if stage.pilot
        && let Some(job) = pilot::pilot_job(ctx)
    {
        out.push(Child::Job(job));
    }
    out
}

#[cfg(test)]
mod tests;
