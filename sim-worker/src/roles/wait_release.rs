//! `sim-worker wait-release URL`: the pilot pod's init container. It polls the coordinator's
//! airspace API (`GET /healthz`) until `pilotsReleased` is true, then exits 0 and the
//! pilot's container starts: the cluster counterpart of `sadesim run` starting the pilot
//! process on the `pilotsReleased` event.
//!
//! # Guarantees
//! - Exits 0 only after an answer with `"pilotsReleased": true`.
//! - A coordinator not up yet (connection refused, DNS not there yet, a timeout) is waited
//!   for: the pilot's pod is created with the coordinator's. Only a malformed URL fails.
//!
//! # Caveats
//! There is no overall deadline: the run's own lifecycle bounds the wait (the operator
//! deletes the pilot Job when the run ends).

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::RoleError;

/// Between two polls.
pub const POLL: Duration = Duration::from_millis(200);
/// Connect, read and write timeout of one poll.
const TIMEOUT: Duration = Duration::from_secs(2);
/// How often a line says it is still waiting.
const REPORT_EVERY: Duration = Duration::from_secs(30);

/// `host:port` and path of an `http://` URL.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Target {
    pub authority: String,
    pub host: String,
    pub path: String,
}

/// Reads `http://host[:port][/path]` (port 80 when absent).
///
/// # Errors
/// Anything else, with what was expected.
pub fn parse_url(url: &str) -> Result<Target, RoleError> {
    let bad =
        |why: &str| RoleError::Protocol(format!("wait-release: URL {url:?} {why}; expected http://host:port/healthz"));
    let rest = url.strip_prefix("http://").ok_or_else(|| bad("is not http://"))?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    if authority.is_empty() {
        return Err(bad("has no host"));
    }
    let host = authority.rsplit_once(':').map_or(authority, |(h, _)| h).to_string();
    let authority = if authority.contains(':') { authority.to_string() } else { format!("{authority}:80") };
    Ok(Target { authority, host, path: path.to_string() })
}

/// Whether a `/healthz` body says the pilots are released (`None`: not the API's JSON).
pub fn released(body: &str) -> Option<bool> {
    let value: serde_json::Value = serde_json::from_str(body.trim()).ok()?;
    value.get("pilotsReleased")?.as_bool()
}

/// One GET: the body of a 200 answer, `None` for anything else.
fn get(target: &Target) -> Option<String> {
    let addr = target.authority.to_socket_addrs().ok()?.next()?;
    let mut stream = TcpStream::connect_timeout(&addr, TIMEOUT).ok()?;
    stream.set_read_timeout(Some(TIMEOUT)).ok()?;
    stream.set_write_timeout(Some(TIMEOUT)).ok()?;
    let request = format!("GET {} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n", target.path, target.host);
    stream.write_all(request.as_bytes()).ok()?;
    let mut answer = String::new();
    stream.read_to_string(&mut answer).ok()?;
    let (head, body) = answer.split_once("\r\n\r\n")?;
    head.starts_with("HTTP/1.1 200").then(|| body.to_string())
}

/// Polls `url` every [`POLL`] until the pilots are released (`Ok`), or `stop` is set
/// (an error: the pilot must not start).
///
/// # Errors
/// A malformed URL, or `stop`.
pub fn run(url: &str, stop: &AtomicBool) -> Result<(), RoleError> {
    let target = parse_url(url)?;
    let started = Instant::now();
    let mut reported = Instant::now();
    eprintln!("wait-release: waiting for the coordinator to release the pilots ({url})");
    loop {
        if stop.load(Ordering::Relaxed) {
            return Err(RoleError::NotConnected("wait-release: interrupted before the pilots were released".into()));
        }
        if get(&target).as_deref().and_then(released) == Some(true) {
            eprintln!("wait-release: pilots released after {:.1} s", started.elapsed().as_secs_f64());
            return Ok(());
        }
        if reported.elapsed() >= REPORT_EVERY {
            eprintln!("wait-release: still waiting ({:.0} s)", started.elapsed().as_secs_f64());
            reported = Instant::now();
        }
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    #[test]
    fn urls_are_read_with_their_port_and_path() {
        let t = parse_url("http://run-airspace.ns.svc:8480/healthz").unwrap();
        assert_eq!(
            t,
            Target {
                authority: "run-airspace.ns.svc:8480".into(),
                host: "run-airspace.ns.svc".into(),
                path: "/healthz".into()
            }
        );
        assert_eq!(parse_url("http://h").unwrap().authority, "h:80");
        for bad in ["https://h/healthz", "h:1/healthz", "http:///x"] {
            let e = parse_url(bad).unwrap_err().to_string();
            assert!(e.contains(bad) && e.contains("expected http://"), "{e}");
        }
    }

    #[test]
    fn only_a_true_flag_releases() {
        assert_eq!(released(r#"{"status":"ok","simTimeS":0.0,"pilotsReleased":false}"#), Some(false));
        assert_eq!(released(r#"{"status":"ok","simTimeS":3.0,"pilotsReleased":true}"#), Some(true));
        assert_eq!(released(r#"{"status":"ok","simTimeS":3.0}"#), None);
        assert_eq!(released("<html>"), None);
    }

    /// A server that answers "not released" twice, then "released": `run` returns only
    /// after the third poll.
    #[test]
    fn waits_until_the_coordinator_says_released() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let server = std::thread::spawn(move || {
            for i in 0..3 {
                let (mut s, _) = listener.accept().unwrap();
                let mut buf = [0u8; 1024];
                let n = s.read(&mut buf).unwrap();
                assert!(String::from_utf8_lossy(&buf[..n]).starts_with("GET /healthz HTTP/1.1\r\n"));
                let body = format!(r#"{{"status":"ok","simTimeS":0.0,"pilotsReleased":{}}}"#, i == 2);
                let answer = format!("HTTP/1.1 200 OK\r\nContent-Length: {}\r\n\r\n{body}", body.len());
                s.write_all(answer.as_bytes()).unwrap();
            }
            3
        });
        run(&format!("http://127.0.0.1:{port}/healthz"), &AtomicBool::new(false)).unwrap();
        assert_eq!(server.join().unwrap(), 3, "released on the third answer, not before");
    }

    #[test]
    fn a_stop_ends_the_wait_with_an_error() {
        // Nothing listens on port 9 of localhost: the poll keeps failing until the stop.
        let e = run("http://127.0.0.1:9/healthz", &AtomicBool::new(true)).unwrap_err();
        assert!(e.to_string().contains("interrupted"), "{e}");
    }
}
