//! The run's ConfigMaps: `plan.json` (every role) and `fleet.json` (the pilot), one
//! ConfigMap each so each file has the whole ConfigMap limit to itself.
//!
//! Sizes, compact JSON: a 1000-drone plan is about 0.46 MB and its fleet file 0.40 MB; both
//! grow linearly, so a ConfigMap holds a plan of roughly 2200 drones. Bigger runs are
//! refused with a message (`problems`) rather than failing at apply time.

use std::collections::BTreeMap;

use k8s_openapi::api::core::v1::ConfigMap;
use sadesim_crds::plan::RunPlan;

use super::pod::Context;
use super::{ASSET_KEY_ANNOTATION, Problem, Role, names};
use sadesim_planner::{Addressing, fleet_file};

/// Most bytes of `data` the API server accepts in one ConfigMap (1 MiB).
pub const CONFIG_MAP_LIMIT_BYTES: usize = 1024 * 1024;

/// `plan.json` as stored: compact JSON.
pub(super) fn plan_json(plan: &RunPlan) -> String {
    serde_json::to_string(plan).expect("a RunPlan always serializes")
}

/// `fleet.json` as stored: compact JSON, cluster DNS names.
pub(super) fn fleet_json(plan: &RunPlan) -> String {
    serde_json::to_string(&fleet_file(plan, &Addressing::Cluster)).expect("a fleet file always serializes")
}

/// `scenario.json`, beside `fleet.json`: the run as applied (name, namespace, spec), for
/// pilots that read the scenario they fly in (`SADESIM_SCENARIO`, as locally).
pub(super) fn scenario_json(plan: &RunPlan) -> String {
    let mut run = sadesim_crds::SimulationRun::new(&plan.run.name, plan.spec.clone());
    run.metadata.namespace = Some(plan.run.namespace.clone());
    serde_json::to_string(&run).expect("a SimulationRun always serializes")
}

/// Bytes of `plan.json` and `fleet.json` as the ConfigMaps store them.
pub fn config_map_sizes(plan: &RunPlan) -> (usize, usize) {
    (plan_json(plan).len(), fleet_json(plan).len() + scenario_json(plan).len())
}

/// Files too big for a ConfigMap.
pub(super) fn size_problems(plan: &RunPlan) -> Vec<Problem> {
    let (plan_bytes, fleet_bytes) = config_map_sizes(plan);
    let drones = plan.drones.len();
    [("plan.json", plan_bytes), ("fleet.json", fleet_bytes)]
        .into_iter()
        .filter(|(_, bytes)| *bytes > CONFIG_MAP_LIMIT_BYTES)
        .map(|(file, bytes)| Problem {
            field: "spec.fleet".into(),
            message: format!(
                "{drones} drones make a {file} of {bytes} bytes, over the {CONFIG_MAP_LIMIT_BYTES}-byte ConfigMap limit: not supported on Kubernetes yet (split the fleet into several runs)"
            ),
            fatal: true,
        })
        .collect()
}

fn config_map(ctx: &Context, name: String, files: &[(&str, String)]) -> ConfigMap {
    let mut meta = ctx.meta(name, Role::Config);
    meta.annotations = Some(BTreeMap::from([(ASSET_KEY_ANNOTATION.to_string(), ctx.plan.asset_cache_key.clone())]));
    let data = files.iter().map(|(key, value)| (key.to_string(), value.clone())).collect();
    ConfigMap { metadata: meta, data: Some(data), ..Default::default() }
}

/// `<run>-config`: `plan.json`.
pub(super) fn plan_config_map(ctx: &Context) -> ConfigMap {
    config_map(ctx, names::config(ctx.name), &[("plan.json", plan_json(ctx.plan))])
}

/// `<run>-fleet`: the pilot's files, `fleet.json` with in-cluster addresses and
/// `scenario.json`.
pub(super) fn fleet_config_map(ctx: &Context) -> ConfigMap {
    let files = [("fleet.json", fleet_json(ctx.plan)), ("scenario.json", scenario_json(ctx.plan))];
    config_map(ctx, names::fleet(ctx.name), &files)
}
