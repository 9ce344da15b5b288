//! The hold for the pilot: simulated time stands at the release until the pilot connects.
//!
//! The pilot process (or pod) starts when the pilots are released, and may need a while
//! before it says anything: a `cargo run` that builds first, a Python pilot importing its
//! SDK, a pod pulling its image. Simulated time that ran on meanwhile would be lost to the
//! pilot (a run `asFastAsPossible` can be over before it starts). So after the window that
//! carries `pilotsReleased` the coordinator asks the shards to hold ([`ToShard::Hold`])
//! instead of advancing: they read their drones' MAVLink sockets, keeping what arrived for
//! the sessions, and send each drone's HEARTBEAT once a wall second, so that a pilot waiting
//! for one (MAVSDK, `wait_heartbeat`) finds its drones. The hold ends when a MAVLink frame
//! from a peer has reached any drone the pilot flies (a group without a `mission`), and the
//! run goes on from the same simulated time, the frames handled at the next exchange as if
//! they had arrived just before it.
//!
//! Why the first frame to *any* of its drones, not to every one: a pilot may talk to its
//! drones one after another (fly the first, then the second), and one that has not spoken
//! to some drone yet may be waiting for simulated time to move; holding for every drone
//! would stall it. A pilot that connects to its drones one by one over the wall clock is
//! held until the first.
//!
//! # Guarantees
//! - Nothing is simulated while holding, and the hold's wall time reaches the simulation
//!   nowhere: a run whose pilot connects late has the same windows, in the same simulated
//!   time, as one whose pilot connects at once (tested).
//! - A pilot silent for [`PilotHold::limit`] of wall time ends the run with
//!   [`EndReason::PilotNotConnected`], saying so; Ctrl-C and the observer's stop requests
//!   (the pilot exited, the operator asked) end the hold too.
//! - Paced runs (realtime, scaled) restart their clock after the hold: no catching up.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sadesim_crds::plan::RunPlan;

use super::{CoordinatorError, EndReason, RunObserver, ShardLink};
use crate::pacing::WallClock;
use crate::protocol::{FromShard, ToShard};

/// Between two looks at the shards while holding.
pub const HOLD_POLL: Duration = Duration::from_millis(50);
/// Between two HEARTBEATs of a held drone (PX4's 1 Hz).
pub const HOLD_HEARTBEAT: Duration = Duration::from_secs(1);

/// Holding at the release for the pilot ([`super::run`]'s `hold`).
#[derive(Clone, Debug, PartialEq)]
pub struct PilotHold {
    /// The drones the pilot flies (global indices, ascending): the hold ends when MAVLink
    /// from a peer reaches any of them.
    pub drones: Vec<u32>,
    /// The longest wall time to hold (`spec.pilot.connectTimeoutS`).
    pub limit: Duration,
}

impl PilotHold {
    /// The hold of a run of `plan` whose pilot is started and whose drones have MAVLink:
    /// the drones of the groups without a `mission`, `spec.pilot.connectTimeoutS`. `None`
    /// when there is nothing to hold for: no `spec.pilot`, or every drone flies a mission.
    pub fn for_plan(plan: &RunPlan) -> Option<Self> {
        let pilot = plan.spec.pilot.as_ref()?;
        let drones: Vec<u32> = plan
            .drones
            .iter()
            .filter(|d| plan.spec.fleet.get(d.group_index as usize).is_some_and(|g| g.mission.is_none()))
            .map(|d| d.index)
            .collect();
        (!drones.is_empty()).then(|| Self { drones, limit: Duration::from_secs(u64::from(pilot.connect_timeout_s())) })
    }

    /// [`EndReason::PilotNotConnected`] for this hold.
    fn not_connected(&self) -> EndReason {
        let drones = match self.drones.len() {
            1 => "the drone it flies".to_string(),
            n => format!("any of the {n} drones it flies"),
        };
        EndReason::PilotNotConnected(format!(
            "the pilot did not connect within {} s: no MAVLink frame reached {drones} (spec.pilot.connectTimeoutS; see pilot.log)",
            self.limit.as_secs()
        ))
    }
}

/// How a hold ended.
#[derive(Debug, PartialEq)]
pub(super) enum Held {
    /// The pilot's first frame reached one of its drones after this much wall time.
    Connected(Duration),
    /// The run ends: the limit passed, Ctrl-C, or the observer asked.
    Ends(EndReason),
}

