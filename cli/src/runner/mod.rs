//! The local runner (`sadesim run`): every role of a run in this process — world, shards
//! (one thread each), coordinator, recorder, the pilot as a child process — with a
//! progress bar, Ctrl-C handling and an output folder that holds the evidence even when
//! the run is interrupted.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use indicatif::{ProgressBar, ProgressStyle};
use sadesim_crds::SimulationRun;
use sadesim_crds::fleet::Credential;
use sadesim_crds::plan::RunPlan;
use sadesim_engine::coordinator::{CoordinatorError, ObserverError, PilotHold, RunObserver, ShardLink};
use sadesim_engine::events::{EndReason, Event, EventKind};
use sadesim_engine::mavlink::signing::SecretKey;
use sadesim_engine::protocol::{DroneSnapshot, FleetCounts};
use sadesim_evidence::archive::is_object_store;
use sadesim_evidence::finish::{Finished, RunAddress, finish_run};
use sadesim_sources::assets::{AssetsError, AssetsOutcome, ensure_bundle};
use sadesim_sources::wind::WindOutcome;
use sadesim_world::World;
use sim_worker::airspace::runtime::Airspace;
use sim_worker::conduct::{ConductError, Watchers, conduct};
use sim_worker::mavlink::router::RouterHandle;
use sim_worker::record::RunSummary;
use sim_worker::roles::router::RouterOptions;
use sim_worker::shard_io::MavlinkOptions;
use sim_worker::transport;

use sadesim_planner::{self as planner, Addressing, PlanError};

pub mod pilot;
mod workers;

use pilot::{PilotError, PilotRecord, Supervisor};

/// How to run.
#[derive(Clone, Debug)]
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
    /// The scenario file: `spec.pilot` starts in its folder. `None` (read from stdin): the
    /// current directory.
    pub scenario: Option<PathBuf>,
    /// Start `spec.pilot.command` when the pilots are released (default true). False
    /// (`--no-pilot`): the user attaches a pilot, SDK script or ground station by hand and
    /// the run lasts until `duration` or Ctrl-C.
    pub start_pilot: bool,
    /// Serve a MAVLink endpoint per drone (default true; `--no-mavlink` turns it off, for
    /// runs of scripted missions that need no ports). Groups without a `mission` are flown
    /// over MAVLink, so they are refused without it. The shards read this option.
    pub mavlink: bool,
    /// The asset cache (an archive URL; `sadesim run` uses the user cache folder,
    /// `sadesim_sources::assets::local_cache_url`): the world is loaded from the bundle of
    /// its key when one verifies there, else built and stored there, and `--processes`
    /// shards load it from there. `None` (`--no-asset-cache`): built in memory, stored
    /// nowhere, and every shard process builds it again.
    pub asset_cache: Option<String>,
    /// The run folder itself (created; it must not exist), instead of
    /// `<out_root>/<run>/<UTC time>/` (`sadesim sweep` puts each run in its sweep's folder).
    pub run_dir: Option<PathBuf>,
    /// Moves every MAVLink port of the run up by this much (`planner::offset_ports`), so
    /// runs can fly at once on this machine; the fleet file names the moved ports.
    pub port_offset: u16,
    /// The document `SADESIM_SCENARIO` names, when it is not `scenario` (a sweep's run: its
    /// own expanded document, while the pilot starts in the sweep file's folder).
    pub scenario_document: Option<PathBuf>,
    /// Told where the run writes and how it advances (`sadesim console` shows its runs
    /// with it). In-process runs only: `processes` runs do not call it.
    pub watch: Option<Arc<dyn RunWatch>>,
    /// Overrides `spec.pilot.connectTimeoutS` (`--pilot-connect-timeout`): the longest wall
    /// time, seconds, simulated time holds at the release for the pilot to connect.
    pub pilot_connect_timeout_s: Option<u32>,
}

/// Someone following a run as it goes, beside the progress bar.
pub trait RunWatch: Send + Sync {
    /// The run folder exists and the run is about to start; `view` is the live view's URL
    /// when `spec.rendering.enabled`.
    fn started(&self, out_dir: &Path, view: Option<String>);
    /// A window of simulated time was recorded: the time reached, the run's length and the
    /// fleet's counts.
    fn window(&self, time_s: f64, duration_s: f64, counts: FleetCounts);
}

