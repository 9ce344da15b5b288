//! The recorder: a [`RunObserver`] writing every evidence file of a run into one folder.

use std::path::{Path, PathBuf};

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_world::World;

use super::cost::Lap;
use super::{
    CameraImage, CameraStream, DroneSummary, EventLog, McapRecorder, RunSummary, Sampler, StreamWriter, TrajectoryCsv,
    TrajectoryGeoJson, UlogRecorder,
};
use sadesim_engine::airspace::criteria::RunVerdict;
use sadesim_engine::coordinator::{ObserverError, RunObserver, RunOutcome};
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::DroneSnapshot;

/// Sampling rates of the recorded streams, and the recorded cameras.
#[derive(Clone, Debug, PartialEq)]
pub struct RecorderOptions {
    /// Rows per drone per simulated second in `trajectory.csv`.
    pub trajectory_hz: f64,
    /// Points per drone per simulated second in `trajectory.geojson`.
    pub track_hz: f64,
    /// The onboard cameras whose frames `recording.mcap` holds ([`Recorder::queue_images`]).
    pub cameras: Vec<CameraStream>,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self { trajectory_hz: 10.0, track_hz: 1.0, cameras: Vec::new() }
    }
}

/// Writes `events.jsonl`, `trajectory.csv` as the run goes, and `trajectory.geojson` and
/// `summary.json` at [`Recorder::finish`]; `recording.mcap` and the ULogs as the run goes
/// too, on a thread of their own ([`StreamWriter`]).
#[derive(Debug)]
pub struct Recorder {
    dir: PathBuf,
    plan: RunPlan,
    frame: LocalFrame,
    events: EventLog,
    csv: TrajectoryCsv,
    tracks: TrajectoryGeoJson,
    /// When `trajectory.csv` takes a row.
    rows: Sampler,
    /// When `trajectory.geojson` takes a point (the first window included).
    track_points: Sampler,
    summary: RunSummary,
    /// Per drone: the GNSS part of the summary.
    gnss: Vec<super::gnss_tally::GnssTally>,
    /// `gnss.csv`: each drone's receiver in flight once a second, for the report's GNSS
    /// timeline; written for runs with the ranging receiver (a constellation) only.
    gnss_csv: Option<std::io::BufWriter<std::fs::File>>,
    /// Per drone: what the summary carries from one window to the next.
    drone_tracks: Vec<super::summary::DroneTrack>,
    /// When the last window folded into the summary ended, simulated seconds.
    last_window_end_s: f64,
    /// `recording.mcap` (unless `spec.recording.mcap` is false) and `ulog/*.ulg` (unless
    /// `spec.recording.ulog` is false); `None` when both are off.
    streams: Option<StreamWriter>,
    /// Camera frames for the next window ([`Recorder::queue_images`]).
    images: Vec<CameraImage>,
}

impl Recorder {
    /// Creates the files in `dir` (which must exist); `world` is the run's (drawn in
    /// `recording.mcap`).
    ///
    /// # Errors
    /// When a file cannot be created.
    pub fn create(dir: &Path, plan: &RunPlan, world: &World, options: RecorderOptions) -> std::io::Result<Self> {
        let summary = RunSummary {
            run: plan.run.name.clone(),
            drones: plan.drones.len() as u32,
            shards: plan.shards.len() as u32,
            per_drone: plan
                .drones
                .iter()
                .map(|d| DroneSummary {
                    index: d.index,
                    name: d.name.clone(),
                    group: d.group.clone(),
                    // Tallied in flight in runs with wind (`summary::observe_window`).
                    wind: plan.spec.environment().wind.map(|_| Default::default()),
                    ..Default::default()
                })
                .collect(),
            ..Default::default()
        };
        let recording = plan.spec.recording();
        let mcap = if recording.mcap { Some(McapRecorder::create(dir, plan, world, &options.cameras)?) } else { None };
        let ulog = if recording.ulog { Some(UlogRecorder::create(dir, plan)?) } else { None };
        let streams = if mcap.is_some() || ulog.is_some() { Some(StreamWriter::start(mcap, ulog)?) } else { None };
        Ok(Self {
            streams,
            dir: dir.to_path_buf(),
            frame: LocalFrame::new(plan.spec.origin.geo()),
            events: EventLog::create(&dir.join(sadesim_crds::outcome::run_folder::EVENTS))?,
            csv: TrajectoryCsv::create(&dir.join("trajectory.csv"))?,
            tracks: TrajectoryGeoJson::new(plan.drones.len()),
            rows: Sampler::new(options.trajectory_hz),
            track_points: Sampler::including_start(options.track_hz),
            summary,
            gnss: vec![super::gnss_tally::GnssTally::default(); plan.drones.len()],
            gnss_csv: match plan.spec.environment().gnss.is_some_and(|g| g.constellation.is_some()) {
                true => {
                    use std::io::Write;
                    let mut w = std::io::BufWriter::new(std::fs::File::create(
                        dir.join(sadesim_crds::outcome::run_folder::GNSS),
                    )?);
                    writeln!(w, "time_s,drone,fix_type,satellites,hdop,fix_error_m,estimate_error_m")?;
                    Some(w)
                }
                false => None,
            },
            drone_tracks: plan
                .drones
                .iter()
                .map(|d| super::summary::DroneTrack::new([d.home.local.east_m, d.home.local.north_m]))
                .collect(),
            last_window_end_s: 0.0,
            images: Vec::new(),
            plan: plan.clone(),
        })
    }

