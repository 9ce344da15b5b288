//! `recording.mcap`: the whole run in one MCAP file with Foxglove's well-known schemas, so
//! it opens in Foxglove with a 3D and a map panel.
//!
//! The ground-truth streams (pose, `/tf`, velocity: 100 Hz by default, most of the file)
//! are protobuf with Foxglove's `.proto` schemas (see [`protobuf`]); the others are JSON
//! (schema encoding `jsonschema`, see [`schemas`]). Every time is
//! simulated time since the run start: `log_time` is the sync window the recorder saw the
//! value in, `publish_time` and the message's `timestamp` when it was true (the same for
//! sampled streams; the fix time for GNSS, the event time for events).
//!
//! | topic | schema | frame | rate |
//! |---|---|---|---|
//! | `/drones/<name>/pose` | foxglove.PoseInFrame (protobuf) | `world` | ground truth (100 Hz) |
//! | `/tf` (all drones in one message) | foxglove.FrameTransforms (protobuf) | `world` -> `drone/<name>` | ground truth |
//! | `/drones/<name>/velocity` | sadesim.Velocity (protobuf) | `world` / body FLU | ground truth |
//! | `/drones/<name>/estimate` | sadesim.Estimate | `world` | estimator (10 Hz), from the first fix |
//! | `/drones/<name>/motors` | sadesim.MotorCommands | | actuators (10 Hz) |
//! | `/drones/<name>/battery` | sadesim.Battery | | status (10 Hz) |
//! | `/drones/<name>/status` | sadesim.Status | | status |
//! | `/drones/<name>/wind` | sadesim.Wind | `world` | status |
//! | `/drones/<name>/location` | foxglove.LocationFix (ground truth) | `drone/<name>` | status |
//! | `/drones/<name>/gnss` | foxglove.LocationFix (receiver) | `drone/<name>` | each new 3D fix |
//! | `/world` | foxglove.SceneUpdate (buildings, ground) | `world` | once, at 0 |
//! | `/zones` | foxglove.SceneUpdate | `world` | once, at 0 |
//! | `/markers` (runs with `spec.world.markers`) | foxglove.SceneUpdate | `world` | once, at 0 |
//! | `/events` | foxglove.Log | | each event |
//! | `/drones/<name>/cameras/<camera>/image` | foxglove.CompressedImage (protobuf, JPEG) | `drone/<name>/<camera>` | the camera's `recordRateHz` |
//! | `/drones/<name>/cameras/<camera>/calibration` | foxglove.CameraCalibration (protobuf) | `drone/<name>/<camera>` | with each image |
//! | `/drones/<name>/cameras/<camera>/depth` | foxglove.RawImage (protobuf, `16UC1` mm) | `drone/<name>/<camera>` | with each image, depth cameras |
//!
//! Camera frames (`drone/<name>/<camera>`) are optical frames (x right, y down, z forward,
//! as `CameraCalibration` expects); their mounts on the body are one `/tf` message at 0.
//!
//! `world` is ENU (x east, y north, z up) in metres from the run origin. Sampled streams
//! take one sample at the first sync window at or after each multiple of their period
//! (as `trajectory.csv`), so a run of `d` seconds holds `d x rate` samples per stream.
//!
//! # Guarantees
//! Chunks (about 1 MiB of messages, compressed with `spec.recording.compression` in one
//! call, see [`writer`]) are built in memory and written whole, then the file is flushed:
//! a process killed at any point leaves a file whose complete chunks a streaming MCAP
//! reader reads (the summary section and footer are only written by
//! [`McapRecorder::finish`]). The compressor runs on the recorder's thread (no worker
//! threads), so a recording depends only on the run, not on the machine.

mod json;
pub(crate) mod messages;
pub mod protobuf;
mod scene;
pub mod schemas;
#[cfg(test)]
mod tests;
pub mod writer;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::{Compression, RecordingRates};
use sadesim_world::World;

use self::writer::{ChunkCompression, McapWriter};
use crate::record::{CameraImage, CameraStream, Sampler};
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::DroneSnapshot;

/// File name inside the run folder.
pub const MCAP_FILE: &str = "recording.mcap";

/// Uncompressed bytes of messages after which the open chunk is written and flushed.
pub const CHUNK_BYTES: usize = 1 << 20;

/// Channels per drone (pose, velocity, estimate, motors, battery, status, wind, location,
/// gnss, gnss_quality); MCAP channel ids are 16-bit, which bounds the fleet one file can
/// record.
const CHANNELS_PER_DRONE: usize = 10;

