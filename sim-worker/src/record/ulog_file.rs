//! `ulog/<drone>.ulg`: one PX4 ULog per drone, so PX4 Flight Review, pyulog and PlotJuggler
//! open each drone's flight as if PX4 SITL had logged it.
//!
//! Submodules: [`writer`] the byte format over any `Write`, [`topics`] the PX4 messages,
//! `convert` our ENU/FLU snapshots into PX4's NED/FRD messages, `messages` events as
//! logged strings. This file is the I/O shell: one buffered file per drone, the sampling
//! schedule, flushing.
//!
//! Streams and rates (`spec.recording.rates`, Hz of simulated time), sampled at sync-window
//! boundaries, one sample at the first window at or after each multiple of the period (as
//! `trajectory.csv`), so a run of T seconds has T x rate samples:
//! - estimator_hz: `vehicle_local_position`, `vehicle_global_position`, `vehicle_attitude`
//!   (the estimator's output, from its first GNSS fix on, as PX4 publishes them);
//! - estimator_hz too: the same three messages as `*_groundtruth` (the simulator's truth,
//!   at the estimator's rate as PX4 SITL logs them; `ground_truth_hz` applies to the MCAP
//!   recording only);
//! - actuators_hz: `actuator_outputs`;
//! - status_hz: `battery_status`, `vehicle_status`;
//! - each new GNSS receiver output: `sensor_gps` and `vehicle_gps_position` (same content);
//! - each event of the drone (and run-wide events): a logged string.
//!
//! Parameters: the drone's MAVLink parameter table at the run start
//! (`mavlink::params::plan::drone_table`), so the log and a ground station agree; only
//! MPC_XY_CRUISE is the scripted mission's speed when the group's mission sets one.
//!
//! Timestamps are microseconds of simulated time since the run start.

mod convert;
mod messages;
pub mod topics;
pub mod writer;

#[cfg(test)]
mod tests;

use std::fs::File;
use std::io::{self, BufWriter};
use std::path::Path;

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::{PlannedDrone, RunPlan};

use self::convert::{DroneFrame, Solution, StatusTracker, micros};
use self::topics::Topic;
use self::writer::{ParamValue, UlogWriter};
use crate::record::Sampler;
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::mavlink::params::{self as mavlink_params, plan::drone_table};
use sadesim_engine::protocol::DroneSnapshot;
use sadesim_engine::vehicle::BatterySpec;

pub use self::convert::q_ned_frd;
pub use sadesim_engine::mavlink::px4_mode::nav_state;

/// The cruise speed parameter, logged as the scripted mission's speed.
const CRUISE_PARAM: &str = "MPC_XY_CRUISE";

/// Folder inside the run folder.
pub const ULOG_DIR: &str = "ulog";

/// The topics of every file, in `msg_id` order: (ULog format and topic name, fields).
fn topic_table() -> Vec<(&'static str, Vec<(String, &'static str)>)> {
    use topics::*;
    vec![
        ("vehicle_local_position", VehicleLocalPosition::fields()),
        ("vehicle_global_position", VehicleGlobalPosition::fields()),
        ("vehicle_attitude", VehicleAttitude::fields()),
        ("vehicle_local_position_groundtruth", VehicleLocalPosition::fields()),
        ("vehicle_global_position_groundtruth", VehicleGlobalPosition::fields()),
        ("vehicle_attitude_groundtruth", VehicleAttitude::fields()),
        ("sensor_gps", SensorGps::fields()),
        ("vehicle_gps_position", SensorGps::fields()),
        ("battery_status", BatteryStatus::fields()),
        ("vehicle_status", VehicleStatus::fields()),
        ("actuator_outputs", ActuatorOutputs::fields()),
    ]
}

