//! `sadesim assets build|show FILE`: a scenario's world built once into the asset cache (or
//! found there), and a PNG preview of it with the run's zones and homes, before anyone flies.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::time::Duration;

use indicatif::ProgressBar;
use sadesim_crds::plan::RunPlan;
use sadesim_evidence::assets::{AssetsOutcome, local_cache_url};
use sadesim_planner as planner;
use sadesim_world::World;

use super::scenario::{load_one, report_problems};
use super::{CliError, Outcome};
use crate::runner::{RunError, run_world};

/// Where the world is looked up and stored.
pub enum Cache {
    /// An archive URL (`--asset-cache`), else the user cache folder.
    At(Option<String>),
    /// `--no-asset-cache`: built in memory, stored nowhere.
    Off,
}

/// A scenario's world and the plan in it.
struct Planned {
    /// Where the world came from (`None` without a cache).
    outcome: Option<AssetsOutcome>,
    world: World,
    plan: RunPlan,
}

/// The scenario's world (from the cache, or built and stored) and the plan in it; problems
/// with the scenario are reported on `out` (`None`).
fn world_and_plan(file: &Path, cache: Cache, quiet: bool, out: &mut dyn Write) -> Result<Option<Planned>, CliError> {
    let path = file.display().to_string();
    let Some(run) = load_one(file, out)? else { return Ok(None) };
    if let Err(errors) = sadesim_crds::validate::validate(&run) {
        report_problems(out, &path, &errors)?;
        return Ok(None);
    }
    let cache = match cache {
        Cache::Off => None,
        Cache::At(Some(url)) => Some(url),
        Cache::At(None) => {
            Some(local_cache_url(&|k| std::env::var(k).ok()).map_err(|e| CliError::Failed(e.to_string()))?)
        }
    };
    let progress = !quiet && std::io::stderr().is_terminal();
    // Reading and decoding a large extract or DEM takes a while: say so.
    let spinner = if progress { ProgressBar::new_spinner() } else { ProgressBar::hidden() };
    spinner.set_message(format!("reading the world's files of {path}"));
    spinner.enable_steady_tick(Duration::from_millis(120));
    let data = sadesim_evidence::world::read_data(&run.spec);
    spinner.finish_and_clear();
    let run_err = |source: RunError| CliError::Run { path: path.clone(), source };
    let data = data.map_err(|e| run_err(e.into()))?;
    let (outcome, world) = run_world(&run, &data, cache.as_deref(), progress).map_err(run_err)?;
    match planner::plan_in(&run, &data, &world) {
        Ok(plan) => Ok(Some(Planned { outcome, world, plan })),
        Err(e @ planner::PlanError::NoHome { .. }) => {
            writeln!(out, "error: {path}: {e}")?;
            Ok(None)
        }
        Err(e) => Err(run_err(e.into())),
    }
}

/// The world's statistics, as both commands print them.
fn describe(world: &World, out: &mut dyn Write) -> std::io::Result<()> {
    let s = world.stats();
    writeln!(
        out,
        "  {} buildings over {:.0} m x {:.0} m; heights median {:.1} m, max {:.1} m; ground {:.1} to {:.1} m from the origin",
        world.buildings().len(),
        2.0 * s.extent_m,
        2.0 * s.extent_m,
        s.median_height_m,
        s.max_height_m,
        s.ground_min_up_m,
        s.ground_max_up_m
    )?;
    if let Some(osm) = &s.osm {
        writeln!(
            out,
            "  OpenStreetMap heights: {} tagged, {} from building:levels, {} defaulted; {} open spaces",
            osm.heights_tagged,
            osm.heights_from_levels,
            osm.heights_defaulted,
            world.open_spaces().len()
        )?;
    }
    Ok(())
}

/// `sadesim assets build FILE`.
pub(super) fn build(file: &Path, cache: Option<String>, quiet: bool, out: &mut dyn Write) -> Result<Outcome, CliError> {
    let Some(Planned { outcome, world, plan }) = world_and_plan(file, Cache::At(cache), quiet, out)? else {
        return Ok(Outcome::Problems);
    };
    let outcome = outcome.expect("a cache was given");
    writeln!(out, "world of run {}: {outcome}", plan.run.name)?;
    describe(&world, out)?;
    Ok(Outcome::Success)
}

/// `sadesim assets show FILE --png OUT`.
pub(super) fn show(
    file: &Path,
    png: &Path,
    svg: Option<&Path>,
    cache: Cache,
    quiet: bool,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let Some(Planned { outcome, world, plan }) = world_and_plan(file, cache, quiet, out)? else {
        return Ok(Outcome::Problems);
    };
    let write = |path: &Path, bytes: &[u8]| {
        std::fs::write(path, bytes).map_err(|e| CliError::Failed(format!("failed to write {}: {e}", path.display())))
    };
    let picture = sadesim_evidence::report::preview::svg(&world, &plan);
    let image = sadesim_evidence::report::png::render(&picture).map_err(CliError::Failed)?;
    write(png, &image)?;
    if let Some(svg) = svg {
        write(svg, picture.as_bytes())?;
    }
    writeln!(out, "world of run {}: preview {}", plan.run.name, png.display())?;
    if let Some(outcome) = outcome {
        writeln!(out, "  {outcome}")?;
    }
    describe(&world, out)?;
    writeln!(
        out,
        "  {} zones; {} homes in {} groups",
        plan.spec.zones.len(),
        plan.drones.len(),
        plan.spec.fleet.len()
    )?;
    Ok(Outcome::Success)
}
