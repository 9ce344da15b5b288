//! The operator (`sadesim operator`): watches SimulationRuns and the Jobs and Pods they
//! own, and reconciles each run: read -> decide (pure, [`lifecycle`]) -> server-side apply
//! the children (one field manager) -> archive logs -> write status on the status
//! subresource. Beside it, under the same leader election, runs the SimulationSweep
//! controller ([`crate::k8s::sweep`]). See docs/architecture.md, "Operator internals".
//!
//! Modules: [`lifecycle`] (the phase machine), [`queue`] (admission without Kueue),
//! [`observe`] and [`progress`] (what the children and the coordinator say), [`planning`]
//! (the planner with a mapped world's files from object storage),
//! [`reconcile`] (the I/O shell), [`leader`] (Lease election), [`metrics`], [`log`].

pub mod leader;
pub mod lifecycle;
pub mod log;
pub mod metrics;
pub mod observe;
pub mod planning;
pub mod progress;
pub mod queue;
pub mod reconcile;

#[cfg(test)]
mod tests;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use futures_util::StreamExt;
use k8s_openapi::api::batch::v1::Job;
use k8s_openapi::api::coordination::v1::Lease;
use k8s_openapi::api::core::v1::Pod;
use kube::api::{Api, ListParams};
use kube::runtime::{Controller, watcher};
use kube::{Client, Config};
use sadesim_crds::{SimulationRun, SimulationSweep};

use super::children::Workload;
use tokio::sync::watch;

use self::metrics::Metrics;
use self::reconcile::{Context, error_policy, reconcile};

/// How long the first contact with the API server may take before the operator gives up.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(15);

/// Options of `sadesim operator` (flags, each also read from its environment variable).
#[derive(Clone, Debug, PartialEq)]
pub struct OperatorOptions {
    pub settings: super::children::ClusterSettings,
    /// Active runs per namespace without Kueue; 0 = unlimited.
    pub max_concurrent_runs: u32,
    /// Where `/metrics` and `/healthz` are served.
    pub metrics_addr: SocketAddr,
    /// Elect a leader through the Lease `sadesim-operator` before reconciling.
    pub leader_election: bool,
    /// Namespace of the Lease (`POD_NAMESPACE`; default: the client's namespace).
    pub lease_namespace: Option<String>,
    /// Identity in the Lease (`POD_NAME`; default: host name and process id).
    pub identity: Option<String>,
}

impl Default for OperatorOptions {
    fn default() -> Self {
        Self {
            settings: super::children::ClusterSettings::default(),
            max_concurrent_runs: 0,
            metrics_addr: SocketAddr::from(([0, 0, 0, 0], 8080)),
            leader_election: true,
            lease_namespace: None,
            identity: None,
        }
    }
}

/// Runs the operator until SIGTERM/SIGINT (then it stops taking work, finishes the
/// reconciles in flight and exits) or until leadership is lost (an error: the Deployment
/// restarts the pod as a follower).
///
/// # Errors
/// No cluster to talk to (no kubeconfig and no in-cluster service account), the API
/// server unreachable or without the SimulationRun CRD, the metrics address taken, or
/// leadership lost. Each message says what to fix.
pub fn run(options: OperatorOptions) -> Result<(), OperatorError> {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(OperatorError::Runtime)?;
    runtime.block_on(operate(options))
}

