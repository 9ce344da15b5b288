//! The local runner (`sadesim run`): every role of a run in this process — world, shards
//! (one thread each), coordinator, recorder — with a progress bar, Ctrl-C handling and an
//! output folder that holds the evidence even when the run is interrupted.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use indicatif::{ProgressBar, ProgressStyle};
use sadesim_crds::SimulationRun;
use sadesim_crds::plan::RunPlan;
use sim_worker::coordinator::{self, CoordinatorError, RunObserver, ShardLink};
use sim_worker::events::Event;
use sim_worker::protocol::{DroneSnapshot, FleetCounts};
use sim_worker::record::{Recorder, RecorderOptions, RunSummary};
use sim_worker::transport;
use sim_worker::world::{World, WorldInputs};

use crate::planner::{self, PlanError};

mod workers;

/// How to run.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Folder under which `<run>/<UTC time>/` is created. Default: the archive URL's folder
    /// for `file://` URLs, else `runs`.
    pub out_root: Option<PathBuf>,
    /// Draw a progress bar (only on a terminal).
    pub progress: bool,
    /// Run the coordinator and every shard as `sim-worker` processes talking TCP, instead
    /// of threads in this process.
    pub processes: bool,
    /// The `sim-worker` binary for `processes` (default: `$SADESIM_WORKER`, else next to
    /// this executable).
    pub worker: Option<PathBuf>,
}

/// Why a run did not happen or did not finish.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The scenario asks for something this build cannot do yet.
    #[error("not supported yet: {0}")]
    NotSupported(String),
    #[error("failed to write the output folder {path}: {source}")]
    Output { path: String, source: std::io::Error },
    #[error("failed to start shard {shard}: {source}")]
    Shard { shard: u32, source: sim_worker::shard::ShardError },
    #[error(transparent)]
    Coordinator(#[from] CoordinatorError),
    /// A `sim-worker` process could not be started or failed.
    #[error("{0}")]
    Worker(String),
}

/// What a finished run reports.
#[derive(Debug)]
pub struct RunReport {
    pub out_dir: PathBuf,
    pub summary: RunSummary,
}

/// Refuses what the local runner cannot do yet, naming the field.
fn check_supported(plan: &RunPlan) -> Result<(), RunError> {
    let spec = &plan.spec;
    let external: Vec<&str> = spec.fleet.iter().filter(|g| g.mission.is_none()).map(|g| g.name.as_str()).collect();
    if !external.is_empty() {
        return Err(RunError::NotSupported(format!(
            "spec.fleet: groups {} are flown by an external MAVLink pilot (spec.pilot), which arrives with the MAVLink endpoints; give each group a `mission` to fly it with the built-in pilot",
            external.join(", ")
        )));
    }
    if let Some(i) = spec.fleet.iter().position(|g| g.geofence.is_some()) {
        return Err(RunError::NotSupported(format!(
            "spec.fleet[{i}].geofence: the built-in geofence arrives with the airspace authority; remove it for now"
        )));
    }
    if spec.rendering().enabled {
        return Err(RunError::NotSupported(
            "spec.rendering.enabled: the renderer is not built yet; set it to false".into(),
        ));
    }
    if let Some(a) = &spec.archive
        && !a.url.starts_with("file://")
    {
        return Err(RunError::NotSupported(format!(
            "spec.archive.url {:?}: local runs archive to a folder (file://) until object storage archives arrive",
            a.url
        )));
    }
    Ok(())
}

/// `YYYYMMDDTHHMMSSZ` for a UNIX time (UTC), for folder names that sort by time.
fn utc_stamp(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).unwrap_or_default().as_secs();
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}{month:02}{day:02}T{:02}{:02}{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

fn out_root(plan: &RunPlan, options: &RunOptions) -> PathBuf {
    if let Some(root) = &options.out_root {
        return root.clone();
    }
    match plan.spec.archive.as_ref().and_then(|a| a.url.strip_prefix("file://")) {
        Some(path) if !path.is_empty() => PathBuf::from(path),
        _ => PathBuf::from("runs"),
    }
}

fn write_json(dir: &Path, name: &str, value: &impl serde::Serialize) -> Result<(), RunError> {
    let path = dir.join(name);
    let bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| RunError::Output { path: path.display().to_string(), source: std::io::Error::other(e) })?;
    std::fs::write(&path, bytes).map_err(|source| RunError::Output { path: path.display().to_string(), source })
}

