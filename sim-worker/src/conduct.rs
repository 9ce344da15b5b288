//! One run's coordinator side, from its shards' links to its summary, for every runner: the
//! local runner (`sadesim run`, shards as threads) and the coordinator role (`sim-worker
//! coordinator`: a pod on Kubernetes, a process in `sadesim run --processes`). Each caller
//! adds only what is its own through the observer it passes: a progress bar and the pilot
//! process locally; progress lines and stop requests in the role.
//!
//! Conducting a run: the recorder, the onboard cameras and the live stream around the
//! lockstep loop ([`sadesim_engine::coordinator::run`]) with the airspace before them; then its end.
//! A run a shard failure ended has its files closed up to its last complete window (no
//! verdict: the criteria are not judged on part of a run); a run that ended has
//! `airspace.json`, its verdict, the shards' CPU time when the caller knows it, and
//! `summary.json`.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use sadesim_crds::plan::RunPlan;
use sadesim_world::World;

use crate::airspace::runtime::{AIRSPACE_FILE, Airspace, WithAirspace};
use crate::cameras::Cameras;
use crate::record::{Recorder, RunSummary};
use crate::view::{Feed, LiveView, Publisher};
use sadesim_engine::coordinator::{
    self, CoordinatorError, ObserverError, PilotHold, RunFailure, RunObserver, RunOutcome, ShardLink,
};
use sadesim_engine::events::{EndReason, Event};
use sadesim_engine::protocol::DroneSnapshot;

/// What watches a run besides its recorder: its onboard cameras (`spec.fleet[].cameras`) and
/// its live stream (`spec.rendering.enabled`), up before the shards connect so that a
/// browser or the renderer sees the run from its first window.
#[derive(Debug, Default)]
pub struct Watchers {
    pub cameras: Option<Cameras>,
    pub live: Option<LiveView>,
}

impl Watchers {
    /// The cameras of `plan` and, with `spec.rendering.enabled`, the live view served on
    /// `bind` (or a free port of its host), serving the cameras' frames too. Says on stderr
    /// where each answers (`live view: <url>`, `onboard cameras: <url>cameras`).
    ///
    /// # Errors
    /// No Vulkan adapter for the cameras, no three.js in the build, no port to listen on.
    pub fn start(plan: &RunPlan, world: &World, bind: SocketAddr) -> Result<Self, String> {
        let cameras = Cameras::new(plan, world)?;
        let live = match plan.spec.rendering().enabled {
            true => {
                let frames = cameras.as_ref().map(Cameras::store);
                let live = crate::view::serve_live(plan, world, bind, frames)?;
                eprintln!("live view: {} (stream: {}live)", live.server.url(), live.server.url());
                if let Some(c) = &cameras {
                    eprintln!("onboard cameras: {}cameras (rendered on {})", live.server.url(), c.adapter());
                }
                Some(live)
            }
            false => None,
        };
        Ok(Self { cameras, live })
    }

    /// The live stream's feed, for the run's publisher.
    pub fn feed(&self) -> Option<Arc<Feed>> {
        self.live.as_ref().map(|l| l.feed.clone())
    }
}

