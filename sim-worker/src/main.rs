//! `sim-worker <role>`: one runtime role of a run as its own process (DESIGN §3). The local
//! runner (`sadesim run --processes`) and the Kubernetes pods start these.

use std::net::IpAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use clap::{Parser, Subcommand};
use sadesim_crds::outcome::coordinator::UPLOAD_FAILED_EXIT;
use sim_worker::roles;

/// SADE-SIM runtime roles.
#[derive(Debug, Parser)]
#[command(name = "sim-worker", version, max_term_width = 100)]
struct Cli {
    #[command(subcommand)]
    role: Role,
}

#[derive(Debug, Subcommand)]
enum Role {
    /// Simulate one shard of the plan's drones and serve it to the coordinator over TCP.
    Shard {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// Shard index (on Kubernetes: JOB_COMPLETION_INDEX).
        #[arg(long, env = "JOB_COMPLETION_INDEX")]
        shard: u32,
        /// Coordinator address, host:port.
        #[arg(long)]
        coordinator: String,
        /// Address the drones' MAVLink endpoints bind (0.0.0.0 in a pod).
        #[arg(long, default_value = "127.0.0.1")]
        mavlink_bind: std::net::IpAddr,
        /// Host that receives each drone's API link on UDP 14540+i, PX4 SITL style
        /// (`none`: no API link; clients connect to the endpoints).
        #[arg(long, default_value = "127.0.0.1")]
        mavlink_api_host: String,
        /// Run without MAVLink endpoints.
        #[arg(long)]
        no_mavlink: bool,
        /// Seconds to keep trying to reach the coordinator (it may start later, on another
        /// host); each attempt is bounded, so a wrong address fails within this time.
        #[arg(long, value_name = "SECONDS", default_value_t = roles::shard::CONNECT_TIMEOUT.as_secs_f64(), value_parser = seconds)]
        connect_timeout: f64,
        /// The world's asset bundle, `<cache>/assets/<key>/world/` (file://, s3://, gs://,
        /// az://): its checked `world.bin` is loaded instead of building the world from the
        /// plan and the files it names. Without it the shard builds the world itself.
        #[arg(long, value_name = "URL")]
        assets: Option<String>,
    },
    /// Accept every shard, run the lockstep clock, record the run into --out.
    Coordinator {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// Address to listen on for shards (port 0: any free port, printed on stdout).
        #[arg(long, default_value = "127.0.0.1:7400")]
        listen: String,
        /// Output folder (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Address of the airspace authority's HTTP API (default: 127.0.0.1 at the plan's
        /// `services.airspaceHttp` port; 0.0.0.0 in a pod).
        #[arg(long)]
        airspace_bind: Option<std::net::SocketAddr>,
        /// With `spec.rendering.enabled`: where to serve the live stream the renderer follows
        /// (default: 127.0.0.1 at the plan's `services.rendererHttp` port; 0.0.0.0 in a pod).
        #[arg(long)]
        view_bind: Option<std::net::SocketAddr>,
        /// Seconds to wait for a shard's answer to a window before failing the run (its
        /// host down or the network cut: no FIN arrives); 0 waits forever. A shard whose
        /// process dies fails the run at once.
        #[arg(long, value_name = "SECONDS", default_value_t = roles::coordinator::SHARD_TIMEOUT.as_secs_f64(), value_parser = seconds)]
        shard_timeout: f64,
        /// Seconds to wait for every shard to connect before giving up (exit 2, naming the
        /// missing shards); 0 waits forever (the default: pods may wait for a node or an
        /// image pull, and the operator watches them).
        #[arg(long, value_name = "SECONDS", default_value_t = 0.0, value_parser = seconds)]
        connect_timeout: f64,
        /// A file of `key="value"` annotation lines (a downward-API volume of the Pod's
        /// annotations): the annotation `sadesim.io/stop="<reason>"` ends the run after the
        /// current window with that reason. Stdin lines `{"type":"stop","reason":...}` do
        /// the same when stdin is not a terminal.
        #[arg(long, value_name = "FILE")]
        control_file: Option<PathBuf>,
        /// After the run, whatever its end, finish the run folder as `sadesim run` does:
        /// `plan.json`, `report.html` with its plots, `manifest.json`, then the upload to
        /// `--archive-url` when given. SIGTERM (a Pod deleted) then ends the run like
        /// Ctrl-C, so the files are still written and uploaded. Exit status: 0, 2 when the
        /// run failed, 3 when only the upload failed.
        #[arg(long)]
        finish_run: bool,
        /// With `--finish-run`: the archive (`s3://`, `gs://`, `az://`, `file://`) to upload
        /// the run folder to, at `<url>/<namespace>/<run>/<uid>/` (names from the plan).
        #[arg(long, env = "SADESIM_ARCHIVE_URL", value_name = "URL", requires = "finish_run")]
        archive_url: Option<String>,
        /// The world's asset bundle, as for `shard --assets`: the city drawn in
        /// `recording.mcap` and the report is loaded from it instead of built.
        #[arg(long, env = "SADESIM_ASSETS_URL", value_name = "URL")]
        assets: Option<String>,
        /// A pilot is started on the release (the pilot Job, `sadesim run --processes`):
        /// simulated time holds at the release until MAVLink from it reaches a drone it
        /// flies, for at most `spec.pilot.connectTimeoutS` of wall time, after which the run
        /// ends `pilotNotConnected`. Without it simulated time runs on at once.
        #[arg(long)]
        hold_for_pilot: bool,
    },
    /// Build the run's world into the asset cache `<archive>/assets/<asset cache key>/world/`
    /// (world.bin, world.glb, buildings.geojson, world.json, manifest.json), or exit at once
    /// when a verified entry is there. Prints the outcome as one JSON line.
    Assets {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// The archive holding the cache (s3://, gs://, az:// or file://).
        #[arg(long, value_name = "URL")]
        archive: String,
        /// Also write the outcome line to this file (the Job's termination message,
        /// `/dev/termination-log`, which the operator reads).
        #[arg(long, value_name = "FILE")]
        report_file: Option<PathBuf>,
    },
    /// Serve the live 3D view of a run to browsers: follows the coordinator's live stream
    /// (`--feed`, its `--view-bind`) and serves the page, three.js, the world's glTF and
    /// the stream on `--listen` until SIGINT/SIGTERM. Any number of browsers; none of them
    /// can slow the simulation.
    Renderer {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// Address to serve the page on.
        #[arg(long, default_value = "127.0.0.1:8490")]
        listen: std::net::SocketAddr,
        /// `host:port` of the coordinator's live stream.
        #[arg(long)]
        feed: String,
        /// The world's asset bundle, as for `shard --assets` (the city drawn in the view).
        #[arg(long, env = "SADESIM_ASSETS_URL", value_name = "URL")]
        assets: Option<String>,
    },
    /// Joins a file the operator stored in parts (`FILE.part-000`, ... and `FILE.sha256`,
    /// side by side) into `--out`, checking its digest; a whole FILE is copied. The pilot's
    /// pod runs it first when its fleet file is too big for one ConfigMap.
    Join {
        /// The file, as if whole (e.g. /etc/sadesim/fleet.json).
        file: PathBuf,
        /// Where to write it.
        #[arg(long)]
        out: PathBuf,
    },
    /// Waits until the coordinator has released the pilots: polls URL (the airspace API's
    /// `/healthz`) until it says `pilotsReleased: true`. The pilot pod's init container.
    WaitRelease {
        /// e.g. http://<run>-airspace.<namespace>.svc:8480/healthz
        url: String,
    },
    /// Serve one router segment's drones to ground stations (QGroundControl) on the
    /// segment's GCS ports (UDP 14550+N, TCP 5760+N) until SIGINT/SIGTERM. With
    /// `SADESIM_MAVLINK_SIGNING_KEY` set (the passphrase), ground stations must sign their
    /// MAVLink 2 frames with it and everything sent to them is signed.
    Router {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// Router segment index (drones with system ids 1..=250 each).
        #[arg(long)]
        segment: u32,
        /// Interface for the GCS ports.
        #[arg(long, default_value = "0.0.0.0")]
        bind: IpAddr,
        /// Host of the drone endpoints; `{run}` and `{shard}` are replaced by the run name and
        /// the drone's shard index (Kubernetes: `{run}-shard-{shard}.{run}-shards`).
        #[arg(long, default_value = roles::router::DEFAULT_DRONE_HOST)]
        drone_host: String,
    },
}

