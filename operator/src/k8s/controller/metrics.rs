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
    /// Runs planned (once per SimulationRun generation: the controller caches plans).
    pub plans: Counter,
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
        let plans = Counter::default();
        let failures = Family::<ErrorLabels, Counter>::default();
        let runs = Family::<PhaseLabels, Gauge>::default();
        // 1 s .. ~9 h.
        let queue_wait = Histogram::new([1.0, 5.0, 15.0, 60.0, 300.0, 900.0, 3600.0, 4.0 * 3600.0, 9.0 * 3600.0]);
        registry.register("reconciles", "Reconciles of SimulationRuns", reconciles.clone());
        registry.register("plans", "Runs planned (once per SimulationRun generation)", plans.clone());
        registry.register("reconcile_failures", "Reconciles that failed, by error", failures.clone());
        registry.register("runs", "SimulationRuns by phase", runs.clone());
        registry.register("queue_wait_seconds", "Time from creation to admission", queue_wait.clone());
        Self { reconciles, plans, failures, runs, queue_wait, phases: Mutex::default(), registry }
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
/// A plain HTTP/1.1 responder on tokio, one request per connection (`Connection: close`):
/// Prometheus and the kubelet's probes need nothing more, and the operator then links no
/// HTTP server framework.
///
/// # Errors
/// When `addr` cannot be bound (message names the address).
pub async fn serve(
    addr: SocketAddr,
    metrics: Arc<Metrics>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<tokio::task::JoinHandle<()>, ListenError> {
    let listener = tokio::net::TcpListener::bind(addr).await.map_err(|source| ListenError { addr, source })?;
    Ok(tokio::spawn(async move {
        tokio::pin!(shutdown);
        loop {
            tokio::select! {
                () = &mut shutdown => break,
                accepted = listener.accept() => match accepted {
                    Ok((stream, _)) => {
                        tokio::spawn(answer(stream, metrics.clone()));
                    }
                    Err(e) => super::log::error("metrics server: accept failed", &[("error", &e.to_string())]),
                },
            }
        }
    }))
}

/// The metrics address cannot be listened on (taken, or not an address of this host).
#[derive(Debug, thiserror::Error)]
#[error("--metrics-addr {addr}: cannot listen: {source}")]
pub struct ListenError {
    pub addr: SocketAddr,
    #[source]
    pub source: std::io::Error,
}

/// Most bytes of a request head read before answering (probes send about 100).
const MAX_REQUEST_HEAD: usize = 8 * 1024;
/// Longest wait for a client's request head.
const REQUEST_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// Reads one request head and writes the answer; errors only end the connection.
async fn answer(mut stream: tokio::net::TcpStream, metrics: Arc<Metrics>) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut head = Vec::with_capacity(512);
    let mut buf = [0u8; 1024];
    let read = tokio::time::timeout(REQUEST_TIMEOUT, async {
        while !head.windows(4).any(|w| w == b"\r\n\r\n") && head.len() < MAX_REQUEST_HEAD {
            match stream.read(&mut buf).await {
                Ok(0) | Err(_) => return false,
                Ok(n) => head.extend_from_slice(&buf[..n]),
            }
        }
        true
    })
    .await;
    if !matches!(read, Ok(true)) {
        return;
    }
    let request_line = head.split(|&b| b == b'\n').next().unwrap_or_default();
    let (status, content_type, body) = route(&String::from_utf8_lossy(request_line), &metrics);
    let response = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = stream.write_all(response.as_bytes()).await;
    let _ = stream.shutdown().await;
}

/// The answer to a request line (`GET /metrics HTTP/1.1`): status, content type, body.
fn route(request_line: &str, metrics: &Metrics) -> (&'static str, &'static str, String) {
    let mut parts = request_line.split_ascii_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let path = target.split('?').next().unwrap_or("");
    match (method, path) {
        ("GET", "/metrics") => {
            ("200 OK", "application/openmetrics-text; version=1.0.0; charset=utf-8", metrics.encode())
        }
        ("GET", "/healthz") => ("200 OK", "text/plain; charset=utf-8", "ok\n".into()),
        (_, "/metrics" | "/healthz") => ("405 Method Not Allowed", "text/plain; charset=utf-8", "GET only\n".into()),
        _ => ("404 Not Found", "text/plain; charset=utf-8", "not found: try /metrics or /healthz\n".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A real GET over loopback, as Prometheus and the kubelet send it.
    fn get(addr: SocketAddr, path: &str) -> String {
        use std::io::{Read, Write};
        let mut s = std::net::TcpStream::connect(addr).unwrap();
        write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\nUser-Agent: test\r\n\r\n").unwrap();
        let mut out = String::new();
        s.read_to_string(&mut out).unwrap();
        out
    }

    #[test]
    fn the_server_answers_metrics_health_and_unknown_paths_then_stops() {
        let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
        let metrics = Arc::new(Metrics::default());
        metrics.set_phase("a", Some(Phase::Running));
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let handle = rt.block_on(serve(addr, metrics, async move {
            let _ = stopped.await;
        }));
        let handle = handle.unwrap();
        let client = std::thread::spawn(move || (get(addr, "/metrics"), get(addr, "/healthz"), get(addr, "/nope")));
        let (m, h, n) = rt.block_on(async {
            loop {
                if client.is_finished() {
                    break client.join().unwrap();
                }
                tokio::time::sleep(std::time::Duration::from_millis(5)).await;
            }
        });
        assert!(m.starts_with("HTTP/1.1 200 OK\r\n"), "{m}");
        assert!(m.contains("Content-Type: application/openmetrics-text"), "{m}");
        assert!(m.contains("sadesim_operator_runs{phase=\"Running\"} 1"), "{m}");
        assert!(h.starts_with("HTTP/1.1 200 OK") && h.ends_with("\r\n\r\nok\n"), "{h}");
        assert!(n.starts_with("HTTP/1.1 404"), "{n}");
        stop.send(()).unwrap();
        rt.block_on(handle).unwrap();
        assert!(std::net::TcpStream::connect(addr).is_err(), "the listener closed with the shutdown");
    }

    #[test]
    fn only_get_is_answered() {
        let m = Metrics::default();
        assert_eq!(route("POST /metrics HTTP/1.1", &m).0, "405 Method Not Allowed");
        assert_eq!(route("GET /healthz?x=1 HTTP/1.1", &m).0, "200 OK");
        assert_eq!(route("", &m).0, "404 Not Found");
    }

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