/// Holds the run (see the module docs) until the pilot connects or the run ends.
///
/// # Errors
/// A shard failed or answered out of protocol (the loop's errors, see [`super::run`]).
pub(super) fn hold(
    hold: &PilotHold,
    links: &mut [Box<dyn ShardLink>],
    observer: &mut dyn RunObserver,
    stop: &AtomicBool,
    clock: &dyn WallClock,
) -> Result<Held, CoordinatorError> {
    let began = clock.now();
    let mut last_heartbeat: Option<Instant> = None;
    loop {
        let now = clock.now();
        let waited = now.saturating_duration_since(began);
        if stop.load(Ordering::Relaxed) {
            return Ok(Held::Ends(EndReason::Interrupted));
        }
        observer.on_hold(waited);
        if let Some(reason) = observer.stop_reason() {
            return Ok(Held::Ends(reason));
        }
        let heartbeat = last_heartbeat.is_none_or(|t| now.saturating_duration_since(t) >= HOLD_HEARTBEAT);
        if heartbeat {
            last_heartbeat = Some(now);
        }
        for (i, link) in links.iter_mut().enumerate() {
            link.send(&ToShard::Hold { heartbeat }).map_err(|source| CoordinatorError::Link { shard: i, source })?;
        }
        let mut connected = false;
        for (i, link) in links.iter_mut().enumerate() {
            match link.recv().map_err(|source| CoordinatorError::Link { shard: i, source })? {
                FromShard::Held { heard, .. } => {
                    connected |= heard.iter().any(|d| hold.drones.binary_search(d).is_ok());
                }
                FromShard::Failed { shard, reason } => return Err(CoordinatorError::ShardFailed { shard, reason }),
                other => return Err(CoordinatorError::Unexpected { shard: i, message: format!("{other:?}") }),
            }
        }
        if connected {
            return Ok(Held::Connected(clock.now().saturating_duration_since(began)));
        }
        if waited >= hold.limit {
            return Ok(Held::Ends(hold.not_connected()));
        }
        clock.sleep(HOLD_POLL.min(hold.limit - waited));
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use ::mavlink::MavHeader;
    use ::mavlink::dialects::common::{COMMAND_LONG_DATA, MavCmd, MavMessage};
    use sadesim_crds::run::{Clock, ClockMode};

    use super::*;
    use crate::coordinator::{LinkError, ObserverError, RunOutcome, run};
    use crate::events::Event;
    use crate::fixtures::{plan_of, run_with_groups, world_of};
    use crate::mavlink::frame::{FrameParser, encode};
    use crate::protocol::DroneSnapshot;
    use crate::shard::{Shard, Surroundings};

    /// A wall clock whose sleeps pass at once: it moves on by what was slept.
    struct VirtualClock {
        base: Instant,
        slept: Mutex<Duration>,
    }

    impl VirtualClock {
        fn new() -> Self {
            Self { base: Instant::now(), slept: Mutex::new(Duration::ZERO) }
        }
        fn slept(&self) -> Duration {
            *self.slept.lock().unwrap()
        }
    }

    impl WallClock for VirtualClock {
        fn now(&self) -> Instant {
            self.base + self.slept()
        }
        fn sleep(&self, duration: Duration) {
            *self.slept.lock().unwrap() += duration;
        }
    }

    /// A pilot's COMMAND_LONG arming drone 1 (system id 1), as one checksummed frame.
    fn arm_frame() -> crate::mavlink::frame::Frame {
        let arm = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 1,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            param1: 1.0,
            ..Default::default()
        });
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        FrameParser::new().push(&encode(header, &arm)).pop().expect("one frame")
    }

    /// One real shard (MAVLink queues, no sockets) whose pilot "connects" at the
    /// `connects_at`-th hold: its arming command lands in drone `to`'s inbound queue then.
    struct LatePilot {
        shard: Shard,
        reply: Option<FromShard>,
        holds: u32,
        connects_at: Option<u32>,
        to: usize,
    }

    impl ShardLink for LatePilot {
        fn send(&mut self, msg: &ToShard) -> Result<(), LinkError> {
            if matches!(msg, ToShard::Hold { .. }) {
                self.holds += 1;
                if Some(self.holds) == self.connects_at {
                    self.shard.mavlink_queues()[self.to].inbound.push(arm_frame());
                }
            }
            self.reply = self.shard.handle(msg.clone());
            // Nothing reads the telemetry: keep the queues short.
            for q in self.shard.mavlink_queues() {
                q.outbound.clear();
            }
            Ok(())
        }
        fn recv(&mut self) -> Result<FromShard, LinkError> {
            match self.reply.take() {
                Some(r) => Ok(r),
                None => Ok(self.shard.hello()),
            }
        }
    }

    /// Every window: time, drones and events.
    #[derive(Default)]
    struct Windows(Vec<(f64, Vec<DroneSnapshot>, Vec<Event>)>);

    impl RunObserver for Windows {
        fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
            self.0.push((time_s, drones.to_vec(), events.to_vec()));
            Ok(())
        }
    }

    /// Two drones, `pilot` (flown by the pilot) and `scripted` (a mission), 6 s at 250 Hz.
    fn plan(clock: ClockMode) -> RunPlan {
        let run = run_with_groups(&[("pilot", 1), ("scripted", 1)])
            .with_pilot(&["pilot"])
            .with(|r| {
                r.spec.clock = Some(Clock { mode: clock, factor: None });
                r.spec.duration = "6s".parse().expect("a valid duration");
                r.spec.physics_rate_hz = Some(250);
                let template = r.spec.fleet[0].clone();
                r.spec.fleet[1].mission = Some(sadesim_crds::fleet::Mission {
                    items: vec![sadesim_crds::fleet::MissionItem::Takeoff { altitude_agl_m: 5.0 }],
                    speed_mps: None,
                });
                r.spec.fleet[1].homes = template.homes;
                r.spec.pilot.as_mut().expect("a pilot").connect_timeout_s = Some(20);
            })
            .build();
        plan_of(run)
    }

    /// Runs `plan` with the pilot's command reaching drone `to` at the `connects_at`-th hold.
    fn fly(
        plan: &RunPlan,
        connects_at: Option<u32>,
        to: usize,
        hold: bool,
    ) -> (Result<RunOutcome, CoordinatorError>, Windows, Duration) {
        let world = std::sync::Arc::new(world_of(plan));
        let mut shard = Shard::new(plan, 0, &Surroundings::new(plan, world, None)).expect("a shard");
        shard.enable_mavlink(plan, 0).expect("MAVLink");
        let pilot = LatePilot { shard, reply: None, holds: 0, connects_at, to };
        let mut links: Vec<Box<dyn ShardLink>> = vec![Box::new(pilot)];
        let mut windows = Windows::default();
        let clock = VirtualClock::new();
        let hold = PilotHold::for_plan(plan).filter(|_| hold);
        let outcome = run(plan, &mut links, &mut windows, &AtomicBool::new(false), &clock, hold.as_ref());
        (outcome, windows, clock.slept())
    }

    #[test]
    fn the_hold_is_for_the_drones_without_a_mission_with_the_scenario_s_limit() {
        let plan = plan(ClockMode::AsFastAsPossible);
        let hold = PilotHold::for_plan(&plan).expect("a pilot-flown drone");
        assert_eq!(hold, PilotHold { drones: vec![0], limit: Duration::from_secs(20) });
        let mut no_pilot = plan.clone();
        no_pilot.spec.pilot = None;
        assert_eq!(PilotHold::for_plan(&no_pilot), None, "no pilot, no hold");
        let mut all_scripted = plan.clone();
        all_scripted.spec.fleet[0].mission = all_scripted.spec.fleet[1].mission.clone();
        assert_eq!(PilotHold::for_plan(&all_scripted), None, "nothing for a pilot to connect to");
    }

    /// The pilot's first frame reaching its drone at the 2nd or the 300th hold (15 s of wall
    /// time later): the same windows, drones and events, and its command acted on at the
    /// same simulated time. Only the wall time held differs.
    #[test]
    fn a_late_pilot_flies_the_same_run_as_a_prompt_one() {
        let plan = plan(ClockMode::AsFastAsPossible);
        let (prompt, prompt_windows, prompt_slept) = fly(&plan, Some(2), 0, true);
        let (late, late_windows, late_slept) = fly(&plan, Some(300), 0, true);
        let (prompt, late) = (prompt.expect("the run ends"), late.expect("the run ends"));
        assert_eq!(prompt.reason, EndReason::Duration);
        assert_eq!(late.reason, EndReason::Duration);
        assert_eq!(prompt.sim_time_s, late.sim_time_s);
        assert_eq!(prompt.released_at_s, late.released_at_s);
        assert!(prompt_windows.0 == late_windows.0, "the wall time held reached the simulation");
        // The arming command was acted on (armed, or refused with a reason) after the release.
        let released = prompt.released_at_s.expect("released");
        let answered = prompt_windows.0.iter().flat_map(|w| &w.2).find(|e| {
            e.drone == Some(0)
                && matches!(e.kind, crate::events::EventKind::Armed | crate::events::EventKind::CommandRejected { .. })
        });
        let answered = answered.expect("the pilot's command was handled");
        assert!(answered.time_s > released && answered.time_s < released + 0.1, "{answered:?} after {released}");
        // Held 1 poll against 299 (the virtual clock counts the polls' sleeps).
        let waited = |o: &RunOutcome| o.pilot_connect_wait.expect("held").as_secs_f64();
        assert!((waited(&prompt) - 0.05).abs() < 1e-6, "{:?}", prompt.pilot_connect_wait);
        assert!((waited(&late) - 299.0 * 0.05).abs() < 1e-6, "{:?}", late.pilot_connect_wait);
        assert!(late_slept > prompt_slept);
    }

    #[test]
    fn a_pilot_that_never_connects_ends_the_run_at_the_release_after_the_limit() {
        let plan = plan(ClockMode::AsFastAsPossible);
        let (outcome, windows, slept) = fly(&plan, None, 0, true);
        let outcome = outcome.expect("the run ends cleanly");
        let EndReason::PilotNotConnected(why) = &outcome.reason else { panic!("{:?}", outcome.reason) };
        assert!(
            why.starts_with("the pilot did not connect within 20 s: no MAVLink frame reached the drone it flies"),
            "{why}"
        );
        assert!(outcome.reason.to_string().starts_with("pilotNotConnected: the pilot did not connect within 20 s"));
        // Simulated time stood at the release (the window carrying it is the last but the end).
        let released = outcome.released_at_s.expect("released");
        let dt = 1.0 / f64::from(plan.physics_rate_hz) * f64::from(plan.sync_window_steps);
        assert!((outcome.sim_time_s - (released + dt)).abs() < 1e-9, "{} vs {released}", outcome.sim_time_s);
        assert_eq!(outcome.pilot_connect_wait, None);
        assert_eq!(slept, Duration::from_secs(20), "held exactly the limit");
        let last = windows.0.last().expect("the end's window");
        assert!(matches!(&last.2[..], [Event { kind: crate::events::EventKind::RunEnded { .. }, .. }]));
    }

    #[test]
    fn mavlink_to_a_drone_flying_a_mission_is_not_the_pilot_connecting() {
        let plan = plan(ClockMode::AsFastAsPossible);
        let (outcome, _, _) = fly(&plan, Some(2), 1, true);
        assert!(matches!(outcome.expect("ends").reason, EndReason::PilotNotConnected(_)));
    }

    #[test]
    fn without_a_hold_simulated_time_runs_on_at_once() {
        let plan = plan(ClockMode::AsFastAsPossible);
        let (outcome, _, slept) = fly(&plan, None, 0, false);
        let outcome = outcome.expect("ends");
        assert_eq!((outcome.reason, outcome.pilot_connect_wait), (EndReason::Duration, None));
        assert_eq!(slept, Duration::ZERO);
    }

    /// A realtime run held 15 s goes on at its pace from there: it does not race to catch
    /// up the 15 s (the virtual clock sleeps the run's 6 s plus the hold).
    #[test]
    fn a_paced_run_keeps_its_pace_after_the_hold() {
        let plan = plan(ClockMode::Realtime);
        let (outcome, _, slept) = fly(&plan, Some(301), 0, true);
        let outcome = outcome.expect("ends");
        assert_eq!(outcome.reason, EndReason::Duration);
        let held = outcome.pilot_connect_wait.expect("held").as_secs_f64();
        assert!((held - 15.0).abs() < 1e-6, "{held}");
        let slept = slept.as_secs_f64();
        assert!((slept - (6.0 + held)).abs() < 0.05, "slept {slept} s: 6 s of run and {held} s held");
    }

    /// A held shard simulates nothing, sends each drone's HEARTBEAT when asked, and keeps
    /// what arrived for the sessions' next exchange, saying which drones have something.
    #[test]
    fn a_held_shard_heartbeats_and_keeps_the_pilot_s_frames_for_the_next_exchange() {
        let plan = plan(ClockMode::AsFastAsPossible);
        let world = std::sync::Arc::new(world_of(&plan));
        let mut shard = Shard::new(&plan, 0, &Surroundings::new(&plan, world, None)).expect("a shard");
        shard.enable_mavlink(&plan, 0).expect("MAVLink");
        shard.handle(ToShard::Advance { until_step: 10, release_pilots: false, leases: None });
        for q in shard.mavlink_queues() {
            q.outbound.clear();
        }
        let held = shard.handle(ToShard::Hold { heartbeat: true });
        assert_eq!(held, Some(FromShard::Held { shard: 0, heard: vec![] }));
        for q in shard.mavlink_queues() {
            let [crate::mavlink::session::Outgoing::Message(MavMessage::HEARTBEAT(_))] = &q.outbound[..] else {
                panic!("one HEARTBEAT: {:?}", q.outbound)
            };
            q.outbound.clear();
        }
        // A router registering with the drones (its own HEARTBEAT) is not the pilot.
        let router = MavMessage::HEARTBEAT(Default::default());
        let ids = MavHeader {
            system_id: u32::from(crate::shard::ROUTER_SYSTEM_ID),
            component_id: crate::shard::ROUTER_COMPONENT_ID,
            sequence: 0,
        };
        let router = FrameParser::new().push(&encode(ids, &router)).pop().expect("one frame");
        shard.mavlink_queues()[1].inbound.push(router);
        let held = shard.handle(ToShard::Hold { heartbeat: false });
        assert_eq!(held, Some(FromShard::Held { shard: 0, heard: vec![] }));
        shard.mavlink_queues()[0].inbound.push(arm_frame());
        let held = shard.handle(ToShard::Hold { heartbeat: false });
        assert_eq!(held, Some(FromShard::Held { shard: 0, heard: vec![0] }));
        assert!(shard.mavlink_queues().iter().all(|q| q.outbound.is_empty()), "no heartbeat unless asked");
        // Kept (held again: still there), then handled at the next exchange.
        let held = shard.handle(ToShard::Hold { heartbeat: false });
        assert_eq!(held, Some(FromShard::Held { shard: 0, heard: vec![0] }));
        let Some(FromShard::Advanced { step, .. }) =
            shard.handle(ToShard::Advance { until_step: 20, release_pilots: true, leases: None })
        else {
            panic!("a window")
        };
        assert_eq!(step, 20, "the holds simulated nothing");
        assert!(shard.mavlink_queues()[0].inbound.is_empty(), "the session read the frame");
    }

    /// The observer's stop request (the pilot process exited while the run held) ends the
    /// hold at once with its reason.
    #[test]
    fn a_stop_request_ends_the_hold() {
        struct ExitsWhileHeld(u32);
        impl RunObserver for ExitsWhileHeld {
            fn on_window(&mut self, _: f64, _: &[DroneSnapshot], _: &[Event]) -> Result<(), ObserverError> {
                Ok(())
            }
            fn on_hold(&mut self, _: Duration) {
                self.0 += 1;
            }
            fn stop_reason(&mut self) -> Option<EndReason> {
                (self.0 >= 3).then_some(EndReason::PilotExited)
            }
        }
        let plan = plan(ClockMode::AsFastAsPossible);
        let world = std::sync::Arc::new(world_of(&plan));
        let mut shard = Shard::new(&plan, 0, &Surroundings::new(&plan, world, None)).expect("a shard");
        shard.enable_mavlink(&plan, 0).expect("MAVLink");
        let pilot = LatePilot { shard, reply: None, holds: 0, connects_at: None, to: 0 };
        let mut links: Vec<Box<dyn ShardLink>> = vec![Box::new(pilot)];
        let clock = VirtualClock::new();
        let hold = PilotHold::for_plan(&plan);
        let mut observer = ExitsWhileHeld(0);
        let outcome =
            run(&plan, &mut links, &mut observer, &AtomicBool::new(false), &clock, hold.as_ref()).expect("ends");
        assert_eq!(outcome.reason, EndReason::PilotExited);
        assert_eq!(clock.slept(), 2 * HOLD_POLL);
    }
}
