//! The thin I/O shell around [`lifecycle::decide`]: read (the sweep's runs, by label),
//! decide (pure), then act in a fixed order — create the next runs, write the report once
//! every run ended ([`super::report`], on a blocking thread), the status on the status
//! subresource. Each step is one kind of API call; the order is what the tests assert.

use std::sync::Arc;
use std::time::Duration;

use k8s_openapi::jiff::Timestamp;
use kube::api::{Api, ListParams, Patch, PatchParams, PostParams};
use kube::runtime::controller::Action;
use kube::{Client, ResourceExt};
use sadesim_crds::SimulationRun;
use sadesim_crds::sweep::{Expansion, SWEEP_LABEL, SimulationSweep, SimulationSweepStatus, SweepPhase};
use serde_json::json;

use super::{lifecycle, report};
use crate::k8s::controller::log;
use crate::k8s::controller::metrics::Metrics;
use crate::k8s::controller::reconcile::MANAGER;

/// How often a running sweep is looked at without any change to its runs (a safety net:
/// every change of a run it owns wakes it at once).
const RUNNING_RECHECK: Duration = Duration::from_secs(300);

/// How soon a report that could not be written is tried again.
const REPORT_RETRY: Duration = Duration::from_secs(60);

/// Why a sweep's reconcile failed (it is retried with backoff).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A call to the API server failed.
    #[error("failed to {what}: {source}")]
    Kube {
        what: String,
        #[source]
        source: kube::Error,
    },
    /// The sweep has no namespace (SimulationSweeps are namespaced; the watch always sets it).
    #[error("sweep {0} has no namespace")]
    NoNamespace(String),
}

fn kube_err(what: impl Into<String>) -> impl FnOnce(kube::Error) -> Error {
    let what = what.into();
    move |source| Error::Kube { what, source }
}

/// What every sweep reconcile shares.
pub struct Context {
    pub client: Client,
    /// The operator's metrics (reconcile failures are counted under `sweep`).
    pub metrics: Arc<Metrics>,
    /// The wall clock (fixed in tests).
    pub clock: Box<dyn Fn() -> Timestamp + Send + Sync>,
}

impl std::fmt::Debug for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Context").finish_non_exhaustive()
    }
}

impl Context {
    pub fn new(client: Client, metrics: Arc<Metrics>) -> Self {
        Self { client, metrics, clock: Box::new(Timestamp::now) }
    }
}

/// The label selector of a sweep's runs.
pub fn selector(sweep: &str) -> String {
    format!("{SWEEP_LABEL}={sweep}")
}

