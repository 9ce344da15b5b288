//! Onboard cameras (`spec.fleet[].cameras`), where the lockstep loop is: the local runner's
//! observer, or the coordinator role's (`--processes`).: at every window boundary where
//! a camera is due, its frame is rendered from the drone's ground-truth pose at that exact
//! simulated time (`sadesim-render`, wgpu on Vulkan) and published to the pilots' HTTP API
//! (`sim_worker::view::frames`, served with the live view).
//!
//! Rendering happens on the coordinator's thread, inside the window: the run waits for due
//! frames, so the same seed gives the same images at any clock (a real-time run that
//! cannot keep up runs late, as with any other load; the real-time factor shows it).
//!
//! In a paced run (realtime, scaled) a frame handed over more than one camera period after
//! its simulated time was due on the wall clock is counted late, per camera, in
//! `summary.json` (`cameras[].late`), and the run warns about it: frames are never dropped,
//! a machine too slow for the cameras makes them late, and the count says so.
//!
//! Every n-th frame of a camera (its `recordRateHz`) also goes into `recording.mcap`, JPEG
//! with its calibration, and depth as `16UC1` ([`Cameras::streams`], [`Cameras::on_window`]).

use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::record::{CameraImage, CameraStream, Recorder, RecorderOptions};
use crate::view::frames::{CameraFrame, FrameImage, FrameStore};
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::outcome::summary::CameraTally;
use sadesim_crds::plan::RunPlan;
use sadesim_engine::coordinator::ObserverError;
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::pacing::Pacer;
use sadesim_engine::protocol::DroneSnapshot;
use sadesim_render::{CameraModel, CameraPose, CameraView, Frame, Marker, Mount, Renderer, Scene};
use sadesim_world::World;

/// JPEG quality of served frames (the libjpeg default a pilot's decoder expects).
const JPEG_QUALITY: u8 = 85;

/// One camera on one drone.
#[derive(Debug)]
struct DroneCamera {
    drone: u32,
    drone_name: String,
    camera: String,
    model: CameraModel,
    mount: Mount,
    depth: bool,
    /// Due every this many windows.
    every_windows: u64,
    /// Every this many frames one goes into `recording.mcap` (`None`: none does).
    record_every: Option<u64>,
    /// Its index in [`Cameras::streams`] when recorded.
    stream: Option<usize>,
    /// The camera's period, simulated seconds (on the wall clock: divided by the clock's
    /// factor).
    period_s: f64,
    /// Frames taken so far.
    taken: u64,
    /// Frames handed over more than a period after they were due (paced runs).
    late: u64,
    /// The latest a frame came after its due time, wall seconds.
    max_late_s: f64,
}

/// The run's cameras, their renderer and the store pilots read.
#[derive(Debug)]
pub struct Cameras {
    renderer: Renderer,
    cameras: Vec<DroneCamera>,
    /// The recorded cameras.
    streams: Vec<CameraStream>,
    store: Arc<FrameStore>,
    window_s: f64,
    /// When simulated times are due on the wall clock, from `clock_started`.
    pacer: Pacer,
    /// The coordinator's clock start ([`Cameras::clock_started`]); `None` before it.
    clock_started: Option<Instant>,
    /// Reused between windows.
    due: Vec<usize>,
    views: Vec<CameraView>,
    frames: Vec<Frame>,
}

