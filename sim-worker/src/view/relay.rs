//! The renderer pod's side of the pose stream: it follows the coordinator's `/live`
//! Server-Sent Events and republishes every frame and event into its own [`Feed`], which
//! its browsers read. The coordinator then serves one stream whatever the number of
//! browsers, and a slow browser is the renderer's problem, never the simulation's.
//!
//! Plain HTTP/1.0 over a `TcpStream`: the response is the event stream itself, not chunked,
//! ending when the coordinator closes it (the run ended, the pod went away).

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use super::Feed;

/// How long a read may wait before the stop flag is looked at again.
const POLL: Duration = Duration::from_millis(500);

/// Why one connection to the coordinator ended.
#[derive(Debug, thiserror::Error)]
pub enum RelayError {
    #[error("cannot reach the coordinator's live stream at {addr}: {source}")]
    Connect { addr: String, source: std::io::Error },
    #[error("the coordinator's live stream at {addr} answered {status:?}, expected HTTP 200")]
    Status { addr: String, status: String },
    #[error("reading the coordinator's live stream at {addr}: {source}")]
    Read { addr: String, source: std::io::Error },
}

/// Follows `http://<addr>/live` into `feed` until the stream ends (`Ok`, the coordinator
/// closed it) or `stop` is set.
///
/// # Errors
/// [`RelayError`]: the connection failed, the answer is not a stream, or a read failed.
pub fn follow(addr: &str, feed: &Feed, stop: &AtomicBool) -> Result<(), RelayError> {
    let connect = |source| RelayError::Connect { addr: addr.to_string(), source };
    let read_err = |source| RelayError::Read { addr: addr.to_string(), source };
    let target =
        addr.to_socket_addrs().map_err(connect)?.next().ok_or_else(|| connect(std::io::Error::other("no address")))?;
    let mut stream = TcpStream::connect_timeout(&target, Duration::from_secs(5)).map_err(connect)?;
    stream.set_read_timeout(Some(POLL)).map_err(connect)?;
    write!(stream, "GET /live HTTP/1.0\r\nHost: {addr}\r\nAccept: text/event-stream\r\n\r\n").map_err(connect)?;
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    let mut headers_done = false;
    let mut status_seen = false;
    let (mut event, mut data) = (String::new(), String::new());
    while !stop.load(Ordering::Relaxed) {
        match reader.read_line(&mut line) {
            Ok(0) => return Ok(()),
            Ok(_) if !line.ends_with('\n') => continue, // a partial line: read on
            Ok(_) => {}
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => continue,
            Err(e) => return Err(read_err(e)),
        }
        let text = line.trim_end_matches(['\r', '\n']);
        if !status_seen {
            if text.split_whitespace().nth(1) != Some("200") {
                return Err(RelayError::Status { addr: addr.to_string(), status: text.to_string() });
            }
            status_seen = true;
        } else if !headers_done {
            headers_done = text.is_empty();
        } else if text.is_empty() {
            // The end of one event (SSE: a blank line dispatches it).
            match event.as_str() {
                "frame" => feed.publish_frame(std::mem::take(&mut data).into()),
                "event" => feed.publish_event(std::mem::take(&mut data).into()),
                _ => data.clear(), // `lagged`: this relay missed events; its browsers will not know which
            }
            event.clear();
        } else if let Some(name) = text.strip_prefix("event:") {
            event = name.trim_start().to_string();
        } else if let Some(value) = text.strip_prefix("data:") {
            if !data.is_empty() {
                data.push('\n');
            }
            data.push_str(value.strip_prefix(' ').unwrap_or(value));
        }
        // Other lines (`:` keep-alive comments, `id:`, `retry:`) carry nothing for us.
        line.clear();
    }
    Ok(())
}

/// Follows the coordinator's stream for the whole life of the renderer: reconnects every
/// `retry` after a failure or the end of a stream (the coordinator may start after the
/// renderer, or restart), telling `log` what happened once per change.
pub fn follow_forever(addr: &str, feed: &Feed, stop: &AtomicBool, retry: Duration, log: &mut dyn FnMut(&str)) {
    let mut last = String::new();
    while !stop.load(Ordering::Relaxed) {
        let said = match follow(addr, feed, stop) {
            Ok(()) => format!("the live stream at {addr} ended; waiting for it again"),
            Err(e) => format!("{e}; retrying every {} s", retry.as_secs_f64()),
        };
        if said != last {
            log(&said);
            last = said;
        }
        std::thread::sleep(retry);
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::view::{Content, Source, server};

    #[test]
    fn a_relay_republishes_the_coordinators_frames_and_events() {
        let upstream = Feed::new();
        upstream.publish_event(r#"{"timeS":0.0,"event":"runStarted","drones":1,"shards":1}"#.into());
        upstream.publish_frame(r#"{"t":1.5,"p":[1,2,3]}"#.into());
        let content = Content {
            scene_json: Arc::new(b"{}".to_vec()),
            world_glb: None,
            source: Source::Live(upstream.clone()),
            frames: None,
        };
        let coordinator = server::start("127.0.0.1:0".parse().unwrap(), content).unwrap();
        let renderer = Feed::new();
        let mut seen = renderer.subscribe();
        let stop = Arc::new(AtomicBool::new(false));
        let (addr, feed, flag) = (coordinator.addr.to_string(), renderer.clone(), stop.clone());
        let relay = std::thread::spawn(move || follow(&addr, &feed, &flag));
        // The backlog event and the current frame arrive, then what is published later.
        let event = seen.events.blocking_recv().unwrap();
        assert!(event.contains("runStarted"), "{event}");
        wait_for(|| renderer.latest_frame().is_some_and(|f| f.contains("\"t\":1.5")));
        upstream.publish_event(r#"{"timeS":2.0,"drone":0,"event":"takeoff"}"#.into());
        upstream.publish_frame(r#"{"t":2.5,"p":[4,5,6]}"#.into());
        assert!(seen.events.blocking_recv().unwrap().contains("takeoff"));
        wait_for(|| renderer.latest_frame().is_some_and(|f| f.contains("\"t\":2.5")));
        // The coordinator going away ends the stream cleanly.
        coordinator.stop();
        assert!(relay.join().unwrap().is_ok());
    }

    #[test]
    fn a_coordinator_that_is_not_there_is_named() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        drop(listener);
        let e = follow(&addr, &Feed::new(), &AtomicBool::new(false)).unwrap_err();
        assert!(e.to_string().contains(&addr), "{e}");
    }

    fn wait_for(mut done: impl FnMut() -> bool) {
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while !done() {
            assert!(std::time::Instant::now() < deadline, "not within 10 s");
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}
