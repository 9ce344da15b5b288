//! One drone's MAVLink session: the PX4 behaviour its peers see, as a pure state machine.
//!
//! Frames in ([`Session::handle`]), vehicle events in ([`Session::on_events`]), messages
//! out ([`Session::poll`]): acknowledgements and replies as they arise, telemetry streams
//! at PX4's rates (changed by SET_MESSAGE_INTERVAL). Commands reach the autopilot through
//! the [`Vehicle`] trait, so tests drive a session with a fake vehicle and no sockets.
//! Time is sim time, from the [`VehicleView`].
//!
//! Deprecated messages and commands (SET_MODE, PING, MISSION_ITEM, GET_HOME_POSITION, ...)
//! are served on purpose: PX4 still answers them and pymavlink and older ground stations
//! still send them.
#![allow(deprecated)]

use ::mavlink::Message;
use ::mavlink::dialects::common::*;
use nalgebra::{Vector2, Vector3};
use sadesim_crds::geo::GeoPoint;

use crate::autopilot::control::Setpoint;
use crate::autopilot::mission::MissionPlan;
use crate::autopilot::navigator::{Command, NavigatorConfig, Rejection};
use crate::events::{EventKind, FlightMode};
use crate::mavlink::frame::{Decoded, Frame};
use crate::mavlink::mission_protocol::{MissionContext, MissionProtocol};
use crate::mavlink::params::ParamTable;
use crate::mavlink::px4_mode;
use crate::mavlink::streams::{Due, StreamScheduler};
use crate::mavlink::telemetry::{self, VehicleIdentity, VehicleView, ned_to_enu};

/// Our component: the autopilot (MAV_COMP_ID_AUTOPILOT1).
pub const COMPONENT_ID: u8 = 1;
/// Replies a session keeps between two polls; more are dropped (counted in
/// [`SessionStats::dropped_replies`]). Ten parameter lists: what no peer needs at once, but
/// what a flood of PARAM_REQUEST_LIST would otherwise multiply without bound.
pub const MAX_PENDING_REPLIES: usize = 1024;

mod flood;
pub use flood::{BURST as INBOUND_BURST, InboundBudget, PER_S as INBOUND_PER_S};

/// What a session may ask of the drone's autopilot.
pub trait Vehicle {
    /// # Errors
    /// The autopilot's refusal.
    fn command(&mut self, cmd: Command) -> Result<(), Rejection>;
    fn navigator_config(&self) -> NavigatorConfig;
    fn set_navigator_config(&mut self, config: NavigatorConfig);
}

/// Counters for logs and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SessionStats {
    pub handled: u64,
    pub commands: u64,
    pub unsupported_commands: u64,
    pub ignored: u64,
    /// Frames dropped unread: their peer was over its budget (`flood`).
    pub refused_flood: u64,
    /// Replies dropped because [`MAX_PENDING_REPLIES`] were waiting.
    pub dropped_replies: u64,
}

/// The MAVLink face of one drone.
#[derive(Debug)]
pub struct Session {
    id: VehicleIdentity,
    params: ParamTable,
    streams: StreamScheduler,
    missions: MissionProtocol,
    outbox: Vec<MavMessage>,
    /// Replies the typed dialect cannot express.
    raw: Vec<Outgoing>,
    /// (current, count) last reported in MISSION_CURRENT, to report changes at once.
    reported_mission: Option<(usize, usize)>,
    /// What each peer may send (`flood`).
    budget: InboundBudget,
    /// Run events the session raised (a flood), for the drone to take.
    events: Vec<EventKind>,
    pub stats: SessionStats,
}

impl Session {
    /// `params` is the drone's parameter table (`params::plan::drone_table`, or
    /// [`ParamTable::px4`]).
    pub fn new(id: VehicleIdentity, params: ParamTable) -> Self {
        Self {
            params,
            streams: StreamScheduler::px4_default(),
            missions: MissionProtocol::new(),
            outbox: Vec::new(),
            raw: Vec::new(),
            reported_mission: None,
            budget: InboundBudget::default(),
            events: Vec::new(),
            stats: SessionStats::default(),
            id,
        }
    }