    pub fn summary(&self) -> &RunSummary {
        &self.summary
    }

    /// Camera frames taken in the coming window, written into `recording.mcap` with it
    /// (dropped when the run records no MCAP).
    pub fn queue_images(&mut self, images: Vec<CameraImage>) {
        self.images.extend(images);
    }

    /// Frames and late frames per onboard camera, written into `summary.json`.
    pub fn set_camera_tallies(&mut self, tallies: Vec<sadesim_crds::outcome::summary::CameraTally>) {
        self.summary.cameras = tallies;
    }

    /// Per drone (index order), the closest horizontal approach to a zone it held no lease
    /// for (the compliance monitor's), written into `summary.json` (`closestZoneM`).
    pub fn set_closest_zones(&mut self, closest_m: &[Option<f64>]) {
        for (d, closest) in self.summary.per_drone.iter_mut().zip(closest_m) {
            d.closest_zone_m = *closest;
        }
    }

    /// The verdict on the scenario's criteria, written into `summary.json` by [`Recorder::finish`].
    pub fn set_verdict(&mut self, verdict: RunVerdict) {
        self.summary.verdict = Some(verdict);
    }

    /// The CPU seconds each shard's thread spent stepping its drones, by shard index, written
    /// into `summary.json` (`shardCpuS`) by [`Recorder::finish`].
    pub fn set_shard_cpu(&mut self, shard_cpu_s: Vec<f64>) {
        self.summary.shard_cpu_s = shard_cpu_s;
    }

    /// Writes the end-of-run files and returns the summary.
    ///
    /// # Errors
    /// I/O errors.
    pub fn finish(mut self, outcome: &RunOutcome) -> std::io::Result<RunSummary> {
        if let Some(streams) = self.streams.take() {
            let spent = streams.finish()?;
            let cost = &mut self.summary.recording_cpu_s;
            cost.mcap += spent.mcap;
            cost.ulog += spent.ulog;
            cost.other += spent.other;
        }
        self.tracks.write(&self.dir.join("trajectory.geojson"), &self.plan)?;
        self.summary.end_reason = outcome.reason.clone();
        self.summary.sim_time_s = outcome.sim_time_s;
        self.summary.wall_time_s = outcome.wall_time.as_secs_f64();
        self.summary.real_time_factor = outcome.sim_time_s / outcome.wall_time.as_secs_f64().max(1e-9);
        self.summary.pilots_released_at_s = outcome.released_at_s;
        self.summary.pilot_connect_wait_s = outcome.pilot_connect_wait.map(|w| w.as_secs_f64());
        for (d, tally) in self.summary.per_drone.iter_mut().zip(&mut self.gnss) {
            d.gnss = tally.summary();
            // A drone that never flew met no wind.
            d.wind = d.wind.filter(|w| w.windows > 0);
        }
        if let Some(mut csv) = self.gnss_csv.take() {
            use std::io::Write;
            csv.flush()?;
        }
        let json = serde_json::to_vec_pretty(&self.summary).map_err(std::io::Error::other)?;
        std::fs::write(self.dir.join(sadesim_crds::outcome::run_folder::SUMMARY), json)?;
        Ok(self.summary)
    }
}

