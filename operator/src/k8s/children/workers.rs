//! The worker-image roles: assets, coordinator, routers, shards, renderer.

use std::collections::BTreeMap;

use k8s_openapi::api::apps::v1::{Deployment, DeploymentSpec, DeploymentStrategy};
use k8s_openapi::api::batch::v1::{
    Job, JobSpec, PodFailurePolicy, PodFailurePolicyOnExitCodesRequirement, PodFailurePolicyOnPodConditionsPattern,
    PodFailurePolicyRule,
};
use k8s_openapi::api::core::v1::{
    ContainerPort, DownwardAPIVolumeFile, DownwardAPIVolumeSource, ObjectFieldSelector, Pod, PodTemplateSpec, Probe,
    Service, ServicePort, ServiceSpec, TCPSocketAction, Volume,
};
use k8s_openapi::apimachinery::pkg::apis::meta::v1::LabelSelector;
use k8s_openapi::apimachinery::pkg::util::intstr::IntOrString;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::plan::{RoleResources, RouterSegment};

use super::pod::{
    CONTROL_DIR, CONTROL_FILE, Context, OUT_DIR, PLAN_PATH, SIM_WORKER, empty_dir, mount, pod_spec, worker_container,
};
use super::{ASSET_KEY_ANNOTATION, Role, SEGMENT_LABEL, STOP_ANNOTATION, asset_cache_location, names, upload_url};

/// The extended resource of NVIDIA's device plugin (the common one; other vendors' plugins
/// name theirs differently).
const GPU_RESOURCE: &str = "nvidia.com/gpu";

/// Seconds a stopping coordinator gets to finish the run, write its files and upload them.
pub const COORDINATOR_GRACE_S: i64 = 600;

fn strings(items: &[&str]) -> Vec<String> {
    items.iter().map(|s| s.to_string()).collect()
}

fn port(name: &str, port: u16, protocol: &str) -> ContainerPort {
    ContainerPort {
        name: Some(name.into()),
        container_port: i32::from(port),
        protocol: Some(protocol.into()),
        ..Default::default()
    }
}

fn service_port(name: &str, port: u16, protocol: &str) -> ServicePort {
    ServicePort {
        name: Some(name.into()),
        port: i32::from(port),
        target_port: Some(IntOrString::String(name.into())),
        protocol: Some(protocol.into()),
        ..Default::default()
    }
}

fn tcp_probe(port: &str) -> Probe {
    Probe {
        tcp_socket: Some(TCPSocketAction { port: IntOrString::String(port.into()), host: None }),
        period_seconds: Some(2),
        ..Default::default()
    }
}

fn template(ctx: &Context, role: Role, spec: k8s_openapi::api::core::v1::PodSpec) -> PodTemplateSpec {
    PodTemplateSpec { metadata: Some(ctx.template_meta(role)), spec: Some(spec) }
}

/// Where a container writes its termination message (Kubernetes' default path).
pub const TERMINATION_LOG: &str = "/dev/termination-log";

/// `<run>-assets`: builds the world into the asset cache. `None` without an object-store
/// archive (there is no cache to fill; every shard builds the world itself).
///
/// Runs `sim-worker assets --plan P --archive URL --report-file /dev/termination-log`,
/// which fills `<archive>/assets/<asset cache key>/world/` (see `sadesim_sources::assets`)
/// or exits at once on a verified cache hit, and says which in its termination message
/// (read back by [`crate::k8s::controller`] into the `AssetsReady` condition).
pub(super) fn assets_job(ctx: &Context) -> Option<Job> {
    asset_cache_location(ctx.plan, ctx.settings)?;
    let archive = upload_url(ctx.plan, ctx.settings)?.to_string();
    let args = vec![
        "assets".into(),
        "--plan".into(),
        PLAN_PATH.into(),
        "--archive".into(),
        archive,
        "--report-file".into(),
        TERMINATION_LOG.into(),
    ];
    let mut container = worker_container(ctx, Role::Assets, strings(&[SIM_WORKER]), args, ctx.plan.resources.assets);
    if runs_openfoam(ctx.plan) {
        container.image = Some(ctx.settings.openfoam_image.clone());
    }
    container.env_from = ctx.object_store_env();
    container.termination_message_path = Some(TERMINATION_LOG.into());
    let spec = pod_spec(vec![container], vec![super::config::plan_volume(ctx), empty_dir("tmp")], "Never");
    let mut meta = ctx.meta(names::assets_job(ctx.name), Role::Assets);
    meta.annotations = Some(BTreeMap::from([(ASSET_KEY_ANNOTATION.to_string(), ctx.plan.asset_cache_key.clone())]));
    Some(Job {
        metadata: meta,
        spec: Some(JobSpec {
            // A second try covers a flaky object store; the world build is deterministic.
            backoff_limit: Some(1),
            template: template(ctx, Role::Assets, spec),
            ..Default::default()
        }),
        ..Default::default()
    })
}