    /// Handles one frame from a peer, within its peer's budget (`flood`: over it, the
    /// frame is dropped unread and the flood reported); the replies waiting stay within
    /// [`MAX_PENDING_REPLIES`].
    pub fn handle(&mut self, frame: &Frame, view: &VehicleView, vehicle: &mut dyn Vehicle) {
        let from = (frame.header.system_id as u8, frame.header.component_id);
        if u32::from(self.id.system_id) == frame.header.system_id {
            self.stats.ignored += 1; // our own echo (a router looping back)
            return;
        }
        let (accepted, report) = self.budget.take(from, view.time_s);
        if let Some(report) = report {
            // First in the queue, so the replies' limit never cuts it.
            self.status_text(MavSeverity::MAV_SEVERITY_WARNING, &report.status_text);
            self.outbox.rotate_right(1);
            self.events.push(report.event);
        }
        if !accepted {
            self.stats.refused_flood += 1;
            return;
        }
        self.handle_frame(frame, from, view, vehicle);
        for queue in [self.outbox.len(), self.raw.len()] {
            self.stats.dropped_replies += queue.saturating_sub(MAX_PENDING_REPLIES) as u64;
        }
        self.outbox.truncate(MAX_PENDING_REPLIES);
        self.raw.truncate(MAX_PENDING_REPLIES);
    }

    /// The run events the session raised since the last call (a flood's reports).
    pub fn take_events(&mut self) -> Vec<EventKind> {
        std::mem::take(&mut self.events)
    }