/// `msg_id` of each topic (its index in [`topic_table`]).
mod msg_id {
    pub const LOCAL_POSITION: u16 = 0;
    pub const GLOBAL_POSITION: u16 = 1;
    pub const ATTITUDE: u16 = 2;
    pub const LOCAL_POSITION_GT: u16 = 3;
    pub const GLOBAL_POSITION_GT: u16 = 4;
    pub const ATTITUDE_GT: u16 = 5;
    pub const SENSOR_GPS: u16 = 6;
    pub const VEHICLE_GPS_POSITION: u16 = 7;
    pub const BATTERY_STATUS: u16 = 8;
    pub const VEHICLE_STATUS: u16 = 9;
    pub const ACTUATOR_OUTPUTS: u16 = 10;
}

/// One drone's file and what it remembers between windows.
#[derive(Debug)]
struct DroneLog {
    out: UlogWriter<BufWriter<File>>,
    /// `ulog/<name>.ulg`, as write errors name it.
    path: String,
    system_id: u8,
    component_id: u8,
    battery: Option<BatterySpec>,
    /// Set at the first snapshot (the local origin does not move).
    frame: Option<DroneFrame>,
    /// Time of the last GNSS output logged, s.
    last_gnss_s: Option<f64>,
    status: StatusTracker,
    /// Latest timestamp written, microseconds (logged strings never go back in time).
    last_us: u64,
}

/// Writes one ULog file per drone, incrementally.
#[derive(Debug)]
pub struct UlogRecorder {
    frame: LocalFrame,
    drones: Vec<DroneLog>,
    names: Vec<String>,
    estimator: Sampler,
    actuators: Sampler,
    status: Sampler,
    /// Flush every file at the first window at or after each simulated second.
    flush: Sampler,
    scratch: Vec<u8>,
}

impl UlogRecorder {
    /// Creates `dir/ulog/` and one file per drone of `plan` (header, format definitions,
    /// info and parameters, subscriptions), at the rates of `plan.spec.recording()`.
    ///
    /// Each file stays open (one descriptor per drone) until [`UlogRecorder::finish`].
    ///
    /// # Errors
    /// I/O errors, naming the file (too many open files: raise `ulimit -n`).
    pub fn create(dir: &Path, plan: &RunPlan) -> io::Result<Self> {
        let folder = dir.join(ULOG_DIR);
        std::fs::create_dir_all(&folder)?;
        let rates = plan.spec.recording().rates;
        let topics = topic_table();
        let mut drones = Vec::with_capacity(plan.drones.len());
        for drone in &plan.drones {
            let path = folder.join(format!("{}.ulg", drone.name));
            let context = |e: io::Error| {
                let hint = if e.raw_os_error() == Some(24) {
                    " (one open file per drone: raise the limit with `ulimit -n`)"
                } else {
                    ""
                };
                io::Error::new(e.kind(), format!("failed to write {}: {e}{hint}", path.display()))
            };
            let file = File::create(&path).map_err(context)?;
            let mut out = UlogWriter::new(BufWriter::with_capacity(16 * 1024, file), 1).map_err(context)?;
            write_definitions(&mut out, plan, drone, &topics).map_err(context)?;
            drones.push(DroneLog {
                out,
                path: format!("{ULOG_DIR}/{}.ulg", drone.name),
                system_id: drone.system_id,
                component_id: drone.component_id,
                battery: sadesim_engine::preset::Preset::named(&drone.airframe).map(|p| p.airframe.battery),
                frame: None,
                last_gnss_s: None,
                status: StatusTracker::default(),
                last_us: 1,
            });
        }
        Ok(Self {
            frame: LocalFrame::new(plan.spec.origin.geo()),
            drones,
            names: plan.drones.iter().map(|d| d.name.clone()).collect(),
            estimator: Sampler::new(rates.estimator_hz),
            actuators: Sampler::new(rates.actuators_hz),
            status: Sampler::new(rates.status_hz),
            flush: Sampler::new(1.0),
            scratch: Vec::with_capacity(512),
        })
    }