impl Cameras {
    /// The cameras of `plan` in `world` (with the scenario's ground markers), or `None`
    /// for a run without cameras.
    ///
    /// # Errors
    /// No Vulkan device (the message names what to install), or a camera the renderer
    /// refuses (named by its scenario field).
    pub fn new(plan: &RunPlan, world: &World) -> Result<Option<Self>, String> {
        // Frames are recorded only into recording.mcap.
        let recording = plan.spec.recording().mcap;
        let spec = &plan.spec;
        if !spec.has_cameras() {
            return Ok(None);
        }
        let frame = LocalFrame::new(spec.origin.geo());
        let markers = spec
            .world()
            .markers
            .iter()
            .enumerate()
            .map(|(k, m)| {
                let (e, n) = frame.to_plane(m.position.latitude_deg, m.position.longitude_deg);
                let cells = sadesim_render::aruco_4x4_50(m.aruco_id as usize)
                    .ok_or_else(|| format!("spec.world.markers[{k}].arucoId: no ArUco 4x4_50 id {}", m.aruco_id))?;
                Ok(Marker {
                    center_enu_m: [e, n, world.ground_up_m(e, n)],
                    size_m: m.size_m,
                    yaw_deg: m.yaw_deg,
                    cells,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let scene = Scene::with_markers(world, &markers).map_err(|e| format!("spec.world.markers: {e}"))?;
        let renderer = Renderer::new(&scene).map_err(|e| format!("spec.fleet[].cameras: {e}"))?;
        let window_steps = u64::from(plan.sync_window_steps);
        let window_s = window_steps as f64 / f64::from(plan.physics_rate_hz);
        let mut cameras = Vec::new();
        for (i, group) in spec.fleet.iter().enumerate() {
            for (k, c) in group.cameras.iter().enumerate() {
                let model = CameraModel::new(c.width_px, c.height_px, c.horizontal_fov_deg)
                    .map_err(|e| format!("spec.fleet[{i}].cameras[{k}]: {e}"))?;
                let m = c.mount;
                let mount = Mount {
                    offset_flu_m: [m.forward_m, m.left_m, m.up_m],
                    roll_deg: m.roll_deg,
                    pitch_deg: m.pitch_deg,
                    yaw_deg: m.yaw_deg,
                };
                // Validation made the window rate a whole multiple of the camera's.
                let every_windows = ((1.0 / c.rate_hz) / window_s).round().max(1.0) as u64;
                // Validation made the camera's rate a whole multiple of the recording's.
                let record_every = (recording && c.record_rate_hz() > 0.0)
                    .then(|| (c.rate_hz / c.record_rate_hz()).round().max(1.0) as u64);
                for d in plan.drones.iter().filter(|d| d.group_index as usize == i) {
                    cameras.push(DroneCamera {
                        drone: d.index,
                        drone_name: d.name.clone(),
                        camera: c.name.clone(),
                        model,
                        mount,
                        depth: c.depth,
                        every_windows,
                        record_every,
                        stream: None,
                        period_s: 1.0 / c.rate_hz,
                        taken: 0,
                        late: 0,
                        max_late_s: 0.0,
                    });
                }
            }
        }
        let mut streams = Vec::new();
        for c in cameras.iter_mut().filter(|c| c.record_every.is_some()) {
            c.stream = Some(streams.len());
            streams.push(stream_of(c)?);
        }
        let store = FrameStore::new(cameras.iter().map(|c| (c.drone_name.clone(), c.camera.clone())));
        Ok(Some(Self {
            renderer,
            cameras,
            streams,
            store,
            window_s,
            pacer: Pacer::new(&spec.clock()),
            clock_started: None,
            due: Vec::new(),
            views: Vec::new(),
            frames: Vec::new(),
        }))
    }

    /// The cameras `recording.mcap` holds frames of (in the order of
    /// [`CameraImage::stream`]).
    pub fn streams(&self) -> Vec<CameraStream> {
        self.streams.clone()
    }

    /// The recorder's options for a run with `cameras` (the defaults, with the recorded
    /// cameras' streams).
    pub fn recorder_options(cameras: Option<&Self>) -> RecorderOptions {
        RecorderOptions { cameras: cameras.map(Self::streams).unwrap_or_default(), ..RecorderOptions::default() }
    }

    /// The store the HTTP API serves.
    pub fn store(&self) -> Arc<FrameStore> {
        self.store.clone()
    }

    /// The coordinator's clock started at `started`: frames are due from then on.
    pub fn clock_started(&mut self, started: Instant) {
        self.clock_started = Some(started);
    }

    /// Frames and late frames per camera, for `summary.json`.
    pub fn tallies(&self) -> Vec<CameraTally> {
        self.cameras
            .iter()
            .map(|c| CameraTally {
                drone: c.drone_name.clone(),
                camera: c.camera.clone(),
                frames: c.taken,
                late: c.late,
                max_late_s: c.max_late_s,
            })
            .collect()
    }

    /// The renderer's device (e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`), for the log.
    pub fn adapter(&self) -> String {
        self.renderer.adapter_name().to_string()
    }

    /// What an observer with cameras does first in each window (the local runner's and the
    /// coordinator role's): renders the frames due ([`Cameras::on_window`]) and queues those
    /// the recording takes in `recorder`, before the recorder sees the window, so they are
    /// written with it. The final window repeats the last snapshot and takes none.
    ///
    /// # Errors
    /// The renderer failed: the run stops, its files are kept.
    pub fn before_recording(
        &mut self,
        recorder: &mut Recorder,
        time_s: f64,
        drones: &[DroneSnapshot],
        events: &[Event],
    ) -> Result<(), ObserverError> {
        if events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. })) {
            return Ok(());
        }
        let images = self.on_window(time_s, drones).map_err(|e| ObserverError::Record(std::io::Error::other(e)))?;
        recorder.queue_images(images);
        Ok(())
    }

    /// The run is over: each camera's frames and late frames into `recorder`'s
    /// `summary.json`, and a warning on stderr when any was late.
    pub fn finish(self, recorder: &mut Recorder) {
        let tallies = self.tallies();
        if let Some(warning) = late_frames_warning(&tallies) {
            eprintln!("warning: {warning}");
        }
        recorder.set_camera_tallies(tallies);
    }

    /// A window ended at `time_s` with `drones` (by global index): renders every camera due
    /// now (the first window, and every `every_windows` after), publishes the frames, and
    /// returns those due for the recording.
    ///
    /// # Errors
    /// The renderer failed (a lost device): the run stops, its files are kept.
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot]) -> Result<Vec<CameraImage>, String> {
        let window = (time_s / self.window_s).round() as u64;
        self.due.clear();
        self.views.clear();
        for (i, c) in self.cameras.iter().enumerate() {
            if !window.is_multiple_of(c.every_windows) {
                continue;
            }
            let Some(d) = drones.get(c.drone as usize) else { continue };
            let pose = CameraPose::from_body(d.position_enu_m, d.attitude_wxyz, &c.mount)
                .map_err(|e| format!("camera {}/{}: {e}", c.drone_name, c.camera))?;
            self.due.push(i);
            self.views.push(CameraView { model: c.model, pose });
        }
        let mut recorded = Vec::new();
        if self.due.is_empty() {
            return Ok(recorded);
        }
        self.renderer.render_into(&self.views, &mut self.frames).map_err(|e| format!("onboard cameras: {e}"))?;
        // Handed over now (published below, microseconds later).
        let behind = match (self.pacer.due_after(time_s), self.clock_started) {
            (Some(due), Some(started)) => Some(behind_s(due, started.elapsed())),
            _ => None,
        };
        for (&i, frame) in self.due.iter().zip(self.frames.drain(..)) {
            let c = &mut self.cameras[i];
            if let (Some(behind), Some(period)) = (behind, self.pacer.due_after(c.period_s)) {
                c.max_late_s = c.max_late_s.max(behind);
                c.late += u64::from(behind > period.as_secs_f64());
            }
            let record = c.record_every.zip(c.stream).filter(|(every, _)| c.taken.is_multiple_of(*every));
            let depth_mm_le = (record.is_some() && c.depth).then(|| frame.depth_mm_le());
            let published = CameraFrame::new(time_s, c.taken, Box::new(Rendered { frame, depth: c.depth }));
            if let Some((_, stream)) = record {
                // Encoded once: the JPEG recorded is the one pilots are served.
                let jpeg = published.jpeg();
                if jpeg.is_empty() {
                    return Err(format!(
                        "camera {}/{}: the frame could not be encoded as JPEG",
                        c.drone_name, c.camera
                    ));
                }
                recorded.push(CameraImage { stream, time_s, jpeg: jpeg.to_vec(), depth_mm_le });
            }
            self.store.publish(&c.drone_name, &c.camera, published);
            c.taken += 1;
        }
        Ok(recorded)
    }
}