/// Reconciles one sweep (the controller's entry point).
///
/// # Errors
/// See [`Error`]; the controller retries with backoff.
pub async fn reconcile(sweep: Arc<SimulationSweep>, ctx: Arc<Context>) -> Result<Action, Error> {
    let name = sweep.name_any();
    let ns = sweep.namespace().ok_or_else(|| Error::NoNamespace(name.clone()))?;
    let now = (ctx.clock)();
    let runs: Api<SimulationRun> = Api::namespaced(ctx.client.clone(), &ns);

    // Read: the sweep's runs (an invalid sweep has none to look at).
    let expansion = lifecycle::expansion_of(&sweep);
    let existing = match &expansion {
        Ok(_) => {
            let lp = ListParams::default().labels(&selector(&name));
            runs.list(&lp).await.map_err(kube_err(format!("list the runs of sweep {ns}/{name}")))?.items
        }
        Err(_) => Vec::new(),
    };
    let mut d = lifecycle::decide(&sweep, &expansion, &existing, now);

    // 1. The next runs, each created once (a run that already exists was created by an
    //    earlier reconcile whose result the watch had not shown yet: nothing to do).
    let params = PostParams { field_manager: Some(MANAGER.into()), ..Default::default() };
    for run in &d.create {
        let run_name = run.name_any();
        match runs.create(&params, run).await {
            Ok(_) => log::info("created", &[("sweep", &format!("{ns}/{name}")), ("run", &run_name)]),
            Err(kube::Error::Api(e)) if e.code == 409 => {}
            Err(e) => return Err(kube_err(format!("create run {ns}/{run_name} of sweep {name}"))(e)),
        }
    }
    // 2. The report, once every run ended and until it is written.
    let mut retry_report = false;
    if d.report_due
        && let Ok(expansion) = &expansion
    {
        let generation = sweep.metadata.generation;
        match write_report(&sweep, expansion, &existing).await {
            Ok(Some(url)) => {
                lifecycle::reported(&mut d.status, &url, now, generation);
                log::info("reported", &[("sweep", &format!("{ns}/{name}")), ("report", &url)]);
            }
            Ok(None) => lifecycle::not_reported(&mut d.status, "NoArchive", report::NO_ARCHIVE, now, generation),
            Err(message) => {
                lifecycle::not_reported(&mut d.status, "ArchiveFailed", &message, now, generation);
                log::warn("sweep report failed", &[("sweep", &format!("{ns}/{name}")), ("error", &message)]);
                retry_report = true;
            }
        }
    }
    // 3. Status, on the status subresource, only when it changed.
    let previous = sweep.status.clone().unwrap_or_default();
    if d.status != previous {
        write_status(&ctx.client, &ns, &name, &d.status).await?;
        if previous.phase != d.status.phase {
            let phase = d.status.phase.map(|p| format!("{p:?}")).unwrap_or_default();
            let message = d.status.message.clone().unwrap_or_default();
            log::info("phase", &[("sweep", &format!("{ns}/{name}")), ("phase", &phase), ("message", &message)]);
        }
    }
    Ok(match d.status.phase {
        _ if retry_report => Action::requeue(REPORT_RETRY),
        Some(SweepPhase::Running) => Action::requeue(RUNNING_RECHECK),
        _ => Action::await_change(),
    })
}

/// Writes the sweep's report ([`report::write`]) on a blocking thread: the archive drives
/// its own runtime, which cannot start on the reconcile's. Called once every run of the
/// sweep ended and while `status.report` is unset.
///
/// Returns where the report was archived, `None` when the base run has no archive.
///
/// # Errors
/// Why the report could not be written (the reconcile tries again after
/// [`REPORT_RETRY`]).
async fn write_report(
    sweep: &SimulationSweep,
    expansion: &Expansion,
    runs: &[SimulationRun],
) -> Result<Option<String>, String> {
    let (sweep, expansion, runs) = (sweep.clone(), expansion.clone(), runs.to_vec());
    tokio::task::spawn_blocking(move || report::write(&sweep, &expansion, &runs))
        .await
        .map_err(|e| format!("the sweep report writer stopped: {e}"))?
}

/// Writes `status` on the sweep's status subresource (server-side apply, the operator's
/// field manager).
async fn write_status(client: &Client, ns: &str, name: &str, status: &SimulationSweepStatus) -> Result<(), Error> {
    let sweeps: Api<SimulationSweep> = Api::namespaced(client.clone(), ns);
    let patch = json!({
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationSweep",
        "status": status,
    });
    sweeps
        .patch_status(name, &PatchParams::apply(MANAGER).force(), &Patch::Apply(&patch))
        .await
        .map_err(kube_err(format!("write the status of sweep {ns}/{name}")))?;
    Ok(())
}

/// What the controller does after a failed reconcile: count it, log it, retry.
pub fn error_policy(sweep: Arc<SimulationSweep>, error: &Error, ctx: Arc<Context>) -> Action {
    ctx.metrics.failed("sweep");
    log::warn(
        "sweep reconcile failed",
        &[
            ("sweep", &format!("{}/{}", sweep.namespace().unwrap_or_default(), sweep.name_any())),
            ("error", &error.to_string()),
        ],
    );
    Action::requeue(Duration::from_secs(15))
}