    /// Records one sync window: the events as logged strings, then the samples due. The
    /// final window (with `runEnded`) repeats the last state and adds only its events.
    ///
    /// # Errors
    /// I/O errors.
    pub fn write_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> io::Result<()> {
        self.log_events(events)?;
        let final_window = events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. }));
        if final_window {
            return self.flush_all();
        }
        let t_us = micros(time_s);
        let estimator = self.estimator.due(time_s);
        let actuators = self.actuators.due(time_s);
        let status = self.status.due(time_s);
        let due = Due { estimator, actuators, status };
        for d in drones {
            let Some(log) = self.drones.get_mut(d.index as usize) else { continue };
            sample(log, &mut self.scratch, self.frame, d, t_us, due)
                .map_err(|e| crate::record::disk::named(&log.path, e))?;
        }
        if self.flush.due(time_s) {
            self.flush_all()?;
        }
        Ok(())
    }

    /// Flushes and closes every file.
    ///
    /// # Errors
    /// I/O errors, naming the file.
    pub fn finish(self) -> io::Result<()> {
        for log in self.drones {
            let path = log.path;
            log.out.into_inner().into_inner().map_err(|e| crate::record::disk::named(&path, e.into_error()))?;
        }
        Ok(())
    }

    /// [`Self::finish`] that also closes the files after a write error (the disk filled),
    /// once there is room again (the run's [`crate::record::disk::DiskReserve`] released):
    /// what each still buffers is written and the file cut back to its last whole message
    /// (a message whose write failed is dropped). Per file, `ulog/<name>.ulg` and whether it could be closed so;
    /// one that could not ends where its last write stopped (pyulog reads it up to there).
    pub fn close(self) -> Vec<(String, io::Result<()>)> {
        self.drones
            .into_iter()
            .map(|log| {
                let closed = log.out.cut_back(crate::record::disk::cut).map(|_| ());
                (log.path, closed)
            })
            .collect()
    }

    /// Each event as a logged string in its drone's file; run-wide events in every file.
    fn log_events(&mut self, events: &[Event]) -> io::Result<()> {
        let names = &self.names;
        let name = |i: u32| names.get(i as usize).cloned().unwrap_or_else(|| format!("drone {i}"));
        for event in events {
            let (level, text) = messages::describe(&event.kind, name);
            if let EventKind::Failsafe { .. } = event.kind
                && let Some(log) = event.drone.and_then(|i| self.drones.get_mut(i as usize))
            {
                log.status.failsafe = true;
            }
            let len = self.drones.len();
            let targets = match event.drone {
                Some(i) => (i as usize).min(len)..(i as usize + 1).min(len),
                None => 0..len,
            };
            for log in &mut self.drones[targets] {
                let t_us = micros(event.time_s).max(log.last_us);
                log.out.log(level, t_us, &text).map_err(|e| crate::record::disk::named(&log.path, e))?;
                log.last_us = t_us;
            }
        }
        Ok(())
    }

    fn flush_all(&mut self) -> io::Result<()> {
        self.drones.iter_mut().try_for_each(|log| log.out.flush().map_err(|e| crate::record::disk::named(&log.path, e)))
    }
}

/// Which samples a window takes.
#[derive(Clone, Copy)]
struct Due {
    estimator: bool,
    actuators: bool,
    status: bool,
}

