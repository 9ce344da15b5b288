//! The recorder: a [`RunObserver`] writing every evidence file of a run into one folder.

use std::path::{Path, PathBuf};

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_world::World;

use sadesim_evidence::archive::{FileState, INCOMPLETE_FILE, Incomplete, IncompleteFile};

use super::cost::Lap;
use super::disk::{Appender, DiskReserve};
use super::trajectory::{TRAJECTORY_CSV, TRAJECTORY_GEOJSON};
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
    gnss_csv: Option<Appender>,
    /// One `gnss.csv` row, reused.
    gnss_row: String,
    /// Per drone: what the summary carries from one window to the next.
    drone_tracks: Vec<super::summary::DroneTrack>,
    /// When the last window folded into the summary ended, simulated seconds.
    last_window_end_s: f64,
    /// `recording.mcap` (unless `spec.recording.mcap` is false) and `ulog/*.ulg` (unless
    /// `spec.recording.ulog` is false); `None` when both are off.
    streams: Option<StreamWriter>,
    /// Camera frames for the next window ([`Recorder::queue_images`]).
    images: Vec<CameraImage>,
    /// Room to close the files if the disk fills ([`super::disk`]), released at
    /// [`Recorder::finish`].
    reserve: Option<DiskReserve>,
    /// The write error that stopped the recording (it names the file).
    failure: Option<(std::io::ErrorKind, String)>,
    /// The last window recorded whole, simulated seconds.
    recorded_until_s: f64,
    /// Files of the run that could not be written (`Recorder::not_written`).
    not_written: Vec<IncompleteFile>,
}