/// Whether the run's assets phase runs OpenFOAM (`environment.wind.urban.model: openfoam`;
/// an imported `case` is refused on a cluster, see [`super::problems`]).
fn runs_openfoam(plan: &sadesim_crds::plan::RunPlan) -> bool {
    let urban = plan.spec.environment().wind.and_then(|w| w.urban);
    urban.is_some_and(|u| u.model == sadesim_crds::environment::UrbanWindModel::OpenFoam)
}

/// `<run>-airspace`: the coordinator's shard link and airspace API. Not-ready addresses are
/// published so shards can connect while the coordinator is still starting.
pub(super) fn airspace_service(ctx: &Context) -> Service {
    Service {
        metadata: ctx.meta(names::airspace_service(ctx.name), Role::Coordinator),
        spec: Some(ServiceSpec {
            selector: Some(ctx.selector(Role::Coordinator)),
            ports: Some(airspace_service_ports(ctx)),
            publish_not_ready_addresses: Some(true),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// The coordinator's ports: the shard link, the airspace API and, with rendering on, the
/// live stream the renderer follows (the renderer port number, on the coordinator pod).
fn coordinator_ports(ctx: &Context) -> Vec<(&'static str, u16)> {
    let s = ctx.plan.services;
    let mut ports = vec![("shard-link", s.coordinator), ("airspace", s.airspace_http)];
    if ctx.plan.spec.rendering().enabled {
        ports.push(("view-feed", s.renderer_http));
    }
    ports
}

fn airspace_service_ports(ctx: &Context) -> Vec<ServicePort> {
    coordinator_ports(ctx).into_iter().map(|(name, number)| service_port(name, number, "TCP")).collect()
}

/// The coordinator pod's program, one process (no shell): `sim-worker coordinator
/// --finish-run`, which runs the run, then, whatever its end, writes `plan.json`, the report
/// and `manifest.json` into [`OUT_DIR`] and uploads the folder to `SADESIM_ARCHIVE_URL` (from
/// the environment, never spliced into arguments). It catches SIGTERM (pod deletion) itself
/// and still finishes the folder; it exits with `UPLOAD_FAILED_EXIT` when only the upload
/// failed.
fn coordinator_args(ctx: &Context) -> Vec<String> {
    let s = ctx.plan.services;
    let listen = format!("0.0.0.0:{}", s.coordinator);
    let airspace = format!("0.0.0.0:{}", s.airspace_http);
    let mut args = strings(&[
        "coordinator",
        "--plan",
        PLAN_PATH,
        "--listen",
        &listen,
        "--airspace-bind",
        &airspace,
        "--out",
        OUT_DIR,
        "--control-file",
        CONTROL_FILE,
    ]);
    // The pilot Job starts on the release and may still pull its image: simulated time
    // holds until its MAVLink arrives (`spec.pilot.connectTimeoutS`).
    if ctx.plan.spec.pilot.is_some() {
        args.push("--hold-for-pilot".into());
    }
    args.push("--finish-run".into());
    if ctx.plan.spec.rendering().enabled {
        args.extend(["--view-bind".into(), format!("0.0.0.0:{}", s.renderer_http)]);
    }
    args
}

/// `<run>-coordinator`: lockstep clock, recorder, airspace authority; finishes and uploads
/// the run folder at the end (see [`coordinator_args`]). Its stdout is the JSON
/// progress stream the controller reads.
///
/// With `stop`, the Pod carries the annotation `sadesim.io/stop: <stop>`: the coordinator
/// reads its annotations from a downward-API file ([`CONTROL_FILE`]) and ends the run after
/// the current window with that reason. An annotation is the one thing of a running Pod the
/// operator may change, so the same server-side apply that created the Pod asks it to stop.
pub(super) fn coordinator_pod(ctx: &Context, stop: Option<&EndReason>) -> Pod {
    let command = strings(&[SIM_WORKER]);
    let mut c =
        worker_container(ctx, Role::Coordinator, command, coordinator_args(ctx), ctx.plan.resources.coordinator);
    let env = c.env.get_or_insert_with(Vec::new);
    if let Some(url) = upload_url(ctx.plan, ctx.settings) {
        env.push(super::pod::env("SADESIM_ARCHIVE_URL", url));
    }
    // With an object-store asset cache the coordinator loads the world's bundle, as the
    // shards do, for the city it draws in the recording and the report.
    if let Some(url) = asset_cache_location(ctx.plan, ctx.settings) {
        env.push(super::pod::env("SADESIM_ASSETS_URL", url));
    }
    // The authority checks the bearer credentials the pilot presents.
    env.extend(ctx.credential_env());
    if ctx.plan.spec.has_cameras() {
        renders_cameras(ctx, &mut c);
    }
    c.env_from = ctx.object_store_env();
    c.ports = Some(coordinator_ports(ctx).into_iter().map(|(name, number)| port(name, number, "TCP")).collect());
    c.readiness_probe = Some(tcp_probe("airspace"));
    let mounts = c.volume_mounts.get_or_insert_with(Vec::new);
    mounts.push(mount("out", OUT_DIR, false));
    mounts.push(mount("control", CONTROL_DIR, true));
    let volumes =
        vec![super::config::plan_volume(ctx), empty_dir("tmp"), empty_dir("out"), annotations_volume("control")];
    let mut spec = pod_spec(vec![c], volumes, "Never");
    spec.termination_grace_period_seconds = Some(COORDINATOR_GRACE_S);
    let mut metadata = ctx.meta(names::coordinator_pod(ctx.name), Role::Coordinator);
    if let Some(reason) = stop {
        metadata.annotations = Some(BTreeMap::from([(STOP_ANNOTATION.to_string(), reason.to_string())]));
    }
    Pod { metadata, spec: Some(spec), ..Default::default() }
}

/// Makes the coordinator `c` able to render the onboard cameras: the worker image with
/// Mesa's Vulkan drivers (lavapipe renders on the CPU, whose cost the planner added to the
/// coordinator's request), and `spec.rendering.gpus` GPUs when asked. NVIDIA's container
/// runtime mounts its Vulkan driver (ICD) only when the `graphics` capability is asked;
/// wgpu then prefers the GPU over lavapipe, and a pod scheduled without one still renders.
fn renders_cameras(ctx: &Context, c: &mut k8s_openapi::api::core::v1::Container) {
    c.image = Some(ctx.settings.camera_image.clone());
    if let Some(gpus) = ctx.plan.spec.rendering().gpus {
        let limits = c.resources.get_or_insert_with(Default::default).limits.get_or_insert_with(BTreeMap::new);
        limits.insert(GPU_RESOURCE.into(), k8s_openapi::apimachinery::pkg::api::resource::Quantity(gpus.to_string()));
        c.env.get_or_insert_with(Vec::new).push(super::pod::env("NVIDIA_DRIVER_CAPABILITIES", "graphics,utility"));
    }
}

/// A downward-API volume with one file, `annotations` (mounted at [`CONTROL_DIR`], so it is
/// [`CONTROL_FILE`]): the Pod's annotations as `key="value"` lines, refreshed by the
/// kubelet when they change.
fn annotations_volume(name: &str) -> Volume {
    Volume {
        name: name.into(),
        downward_api: Some(DownwardAPIVolumeSource {
            items: Some(vec![DownwardAPIVolumeFile {
                path: "annotations".into(),
                field_ref: Some(ObjectFieldSelector { field_path: "metadata.annotations".into(), api_version: None }),
                ..Default::default()
            }]),
            ..Default::default()
        }),
        ..Default::default()
    }
}

fn segment_labels(ctx: &Context, segment: u32) -> BTreeMap<String, String> {
    let mut l = ctx.selector(Role::Router);
    l.insert(SEGMENT_LABEL.into(), segment.to_string());
    l
}

/// `<run>-mavlink-<s>`: segment `s`'s GCS endpoint, UDP `14550+s` and TCP `5760+s` (the
/// plan's ports, the same inside and outside the pod, so the fleet file's URLs and the
/// status endpoints hold everywhere). The type comes from `--router-service-type`.
pub(super) fn mavlink_service(ctx: &Context, segment: &RouterSegment) -> Service {
    let mut meta = ctx.meta(names::mavlink_service(ctx.name, segment.index), Role::Router);
    meta.labels.get_or_insert_with(BTreeMap::new).insert(SEGMENT_LABEL.into(), segment.index.to_string());
    Service {
        metadata: meta,
        spec: Some(ServiceSpec {
            type_: Some(ctx.settings.router_service_type.clone()),
            selector: Some(segment_labels(ctx, segment.index)),
            ports: Some(vec![
                service_port("mavlink-udp", segment.gcs_udp, "UDP"),
                service_port("mavlink-tcp", segment.gcs_tcp, "TCP"),
            ]),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// `<run>-router-<s>`: serves segment `s`'s drones to ground stations. Stateless, so it is
/// restarted if it crashes; the operator deletes it when the run ends.
pub(super) fn router_pod(ctx: &Context, segment: &RouterSegment) -> Pod {
    let args = vec![
        "router".into(),
        "--plan".into(),
        PLAN_PATH.into(),
        "--segment".into(),
        segment.index.to_string(),
        "--bind".into(),
        "0.0.0.0".into(),
        "--drone-host".into(),
        names::drone_host_template(ctx.namespace),
    ];
    let mut c = worker_container(ctx, Role::Router, strings(&[SIM_WORKER]), args, ctx.plan.resources.router);
    // MAVLink signing: the passphrase in the environment (from the Secret), never an argument.
    c.env.get_or_insert_with(Vec::new).extend(ctx.signing_env());
    c.ports = Some(vec![port("mavlink-udp", segment.gcs_udp, "UDP"), port("mavlink-tcp", segment.gcs_tcp, "TCP")]);
    c.readiness_probe = Some(tcp_probe("mavlink-tcp"));
    let spec = pod_spec(vec![c], vec![super::config::plan_volume(ctx), empty_dir("tmp")], "Always");
    let mut meta = ctx.meta(names::router_pod(ctx.name, segment.index), Role::Router);
    meta.labels.get_or_insert_with(BTreeMap::new).insert(SEGMENT_LABEL.into(), segment.index.to_string());
    Pod { metadata: meta, spec: Some(spec), ..Default::default() }
}

/// `<run>-shards`: headless, so each shard pod gets the DNS name
/// `<run>-shard-<i>.<run>-shards.<ns>.svc` (hostname from the Indexed Job, subdomain this
/// Service). No ports: clients use the drones' endpoint ports from the fleet file directly.
/// Not-ready addresses are published so names resolve as soon as pods have IPs.
pub(super) fn shard_service(ctx: &Context) -> Service {
    Service {
        metadata: ctx.meta(names::shard_service(ctx.name), Role::Shard),
        spec: Some(ServiceSpec {
            cluster_ip: Some("None".into()),
            selector: Some(ctx.selector(Role::Shard)),
            publish_not_ready_addresses: Some(true),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// The largest per-shard estimate: one pod template serves every shard.
fn shard_resources(ctx: &Context) -> RoleResources {
    let shards = &ctx.plan.resources.shards;
    RoleResources {
        cpu_millis: shards.iter().map(|r| r.cpu_millis).max().unwrap_or(250),
        memory_mib: shards.iter().map(|r| r.memory_mib).max().unwrap_or(256),
    }
}

/// `<run>-shard`: one pod per shard (`JOB_COMPLETION_INDEX` = shard index, which
/// `sim-worker shard` reads). A shard cannot be replaced mid-run (the lockstep needs all of
/// them), so any failed or disrupted shard fails the Job at once, and with it the run.
pub(super) fn shard_job(ctx: &Context) -> Job {
    let count = i32::try_from(ctx.plan.shards.len()).expect("at most 10000 shards");
    let mut args: Vec<String> = vec![
        "shard".into(),
        "--plan".into(),
        PLAN_PATH.into(),
        "--coordinator".into(),
        format!("{}:{}", names::airspace_host(ctx.name, ctx.namespace), ctx.plan.services.coordinator),
        "--mavlink-bind".into(),
        "0.0.0.0".into(),
        // The pilot's pod address is unknown here: pilots connect to the drones' endpoints.
        "--mavlink-api-host".into(),
        "none".into(),
    ];
    // With an object-store cache the assets Job has stored the world's bundle: every shard
    // loads it (checked against its manifest) instead of building the world itself.
    let assets = asset_cache_location(ctx.plan, ctx.settings);
    if let Some(url) = &assets {
        args.extend(["--assets".into(), url.clone()]);
    }
    let mut c = worker_container(ctx, Role::Shard, strings(&[SIM_WORKER]), args, shard_resources(ctx));
    // The bundle, or without one the world's own files (a map or DEM in a bucket), are read
    // with the object-store credentials.
    if assets.is_some() || !sadesim_sources::world::world_files(&ctx.plan.spec).is_empty() {
        c.env_from = ctx.object_store_env();
    }
    let mut spec = pod_spec(vec![c], vec![super::config::plan_volume(ctx), empty_dir("tmp")], "Never");
    spec.subdomain = Some(names::shard_service(ctx.name));
    let meta = ctx.meta(names::shard_job(ctx.name), Role::Shard);
    Job {
        metadata: meta,
        spec: Some(JobSpec {
            completion_mode: Some("Indexed".into()),
            completions: Some(count),
            parallelism: Some(count),
            backoff_limit: Some(0),
            pod_failure_policy: Some(PodFailurePolicy {
                rules: vec![
                    PodFailurePolicyRule {
                        action: "FailJob".into(),
                        on_exit_codes: Some(PodFailurePolicyOnExitCodesRequirement {
                            container_name: Some(Role::Shard.label().into()),
                            operator: "NotIn".into(),
                            values: vec![0],
                        }),
                        on_pod_conditions: None,
                    },
                    PodFailurePolicyRule {
                        action: "FailJob".into(),
                        on_exit_codes: None,
                        on_pod_conditions: Some(vec![PodFailurePolicyOnPodConditionsPattern {
                            type_: "DisruptionTarget".into(),
                            status: "True".into(),
                        }]),
                    },
                ],
            }),
            template: template(ctx, Role::Shard, spec),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// `<run>-renderer` Service.
pub(super) fn renderer_service(ctx: &Context) -> Service {
    Service {
        metadata: ctx.meta(names::renderer(ctx.name), Role::Renderer),
        spec: Some(ServiceSpec {
            selector: Some(ctx.selector(Role::Renderer)),
            ports: Some(vec![service_port("http", ctx.plan.services.renderer_http, "TCP")]),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// `<run>-renderer`: `sim-worker renderer --plan P --listen 0.0.0.0:<renderer port> --feed
/// <run>-airspace:<renderer port>` (the coordinator's live stream), one replica, replaced
/// (not rolled) on change. It loads the world's bundle as the shards do (for the city it
/// draws). It asks no GPU: browsers draw the view, and the onboard cameras render in the
/// coordinator (`spec.rendering.gpus` goes there).
pub(super) fn renderer_deployment(ctx: &Context) -> Deployment {
    let port_no = ctx.plan.services.renderer_http;
    let feed = format!("{}:{port_no}", names::airspace_host(ctx.name, ctx.namespace));
    let mut args: Vec<String> = strings(&["renderer", "--plan", PLAN_PATH, "--listen"]);
    args.extend([format!("0.0.0.0:{port_no}"), "--feed".into(), feed]);
    if let Some(url) = asset_cache_location(ctx.plan, ctx.settings) {
        args.extend(["--assets".into(), url]);
    }
    let resources = ctx.plan.resources.renderer.unwrap_or(RoleResources { cpu_millis: 1000, memory_mib: 1024 });
    let mut c = worker_container(ctx, Role::Renderer, strings(&[SIM_WORKER]), args, resources);
    // The bundle, or without one the world's own files, are read with the object-store
    // credentials, as by the shards.
    c.env_from = ctx.object_store_env();
    c.ports = Some(vec![port("http", port_no, "TCP")]);
    c.readiness_probe = Some(tcp_probe("http"));
    let spec = pod_spec(vec![c], vec![super::config::plan_volume(ctx), empty_dir("tmp")], "Always");
    Deployment {
        metadata: ctx.meta(names::renderer(ctx.name), Role::Renderer),
        spec: Some(DeploymentSpec {
            replicas: Some(1),
            selector: LabelSelector { match_labels: Some(ctx.selector(Role::Renderer)), match_expressions: None },
            strategy: Some(DeploymentStrategy { type_: Some("Recreate".into()), rolling_update: None }),
            template: template(ctx, Role::Renderer, spec),
            ..Default::default()
        }),
        ..Default::default()
    }
}