/// One drone's samples of a window (at `t_us`) into its file.
fn sample(
    log: &mut DroneLog,
    buf: &mut Vec<u8>,
    run_frame: LocalFrame,
    d: &DroneSnapshot,
    t_us: u64,
    due: Due,
) -> io::Result<()> {
    log.status.observe(t_us, d);
    let frame = *log.frame.get_or_insert_with(|| DroneFrame::new(run_frame, d.detail.local_origin_enu_m, t_us));
    if let Some(g) = d.detail.gnss.as_ref().filter(|g| log.last_gnss_s != Some(g.time_s)) {
        log.last_gnss_s = Some(g.time_s);
        let gps = convert::sensor_gps(t_us, &frame, g);
        put(&mut log.out, buf, msg_id::SENSOR_GPS, &gps)?;
        put(&mut log.out, buf, msg_id::VEHICLE_GPS_POSITION, &gps)?;
    }
    if due.estimator
        && let Some(est) = Solution::estimate(d)
    {
        put(&mut log.out, buf, msg_id::LOCAL_POSITION, &convert::local_position(t_us, &frame, &est, d))?;
        put(&mut log.out, buf, msg_id::GLOBAL_POSITION, &convert::global_position(t_us, &frame, &est, d))?;
        put(&mut log.out, buf, msg_id::ATTITUDE, &convert::attitude(t_us, &est))?;
    }
    if due.estimator {
        let truth = Solution::truth(d);
        put(&mut log.out, buf, msg_id::LOCAL_POSITION_GT, &convert::local_position(t_us, &frame, &truth, d))?;
        put(&mut log.out, buf, msg_id::GLOBAL_POSITION_GT, &convert::global_position(t_us, &frame, &truth, d))?;
        put(&mut log.out, buf, msg_id::ATTITUDE_GT, &convert::attitude(t_us, &truth))?;
    }
    if due.actuators {
        put(&mut log.out, buf, msg_id::ACTUATOR_OUTPUTS, &convert::actuator_outputs(t_us, d))?;
    }
    if due.status {
        let battery = convert::battery_status(t_us, d, log.battery.as_ref());
        put(&mut log.out, buf, msg_id::BATTERY_STATUS, &battery)?;
        let vehicle = log.status.status(t_us, d, log.system_id, log.component_id);
        put(&mut log.out, buf, msg_id::VEHICLE_STATUS, &vehicle)?;
    }
    log.last_us = log.last_us.max(t_us);
    Ok(())
}

/// Encodes `message` into `buf` and writes it as a `D` message.
fn put<T: Topic>(out: &mut UlogWriter<BufWriter<File>>, buf: &mut Vec<u8>, id: u16, message: &T) -> io::Result<()> {
    buf.clear();
    message.encode(buf);
    out.data(id, buf)
}

/// Formats, info, parameters and subscriptions: everything before the first sample.
fn write_definitions<W: io::Write>(
    out: &mut UlogWriter<W>,
    plan: &RunPlan,
    drone: &PlannedDrone,
    topics: &[(&'static str, Vec<(String, &'static str)>)],
) -> io::Result<()> {
    for (name, fields) in topics {
        out.format(name, fields)?;
    }
    out.info_str("sys_name", "SADE-SIM")?;
    out.info_str("ver_hw", &format!("SADESIM_{}", drone.airframe.to_uppercase()))?;
    out.info_str("ver_sw", env!("CARGO_PKG_VERSION"))?;
    out.info_str("sys_uuid", &format!("{}/{}", plan.run.name, drone.name))?;
    out.info_str("sys_os_name", "sadesim")?;
    // Local time = UTC: simulated time has no time zone.
    out.info_i32("time_ref_utc", 0)?;
    // The drone's MAVLink parameter table as the run starts (none for an unknown airframe,
    // which the validator refuses), except MPC_XY_CRUISE: the scripted mission's speed when
    // it has one, what the drone flies (the table keeps PX4's default for MAVLink missions).
    let group = plan.spec.fleet.get(drone.group_index as usize);
    let mission_speed_mps = group.and_then(|g| g.mission.as_ref()).and_then(|m| m.speed_mps);
    for p in drone_table(plan, drone).iter().flat_map(|t| t.params()) {
        let value = match (p.value, mission_speed_mps) {
            (_, Some(speed_mps)) if p.name == CRUISE_PARAM => ParamValue::Float(speed_mps as f32),
            (mavlink_params::ParamValue::Int32(i), _) => ParamValue::Int32(i),
            (mavlink_params::ParamValue::Real32(v), _) => ParamValue::Float(v),
        };
        out.parameter(p.name, value)?;
    }
    for (id, (name, _)) in topics.iter().enumerate() {
        out.add_logged(0, id as u16, name)?;
    }
    Ok(())
}
