//! Load generator for the airspace API (`sadesim bench --airspace`), and the small blocking
//! HTTP/1.1 client it and the service tests share.
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
use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::{Arc, Barrier, OnceLock};
use std::time::{Duration, Instant};

use serde_json::Value;

/// How long the client waits to connect, send or receive before giving up.
const IO_TIMEOUT: Duration = Duration::from_secs(10);
/// Largest response head (status line and headers) the client reads, bytes.
const MAX_HEAD_BYTES: usize = 64 * 1024;
/// Largest response body the client reads, bytes.
const MAX_BODY_BYTES: usize = 64 * 1024 * 1024;

/// One HTTP response.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HttpResponse {
    pub status: u16,
    /// Header names in lowercase, in the order received.
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl HttpResponse {
    /// The first header called `name` (any case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    /// The body as JSON.
    ///
    /// # Errors
    /// The body is not JSON.
    pub fn json(&self) -> Result<Value, serde_json::Error> {
        serde_json::from_slice(&self.body)
    }

    /// The body as text (invalid UTF-8 replaced), for messages.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// A blocking HTTP/1.1 client on one keep-alive TCP connection: requests carry a
/// `Content-Length`, responses must too (axum's JSON answers do). The connection is
/// re-opened for the next request after the server closed it (`Connection: close`) or
/// after an I/O error.
#[derive(Debug)]
pub struct HttpClient {
    addr: SocketAddr,
    conn: Option<BufReader<TcpStream>>,
}

impl HttpClient {
    /// Connects now (so that connecting is not part of the first request's time).
    ///
    /// # Errors
    /// The connection cannot be made.
    pub fn connect(addr: SocketAddr) -> io::Result<Self> {
        let mut client = Self { addr, conn: None };
        client.connection()?;
        Ok(client)
    }

    fn connection(&mut self) -> io::Result<&mut BufReader<TcpStream>> {
        if self.conn.is_none() {
            let stream = TcpStream::connect_timeout(&self.addr, IO_TIMEOUT)?;
            stream.set_nodelay(true)?;
            stream.set_read_timeout(Some(IO_TIMEOUT))?;
            stream.set_write_timeout(Some(IO_TIMEOUT))?;
            self.conn = Some(BufReader::new(stream));
        }
        Ok(self.conn.as_mut().expect("connected just above"))
    }

    /// `GET path`.
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn get(&mut self, path: &str) -> io::Result<HttpResponse> {
        self.request("GET", path, &[], b"")
    }

    /// `POST path` with a JSON body and, when given, `Authorization: Bearer <token>`.
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn post_json(&mut self, path: &str, token: Option<&str>, body: &str) -> io::Result<HttpResponse> {
        let auth = token.map(|t| format!("Bearer {t}"));
        let mut headers = vec![("Content-Type", "application/json")];
        headers.extend(auth.as_deref().map(|a| ("Authorization", a)));
        self.request("POST", path, &headers, body.as_bytes())
    }

    /// A request with a bearer token and no body (`POST /leases/{id}/renew`, `DELETE`).
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn with_token(&mut self, method: &str, path: &str, token: &str) -> io::Result<HttpResponse> {
        let auth = format!("Bearer {token}");
        self.request(method, path, &[("Authorization", &auth)], b"")
    }

    /// Any request; `Host` and `Content-Length` are added.
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn request(
        &mut self,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &[u8],
    ) -> io::Result<HttpResponse> {
        let mut head = format!("{method} {path} HTTP/1.1\r\nHost: {}\r\nContent-Length: {}\r\n", self.addr, body.len());
        for (name, value) in headers {
            head.push_str(&format!("{name}: {value}\r\n"));
        }
        head.push_str("\r\n");
        let mut bytes = head.into_bytes();
        bytes.extend_from_slice(body);
        self.send_raw(&bytes)
    }

    /// Sends `request` as it is (for malformed requests in tests) and reads one response.
    /// When writing fails (a server may answer and close before reading a huge body), the
    /// response is still read if there is one.
    ///
    /// # Errors
    /// Connection, timeout, or a response that is not HTTP/1.1 with a `Content-Length`.
    pub fn send_raw(&mut self, request: &[u8]) -> io::Result<HttpResponse> {
        let result = self.exchange(request);
        if result.as_ref().map_or(true, |r| r.header("connection").is_some_and(|c| c.eq_ignore_ascii_case("close"))) {
            self.conn = None;
        }
        result
    }

    fn exchange(&mut self, request: &[u8]) -> io::Result<HttpResponse> {
        let conn = self.connection()?;
        let written = conn.get_mut().write_all(request).and_then(|()| conn.get_mut().flush());
        match read_response(conn) {
            Ok(response) => Ok(response),
            Err(read_error) => Err(written.err().unwrap_or(read_error)),
        }
    }
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// Reads a status line, headers and a `Content-Length` body.
fn read_response(conn: &mut BufReader<TcpStream>) -> io::Result<HttpResponse> {
    let mut head_bytes = 0;
    let mut line = String::new();
    let mut read_line = |line: &mut String| -> io::Result<()> {
        line.clear();
        let n = conn.by_ref().take((MAX_HEAD_BYTES - head_bytes) as u64).read_line(line)?;
        head_bytes += n;
        if n == 0 {
            return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "the server closed the connection"));
        }
        if !line.ends_with('\n') {
            return Err(invalid(format!("response head longer than {MAX_HEAD_BYTES} bytes")));
        }
        Ok(())
    };
    read_line(&mut line)?;
    let status = line
        .strip_prefix("HTTP/1.1 ")
        .or_else(|| line.strip_prefix("HTTP/1.0 "))
        .and_then(|rest| rest.get(..3))
        .and_then(|code| code.parse::<u16>().ok())
        .ok_or_else(|| invalid(format!("not an HTTP/1.1 status line: {:?}", line.trim_end())))?;
    let mut headers = Vec::new();
    loop {
        read_line(&mut line)?;
        let text = line.trim_end_matches(['\r', '\n']);
        if text.is_empty() {
            break;
        }
        let (name, value) = text.split_once(':').ok_or_else(|| invalid(format!("malformed header line {text:?}")))?;
        headers.push((name.trim().to_ascii_lowercase(), value.trim().to_string()));
    }
    let mut response = HttpResponse { status, headers, body: Vec::new() };
    let length = match response.header("content-length") {
        Some(v) => v.parse::<usize>().map_err(|_| invalid(format!("bad Content-Length {v:?}")))?,
        None if status == 204 || status == 304 || status < 200 => 0,
        None => return Err(invalid(format!("response {status} without Content-Length (chunked is not supported)"))),
    };
    if length > MAX_BODY_BYTES {
        return Err(invalid(format!("response body of {length} bytes is over the client's limit")));
    }
    response.body = vec![0; length];
    conn.read_exact(&mut response.body)?;
    Ok(response)
}

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