impl RunObserver for Recorder {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        let mut cost = self.summary.recording_cpu_s;
        let mut lap = Lap::start();
        self.events.write(events).map_err(ObserverError::Record)?;
        let images = std::mem::take(&mut self.images);
        if let Some(streams) = &mut self.streams {
            streams
                .write_with_images(time_s, drones.to_vec(), events.to_vec(), images)
                .map_err(ObserverError::Record)?;
        }
        let final_window = events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. }));
        if !final_window && self.rows.due(time_s) {
            self.csv.write(time_s, drones, &self.plan, &self.frame).map_err(ObserverError::Record)?;
        }
        // The track's last point is where the drone ended, whatever the rate.
        if self.track_points.due(time_s) || final_window {
            self.tracks.add(drones, &self.frame);
        }
        for s in drones {
            let Some(tally) = self.gnss.get_mut(s.index as usize) else { continue };
            if let (Some(row), Some(csv)) = (tally.observe(time_s, s), &mut self.gnss_csv) {
                use std::io::Write;
                let opt = |v: Option<f64>, digits: usize| v.map_or(String::new(), |v| format!("{v:.digits$}"));
                writeln!(
                    csv,
                    "{:.3},{},{},{},{},{},{}",
                    row.time_s,
                    s.index,
                    row.fix_type,
                    row.satellites,
                    opt(row.hdop, 2),
                    opt(row.fix_error_m, 2),
                    opt(row.estimate_error_m, 2)
                )
                .map_err(ObserverError::Record)?;
            }
        }
        if !final_window {
            let window_s = time_s - self.last_window_end_s;
            self.last_window_end_s = time_s;
            super::summary::observe_window(&mut self.summary, window_s, drones, events, &mut self.drone_tracks);
        } else {
            self.summary.events += events.len() as u64;
        }
        lap.add_to(&mut cost.other);
        self.summary.recording_cpu_s = cost;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use sadesim_crds::run::Recording;

    use super::*;
    use crate::record::test_dir::TempDir;
    use sadesim_engine::fixtures::{plan_of, run_with_groups, world_of};

    /// Three simulated seconds of 4 drones climbing, recorded with `recording`; the summary.
    fn record(dir: &TempDir, recording: Recording) -> RunSummary {
        let plan = plan_of(run_with_groups(&[("a", 4)]).with(|r| r.spec.recording = Some(recording)).build());
        let mut recorder = Recorder::create(&dir.0, &plan, &world_of(&plan), RecorderOptions::default()).unwrap();
        for w in 1..=300u32 {
            let t = f64::from(w) * 0.01;
            let drones: Vec<DroneSnapshot> =
                (0..4).map(|index| DroneSnapshot::climbing(index, f64::from(index) * 10.0, t)).collect();
            recorder.on_window(t, &drones, &[]).unwrap();
        }
        let outcome = RunOutcome {
            reason: "duration".into(),
            sim_time_s: 3.0,
            wall_time: Duration::from_secs(1),
            released_at_s: None,
            pilot_connect_wait: None,
        };
        recorder.finish(&outcome).unwrap()
    }

    #[test]
    fn the_summary_says_what_each_recording_cost() {
        let dir = TempDir::new("recorder-cost-on");
        let summary = record(&dir, Recording::default());
        let cost = summary.recording_cpu_s;
        assert!(cost.mcap > 0.0 && cost.ulog > 0.0 && cost.other > 0.0, "{cost:?}");
        let written: RunSummary = serde_json::from_slice(&std::fs::read(dir.0.join("summary.json")).unwrap()).unwrap();
        assert_eq!(written.recording_cpu_s, cost);

        let dir = TempDir::new("recorder-cost-off");
        let summary = record(&dir, Recording { mcap: false, ulog: false, ..Recording::default() });
        let cost = summary.recording_cpu_s;
        assert_eq!((cost.mcap, cost.ulog), (0.0, 0.0), "nothing recorded, nothing spent");
        assert!(cost.other > 0.0);
    }
}
