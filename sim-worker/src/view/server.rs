//! The view's HTTP server: the page, three.js, the scene, the world model, and either the
//! live stream (Server-Sent Events) or a recorded run's frames.
//!
//! Routes:
//!
//! | path | what |
//! |---|---|
//! | `/` | the page (`web/index.html`) |
//! | `/app.js` | the page's code |
//! | `/vendor/three/...` | three.js from npm, embedded at build time |
//! | `/scene.json` | [`super::scene::Scene`] |
//! | `/world.glb` | the bundle's glTF (404 when the run has none) |
//! | `/live` | live runs: `text/event-stream`, events `frame` and `event` (and `lagged`); ends after `runEnded` |
//! | `/replay.json` | replays: every frame and event of the recording |
//! | `/healthz` | `ok` (Kubernetes probes) |
//! | `/cameras/...` | onboard camera frames for pilots ([`super::frames`]), in runs with cameras |
//!
//! Why Server-Sent Events rather than a WebSocket: the stream goes one way (the simulation
//! to the browser), EventSource reconnects by itself, and it is plain HTTP/1 that every
//! proxy and `kubectl port-forward` passes; nothing needs a frame protocol of its own.

use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use futures_util::stream::{self, Stream, StreamExt};
use tokio::sync::broadcast::error::RecvError;

use super::feed::{Feed, Subscription};

mod files {
    include!(concat!(env!("OUT_DIR"), "/three_files.rs"));
}

pub use files::THREE_VERSION;

const INDEX_HTML: &str = include_str!("../../web/index.html");
const APP_JS: &str = include_str!("../../web/app.js");

/// Whether this build carries three.js (see `build.rs`): without it the view cannot draw,
/// and a run asking for it is refused.
pub fn has_three() -> bool {
    cfg!(sadesim_three)
}

/// The "not supported" text for a build without three.js.
pub const NO_THREE: &str = "this build has no three.js for the live view (npm was not available when sim-worker was built): run `npm ci --prefix sim-worker/web` and rebuild";

/// Where the moving part of the view comes from.
#[derive(Clone, Debug)]
pub enum Source {
    /// A running simulation.
    Live(Arc<Feed>),
    /// A recorded run: the JSON of [`super::replay::Replay`].
    Replay(Arc<Vec<u8>>),
}

/// What the server serves.
#[derive(Clone, Debug)]
pub struct Content {
    /// `/scene.json`.
    pub scene_json: Arc<Vec<u8>>,
    /// `/world.glb`.
    pub world_glb: Option<Arc<Vec<u8>>>,
    pub source: Source,
    /// The onboard cameras' frames (`/cameras/...`), in runs with cameras.
    pub frames: Option<Arc<super::frames::FrameStore>>,
}

/// A running view server; stops when dropped (or with [`ViewHandle::stop`]).
pub type ViewHandle = crate::http_thread::HttpThread;

/// Serves `content` on `bind` from a thread of its own (one tokio current-thread runtime:
/// the server's work is copying bytes, and the simulation keeps the cores). Stopping ends
/// open streams at once: they never finish by themselves.
///
/// # Errors
/// The address cannot be bound, or the thread cannot start.
pub fn start(bind: SocketAddr, content: Content) -> std::io::Result<ViewHandle> {
    crate::http_thread::start(bind, router(content), "view-http", Duration::ZERO)
}

/// The view's routes (the console mounts them under `/replay/<run>/`: the page asks for
/// everything by relative URL).
pub fn router(content: Content) -> Router {
    let cameras = content.frames.clone().map(super::frames::routes).unwrap_or_default();
    Router::new()
        .route("/", get(|| async { ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], INDEX_HTML) }))
        .route("/app.js", get(|| async { ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], APP_JS) }))
        .route("/vendor/three/{*path}", get(vendor))
        .route("/scene.json", get(scene))
        .route("/world.glb", get(world))
        .route("/live", get(live))
        .route("/replay.json", get(replay))
        .route("/healthz", get(|| async { "ok" }))
        .with_state(content)
        .merge(cameras)
}

async fn vendor(Path(path): Path<String>) -> Response {
    match files::THREE_FILES.iter().find(|(p, _)| *p == path) {
        Some((p, bytes)) => {
            let kind = if p.ends_with(".js") { "text/javascript; charset=utf-8" } else { "text/plain; charset=utf-8" };
            ([(header::CONTENT_TYPE, kind), (header::CACHE_CONTROL, "max-age=86400")], *bytes).into_response()
        }
        None => (StatusCode::NOT_FOUND, format!("no /vendor/three/{path} in this build")).into_response(),
    }
}

async fn scene(State(c): State<Content>) -> Response {
    ([(header::CONTENT_TYPE, "application/json")], c.scene_json.as_ref().clone()).into_response()
}

async fn world(State(c): State<Content>) -> Response {
    match c.world_glb {
        Some(glb) => ([(header::CONTENT_TYPE, "model/gltf-binary")], glb.as_ref().clone()).into_response(),
        None => (StatusCode::NOT_FOUND, "this run has no world model").into_response(),
    }
}

async fn replay(State(c): State<Content>) -> Response {
    match c.source {
        Source::Replay(json) => ([(header::CONTENT_TYPE, "application/json")], json.as_ref().clone()).into_response(),
        Source::Live(_) => (StatusCode::NOT_FOUND, "a live run: the stream is /live").into_response(),
    }
}

