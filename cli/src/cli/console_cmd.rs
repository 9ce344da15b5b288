//! `sadesim console`: the web console (`sadesim_console`), locally on the runner of this
//! machine, or on a cluster with each user's own Kubernetes identity.

use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use sadesim_console::local::{Launcher, LiveRun, LocalBackend};
use sadesim_console::server::{self, Backend, Console};
use sadesim_crds::SimulationRun;
use sadesim_crds::outcome::summary::FleetCounts;

use super::{CliError, Outcome};
use crate::runner::{RunOptions, RunWatch, run_local};

/// `sadesim console`'s options.
#[derive(Debug, Clone, clap::Args)]
pub struct ConsoleArgs {
    /// Address to serve the console on (port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:8400")]
    pub listen: SocketAddr,
    /// Local backend: the folder runs are flown into (`<runs>/<run>/<UTC time>/`, as
    /// `sadesim run`), which is also the archive the console browses.
    #[arg(long, default_value = "runs")]
    pub runs: PathBuf,
    /// Local backend: relative paths in scenarios (maps, DEMs, orbit files, pilots) are
    /// relative to this folder, and pilots start in it.
    #[arg(long, default_value = ".")]
    pub scenarios: PathBuf,
    /// The asset cache worlds are loaded from and stored in (as for `sadesim run`).
    #[arg(long, value_name = "URL")]
    pub asset_cache: Option<String>,
    /// Act on a Kubernetes cluster (SimulationRuns) instead of this machine.
    #[arg(long)]
    pub cluster: bool,
    /// With --cluster: the kubeconfig (default: $KUBECONFIG, ~/.kube/config, or in-cluster).
    #[arg(long, requires = "cluster")]
    pub kubeconfig: Option<PathBuf>,
    /// With --cluster: every request must carry the user's own bearer token, used for every
    /// call to the API server (the chart's console pod). Without it, the kubeconfig's identity.
    #[arg(long, requires = "cluster")]
    pub user_tokens: bool,
    /// With --cluster: a namespace the console offers (repeat; default: the kubeconfig's).
    #[arg(long = "namespace", requires = "cluster")]
    pub namespaces: Vec<String>,
    /// Serve the page from this folder instead of the embedded copy (developing the page).
    #[arg(long, value_name = "DIR")]
    pub web_dir: Option<PathBuf>,
}

/// Flies console runs with `sadesim run`'s runner.
struct RunnerLauncher {
    asset_cache: Option<String>,
}

/// Passes the runner's progress to the console's run.
struct Watch(Arc<LiveRun>);

impl RunWatch for Watch {
    fn started(&self, _out_dir: &Path, view: Option<String>) {
        self.0.started(view);
    }

    fn window(&self, time_s: f64, _duration_s: f64, counts: FleetCounts) {
        self.0.window(time_s, counts);
    }
}

impl Launcher for RunnerLauncher {
    fn fly(
        &self,
        run: &SimulationRun,
        scenario: &Path,
        pilot_dir: &Path,
        run_dir: &Path,
        live: Arc<LiveRun>,
        stop: Arc<AtomicBool>,
    ) -> Result<(), String> {
        let options = RunOptions {
            progress: false,
            // The pilot starts in the scenarios folder; SADESIM_SCENARIO names the run's
            // own document.
            scenario: Some(pilot_dir.join("console-scenario.yaml")),
            scenario_document: Some(scenario.to_path_buf()),
            asset_cache: self.asset_cache.clone(),
            run_dir: Some(run_dir.to_path_buf()),
            watch: Some(Arc::new(Watch(live))),
            ..Default::default()
        };
        run_local(run, &options, stop).map(|_| ()).map_err(|e| e.to_string())
    }
}

/// Serves the console until Ctrl-C (or SIGTERM, in a pod).
///
/// # Errors
/// A build without MapLibre, no cluster configuration, or an address that cannot be bound.
pub(super) fn console(args: ConsoleArgs, out: &mut dyn Write) -> Result<Outcome, CliError> {
    let failed = |what: String| CliError::Failed(format!("console: {what}"));
    if !server::has_maplibre() {
        return Err(failed(server::NO_MAPLIBRE.into()));
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| failed(e.to_string()))?;
    let local = (!args.cluster).then(|| {
        let asset_cache = args
            .asset_cache
            .clone()
            .or_else(|| sadesim_sources::assets::local_cache_url(&|k| std::env::var(k).ok()).ok());
        let scenarios = std::path::absolute(&args.scenarios).unwrap_or(args.scenarios.clone());
        Arc::new(LocalBackend::new(args.runs.clone(), scenarios, Arc::new(RunnerLauncher { asset_cache })))
    });
    let backend = match &local {
        Some(l) => Backend::Local(l.clone()),
        None => {
            let cluster = runtime
                .block_on(sadesim_console::cluster::ClusterBackend::new(
                    args.kubeconfig.clone(),
                    args.user_tokens,
                    args.namespaces.clone(),
                ))
                .map_err(failed)?;
            Backend::Cluster(Arc::new(cluster))
        }
    };
    let app = server::router(Console::new(backend, args.web_dir.clone()));
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind(args.listen))
        .map_err(|e| failed(format!("cannot listen on {}: {e}", args.listen)))?;
    let addr = listener.local_addr().map_err(|e| failed(e.to_string()))?;
    let what = match &local {
        Some(l) => format!("local runs in {}", l.runs_root.display()),
        None => "the cluster".into(),
    };
    writeln!(out, "console ({what}): http://{addr}/")?;
    out.flush()?;
    let (stopped, wait) = tokio::sync::oneshot::channel::<()>();
    let stopped = std::sync::Mutex::new(Some(stopped));
    // Ctrl-C ends the console (see `view_cmd` for why the handler is installed explicitly);
    // in a pod, SIGTERM's default action ends it: the cluster console holds no state.
    ctrlc::set_handler(move || {
        if let Some(tx) = stopped.lock().ok().and_then(|mut s| s.take()) {
            let _ = tx.send(());
        }
    })
    .map_err(|e| failed(format!("cannot handle Ctrl-C: {e}")))?;
    runtime
        .block_on(async move {
            axum::serve(listener, app)
                .with_graceful_shutdown(async move {
                    let _ = wait.await;
                })
                .await
        })
        .map_err(|e| failed(e.to_string()))?;
    if let Some(l) = &local {
        // Runs still flying end as Ctrl-C ends them: interrupted, with their evidence.
        l.stop_all(Duration::from_secs(30));
    }
    runtime.shutdown_timeout(Duration::from_secs(1));
    writeln!(out, "stopped")?;
    Ok(Outcome::Success)
}
