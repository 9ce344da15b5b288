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
use crate::pacing::Pacer;
use crate::protocol::{DroneSnapshot, FromShard, PROTOCOL_VERSION, ToShard};

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
}

/// A broken shard connection.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("shard connection closed")]
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
    Observer(String),
}

/// What the coordinator reports each window, and asks about ending early.
pub trait RunObserver {
    /// A window ended at `time_s`: every drone's state (by global index) and the events
    /// that happened during the window, in time order.
    ///
    /// # Errors
    /// A message; the run stops (outputs already written are kept).
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), String>;
    /// Asked before each window: the valid zone leases as `[drone, zone]` pairs when they
    /// changed since the last call (the shards' geofences let drones into leased zones).
    fn leases_changed(&mut self) -> Option<Vec<[u32; 2]>> {
        None
    }
    /// Asked after each window: `Some(reason)` ends the run (e.g. the pilot exited).
    fn stop_reason(&mut self) -> Option<String> {
        None
    }
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOutcome {
    /// `duration`, `interrupted`, or the observer's reason.
    pub reason: String,
    pub sim_time_s: f64,
    pub wall_time: Duration,
    /// Sim time when pilots were released.
    pub released_at_s: Option<f64>,
}

/// Runs the lockstep loop until `duration`, `stop` or the observer ends it.
///
/// # Errors
/// A [`CoordinatorError`] when a shard fails or the observer cannot record; the shards are
/// told to stop either way.
pub fn run(
    plan: &RunPlan,
    links: &mut [Box<dyn ShardLink>],
    observer: &mut dyn RunObserver,
    stop: &AtomicBool,
) -> Result<RunOutcome, CoordinatorError> {
    let result = run_inner(plan, links, observer, stop);
    for link in links.iter_mut() {
        let _ = link.send(&ToShard::Stop); // best effort: a dead shard needs no stop
    }
    result
}

fn run_inner(
    plan: &RunPlan,
    links: &mut [Box<dyn ShardLink>],
    observer: &mut dyn RunObserver,
    stop: &AtomicBool,
) -> Result<RunOutcome, CoordinatorError> {
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
    let started = Instant::now();
    let mut step = 0u64;
    let mut all_ready = false;
    let mut released_at_s = None;
    let mut drones: Vec<DroneSnapshot> = Vec::with_capacity(plan.drones.len());
    let mut start_events = vec![Event {
        time_s: 0.0,
        drone: None,
        kind: EventKind::RunStarted { drones: plan.drones.len() as u32, shards: plan.shards.len() as u32 },
    }];

    let reason = loop {
        if stop.load(Ordering::Relaxed) {
            break "interrupted".to_string();
        }
        let until = (step + window).min(total_steps);
        let release = all_ready && released_at_s.is_none();
        let mut events = std::mem::take(&mut start_events);
        if release {
            let t = step as f64 * dt_s;
            released_at_s = Some(t);
            events.push(Event { time_s: t, drone: None, kind: EventKind::PilotsReleased });
        }
        let wait = pacer.wait_before(until as f64 * dt_s, started.elapsed());
        if !wait.is_zero() {
            std::thread::sleep(wait);
        }
        let leases = observer.leases_changed();
        for (i, link) in links.iter_mut().enumerate() {
            link.send(&ToShard::Advance { until_step: until, release_pilots: release, leases: leases.clone() })
                .map_err(|source| CoordinatorError::Link { shard: i, source })?;
        }
        drones.clear();
        all_ready = true;
        for (i, link) in links.iter_mut().enumerate() {
            match link.recv().map_err(|source| CoordinatorError::Link { shard: i, source })? {
                FromShard::Advanced { step: s, ready, drones: d, events: e, .. } if s == until => {
                    all_ready &= ready;
                    drones.extend(d);
                    events.extend(e);
                }
                FromShard::Failed { shard, reason } => return Err(CoordinatorError::ShardFailed { shard, reason }),
                other => return Err(CoordinatorError::Unexpected { shard: i, message: format!("{other:?}") }),
            }
        }
        drones.sort_by_key(|d| d.index);
        // Events of one window come from several shards: order them by time, then drone.
        events.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.drone.cmp(&b.drone)));
        step = until;
        let time_s = step as f64 * dt_s;
        observer.on_window(time_s, &drones, &events).map_err(CoordinatorError::Observer)?;
        if step >= total_steps {
            break "duration".to_string();
        }
        if let Some(reason) = observer.stop_reason() {
            break reason;
        }
    };
    let sim_time_s = step as f64 * dt_s;
    let end = [Event { time_s: sim_time_s, drone: None, kind: EventKind::RunEnded { reason: reason.clone() } }];
    observer.on_window(sim_time_s, &drones, &end).map_err(CoordinatorError::Observer)?;
    Ok(RunOutcome { reason, sim_time_s, wall_time: started.elapsed(), released_at_s })
}