    fn handle_frame(&mut self, frame: &Frame, from: (u8, u8), view: &VehicleView, vehicle: &mut dyn Vehicle) {
        let msg = match &frame.message {
            Decoded::Message(m) => m,
            Decoded::UnknownCommand { command, target_system, target_component } => {
                if self.addressed_to_us(Some(*target_system), Some(*target_component)) {
                    self.stats.unsupported_commands += 1;
                    self.ack_raw(*command, MavResult::MAV_RESULT_UNSUPPORTED, from);
                }
                return;
            }
            Decoded::Undecodable(_) => {
                self.stats.ignored += 1;
                return;
            }
        };
        if !self.addressed_to_us(msg.target_system_id(), msg.target_component_id()) {
            self.stats.ignored += 1;
            return;
        }
        self.stats.handled += 1;
        match msg {
            MavMessage::COMMAND_LONG(c) => {
                let args = CommandArgs {
                    params: [c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7],
                    position: Position::Float,
                    frame: MavFrame::MAV_FRAME_GLOBAL,
                };
                self.command(c.command, &args, from, view, vehicle);
            }
            MavMessage::COMMAND_INT(c) => {
                let args = CommandArgs {
                    params: [c.param1, c.param2, c.param3, c.param4, c.x as f32, c.y as f32, c.z],
                    position: Position::Int { x: c.x, y: c.y },
                    frame: c.frame,
                };
                self.command(c.command, &args, from, view, vehicle);
            }
            MavMessage::SET_MODE(m) => {
                let custom = m.custom_mode;
                let (main, sub) = ((custom >> 16) as u8, (custom >> 24) as u8);
                let _ = self.set_mode(main, sub, view, vehicle);
            }
            MavMessage::PING(p) if p.target_system == 0 => {
                self.outbox.push(MavMessage::PING(PING_DATA {
                    time_usec: p.time_usec,
                    seq: p.seq,
                    target_system: from.0,
                    target_component: from.1,
                }));
            }
            MavMessage::TIMESYNC(t) if t.tc1 == 0 => {
                self.outbox.push(MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: (view.time_s * 1e9).round() as i64,
                    ts1: t.ts1,
                    target_system: from.0,
                    target_component: from.1,
                }));
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(t) => {
                if let Some(sp) = local_setpoint(t, view) {
                    let _ = vehicle.command(Command::OffboardSetpoint(sp));
                }
            }
            MavMessage::SET_POSITION_TARGET_GLOBAL_INT(t) => {
                if let Some(sp) = self.global_setpoint(t, view) {
                    let _ = vehicle.command(Command::OffboardSetpoint(sp));
                }
            }
            MavMessage::PARAM_REQUEST_LIST(_) | MavMessage::PARAM_REQUEST_READ(_) | MavMessage::PARAM_SET(_) => {
                let reply = self.params.handle(msg);
                self.outbox.extend(reply.messages);
                if reply.navigator_changed {
                    let config = self.params.navigator_config(vehicle.navigator_config());
                    vehicle.set_navigator_config(config);
                }
            }
            MavMessage::MISSION_SET_CURRENT(m) => {
                if vehicle.command(Command::SetCurrentItem(usize::from(m.seq))).is_ok() {
                    self.reported_mission = None; // report the change at once
                }
            }
            MavMessage::MISSION_COUNT(_)
            | MavMessage::MISSION_ITEM_INT(_)
            | MavMessage::MISSION_ITEM(_)
            | MavMessage::MISSION_REQUEST_LIST(_)
            | MavMessage::MISSION_REQUEST_INT(_)
            | MavMessage::MISSION_REQUEST(_)
            | MavMessage::MISSION_ACK(_)
            | MavMessage::MISSION_CLEAR_ALL(_) => {
                let ctx = mission_context(&self.id, &self.params, view);
                let out = self.missions.handle(from, msg, view.time_s, &ctx);
                self.outbox.extend(out.replies);
                if let Some(plan) = out.loaded {
                    let _ = vehicle.command(Command::LoadMission(plan));
                    self.reported_mission = None;
                } else if out.cleared {
                    let empty = MissionPlan { items: Vec::new(), speed_mps: self.params.cruise_speed_mps() };
                    let _ = vehicle.command(Command::LoadMission(empty));
                    self.reported_mission = None;
                }
            }
            _ => self.stats.ignored += 1,
        }
    }

    /// Reports what the vehicle did (mission items reached, failsafes) as PX4 would.
    pub fn on_events(&mut self, events: &[EventKind]) {
        for e in events {
            match e {
                EventKind::WaypointReached { seq } => {
                    self.outbox.push(MavMessage::MISSION_ITEM_REACHED(MISSION_ITEM_REACHED_DATA {
                        seq: (*seq).min(u32::from(u16::MAX)) as u16,
                    }));
                    self.reported_mission = None;
                }
                EventKind::MissionCompleted => self.status_text(MavSeverity::MAV_SEVERITY_INFO, "Mission finished"),
                EventKind::Failsafe { reason, action } => self.status_text(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!("Failsafe {reason}: {}", mode_name(*action)),
                ),
                EventKind::Crashed { with, .. } => {
                    self.status_text(MavSeverity::MAV_SEVERITY_EMERGENCY, &format!("Crashed into {with}"));
                }
                EventKind::Armed => self.status_text(MavSeverity::MAV_SEVERITY_INFO, "Armed"),
                EventKind::Disarmed => self.status_text(MavSeverity::MAV_SEVERITY_INFO, "Disarmed"),
                _ => {}
            }
        }
    }

    /// Messages due now: replies first, then telemetry streams at their rates (the due
    /// streams as one [`Outgoing::Telemetry`], built when encoded).
    pub fn poll(&mut self, view: &VehicleView) -> Vec<Outgoing> {
        let mut out = Vec::new();
        self.poll_into(view, &mut out);
        out
    }

    /// A HEARTBEAT of `view`, outside the streams' schedule: what a drone held at the
    /// release sends while the run waits for its pilot (the schedule, on simulated time,
    /// sends nothing while simulated time stands still).
    pub fn heartbeat(&self, view: &VehicleView) -> Option<Outgoing> {
        telemetry::build(0, view, &self.id).map(Outgoing::Message)
    }

    /// [`Session::poll`] appending to `out`: the shard's per-drone queue, which keeps its
    /// allocation from window to window (this runs for every drone at every window end, so
    /// building a list per call and moving each message into the queue showed in profiles).
    pub fn poll_into(&mut self, view: &VehicleView, out: &mut Vec<Outgoing>) {
        out.append(&mut self.raw);
        out.extend(self.outbox.drain(..).map(Outgoing::Message));
        out.extend(self.missions.poll(view.time_s).into_iter().map(Outgoing::Message));
        let current = (view.mission.current, view.mission.count);
        let due = self.streams.due(view.time_s);
        // MISSION_CURRENT (42) is always built (`telemetry::build`), so due is sent.
        let mut mission_sent = due.contains(&42);
        if !due.is_empty() {
            out.push(Outgoing::Telemetry(Box::new(DueTelemetry { view: view.clone(), due, identity: self.id })));
        }
        if !mission_sent && self.reported_mission != Some(current) && view.mission.count > 0 {
            out.push(Outgoing::Message(telemetry::mission_current(view)));
            mission_sent = true;
        }
        if mission_sent {
            self.reported_mission = Some(current);
        }
    }

    fn addressed_to_us(&self, system: Option<u8>, component: Option<u8>) -> bool {
        let system_ok = system.is_none_or(|s| s == 0 || s == self.id.system_id);
        let component_ok = component.is_none_or(|c| c == 0 || c == COMPONENT_ID);
        system_ok && component_ok
    }

    fn status_text(&mut self, severity: MavSeverity, text: &str) {
        let mut bytes = [0u8; 50];
        let n = text.len().min(50);
        bytes[..n].copy_from_slice(&text.as_bytes()[..n]);
        self.outbox.push(MavMessage::STATUSTEXT(STATUSTEXT_DATA { severity, text: bytes.into(), id: 0, chunk_seq: 0 }));
    }

    fn ack(&mut self, command: MavCmd, result: MavResult, to: (u8, u8)) {
        self.outbox.push(MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: to.0,
            target_component: to.1,
        }));
    }

    /// An ack for a command number the dialect does not define (the typed message cannot
    /// hold it, so the link encodes it from its fields).
    fn ack_raw(&mut self, command: u16, result: MavResult, to: (u8, u8)) {
        self.raw.push(Outgoing::UnknownCommandAck { command, result, target: to });
    }

    /// ENU point for a global position in `frame`; `None` for frames we do not take.
    fn global_to_enu(
        &self,
        lat_deg: f64,
        lon_deg: f64,
        alt_m: f64,
        frame: MavFrame,
        view: &VehicleView,
    ) -> Option<Vector3<f64>> {
        let origin_alt = self.id.frame.origin().altitude_msl_m;
        let p = self.id.frame.to_enu(GeoPoint {
            latitude_deg: lat_deg,
            longitude_deg: lon_deg,
            altitude_msl_m: origin_alt,
        });
        let up = match frame {
            MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => alt_m - origin_alt,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
                view.home_enu_m.z + alt_m
            }
            _ => return None,
        };
        Some(Vector3::new(p.east_m, p.north_m, up))
    }

    fn global_setpoint(&self, t: &SET_POSITION_TARGET_GLOBAL_INT_DATA, view: &VehicleView) -> Option<Setpoint> {
        let mask = t.type_mask;
        let yaw = yaw_of(mask, t.yaw, view);
        if !mask.intersects(POSITION_IGNORED) {
            let p = self.global_to_enu(
                f64::from(t.lat_int) * 1e-7,
                f64::from(t.lon_int) * 1e-7,
                f64::from(t.alt),
                t.coordinate_frame,
                view,
            )?;
            return Some(Setpoint::Position {
                position_enu_m: p,
                yaw_rad: yaw,
                velocity_ff: velocity_ff(mask, t.vx, t.vy, t.vz),
            });
        }
        velocity_setpoint(mask, t.vx, t.vy, t.vz, yaw)
    }

    /// Dispatches one command and queues its COMMAND_ACK.
    fn command(&mut self, cmd: MavCmd, a: &CommandArgs, from: (u8, u8), view: &VehicleView, vehicle: &mut dyn Vehicle) {
        self.stats.commands += 1;
        let result = match cmd {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                if a.params[0] >= 0.5 {
                    reject(vehicle.command(Command::Arm))
                } else {
                    reject(vehicle.command(Command::Disarm))
                }
            }
            MavCmd::MAV_CMD_NAV_TAKEOFF => {
                // PX4: param7 is the takeoff altitude AMSL; NaN means MIS_TAKEOFF_ALT above home.
                let rel = if a.params[6].is_finite() {
                    f64::from(a.params[6]) - self.id.frame.origin().altitude_msl_m - view.home_enu_m.z
                } else {
                    self.params.takeoff_altitude_m()
                };
                reject(vehicle.command(Command::Takeoff { altitude_rel_home_m: rel.max(1.0) }))
            }
            MavCmd::MAV_CMD_NAV_LAND => reject(vehicle.command(Command::Land)),
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => reject(vehicle.command(Command::ReturnToLaunch)),
            MavCmd::MAV_CMD_DO_SET_MODE => {
                let (main, sub) = (a.params[1] as u8, a.params[2] as u8);
                self.set_mode(main, sub, view, vehicle)
            }
            MavCmd::MAV_CMD_DO_REPOSITION => self.reposition(a, view, vehicle),
            MavCmd::MAV_CMD_MISSION_START => {
                let first = a.params[0];
                let mut r = Ok(());
                if first.is_finite() && first > 0.0 {
                    r = vehicle.command(Command::SetCurrentItem(first as usize));
                }
                reject(r.and_then(|()| vehicle.command(Command::StartMission)))
            }
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let id = a.params[0] as u32;
                if telemetry::PRODUCIBLE.contains(&id) && self.streams.set_interval(id, a.params[1]).is_ok() {
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_UNSUPPORTED
                }
            }
            MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL => {
                let id = a.params[0] as u32;
                match self.streams.interval_us(id) {
                    Some(interval_us) => {
                        self.outbox.push(MavMessage::MESSAGE_INTERVAL(MESSAGE_INTERVAL_DATA {
                            interval_us,
                            message_id: id as u16,
                        }));
                        MavResult::MAV_RESULT_ACCEPTED
                    }
                    None => MavResult::MAV_RESULT_UNSUPPORTED,
                }
            }
            MavCmd::MAV_CMD_REQUEST_MESSAGE => match telemetry::build(a.params[0] as u32, view, &self.id) {
                Some(m) => {
                    self.outbox.push(m);
                    MavResult::MAV_RESULT_ACCEPTED
                }
                // Known but not available yet (e.g. HOME_POSITION before a fix): try later.
                None if telemetry::PRODUCIBLE.contains(&(a.params[0] as u32)) => {
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                }
                None => MavResult::MAV_RESULT_UNSUPPORTED,
            },
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
                self.outbox.push(telemetry::autopilot_version(&self.id));
                MavResult::MAV_RESULT_ACCEPTED
            }
            MavCmd::MAV_CMD_GET_HOME_POSITION => match telemetry::home_position(view, &self.id) {
                Some(m) => {
                    self.outbox.push(m);
                    MavResult::MAV_RESULT_ACCEPTED
                }
                None => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
            },
            _ => {
                self.stats.unsupported_commands += 1;
                MavResult::MAV_RESULT_UNSUPPORTED
            }
        };
        self.ack(cmd, result, from);
    }

    /// DO_SET_MODE / SET_MODE with PX4 main and sub modes.
    fn set_mode(&mut self, main: u8, sub: u8, view: &VehicleView, vehicle: &mut dyn Vehicle) -> MavResult {
        let Some(mode) = px4_mode::from_px4(main, sub) else {
            return MavResult::MAV_RESULT_UNSUPPORTED; // manual/stabilised modes need sticks
        };
        if !view.armed && mode == FlightMode::Hold {
            return MavResult::MAV_RESULT_ACCEPTED; // disarmed on the ground, PX4 is in HOLD anyway
        }
        let cmd = match mode {
            FlightMode::Hold | FlightMode::Idle => Command::Hold,
            FlightMode::Takeoff => Command::Takeoff { altitude_rel_home_m: self.params.takeoff_altitude_m() },
            FlightMode::Mission => Command::StartMission,
            FlightMode::ReturnToLaunch => Command::ReturnToLaunch,
            FlightMode::Land => Command::Land,
            FlightMode::Offboard => Command::StartOffboard,
        };
        reject(vehicle.command(cmd))
    }

    /// DO_REPOSITION: fly to a global position and hold there (NaN fields keep the current
    /// value, as in PX4).
    fn reposition(&mut self, a: &CommandArgs, view: &VehicleView, vehicle: &mut dyn Vehicle) -> MavResult {
        let Some(est) = view.estimate else { return MavResult::MAV_RESULT_TEMPORARILY_REJECTED };
        let (lat, lon) = match a.position {
            Position::Int { x, y } => (f64::from(x) * 1e-7, f64::from(y) * 1e-7),
            Position::Float => (f64::from(a.params[4]), f64::from(a.params[5])),
        };
        // NaN, or lat/lon both 0 (MAVLink's "unset"), keeps the current position.
        let unset = lat == 0.0 && lon == 0.0;
        let here = self.id.frame.to_geodetic(sadesim_crds::geo::Enu {
            east_m: est.position_enu_m.x,
            north_m: est.position_enu_m.y,
            up_m: est.position_enu_m.z,
        });
        let pick = |v: f64, current: f64| if v.is_finite() && !unset { v } else { current };
        let (lat, lon) = (pick(lat, here.latitude_deg), pick(lon, here.longitude_deg));
        let frame = match a.position {
            Position::Int { .. } => a.frame,
            Position::Float => MavFrame::MAV_FRAME_GLOBAL,
        };
        let target = if a.params[6].is_finite() {
            match self.global_to_enu(lat, lon, f64::from(a.params[6]), frame, view) {
                Some(t) => t,
                None => return MavResult::MAV_RESULT_UNSUPPORTED,
            }
        } else {
            let p = self.id.frame.to_enu(GeoPoint { latitude_deg: lat, longitude_deg: lon, altitude_msl_m: 0.0 });
            Vector3::new(p.east_m, p.north_m, est.position_enu_m.z)
        };
        reject(vehicle.command(Command::GoTo {
            target_en_m: Vector2::new(target.x, target.y),
            altitude_rel_home_m: target.z - view.home_enu_m.z,
        }))
    }
}