/// Shows progress and forwards every window to the recorder.
struct Progress<'a> {
    recorder: &'a mut Recorder,
    bar: ProgressBar,
    duration_s: f64,
    started: std::time::Instant,
}

impl RunObserver for Progress<'_> {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), String> {
        self.recorder.on_window(time_s, drones, events)?;
        if !self.bar.is_hidden() {
            show_progress(&self.bar, time_s, self.duration_s, self.started, FleetCounts::of(drones));
        }
        Ok(())
    }
}

/// The progress bar's position and message: sim time, real-time factor, fleet counts.
fn show_progress(bar: &ProgressBar, time_s: f64, duration_s: f64, started: std::time::Instant, c: FleetCounts) {
    let rtf = time_s / started.elapsed().as_secs_f64().max(1e-9);
    bar.set_position((time_s / duration_s * 1000.0) as u64);
    bar.set_message(format!(
        "sim {time_s:7.1}/{duration_s:.0} s  RTF {rtf:5.1}  airborne {} on ground {} crashed {}",
        c.airborne, c.on_ground, c.crashed
    ));
}

/// Runs a scenario locally.
///
/// # Errors
/// See [`RunError`]. When the coordinator fails mid-run, the files written so far stay in
/// the output folder.
pub fn run_local(run: &SimulationRun, options: &RunOptions, stop: Arc<AtomicBool>) -> Result<RunReport, RunError> {
    let plan = planner::plan(run)?;
    check_supported(&plan)?;
    let base = out_root(&plan, options).join(&plan.run.name);
    let stamp = utc_stamp(SystemTime::now());
    // Two runs started within the same second get `-2`, `-3`, ... rather than mixing files.
    let out_dir = (1..)
        .map(|n| if n == 1 { base.join(&stamp) } else { base.join(format!("{stamp}-{n}")) })
        .find(|d| !d.exists())
        .expect("some suffix is free");
    std::fs::create_dir_all(&out_dir)
        .map_err(|source| RunError::Output { path: out_dir.display().to_string(), source })?;
    write_json(&out_dir, "plan.json", &plan)?;

    let world = Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])));
    write_json(&out_dir, "world.json", world.stats())?;
    let bar = if options.progress { ProgressBar::new(1000) } else { ProgressBar::hidden() };
    bar.set_style(ProgressStyle::with_template("{bar:30.cyan/blue} {percent:>3}% {msg}").expect("a valid template"));
    bar.enable_steady_tick(Duration::from_millis(200));
    let summary = if options.processes {
        workers::run(&plan, options.worker.as_deref(), &out_dir, &bar, &stop)
    } else {
        run_threads(&plan, world, &out_dir, &bar, &stop)
    };
    bar.finish_and_clear();
    Ok(RunReport { out_dir, summary: summary? })
}

/// Every role in this process: one thread per shard, the coordinator on this thread.
fn run_threads(
    plan: &RunPlan,
    world: Arc<World>,
    out_dir: &Path,
    bar: &ProgressBar,
    stop: &AtomicBool,
) -> Result<RunSummary, RunError> {
    let mut links: Vec<Box<dyn ShardLink>> = Vec::new();
    let mut threads = Vec::new();
    for shard in &plan.shards {
        let (link, handle) = transport::spawn_thread(plan, shard.index, world.clone())
            .map_err(|source| RunError::Shard { shard: shard.index, source })?;
        links.push(Box::new(link));
        threads.push(handle);
    }
    let output_err = |source| RunError::Output { path: out_dir.display().to_string(), source };
    let mut recorder = Recorder::create(out_dir, plan, RecorderOptions::default()).map_err(output_err)?;
    let mut progress = Progress {
        recorder: &mut recorder,
        bar: bar.clone(),
        duration_s: plan.duration_s,
        started: std::time::Instant::now(),
    };
    let outcome = coordinator::run(plan, &mut links, &mut progress, stop);
    drop(links);
    for t in threads {
        let _ = t.join();
    }
    recorder.finish(&outcome?).map_err(output_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_stamps_match_known_dates() {
        assert_eq!(utc_stamp(UNIX_EPOCH), "19700101T000000Z");
        assert_eq!(utc_stamp(UNIX_EPOCH + Duration::from_secs(951_782_400)), "20000229T000000Z");
        assert_eq!(utc_stamp(UNIX_EPOCH + Duration::from_secs(1_795_302_123)), "20261121T230203Z");
    }
}