impl Recorder {
    /// Creates the files in `dir` (which must exist); `world` is the run's (drawn in
    /// `recording.mcap`). First it sets aside the room to close them if the disk fills
    /// ([`super::disk::reserve_bytes`]).
    ///
    /// # Errors
    /// When a file cannot be created, or the disk has not the room to set aside.
    pub fn create(dir: &Path, plan: &RunPlan, world: &World, options: RecorderOptions) -> std::io::Result<Self> {
        let reserve = DiskReserve::create(dir, super::disk::reserve_bytes(plan.drones.len()))?;
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
            events: EventLog::create(dir)?,
            csv: TrajectoryCsv::create(dir)?,
            tracks: TrajectoryGeoJson::new(plan.drones.len()),
            rows: Sampler::new(options.trajectory_hz),
            track_points: Sampler::including_start(options.track_hz),
            summary,
            gnss: vec![super::gnss_tally::GnssTally::default(); plan.drones.len()],
            gnss_csv: match plan.spec.environment().gnss.is_some_and(|g| g.constellation.is_some()) {
                true => {
                    let mut w = Appender::create(dir, sadesim_crds::outcome::run_folder::GNSS)?;
                    w.write_all(b"time_s,drone,fix_type,satellites,hdop,fix_error_m,estimate_error_m\n")?;
                    Some(w)
                }
                false => None,
            },
            gnss_row: String::new(),
            drone_tracks: plan
                .drones
                .iter()
                .map(|d| super::summary::DroneTrack::new([d.home.local.east_m, d.home.local.north_m]))
                .collect(),
            last_window_end_s: 0.0,
            images: Vec::new(),
            plan: plan.clone(),
            reserve: Some(reserve),
            failure: None,
            recorded_until_s: 0.0,
            not_written: Vec::new(),
        })
    }

    /// The simulated time of the last window recorded whole (0 before the first).
    pub fn recorded_until_s(&self) -> f64 {
        self.recorded_until_s
    }

    /// Gives back the room set aside for closing the files (also done by
    /// [`Recorder::finish`]): for the run's end-of-run files written before it.
    pub fn release_reserve(&mut self) {
        if let Some(reserve) = self.reserve.take() {
            reserve.release();
        }
    }

    /// A file of the run folder the caller could not write (`airspace.json`): it stops
    /// the recording as a write error of the recorder's own does, and `incomplete.json`
    /// lists it as not written.
    pub fn not_written(&mut self, path: &str, error: &std::io::Error) {
        self.failure.get_or_insert_with(|| (error.kind(), format!("{path}: {error}")));
        self.not_written.push(IncompleteFile {
            path: path.to_string(),
            state: FileState::NotWritten,
            detail: format!("it could not be written ({error})"),
        });
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

    /// Writes the end-of-run files and returns the summary. The room set aside is given
    /// back first, so after a write error (the disk filled) it closes every file at its
    /// last whole record and writes `summary.json`; then `incomplete.json` (which the
    /// manifest copies) says which files end early, could not be closed or written.
    ///
    /// # Errors
    /// The write error that stopped the recording (also when the caller saw it already),
    /// else the first file that could not be closed or written, naming it.
    pub fn finish(mut self, outcome: &RunOutcome) -> std::io::Result<RunSummary> {
        self.release_reserve();
        let mut incomplete = std::mem::take(&mut self.not_written);
        let mut close_error = None;
        if let Some(streams) = self.streams.take() {
            let closed = streams.finish_stopped(self.failure.as_ref().map(|_| self.recorded_until_s));
            let cost = &mut self.summary.recording_cpu_s;
            cost.mcap += closed.cost.mcap;
            cost.ulog += closed.cost.ulog;
            cost.other += closed.cost.other;
            if let Some((time_s, e)) = closed.failed {
                // A failure in the last windows, which no write returned.
                self.failure.get_or_insert((e.kind(), e.to_string()));
                self.recorded_until_s = self.recorded_until_s.min(time_s);
            }
            close_error = closed.close_error;
            incomplete.extend(closed.incomplete);
        }
        let stopped = self.failure.as_ref().map(|_| {
            format!("it ends at {:.2} s of simulated time, where the recording stopped", self.recorded_until_s)
        });
        // The files written as the run went: cut back to their last whole line.
        let mut appended = vec![(self.events.close(), sadesim_crds::outcome::run_folder::EVENTS)];
        appended.push((self.csv.close(), TRAJECTORY_CSV));
        if let Some(gnss) = self.gnss_csv.take() {
            appended.push((gnss.close(), sadesim_crds::outcome::run_folder::GNSS));
        }
        for (closed, path) in appended {
            let (state, detail) = match (closed, &stopped) {
                (Ok(()), None) => continue,
                (Ok(()), Some(stopped)) => {
                    (FileState::Truncated, format!("{stopped}; it holds what was written before"))
                }
                (Err(e), _) => {
                    let detail = format!("its last lines could not be written ({e}): it may end mid-line");
                    close_error.get_or_insert(e);
                    (FileState::NotFinalised, detail)
                }
            };
            incomplete.push(IncompleteFile { path: path.into(), state, detail });
        }
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
        let geojson = self.tracks.write(&self.dir.join(TRAJECTORY_GEOJSON), &self.plan);
        let summary = serde_json::to_vec_pretty(&self.summary)
            .map_err(std::io::Error::other)
            .and_then(|json| std::fs::write(self.dir.join(sadesim_crds::outcome::run_folder::SUMMARY), json));
        for (written, path) in [(geojson, TRAJECTORY_GEOJSON), (summary, sadesim_crds::outcome::run_folder::SUMMARY)] {
            if let Err(e) = written {
                // No half-written JSON in the folder.
                let _ = std::fs::remove_file(self.dir.join(path));
                incomplete.push(IncompleteFile {
                    path: path.into(),
                    state: FileState::NotWritten,
                    detail: format!("it could not be written ({e})"),
                });
                close_error.get_or_insert(super::disk::named(path, e));
            }
        }
        let reason = match (&self.failure, &close_error) {
            (Some((_, reason)), _) => Some(reason.clone()),
            (None, Some(e)) => Some(e.to_string()),
            (None, None) => None,
        };
        if let Some(reason) = reason {
            incomplete.sort_by(|a, b| a.path.cmp(&b.path));
            let record = Incomplete { reason, files: incomplete };
            let path = self.dir.join(INCOMPLETE_FILE);
            let json = serde_json::to_vec_pretty(&record).map_err(std::io::Error::other)?;
            if let Err(e) = std::fs::write(&path, json) {
                let _ = std::fs::remove_file(&path);
                close_error.get_or_insert(super::disk::named(INCOMPLETE_FILE, e));
            }
        }
        match (self.failure, close_error) {
            (Some((kind, reason)), _) => Err(std::io::Error::new(kind, reason)),
            (None, Some(e)) => Err(e),
            (None, None) => Ok(self.summary),
        }
    }

    /// [`RunObserver::on_window`]'s writes; the first error is kept as the failure.
    fn record_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        if self.failure.is_some() {
            return Err(ObserverError::Record(std::io::Error::other("the recording stopped after a write error")));
        }
        let result = self.write_window(time_s, drones, events);
        match &result {
            Ok(()) => self.recorded_until_s = time_s,
            Err(e) => self.failure = Some((e.kind(), e.to_string())),
        }
        result.map_err(ObserverError::Record)
    }
}

impl RunObserver for Recorder {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        self.record_window(time_s, drones, events)
    }
}

