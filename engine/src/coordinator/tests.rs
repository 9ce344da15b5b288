//! The shard-failure path of the lockstep loop, with scripted shard links.

use std::sync::{Arc, Mutex};

use sadesim_crds::run::{Clock, ClockMode};

use super::*;
use crate::fixtures::{plan_of, run_with_groups};

/// A wall clock whose sleeps pass at once: it moves on by what was slept.
#[derive(Default)]
struct VirtualClock {
    slept: Mutex<Duration>,
}

impl crate::pacing::WallClock for VirtualClock {
    fn now(&self) -> Instant {
        // One base instant for the test; the clock is never read across tests.
        static BASE: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
        *BASE.get_or_init(Instant::now) + *self.slept.lock().unwrap()
    }

    fn sleep(&self, duration: Duration) {
        *self.slept.lock().unwrap() += duration;
    }
}

/// A shard that answers `windows` Advance messages, then fails as `then` says. Everything
/// it was sent is kept in `sent`.
struct Scripted {
    shard: u32,
    windows: usize,
    then: Then,
    peer: Option<String>,
    pending: Option<FromShard>,
    sent: Arc<Mutex<Vec<ToShard>>>,
}

#[derive(Clone)]
enum Then {
    /// Keep answering.
    Answer,
    /// The connection closes.
    Close,
    /// The shard reports `Failed` with this reason.
    Report(&'static str),
}

impl Scripted {
    fn new(shard: u32, windows: usize, then: Then) -> (Self, Arc<Mutex<Vec<ToShard>>>) {
        let sent = Arc::new(Mutex::new(Vec::new()));
        let hello = FromShard::Hello { version: PROTOCOL_VERSION, shard, drones: 0 };
        let peer = Some(format!("10.0.0.{}:4000", shard + 2));
        (Self { shard, windows, then, peer, pending: Some(hello), sent: sent.clone() }, sent)
    }
}

impl ShardLink for Scripted {
    fn send(&mut self, msg: &ToShard) -> Result<(), LinkError> {
        self.sent.lock().unwrap().push(msg.clone());
        if let ToShard::Advance { until_step, .. } = msg {
            self.pending = if self.windows > 0 || matches!(self.then, Then::Answer) {
                self.windows = self.windows.saturating_sub(1);
                Some(FromShard::Advanced {
                    shard: self.shard,
                    step: *until_step,
                    ready: true,
                    drones: Vec::new(),
                    events: Vec::new(),
                })
            } else if let Then::Report(reason) = self.then {
                Some(FromShard::Failed { shard: self.shard, reason: reason.into() })
            } else {
                None
            };
        }
        Ok(())
    }
    fn recv(&mut self) -> Result<FromShard, LinkError> {
        self.pending.take().ok_or(LinkError::Closed)
    }
    fn peer(&self) -> Option<String> {
        self.peer.clone()
    }
}

/// Every window the observer saw: time and events.
#[derive(Default)]
struct Windows(Vec<(f64, Vec<Event>)>);

impl RunObserver for Windows {
    fn on_window(&mut self, time_s: f64, _drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        self.0.push((time_s, events.to_vec()));
        Ok(())
    }
}

fn plan() -> RunPlan {
    let run = run_with_groups(&[("a", 1)])
        .with(|r| {
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            r.spec.duration = "1s".parse().expect("a valid duration");
        })
        .build();
    plan_of(run)
}

fn run_two(
    second: Then,
    windows: usize,
    observer: &mut dyn RunObserver,
) -> (Result<RunOutcome, CoordinatorError>, Vec<ToShard>) {
    let (first, first_sent) = Scripted::new(0, usize::MAX, Then::Answer);
    let (second, _) = Scripted::new(1, windows, second);
    let mut links: Vec<Box<dyn ShardLink>> = vec![Box::new(first), Box::new(second)];
    let result = run(&plan(), &mut links, observer, &AtomicBool::new(false), &VirtualClock::default(), None);
    let sent = first_sent.lock().unwrap().clone();
    (result, sent)
}

#[test]
fn a_shard_that_disappears_ends_the_run_at_the_last_complete_window() {
    let mut windows = Windows::default();
    let (result, sent_to_survivor) = run_two(Then::Close, 3, &mut windows);
    let Err(CoordinatorError::RunFailed(failure)) = result else { panic!("expected RunFailed, got {result:?}") };
    assert_eq!(
        (failure.shard, failure.peer.as_deref(), failure.cause.as_str()),
        (1, Some("10.0.0.3:4000"), "connection closed")
    );
    // Three windows of 10 steps at 1 kHz completed.
    assert_eq!(failure.outcome.sim_time_s, 0.03);
    assert_eq!(
        failure.outcome.reason,
        EndReason::ShardFailed("shard 1 (10.0.0.3:4000) failed: connection closed".into())
    );
    assert_eq!(failure.outcome.reason.to_string(), "shardFailed: shard 1 (10.0.0.3:4000) failed: connection closed");
    assert_eq!(
        failure.to_string(),
        "shard 1 (10.0.0.3:4000) failed: connection closed (the run ended at 0.03 s of simulated time)"
    );
    // The observer saw the three windows, then the end with the reason.
    let times: Vec<f64> = windows.0.iter().map(|w| w.0).collect();
    assert_eq!(times, [0.01, 0.02, 0.03, 0.03]);
    let (_, last) = windows.0.last().unwrap();
    assert_eq!(last.len(), 1);
    assert_eq!(last[0].kind, EventKind::RunEnded { reason: failure.outcome.reason.clone() });
    assert_eq!(last[0].time_s, 0.03);
    // The surviving shard was told to stop.
    assert_eq!(sent_to_survivor.last(), Some(&ToShard::Stop));
}

#[test]
fn a_shard_reporting_failure_is_named_with_its_reason() {
    let mut windows = Windows::default();
    let (result, _) = run_two(Then::Report("out of memory"), 1, &mut windows);
    let Err(CoordinatorError::RunFailed(failure)) = result else { panic!("expected RunFailed, got {result:?}") };
    assert_eq!(failure.cause, "it reported: out of memory");
    let EndReason::ShardFailed(what) = &failure.outcome.reason else { panic!("{:?}", failure.outcome.reason) };
    assert!(what.starts_with("shard 1 (10.0.0.3:4000)"), "{what}");
}

#[test]
fn a_failure_before_the_first_window_ends_at_time_zero() {
    let mut windows = Windows::default();
    let (result, _) = run_two(Then::Close, 0, &mut windows);
    let Err(CoordinatorError::RunFailed(failure)) = result else { panic!("expected RunFailed, got {result:?}") };
    assert_eq!(failure.outcome.sim_time_s, 0.0);
    assert_eq!(windows.0.len(), 1, "only the end window");
}

#[test]
fn a_run_without_failures_still_ends_with_duration() {
    let mut windows = Windows::default();
    let (result, sent) = run_two(Then::Answer, 0, &mut windows);
    let outcome = result.unwrap();
    assert_eq!((&outcome.reason, outcome.sim_time_s), (&EndReason::Duration, 1.0));
    assert_eq!(windows.0.last().unwrap().1[0].kind, EventKind::RunEnded { reason: "duration".into() });
    assert_eq!(sent.last(), Some(&ToShard::Stop));
}

/// An observer that cannot record: not a shard failure, so no `runEnded` is attempted.
struct Broken;

impl RunObserver for Broken {
    fn on_window(&mut self, _: f64, _: &[DroneSnapshot], _: &[Event]) -> Result<(), ObserverError> {
        Err(ObserverError::Record(std::io::Error::other("disk full")))
    }
}

#[test]
fn an_observer_failure_is_not_blamed_on_a_shard() {
    let (result, sent) = run_two(Then::Answer, 0, &mut Broken);
    assert!(
        matches!(&result, Err(CoordinatorError::Observer(ObserverError::Record(e))) if e.to_string() == "disk full"),
        "{result:?}"
    );
    assert_eq!(sent.last(), Some(&ToShard::Stop));
}
