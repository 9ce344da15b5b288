//! `sadesim run --processes`: the coordinator and each shard as `sim-worker` processes,
//! talking the shard protocol over TCP on 127.0.0.1 — the same processes and messages as
//! the pods of a Kubernetes run. The coordinator says on stdout when it releases the
//! pilots; when the pilot exits, a line on its stdin ends the run.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use indicatif::ProgressBar;
use sadesim_crds::ground_stations::SIGNING_KEY_ENV;
use sadesim_crds::plan::RunPlan;
use sim_worker::record::RunSummary;
use sim_worker::roles::control::Control;
use sim_worker::roles::coordinator::Report;

use super::RunError;
use super::pilot::{self, PilotError, Supervisor};

/// The `sim-worker` binary: the option, `$SADESIM_WORKER`, else next to this executable.
fn worker_binary(configured: Option<&Path>) -> Result<PathBuf, RunError> {
    if let Some(p) = configured {
        return Ok(p.to_path_buf());
    }
    if let Some(p) = std::env::var_os("SADESIM_WORKER") {
        return Ok(PathBuf::from(p));
    }
    let exe = std::env::current_exe().map_err(|e| RunError::Worker(format!("cannot locate sadesim: {e}")))?;
    let worker = exe.with_file_name("sim-worker");
    if worker.exists() {
        Ok(worker)
    } else {
        Err(RunError::Worker(format!(
            "--processes needs the sim-worker binary next to sadesim ({}); build it with `cargo build --release -p sim-worker` or set SADESIM_WORKER",
            worker.display()
        )))
    }
}

/// The first of `shards` (in plan order) that has exited with a failure, as a message
/// naming it and its log.
fn early_shard_exit(shards: &mut [std::process::Child], out_dir: &Path) -> Option<String> {
    shards.iter_mut().enumerate().find_map(|(index, shard)| {
        let status = shard.try_wait().ok().flatten().filter(|s| !s.success())?;
        let log = out_dir.join(format!("shard-{index}.log"));
        Some(format!("shard {index} exited ({status}) before the run started; see {}", log.display()))
    })
}

fn log_file(dir: &Path, name: &str) -> Result<std::fs::File, RunError> {
    let path = dir.join(name);
    std::fs::File::create(&path).map_err(|source| RunError::Output { path: path.display().to_string(), source })
}

fn spawn(cmd: &mut Command, what: &str) -> Result<Child, RunError> {
    cmd.spawn().map_err(|e| RunError::Worker(format!("failed to start the {what}: {e}")))
}

/// Asks a process to stop like Ctrl-C would (SIGINT through `kill`, no unsafe code).
fn interrupt(child: &Child) {
    let _ = Command::new("kill").args(["-INT", &child.id().to_string()]).status();
}

