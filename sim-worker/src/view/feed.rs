//! The live pose stream: the coordinator's merged snapshot, published to any number of
//! browsers without ever waiting for one.
//!
//! Two channels, each with a bound so that a slow or closed browser costs the simulation
//! nothing:
//! - **frames** (every drone's pose, the HUD numbers): a `watch` channel, which keeps only
//!   the newest frame. A browser that falls behind skips to the latest pose (the oldest are
//!   dropped), which is what a live view wants.
//! - **events** (takeoffs, crashes, zone requests, grants, denials, violations): a
//!   `broadcast` ring of [`EVENT_QUEUE`] entries, none skipped for a browser that keeps up;
//!   one that falls more than the ring behind is told how many it missed (`lagged`). The
//!   last [`EVENT_HISTORY`] events are replayed to a browser that opens late.
//!
//! Publishing is a `String` built per frame (throttled to [`FRAME_INTERVAL`] of wall time)
//! and channel sends that never block. The wire format of a frame is documented on
//! [`encode_frame`]; the page (`web/app.js`) and `sadesim view` read the same format.

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::{broadcast, watch};

use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::DroneSnapshot;

/// Events each browser may fall behind before it is told it lagged.
pub const EVENT_QUEUE: usize = 4096;
/// Events replayed to a browser that connects during the run.
pub const EVENT_HISTORY: usize = 200;
/// The shortest wall time between two published frames: 25 frames a second is smooth on
/// a screen, and a run at 50x real time does not build 5 000 frames a second for nobody.
pub const FRAME_INTERVAL: Duration = Duration::from_millis(40);

/// The hub between the coordinator and the browsers (shared with the HTTP server).
#[derive(Debug)]
pub struct Feed {
    frame: watch::Sender<Option<Arc<str>>>,
    events: broadcast::Sender<Arc<str>>,
    /// The last [`EVENT_HISTORY`] events; the lock also orders a subscription against a
    /// publication, so a new browser gets every event exactly once.
    history: Mutex<VecDeque<Arc<str>>>,
}

/// One browser's view of the feed.
#[derive(Debug)]
pub struct Subscription {
    /// Events published before the subscription, oldest first.
    pub backlog: Vec<Arc<str>>,
    pub frames: watch::Receiver<Option<Arc<str>>>,
    pub events: broadcast::Receiver<Arc<str>>,
}

impl Feed {
    pub fn new() -> Arc<Self> {
        Arc::new(Self {
            frame: watch::channel(None).0,
            events: broadcast::channel(EVENT_QUEUE).0,
            history: Mutex::new(VecDeque::with_capacity(EVENT_HISTORY)),
        })
    }

    /// Replaces the latest frame (JSON of [`encode_frame`]). Never blocks.
    pub fn publish_frame(&self, json: Arc<str>) {
        self.frame.send_replace(Some(json));
    }

    /// Publishes one event (JSON of [`Event`]). Never blocks: a browser more than
    /// [`EVENT_QUEUE`] events behind loses the oldest.
    pub fn publish_event(&self, json: Arc<str>) {
        let mut history = self.history.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if history.len() == EVENT_HISTORY {
            history.pop_front();
        }
        history.push_back(json.clone());
        // An error only says nobody is listening.
        let _ = self.events.send(json);
    }

    /// A new browser's subscription: the recent events, then everything from now on.
    pub fn subscribe(&self) -> Subscription {
        let history = self.history.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        Subscription {
            backlog: history.iter().cloned().collect(),
            frames: self.frame.subscribe(),
            events: self.events.subscribe(),
        }
    }

    /// The latest frame, if any was published.
    pub fn latest_frame(&self) -> Option<Arc<str>> {
        self.frame.borrow().clone()
    }

    /// Browsers connected now.
    pub fn viewers(&self) -> usize {
        self.frame.receiver_count()
    }
}

/// The coordinator's side: turns windows into frames and events on a [`Feed`].
#[derive(Debug)]
pub struct Publisher {
    feed: Arc<Feed>,
    /// Wall time of the first window (the real-time factor's start).
    started: Option<Instant>,
    /// Wall time of the last frame published.
    last_frame: Option<Instant>,
    interval: Duration,
    /// Reused between frames.
    poses: Vec<Pose>,
}