impl Recorder {
    /// Records one window (errors name the file).
    fn write_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> std::io::Result<()> {
        let mut cost = self.summary.recording_cpu_s;
        let mut lap = Lap::start();
        self.events.write(events)?;
        let images = std::mem::take(&mut self.images);
        if let Some(streams) = &mut self.streams {
            streams.write_with_images(time_s, drones.to_vec(), events.to_vec(), images)?;
        }
        let final_window = events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. }));
        if !final_window && self.rows.due(time_s) {
            self.csv.write(time_s, drones, &self.plan, &self.frame)?;
        }
        // The track's last point is where the drone ended, whatever the rate.
        if self.track_points.due(time_s) || final_window {
            self.tracks.add(drones, &self.frame);
        }
        for s in drones {
            let Some(tally) = self.gnss.get_mut(s.index as usize) else { continue };
            if let (Some(row), Some(csv)) = (tally.observe(time_s, s), &mut self.gnss_csv) {
                use std::fmt::Write;
                let opt = |v: Option<f64>, digits: usize| v.map_or(String::new(), |v| format!("{v:.digits$}"));
                let line = &mut self.gnss_row;
                line.clear();
                let _ = writeln!(
                    line,
                    "{:.3},{},{},{},{},{},{}",
                    row.time_s,
                    s.index,
                    row.fix_type,
                    row.satellites,
                    opt(row.hdop, 2),
                    opt(row.fix_error_m, 2),
                    opt(row.estimate_error_m, 2)
                );
                csv.write_all(line.as_bytes())?;
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

    /// `trajectory.csv` on a disk with no room at all (`/dev/full`): the window that
    /// samples it fails naming it, and `finish` closes the rest (the MCAP with its summary,
    /// each ULog at a whole message), writes `summary.json`, removes the reserve and
    /// writes `incomplete.json`, which says what is not whole.
    #[test]
    fn a_full_disk_stops_the_recording_and_the_rest_is_closed_and_listed() {
        use sadesim_evidence::archive::{FileState, INCOMPLETE_FILE, Incomplete};
        let dir = TempDir::new("recorder-full");
        std::os::unix::fs::symlink("/dev/full", dir.0.join(TRAJECTORY_CSV)).unwrap();
        let plan = plan_of(run_with_groups(&[("a", 2)]).build());
        let mut recorder = Recorder::create(&dir.0, &plan, &world_of(&plan), RecorderOptions::default()).unwrap();
        assert!(dir.0.join(super::super::disk::RESERVE_FILE).exists());
        let mut failed = None;
        for w in 1..=300u32 {
            let t = f64::from(w) * 0.01;
            let drones: Vec<DroneSnapshot> = (0..2).map(|index| DroneSnapshot::climbing(index, 0.0, t)).collect();
            if let Err(ObserverError::Record(e)) = recorder.on_window(t, &drones, &[]) {
                failed = Some(e);
                break;
            }
        }
        let failed = failed.expect("the first trajectory sample fails");
        assert_eq!(failed.to_string(), "trajectory.csv: No space left on device (os error 28)");
        let outcome = RunOutcome {
            reason: sadesim_engine::events::EndReason::Requested(format!("recordingFailed: {failed}")),
            sim_time_s: recorder.recorded_until_s(),
            wall_time: Duration::from_secs(1),
            released_at_s: None,
            pilot_connect_wait: None,
        };
        let error = recorder.finish(&outcome).unwrap_err();
        assert_eq!(error.to_string(), failed.to_string(), "the error that stopped the recording");
        assert!(!dir.0.join(super::super::disk::RESERVE_FILE).exists(), "the reserve is given back");
        // Readable up to where it stopped: the MCAP has its summary.
        let _poses = crate::record::mcap_file::finished_pose_count(&dir.0);
        let summary: RunSummary =
            serde_json::from_slice(&std::fs::read(dir.0.join(sadesim_crds::outcome::run_folder::SUMMARY)).unwrap())
                .unwrap();
        assert!(summary.end_reason.to_string().starts_with("recordingFailed: trajectory.csv: "));
        let incomplete: Incomplete =
            serde_json::from_slice(&std::fs::read(dir.0.join(INCOMPLETE_FILE)).unwrap()).unwrap();
        assert_eq!(incomplete.reason, failed.to_string());
        let states: Vec<(&str, FileState)> = incomplete.files.iter().map(|f| (f.path.as_str(), f.state)).collect();
        assert_eq!(
            states,
            vec![
                ("events.jsonl", FileState::Truncated),
                ("recording.mcap", FileState::Truncated),
                ("trajectory.csv", FileState::NotFinalised),
                ("ulog/a-0.ulg", FileState::Truncated),
                ("ulog/a-1.ulg", FileState::Truncated),
            ]
        );
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