/// Why the operator could not start or go on; each message says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum OperatorError {
    #[error("failed to start the async runtime: {0}")]
    Runtime(#[source] std::io::Error),
    #[error(
        "no Kubernetes cluster to talk to: {0}. `sadesim operator` needs a kubeconfig (KUBECONFIG or ~/.kube/config) or must run in a pod with a service account"
    )]
    NoCluster(#[source] kube::config::InferConfigError),
    #[error("failed to build the Kubernetes client: {0}")]
    Client(#[source] kube::Error),
    #[error("the Kubernetes API server at {server} did not answer within {seconds} s")]
    Unreachable { server: String, seconds: u64 },
    #[error("the SimulationRun CRD is not installed: `sadesim crd | kubectl apply -f -` (or install the Helm chart)")]
    NoCrd,
    #[error("cannot list SimulationRuns at the API server {server}: {source}")]
    List {
        server: String,
        #[source]
        source: kube::Error,
    },
    #[error(transparent)]
    Metrics(#[from] metrics::ListenError),
    #[error("lost leadership of Lease sadesim-operator: stopped reconciling")]
    LostLeadership,
}

async fn operate(options: OperatorOptions) -> Result<(), OperatorError> {
    let mut config = Config::infer().await.map_err(OperatorError::NoCluster)?;
    config.connect_timeout = Some(CONNECT_TIMEOUT);
    config.read_timeout = Some(Duration::from_secs(295));
    let default_ns = config.default_namespace.clone();
    let server_url = config.cluster_url.to_string();
    let client = Client::try_from(config).map_err(OperatorError::Client)?;

    // Fail fast, with the fix, when the API server or the CRD is missing.
    let runs: Api<SimulationRun> = Api::all(client.clone());
    match tokio::time::timeout(CONNECT_TIMEOUT, runs.list(&ListParams::default().limit(1))).await {
        Err(_) => return Err(OperatorError::Unreachable { server: server_url, seconds: CONNECT_TIMEOUT.as_secs() }),
        Ok(Err(kube::Error::Api(e))) if e.code == 404 => return Err(OperatorError::NoCrd),
        Ok(Err(source)) => return Err(OperatorError::List { server: server_url, source }),
        Ok(Ok(_)) => {}
    }

    let (stop_tx, stop_rx) = watch::channel(false);
    tokio::spawn(async move {
        shutdown_signal().await;
        log::info("shutting down", &[]);
        let _ = stop_tx.send(true);
    });
    let stopped = |mut rx: watch::Receiver<bool>| async move {
        let _ = rx.wait_for(|s| *s).await;
    };

    let metrics = Arc::new(Metrics::default());
    let server = metrics::serve(options.metrics_addr, metrics.clone(), stopped(stop_rx.clone())).await?;
    log::info("serving /metrics and /healthz", &[("addr", &options.metrics_addr.to_string())]);

    let mut leadership: Option<watch::Receiver<bool>> = None;
    if options.leader_election {
        let ns = options.lease_namespace.clone().unwrap_or(default_ns);
        let me = options.identity.clone().unwrap_or_else(default_identity);
        let leases: Api<Lease> = Api::namespaced(client.clone(), &ns);
        match leader::acquire(leases, me, stop_rx.clone()).await {
            Some(rx) => leadership = Some(rx),
            None => {
                let _ = server.await;
                return Ok(());
            }
        }
    }
    // Each controller stops on SIGTERM/SIGINT or when leadership is lost.
    let stop_or_lost = || {
        let lost = leadership.clone();
        let stop = stop_rx.clone();
        async move {
            match lost {
                Some(mut lost) => {
                    tokio::select! {
                        _ = stopped(stop) => {}
                        _ = lost.wait_for(|leading| !*leading) => {}
                    }
                }
                None => stopped(stop).await,
            }
        }
    };

    // Sweeps are reconciled when their CRD is installed (an operator upgraded before its
    // CRDs still reconciles runs).
    let sweeps: Api<SimulationSweep> = Api::all(client.clone());
    let with_sweeps = match sweeps.list(&ListParams::default().limit(1)).await {
        Ok(_) => true,
        Err(e) => {
            log::warn(
                "not reconciling SimulationSweeps: cannot list them (install the SimulationSweep CRD: `sadesim crd | kubectl apply -f -`, and the chart's RBAC)",
                &[("error", &e.to_string())],
            );
            false
        }
    };

    let ctx =
        Arc::new(Context::new(client.clone(), options.settings.clone(), options.max_concurrent_runs, metrics.clone()));
    log::info("reconciling SimulationRuns", &[("kueue", &options.settings.kueue.to_string())]);
    let mut controller = Controller::new(runs, watcher::Config::default())
        .owns(Api::<Job>::all(client.clone()), watcher::Config::default())
        .owns(Api::<Pod>::all(client.clone()), watcher::Config::default());
    if options.settings.kueue {
        // Kueue's admission (or eviction) of a run's Workload wakes its reconcile.
        controller = controller.owns(Api::<Workload>::all(client.clone()), watcher::Config::default());
    }
    let run_controller = controller.graceful_shutdown_on(stop_or_lost()).run(reconcile, error_policy, ctx).for_each(
        |result| async move {
            if let Err(e) = result {
                log::warn("controller", &[("error", &e.to_string())]);
            }
        },
    );
    let sweep_controller = async {
        if with_sweeps {
            super::sweep::run(client.clone(), metrics, stop_or_lost()).await;
        }
    };
    futures_util::future::join(run_controller, sweep_controller).await;
    if leadership.is_some_and(|l| !*l.borrow()) {
        return Err(OperatorError::LostLeadership);
    }
    let _ = server.await;
    log::info("stopped", &[]);
    Ok(())
}

/// SIGTERM (Kubernetes) or SIGINT (a terminal).
async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = term.recv() => {}
                    _ = tokio::signal::ctrl_c() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

fn default_identity() -> String {
    let host = std::env::var("HOSTNAME").unwrap_or_else(|_| "sadesim-operator".into());
    format!("{host}-{}", std::process::id())
}