fn mission_context<'a>(id: &'a VehicleIdentity, params: &ParamTable, view: &VehicleView) -> MissionContext<'a> {
    MissionContext {
        frame: &id.frame,
        home_alt_amsl_m: id.frame.origin().altitude_msl_m + view.home_enu_m.z,
        our_system: id.system_id,
        our_component: COMPONENT_ID,
        cruise_speed_mps: params.cruise_speed_mps(),
        current_seq: view.mission.current.min(usize::from(u16::MAX)) as u16,
    }
}

/// What a session sends. (Encoded within the same window; a reply is not worth a box.)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Outgoing {
    Message(MavMessage),
    /// COMMAND_ACK for a command number outside the dialect.
    UnknownCommandAck {
        command: u16,
        result: MavResult,
        target: (u8, u8),
    },
    /// The telemetry streams due at one window end, built where they are encoded (one
    /// frame per message, in [`DueTelemetry::messages`]' order).
    Telemetry(Box<DueTelemetry>),
}

/// The telemetry streams found due at `view.time_s`, not built yet.
///
/// Why deferred: building the messages (Euler angles, the geodetic conversion) and
/// encoding them are most of MAVLink's cost in a shard, and both depend on this snapshot
/// alone. So the shard keeps only the snapshot, and whoever encodes the queue (the shard's
/// MAVLink I/O thread, `sim_worker::shard_io::MavlinkThread`) builds the messages while the
/// shard steps its next window. PX4 does the same: its streams run in the mavlink module's own
/// task and read the uORB topics the controllers published. The frames are the ones an
/// immediate build gives: same messages, same order, same sequence numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct DueTelemetry {
    pub view: VehicleView,
    /// Message ids, ascending.
    pub due: Due,
    pub identity: VehicleIdentity,
}

