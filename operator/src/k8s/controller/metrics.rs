//! The operator's Prometheus metrics and its HTTP endpoint (`/metrics`, `/healthz`).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::Histogram;
use prometheus_client::registry::Registry;
use sadesim_crds::status::Phase;

/// Label of the failure counter: the error's kind.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct ErrorLabels {
    pub error: String,
}

/// Label of the runs-by-phase gauge.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct PhaseLabels {
    pub phase: String,
}

/// Counters and gauges the reconciler updates.
#[derive(Debug)]
pub struct Metrics {
    /// Reconciles started.
    pub reconciles: Counter,
    /// Reconciles that failed, by error kind.
    pub failures: Family<ErrorLabels, Counter>,
    /// Runs known to this operator, by phase.
    pub runs: Family<PhaseLabels, Gauge>,
    /// Seconds from a run's creation to its admission from the queue.
    pub queue_wait: Histogram,
    /// Last phase of each run (uid -> phase), to keep `runs` exact.
    phases: Mutex<HashMap<String, Phase>>,
    registry: Registry,
}

impl Default for Metrics {
    fn default() -> Self {
        let mut registry = Registry::with_prefix("sadesim_operator");
        let reconciles = Counter::default();
        let failures = Family::<ErrorLabels, Counter>::default();
        let runs = Family::<PhaseLabels, Gauge>::default();
        // 1 s .. ~9 h.
        let queue_wait = Histogram::new([1.0, 5.0, 15.0, 60.0, 300.0, 900.0, 3600.0, 4.0 * 3600.0, 9.0 * 3600.0]);
        registry.register("reconciles", "Reconciles of SimulationRuns", reconciles.clone());
        registry.register("reconcile_failures", "Reconciles that failed, by error", failures.clone());
        registry.register("runs", "SimulationRuns by phase", runs.clone());
        registry.register("queue_wait_seconds", "Time from creation to admission", queue_wait.clone());
        Self { reconciles, failures, runs, queue_wait, phases: Mutex::default(), registry }
    }
}

impl Metrics {
    /// Records the phase of run `uid` (`None`: the run is gone).
    pub fn set_phase(&self, uid: &str, phase: Option<Phase>) {
        let mut phases = self.phases.lock().unwrap_or_else(|e| e.into_inner());
        let old = match phase {
            Some(p) => phases.insert(uid.to_string(), p),
            None => phases.remove(uid),
        };
        if old == phase {
            return;
        }
        if let Some(old) = old {
            self.runs.get_or_create(&PhaseLabels { phase: format!("{old:?}") }).dec();
        }
        if let Some(new) = phase {
            self.runs.get_or_create(&PhaseLabels { phase: format!("{new:?}") }).inc();
        }
    }

    /// Counts a failed reconcile.
    pub fn failed(&self, error: &str) {
        self.failures.get_or_create(&ErrorLabels { error: error.to_string() }).inc();
    }

    /// The Prometheus text exposition of every metric.
    pub fn encode(&self) -> String {
        let mut out = String::new();
        let _ = prometheus_client::encoding::text::encode(&mut out, &self.registry);
        out
    }
}

/// Serves `/metrics` and `/healthz` on `addr` until `shutdown` resolves.
///
/// # Errors
/// When `addr` cannot be bound (message names the address).
pub async fn serve(
    addr: SocketAddr,
    metrics: Arc<Metrics>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<tokio::task::JoinHandle<()>, String> {
    use axum::routing::get;
    let listener =
        tokio::net::TcpListener::bind(addr).await.map_err(|e| format!("--metrics-addr {addr}: cannot listen: {e}"))?;
    let app = axum::Router::new()
        .route(
            "/metrics",
            get(move || {
                let metrics = metrics.clone();
                async move {
                    (
                        [(
                            axum::http::header::CONTENT_TYPE,
                            "application/openmetrics-text; version=1.0.0; charset=utf-8",
                        )],
                        metrics.encode(),
                    )
                }
            }),
        )
        .route("/healthz", get(|| async { "ok\n" }));
    Ok(tokio::spawn(async move {
        if let Err(e) = axum::serve(listener, app).with_graceful_shutdown(shutdown).await {
            super::log::error("metrics server stopped", &[("error", &e.to_string())]);
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phases_are_counted_once_per_run() {
        let m = Metrics::default();
        m.set_phase("a", Some(Phase::Queued));
        m.set_phase("b", Some(Phase::Queued));
        m.set_phase("a", Some(Phase::Running));
        m.set_phase("a", Some(Phase::Running));
        m.set_phase("b", None);
        let text = m.encode();
        assert!(text.contains("sadesim_operator_runs{phase=\"Running\"} 1"), "{text}");
        assert!(text.contains("sadesim_operator_runs{phase=\"Queued\"} 0"), "{text}");
        m.reconciles.inc();
        m.failed("kube");
        let text = m.encode();
        assert!(text.contains("sadesim_operator_reconciles_total 1"), "{text}");
        assert!(text.contains("sadesim_operator_reconcile_failures_total{error=\"kube\"} 1"), "{text}");
    }
}