impl std::fmt::Debug for dyn RunWatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RunWatch")
    }
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            out_root: None,
            progress: false,
            processes: false,
            worker: None,
            scenario: None,
            start_pilot: true,
            mavlink: true,
            asset_cache: None,
            run_dir: None,
            port_offset: 0,
            scenario_document: None,
            watch: None,
            pilot_connect_timeout_s: None,
        }
    }
}

/// Why a run did not happen or did not finish.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Plan(#[from] PlanError),
    #[error(transparent)]
    World(#[from] sadesim_sources::world::WorldReadError),
    #[error(transparent)]
    Assets(#[from] sadesim_sources::assets::AssetsError),
    #[error(transparent)]
    Sky(#[from] sadesim_sources::gnss::SkyReadError),
    /// The scenario asks for something this build cannot do yet.
    #[error("not supported yet: {0}")]
    NotSupported(String),
    /// A signing passphrase that only Kubernetes can resolve.
    #[error(
        "spec.groundStations.signing.key.secretKeyRef: not supported locally (Secret {secret:?} lives in Kubernetes); give the passphrase as `value` for local runs"
    )]
    SigningSecretRef { secret: String },
    /// Groups flown over MAVLink in a run without MAVLink endpoints (`--no-mavlink`).
    #[error(
        "spec.fleet: groups {groups} have no mission, so the pilot (spec.pilot) flies them over MAVLink: external pilots need the MAVLink endpoints; drop --no-mavlink"
    )]
    NeedsMavlink { groups: String },
    /// The pilot could not be prepared or started.
    #[error(transparent)]
    Pilot(#[from] PilotError),
    #[error("failed to write the output folder {path}: {source}")]
    Output { path: String, source: std::io::Error },
    #[error("failed to start shard {shard}: {source}")]
    Shard { shard: u32, source: sim_worker::shard_io::StartError },
    #[error(transparent)]
    Coordinator(#[from] CoordinatorError),
    /// A `sim-worker` process could not be started or failed.
    #[error("{0}")]
    Worker(String),
    /// `manifest.json` could not be written, or `spec.archive.url` cannot be opened or the
    /// upload to it failed.
    #[error("archive: {0}")]
    Archive(#[from] sadesim_evidence::archive::ArchiveError),
}

/// What a finished run reports.
#[derive(Debug)]
pub struct RunReport {
    pub out_dir: PathBuf,
    pub summary: RunSummary,
    /// What happened to `spec.pilot` (also in `pilot.json`); `None` when no pilot was to
    /// be started (no `spec.pilot`, or `--no-pilot`).
    pub pilot: Option<PilotRecord>,
    /// URL of the uploaded run folder when `spec.archive.url` is an object store.
    pub archive: Option<String>,
    /// Why `report.html` could not be written (also printed as a warning and kept in
    /// `report-error.txt`); `None` when the report was written.
    pub report_error: Option<String>,
    /// Whether the world came from the asset cache or was built into it (`None` without
    /// a cache).
    pub assets: Option<AssetsOutcome>,
}

/// The run's world: from the asset cache `cache` when set (a verified bundle of the run's
/// key is loaded; else the world is built and stored there), else built in memory. The
/// world's files are already read into `data`. With `progress`, a spinner says what it is
/// doing (looking in the cache, building, storing).
///
/// # Errors
/// The world cannot be built from `data` (a DEM not covering the square), or the cache
/// cannot be read or written.
pub fn run_world(
    run: &SimulationRun,
    data: &sadesim_world::WorldData,
    cache: Option<&str>,
    progress: bool,
) -> Result<(Option<AssetsOutcome>, World), RunError> {
    let build = || World::build(&sadesim_world::WorldInputs::from_spec(&run.spec, &[]), data);
    let Some(cache) = cache else {
        return Ok((None, build().map_err(PlanError::from)?));
    };
    let key = planner::asset_key(run, data)?;
    let spinner = if progress { ProgressBar::new_spinner() } else { ProgressBar::hidden() };
    spinner.set_message(format!("world assets {}: looking in {cache}", &key[..12]));
    spinner.enable_steady_tick(Duration::from_millis(120));
    let scratch = std::env::temp_dir().join(format!("sadesim-assets-{}", std::process::id()));
    let outcome = ensure_bundle(&key, run.spec.origin.geo(), cache, &scratch, || {
        spinner.set_message(format!("world assets {}: building", &key[..12]));
        build().map_err(|e| AssetsError::World(e.into()))
    });
    spinner.finish_and_clear();
    let _ = std::fs::remove_dir_all(&scratch);
    let (outcome, world) = outcome?;
    Ok((Some(outcome), world))
}

/// The urban wind field of a run that has one: from the asset cache (made and stored on a
/// miss, with a progress bar: every sector of the built-in model, the run direction's of
/// OpenFOAM), or without a cache only the sectors of the run's direction, made in memory
/// (an imported OpenFOAM case is always read from its folder). `None` for a run without
/// one; the cache's outcome with a cache.
///
/// # Errors
/// The cache cannot be opened or written; OpenFOAM or an imported case fails (naming the
/// program or file).
pub fn run_wind(
    plan: &RunPlan,
    world: &World,
    cache: Option<&str>,
    progress: bool,
) -> Result<Option<(Option<WindOutcome>, sadesim_wind::UrbanWindField)>, RunError> {
    use sadesim_wind::request::{FieldModel, wind_request};
    let Some(request) = wind_request(&plan.spec, world) else { return Ok(None) };
    let total = request.sectors_built().len() as u64;
    let bar = if progress { ProgressBar::new(total) } else { ProgressBar::hidden() };
    bar.set_style(ProgressStyle::with_template("{bar:30.cyan/blue} {pos}/{len} {msg}").expect("a valid template"));
    let scratch = std::env::temp_dir().join(format!("sadesim-wind-{}", std::process::id()));
    let what = match request.model {
        FieldModel::Diagnostic => format!("computing {total} direction sectors"),
        FieldModel::OpenFoam => format!("running OpenFOAM for {total} direction sector(s) (minutes each)"),
        FieldModel::Imported(_) => "reading the OpenFOAM case".to_string(),
    };
    let build = || {
        bar.set_message(format!("urban wind: {what}"));
        sim_worker::wind_field::build_field(world, &request, &scratch, |done, _| bar.set_position(u64::from(done)))
            .map_err(|e| AssetsError::WindBuild(e.to_string()))
    };
    let made = match (cache, &request.model) {
        (_, FieldModel::Imported(_)) | (None, FieldModel::OpenFoam) => build().map(|field| (None, field)),
        (None, FieldModel::Diagnostic) => Ok((
            None,
            sadesim_engine::env::urban_wind_field(&plan.spec, world).expect("the run wants the built-in field"),
        )),
        (Some(cache), _) => {
            bar.set_message(format!("urban wind: looking in {cache}"));
            sadesim_sources::wind::ensure_wind(
                &plan.asset_cache_key,
                &request,
                plan.spec.origin.geo(),
                cache,
                &scratch,
                build,
            )
            .map(|(outcome, field)| (Some(outcome), field))
        }
    };
    bar.finish_and_clear();
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(Some(made?))
}

/// Refuses what the local runner cannot do (yet, or with these options), naming the field.
fn check_supported(plan: &RunPlan, options: &RunOptions) -> Result<(), RunError> {
    let spec = &plan.spec;
    let external: Vec<&str> = spec.fleet.iter().filter(|g| g.mission.is_none()).map(|g| g.name.as_str()).collect();
    if !external.is_empty() && !options.mavlink {
        return Err(RunError::NeedsMavlink { groups: external.join(", ") });
    }
    if spec.rendering().enabled && !sim_worker::view::server::has_three() {
        return Err(RunError::NotSupported(format!("spec.rendering.enabled: {}", sim_worker::view::server::NO_THREE)));
    }
    // Object stores are written at the end of the run: a bad URL or store configuration
    // (credentials, account) fails now, not after the run.
    if let Some(a) = &spec.archive {
        sadesim_evidence::archive::Archive::open(&a.url)?;
    }
    Ok(())
}

/// What the scenario asks that only a cluster does, said rather than silently dropped: the
/// same file runs locally and on Kubernetes (GitOps), so these fields are valid here but
/// have no local effect.
fn cluster_only_notices(plan: &RunPlan) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(queue) = &plan.spec.queue {
        out.push(format!(
            "spec.queue: the Kueue LocalQueue {queue:?} admits the run on Kubernetes only; this local run starts at once"
        ));
    }
    if let Some(stations) = plan.spec.ground_stations.as_ref().filter(|s| !s.allow_from.is_empty()) {
        out.push(format!(
            "spec.groundStations.allowFrom: the {} range(s) open the run's NetworkPolicy on Kubernetes only; locally every service listens on 127.0.0.1",
            stations.allow_from.len()
        ));
    }
    if let Some(gpus) = plan.spec.rendering().gpus {
        out.push(format!(
            "spec.rendering.gpus: the {gpus} GPU(s) are asked for the pod that renders the onboard cameras on Kubernetes only; locally they render on this machine's Vulkan device (named below)"
        ));
    }
    out
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

/// Shows progress, and starts and watches the pilot (the conductor records every window
/// before it).
struct Progress<'a> {
    bar: ProgressBar,
    duration_s: f64,
    started: std::time::Instant,
    pilot: Option<&'a mut Supervisor>,
    /// Set when the pilot could not be started: the run ends (and then fails) with it.
    pilot_error: Option<PilotError>,
    /// The pilot exited and `onExit` is `endRun`.
    pilot_exited: bool,
    /// [`RunOptions::watch`].
    watch: Option<Arc<dyn RunWatch>>,
}

impl RunObserver for Progress<'_> {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        // The conductor recorded (and flushed) the window before: a pilot started now finds
        // `pilotsReleased` in events.jsonl.
        if let Some(pilot) = self.pilot.as_deref_mut() {
            pilot.advance(time_s);
            if events.iter().any(|e| matches!(e.kind, EventKind::PilotsReleased))
                && let Err(e) = pilot.start()
            {
                self.pilot_error = Some(e);
            }
            self.pilot_exited = pilot.poll();
        }
        if let Some(watch) = &self.watch {
            watch.window(time_s, self.duration_s, sadesim_engine::protocol::fleet_counts(drones));
        }
        if !self.bar.is_hidden() {
            show_progress(
                &self.bar,
                time_s,
                self.duration_s,
                self.started,
                sadesim_engine::protocol::fleet_counts(drones),
            );
        }
        Ok(())
    }

    fn stop_reason(&mut self) -> Option<EndReason> {
        pilot::end_reason(self.pilot_error.is_some(), self.pilot_exited)
    }

    /// Held at the release for the pilot: whether it exited meanwhile, and the bar says so.
    fn on_hold(&mut self, waited: Duration) {
        if let Some(pilot) = self.pilot.as_deref_mut() {
            self.pilot_exited = pilot.poll();
        }
        if !self.bar.is_hidden() {
            self.bar.set_message(format!("waiting for the pilot to connect ({:.0} s)", waited.as_secs_f64()));
        }
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
    let world_data = sadesim_sources::world::read_data(&run.spec)?;
    let (assets, world) = run_world(run, &world_data, options.asset_cache.as_deref(), options.progress)?;
    let mut plan = planner::plan_in(run, &world_data, &world)?;
    planner::offset_ports(&mut plan, options.port_offset).map_err(|top| {
        RunError::NotSupported(format!("MAVLink ports moved up by {} would reach {top}", options.port_offset))
    })?;
    check_supported(&plan, options)?;
    // Into the plan (plan.json), which the coordinator process of `--processes` reads too.
    if let (Some(s), Some(pilot)) = (options.pilot_connect_timeout_s, plan.spec.pilot.as_mut()) {
        pilot.connect_timeout_s = Some(s);
    }
    // The routers' passphrase is resolved before anything is written, like the pilot's
    // credentials; only runs with MAVLink have routers.
    let signing = if options.mavlink { signing_passphrase(&plan)? } else { None };
    for notice in cluster_only_notices(&plan) {
        eprintln!("note: {notice}");
    }
    if signing.is_some() {
        eprintln!(
            "note: spec.groundStations.signing: the MAVLink routers take only MAVLink 2 frames signed with the scenario's passphrase from ground stations, and sign what they send them"
        );
    }
    // The orbit file is read before anything is written: a bad one fails the run at once.
    let sky = sadesim_sources::gnss::load_sky(&plan.spec)?.map(Arc::new);
    let out_dir = match &options.run_dir {
        Some(dir) if dir.exists() => {
            let source = std::io::Error::new(std::io::ErrorKind::AlreadyExists, "the run folder exists already");
            return Err(RunError::Output { path: dir.display().to_string(), source });
        }
        Some(dir) => dir.clone(),
        None => {
            let base = out_root(&plan, options).join(&plan.run.name);
            let stamp = utc_stamp(SystemTime::now());
            // Two runs started within the same second get `-2`, `-3`, ... rather than mixing
            // files.
            (1..)
                .map(|n| if n == 1 { base.join(&stamp) } else { base.join(format!("{stamp}-{n}")) })
                .find(|d| !d.exists())
                .expect("some suffix is free")
        }
    };
    // Everything about the pilot that can be wrong is found before the run starts.
    let launch = match (&plan.spec.pilot, options.start_pilot) {
        (Some(p), true) => {
            let mut launch = pilot::Launch::prepare(&plan, p, options.scenario.as_deref(), &out_dir)?;
            if let Some(document) = &options.scenario_document {
                launch.set_scenario_document(document)?;
            }
            Some(launch)
        }
        _ => None,
    };
    std::fs::create_dir_all(&out_dir)
        .map_err(|source| RunError::Output { path: out_dir.display().to_string(), source })?;
    write_json(&out_dir, sadesim_crds::outcome::run_folder::PLAN, &plan)?;
    // The airspace authority answers before the pilot starts. In `--processes` runs the
    // coordinator process serves it instead, on the planned port or a free one.
    let mut airspace = Airspace::new(&plan, &|key| std::env::var(key).ok());
    let airspace_addr = match options.processes {
        true => None,
        false => Some(serve_airspace(&mut airspace, &plan)?),
    };

    // With a cache the field is stored there for the worker processes to load; without one
    // they compute it themselves.
    let wind = if options.processes && options.asset_cache.is_none() {
        None
    } else {
        run_wind(&plan, &world, options.asset_cache.as_deref(), options.progress)?.map(|(_, field)| Arc::new(field))
    };
    let world = Arc::new(world);
    write_json(&out_dir, "world.json", world.stats())?;
    // The cameras and the live view are up before the run starts, so a browser opened on
    // the printed URL sees the drones from the first window. With --processes the
    // coordinator process serves them (`--view-bind`), as its pod does.
    let mut watchers = match options.processes {
        false => {
            let bind = std::net::SocketAddr::from(([127, 0, 0, 1], plan.services.renderer_http));
            Watchers::start(&plan, &world, bind).map_err(RunError::NotSupported)?
        }
        true => Watchers::default(),
    };
    let mut supervisor = launch.map(Supervisor::new);
    // In-process servers listen already; a coordinator process says where its own listen
    // (`workers::run` writes the fleet file then).
    if let Some(airspace_addr) = airspace_addr {
        let view = watchers.live.as_ref().map(|v| v.server.addr);
        write_fleet_file(&plan, &out_dir, airspace_addr, view, supervisor.as_mut())?;
    }
    if let Some(watch) = &options.watch {
        watch.started(&out_dir, watchers.live.as_ref().map(|v| v.server.url()));
    }
    let bar = if options.progress { ProgressBar::new(1000) } else { ProgressBar::hidden() };
    bar.set_style(ProgressStyle::with_template("{bar:30.cyan/blue} {percent:>3}% {msg}").expect("a valid template"));
    bar.enable_steady_tick(Duration::from_millis(200));
    let summary = if options.processes {
        let local = |port| std::net::SocketAddr::from(([127, 0, 0, 1], port));
        workers::run(
            &plan,
            options.worker.as_deref(),
            options.mavlink.then_some(signing.as_deref()),
            &out_dir,
            &bar,
            &stop,
            supervisor.as_mut(),
            local(plan.services.airspace_http),
            assets.as_ref().map(AssetsOutcome::url),
            plan.spec.rendering().enabled.then(|| local(plan.services.renderer_http)),
        )
    } else {
        let surroundings = sadesim_engine::shard::Surroundings { world: world.clone(), sky, wind };
        let signing = signing.as_deref().map(SecretKey::from_passphrase);
        let routers = options.mavlink.then_some(signing);
        let inputs = ShardInputs { surroundings, routers, watchers: &mut watchers, watch: options.watch.clone() };
        run_threads(&plan, inputs, &out_dir, &bar, &stop, supervisor.as_mut(), &mut airspace)
    };
    bar.finish_and_clear();
    // The run is over, whatever its end: stop a pilot still running and record it.
    let record = supervisor.as_mut().map(Supervisor::finish);
    if let Some(r) = &record {
        let written = write_json(&out_dir, pilot::RECORD_FILE, r);
        if summary.is_ok() {
            written?;
        }
    }
    // How the pilot ended goes into summary.json, and an end `spec.pilot.expectedExit`
    // does not allow fails the verdict; before the report and the manifest read it.
    let mut summary = summary;
    if let (Ok(summary), Some(r)) = (&mut summary, &record) {
        judge_pilot(summary, r, &out_dir)?;
    }
    // The end of every run, as the coordinator pod does it (DESIGN §8): report, manifest,
    // and the upload when `spec.archive.url` is an object store (a folder archive holds the
    // run folder already). The report cannot lose the run's files: a failure is a warning.
    let uid = out_dir.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
    let address = RunAddress { namespace: &plan.run.namespace, run: &plan.run.name, uid: &uid };
    let upload_to = plan.spec.archive.as_ref().map(|a| a.url.as_str()).filter(|url| is_object_store(url));
    let Finished { report_error, archived } = finish_run(&out_dir, address, upload_to, options.progress, Some(&world));
    if let Some(e) = &report_error {
        eprintln!("warning: the run's report was not written: {e}");
    }
    let summary = summary?;
    let report_error = report_error.map(|e| e.to_string());
    Ok(RunReport { out_dir, summary, pilot: record, archive: archived?.map(|a| a.url), report_error, assets })
}