impl DueTelemetry {
    /// The messages, in `due`'s order; ids [`telemetry::build`] does not produce yet (a
    /// position before the first fix) are skipped.
    pub fn messages(&self) -> impl Iterator<Item = MavMessage> + '_ {
        self.due.iter().filter_map(|&id| telemetry::build(id, &self.view, &self.identity))
    }
}

impl Outgoing {
    /// The MAVLink 2 frames, the first with `header`'s sequence number and the next ones
    /// (telemetry) counting up from it, as a client receives them. (Links encode with
    /// their own sequence numbers, in `Endpoint::queue`.) For tests (feature `fixtures`).
    #[cfg(any(test, feature = "fixtures"))]
    pub fn encode(&self, header: ::mavlink::MavHeader) -> Vec<u8> {
        let mut out = Vec::new();
        match self {
            Outgoing::Message(m) => crate::mavlink::frame::encode_into(&mut out, header, m),
            Outgoing::UnknownCommandAck { command, result, target } => {
                out.extend(crate::mavlink::frame::encode_command_ack(header, *command, *result, *target));
            }
            Outgoing::Telemetry(t) => {
                let mut header = header;
                for m in t.messages() {
                    crate::mavlink::frame::encode_into(&mut out, header, &m);
                    header.sequence = header.sequence.wrapping_add(1);
                }
            }
        }
        out
    }

