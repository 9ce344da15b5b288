//! Load generator for the airspace API (`sadesim bench --airspace`).
//!
//! [`run`] sends an open-loop stream of requests: request `k` is due at `k / rate` seconds
//! after the start whatever happened to the earlier ones, spread round-robin over keep-alive
//! connections, one thread each. Latency is measured from the due time to the end of the
//! answer, so a slow answer that delays the next request on its connection is counted in
//! that request's latency too (no coordinated omission).
//!
//! The mix assumes the service serves the Chicago case study (`examples/chicago-museum.yaml`):
//! zone [`ZONE`], groups `public-safety`, `journalists` and `recreational` with the
//! example's inline credentials. Every answer is checked (status, and the verdict and
//! reason of zone requests): anything unexpected counts as an error.

use std::fmt;
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Barrier, OnceLock};
use std::time::{Duration, Instant};

use serde_json::Value;
use sim_worker::airspace::service::client::{HttpClient, HttpResponse};

/// The zone the load's entry requests ask for (the Chicago example's).
pub const ZONE: &str = "museum-tfr";

/// What the load generator measured.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadReport {
    pub target_rate_per_s: f64,
    pub seconds: f64,
    pub connections: usize,
    /// Requests sent (or attempted, when a connection failed).
    pub requests: u64,
    /// Requests that got an HTTP response (expected or not).
    pub answered: u64,
    /// Requests without a response, or with an unexpected status or verdict.
    pub errors: u64,
    /// The first few errors, for diagnosis.
    pub error_samples: Vec<String>,
    /// Entry requests answered `granted` / `denied` as expected.
    pub granted: u64,
    pub denied: u64,
    /// Latency percentiles from each request's due time to the end of its answer, ms.
    pub p50_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    /// Wall time from the first due time to the last answer, s.
    pub wall_s: f64,
    /// Answered requests per wall second.
    pub achieved_rate_per_s: f64,
}

impl fmt::Display for LoadReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "airspace API load: {} requests in {:.2} s over {} keep-alive connections (target {:.0}/s, achieved {:.1}/s)",
            self.requests, self.wall_s, self.connections, self.target_rate_per_s, self.achieved_rate_per_s
        )?;
        writeln!(
            f,
            "  answered {}, errors {}; entry verdicts as expected: {} granted, {} denied",
            self.answered, self.errors, self.granted, self.denied
        )?;
        write!(
            f,
            "  latency from due time: p50 {:.3} ms, p90 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
            self.p50_ms, self.p90_ms, self.p99_ms, self.max_ms
        )?;
        for e in &self.error_samples {
            write!(f, "\n  error: {e}")?;
        }
        Ok(())
    }
}

/// What an answer must be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Expect {
    /// 200 with `verdict: granted`.
    Granted,
    /// 200 with `verdict: denied` and this reason.
    Denied(&'static str),
    /// 200 with a JSON body.
    Ok,
}

/// One request of the mix.
#[derive(Debug, Clone, PartialEq)]
struct Call {
    method: &'static str,
    path: String,
    token: Option<&'static str>,
    body: Option<String>,
    expect: Expect,
}

/// Request `k` of the mix (repeats every 10): 3 entry requests DPS drones are granted, one
/// with a band below the zone's minimum (`unsafe_altitude`), two from journalists and one
/// from a hobbyist (`insufficient_credentials`), a journalist presenting the DPS token
/// (`insufficient_credentials`), `GET /zones`, and `GET /events` from the connection's
/// cursor.
fn call(k: u64, events_since: u64) -> Call {
    let round = k / 10;
    let entry = |drone: String, operator: &str, token: &'static str, band: (f64, f64), expect| {
        Call {
        method: "POST",
        path: format!("/zones/{ZONE}/requests"),
        token: Some(token),
        body: Some(
            serde_json::json!({"drone": drone, "operator": operator, "altitude": {"minAglM": band.0, "maxAglM": band.1}})
                .to_string(),
        ),
        expect,
    }
    };
    const DPS: &str = "dps-token-local-only";
    const NEWS: &str = "news-token-local-only";
    const HOBBY: &str = "hobby-token-local-only";
    const CREDENTIALS: Expect = Expect::Denied("insufficient_credentials");
    match k % 10 {
        0..=2 => {
            entry(format!("public-safety-{}", (round + k) % 5), "chicago-dps", DPS, (107.0, 121.0), Expect::Granted)
        }
        3 => entry(
            format!("public-safety-{}", round % 5),
            "chicago-dps",
            DPS,
            (30.0, 60.0),
            Expect::Denied("unsafe_altitude"),
        ),
        4 | 5 => entry(format!("journalists-{}", (round + k) % 10), "wgn-news", NEWS, (95.0, 110.0), CREDENTIALS),
        6 => entry(format!("recreational-{}", round % 17), "hobbyists", HOBBY, (5.0, 27.0), CREDENTIALS),
        7 => entry(format!("journalists-{}", round % 10), "chicago-dps", DPS, (107.0, 121.0), CREDENTIALS),
        8 => Call { method: "GET", path: "/zones".into(), token: None, body: None, expect: Expect::Ok },
        _ => Call {
            method: "GET",
            path: format!("/events?since={events_since}&limit=100"),
            token: None,
            body: None,
            expect: Expect::Ok,
        },
    }
}