/// Puts the pilot's outcome into `summary` (`pilot`), adds a failed expectation to its
/// verdict (when the criteria were judged), and writes `summary.json` again.
fn judge_pilot(summary: &mut RunSummary, record: &PilotRecord, out_dir: &Path) -> Result<(), RunError> {
    let outcome = pilot::outcome(record, out_dir);
    if let Some(verdict) = summary.verdict.as_mut() {
        outcome.judge_into(verdict);
    }
    summary.pilot = Some(outcome);
    write_json(out_dir, sadesim_crds::outcome::run_folder::SUMMARY, summary)
}

/// Serves the airspace API on 127.0.0.1 at the planned port, or on a free port when that is
/// taken (another run on this machine): the fleet file gives pilots the address either way.
fn serve_airspace(airspace: &mut Airspace, plan: &RunPlan) -> Result<std::net::SocketAddr, RunError> {
    let planned = std::net::SocketAddr::from(([127, 0, 0, 1], plan.services.airspace_http));
    sim_worker::http_thread::or_free_port(planned, |addr| airspace.serve(addr))
        .map_err(|e| RunError::Worker(format!("airspace API: cannot listen on 127.0.0.1: {e}")))
}

/// Writes the fleet file for every run: pilots started by hand and ground stations use it
/// too. It is written once the servers listen, as their addresses can differ from the
/// plan's ports: `airspace` serves the airspace API, `view` the live view, which serves the
/// onboard cameras' frames in a run with cameras. The pilot, started later, gets the
/// cameras' URL in its environment.
fn write_fleet_file(
    plan: &RunPlan,
    out_dir: &Path,
    airspace: std::net::SocketAddr,
    view: Option<std::net::SocketAddr>,
    supervisor: Option<&mut Supervisor>,
) -> Result<(), RunError> {
    let mut fleet = planner::fleet_file(plan, &Addressing::Local { host: "127.0.0.1".into() });
    fleet.airspace_url = format!("http://{airspace}");
    if let Some(url) = view.filter(|_| plan.spec.has_cameras()).map(|addr| format!("http://{addr}/cameras")) {
        planner::add_camera_urls(&mut fleet, plan, &url);
        if let Some(s) = supervisor {
            s.set_cameras_url(&url);
        }
    }
    write_json(out_dir, pilot::FLEET_FILE, &fleet)
}

