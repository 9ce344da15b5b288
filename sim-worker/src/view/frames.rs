//! Onboard camera frames for pilots over HTTP (issue 18, "onboard cameras as sensors"):
//! the latest frame of each drone's camera, an MJPEG stream that OpenCV's `VideoCapture`
//! opens, and a blocking "next frame after simulated time t" call for lockstep pilots.
//!
//! The store holds each camera's newest frame behind a `watch` channel (the producer never
//! waits for a pilot; a pilot that falls behind gets the newest frame). Frames are encoded
//! on request, on the server's thread, once per format ([`CameraFrame`]): the simulation
//! never pays for a format nobody asked for.
//!
//! | path | what |
//! |---|---|
//! | `/cameras` | every drone's cameras and their URLs (JSON) |
//! | `/cameras/{drone}/{camera}/latest.jpg` (`.png`) | the newest RGB frame |
//! | `/cameras/{drone}/{camera}/depth.png` | the newest depth frame, 16-bit PNG, millimetres |
//! | `/cameras/{drone}/{camera}/next.jpg?after=T` (`.png`, `depth`) | waits for the first frame taken after `T` simulated seconds |
//! | `/cameras/{drone}/{camera}/stream.mjpg` | every new frame, `multipart/x-mixed-replace` |
//!
//! Every image answer carries `X-Sim-Time` (simulated seconds of the frame) and
//! `X-Frame-Seq` (frames of that camera before it).

use std::collections::BTreeMap;
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use futures_util::stream;
use tokio::sync::watch;

/// How long `next` waits before answering 504 (a paused or ended run).
pub const NEXT_TIMEOUT: Duration = Duration::from_secs(30);

/// One rendered frame, encoded on demand.
pub trait FrameImage: Send + Sync + std::fmt::Debug {
    /// RGB as JPEG.
    fn jpeg(&self) -> Vec<u8>;
    /// RGB as PNG.
    fn png(&self) -> Vec<u8>;
    /// Depth as a 16-bit grayscale PNG in millimetres (0: nothing within range); `None`
    /// for a camera without depth.
    fn depth_png_mm(&self) -> Option<Vec<u8>>;
}

/// A camera's frame at one simulated instant, with its encodings made at most once.
#[derive(Debug)]
pub struct CameraFrame {
    /// Simulated seconds when it was taken.
    pub time_s: f64,
    /// Frames of this camera before this one.
    pub seq: u64,
    image: Box<dyn FrameImage>,
    jpeg: OnceLock<Bytes>,
    png: OnceLock<Bytes>,
    depth: OnceLock<Option<Bytes>>,
}

impl CameraFrame {
    pub fn new(time_s: f64, seq: u64, image: Box<dyn FrameImage>) -> Self {
        Self { time_s, seq, image, jpeg: OnceLock::new(), png: OnceLock::new(), depth: OnceLock::new() }
    }

    /// The frame as JPEG, encoded on the first call (by a pilot's request or the recorder)
    /// and kept.
    pub fn jpeg(&self) -> Bytes {
        self.encoded(Format::Jpeg).unwrap_or_default()
    }

    fn encoded(&self, format: Format) -> Option<Bytes> {
        match format {
            Format::Jpeg => Some(self.jpeg.get_or_init(|| self.image.jpeg().into()).clone()),
            Format::Png => Some(self.png.get_or_init(|| self.image.png().into()).clone()),
            Format::Depth => self.depth.get_or_init(|| self.image.depth_png_mm().map(Bytes::from)).clone(),
        }
    }
}

/// Each camera's newest frame, by (drone name, camera name).
#[derive(Debug)]
pub struct FrameStore {
    cameras: BTreeMap<(String, String), watch::Sender<Option<Arc<CameraFrame>>>>,
}

impl FrameStore {
    /// A store for `cameras`: (drone name, camera name) pairs.
    pub fn new(cameras: impl IntoIterator<Item = (String, String)>) -> Arc<Self> {
        Arc::new(Self { cameras: cameras.into_iter().map(|key| (key, watch::channel(None).0)).collect() })
    }