/// Most drones one `recording.mcap` holds (65 535 channel ids, 4 run-wide channels).
pub const MAX_DRONES: usize = (u16::MAX as usize - 4) / CHANNELS_PER_DRONE;

/// Channels per recorded camera (image, calibration, depth).
const CHANNELS_PER_CAMERA: usize = 3;

/// zstd level: 1 is the fastest standard level. On a real recording it compresses 7.7x at
/// about 700 MB/s here; level 3 compresses less well on this data (7.3x) at 25 % more CPU,
/// level -1 is 13 % faster for 12 % larger files (docs/performance.md, "Recording cost").
const ZSTD_LEVEL: i32 = 1;

/// Buffer of the file: a chunk goes through in one write (it is written whole anyway).
type Sink = McapWriter<BufWriter<File>>;

/// One channel and the sequence number of its next message.
#[derive(Debug, Clone, Copy)]
struct Channel {
    id: u16,
    sequence: u32,
}

/// The MCAP writer, which closes and flushes its chunk once it holds [`CHUNK_BYTES`].
#[derive(Debug)]
struct Output {
    writer: Sink,
}

impl Output {
    /// Writes one message whose JSON `data` appends to the chunk; closes the chunk
    /// (written whole, then flushed to the file) once it holds [`CHUNK_BYTES`].
    fn write(
        &mut self,
        channel: &mut Channel,
        log_ns: u64,
        publish_ns: u64,
        data: impl FnOnce(&mut Vec<u8>),
    ) -> std::io::Result<()> {
        let size = self.writer.message(channel.id, channel.sequence, log_ns, publish_ns, data);
        channel.sequence = channel.sequence.wrapping_add(1);
        if size >= CHUNK_BYTES {
            self.writer.flush()?;
        }
        Ok(())
    }
}

/// The channels of one drone.
#[derive(Debug)]
struct DroneChannels {
    /// `drone/<name>`: the child frame of its transform and the frame of its fixes.
    frame: String,
    name: String,
    pose: Channel,
    velocity: Channel,
    estimate: Channel,
    motors: Channel,
    battery: Channel,
    status: Channel,
    wind: Channel,
    location: Channel,
    gnss: Channel,
    gnss_quality: Channel,
    /// `time_s` of the last GNSS output seen (a new fix when it changes).
    last_gnss_s: Option<f64>,
}

/// The channels of one recorded camera.
#[derive(Debug)]
struct CameraChannels {
    stream: CameraStream,
    /// `drone/<name>/<camera>`: the optical frame.
    frame: String,
    image: Channel,
    calibration: Channel,
    /// For depth cameras.
    depth: Option<Channel>,
}

/// Writes `recording.mcap` incrementally.
#[derive(Debug)]
pub struct McapRecorder {
    out: Output,
    /// The file (to cut back when its summary could not be written).
    path: std::path::PathBuf,
    frame: LocalFrame,
    drones: Vec<DroneChannels>,
    tf: Channel,
    events: Channel,
    cameras: Vec<CameraChannels>,
    ground_truth: Sampler,
    estimator: Sampler,
    actuators: Sampler,
    status: Sampler,
    /// The `/tf` message of the window, built beside the per-drone messages (empty when the
    /// window takes no ground-truth sample).
    tf_buf: Vec<u8>,
}

/// Simulated seconds -> nanoseconds since the run start.
fn ns(time_s: f64) -> u64 {
    (time_s.max(0.0) * 1e9).round() as u64
}

impl McapRecorder {
    /// Creates `dir/recording.mcap` and writes the header, schemas, channels and the static
    /// scene (the city of `world`, the zones of `plan`), at the rates of
    /// `plan.spec.recording()`, with channels for the frames of `cameras`.
    ///
    /// # Errors
    /// I/O errors; an `Unsupported` error for fleets over [`MAX_DRONES`].
    pub fn create(dir: &Path, plan: &RunPlan, world: &World, cameras: &[CameraStream]) -> std::io::Result<Self> {
        let recording = plan.spec.recording();
        Self::create_with(dir, plan, world, recording.compression, recording.rates, cameras)
    }

