//! `sadesim assets build|show FILE`: a scenario's world built once into the asset cache (or
//! found there), and a PNG preview of it with the run's zones and homes, before anyone flies.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::time::Duration;

use indicatif::ProgressBar;
use sadesim_crds::plan::RunPlan;
use sadesim_planner as planner;
use sadesim_sources::assets::{AssetsOutcome, local_cache_url};
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
    let data = sadesim_sources::world::read_data(&run.spec);
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

/// The cache URL an entry's URL (`<cache>/assets/<key>/world/`) is in: the wind entry goes
/// beside the world's.
fn cache_of(outcome: &AssetsOutcome) -> String {
    outcome.url().split("/assets/").next().unwrap_or_default().to_string()
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
    // The cache URL the world came from, for the wind entry beside it.
    let cache_url = cache_of(&outcome);
    let started = std::time::Instant::now();
    let wind = crate::runner::run_wind(&plan, &world, Some(&cache_url), !quiet && std::io::stderr().is_terminal())
        .map_err(|source| CliError::Run { path: file.display().to_string(), source })?;
    if let Some((Some(outcome), field)) = wind {
        writeln!(out, "{outcome}")?;
        writeln!(out, "  {}", sadesim_engine::env::describe_urban_wind(&field, started.elapsed().as_secs_f64()))?;
    }
    Ok(Outcome::Success)
}

/// `sadesim assets show FILE --png OUT`.
pub(super) fn show(
    file: &Path,
    png: &Path,
    svg: Option<&Path>,
    cache: Cache,
    quiet: bool,
    wind: Option<&WindSliceArgs>,
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
    if let Some(outcome) = &outcome {
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
    if let Some(args) = wind {
        // The cache the world came from holds the field too (or gets it); without a cache
        // (`--no-asset-cache`) it is computed for the run's direction only.
        let cache = outcome.as_ref().map(cache_of);
        wind_slice(file, &world, &plan, cache.as_deref(), quiet, args, out)?;
    }
    Ok(Outcome::Success)
}

/// `assets show --wind-slice-agl`: what to draw and where.
pub struct WindSliceArgs {
    pub height_agl_m: f64,
    pub png: std::path::PathBuf,
    pub area: Option<[f64; 4]>,
}

/// Draws the slice of the run's field (from the cache, or computed for its direction).
fn wind_slice(
    file: &Path,
    world: &World,
    plan: &RunPlan,
    cache: Option<&str>,
    quiet: bool,
    args: &WindSliceArgs,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    use sadesim_evidence::report::svg::{WindSlice, wind_map};
    let path = file.display().to_string();
    if !(args.height_agl_m.is_finite() && args.height_agl_m > 0.0) {
        return Err(CliError::Failed(format!("--wind-slice-agl {}: expected metres above 0", args.height_agl_m)));
    }
    let wind = plan.spec.environment().wind.ok_or_else(|| {
        CliError::Failed(format!("--wind-slice-agl: {path} has no spec.environment.wind: there is no wind to draw"))
    })?;
    let progress = !quiet && std::io::stderr().is_terminal();
    let field = crate::runner::run_wind(plan, world, cache, progress)
        .map_err(|source| CliError::Run { path: path.clone(), source })?
        .map(|(_, field)| field)
        .ok_or_else(|| {
            CliError::Failed(format!(
                "--wind-slice-agl: {path} has no urban wind field (no buildings, or environment.wind.urban.model is none)"
            ))
        })?;
    let e = world.extent_m();
    let slice = WindSlice {
        field: &field,
        direction_from_deg: wind.direction_from_deg,
        // The field's factors are of the wind at its reference height over open ground:
        // the scenario's wind there, by the flight's profile.
        speed_mps: sadesim_engine::env::MeanWind::urban(
            wind.speed_mps,
            wind.direction_from_deg,
            wind.reference_height_m,
        )
        .speed_at_mps(field.profile.reference_height_m),
        height_agl_m: args.height_agl_m,
        area: args.area.unwrap_or([-e, -e, e, e]),
        run: plan.run.name.clone(),
    };
    let (picture, counts) = wind_map(&slice, &sadesim_evidence::report::footprints(world));
    let image = sadesim_evidence::report::png::render(&picture).map_err(CliError::Failed)?;
    std::fs::write(&args.png, image)
        .map_err(|e| CliError::Failed(format!("failed to write {}: {e}", args.png.display())))?;
    let columns: usize = counts.iter().sum();
    let share = |n: usize| 100.0 * n as f64 / columns.max(1) as f64;
    writeln!(
        out,
        "wind slice {} m above the ground: {} ({columns} columns: {:.0} % below half the open wind, {:.0} % above 1.1x)",
        args.height_agl_m,
        args.png.display(),
        share(counts[0] + counts[1]),
        share(counts[4] + counts[5] + counts[6]),
    )?;
    Ok(())
}