    /// Replaces the camera's newest frame; never waits. Returns false for a camera the
    /// store does not have.
    pub fn publish(&self, drone: &str, camera: &str, frame: CameraFrame) -> bool {
        match self.cameras.get(&(drone.to_string(), camera.to_string())) {
            Some(tx) => {
                tx.send_replace(Some(Arc::new(frame)));
                true
            }
            None => false,
        }
    }

    /// The camera's channel, or the 404 text naming the cameras there are.
    fn channel(&self, drone: &str, camera: &str) -> Result<&watch::Sender<Option<Arc<CameraFrame>>>, String> {
        self.cameras.get(&(drone.to_string(), camera.to_string())).ok_or_else(|| {
            let known: Vec<String> = self.cameras.keys().map(|(d, c)| format!("{d}/{c}")).collect();
            format!("no camera {drone}/{camera}; this run has: {}", known.join(", "))
        })
    }
}

/// An image format of the HTTP API.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Jpeg,
    Png,
    Depth,
}

impl Format {
    fn of(file: &str) -> Option<(&str, Format)> {
        let (stem, ext) = file.rsplit_once('.')?;
        match (stem, ext) {
            ("depth", "png") => Some(("latest", Format::Depth)),
            ("next-depth", "png") => Some(("next", Format::Depth)),
            (stem @ ("latest" | "next"), "jpg" | "jpeg") => Some((stem, Format::Jpeg)),
            (stem @ ("latest" | "next"), "png") => Some((stem, Format::Png)),
            _ => None,
        }
    }

    fn content_type(self) -> &'static str {
        match self {
            Format::Jpeg => "image/jpeg",
            Format::Png | Format::Depth => "image/png",
        }
    }
}

/// The routes of the camera API, to merge into the view's router.
pub fn routes(store: Arc<FrameStore>) -> Router {
    Router::new()
        .route("/cameras", get(list))
        .route("/cameras/{drone}/{camera}/stream.mjpg", get(mjpeg))
        .route("/cameras/{drone}/{camera}/{file}", get(image))
        .with_state(store)
}

async fn list(State(store): State<Arc<FrameStore>>) -> Response {
    let cameras: Vec<serde_json::Value> = store
        .cameras
        .keys()
        .map(|(d, c)| {
            let base = format!("/cameras/{d}/{c}");
            serde_json::json!({
                "drone": d, "camera": c,
                "latest": format!("{base}/latest.jpg"), "depth": format!("{base}/depth.png"),
                "next": format!("{base}/next.jpg?after="), "stream": format!("{base}/stream.mjpg"),
            })
        })
        .collect();
    axum::Json(cameras).into_response()
}

#[derive(serde::Deserialize)]
struct After {
    /// Simulated seconds.
    after: Option<f64>,
}

async fn image(
    State(store): State<Arc<FrameStore>>,
    Path((drone, camera, file)): Path<(String, String, String)>,
    Query(query): Query<After>,
) -> Response {
    let tx = match store.channel(&drone, &camera) {
        Ok(tx) => tx,
        Err(text) => return (StatusCode::NOT_FOUND, text).into_response(),
    };
    let Some((which, format)) = Format::of(&file) else {
        let text = format!(
            "no {file}: ask latest.jpg, latest.png, depth.png, next.jpg?after=T, next.png?after=T, next-depth.png?after=T or stream.mjpg"
        );
        return (StatusCode::NOT_FOUND, text).into_response();
    };
    let frame = if which == "latest" {
        match tx.borrow().clone() {
            Some(frame) => frame,
            None => {
                return (StatusCode::SERVICE_UNAVAILABLE, "no frame yet: the camera's first is not due")
                    .into_response();
            }
        }
    } else {
        let Some(after) = query.after.filter(|t| t.is_finite()) else {
            return (StatusCode::BAD_REQUEST, "next needs ?after=T, simulated seconds (a finite number)")
                .into_response();
        };
        let mut rx = tx.subscribe();
        let wait = rx.wait_for(|f| f.as_ref().is_some_and(|f| f.time_s > after));
        match tokio::time::timeout(NEXT_TIMEOUT, wait).await {
            Ok(Ok(frame)) => frame.clone().expect("wait_for returned a frame"),
            Ok(Err(_)) => return (StatusCode::GONE, "the run ended").into_response(),
            Err(_) => {
                let text = format!("no frame after {after} s within {} s of wall time", NEXT_TIMEOUT.as_secs());
                return (StatusCode::GATEWAY_TIMEOUT, text).into_response();
            }
        }
    };
    match frame.encoded(format) {
        Some(bytes) => image_answer(&frame, format, bytes),
        None => {
            (StatusCode::NOT_FOUND, format!("camera {drone}/{camera} has no depth (set depth: true)")).into_response()
        }
    }
}