/// Why a run could not be conducted to its end.
#[derive(Debug, thiserror::Error)]
pub enum ConductError {
    /// The run folder could not be written (the recordings, `airspace.json`, the summary).
    #[error("{0}")]
    Record(#[source] std::io::Error),
    /// The lockstep loop failed, not by a shard's failure (the observer, a shard's link
    /// before the run started).
    #[error(transparent)]
    Coordinator(CoordinatorError),
    /// A shard failed mid-run. The run's files were closed up to its last complete window:
    /// `closed` is their summary, or why closing them failed too.
    #[error("{failure}")]
    RunFailed { failure: Box<RunFailure>, closed: Result<Box<RunSummary>, String> },
}

/// Conducts the run of `plan` over its shards' `links` to its end, recording into `out_dir`
/// what it sees in `world`, with `airspace` (already serving its API) judging the drones
/// and `watchers` rendering and streaming (the caller keeps the live view serving as long as
/// it likes; the cameras are finished into the recording). `caller` sees every window after the recorder
/// (so the files hold a window before the caller acts on it, e.g. starts the pilot on
/// `pilotsReleased`) and may end the run (`stop_reason`); `stop` ends it too (Ctrl-C,
/// SIGTERM). With `hold` (a pilot was started: [`PilotHold::for_plan`]) simulated time
/// stands at the release until the pilot connects, and a run whose pilot never did ends
/// `pilotNotConnected` with no verdict (its criteria would judge a run nobody flew). Once
/// every link is closed, `shard_cpu` gives the shards' CPU time when the
/// caller knows it (threads it joins), recorded in the summary.
///
/// # Errors
/// See [`ConductError`]; the files written so far stay in `out_dir` whatever the error.
#[allow(clippy::too_many_arguments)] // each is one thing the run is conducted with; a struct would only rename them
pub fn conduct(
    plan: &RunPlan,
    world: &World,
    mut links: Vec<Box<dyn ShardLink>>,
    airspace: &mut Airspace,
    watchers: &mut Watchers,
    out_dir: &Path,
    stop: &AtomicBool,
    caller: &mut dyn RunObserver,
    hold: Option<&PilotHold>,
    shard_cpu: impl FnOnce() -> Option<Vec<f64>>,
) -> Result<RunSummary, ConductError> {
    let started = Instant::now();
    let options = Cameras::recorder_options(watchers.cameras.as_ref());
    let mut recorder = Recorder::create(out_dir, plan, world, options).map_err(ConductError::Record)?;
    let mut conducting = Conducting {
        recorder: &mut recorder,
        cameras: watchers.cameras.take(),
        view: watchers.feed().map(Publisher::new),
        caller,
    };
    let result = coordinator::run(
        plan,
        &mut links,
        &mut WithAirspace::new(airspace, &mut conducting),
        stop,
        &crate::transport::SystemClock,
        hold,
    );
    if let Some(cameras) = conducting.cameras.take() {
        cameras.finish(&mut recorder);
    }
    // Every shard connection closed now: the survivors exit without waiting for us.
    drop(links);
    let cpu = shard_cpu();
    let outcome = match result {
        Ok(outcome) => outcome,
        Err(CoordinatorError::RunFailed(failure)) => {
            let closed = close_failed_run(airspace, recorder, &failure.outcome, out_dir)
                .map(Box::new)
                .map_err(|e| e.to_string());
            return Err(ConductError::RunFailed { failure, closed });
        }
        // A file could not be written (the disk filled): the recording stops, its files
        // are closed at their last whole record and `incomplete.json` says which are not
        // whole (`crate::record::disk`).
        Err(CoordinatorError::Observer(ObserverError::Record(e))) => {
            let outcome = RunOutcome {
                reason: EndReason::Requested(format!("recordingFailed: {e}")),
                sim_time_s: recorder.recorded_until_s(),
                wall_time: started.elapsed(),
                released_at_s: None,
                pilot_connect_wait: None,
            };
            let _ = close_failed_run(airspace, recorder, &outcome, out_dir);
            return Err(ConductError::Record(e));
        }
        Err(e) => return Err(ConductError::Coordinator(e)),
    };
    // The room set aside for closing the files after a full disk is for this too.
    recorder.release_reserve();
    if let Err(e) = write_airspace(airspace, out_dir) {
        recorder.not_written(AIRSPACE_FILE, &e);
    }
    recorder.set_closest_zones(&airspace.closest_zones_m());
    if !matches!(outcome.reason, EndReason::PilotNotConnected(_)) {
        recorder.set_verdict(airspace.verdict(plan, outcome.sim_time_s));
    }
    if let Some(cpu) = cpu {
        recorder.set_shard_cpu(cpu);
    }
    recorder.finish(&outcome).map_err(ConductError::Record)
}

/// `airspace.json`: the airspace's record of the run (leases, requests, entries).
fn write_airspace(airspace: &Airspace, out_dir: &Path) -> std::io::Result<()> {
    let json = serde_json::to_vec_pretty(&airspace.record()).map_err(std::io::Error::other)?;
    std::fs::write(out_dir.join(AIRSPACE_FILE), json)
}

/// Closes the files of a run a shard failure ended, up to its last complete window:
/// `airspace.json`, the recordings (`recording.mcap` with its summary, the ULogs flushed)
/// and `summary.json` with `outcome.reason` as `endReason` and the closest zone approaches
/// up to then (no verdict: the criteria were not judged on a whole run).
///
/// # Errors
/// The first file that could not be written (the others are still tried).
fn close_failed_run(
    airspace: &Airspace,
    mut recorder: Recorder,
    outcome: &RunOutcome,
    out_dir: &Path,
) -> std::io::Result<RunSummary> {
    recorder.release_reserve();
    if let Err(e) = write_airspace(airspace, out_dir) {
        recorder.not_written(AIRSPACE_FILE, &e);
    }
    recorder.set_closest_zones(&airspace.closest_zones_m());
    recorder.finish(outcome)
}

/// The run's own observer: cameras, recorder and live stream, then the caller's.
struct Conducting<'a> {
    recorder: &'a mut Recorder,
    /// Frames due in a window are rendered before the next one.
    cameras: Option<Cameras>,
    view: Option<Publisher>,
    caller: &'a mut dyn RunObserver,
}