    /// [`Self::create`] with explicit compression and rates.
    ///
    /// # Errors
    /// As [`Self::create`].
    pub fn create_with(
        dir: &Path,
        plan: &RunPlan,
        world: &World,
        compression: Compression,
        rates: RecordingRates,
        cameras: &[CameraStream],
    ) -> std::io::Result<Self> {
        if plan.drones.len() > MAX_DRONES {
            return Err(std::io::Error::new(
                std::io::ErrorKind::Unsupported,
                format!(
                    "recording.mcap holds at most {MAX_DRONES} drones ({CHANNELS_PER_DRONE} channels each), this run has {}; set spec.recording.mcap: false",
                    plan.drones.len()
                ),
            ));
        }
        // Within the fleet limit, recorded cameras can still need too many channels.
        let channels = 5 + plan.drones.len() * CHANNELS_PER_DRONE + cameras.len() * CHANNELS_PER_CAMERA;
        if channels > usize::from(u16::MAX) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::Unsupported,
                format!(
                    "recording.mcap holds at most 65535 channels, this run's {} drones and {} recorded cameras need {channels}; set recordRateHz: 0 on some of spec.fleet[].cameras",
                    plan.drones.len(),
                    cameras.len()
                ),
            ));
        }
        let path = dir.join(MCAP_FILE);
        let file = BufWriter::new(File::create(&path)?);
        let compression = match compression {
            Compression::Zstd => ChunkCompression::zstd(ZSTD_LEVEL)?,
            Compression::Lz4 => ChunkCompression::Lz4,
            Compression::None => ChunkCompression::None,
        };
        let mut writer = McapWriter::new(file, "", concat!("sadesim/", env!("CARGO_PKG_VERSION")), compression)?;
        // Schema name -> (schema id, message encoding of its channels).
        let mut schema = BTreeMap::new();
        for (name, text) in schemas::ALL {
            schema.insert(name, (writer.add_schema(name, "jsonschema", text.as_bytes())?, "json"));
        }
        let camera_schemas = if cameras.is_empty() { &[][..] } else { &schemas::CAMERA_PROTOBUF[..] };
        for name in schemas::PROTOBUF.iter().chain(camera_schemas) {
            let descriptors = protobuf::descriptor_set(name).expect("every protobuf schema is in protobuf::FILES");
            schema.insert(name, (writer.add_schema(name, "protobuf", &descriptors)?, "protobuf"));
        }
        let channel = |writer: &mut Sink, topic: &str, schema_name: &str| -> std::io::Result<Channel> {
            let (schema_id, encoding) = schema[schema_name];
            let id = writer.add_channel(schema_id, topic, encoding)?;
            Ok(Channel { id, sequence: 0 })
        };
        let mut city = channel(&mut writer, "/world", schemas::SCENE_UPDATE_NAME)?;
        let zones = channel(&mut writer, "/zones", schemas::SCENE_UPDATE_NAME)?;
        let events = channel(&mut writer, "/events", schemas::LOG_NAME)?;
        let mut tf = channel(&mut writer, "/tf", schemas::FRAME_TRANSFORMS_NAME)?;
        let mut drones = Vec::with_capacity(plan.drones.len());
        for d in &plan.drones {
            let topic = |stream: &str| format!("/drones/{}/{stream}", d.name);
            drones.push(DroneChannels {
                frame: format!("drone/{}", d.name),
                name: d.name.clone(),
                pose: channel(&mut writer, &topic("pose"), schemas::POSE_IN_FRAME_NAME)?,
                velocity: channel(&mut writer, &topic("velocity"), schemas::VELOCITY_NAME)?,
                estimate: channel(&mut writer, &topic("estimate"), schemas::ESTIMATE_NAME)?,
                motors: channel(&mut writer, &topic("motors"), schemas::MOTORS_NAME)?,
                battery: channel(&mut writer, &topic("battery"), schemas::BATTERY_NAME)?,
                status: channel(&mut writer, &topic("status"), schemas::STATUS_NAME)?,
                wind: channel(&mut writer, &topic("wind"), schemas::WIND_NAME)?,
                location: channel(&mut writer, &topic("location"), schemas::LOCATION_FIX_NAME)?,
                gnss: channel(&mut writer, &topic("gnss"), schemas::LOCATION_FIX_NAME)?,
                gnss_quality: channel(&mut writer, &topic("gnss_quality"), schemas::GNSS_QUALITY_NAME)?,
                last_gnss_s: None,
            });
        }
        let mut camera_channels = Vec::with_capacity(cameras.len());
        for c in cameras {
            let drone = plan.drones.get(c.drone as usize).ok_or_else(|| {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    format!("camera {}: no drone {}", c.camera, c.drone),
                )
            })?;
            let topic = |stream: &str| format!("/drones/{}/cameras/{}/{stream}", drone.name, c.camera);
            camera_channels.push(CameraChannels {
                frame: crate::record::optical_frame(&drone.name, &c.camera),
                image: channel(&mut writer, &topic("image"), schemas::COMPRESSED_IMAGE_NAME)?,
                calibration: channel(&mut writer, &topic("calibration"), schemas::CAMERA_CALIBRATION_NAME)?,
                depth: match c.depth {
                    true => Some(channel(&mut writer, &topic("depth"), schemas::RAW_IMAGE_NAME)?),
                    false => None,
                },
                stream: c.clone(),
            });
        }
        let mut out = Output { writer };
        let mut zones = zones;
        let scene = scene::world_update(world);
        out.write(&mut city, 0, 0, |b| b.extend_from_slice(&scene))?;
        let scene = scene::zones_update(plan, world);
        out.write(&mut zones, 0, 0, |b| b.extend_from_slice(scene.as_bytes()))?;
        if let Some(scene) = scene::markers_update(plan, world) {
            let mut markers = channel(&mut out.writer, "/markers", schemas::SCENE_UPDATE_NAME)?;
            out.write(&mut markers, 0, 0, |b| b.extend_from_slice(scene.as_bytes()))?;
        }
        // The cameras' mounts: fixed on the bodies, one transform each, valid from 0 on.
        if !camera_channels.is_empty() {
            out.write(&mut tf, 0, 0, |b| {
                for c in &camera_channels {
                    messages::mount_transform(b, 0, &drones[c.stream.drone as usize].frame, &c.frame, &c.stream);
                }
            })?;
        }
        // The first chunks (schemas, channels, city, zones) are on disk before the run starts.
        out.writer.flush()?;
        Ok(Self {
            out,
            path,
            frame: LocalFrame::new(plan.spec.origin.geo()),
            drones,
            tf,
            events,
            cameras: camera_channels,
            ground_truth: Sampler::new(rates.ground_truth_hz),
            estimator: Sampler::new(rates.estimator_hz),
            actuators: Sampler::new(rates.actuators_hz),
            status: Sampler::new(rates.status_hz),
            tf_buf: Vec::with_capacity(256 * plan.drones.len()),
        })
    }

    /// Records one sync window (time `time_s` of simulated time).
    ///
    /// # Errors
    /// I/O errors.
    pub fn write_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> std::io::Result<()> {
        let log_ns = ns(time_s);
        let Self { out, frame, drones: channels, tf, events: event_channel, tf_buf, .. } = self;
        for event in events {
            let name = event.drone.and_then(|i| channels.get(i as usize)).map_or("run", |c| c.name.as_str());
            out.write(event_channel, log_ns, ns(event.time_s).min(log_ns), |b| {
                messages::log(b, ns(event.time_s), event, name);
            })?;
        }
        // The final window repeats the last snapshot, with the run-ended event.
        if events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. })) {
            return Ok(());
        }
        let ground_truth = self.ground_truth.due(time_s);
        let estimator = self.estimator.due(time_s);
        let actuators = self.actuators.due(time_s);
        let status = self.status.due(time_s);
        tf_buf.clear();
        for s in drones {
            let Some(c) = channels.get_mut(s.index as usize) else { continue };
            if ground_truth {
                out.write(&mut c.pose, log_ns, log_ns, |b| messages::pose(b, log_ns, s))?;
                messages::transform(tf_buf, log_ns, &c.frame, s);
                out.write(&mut c.velocity, log_ns, log_ns, |b| messages::velocity(b, log_ns, s))?;
            }
            if estimator && let Some(e) = &s.detail.estimate {
                out.write(&mut c.estimate, log_ns, log_ns, |b| messages::estimate(b, log_ns, e, s))?;
            }
            if actuators {
                out.write(&mut c.motors, log_ns, log_ns, |b| messages::motors(b, log_ns, s))?;
            }
            if status {
                out.write(&mut c.battery, log_ns, log_ns, |b| messages::battery(b, log_ns, s))?;
                out.write(&mut c.status, log_ns, log_ns, |b| messages::status(b, log_ns, s))?;
                out.write(&mut c.wind, log_ns, log_ns, |b| messages::wind(b, log_ns, s))?;
                let [e, n, u] = s.position_enu_m;
                out.write(&mut c.location, log_ns, log_ns, |b| {
                    messages::location(b, log_ns, &c.frame, frame.to_geodetic(Enu::new(e, n, u)), None)
                })?;
            }
            if let Some(g) = &s.detail.gnss
                && c.last_gnss_s != Some(g.time_s)
            {
                c.last_gnss_s = Some(g.time_s);
                let fix_ns = ns(g.time_s).min(log_ns);
                let truth = s.position_back_at(g.time_s, time_s);
                out.write(&mut c.gnss_quality, log_ns, fix_ns, |b| messages::gnss_quality(b, fix_ns, g, truth))?;
                // Without a 3D fix the receiver's position means nothing.
                if g.fix_type >= 3 {
                    let sigma = g.eph_m.zip(g.epv_m);
                    out.write(&mut c.gnss, log_ns, fix_ns, |b| {
                        messages::location(b, fix_ns, &c.frame, frame.to_geodetic(messages::gnss_enu(g)), sigma)
                    })?;
                }
            }
        }
        if !tf_buf.is_empty() {
            out.write(tf, log_ns, log_ns, |b| b.extend_from_slice(tf_buf))?;
        }
        Ok(())
    }

    /// Records camera frames taken in the window at `time_s`, after the window's
    /// messages ([`Self::write_window`]): each frame's calibration, image and depth.
    ///
    /// # Errors
    /// I/O errors; `InvalidInput` for an image of a camera not given at creation.
    pub fn write_images(&mut self, time_s: f64, images: &[CameraImage]) -> std::io::Result<()> {
        let log_ns = ns(time_s);
        for image in images {
            let c = self.cameras.get_mut(image.stream).ok_or_else(|| {
                std::io::Error::new(std::io::ErrorKind::InvalidInput, format!("no recorded camera {}", image.stream))
            })?;
            let at = ns(image.time_s).min(log_ns);
            let CameraChannels { stream, frame, image: image_channel, calibration, depth } = c;
            self.out.write(calibration, log_ns, at, |b| messages::calibration(b, at, frame, stream))?;
            self.out.write(image_channel, log_ns, at, |b| messages::compressed_image(b, at, frame, &image.jpeg))?;
            if let (Some(depth), Some(data)) = (depth, &image.depth_mm_le) {
                self.out.write(depth, log_ns, at, |b| messages::depth_image(b, at, frame, stream, data))?;
            }
        }
        Ok(())
    }

    /// Writes the summary section and closes the file.
    ///
    /// # Errors
    /// I/O errors.
    pub fn finish(self) -> std::io::Result<()> {
        let file = self.out.writer.finish()?;
        file.into_inner().map_err(|e| e.into_error())?;
        Ok(())
    }

    /// [`Self::finish`] that also closes the file after a write error (the disk filled),
    /// once there is room again (the run's [`super::disk::DiskReserve`] released): the file
    /// is cut back to its last whole chunk, then the open chunk (also one whose write
    /// failed) and the summary section are written. With no room for that chunk, it is
    /// dropped and the summary written alone. `Ok(None)`: every message given is in the
    /// file; `Ok(Some(what))`: closed, without `what`.
    ///
    /// # Errors
    /// Not even the summary could be written: the file ends after its last whole chunk,
    /// without summary and footer (MCAP readers read it in their recovery mode).
    pub fn close(self) -> std::io::Result<Option<String>> {
        let mut writer = self.out.writer.cut_back(super::disk::cut)?;
        let mut dropped = None;
        if writer.flush().is_err() {
            dropped = Some(writer.discard_open_chunk());
            writer = writer.cut_back(super::disk::cut)?;
        }
        let whole = writer.position();
        match writer.finish() {
            Ok(file) => {
                file.into_inner().map_err(|e| e.into_error())?;
            }
            Err(e) => {
                // No summary: the file ends after its last whole chunk, not mid-record.
                let file = std::fs::OpenOptions::new().write(true).open(&self.path)?;
                file.set_len(whole)?;
                return Err(e);
            }
        }
        Ok(dropped.map(|n| format!("the {n} messages of its last chunk, for which there was no room")))
    }
}

/// Test support: the pose messages (`/drones/<name>/pose`, all drones) in the finished
/// `recording.mcap` of `dir`, from its summary's statistics.
///
/// # Panics
/// When the file does not end with the closing magic or has no summary: it was not finished.
#[cfg(test)]
pub(crate) fn finished_pose_count(dir: &Path) -> u64 {
    let mcap = std::fs::read(dir.join(MCAP_FILE)).unwrap();
    assert!(mcap.ends_with(writer::MAGIC), "no closing magic: {MCAP_FILE} was not finished");
    let summary = mcap::Summary::read(&mcap).unwrap().expect("a summary section");
    let stats = summary.stats.expect("statistics");
    summary.channels.values().filter(|c| c.topic.ends_with("/pose")).map(|c| stats.channel_message_counts[&c.id]).sum()
}
