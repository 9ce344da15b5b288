//! The coordinator: lockstep clock and barrier over the shards, the merged snapshot,
//! pilot release and the end of the run (DESIGN §3, §5).
//!
//! It talks to shards only through [`ShardLink`], so the same loop drives in-process shard
//! threads and `sim-worker shard` processes over TCP. Wall-clock time is read here, at
//! the edge, for pacing; everything simulated depends only on the step count.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sadesim_crds::plan::RunPlan;

use crate::events::{Event, EventKind};
use crate::pacing::{Pacer, WallClock};
use crate::protocol::{DroneSnapshot, FromShard, PROTOCOL_VERSION, ToShard};

mod hold;
pub use hold::{HOLD_HEARTBEAT, HOLD_POLL, PilotHold};

/// A bidirectional connection to one shard.
pub trait ShardLink: Send {
    /// # Errors
    /// When the shard is gone.
    fn send(&mut self, msg: &ToShard) -> Result<(), LinkError>;
    /// Blocks for the next message.
    ///
    /// # Errors
    /// When the shard is gone or sent something unreadable.
    fn recv(&mut self) -> Result<FromShard, LinkError>;
    /// Where the shard is (`host:port` of a TCP peer), to name it when it fails.
    fn peer(&self) -> Option<String> {
        None
    }
}

/// A broken shard connection.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The shard's end went away without `Stopped` (its process exited or was killed,
    /// its thread ended).
    #[error("connection closed")]
    Closed,
    #[error("failed to talk to the shard: {0}")]
    Io(#[from] std::io::Error),
    #[error("unreadable message from the shard: {0}")]
    Decode(String),
}

/// Why a run could not go on.
#[derive(Debug, thiserror::Error)]
pub enum CoordinatorError {
    #[error("shard {shard}: {source}")]
    Link { shard: usize, source: LinkError },
    #[error("shard {shard} failed: {reason}")]
    ShardFailed { shard: u32, reason: String },
    #[error("shard {shard} speaks protocol version {version}, expected {PROTOCOL_VERSION}")]
    Version { shard: u32, version: u32 },
    #[error("shard {shard} sent an unexpected message: {message}")]
    Unexpected { shard: usize, message: String },
    #[error("the observer failed: {0}")]
    Observer(#[source] ObserverError),
    /// A shard failed, and then the observer could not record the end of the run.
    #[error("{failure}; then recording the end of the run failed: {source}")]
    ObserverAfterFailure {
        failure: Box<RunFailure>,
        #[source]
        source: ObserverError,
    },
    /// A shard failed once [`run`] had started; see [`RunFailure`]. [`run`] returns the
    /// shard variants above only inside this one, and otherwise only `Observer`.
    #[error("{0}")]
    RunFailed(Box<RunFailure>),
}

pub use sadesim_crds::outcome::ending::{EndReason, SHARD_FAILED};

/// A run ended by a failed shard (its process died, its host went away, it reported
/// `Failed` or broke the protocol). The coordinator ends such a run as cleanly as it can:
/// the surviving shards are told to stop, and the observer gets a last window at the time
/// of the last window every shard completed, carrying a `runEnded` event whose reason is
/// `outcome.reason`. `outcome` describes the run up to there, so the caller can
/// still finish its recording (summary, recordings) before reporting the failure.
#[derive(Clone, Debug, PartialEq)]
pub struct RunFailure {
    /// Plan index of the failed shard.
    pub shard: u32,
    /// The shard's address (`host:port` of its TCP connection), when known.
    pub peer: Option<String>,
    /// What went wrong, e.g. `connection closed`.
    pub cause: String,
    /// The run up to the last complete window; `reason` is [`EndReason::ShardFailed`] with
    /// [`describe`]'s text.
    pub outcome: RunOutcome,
}

/// `shard 1 (10.77.0.3:40122) failed: connection closed`: a failed shard as the run's end
/// reason names it (`shardFailed: shard 1 ...`, machine-matchable by its [`SHARD_FAILED`]
/// prefix) and as [`RunFailure`] displays it.
fn describe(shard: u32, peer: Option<&str>, cause: &str) -> String {
    match peer {
        Some(peer) => format!("shard {shard} ({peer}) failed: {cause}"),
        None => format!("shard {shard} failed: {cause}"),
    }
}

impl std::fmt::Display for RunFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = describe(self.shard, self.peer.as_deref(), &self.cause);
        write!(f, "{what} (the run ended at {:.2} s of simulated time)", self.outcome.sim_time_s)
    }
}

