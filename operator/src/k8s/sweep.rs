//! The SimulationSweep controller: watches SimulationSweeps and the SimulationRuns they
//! own, and reconciles each sweep: read its runs (by label) -> decide (pure,
//! [`lifecycle`]) -> create the next runs up to the sweep's parallelism -> once every run
//! ended, archive the sweep's report ([`report`]) -> write status on the status
//! subresource. It runs beside the SimulationRun controller
//! ([`crate::k8s::controller`]), under the same leader election; the runs it creates are
//! then reconciled by that controller like any other.
//!
//! Modules: [`lifecycle`] (what to create, the status), [`reconcile`] (the I/O shell),
//! [`report`] (`sweep.json` and `sweep.html` beside the runs' archives).

pub mod lifecycle;
pub mod reconcile;
pub mod report;

#[cfg(test)]
mod tests;

use std::future::Future;
use std::sync::Arc;

use futures_util::StreamExt;
use kube::runtime::{Controller, watcher};
use kube::{Api, Client};
use sadesim_crds::{SimulationRun, SimulationSweep};

use self::reconcile::{Context, error_policy, reconcile};
use crate::k8s::controller::log;
use crate::k8s::controller::metrics::Metrics;

/// Reconciles every SimulationSweep until `shutdown` resolves (then finishes the reconciles
/// in flight). A change to a run a sweep owns (its phase, its verdict) wakes the sweep.
pub async fn run(client: Client, metrics: Arc<Metrics>, shutdown: impl Future<Output = ()> + Send + Sync + 'static) {
    let ctx = Arc::new(Context::new(client.clone(), metrics));
    log::info("reconciling SimulationSweeps", &[]);
    Controller::new(Api::<SimulationSweep>::all(client.clone()), watcher::Config::default())
        .owns(Api::<SimulationRun>::all(client), watcher::Config::default())
        .graceful_shutdown_on(shutdown)
        .run(reconcile, error_policy, ctx)
        .for_each(|result| async move {
            if let Err(e) = result {
                log::warn("sweep controller", &[("error", &e.to_string())]);
            }
        })
        .await;
}