    /// The typed messages (an unknown command's ack has none): what peers decode.
    #[cfg(test)]
    pub(crate) fn into_messages(self) -> Vec<MavMessage> {
        match self {
            Outgoing::Message(m) => vec![m],
            Outgoing::UnknownCommandAck { .. } => Vec::new(),
            Outgoing::Telemetry(t) => t.messages().collect(),
        }
    }
}

/// Command parameters, whichever message carried them.
struct CommandArgs {
    params: [f32; 7],
    position: Position,
    frame: MavFrame,
}

/// COMMAND_INT carries lat/lon as integers (1e-7 degrees); COMMAND_LONG as floats.
#[derive(Clone, Copy)]
enum Position {
    Int { x: i32, y: i32 },
    Float,
}

fn reject(r: Result<(), Rejection>) -> MavResult {
    match r {
        Ok(()) => MavResult::MAV_RESULT_ACCEPTED,
        // Arming checks may pass later (GNSS fix, accuracy): PX4 answers "temporarily".
        Err(Rejection::ArmingCheck(_) | Rejection::NoOffboardSetpoint(_)) => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
        Err(_) => MavResult::MAV_RESULT_DENIED,
    }
}

fn mode_name(m: FlightMode) -> &'static str {
    match m {
        FlightMode::Idle => "idle",
        FlightMode::Takeoff => "takeoff",
        FlightMode::Hold => "hold",
        FlightMode::Mission => "mission",
        FlightMode::Offboard => "offboard",
        FlightMode::ReturnToLaunch => "return",
        FlightMode::Land => "land",
    }
}