/// The passphrase of `spec.groundStations.signing` for the routers of a local run (`None`:
/// no signing).
///
/// # Errors
/// [`RunError::SigningSecretRef`]: a Secret's key, which only a cluster resolves.
fn signing_passphrase(plan: &RunPlan) -> Result<Option<String>, RunError> {
    match plan.spec.ground_stations.as_ref().and_then(|g| g.signing.as_ref()).map(|s| &s.key) {
        None => Ok(None),
        Some(Credential::Value(passphrase)) => Ok(Some(passphrase.clone())),
        Some(Credential::SecretKeyRef(r)) => Err(RunError::SigningSecretRef { secret: r.name.clone() }),
    }
}

/// The MAVLink routers of a local run: one per segment, on 127.0.0.1, drones on 127.0.0.1,
/// signing on the GCS side with `signing`.
fn start_routers(plan: &RunPlan, signing: Option<&SecretKey>) -> Result<Vec<RouterHandle>, RunError> {
    let options = |segment| RouterOptions {
        segment,
        bind: std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
        drone_host: sim_worker::roles::router::DEFAULT_DRONE_HOST.to_string(),
        signing: signing.cloned(),
    };
    plan.segments
        .iter()
        .map(|s| {
            let config = sim_worker::roles::router::config(plan, &options(s.index), &mut |host| {
                host.parse().map_err(std::io::Error::other)
            })
            .map_err(|e| RunError::Worker(format!("MAVLink router of segment {}: {e}", s.index)))?;
            sim_worker::mavlink::router::start(config)
                .map_err(|e| RunError::Worker(format!("MAVLink router of segment {}: {e}", s.index)))
        })
        .collect()
}