/// What to say when a paced run handed frames over late (`None` when none was).
fn late_frames_warning(tallies: &[CameraTally]) -> Option<String> {
    let late: u64 = tallies.iter().map(|t| t.late).sum();
    if late == 0 {
        return None;
    }
    let frames: u64 = tallies.iter().map(|t| t.frames).sum();
    let worst = tallies.iter().map(|t| t.max_late_s).fold(0.0, f64::max);
    Some(format!(
        "{late} of {frames} camera frames were late (handed to pilots more than one camera period after their simulated time; the latest {:.0} ms behind): this machine renders the cameras slower than the clock. Lower spec.fleet[].cameras rateHz or resolution, slow the clock (spec.clock), or give the renderer a GPU; summary.json lists them per camera",
        worst * 1000.0
    ))
}

/// How far behind its due time a frame handed over at `elapsed` (wall time since the clock
/// started) is, wall seconds; 0 when on time.
fn behind_s(due: Duration, elapsed: Duration) -> f64 {
    elapsed.saturating_sub(due).as_secs_f64()
}

/// How `recording.mcap` declares camera `c`: its calibration, and its mount as the optical
/// frame's pose in the body frame (the camera pose of a body at the origin, unrotated).
fn stream_of(c: &DroneCamera) -> Result<CameraStream, String> {
    let calibration = c.model.calibration();
    let mount = CameraPose::from_body([0.0; 3], [1.0, 0.0, 0.0, 0.0], &c.mount)
        .map_err(|e| format!("camera {}/{}: {e}", c.drone_name, c.camera))?;
    Ok(CameraStream {
        drone: c.drone,
        camera: c.camera.clone(),
        width: calibration.width,
        height: calibration.height,
        k: calibration.k,
        p: calibration.p,
        mount_offset_flu_m: mount.position_enu_m(),
        mount_optical_to_flu_wxyz: mount.optical_to_enu_wxyz(),
        depth: c.depth,
    })
}

/// A rendered frame, encoded when a pilot asks.
#[derive(Debug)]
struct Rendered {
    frame: Frame,
    depth: bool,
}

impl FrameImage for Rendered {
    fn jpeg(&self) -> Vec<u8> {
        self.frame.rgb_jpeg(JPEG_QUALITY).unwrap_or_default()
    }

    fn png(&self) -> Vec<u8> {
        self.frame.rgb_png().unwrap_or_default()
    }

    fn depth_png_mm(&self) -> Option<Vec<u8>> {
        self.depth.then(|| self.frame.depth_png_mm().unwrap_or_default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_behind_by_the_wall_time_past_its_due_time() {
        let ms = Duration::from_millis;
        assert_eq!(behind_s(ms(500), ms(400)), 0.0, "early: on time");
        assert_eq!(behind_s(ms(500), ms(500)), 0.0);
        assert!((behind_s(ms(500), ms(750)) - 0.25).abs() < 1e-12);
    }
}