const POSITION_IGNORED: PositionTargetTypemask = PositionTargetTypemask::from_bits_truncate(0b111);
const VELOCITY_IGNORED: PositionTargetTypemask = PositionTargetTypemask::from_bits_truncate(0b111_000);
const YAW_IGNORED: PositionTargetTypemask = PositionTargetTypemask::from_bits_truncate(1 << 10);

/// ENU yaw for a setpoint: the NED yaw if given, else the current heading.
fn yaw_of(mask: PositionTargetTypemask, yaw_ned: f32, view: &VehicleView) -> f64 {
    if mask.contains(YAW_IGNORED) || !yaw_ned.is_finite() {
        crate::vehicle::yaw_of(&view.attitude)
    } else {
        telemetry::enu_yaw_to_heading(f64::from(yaw_ned)) // the map is its own inverse
    }
}

fn velocity_ff(mask: PositionTargetTypemask, vx: f32, vy: f32, vz: f32) -> Vector3<f64> {
    if mask.intersects(VELOCITY_IGNORED) || !(vx.is_finite() && vy.is_finite() && vz.is_finite()) {
        Vector3::zeros()
    } else {
        ned_to_enu(&Vector3::new(f64::from(vx), f64::from(vy), f64::from(vz)))
    }
}

fn velocity_setpoint(mask: PositionTargetTypemask, vx: f32, vy: f32, vz: f32, yaw: f64) -> Option<Setpoint> {
    if mask.intersects(VELOCITY_IGNORED) {
        return None; // acceleration/thrust-only setpoints are not supported
    }
    let v = Vector3::new(f64::from(vx), f64::from(vy), f64::from(vz));
    if !v.iter().all(|c| c.is_finite()) {
        return None;
    }
    Some(Setpoint::Velocity { velocity_enu_mps: ned_to_enu(&v), yaw_rad: yaw })
}

