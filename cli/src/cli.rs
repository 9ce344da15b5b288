//! The `sadesim` command line: flags and glue only; the work is in the planner and the
//! contracts crate.

mod archive_cmd;
mod args;
mod assets_cmd;
mod console_cmd;
mod dem_cmd;
mod gnss_cmd;
mod osm_cmd;
mod outcome;
mod plan_cmd;
mod run_cmd;
mod scenario;
mod sky_grid_cmd;
mod sweep_cmd;
mod validate_cmd;
mod view_cmd;

use std::io::Write;

pub use args::{ArchiveCommand, AssetsCommand, Cli, Command, GnssCommand};
pub use outcome::{CliError, Outcome};
pub use plan_cmd::summary;
pub use scenario::read_scenario;

use archive_cmd::archive_command;
use plan_cmd::plan_file;
use run_cmd::run_file;
use validate_cmd::validate_files;

/// Runs a parsed command, writing its report to `out`.
///
/// # Errors
/// Only for failures to read input or write output; invalid scenarios are reported on
/// `out` and give [`Outcome::Problems`].
pub fn execute(cli: Cli, out: &mut dyn Write) -> Result<Outcome, CliError> {
    match cli.command {
        Command::Validate { files } => validate_files(&files, out),
        Command::Plan { file, json, fleet, namespace } => plan_file(&file, json, fleet, namespace, out),
        Command::Run {
            file,
            out: out_root,
            quiet,
            processes,
            clock,
            no_pilot,
            pilot_connect_timeout,
            no_mavlink,
            asset_cache,
            no_asset_cache,
        } => {
            let asset_cache = match (asset_cache, no_asset_cache) {
                (_, true) => None,
                (Some(url), false) => Some(url),
                (None, false) => Some(
                    sadesim_sources::assets::local_cache_url(&|k| std::env::var(k).ok())
                        .map_err(|e| CliError::Failed(e.to_string()))?,
                ),
            };
            let options = crate::runner::RunOptions {
                out_root,
                progress: !quiet,
                processes,
                worker: None,
                scenario: (file.as_os_str() != "-").then(|| file.clone()),
                start_pilot: !no_pilot,
                mavlink: !no_mavlink,
                asset_cache,
                pilot_connect_timeout_s: pilot_connect_timeout,
                ..Default::default()
            };
            run_file(&file, options, clock, out)
        }
        Command::Bench { airspace: true, seconds, rate, connections, .. } => {
            let report = crate::bench::run_airspace(
                f64::from(rate.unwrap_or(1000)),
                f64::from(seconds.unwrap_or(10)),
                connections.unwrap_or(8),
            )?;
            writeln!(out, "{report}")?;
            writeln!(out, "  ({} cores available, shared by the service and the client)", cores_available())?;
            let clean = report.errors == 0 && report.answered == report.requests;
            Ok(if clean { Outcome::Success } else { Outcome::Problems })
        }
        Command::Bench {
            drones,
            seconds,
            drones_per_shard,
            mavlink,
            recording,
            urban_gnss,
            urban_wind,
            cameras,
            bare,
            whole_stack,
            ground_truth_hz,
            compression,
            ground_stations,
            repeat,
            ..
        } => {
            use crate::bench::pairs::Comparison;
            if ground_stations && !(mavlink || whole_stack) {
                return Err(CliError::Failed(
                    "bench: --ground-stations listens to MAVLink telemetry: it needs --mavlink or --whole-stack".into(),
                ));
            }
            let comparison = match (mavlink, recording, urban_gnss, urban_wind, cameras) {
                _ if bare => Comparison::BareOnly,
                _ if whole_stack => Comparison::WholeStack,
                (true, ..) => Comparison::Mavlink,
                (_, Some(set), ..) => Comparison::Recording(set),
                (_, _, true, ..) => Comparison::UrbanGnss,
                (_, _, _, true, _) => Comparison::UrbanWind,
                (.., Some(size)) => Comparison::Cameras(size),
                _ => Comparison::None,
            };
            let setup = crate::bench::Setup {
                drones,
                seconds: seconds.unwrap_or(60),
                drones_per_shard,
                ground_truth_hz,
                compression: compression.as_deref().map(crate::bench::compression_named).transpose()?,
                ground_stations,
            };
            crate::bench::pairs::run_pairs(setup, comparison, repeat, out)
        }
        Command::Crd => {
            out.write_all(sadesim_crds::crd::all_crds_yaml().as_bytes())?;
            Ok(Outcome::Success)
        }
        Command::Archive { command } => archive_command(command, out),
        Command::Report { run_dir } if crate::sweep::is_sweep_folder(&run_dir) => {
            crate::sweep::rebuild_report(&run_dir).map_err(|e| CliError::Failed(e.to_string()))?;
            writeln!(out, "report: {}", run_dir.join(sadesim_evidence::sweep::SWEEP_HTML).display())?;
            Ok(Outcome::Success)
        }
        Command::Report { run_dir } => {
            let files = sadesim_evidence::report::write_report(&run_dir, sadesim_sources::assets::find_world)
                .map_err(|e| CliError::Failed(e.to_string()))?;
            writeln!(out, "report: {}", files.html.display())?;
            Ok(Outcome::Success)
        }
        Command::View { run, listen, rate } => view_cmd::view(&run, listen, rate, out),
        Command::Console(args) => console_cmd::console(args, out),
        Command::Manifests { files, namespace, kueue } => {
            let settings = sadesim_operator::k8s::children::ClusterSettings { kueue, ..Default::default() };
            for (i, file) in files.iter().enumerate() {
                let text = read_scenario(file)?;
                if i > 0 {
                    // One YAML stream: a document separator between files.
                    writeln!(out, "---")?;
                }
                sadesim_operator::k8s::manifests::write_manifests(&text, namespace.as_deref(), &settings, out)
                    .map_err(|e| CliError::Failed(format!("{}: {e}", file.display())))?;
            }
            Ok(Outcome::Success)
        }
        Command::Assets { command: AssetsCommand::Build { file, asset_cache, quiet } } => {
            assets_cmd::build(&file, asset_cache, quiet, out)
        }
        Command::Assets {
            command:
                AssetsCommand::Show {
                    file,
                    png,
                    svg,
                    asset_cache,
                    no_asset_cache,
                    quiet,
                    wind_slice_agl,
                    wind_png,
                    wind_area,
                },
        } => {
            let cache = if no_asset_cache { assets_cmd::Cache::Off } else { assets_cmd::Cache::At(asset_cache) };
            let wind = wind_slice_agl.map(|height_agl_m| assets_cmd::WindSliceArgs {
                height_agl_m,
                png: wind_png,
                area: wind_area,
            });
            assets_cmd::show(&file, &png, svg.as_deref(), cache, quiet, wind.as_ref(), out)
        }
        Command::Osm { file, origin, extent_m, geojson, glb, json } => {
            let targets = osm_cmd::Targets { geojson: geojson.as_deref(), glb: glb.as_deref() };
            osm_cmd::osm_file(&file, origin, extent_m, targets, json, out)
        }
        Command::Dem { file, origin, extent_m, at, json } => dem_cmd::dem_file(&file, origin, extent_m, &at, json, out),
        Command::Gnss { command: GnssCommand::Sky { file, at, time, mask_deg, json } } => {
            gnss_cmd::sky(&file, at, &time, mask_deg, json, out)
        }
        Command::Gnss { command: GnssCommand::Los { scenario, points, at_s, buildings } } => {
            gnss_cmd::los(&scenario, &points, at_s, buildings.as_deref(), out)
        }
        Command::Gnss { command: GnssCommand::Grid { scenario, out: dir, spacing_m, slice_s } } => {
            sky_grid_cmd::grid(&scenario, &dir, spacing_m, slice_s, out)
        }
        Command::Sweep(args) => sweep_cmd::sweep(args, out),
        Command::Operator(args) => {
            sadesim_operator::k8s::controller::run(args.options()).map_err(|e| CliError::Failed(e.to_string()))?;
            Ok(Outcome::Success)
        }
    }
}

/// CPU cores this process may use.
fn cores_available() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

/// "1 problem", "3 problems".
pub(crate) fn count(n: usize, noun: &str) -> String {
    if n == 1 { format!("1 {noun}") } else { format!("{n} {noun}s") }
}