impl Publisher {
    pub fn new(feed: Arc<Feed>) -> Self {
        Self { feed, started: None, last_frame: None, interval: FRAME_INTERVAL, poses: Vec::new() }
    }

    /// One window of the run: every event, and a frame when [`FRAME_INTERVAL`] has passed
    /// since the last (always for the first window and the one that ends the run).
    pub fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) {
        let now = Instant::now();
        let started = *self.started.get_or_insert(now);
        // The frame first: a browser's stream ends at `runEnded` with the frame then current.
        let last = events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. }));
        let due = self.last_frame.is_none_or(|t| now.duration_since(t) >= self.interval);
        if due || last {
            let wall_s = now.duration_since(started).as_secs_f64();
            self.poses.clear();
            self.poses.extend(drones.iter().map(Pose::of));
            self.feed.publish_frame(encode_frame(time_s, Some(wall_s), &self.poses).into());
            self.last_frame = Some(now);
        }
        for event in events {
            if let Ok(json) = serde_json::to_string(event) {
                self.feed.publish_event(json.into());
            }
        }
    }
}

/// One drone in a frame: ENU position (m), body (FLU) -> ENU attitude `[w, x, y, z]`,
/// and its state letter (`G` on the ground, `A` airborne, `C` crashed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub position_enu_m: [f64; 3],
    pub attitude_wxyz: [f64; 4],
    pub state: u8,
}

impl Pose {
    pub fn of(d: &DroneSnapshot) -> Self {
        Self {
            position_enu_m: d.position_enu_m,
            attitude_wxyz: d.attitude_wxyz,
            state: state_letter(d.on_ground, d.crashed),
        }
    }
}

/// A drone's state letter: `C` crashed (whatever else), `G` on the ground, `A` airborne.
pub fn state_letter(on_ground: bool, crashed: bool) -> u8 {
    if crashed {
        b'C'
    } else if on_ground {
        b'G'
    } else {
        b'A'
    }
}

/// A frame as JSON:
///
/// `{"t": sim s, "rtf": real-time factor or null, "air": n, "ground": n, "crashed": n,
///   "p": [e0, n0, u0, e1, ...], "q": [w0, x0, y0, z0, w1, ...], "s": "GAC..."}`
///
/// `p` is every drone's ENU position (m, 2 decimals), `q` its body (FLU) -> ENU attitude
/// (4 decimals), `s` one letter per drone ([`Pose::state`]), all by global drone index.
/// `wall_s` is the wall time since the first window (`None` in a replay, which has no
/// real-time factor).
pub fn encode_frame(time_s: f64, wall_s: Option<f64>, drones: &[Pose]) -> String {
    let count = |letter: u8| drones.iter().filter(|d| d.state == letter).count();
    let mut out = String::with_capacity(96 + drones.len() * 64);
    let rtf = wall_s.filter(|w| *w > 0.0).map(|w| time_s / w);
    let _ = write!(out, "{{\"t\":{},\"rtf\":", number(time_s, 3));
    match rtf {
        Some(r) => out.push_str(&number(r, 2)),
        None => out.push_str("null"),
    }
    let _ = write!(out, ",\"air\":{},\"ground\":{},\"crashed\":{},\"p\":[", count(b'A'), count(b'G'), count(b'C'));
    join(&mut out, drones.iter().flat_map(|d| d.position_enu_m), 2);
    out.push_str("],\"q\":[");
    join(&mut out, drones.iter().flat_map(|d| d.attitude_wxyz), 4);
    out.push_str("],\"s\":\"");
    out.extend(drones.iter().map(|d| char::from(d.state)));
    out.push_str("\"}");
    out
}

/// `values` comma-separated with `decimals` (JSON has no NaN: a non-finite value is 0).
fn join(out: &mut String, values: impl Iterator<Item = f64>, decimals: usize) {
    for (i, v) in values.enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(&number(v, decimals));
    }
}

