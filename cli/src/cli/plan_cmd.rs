//! `sadesim plan`: a run's layout as a summary table, RunPlan JSON or fleet file.

use std::io::Write;
use std::path::Path;

use sadesim_crds::plan::RunPlan;
use sadesim_planner::{self as planner, Addressing};

use super::scenario::{load_one, report_problems};
use super::{CliError, Outcome};

pub(super) fn plan_file(
    file: &Path,
    json: bool,
    fleet: bool,
    namespace: Option<String>,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let path = file.display().to_string();
    let Some(mut run) = load_one(file, out)? else { return Ok(Outcome::Problems) };
    if namespace.is_some() {
        run.metadata.namespace = namespace;
    }
    let world_data = match sadesim_sources::world::read_data(&run.spec) {
        Ok(data) => data,
        Err(e) => {
            writeln!(out, "error: {path}: {e}")?;
            return Ok(Outcome::Problems);
        }
    };
    let plan = match planner::plan_with(&run, &world_data) {
        Ok(plan) => plan,
        Err(planner::PlanError::Invalid(errors)) => {
            report_problems(out, &path, &errors)?;
            return Ok(Outcome::Problems);
        }
        Err(e) => {
            writeln!(out, "error: {path}: {e}")?;
            return Ok(Outcome::Problems);
        }
    };
    if json {
        serde_json::to_writer_pretty(&mut *out, &plan).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else if fleet {
        let file = planner::fleet_file(&plan, &Addressing::Local { host: "127.0.0.1".into() });
        serde_json::to_writer_pretty(&mut *out, &file).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        out.write_all(summary(&plan).as_bytes())?;
    }
    Ok(Outcome::Success)
}

/// Human-readable plan summary.
pub fn summary(plan: &RunPlan) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let spec = &plan.spec;
    let clock = spec.clock();
    let clock = match clock.factor {
        Some(f) => format!("{:?} x{f}", clock.mode),
        None => format!("{:?}", clock.mode),
    };
    let o = &spec.origin;
    let _ = writeln!(s, "Run {}/{}", plan.run.namespace, plan.run.name);
    let _ = writeln!(
        s,
        "  origin {:.6}, {:.6} at {} m MSL; duration {} s at {} Hz; clock {clock}; seed {}",
        o.latitude_deg, o.longitude_deg, o.altitude_msl_m, plan.duration_s, plan.physics_rate_hz, plan.seed
    );
    let world = spec.world();
    let _ = writeln!(
        s,
        "  world {:?}, {} m around the origin; asset cache key {}",
        world.source,
        world.extent_m,
        &plan.asset_cache_key[..16]
    );
    let _ = writeln!(s, "\nGroups ({} drones)", plan.drones.len());
    let _ = writeln!(
        s,
        "  {:<20} {:>6}  {:<13} {:<9} {:<20} flown by",
        "group", "drones", "indices", "airframe", "operator"
    );
    for (gi, g) in spec.fleet.iter().enumerate() {
        let idx: Vec<u32> = plan.drones.iter().filter(|d| d.group_index == gi as u32).map(|d| d.index).collect();
        let range = format!("{}-{}", idx.first().unwrap_or(&0), idx.last().unwrap_or(&0));
        let by = if g.mission.is_some() { "scripted mission" } else { "pilot over MAVLink" };
        let _ = writeln!(s, "  {:<20} {:>6}  {:<13} {:<9} {:<20} {by}", g.name, g.count, range, g.airframe, g.operator);
    }
    let _ = writeln!(
        s,
        "\nShards ({} drones per shard, sync every {} steps)",
        spec.sharding().drones_per_shard,
        plan.sync_window_steps
    );
    let _ = writeln!(s, "  {:<6} {:>6}  {:<13} {:>8} {:>9}", "shard", "drones", "indices", "cpu (m)", "mem (MiB)");
    for (sh, r) in plan.shards.iter().zip(&plan.resources.shards).take(20) {
        let range = format!("{}-{}", sh.first_drone, sh.first_drone + sh.drone_count - 1);
        let _ = writeln!(
            s,
            "  {:<6} {:>6}  {:<13} {:>8} {:>9}",
            sh.index, sh.drone_count, range, r.cpu_millis, r.memory_mib
        );
    }
    if plan.shards.len() > 20 {
        let _ = writeln!(s, "  ... {} more shards", plan.shards.len() - 20);
    }
    let _ = writeln!(s, "\nMAVLink router segments (system ids 1..250 each)");
    let _ = writeln!(s, "  {:<8} {:>6}  {:<13} {:>8} {:>8}", "segment", "drones", "indices", "GCS udp", "GCS tcp");
    for seg in &plan.segments {
        let range = format!("{}-{}", seg.first_drone, seg.first_drone + seg.drone_count - 1);
        let _ = writeln!(
            s,
            "  {:<8} {:>6}  {:<13} {:>8} {:>8}",
            seg.index, seg.drone_count, range, seg.gcs_udp, seg.gcs_tcp
        );
    }
    let _ = writeln!(s, "\nDrones (API link: the drone sends to this UDP port; endpoint: connect here, UDP or TCP)");
    let _ = writeln!(
        s,
        "  {:<6} {:<24} {:>5} {:>4} {:>5} {:>9} {:>9}  home (lat, lon)",
        "index", "name", "sysid", "seg", "shard", "api udp", "endpoint"
    );
    for d in plan.drones.iter().take(12) {
        let _ = writeln!(
            s,
            "  {:<6} {:<24} {:>5} {:>4} {:>5} {:>9} {:>9}  {:.6}, {:.6}",
            d.index,
            d.name,
            d.system_id,
            d.segment,
            d.shard,
            d.ports.api_udp,
            d.ports.endpoint,
            d.home.global.latitude_deg,
            d.home.global.longitude_deg
        );
    }
    if plan.drones.len() > 12 {
        let _ = writeln!(s, "  ... {} more drones (`sadesim plan --json` lists all)", plan.drones.len() - 12);
    }
    let sv = plan.services;
    let _ = writeln!(
        s,
        "\nServices: coordinator tcp {}, airspace http {}, renderer http {}, metrics {}",
        sv.coordinator, sv.airspace_http, sv.renderer_http, sv.metrics
    );
    let total = plan.resources.total(plan.segments.len());
    let _ = writeln!(
        s,
        "Resources for the whole run: {} millicores, {} MiB (assets job: {} m, {} MiB)",
        total.cpu_millis, total.memory_mib, plan.resources.assets.cpu_millis, plan.resources.assets.memory_mib
    );
    s
}
