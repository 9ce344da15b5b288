//! The run's ConfigMaps: `plan.json` (every role) and the pilot's files (`fleet.json`,
//! `scenario.json`).
//!
//! Sizes, compact JSON: a 1000-drone plan is about 0.46 MB and its fleet file 0.40 MB; both
//! grow linearly. A file over [`sadesim_crds::parts::PART_BYTES`] is stored in parts
//! (`plan.json.part-000`, ... and `plan.json.sha256`), one ConfigMap each (`<run>-config`,
//! `<run>-config-1`, ...), all mounted in one folder by a projected volume: a 10 000-drone
//! plan is 6 ConfigMaps. `sim-worker` joins and checks them (`sadesim_crds::parts::join`); the
//! pilot's fleet file is joined by an init container into the file the pilot reads.

use std::collections::BTreeMap;

use k8s_openapi::api::core::v1::{ConfigMap, ConfigMapProjection, ProjectedVolumeSource, Volume, VolumeProjection};
use sadesim_crds::parts::{PART_BYTES, digest_name, part_name, sha256_hex, split};
use sadesim_crds::plan::RunPlan;

use super::pod::Context;
use super::{ASSET_KEY_ANNOTATION, Role, names};
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

/// Bytes of `plan.json` and of the pilot's files as stored (before any split).
pub fn config_map_sizes(plan: &RunPlan) -> (usize, usize) {
    (plan_json(plan).len(), fleet_json(plan).len() + scenario_json(plan).len())
}

/// Whether a file of `text` is stored in parts rather than whole.
pub(super) fn in_parts(text: &str) -> bool {
    text.len() > PART_BYTES
}

/// The names of the ConfigMaps that hold a file of `text` stored under `base`: `base`, then
/// `<base>-1`, `<base>-2`, ... one per part beyond the first.
fn stored_names(base: &str, text: &str) -> Vec<String> {
    let parts = if in_parts(text) { split(text, PART_BYTES).len() } else { 1 };
    (0..parts).map(|i| if i == 0 { base.to_string() } else { names::part(base, i) }).collect()
}

fn config_map(ctx: &Context, name: String, files: Vec<(String, String)>) -> ConfigMap {
    let mut meta = ctx.meta(name, Role::Config);
    meta.annotations = Some(BTreeMap::from([(ASSET_KEY_ANNOTATION.to_string(), ctx.plan.asset_cache_key.clone())]));
    ConfigMap { metadata: meta, data: Some(files.into_iter().collect()), ..Default::default() }
}

/// The ConfigMaps that hold `file` (`text`), named by [`stored_names`]: `base` alone with
/// the whole file and `extra` when it fits one part; otherwise `base` with `extra`, the
/// digest and part 0, and `<base>-<i>` with part i.
fn stored(ctx: &Context, base: &str, file: &str, text: &str, extra: Vec<(String, String)>) -> Vec<ConfigMap> {
    if !in_parts(text) {
        let mut files = extra;
        files.push((file.to_string(), text.to_string()));
        return vec![config_map(ctx, base.to_string(), files)];
    }
    // The digest and `extra` go with part 0.
    let mut first = extra;
    first.push((digest_name(file), sha256_hex(text.as_bytes())));
    let names = stored_names(base, text);
    let parts = split(text, PART_BYTES);
    let files = std::iter::once(first).chain(std::iter::repeat_with(Vec::new));
    (names.into_iter().zip(parts).zip(files).enumerate())
        .map(|(i, ((name, part), mut files))| {
            files.push((part_name(file, i), part.to_string()));
            config_map(ctx, name, files)
        })
        .collect()
}

/// `<run>-config` (and its parts): `plan.json`.
pub(super) fn plan_config_maps(ctx: &Context) -> Vec<ConfigMap> {
    stored(ctx, &names::config(ctx.name), "plan.json", &ctx.plan_json, Vec::new())
}

/// `<run>-fleet` (and its parts): the pilot's files, `fleet.json` with in-cluster addresses
/// and `scenario.json`.
pub(super) fn fleet_config_maps(ctx: &Context) -> Vec<ConfigMap> {
    let scenario = vec![("scenario.json".to_string(), scenario_json(ctx.plan))];
    stored(ctx, &names::fleet(ctx.name), "fleet.json", &ctx.fleet_json, scenario)
}

/// Volume `config`: every ConfigMap of `plan.json` in one folder, [`super::pod::CONFIG_DIR`]
/// in the worker pods.
pub(super) fn plan_volume(ctx: &Context) -> Volume {
    volume("config", &stored_names(&names::config(ctx.name), &ctx.plan_json))
}

/// Volume `fleet`: every ConfigMap of the pilot's files in one folder.
pub(super) fn fleet_volume(ctx: &Context) -> Volume {
    volume("fleet", &stored_names(&names::fleet(ctx.name), &ctx.fleet_json))
}

/// A volume named `volume` with the ConfigMaps `config_maps` in one folder (a projected
/// volume: the parts of a split file side by side).
fn volume(volume: &str, config_maps: &[String]) -> Volume {
    let sources = config_maps
        .iter()
        .map(|name| VolumeProjection {
            config_map: Some(ConfigMapProjection { name: name.clone(), optional: Some(false), items: None }),
            ..Default::default()
        })
        .collect();
    Volume {
        name: volume.into(),
        projected: Some(ProjectedVolumeSource { sources: Some(sources), default_mode: None }),
        ..Default::default()
    }
}