/// A number of seconds for a flag: finite, not negative, at most a day.
fn seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if s.is_finite() && (0.0..=86_400.0).contains(&s) => Ok(s),
        _ => Err(format!("expected seconds between 0 and 86400, got {text:?}")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.role {
        Role::Shard {
            plan,
            shard,
            coordinator,
            mavlink_bind,
            mavlink_api_host,
            no_mavlink,
            connect_timeout,
            assets,
        } => {
            // Ctrl-C in a terminal reaches every process of the group. A shard stops when
            // the coordinator says so (or its connection closes), so the coordinator can
            // finish the run and write its files first. SIGTERM (its Pod deleted) ends it at
            // once: the coordinator then reports the shard's failure.
            let _ = ctrlc::set_handler(|| {});
            exit_on_sigterm();
            let api_host = match mavlink_api_host.as_str() {
                "none" => Ok(None),
                host => host.parse().map(Some).map_err(|_| {
                    roles::RoleError::Protocol(format!("--mavlink-api-host {host:?}: expected an IP address or `none`"))
                }),
            };
            api_host.and_then(|api_host| {
                let mavlink = (!no_mavlink).then(|| sim_worker::shard_io::MavlinkOptions {
                    bind_ip: mavlink_bind,
                    api_host,
                    ..sim_worker::shard_io::MavlinkOptions::local()
                });
                let timeout = Duration::from_secs_f64(connect_timeout);
                roles::read_plan(&plan).and_then(|plan| {
                    let world = roles::world(&plan, assets.as_deref())?;
                    let sky = roles::sky(&plan)?;
                    let surroundings = roles::surroundings(&plan, world, sky, assets.as_deref())?;
                    roles::shard::run(&plan, &surroundings, shard, &coordinator, mavlink.as_ref(), timeout)
                })
            })
        }
        Role::Coordinator {
            plan,
            listen,
            out,
            airspace_bind,
            view_bind,
            shard_timeout,
            connect_timeout,
            control_file,
            finish_run,
            archive_url,
            assets,
            hold_for_pilot,
        } => {
            let stop = Arc::new(AtomicBool::new(false));
            let flag = stop.clone();
            let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
            if finish_run {
                // No shell in the pod passes SIGTERM on as SIGINT: this process is PID 1 of
                // its container and ends the run itself, so the files are still finished.
                if let Err(e) = signal_hook::flag::register(signal_hook::consts::SIGTERM, stop.clone()) {
                    eprintln!("warning: SIGTERM cannot be caught ({e}): a deleted Pod loses the run's end");
                }
            }
            let requests = roles::control::StopRequest::new();
            requests.read_stdin();
            let watched = match &control_file {
                Some(file) => requests.watch_annotations(file).map_err(roles::RoleError::ControlFile),
                None => Ok(()),
            };
            let plan_file = plan;
            let read = watched.and_then(|()| roles::read_plan(&plan_file));
            let (plan, world) = match read.and_then(|plan| roles::world(&plan, assets.as_deref()).map(|w| (plan, w))) {
                Ok(read) => read,
                Err(e) => return failure(&e),
            };
            let ran = std::fs::create_dir_all(&out).map_err(roles::RoleError::from).and_then(|()| {
                let airspace = airspace_bind
                    .unwrap_or_else(|| std::net::SocketAddr::from(([127, 0, 0, 1], plan.services.airspace_http)));
                let positive = |s: f64| (s > 0.0).then(|| Duration::from_secs_f64(s));
                let timeouts =
                    roles::coordinator::Timeouts { connect: positive(connect_timeout), shard: positive(shard_timeout) };
                let ends = roles::coordinator::Ends { stop: &stop, timeouts, requests, hold_for_pilot };
                roles::coordinator::run(&plan, &world, listen.as_str(), airspace, &out, ends, view_bind).map(|_| ())
            });
            // Whatever the run's end: the folder's files are evidence of a failed run too.
            let archived = !finish_run
                || roles::coordinator::finish(&plan_file, &plan, &world, &out, archive_url.as_deref()).archived.is_ok();
            return match ran {
                Err(e) => failure(&e),
                Ok(()) if !archived => ExitCode::from(UPLOAD_FAILED_EXIT),
                Ok(()) => ExitCode::SUCCESS,
            };
        }
        Role::Assets { plan, archive, report_file } => roles::read_plan(&plan)
            .and_then(|plan| roles::assets::run(&plan, &archive, report_file.as_deref()).map(|_| ())),
        Role::Renderer { plan, listen, feed, assets } => {
            let stop = Arc::new(AtomicBool::new(false));
            let flag = stop.clone();
            // SIGTERM ends the process at once: a renderer holds nothing to flush.
            let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
            exit_on_sigterm();
            roles::read_plan(&plan).and_then(|plan| {
                let world = roles::world(&plan, assets.as_deref())?;
                roles::renderer::run(&plan, &world, listen, &feed, &stop)
            })
        }
        Role::Join { file, out } => roles::read_parts(&file).map_err(roles::RoleError::from).and_then(|bytes| {
            std::fs::write(&out, bytes)
                .map_err(|source| roles::RoleError::Write { path: out.display().to_string(), source })
        }),
        Role::WaitRelease { url } => {
            let stop = Arc::new(AtomicBool::new(false));
            let flag = stop.clone();
            let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
            exit_on_sigterm();
            roles::wait_release::run(&url, &stop)
        }
        Role::Router { plan, segment, bind, drone_host } => {
            let stop = Arc::new(AtomicBool::new(false));
            let flag = stop.clone();
            // SIGTERM (a pod stopping) ends the process at once: a router holds nothing that
            // needs flushing.
            let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
            exit_on_sigterm();
            // The signing passphrase is read from the environment only: a flag would show
            // it in `ps` to every user of the machine.
            let key = std::env::var_os(sadesim_crds::ground_stations::SIGNING_KEY_ENV);
            roles::router::signing_key(key).and_then(|signing| {
                let options = roles::router::RouterOptions { segment, bind, drone_host, signing };
                roles::read_plan(&plan).and_then(|plan| roles::router::run(&plan, &options, &stop).map(|_| ()))
            })
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => failure(&e),
    }
}

/// Ends this process at SIGTERM with exit status 143, what the default action means. A
/// pod's program is PID 1 of its container, and the kernel ignores SIGTERM for PID 1 unless
/// it has a handler: without one a deleted pod waits out its grace period (30 s) and is
/// killed, and the rest of the run (the coordinator, the operator) waits with it.
fn exit_on_sigterm() {
    let always = Arc::new(AtomicBool::new(true));
    if let Err(e) = signal_hook::flag::register_conditional_shutdown(signal_hook::consts::SIGTERM, 143, always) {
        eprintln!("warning: SIGTERM cannot be caught ({e}): a deleted Pod waits out its grace period");
    }
}

/// A failed role: the reason on stderr (the Pod's termination message), exit status 2.
fn failure(e: &roles::RoleError) -> ExitCode {
    eprintln!("error: {e}");
    ExitCode::from(2)
}