/// SET_POSITION_TARGET_LOCAL_NED in MAV_FRAME_LOCAL_NED (positions from the local origin)
/// or MAV_FRAME_BODY_NED (velocities rotated by the current heading, as MAVSDK's
/// `set_velocity_body` sends them).
fn local_setpoint(t: &SET_POSITION_TARGET_LOCAL_NED_DATA, view: &VehicleView) -> Option<Setpoint> {
    let mask = t.type_mask;
    let yaw = yaw_of(mask, t.yaw, view);
    match t.coordinate_frame {
        MavFrame::MAV_FRAME_LOCAL_NED => {
            if !mask.intersects(POSITION_IGNORED) {
                let p = Vector3::new(f64::from(t.x), f64::from(t.y), f64::from(t.z));
                if !p.iter().all(|c| c.is_finite()) {
                    return None;
                }
                let position_enu_m = view.local_origin_enu_m + ned_to_enu(&p);
                return Some(Setpoint::Position {
                    position_enu_m,
                    yaw_rad: yaw,
                    velocity_ff: velocity_ff(mask, t.vx, t.vy, t.vz),
                });
            }
            velocity_setpoint(mask, t.vx, t.vy, t.vz, yaw)
        }
        MavFrame::MAV_FRAME_BODY_NED | MavFrame::MAV_FRAME_BODY_FRD => {
            let heading = crate::vehicle::yaw_of(&view.attitude);
            let (s, c) = heading.sin_cos();
            // Body forward/right/down -> ENU: forward along the heading, right 90 degrees clockwise.
            let (f, r, d) = (f64::from(t.vx), f64::from(t.vy), f64::from(t.vz));
            if mask.intersects(VELOCITY_IGNORED) || !(f.is_finite() && r.is_finite() && d.is_finite()) {
                return None;
            }
            let v = Vector3::new(f * c + r * s, f * s - r * c, -d);
            Some(Setpoint::Velocity { velocity_enu_mps: v, yaw_rad: yaw })
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests;
