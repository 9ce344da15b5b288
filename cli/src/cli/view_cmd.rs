//! `sadesim view RUN`: the live view's page on a recorded run (a local run folder or an
//! archived one), with a timeline to play, pause and scrub.

use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;

use sadesim_evidence::archive::{Archive, is_object_store};
use sim_worker::view;

use super::{CliError, Outcome};

/// Serves the replay of the run at `location` on `listen` until the process is stopped
/// (Ctrl-C). `ready` is called with the page's URL once it is served (the CLI prints it).
///
/// # Errors
/// A run folder without `plan.json`, `events.jsonl` or `recording.mcap` (a run recorded
/// with `spec.recording.mcap: false` has no poses to replay), an archive that does not
/// verify, a damaged recording, a bad `--rate`, or an address that cannot be bound.
pub fn view(location: &str, listen: SocketAddr, rate_hz: f64, out: &mut dyn Write) -> Result<Outcome, CliError> {
    let failed = |what: String| CliError::Failed(format!("view {location}: {what}"));
    let read = RunFiles::open(location)?;
    let replay =
        sadesim_console::replay::replay(&|name| read.file(name).map_err(|e| e.to_string()), rate_hz).map_err(failed)?;
    if replay.flat_ground {
        writeln!(
            out,
            "note: the run's world (asset bundle {}) was not found: drawing flat ground",
            replay.plan.asset_cache_key
        )?;
    }
    let (plan, content) = (&replay.plan, replay.content.clone());
    let server = view::server::start(listen, content).map_err(|e| failed(format!("cannot listen on {listen}: {e}")))?;
    writeln!(
        out,
        "replay of {}/{} ({:.1} s, {} drones, {} frames at {} Hz): {}",
        plan.run.namespace,
        plan.run.name,
        replay.end_s,
        plan.drones.len(),
        replay.frames,
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