/// Why an observer stopped the run (what it had written is kept).
#[derive(Debug, thiserror::Error)]
pub enum ObserverError {
    /// The recording could not be written (disk full, the folder removed).
    #[error("failed to record: {0}")]
    Record(#[source] std::io::Error),
}

/// What the coordinator reports each window, and asks about ending early.
///
/// Only `on_window` must be written; the other methods default to doing nothing. An
/// observer that wraps another (the conductor's, the airspace's) forwards every method it
/// does not answer itself: a default left in a wrapper silently cuts off the one inside.
pub trait RunObserver {
    /// A window ended at `time_s`: every drone's state (by global index) and the events
    /// that happened during the window, in time order.
    ///
    /// # Errors
    /// [`ObserverError`]; the run stops (outputs already written are kept).
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError>;
    /// Asked before each window: the valid zone leases as `[drone, zone]` pairs when they
    /// changed since the last call (the shards' geofences let drones into leased zones).
    fn leases_changed(&mut self) -> Option<Vec<[u32; 2]>> {
        None
    }
    /// Asked after each window: `Some(reason)` ends the run (e.g. the pilot exited).
    fn stop_reason(&mut self) -> Option<EndReason> {
        None
    }
    /// The clock started at `started`: in a paced run (realtime, scaled), simulated time
    /// `t` is due at `started + t / factor` (see [`crate::pacing::Pacer::due_after`]).
    /// Called before the first window, and again after a hold for the pilot, with the
    /// start moved on by the wall time held.
    fn on_clock_started(&mut self, started: Instant) {
        let _ = started;
    }
    /// The run is holding at the release for the pilot to connect (see [`PilotHold`]), for
    /// `waited` so far: called about every [`HOLD_POLL`], before [`RunObserver::stop_reason`]
    /// is asked (e.g. to see whether the pilot process exited meanwhile).
    fn on_hold(&mut self, waited: Duration) {
        let _ = waited;
    }
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOutcome {
    /// [`EndReason::Duration`], [`EndReason::Interrupted`], the observer's reason, or
    /// [`EndReason::ShardFailed`] inside a [`RunFailure`].
    pub reason: EndReason,
    pub sim_time_s: f64,
    pub wall_time: Duration,
    /// Sim time when pilots were released.
    pub released_at_s: Option<f64>,
    /// Wall time the run held at the release until the pilot connected (`None`: no hold,
    /// or the run ended while holding).
    pub pilot_connect_wait: Option<Duration>,
}

/// Runs the lockstep loop until `duration`, `stop` or the observer ends it; `clock` paces
/// it (realtime, scaled) and measures its wall time. With `hold`, simulated time stands at
/// the release until the pilot connects (see [`PilotHold`]).
///
/// # Errors
/// [`CoordinatorError::RunFailed`] when a shard fails (the observer has then seen the
/// final window, see [`RunFailure`]); [`CoordinatorError::Observer`] when the observer
/// cannot record. The shards are told to stop either way.
pub fn run(
    plan: &RunPlan,
    links: &mut [Box<dyn ShardLink>],
    observer: &mut dyn RunObserver,
    stop: &AtomicBool,
    clock: &dyn WallClock,
    hold: Option<&PilotHold>,
) -> Result<RunOutcome, CoordinatorError> {
    let mut state = LoopState {
        step: 0,
        drones: Vec::with_capacity(plan.drones.len()),
        released_at_s: None,
        pilot_connect_wait: None,
    };
    let started = clock.now();
    let result = run_inner(plan, links, observer, stop, clock, hold, &mut state);
    for link in links.iter_mut() {
        let _ = link.send(&ToShard::Stop); // best effort: a dead shard needs no stop
    }
    let error = match result {
        Ok(reason) => {
            let sim_time_s = state.time_s(plan);
            let end = [Event { time_s: sim_time_s, drone: None, kind: EventKind::RunEnded { reason: reason.clone() } }];
            observer.on_window(sim_time_s, &state.drones, &end).map_err(CoordinatorError::Observer)?;
            return Ok(RunOutcome {
                reason,
                sim_time_s,
                wall_time: clock.now().saturating_duration_since(started),
                released_at_s: state.released_at_s,
                pilot_connect_wait: state.pilot_connect_wait,
            });
        }
        Err(e) => e,
    };
    let Some((shard, cause)) = shard_cause(&error) else { return Err(error) };
    let sim_time_s = state.time_s(plan);
    let peer = links.get(shard as usize).and_then(|l| l.peer());
    let reason = EndReason::ShardFailed(describe(shard, peer.as_deref(), &cause));
    let end = [Event { time_s: sim_time_s, drone: None, kind: EventKind::RunEnded { reason: reason.clone() } }];
    let failure = RunFailure {
        shard,
        peer,
        cause,
        outcome: RunOutcome {
            reason,
            sim_time_s,
            wall_time: clock.now().saturating_duration_since(started),
            released_at_s: state.released_at_s,
            pilot_connect_wait: state.pilot_connect_wait,
        },
    };
    observer
        .on_window(sim_time_s, &state.drones, &end)
        .map_err(|source| CoordinatorError::ObserverAfterFailure { failure: Box::new(failure.clone()), source })?;
    Err(CoordinatorError::RunFailed(Box::new(failure)))
}

/// The failed shard's plan index and what happened, for the errors a shard causes.
fn shard_cause(error: &CoordinatorError) -> Option<(u32, String)> {
    /// A message long enough to recognise, short enough for a log line and `endReason`
    /// (an unexpected message may be a whole window of snapshots).
    const MAX_CHARS: usize = 300;
    let (shard, cause) = match error {
        CoordinatorError::Link { shard, source: LinkError::Io(e) } => (*shard as u32, e.to_string()),
        CoordinatorError::Link { shard, source } => (*shard as u32, source.to_string()),
        CoordinatorError::ShardFailed { shard, reason } => (*shard, format!("it reported: {reason}")),
        CoordinatorError::Version { shard, version } => {
            (*shard, format!("it speaks protocol version {version}, expected {PROTOCOL_VERSION}"))
        }
        CoordinatorError::Unexpected { shard, message } => (*shard as u32, format!("unexpected message: {message}")),
        CoordinatorError::Observer(_)
        | CoordinatorError::ObserverAfterFailure { .. }
        | CoordinatorError::RunFailed(_) => return None,
    };
    let cause = match cause.char_indices().nth(MAX_CHARS) {
        Some((cut, _)) => format!("{}...", &cause[..cut]),
        None => cause,
    };
    Some((shard, cause))
}

/// What the loop has completed: kept outside it so a failed run can still be ended at
/// the last window every shard finished.
struct LoopState {
    /// The next step to simulate (every shard is there).
    step: u64,
    /// Every drone at `step`, by global index.
    drones: Vec<DroneSnapshot>,
    /// Sim time when pilots were released.
    released_at_s: Option<f64>,
    /// Wall time held at the release until the pilot connected.
    pilot_connect_wait: Option<Duration>,
}

impl LoopState {
    fn time_s(&self, plan: &RunPlan) -> f64 {
        // The same expression as the loop's window times, to the last bit.
        self.step as f64 * (1.0 / f64::from(plan.physics_rate_hz))
    }
}

/// The lockstep loop; returns the end reason of a run that ended normally.
fn run_inner(
    plan: &RunPlan,
    links: &mut [Box<dyn ShardLink>],
    observer: &mut dyn RunObserver,
    stop: &AtomicBool,
    clock: &dyn WallClock,
    hold: Option<&PilotHold>,
    state: &mut LoopState,
) -> Result<EndReason, CoordinatorError> {
    for (i, link) in links.iter_mut().enumerate() {
        match link.recv().map_err(|source| CoordinatorError::Link { shard: i, source })? {
            FromShard::Hello { version, .. } if version == PROTOCOL_VERSION => {}
            FromShard::Hello { version, shard, .. } => return Err(CoordinatorError::Version { shard, version }),
            FromShard::Failed { shard, reason } => return Err(CoordinatorError::ShardFailed { shard, reason }),
            other => return Err(CoordinatorError::Unexpected { shard: i, message: format!("{other:?}") }),
        }
    }
    let dt_s = 1.0 / f64::from(plan.physics_rate_hz);
    let total_steps = (plan.duration_s / dt_s).round() as u64;
    let window = u64::from(plan.sync_window_steps);
    let pacer = Pacer::new(&plan.spec.clock());
    let mut started = clock.now();
    observer.on_clock_started(started);
    let mut all_ready = false;
    // The window being received; swapped into `state.drones` once every shard answered.
    let mut incoming: Vec<DroneSnapshot> = Vec::with_capacity(plan.drones.len());
    let mut start_events = vec![Event {
        time_s: 0.0,
        drone: None,
        kind: EventKind::RunStarted { drones: plan.drones.len() as u32, shards: plan.shards.len() as u32 },
    }];

    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(EndReason::Interrupted);
        }
        let step = state.step;
        let until = (step + window).min(total_steps);
        let release = all_ready && state.released_at_s.is_none();
        let mut events = std::mem::take(&mut start_events);
        if release {
            let t = step as f64 * dt_s;
            state.released_at_s = Some(t);
            events.push(Event { time_s: t, drone: None, kind: EventKind::PilotsReleased });
        }
        let wait = pacer.wait_before(until as f64 * dt_s, clock.now().saturating_duration_since(started));
        if !wait.is_zero() {
            clock.sleep(wait);
        }
        let leases = observer.leases_changed();
        for (i, link) in links.iter_mut().enumerate() {
            link.send(&ToShard::Advance { until_step: until, release_pilots: release, leases: leases.clone() })
                .map_err(|source| CoordinatorError::Link { shard: i, source })?;
        }
        incoming.clear();
        all_ready = true;
        for (i, link) in links.iter_mut().enumerate() {
            match link.recv().map_err(|source| CoordinatorError::Link { shard: i, source })? {
                FromShard::Advanced { step: s, ready, drones: d, events: e, .. } if s == until => {
                    all_ready &= ready;
                    incoming.extend(d);
                    events.extend(e);
                }
                FromShard::Failed { shard, reason } => return Err(CoordinatorError::ShardFailed { shard, reason }),
                other => return Err(CoordinatorError::Unexpected { shard: i, message: format!("{other:?}") }),
            }
        }
        incoming.sort_by_key(|d| d.index);
        std::mem::swap(&mut state.drones, &mut incoming);
        // Events of one window come from several shards: order them by time, then drone.
        events.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.drone.cmp(&b.drone)));
        state.step = until;
        let time_s = until as f64 * dt_s;
        observer.on_window(time_s, &state.drones, &events).map_err(CoordinatorError::Observer)?;
        if until >= total_steps {
            return Ok(EndReason::Duration);
        }
        if let Some(reason) = observer.stop_reason() {
            return Ok(reason);
        }
        // The observer has seen `pilotsReleased` (and started the pilot): hold here.
        if release && let Some(h) = hold {
            match hold::hold(h, links, observer, stop, clock)? {
                hold::Held::Connected(waited) => {
                    state.pilot_connect_wait = Some(waited);
                    // A paced run goes on from here at its pace, without catching up.
                    started += waited;
                    observer.on_clock_started(started);
                }
                hold::Held::Ends(reason) => return Ok(reason),
            }
        }
    }
}

#[cfg(test)]
mod tests;