/// `v` with at most `decimals` decimals, trailing zeros dropped (`12.5`, `3`, `-0.25`).
fn number(v: f64, decimals: usize) -> String {
    let v = if v.is_finite() { v } else { 0.0 };
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    if s == "-0" { "0".into() } else { s }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_carries_every_drone_in_index_order() {
        let mut crashed = DroneSnapshot::climbing(1, 5.0, 2.0);
        crashed.crashed = true;
        let mut grounded = DroneSnapshot::climbing(2, -3.25, 0.0);
        grounded.on_ground = true;
        let drones: Vec<Pose> =
            [DroneSnapshot::climbing(0, 10.0, 1.5), crashed, grounded].iter().map(Pose::of).collect();
        let json: serde_json::Value = serde_json::from_str(&encode_frame(12.5, Some(5.0), &drones)).unwrap();
        assert_eq!(json["t"], 12.5);
        assert_eq!(json["rtf"], 2.5);
        assert_eq!(
            (json["air"].as_u64(), json["ground"].as_u64(), json["crashed"].as_u64()),
            (Some(1), Some(1), Some(1))
        );
        let p: Vec<f64> = serde_json::from_value(json["p"].clone()).unwrap();
        assert_eq!(p, [10.0, 0.0, 1.5, 5.0, 0.0, 2.0, -3.25, 0.0, 0.0]);
        assert_eq!(json["q"].as_array().unwrap().len(), 12);
        assert_eq!(json["s"], "ACG");
        // A replay has no real-time factor.
        assert!(serde_json::from_str::<serde_json::Value>(&encode_frame(1.0, None, &drones)).unwrap()["rtf"].is_null());
    }

    #[test]
    fn numbers_are_short_and_always_json() {
        assert_eq!(number(1.0, 2), "1");
        assert_eq!(number(-0.001, 2), "0");
        assert_eq!(number(2.345_678, 2), "2.35");
        assert_eq!(number(f64::NAN, 2), "0");
    }

    #[test]
    fn a_browser_that_never_reads_does_not_hold_the_publisher() {
        let feed = Feed::new();
        let stalled = feed.subscribe();
        let mut publisher = Publisher::new(feed.clone());
        publisher.interval = Duration::ZERO;
        let takeoff = |t: f64| Event { time_s: t, drone: Some(0), kind: EventKind::Takeoff };
        // Far more windows and events than any queue holds: every publish returns.
        for step in 0..(EVENT_QUEUE as u32 + 100) {
            let t = f64::from(step) * 0.01;
            publisher.on_window(t, &[DroneSnapshot::climbing(0, 0.0, t)], &[takeoff(t)]);
        }
        // The stalled browser sees only the newest frame, and is told it lagged on events.
        let latest = stalled.frames.borrow().clone().unwrap();
        assert!(
            latest.contains(&format!("\"t\":{}", number(f64::from(EVENT_QUEUE as u32 + 99) * 0.01, 3))),
            "{latest}"
        );
        let mut events = stalled.events;
        assert!(matches!(events.try_recv(), Err(broadcast::error::TryRecvError::Lagged(100))));
        // A browser that opens now gets the recent history, oldest first.
        let late = feed.subscribe();
        assert_eq!(late.backlog.len(), EVENT_HISTORY);
        let first: serde_json::Value = serde_json::from_str(&late.backlog[0]).unwrap();
        let last: serde_json::Value = serde_json::from_str(late.backlog.last().unwrap()).unwrap();
        assert!(first["timeS"].as_f64().unwrap() < last["timeS"].as_f64().unwrap());
    }

    #[test]
    fn frames_are_throttled_but_the_last_window_is_always_published() {
        let feed = Feed::new();
        let mut publisher = Publisher::new(feed.clone());
        publisher.interval = Duration::from_secs(3600);
        publisher.on_window(0.0, &[DroneSnapshot::climbing(0, 0.0, 0.0)], &[]);
        publisher.on_window(0.01, &[DroneSnapshot::climbing(0, 0.0, 0.01)], &[]);
        assert!(feed.latest_frame().unwrap().starts_with("{\"t\":0,"), "the first window only");
        let end = Event { time_s: 0.02, drone: None, kind: EventKind::RunEnded { reason: "duration".into() } };
        publisher.on_window(0.02, &[DroneSnapshot::climbing(0, 0.0, 0.02)], &[end]);
        assert!(feed.latest_frame().unwrap().starts_with("{\"t\":0.02,"));
    }
}