fn image_answer(frame: &CameraFrame, format: Format, bytes: Bytes) -> Response {
    let mut answer = ([(header::CONTENT_TYPE, format.content_type())], bytes).into_response();
    let headers = answer.headers_mut();
    headers.insert("x-sim-time", HeaderValue::from_str(&frame.time_s.to_string()).expect("a number is a header"));
    headers.insert("x-frame-seq", HeaderValue::from(frame.seq));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    answer
}

/// Multipart boundary of the MJPEG stream.
const BOUNDARY: &str = "sadesimframe";

async fn mjpeg(State(store): State<Arc<FrameStore>>, Path((drone, camera)): Path<(String, String)>) -> Response {
    let rx = match store.channel(&drone, &camera) {
        Ok(tx) => tx.subscribe(),
        Err(text) => return (StatusCode::NOT_FOUND, text).into_response(),
    };
    // The current frame first (if any), then each new one; a slow reader skips frames.
    let parts = stream::unfold((rx, true), |(mut rx, first)| async move {
        if !first || rx.borrow().is_none() {
            rx.changed().await.ok()?;
        }
        let frame = rx.borrow_and_update().clone()?;
        let jpeg = frame.encoded(Format::Jpeg).expect("every frame has RGB");
        let mut part = format!(
            "--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\nX-Sim-Time: {}\r\n\r\n",
            jpeg.len(),
            frame.time_s
        )
        .into_bytes();
        part.extend_from_slice(&jpeg);
        part.extend_from_slice(b"\r\n");
        Some((Ok::<_, std::convert::Infallible>(Bytes::from(part)), (rx, false)))
    });
    let content_type = format!("multipart/x-mixed-replace; boundary={BOUNDARY}");
    ([(header::CONTENT_TYPE, content_type)], Body::from_stream(parts)).into_response()
}

#[cfg(test)]
mod tests {
    use std::io::{Read, Write};
    use std::net::TcpStream;

    use super::*;

    /// A "frame" whose encodings are tagged bytes, so tests see which was served.
    #[derive(Debug)]
    struct Tagged(u8, bool);

    impl FrameImage for Tagged {
        fn jpeg(&self) -> Vec<u8> {
            vec![0xFF, 0xD8, self.0]
        }
        fn png(&self) -> Vec<u8> {
            vec![0x89, b'P', self.0]
        }
        fn depth_png_mm(&self) -> Option<Vec<u8>> {
            self.1.then(|| vec![0x89, b'D', self.0])
        }
    }