impl RunObserver for Conducting<'_> {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        if let Some(cameras) = &mut self.cameras {
            cameras.before_recording(self.recorder, time_s, drones, events)?;
        }
        self.recorder.on_window(time_s, drones, events)?;
        if let Some(view) = &mut self.view {
            view.on_window(time_s, drones, events);
        }
        self.caller.on_window(time_s, drones, events)
    }

    fn leases_changed(&mut self) -> Option<Vec<[u32; 2]>> {
        self.caller.leases_changed()
    }

    fn stop_reason(&mut self) -> Option<sadesim_engine::events::EndReason> {
        self.caller.stop_reason()
    }

    fn on_clock_started(&mut self, started: Instant) {
        if let Some(cameras) = &mut self.cameras {
            cameras.clock_started(started);
        }
        self.caller.on_clock_started(started);
    }

    fn on_hold(&mut self, waited: std::time::Duration) {
        self.caller.on_hold(waited);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    use crate::record::test_dir::TempDir;
    use sadesim_engine::events::EventKind;
    use sadesim_engine::fixtures::{plan_of, run_with_groups, world_of};

    #[test]
    fn a_failed_run_still_closes_its_files() {
        let dir = TempDir::new("close-failed-run");
        let plan = plan_of(run_with_groups(&[("a", 2)]).build());
        let airspace = Airspace::new(&plan, &|_| None);
        let mut recorder =
            Recorder::create(&dir.0, &plan, &world_of(&plan), crate::record::RecorderOptions::default()).unwrap();
        for w in 1..=50u32 {
            let t = f64::from(w) * 0.01;
            let drones: Vec<DroneSnapshot> =
                (0..2).map(|index| DroneSnapshot::climbing(index, f64::from(index), t)).collect();
            recorder.on_window(t, &drones, &[]).unwrap();
        }
        let outcome = RunOutcome {
            reason: "shardFailed: shard 1 failed: connection closed".into(),
            sim_time_s: 0.5,
            wall_time: Duration::from_millis(100),
            released_at_s: None,
            pilot_connect_wait: None,
        };
        let summary = close_failed_run(&airspace, recorder, &outcome, &dir.0).unwrap();
        assert_eq!(summary.end_reason, outcome.reason);
        assert!(summary.verdict.is_none(), "criteria are not judged on part of a run");
        let written: RunSummary = serde_json::from_slice(&std::fs::read(dir.0.join("summary.json")).unwrap()).unwrap();
        assert_eq!(written.end_reason, outcome.reason);
        assert!(dir.0.join(AIRSPACE_FILE).is_file());
        // The MCAP was finished: summary section and closing magic, every pose in it.
        let poses = crate::record::mcap_file::finished_pose_count(&dir.0);
        assert_eq!(poses, 2 * 50, "100 Hz x 0.5 s x 2 drones");
    }

    /// Two x500s fly 60 m north at 10 m AGL and return to launch: `through` from the home
    /// area's centre across the zone `tfr` (20 m square, 20 m to 40 m north of it, no
    /// lease), `beside` 30 m east of it, so 20 m from the zone's east edge.
    fn out_and_back_past_a_zone() -> sadesim_crds::plan::RunPlan {
        use sadesim_crds::fixtures::{HOMES, RunBuilder};
        use sadesim_crds::fleet::{HomePlacement, LatLon, Mission, MissionItem};
        use sadesim_crds::geo::{Enu, LocalFrame};
        use sadesim_crds::run::{Clock, ClockMode};
        let run = RunBuilder::test().with(|r| {
            let frame = LocalFrame::new(r.spec.origin.geo());
            let (e0, n0) = frame.to_plane(HOMES.latitude_deg, HOMES.longitude_deg);
            let at = |de: f64, dn: f64| {
                let g = frame.to_geodetic(Enu::new(e0 + de, n0 + dn, 0.0));
                LatLon { latitude_deg: g.latitude_deg, longitude_deg: g.longitude_deg }
            };
            r.spec.duration = "150s".parse().unwrap();
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            let template = r.spec.fleet[0].clone();
            r.spec.fleet = [("through", 0.0), ("beside", 30.0)]
                .map(|(name, de)| {
                    let to = at(de, 60.0);
                    let items = vec![
                        MissionItem::Takeoff { altitude_agl_m: 10.0 },
                        MissionItem::Waypoint {
                            latitude_deg: to.latitude_deg,
                            longitude_deg: to.longitude_deg,
                            altitude_agl_m: 10.0,
                            hold_s: None,
                        },
                        MissionItem::ReturnToLaunch {},
                    ];
                    sadesim_crds::fleet::FleetGroup {
                        name: name.into(),
                        homes: HomePlacement::Explicit(vec![at(de, 0.0)]),
                        mission: Some(Mission { items, speed_mps: Some(8.0) }),
                        ..template.clone()
                    }
                })
                .into();
            r.spec.zones.push(sadesim_engine::fixtures::rect_zone(
                "tfr",
                (e0 - 10.0, e0 + 10.0),
                (n0 + 20.0, n0 + 40.0),
                0.0,
                150.0,
            ));
        });
        plan_of(run.build())
    }

    /// The takeoff and landing times of every drone, from the run's events.
    #[derive(Default)]
    struct FlightTimes {
        takeoffs: Vec<(u32, f64)>,
        landings: Vec<(u32, f64)>,
    }

    impl RunObserver for FlightTimes {
        fn on_window(&mut self, _: f64, _: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
            for e in events {
                match (&e.kind, e.drone) {
                    (EventKind::Takeoff, Some(d)) => self.takeoffs.push((d, e.time_s)),
                    (EventKind::Landed, Some(d)) => self.landings.push((d, e.time_s)),
                    _ => {}
                }
            }
            Ok(())
        }
    }

    #[test]
    fn a_flight_out_and_back_past_a_zone_has_its_flight_time_landing_error_zone_distance_and_energy() {
        let dir = TempDir::new("conduct-out-and-back");
        let plan = out_and_back_past_a_zone();
        let world = std::sync::Arc::new(world_of(&plan));
        let surroundings = sadesim_engine::shard::Surroundings::new(&plan, world.clone(), None);
        let mut links: Vec<Box<dyn ShardLink>> = Vec::new();
        let mut threads = Vec::new();
        for shard in &plan.shards {
            let (link, handle) = crate::transport::spawn_thread(&plan, shard.index, &surroundings, None).unwrap();
            links.push(Box::new(link));
            threads.push(handle);
        }
        let mut airspace = Airspace::new(&plan, &|_| None);
        let mut watchers = Watchers { cameras: None, live: None };
        let mut times = FlightTimes::default();
        let stop = AtomicBool::new(false);
        let summary =
            conduct(&plan, &world, links, &mut airspace, &mut watchers, &dir.0, &stop, &mut times, None, || None)
                .unwrap();
        for t in threads {
            t.join().unwrap();
        }
        let [through, beside] = &summary.per_drone[..] else { panic!("two drones: {:?}", summary.per_drone) };
        for d in [through, beside] {
            assert!(d.took_off && d.landed && !d.crashed, "{d:?}");
            // Airborne from takeoff to touchdown, give or take the windows around them.
            let takeoff = times.takeoffs.iter().find(|t| t.0 == d.index).expect("takeoff").1;
            let landing = times.landings.iter().rev().find(|t| t.0 == d.index).expect("landing").1;
            let flight_s = d.flight_time_s.expect("flew");
            assert!((flight_s - (landing - takeoff)).abs() < 1.0, "{flight_s} s airborne, {takeoff}..{landing}");
            assert!(flight_s > 60.0 * 2.0 / 8.0, "at least the 120 m out and back at 8 m/s: {flight_s} s");
            let error_m = d.landing_error_m.expect("landed");
            assert!(error_m < 5.0, "return to launch lands at home, within its GNSS error: {error_m} m off");
            // Charge drawn times a 4-cell LiPo's voltage (3.3 V to 4.2 V a cell), x500: 5000 mAh.
            let drawn_ah = (1.0 - d.final_battery_remaining) * 5.0;
            let energy_wh = d.energy_wh.expect("drawn");
            assert!(
                energy_wh > drawn_ah * 4.0 * 3.3 && energy_wh < drawn_ah * 4.0 * 4.2,
                "{energy_wh} Wh, {drawn_ah} Ah"
            );
        }
        assert_eq!(through.closest_zone_m, Some(0.0), "flew through the zone without a lease");
        let beside_m = beside.closest_zone_m.expect("flew past the zone");
        assert!((beside_m - 20.0).abs() < 1.5, "20 m east of the zone's edge: {beside_m} m");
        let written: RunSummary = serde_json::from_slice(&std::fs::read(dir.0.join("summary.json")).unwrap()).unwrap();
        assert_eq!(written.per_drone, summary.per_drone);
    }
}