/// What the in-process roles fly in and with, and who watches.
struct ShardInputs<'a> {
    /// The world, the GNSS sky and the urban wind field.
    surroundings: sadesim_engine::shard::Surroundings,
    /// Whether the drones get MAVLink endpoints and the segments routers: `None` for
    /// neither, else the routers' signing key (`None` inside: no signing).
    routers: Option<Option<SecretKey>>,
    /// The onboard cameras and the live view (served until the runner is done).
    watchers: &'a mut Watchers,
    /// [`RunOptions::watch`].
    watch: Option<Arc<dyn RunWatch>>,
}

/// Every role in this process: one thread per shard, the MAVLink routers on their own
/// threads, and the run conducted on this thread (`sim_worker::conduct`).
fn run_threads(
    plan: &RunPlan,
    inputs: ShardInputs<'_>,
    out_dir: &Path,
    bar: &ProgressBar,
    stop: &AtomicBool,
    pilot: Option<&mut Supervisor>,
    airspace: &mut Airspace,
) -> Result<RunSummary, RunError> {
    let ShardInputs { surroundings, routers, watchers, watch } = inputs;
    let mut links: Vec<Box<dyn ShardLink>> = Vec::new();
    let mut threads = Vec::new();
    let mavlink_options = routers.is_some().then(MavlinkOptions::local);
    let _routers = match &routers {
        Some(signing) => start_routers(plan, signing.as_ref())?,
        None => Vec::new(),
    };
    for shard in &plan.shards {
        let (link, handle) = transport::spawn_thread(plan, shard.index, &surroundings, mavlink_options.as_ref())
            .map_err(|source| RunError::Shard { shard: shard.index, source })?;
        links.push(Box::new(link));
        threads.push(handle);
    }
    let mut progress = Progress {
        bar: bar.clone(),
        duration_s: plan.duration_s,
        started: std::time::Instant::now(),
        pilot,
        pilot_error: None,
        pilot_exited: false,
        watch,
    };
    // Each shard thread's CPU time stepping its drones; a thread that panicked or lost the
    // coordinator before `Stop` has none (the run then failed).
    let shard_cpu = || threads.into_iter().map(|t| t.join().ok().flatten()).collect::<Option<Vec<f64>>>();
    let world = &surroundings.world;
    // A pilot flying over MAVLink: simulated time waits at the release until it connects.
    let hold = progress.pilot.is_some().then(|| routers.as_ref().and(PilotHold::for_plan(plan))).flatten();
    let conducted =
        conduct(plan, world, links, airspace, watchers, out_dir, stop, &mut progress, hold.as_ref(), shard_cpu);
    let summary = match conducted {
        Ok(summary) => summary,
        Err(ConductError::RunFailed { failure, closed }) => {
            if let Err(e) = closed {
                eprintln!("writing the run's files into {} after the failure failed too: {e}", out_dir.display());
            }
            return Err(CoordinatorError::RunFailed(failure).into());
        }
        Err(ConductError::Record(source)) => {
            return Err(RunError::Output { path: out_dir.display().to_string(), source });
        }
        Err(ConductError::Coordinator(e)) => return Err(e.into()),
    };
    // The run ended cleanly (`pilotFailed`) and its files are complete; it still failed.
    match progress.pilot_error.take() {
        Some(e) => Err(e.into()),
        None => Ok(summary),
    }
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

    #[test]
    fn a_queue_is_said_to_apply_on_kubernetes_only() {
        use sadesim_crds::fixtures::RunBuilder;
        let plan_with = |queue: Option<&str>| {
            let run = RunBuilder::test().with(|r| r.spec.queue = queue.map(String::from)).build();
            sadesim_planner::plan(&run).unwrap()
        };
        let notices = cluster_only_notices(&plan_with(Some("team-a")));
        assert_eq!(notices.len(), 1);
        assert!(notices[0].starts_with("spec.queue: the Kueue LocalQueue \"team-a\""), "{notices:?}");
        assert!(cluster_only_notices(&plan_with(None)).is_empty());
    }

    #[test]
    fn a_secret_signing_key_is_refused_locally_naming_the_field() {
        use sadesim_crds::fixtures::RunBuilder;
        use sadesim_crds::fleet::SecretKeyRef;
        use sadesim_crds::ground_stations::{GroundStations, Signing};
        let plan_with = |key: Option<Credential>| {
            let run = RunBuilder::test()
                .with(|r| {
                    let signing = key.map(|key| Signing { key });
                    r.spec.ground_stations = Some(GroundStations { allow_from: vec![], signing });
                })
                .build();
            sadesim_planner::plan(&run).unwrap()
        };
        let secret = Credential::SecretKeyRef(SecretKeyRef { name: "gcs-signing".into(), key: "passphrase".into() });
        let err = signing_passphrase(&plan_with(Some(secret))).unwrap_err().to_string();
        assert!(err.starts_with("spec.groundStations.signing.key.secretKeyRef: not supported locally"), "{err}");
        assert!(err.contains("\"gcs-signing\"") && err.contains("`value`"), "{err}");
        let inline = signing_passphrase(&plan_with(Some(Credential::Value("a passphrase".into())))).unwrap();
        assert_eq!(inline.as_deref(), Some("a passphrase"));
        assert_eq!(signing_passphrase(&plan_with(None)).unwrap(), None);
    }

    #[test]
    fn gpus_for_the_renderer_are_said_to_apply_on_kubernetes_only() {
        use sadesim_crds::fixtures::RunBuilder;
        use sadesim_crds::run::Rendering;
        let run = RunBuilder::test()
            .with_camera(sadesim_crds::fixtures::down_camera())
            .with(|r| r.spec.rendering = Some(Rendering { enabled: true, gpus: Some(1) }))
            .build();
        let notices = cluster_only_notices(&sadesim_planner::plan(&run).unwrap());
        assert_eq!(notices.len(), 1, "{notices:?}");
        assert!(notices[0].starts_with("spec.rendering.gpus: the 1 GPU(s)"), "{notices:?}");
    }
}