    fn serve(store: Arc<FrameStore>) -> (std::net::SocketAddr, std::thread::JoinHandle<()>) {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let addr = listener.local_addr().unwrap();
        let thread = std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
            rt.block_on(async move {
                let listener = tokio::net::TcpListener::from_std(listener).unwrap();
                let _ = axum::serve(listener, routes(store)).await;
            });
        });
        (addr, thread)
    }

    /// `GET path` over HTTP/1.0: (status, headers, body).
    fn get(addr: std::net::SocketAddr, path: &str) -> (u16, String, Vec<u8>) {
        let mut s = TcpStream::connect(addr).unwrap();
        write!(s, "GET {path} HTTP/1.0\r\nHost: x\r\n\r\n").unwrap();
        let mut all = Vec::new();
        s.read_to_end(&mut all).unwrap();
        let split = all.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
        let head = String::from_utf8_lossy(&all[..split]).to_string();
        let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
        (status, head.to_lowercase(), all[split + 4..].to_vec())
    }

    fn frame(t: f64, seq: u64, tag: u8) -> CameraFrame {
        CameraFrame::new(t, seq, Box::new(Tagged(tag, true)))
    }

    #[test]
    fn the_latest_frame_comes_in_each_format_with_its_time() {
        let store = FrameStore::new([("scout-0".to_string(), "down".to_string())]);
        let (addr, _server) = serve(store.clone());
        assert_eq!(get(addr, "/cameras/scout-0/down/latest.jpg").0, 503, "no frame yet");
        store.publish("scout-0", "down", frame(1.5, 0, 7));
        let (status, head, body) = get(addr, "/cameras/scout-0/down/latest.jpg");
        assert_eq!((status, body), (200, vec![0xFF, 0xD8, 7]));
        assert!(head.contains("content-type: image/jpeg") && head.contains("x-sim-time: 1.5"), "{head}");
        assert_eq!(get(addr, "/cameras/scout-0/down/latest.png").2, vec![0x89, b'P', 7]);
        assert_eq!(get(addr, "/cameras/scout-0/down/depth.png").2, vec![0x89, b'D', 7]);
        let (status, _, body) = get(addr, "/cameras/scout-0/nose/latest.jpg");
        assert_eq!(status, 404);
        assert!(String::from_utf8_lossy(&body).contains("this run has: scout-0/down"));
        assert_eq!(get(addr, "/cameras/scout-0/down/latest.gif").0, 404);
        assert_eq!(get(addr, "/cameras/scout-0/down/next.jpg").0, 400, "next needs after");
        let list: serde_json::Value = serde_json::from_slice(&get(addr, "/cameras").2).unwrap();
        assert_eq!(list[0]["stream"], "/cameras/scout-0/down/stream.mjpg");
    }

    #[test]
    fn next_waits_for_the_first_frame_after_the_time() {
        let store = FrameStore::new([("scout-0".to_string(), "down".to_string())]);
        let (addr, _server) = serve(store.clone());
        store.publish("scout-0", "down", frame(1.0, 0, 1));
        let waiting = std::thread::spawn(move || get(addr, "/cameras/scout-0/down/next.jpg?after=1.0"));
        std::thread::sleep(Duration::from_millis(200));
        assert!(!waiting.is_finished(), "the frame at 1.0 s is not after 1.0 s");
        store.publish("scout-0", "down", frame(1.1, 1, 2));
        let (status, head, body) = waiting.join().unwrap();
        assert_eq!((status, body), (200, vec![0xFF, 0xD8, 2]));
        assert!(head.contains("x-frame-seq: 1"), "{head}");
        // A frame already after the time answers at once.
        assert_eq!(get(addr, "/cameras/scout-0/down/next.png?after=0.5").2, vec![0x89, b'P', 2]);
    }

    #[test]
    fn the_mjpeg_stream_carries_each_new_frame_as_a_part() {
        let store = FrameStore::new([("scout-0".to_string(), "down".to_string())]);
        let (addr, _server) = serve(store.clone());
        store.publish("scout-0", "down", frame(0.1, 0, 10));
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        write!(s, "GET /cameras/scout-0/down/stream.mjpg HTTP/1.0\r\nHost: x\r\n\r\n").unwrap();
        let mut seen = Vec::new();
        let mut buf = [0u8; 4096];
        let parts = |seen: &[u8]| seen.windows(BOUNDARY.len()).filter(|w| *w == BOUNDARY.as_bytes()).count();
        let mut published = false;
        while parts(&seen) < 3 {
            let n = s.read(&mut buf).unwrap();
            assert!(n > 0, "the stream ended");
            seen.extend_from_slice(&buf[..n]);
            if !published && parts(&seen) >= 2 {
                store.publish("scout-0", "down", frame(0.2, 1, 11));
                published = true;
            }
        }
        let text = String::from_utf8_lossy(&seen);
        assert!(text.contains("multipart/x-mixed-replace; boundary=sadesimframe"), "{text}");
        assert!(text.contains("X-Sim-Time: 0.1") && text.contains("X-Sim-Time: 0.2"), "{text}");
        assert!(seen.windows(3).any(|w| w == [0xFF, 0xD8, 11]));
    }
}