/// Runs the plan written at `out_dir/plan.json` with worker processes. `routers`: `None`
/// for a run without MAVLink, else the routers' signing passphrase (`None` inside: no
/// signing), handed to them in `SADESIM_MAVLINK_SIGNING_KEY`. `airspace` and `view` are
/// where the coordinator should serve the airspace API and the live view; it reports where
/// it does (another port when one is taken), and the fleet file is written then.
#[allow(clippy::too_many_arguments)]
pub(super) fn run(
    plan: &RunPlan,
    worker: Option<&Path>,
    routers: Option<Option<&str>>,
    out_dir: &Path,
    bar: &ProgressBar,
    stop: &AtomicBool,
    mut pilot: Option<&mut Supervisor>,
    airspace: std::net::SocketAddr,
    assets: Option<&str>,
    view: Option<std::net::SocketAddr>,
) -> Result<RunSummary, RunError> {
    let worker = worker_binary(worker)?;
    let plan_path = out_dir.join(sadesim_crds::outcome::run_folder::PLAN);
    let mut coordinator = spawn(
        Command::new(&worker)
            .arg("coordinator")
            .arg("--plan")
            .arg(&plan_path)
            .args(["--listen", "127.0.0.1:0", "--out"])
            .arg(out_dir)
            .arg("--airspace-bind")
            .arg(airspace.to_string())
            .args(assets.iter().flat_map(|url| ["--assets", url]))
            .args(view.iter().flat_map(|addr| ["--view-bind".to_string(), addr.to_string()]))
            // A pilot to wait for at the release (see `sim_worker::conduct`).
            .args((pilot.is_some() && routers.is_some()).then_some("--hold-for-pilot"))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(log_file(out_dir, "coordinator.log")?),
        "coordinator",
    )?;
    let stdout = coordinator.stdout.take().expect("stdout is piped");
    let mut control = coordinator.stdin.take();
    let mut lines = BufReader::new(stdout).lines();
    let address = match lines.next().and_then(Result::ok).and_then(|l| serde_json::from_str::<Report>(&l).ok()) {
        Some(Report::Listening { address, airspace, view: shown }) => {
            // The ports the coordinator listens on: the planned ones unless other programs
            // held them. The fleet file tells them to the pilot and the ground stations.
            let served = |what: &str, addr: &str| {
                addr.parse::<std::net::SocketAddr>().map_err(|e| {
                    RunError::Worker(format!("the coordinator reported its {what} at {addr:?}, not host:port: {e}"))
                })
            };
            let fleet_file = served("airspace API", &airspace).and_then(|airspace| {
                let view = shown.as_deref().map(|view| served("live view", view)).transpose()?;
                super::write_fleet_file(plan, out_dir, airspace, view, pilot.as_deref_mut())
            });
            if let Err(e) = fleet_file {
                let _ = coordinator.kill();
                return Err(e);
            }
            if let Some(shown) = shown {
                bar.suspend(|| eprintln!("live view: http://{shown}/"));
                // The coordinator process renders the cameras and serves their frames.
                if plan.spec.has_cameras() {
                    bar.suspend(|| {
                        eprintln!("onboard cameras: http://{shown}/cameras (rendered by the coordinator process)")
                    });
                }
            }
            address
        }
        _ => {
            let _ = coordinator.kill();
            return Err(RunError::Worker(format!(
                "the coordinator did not start; see {}",
                out_dir.join("coordinator.log").display()
            )));
        }
    };
    // One process per shard, then one router per segment, like the pods of a cluster run;
    // each logs to `<role>-<index>.log`.
    let start = |mut cmd: Command, role: &str, index_flag: &str, index: u32, extra: &[&str]| {
        spawn(
            cmd.args([role, "--plan"])
                .arg(&plan_path)
                .args([index_flag, &index.to_string()])
                .args(extra)
                .stdout(Stdio::null())
                .stderr(log_file(out_dir, &format!("{role}-{index}.log"))?),
            role,
        )
    };
    let mavlink = routers.is_some();
    let mut shards = Vec::new();
    for shard in &plan.shards {
        let mut extra = vec!["--coordinator", &address];
        if !mavlink {
            extra.push("--no-mavlink");
        }
        // The bundle the runner loaded or built: the shards load it rather than build the
        // world again.
        if let Some(url) = assets {
            extra.extend(["--assets", url]);
        }
        shards.push(start(Command::new(&worker), "shard", "--shard", shard.index, &extra)?);
    }
    if let Some(signing) = routers {
        for segment in &plan.segments {
            // The passphrase travels in the environment, never on the command line (`ps`);
            // without signing a variable inherited from the user's shell must not turn it on.
            let mut cmd = Command::new(&worker);
            match signing {
                Some(passphrase) => cmd.env(SIGNING_KEY_ENV, passphrase),
                None => cmd.env_remove(SIGNING_KEY_ENV),
            };
            shards.push(start(cmd, "router", "--segment", segment.index, &[])?);
        }
    }
    // Progress lines arrive on a reader thread so Ctrl-C is noticed between them.
    let (tx, rx) = std::sync::mpsc::channel::<Report>();
    let reader = std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            if let Ok(r) = serde_json::from_str::<Report>(&line)
                && tx.send(r).is_err()
            {
                break;
            }
        }
    });
    let started = Instant::now();
    let mut summary = None;
    // The coordinator's `failed` line: why it exits without `finished`.
    let mut failure: Option<String> = None;
    let mut interrupted = false;
    let mut pilot_error: Option<PilotError> = None;
    let mut stop_sent = false;
    // Until the first progress line the coordinator is waiting for its shards: a shard that
    // dies then (bad plan, world build failed) would leave it waiting for ever.
    let mut started_run = false;
    let mut shard_died: Option<String> = None;
    loop {
        if !started_run && shard_died.is_none() {
            shard_died = early_shard_exit(&mut shards[..plan.shards.len()], out_dir);
            if shard_died.is_some() && !interrupted {
                interrupted = true;
                interrupt(&coordinator);
            }
        }
        if stop.load(Ordering::Relaxed) && !interrupted {
            interrupted = true;
            interrupt(&coordinator);
        }
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(Report::Progress { sim_time_s, counts }) => {
                started_run = true;
                if let Some(p) = pilot.as_deref_mut() {
                    p.advance(sim_time_s);
                }
                super::show_progress(bar, sim_time_s, plan.duration_s, started, counts);
            }
            Ok(Report::PilotsReleased { sim_time_s }) => {
                if let Some(p) = pilot.as_deref_mut() {
                    p.advance(sim_time_s);
                    if let Err(e) = p.start() {
                        pilot_error = Some(e);
                    }
                }
            }
            Ok(Report::Finished { summary: s }) => summary = Some(s),
            Ok(Report::Failed { reason, .. }) => failure = Some(reason),
            Ok(Report::Listening { .. }) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
        }
        // The pilot exited (`endRun`) or could not start: the coordinator ends the run
        // after its current window, with that reason.
        let exited = pilot.as_deref_mut().is_some_and(Supervisor::poll);
        let reason = pilot::end_reason(pilot_error.is_some(), exited);
        if let (Some(reason), Some(stdin), false) = (reason, control.as_mut(), stop_sent) {
            stop_sent = true;
            let mut line = serde_json::to_vec(&Control::Stop { reason }).expect("serializable");
            line.push(b'\n');
            // A coordinator that already finished has closed its stdin: nothing to stop.
            let _ = stdin.write_all(&line).and_then(|()| stdin.flush());
        }
    }
    drop(control);
    let _ = reader.join();
    let status = coordinator.wait().map_err(|e| RunError::Worker(format!("coordinator: {e}")))?;
    // Shards exit when the coordinator says Stop or its socket closes; give them a moment.
    let deadline = Instant::now() + Duration::from_secs(10);
    for mut shard in shards {
        while shard.try_wait().ok().flatten().is_none() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = shard.kill();
        let _ = shard.wait();
    }
    if let Some(e) = pilot_error {
        return Err(e.into());
    }
    if let (None, Some(died)) = (&summary, shard_died) {
        return Err(RunError::Worker(died));
    }
    summary.ok_or_else(|| {
        let why = failure
            .map_or_else(|| "without finishing the run".to_string(), |reason| format!("after a failure: {reason}"));
        RunError::Worker(format!(
            "the coordinator exited ({status}) {why}; see {}",
            out_dir.join("coordinator.log").display()
        ))
    })
}