/// Checks an answer against what the call expects; returns the JSON body.
fn check(call: &Call, response: &HttpResponse) -> Result<Value, String> {
    let what = format!("{} {}", call.method, call.path);
    if response.status != 200 {
        return Err(format!("{what}: status {} ({})", response.status, response.text()));
    }
    let body = response.json().map_err(|e| format!("{what}: body is not JSON: {e}"))?;
    let verdict = body.get("verdict").and_then(Value::as_str);
    let reason = body.get("reason").and_then(Value::as_str);
    match call.expect {
        Expect::Granted if verdict != Some("granted") => Err(format!("{what}: expected granted, got {body}")),
        Expect::Denied(want) if verdict != Some("denied") || reason != Some(want) => {
            Err(format!("{what}: expected denied ({want}), got {body}"))
        }
        _ => Ok(body),
    }
}

/// What one connection's thread measured.
#[derive(Debug, Default)]
struct ConnectionTally {
    requests: u64,
    answered: u64,
    errors: u64,
    error_samples: Vec<String>,
    granted: u64,
    denied: u64,
    latencies_ms: Vec<f64>,
    last_answer: Option<Instant>,
}

impl ConnectionTally {
    fn error(&mut self, message: String) {
        self.errors += 1;
        if self.error_samples.len() < 5 {
            self.error_samples.push(message);
        }
    }
}

/// Sends `rate_per_s * seconds` requests of the Chicago mix to the API at `addr` over
/// `connections` keep-alive connections, open-loop (see the module doc), and reports.
/// Blocks for about `seconds`.
pub fn run(addr: SocketAddr, rate_per_s: f64, seconds: f64, connections: usize) -> LoadReport {
    let connections = connections.max(1);
    let rate = rate_per_s.max(f64::MIN_POSITIVE);
    let total = (rate * seconds.max(0.0)).round() as u64;
    // Everyone connects first; the clock starts when the last connection is up.
    let ready = Arc::new(Barrier::new(connections));
    let start_cell = Arc::new(OnceLock::<Instant>::new());
    let threads: Vec<_> = (0..connections)
        .map(|c| {
            let (ready, start_cell) = (ready.clone(), start_cell.clone());
            std::thread::Builder::new()
                .name(format!("airspace-load-{c}"))
                .spawn(move || {
                    let client = HttpClient::connect(addr);
                    ready.wait();
                    let start = *start_cell.get_or_init(Instant::now);
                    drive(client, start, (c as u64..total).step_by(connections), rate)
                })
                .expect("spawn a load thread")
        })
        .collect();
    let tallies: Vec<ConnectionTally> =
        threads.into_iter().map(|t| t.join().expect("a load thread panicked")).collect();

    let mut report = LoadReport {
        target_rate_per_s: rate_per_s,
        seconds,
        connections,
        requests: 0,
        answered: 0,
        errors: 0,
        error_samples: Vec::new(),
        granted: 0,
        denied: 0,
        p50_ms: 0.0,
        p90_ms: 0.0,
        p99_ms: 0.0,
        max_ms: 0.0,
        wall_s: 0.0,
        achieved_rate_per_s: 0.0,
    };
    let mut latencies = Vec::new();
    let mut last_answer = None;
    for t in tallies {
        report.requests += t.requests;
        report.answered += t.answered;
        report.errors += t.errors;
        report.granted += t.granted;
        report.denied += t.denied;
        report.error_samples.extend(t.error_samples);
        latencies.extend(t.latencies_ms);
        last_answer = last_answer.max(t.last_answer);
    }
    report.error_samples.truncate(10);
    latencies.sort_by(f64::total_cmp);
    report.p50_ms = percentile(&latencies, 0.50);
    report.p90_ms = percentile(&latencies, 0.90);
    report.p99_ms = percentile(&latencies, 0.99);
    report.max_ms = latencies.last().copied().unwrap_or(0.0);
    if let (Some(start), Some(end)) = (start_cell.get(), last_answer) {
        report.wall_s = end.duration_since(*start).as_secs_f64();
        report.achieved_rate_per_s = report.answered as f64 / report.wall_s.max(1e-9);
    }
    report
}

/// One connection's loop: waits for each request's due time, sends it, checks the answer.
fn drive(
    client: io::Result<HttpClient>,
    start: Instant,
    ks: impl Iterator<Item = u64>,
    rate_per_s: f64,
) -> ConnectionTally {
    let mut tally = ConnectionTally::default();
    let mut client = match client {
        Ok(c) => c,
        Err(e) => {
            for _ in ks {
                tally.requests += 1;
                tally.error(format!("cannot connect: {e}"));
            }
            return tally;
        }
    };
    let mut events_since = 0;
    for k in ks {
        let due = start + Duration::from_secs_f64(k as f64 / rate_per_s);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let call = call(k, events_since);
        tally.requests += 1;
        let result = match &call.body {
            Some(body) => client.post_json(&call.path, call.token, body),
            None => client.get(&call.path),
        };
        let answered_at = Instant::now();
        let response = match result {
            Ok(r) => r,
            Err(e) => {
                tally.error(format!("{} {}: {e}", call.method, call.path));
                continue;
            }
        };
        tally.answered += 1;
        tally.last_answer = Some(answered_at);
        tally.latencies_ms.push(answered_at.duration_since(due).as_secs_f64() * 1000.0);
        match check(&call, &response) {
            Ok(body) => match call.expect {
                Expect::Granted => tally.granted += 1,
                Expect::Denied(_) => tally.denied += 1,
                Expect::Ok => {
                    if let Some(next) = body.get("next").and_then(Value::as_u64) {
                        events_since = next;
                    }
                }
            },
            Err(message) => tally.error(message),
        }
    }
    tally
}

/// Nearest-rank percentile of sorted values (0 when empty).
fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = (p * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}