async fn live(State(c): State<Content>) -> Response {
    match c.source {
        Source::Live(feed) => Sse::new(stream_of(feed.subscribe()))
            .keep_alive(KeepAlive::new().interval(Duration::from_secs(10)))
            .into_response(),
        Source::Replay(_) => (StatusCode::NOT_FOUND, "a recorded run: the frames are /replay.json").into_response(),
    }
}

/// An item of a browser's stream, or its end.
enum Item {
    Send(SseEvent),
    End,
}

fn event_item(json: &str) -> Item {
    Item::Send(SseEvent::default().event("event").data(json))
}

fn frame_item(json: &str) -> Item {
    Item::Send(SseEvent::default().event("frame").data(json))
}

/// Whether an event's JSON is the run's `runEnded`.
fn is_run_end(json: &str) -> bool {
    json.contains(r#""event":"runEnded""#)
        && serde_json::from_str::<serde_json::Value>(json).is_ok_and(|v| v["event"] == "runEnded")
}

/// One browser's stream: the backlog of events, the current frame, then frames and events
/// as they come, until the run's `runEnded` event and its last frame: then the response
/// ends properly, so the page sees a finished stream, not a cut connection. Each browser's
/// stream is polled by its own connection task, so a slow one holds only itself.
fn stream_of(sub: Subscription) -> impl Stream<Item = Result<SseEvent, Infallible>> {
    let Subscription { backlog, mut frames, events } = sub;
    let current = frames.borrow_and_update().clone();
    let ended_before = backlog.iter().any(|e| is_run_end(e));
    let first: Vec<Item> = backlog
        .iter()
        .map(|e| event_item(e))
        .chain(current.map(|f| frame_item(&f)))
        .chain(ended_before.then_some(Item::End))
        .collect();
    let last_frame = frames.clone();
    let frames = stream::unfold(frames, |mut rx| async move {
        rx.changed().await.ok()?;
        let frame = rx.borrow_and_update().clone();
        Some((frame.map(|f| frame_item(&f)), rx))
    })
    .filter_map(|item| async move { item });
    let events = stream::unfold((events, last_frame), |(mut rx, last_frame)| async move {
        let items = match rx.recv().await {
            // The feed publishes the last window's frame before its events.
            Ok(e) if is_run_end(&e) => {
                let frame = last_frame.borrow().clone();
                vec![event_item(&e)].into_iter().chain(frame.map(|f| frame_item(&f))).chain([Item::End]).collect()
            }
            Ok(e) => vec![event_item(&e)],
            Err(RecvError::Lagged(n)) => vec![Item::Send(SseEvent::default().event("lagged").data(n.to_string()))],
            Err(RecvError::Closed) => return None,
        };
        Some((stream::iter(items), (rx, last_frame)))
    })
    .flatten();
    let items = stream::iter(first).chain(stream::select(frames, events));
    stream::unfold(Box::pin(items), |mut items| async move {
        match items.next().await? {
            Item::Send(event) => Some((Ok(event), items)),
            Item::End => None,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collect(sub: Subscription) -> Vec<String> {
        let runtime = tokio::runtime::Builder::new_current_thread().enable_time().build().unwrap();
        runtime.block_on(async {
            let items = stream_of(sub).map(|e| format!("{:?}", e.unwrap())).collect::<Vec<_>>();
            tokio::time::timeout(Duration::from_secs(5), items).await.expect("the stream ends after runEnded")
        })
    }

    const RUN_ENDED: &str = r#"{"timeS":2.0,"event":"runEnded","reason":"duration"}"#;

    /// A browser watching when the run ends gets `runEnded` and the last frame, then the
    /// response ends; one that opens after the end gets the backlog and the frame, and ends.
    #[test]
    fn the_live_stream_ends_after_the_run_ends() {
        let feed = Feed::new();
        feed.publish_event(r#"{"timeS":0.0,"event":"runStarted","drones":1,"shards":1}"#.into());
        let watching = feed.subscribe();
        feed.publish_frame(r#"{"t":2.0}"#.into());
        feed.publish_event(RUN_ENDED.into());
        let seen = collect(watching);
        assert!(seen.iter().any(|e| e.contains("runEnded")), "{seen:?}");
        let last = seen.last().unwrap();
        assert!(last.contains("event: frame") && last.contains("2.0"), "the last frame comes last: {seen:?}");
        let late = collect(feed.subscribe());
        assert_eq!(late.len(), 3, "runStarted, runEnded, the frame: {late:?}");
        // Other events do not end it: a stream with no end is still open after them.
        let feed = Feed::new();
        let open = feed.subscribe();
        feed.publish_event(r#"{"timeS":1.0,"drone":0,"event":"reason","command":"runEnded"}"#.into());
        let runtime = tokio::runtime::Builder::new_current_thread().enable_time().build().unwrap();
        let still_open = runtime.block_on(async {
            tokio::time::timeout(Duration::from_millis(200), stream_of(open).count()).await.is_err()
        });
        assert!(still_open);
        assert!(is_run_end(RUN_ENDED) && !is_run_end(r#"{"event":"landed","note":"\"event\":\"runEnded\""}"#));
    }
}
