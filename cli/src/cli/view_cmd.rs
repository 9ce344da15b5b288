//! `sadesim view RUN`: the live view's page on a recorded run (a local run folder or an
//! archived one), with a timeline to play, pause and scrub.

use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;

use sadesim_crds::outcome::run_folder;
use sadesim_crds::plan::RunPlan;
use sadesim_evidence::archive::{Archive, is_object_store};
use sadesim_world::World;
use sim_worker::view::{self, Content, Source};

use super::{CliError, Outcome};

/// The files a replay reads.
const MCAP: &str = "recording.mcap";
const WORLD_STATS: &str = "world.json";

/// Serves the replay of the run at `location` on `listen` until the process is stopped
/// (Ctrl-C). `ready` is called with the page's URL once it is served (the CLI prints it).
///
/// # Errors
/// A run folder without `plan.json`, `events.jsonl` or `recording.mcap` (a run recorded
/// with `spec.recording.mcap: false` has no poses to replay), an archive that does not
/// verify, a damaged recording, a bad `--rate`, or an address that cannot be bound.
pub fn view(location: &str, listen: SocketAddr, rate_hz: f64, out: &mut dyn Write) -> Result<Outcome, CliError> {
    let failed = |what: String| CliError::Failed(format!("view {location}: {what}"));
    if !view::server::has_three() {
        return Err(failed(view::server::NO_THREE.into()));
    }
    let read = RunFiles::open(location)?;
    let plan: RunPlan = serde_json::from_slice(&read.file(run_folder::PLAN)?)
        .map_err(|e| failed(format!("{}: not a run plan: {e}", run_folder::PLAN)))?;
    let mcap = read.file(MCAP).map_err(|e| {
        failed(format!("{e} (the run needs recording.mcap for its poses: spec.recording.mcap must not be false)"))
    })?;
    let events = String::from_utf8(read.file(run_folder::EVENTS)?)
        .map_err(|e| failed(format!("{}: not UTF-8: {e}", run_folder::EVENTS)))?;
    let names: Vec<String> = plan.drones.iter().map(|d| d.name.clone()).collect();
    let replay = view::replay::replay(&mcap, &events, &names, rate_hz).map_err(|e| failed(e.to_string()))?;
    // The run's own world only: the bundle of its key, or rebuilt from its files, and
    // checked against the statistics the run wrote (another city's buildings would lie).
    let recorded: Option<serde_json::Value> =
        read.file(WORLD_STATS).ok().and_then(|bytes| serde_json::from_slice(&bytes).ok());
    let world: Option<World> = sadesim_sources::assets::find_world(&plan)
        .filter(|w| recorded.as_ref().is_some_and(|r| serde_json::to_value(w.stats()).ok().as_ref() == Some(r)));
    if world.is_none() {
        writeln!(
            out,
            "note: the run's world (asset bundle {}) was not found: drawing flat ground",
            plan.asset_cache_key
        )?;
    }
    let glb = world.as_ref().map(|w| Arc::new(sadesim_sources::gltf::world_glb(w, plan.spec.origin.geo())));
    let scene = view::scene::scene(&plan, world.as_ref(), "replay", glb.is_some());
    let content = Content {
        scene_json: Arc::new(serde_json::to_vec(&scene).expect("a scene is JSON")),
        world_glb: glb,
        source: Source::Replay(Arc::new(serde_json::to_vec(&replay).expect("a replay is JSON"))),
        frames: None,
    };
    let server = view::server::start(listen, content).map_err(|e| failed(format!("cannot listen on {listen}: {e}")))?;
    writeln!(
        out,
        "replay of {}/{} ({:.1} s, {} drones, {} frames at {} Hz): {}",
        plan.run.namespace,
        plan.run.name,
        replay.end_s,
        names.len(),
        replay.frames.len(),
        rate_hz,
        server.url()
    )?;
    writeln!(out, "serving until Ctrl-C")?;
    out.flush()?;
    // Ctrl-C ends the replay. The handler is installed rather than left to the default
    // action: a program started in the background by a non-interactive shell (`cmd &` in a
    // script, CI) inherits SIGINT ignored, and would then never stop.
    let (stopped, wait) = std::sync::mpsc::channel();
    ctrlc::set_handler(move || {
        let _ = stopped.send(());
    })
    .map_err(|e| failed(format!("cannot handle Ctrl-C: {e}")))?;
    let _ = wait.recv();
    drop(server);
    writeln!(out, "stopped")?;
    Ok(Outcome::Success)
}

/// Where the run's files are: a local folder, or an archive (each file checked against the
/// run's manifest as it is read).
enum RunFiles {
    Folder(std::path::PathBuf),
    Archive(Box<Archive>),
}

impl RunFiles {
    fn open(location: &str) -> Result<Self, CliError> {
        if is_object_store(location) {
            return Ok(Self::Archive(Box::new(Archive::open(location)?)));
        }
        let path = location.strip_prefix("file://").unwrap_or(location);
        Ok(Self::Folder(Path::new(path).to_path_buf()))
    }

    fn file(&self, name: &str) -> Result<Vec<u8>, CliError> {
        match self {
            Self::Folder(dir) => {
                let path = dir.join(name);
                std::fs::read(&path).map_err(|source| CliError::Read { path: path.display().to_string(), source })
            }
            Self::Archive(archive) => Ok(archive.read_checked("", name)?),
        }
    }
}
