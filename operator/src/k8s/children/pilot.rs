//! The pilot under test as a Job from the user's image (DESIGN §3, role "pilot"): the
//! cluster counterpart of `runner::pilot`, with the same environment. The Job is created
//! with the other workers; an init container holds the pilot until the pilots are released.

use k8s_openapi::api::batch::v1::{Job, JobSpec};
use k8s_openapi::api::core::v1::{Container, PodTemplateSpec};
use sadesim_crds::plan::RoleResources;

use super::pod::{
    CONFIG_DIR, Context, FLEET_PATH, OUT_DIR, SCENARIO_PATH, SIM_WORKER, TMP_DIR, container_security, empty_dir, env,
    mount, pod_spec, resources, worker_container,
};
use super::{Role, config, names};

/// Where the joined fleet file is when `fleet.json` is stored in parts (an emptyDir the
/// `join` init container writes).
const JOINED_DIR: &str = "/var/run/sadesim/fleet";

/// `<run>-pilot`, or `None` when the run has no pilot or its pilot has no image (see
/// `problems`). Its command is `spec.pilot.containerCommand`, else `spec.pilot.command`
/// (none: the image's entrypoint). Environment, in order: `spec.pilot.env`, `SADESIM_FLEET`
/// (the mounted fleet file, in-cluster addresses), `SADESIM_SCENARIO` (the run as applied,
/// JSON), `SADESIM_RUN`, `SADESIM_NAMESPACE`, `SADESIM_RUN_UID`,
/// `SADESIM_OUT` (a writable folder), `HOME` (`/tmp` unless `spec.pilot.env` sets it: the
/// root filesystem is read-only), `SADESIM_CREDENTIAL_<GROUP>` per group with a
/// credential and, with onboard cameras, `SADESIM_CAMERAS_URL` (the coordinator's frame
/// listing; the fleet file has each drone's camera URLs). The pilot runs once: a pilot that fails is a finding, not something to retry.
pub(super) fn pilot_job(ctx: &Context) -> Option<Job> {
    let pilot = ctx.plan.spec.pilot.as_ref()?;
    let image = pilot.image.clone()?;
    let mut vars: Vec<_> = pilot.env.iter().map(|e| env(&e.name, e.value.clone())).collect();
    // A fleet file in parts is joined first (and checked against its digest) by an init
    // container from the worker image, into a file the pilot reads like any other.
    let in_parts = config::in_parts(&ctx.fleet_json);
    let joined = format!("{JOINED_DIR}/fleet.json");
    vars.push(env("SADESIM_FLEET", if in_parts { joined.as_str() } else { FLEET_PATH }));
    vars.push(env("SADESIM_SCENARIO", SCENARIO_PATH));
    vars.extend(ctx.run_env());
    vars.push(env("SADESIM_OUT", OUT_DIR));
    if !pilot.env.iter().any(|e| e.name == "HOME") {
        vars.push(env("HOME", TMP_DIR));
    }
    vars.extend(ctx.credential_env());
    if let Some(url) = sadesim_planner::cluster_cameras_url(ctx.plan) {
        vars.push(env(sadesim_planner::CAMERAS_URL_ENV, url));
    }
    let planned = ctx.plan.resources.pilot.unwrap_or(RoleResources { cpu_millis: 500, memory_mib: 512 });
    let mut container = Container {
        name: Role::Pilot.label().into(),
        image: Some(image),
        // `containerCommand` when given (`[]`: the image's entrypoint), else `command`.
        command: Some(pilot.container_command.as_ref().unwrap_or(&pilot.command)).filter(|c| !c.is_empty()).cloned(),
        env: Some(vars),
        resources: Some(resources(planned)),
        security_context: Some(container_security()),
        volume_mounts: Some(vec![
            mount("fleet", CONFIG_DIR, true),
            mount("tmp", TMP_DIR, false),
            mount("out", OUT_DIR, false),
        ]),
        termination_message_policy: Some("FallbackToLogsOnError".into()),
        ..Default::default()
    };
    let mut volumes = vec![config::fleet_volume(ctx), empty_dir("tmp"), empty_dir("out")];
    let mut init = Vec::new();
    if in_parts {
        container.volume_mounts.get_or_insert_with(Vec::new).push(mount("joined", JOINED_DIR, true));
        let args = vec!["join".to_string(), FLEET_PATH.to_string(), "--out".to_string(), joined];
        let mut join = worker_container(
            ctx,
            Role::Pilot,
            vec![SIM_WORKER.into()],
            args,
            RoleResources { cpu_millis: 100, memory_mib: 128 },
        );
        join.name = "join-fleet".into();
        join.volume_mounts = Some(vec![mount("fleet", CONFIG_DIR, true), mount("joined", JOINED_DIR, false)]);
        volumes.push(empty_dir("joined"));
        init.push(join);
    }
    init.push(wait_release(ctx));
    Some(job(ctx, container, volumes, Some(init)))
}

/// The init container that holds the pilot until the coordinator releases the pilots
/// (every shard ready, simulated time about to run): it polls the airspace API's
/// `/healthz` for `pilotsReleased`, as `sadesim run` starts the pilot process on the
/// `pilotsReleased` event. The pilot's pod is created, scheduled and its image pulled with
/// the rest of the run, so the pilot starts within one poll (0.2 s) of the release instead
/// of after a pod start.
fn wait_release(ctx: &Context) -> Container {
    let url = format!(
        "http://{}:{}/healthz",
        names::airspace_host(&ctx.plan.run.name, &ctx.plan.run.namespace),
        ctx.plan.services.airspace_http
    );
    let args = vec!["wait-release".to_string(), url];
    let mut wait = worker_container(
        ctx,
        Role::Pilot,
        vec![SIM_WORKER.into()],
        args,
        RoleResources { cpu_millis: 50, memory_mib: 32 },
    );
    wait.name = "wait-release".into();
    wait.volume_mounts = Some(vec![mount("tmp", TMP_DIR, false)]);
    wait
}

fn job(
    ctx: &Context,
    container: Container,
    volumes: Vec<k8s_openapi::api::core::v1::Volume>,
    init: Option<Vec<Container>>,
) -> Job {
    let mut spec = pod_spec(vec![container], volumes, "Never");
    spec.init_containers = init;
    let meta = ctx.meta(names::pilot_job(ctx.name), Role::Pilot);
    Job {
        metadata: meta,
        spec: Some(JobSpec {
            backoff_limit: Some(0),
            template: PodTemplateSpec { metadata: Some(ctx.template_meta(Role::Pilot)), spec: Some(spec) },
            ..Default::default()
        }),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests;
