//! The MAVLink mission protocol of one drone (<https://mavlink.io/en/services/mission.html>)
//! as PX4 speaks it to MAVSDK, QGroundControl and pymavlink: upload, download and clear.
//!
//! A pure state machine in the style of the session: messages and the time go in, replies
//! and (when an upload completes) a [`MissionPlan`] for the autopilot come out. No sockets,
//! no clock: `now_s` is whatever monotonic clock the caller drives it with, in seconds.
//!
//! # What is stored
//! Only `MAV_MISSION_TYPE_MISSION`. The mission is kept as the `MISSION_ITEM_INT` list the
//! client uploaded, so a download returns it unchanged (only `target_*` and the `current`
//! flag are rewritten); legacy `MISSION_ITEM` uploads are stored in the INT encoding with
//! their frame kept. Geofence and rally plans are not stored: a non-empty upload is refused
//! with `MAV_MISSION_UNSUPPORTED`, while empty uploads, clears and list requests succeed
//! (an empty plan), because QGroundControl uploads an empty fence and rally plan after every
//! mission and MAVSDK / QGC download them on connect; refusing those would fail the whole
//! plan transfer.
//!
//! # Upload (client -> drone)
//! `MISSION_COUNT` -> `MISSION_REQUEST_INT(0)`, each accepted item -> the next request,
//! the last item -> `MISSION_ACK(ACCEPTED, opaque_id)` and [`MissionOutput::loaded`]. Every
//! item is converted on arrival ([`to_plan`]'s rules), so an unsupported item is refused
//! with its result right after that item (the ACK itself carries no seq; the seq is the
//! item just sent) and the previously stored mission stays in force, as in PX4, which
//! writes uploads to an inactive buffer. Out-of-sequence items are dropped and the expected
//! seq re-requested at once. A client that answers with `MISSION_ITEM` (float) gets legacy
//! `MISSION_REQUEST`s from then on, as PX4 does.
//!
//! # Download (drone -> client)
//! `MISSION_REQUEST_LIST` -> `MISSION_COUNT(count, opaque_id)`; `MISSION_REQUEST_INT(seq)`
//! -> `MISSION_ITEM_INT`; legacy `MISSION_REQUEST(seq)` -> `MISSION_ITEM` with float
//! lat/lon (PX4 answers in the form it was asked in; the spec would answer INT, but the
//! clients still sending `MISSION_REQUEST` are the ones that expect `MISSION_ITEM`). The
//! client's final `MISSION_ACK` ends the download; so does sending the last item (PX4's
//! "maybe completed" rule) or [`DOWNLOAD_TIMEOUT_S`] of silence.
//!
//! # Opaque ids
//! PX4 (v1.14+) fills `opaque_id` with a CRC-32 of the mission items: in the upload's
//! `MISSION_ACK`, the download's `MISSION_COUNT` and `MISSION_CURRENT.mission_id`;
//! QGroundControl uses it to skip downloading a plan it already has. We do the same with a
//! CRC-32 over each item's frame, command, autocontinue and params 1–7 (not bit-identical to
//! PX4's, which hashes a packed C struct; the id is opaque, so no client can tell). An
//! empty mission, and every fence and rally plan, has id 0 ("none"), as in PX4.
//!
//! # Timeouts
//! During an upload the drone re-sends its last request after [`RETRY_TIMEOUT_S`] (PX4's
//! `MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT`, also the spec's item timeout) up to
//! [`MAX_RETRIES`] times (the spec's retry count), then cancels with
//! `MISSION_ACK(MAV_MISSION_OPERATION_CANCELLED)`. PX4 keeps re-requesting until 5 s of
//! silence and then drops the transfer without a word; the ACK tells the client at once.
//!
//! # Departures from PX4 (deliberate, friendlier, never stricter)
//! - A new `MISSION_COUNT` from the uploading client restarts its upload (PX4 answers
//!   `MAV_MISSION_ERROR` once an item has arrived, until its 5 s timeout).
//! - `MISSION_CLEAR_ALL` or `MISSION_REQUEST_LIST` from the uploading client abandons its
//!   upload and is served (PX4 ignores them while busy).
//! - Item requests are answered outside a download too (PX4 ignores them silently).
//! - A completed upload always yields [`MissionOutput::loaded`], even when identical to the
//!   stored mission (PX4 then keeps the active mission and its progress).
//!
//! # Caveats
//! - `now_s`: clients time out in wall-clock time (within a second or two). When the
//!   simulation runs much faster than real time, 0.25 s of sim time is little wall time and
//!   retries would burn out before a remote client could answer; drive this state machine
//!   with a clock that does not run far ahead of the wall.
//! - The item `current` flag of an upload (PX4: start the mission there) and
//!   `autocontinue = 0` (PX4: pause after the item) are stored and returned but not acted on.

// MISSION_ITEM, MISSION_REQUEST and the *_INT frame names are deprecated in the dialect, but
// PX4 and older clients still use them; handling them is the point of this module.
#![allow(deprecated)]

use ::mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA,
    MISSION_ITEM_REACHED_DATA, MISSION_REQUEST_DATA, MISSION_REQUEST_INT_DATA, MavCmd, MavFrame, MavMessage,
    MavMissionResult, MavMissionType, MissionState,
};
use nalgebra::Vector2;
use sadesim_crds::geo::LocalFrame;

use crate::autopilot::mission::{MissionItem, MissionPlan};

/// Time without the requested item after which the request is sent again, s (PX4
/// `MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT` = 250 ms; the spec's item timeout).
pub const RETRY_TIMEOUT_S: f64 = 0.25;
/// Re-sends of one request before the upload is cancelled (the spec's maximum).
pub const MAX_RETRIES: u32 = 5;
/// Silence after which a download is considered abandoned, s (PX4
/// `MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT` = 5 s).
pub const DOWNLOAD_TIMEOUT_S: f64 = 5.0;
/// Largest mission accepted; larger counts get `MAV_MISSION_NO_SPACE`. PX4 on flight
/// hardware stores 2000 (`NUM_MISSIONS_SUPPORTED`); SITL allows 65534, but a fleet of
/// thousands of drones should not let one client allocate that much per drone.
pub const MAX_MISSION_ITEMS: u16 = 2000;
/// `hold_s` of a `MAV_CMD_NAV_LOITER_UNLIM`: never elapses in the navigator's
/// `t - reached >= hold_s` test. `f64::MAX` rather than infinity because plans are
/// serialised as JSON, where infinity does not survive.
pub const HOLD_FOREVER_S: f64 = f64::MAX;
/// How far a `MAV_CMD_NAV_LAND` position may lie from where the previous item leaves the
/// drone and still be flown as "land here", m. The navigator lands where the drone is (one
/// [`MissionItem`] per MAVLink seq and no "fly there, then land" item), so a landing point
/// further away is refused rather than silently landed somewhere else.
pub const LAND_POSITION_TOLERANCE_M: f64 = 5.0;
/// `MAV_COMP_ID_MISSIONPLANNER`: PX4 accepts mission messages addressed to it too.
const COMP_ID_MISSIONPLANNER: u8 = 190;
/// `MAV_COMP_ID_ALL`.
const COMP_ID_ALL: u8 = 0;

/// A MAVLink peer: (system id, component id).
pub type Peer = (u8, u8);

/// What the conversion and the replies need to know about the drone.
#[derive(Clone, Copy, Debug)]
pub struct MissionContext<'a> {
    /// The run's local frame: lat/lon -> ENU east/north, m.
    pub frame: &'a LocalFrame,
    /// Altitude of the home position's ground, m AMSL (for `MAV_FRAME_GLOBAL(_INT)` items).
    pub home_alt_amsl_m: f64,
    /// Default horizontal mission speed, m/s (PX4 `MPC_XY_CRUISE`): the plan's speed and
    /// what `DO_CHANGE_SPEED` with speed -2 ("vehicle default") returns to.
    pub cruise_speed_mps: f64,
    /// The autopilot's current mission item, for the `current` flag of downloaded items.
    pub current_seq: u16,
    /// Our MAVLink system id: messages for other systems are ignored.
    pub our_system: u8,
    /// Our component id (the autopilot, 1); 0 (all) and 190 (mission planner) also match.
    pub our_component: u8,
}

/// What one message caused.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MissionOutput {
    /// Messages to send back (each addressed to the requester).
    pub replies: Vec<MavMessage>,
    /// A complete, accepted upload: load it into the autopilot (replacing its mission).
    pub loaded: Option<MissionPlan>,
    /// The mission was cleared (`MISSION_CLEAR_ALL`, or an upload of 0 items): remove the
    /// autopilot's mission.
    pub cleared: bool,
}

/// The mission protocol endpoint of one drone. See the module docs for the behaviour.
#[derive(Debug, Default)]
pub struct MissionProtocol {
    /// The stored mission, as uploaded.
    items: Vec<MISSION_ITEM_INT_DATA>,
    /// Opaque id of `items` (0 when empty).
    mission_id: u32,
    transfer: Transfer,
    /// The last completed upload, to re-acknowledge a repeated last item whose ACK was lost.
    last_upload: Option<CompletedUpload>,
}

#[derive(Debug, Default)]
enum Transfer {
    #[default]
    Idle,
    Upload(Upload),
    Download(Download),
}

#[derive(Debug)]
struct Upload {
    peer: Peer,
    count: u16,
    received: Vec<MISSION_ITEM_INT_DATA>,
    plan: PlanBuilder,
    /// Request items with MISSION_REQUEST_INT (true) or legacy MISSION_REQUEST.
    int_mode: bool,
    last_sent_s: f64,
    retries: u32,
}

impl Upload {
    fn next_seq(&self) -> u16 {
        u16::try_from(self.received.len()).unwrap_or(u16::MAX)
    }

    fn request(&self) -> MavMessage {
        request_msg(self.peer, self.next_seq(), self.int_mode)
    }
}

#[derive(Debug)]
struct Download {
    peer: Peer,
    last_recv_s: f64,
}

#[derive(Debug)]
struct CompletedUpload {
    peer: Peer,
    last_seq: u16,
}

impl MissionProtocol {
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of stored mission items (`MISSION_CURRENT.total`, `MISSION_COUNT`).
    pub fn count(&self) -> u16 {
        u16::try_from(self.items.len()).unwrap_or(u16::MAX)
    }

    /// The stored mission, as uploaded.
    pub fn items(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.items
    }

    /// Opaque id of the stored mission (CRC-32 of its items; 0 when there is none).
    pub fn mission_id(&self) -> u32 {
        self.mission_id
    }

    /// An upload or download is under way. PX4 ignores `MISSION_SET_CURRENT` meanwhile.
    pub fn transfer_in_progress(&self) -> bool {
        !matches!(self.transfer, Transfer::Idle)
    }

    /// `MISSION_CURRENT` as PX4 streams it: `total` is `u16::MAX` without a mission, the ids
    /// are this module's opaque ids (fence and rally: 0, none stored).
    /// `mission_mode`: 1 in mission mode, 2 suspended, 0 unknown.
    pub fn mission_current(&self, seq: u16, mission_state: MissionState, mission_mode: u8) -> MavMessage {
        let total = if self.items.is_empty() { u16::MAX } else { self.count() };
        MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq,
            total,
            mission_state,
            mission_mode,
            mission_id: self.mission_id,
            fence_id: 0,
            rally_points_id: 0,
        })
    }

    /// `MISSION_ITEM_REACHED` for item `seq`.
    pub fn item_reached(seq: u16) -> MavMessage {
        MavMessage::MISSION_ITEM_REACHED(MISSION_ITEM_REACHED_DATA { seq })
    }

    /// Handles one message from `from` (sysid, compid) received at `now_s`. Messages that
    /// are not mission protocol messages, or are addressed to another system or component,
    /// produce nothing.
    pub fn handle(&mut self, from: Peer, msg: &MavMessage, now_s: f64, ctx: &MissionContext) -> MissionOutput {
        self.expire_download(now_s);
        let to_us = |system: u8, component: u8| {
            system == ctx.our_system && [ctx.our_component, COMP_ID_ALL, COMP_ID_MISSIONPLANNER].contains(&component)
        };
        match msg {
            MavMessage::MISSION_COUNT(m) if to_us(m.target_system, m.target_component) => {
                self.on_count(from, m.count, m.mission_type, now_s, ctx)
            }
            MavMessage::MISSION_ITEM_INT(m) if to_us(m.target_system, m.target_component) => {
                self.on_item(from, m.clone(), true, now_s, ctx)
            }
            MavMessage::MISSION_ITEM(m) if to_us(m.target_system, m.target_component) => {
                self.on_item(from, legacy_to_int(m), false, now_s, ctx)
            }
            MavMessage::MISSION_REQUEST_LIST(m) if to_us(m.target_system, m.target_component) => {
                self.on_request_list(from, m.mission_type, now_s)
            }
            MavMessage::MISSION_REQUEST_INT(m) if to_us(m.target_system, m.target_component) => {
                self.on_request(from, m.seq, m.mission_type, true, now_s, ctx)
            }
            MavMessage::MISSION_REQUEST(m) if to_us(m.target_system, m.target_component) => {
                self.on_request(from, m.seq, m.mission_type, false, now_s, ctx)
            }
            MavMessage::MISSION_ACK(m) if to_us(m.target_system, m.target_component) => {
                self.on_ack(from, m.mavtype, m.mission_type)
            }
            MavMessage::MISSION_CLEAR_ALL(m) if to_us(m.target_system, m.target_component) => {
                self.on_clear(from, m.mission_type)
            }
            _ => MissionOutput::default(),
        }
    }

    /// Timers: re-sends an unanswered upload request every [`RETRY_TIMEOUT_S`], cancels the
    /// upload after [`MAX_RETRIES`] re-sends (`MISSION_ACK(OPERATION_CANCELLED)`), and
    /// forgets a download silent for [`DOWNLOAD_TIMEOUT_S`]. Call it regularly (every step
    /// or at least every 50 ms).
    pub fn poll(&mut self, now_s: f64) -> Vec<MavMessage> {
        self.expire_download(now_s);
        let Transfer::Upload(up) = &mut self.transfer else { return Vec::new() };
        if now_s - up.last_sent_s < RETRY_TIMEOUT_S {
            return Vec::new();
        }
        if up.retries >= MAX_RETRIES {
            let cancel = ack_msg(up.peer, MavMissionResult::MAV_MISSION_OPERATION_CANCELLED, mission(), 0);
            self.transfer = Transfer::Idle;
            return vec![cancel];
        }
        up.retries += 1;
        up.last_sent_s = now_s;
        vec![up.request()]
    }

    fn expire_download(&mut self, now_s: f64) {
        if let Transfer::Download(d) = &self.transfer
            && now_s - d.last_recv_s > DOWNLOAD_TIMEOUT_S
        {
            self.transfer = Transfer::Idle;
        }
    }

    /// Another client's upload is under way (or its download, which an upload would
    /// change under its feet).
    fn busy_with_other(&self, from: Peer) -> bool {
        match &self.transfer {
            Transfer::Idle => false,
            Transfer::Upload(u) => u.peer != from,
            Transfer::Download(d) => d.peer != from,
        }
    }

    fn clear_mission(&mut self) {
        self.items.clear();
        self.mission_id = 0;
        self.last_upload = None;
    }

    fn on_count(
        &mut self,
        from: Peer,
        count: u16,
        kind: MavMissionType,
        now_s: f64,
        ctx: &MissionContext,
    ) -> MissionOutput {
        let reply = |result| MissionOutput { replies: vec![ack_msg(from, result, kind, 0)], ..Default::default() };
        match kind {
            MavMissionType::MAV_MISSION_TYPE_FENCE | MavMissionType::MAV_MISSION_TYPE_RALLY => {
                // Nothing is stored: an empty plan is what we have, anything else we refuse.
                if count == 0 {
                    reply(MavMissionResult::MAV_MISSION_ACCEPTED)
                } else {
                    reply(MavMissionResult::MAV_MISSION_UNSUPPORTED)
                }
            }
            // ALL is only meaningful in MISSION_CLEAR_ALL; an empty upload of it is a clear.
            MavMissionType::MAV_MISSION_TYPE_ALL if count == 0 => self.on_clear(from, kind),
            MavMissionType::MAV_MISSION_TYPE_ALL => reply(MavMissionResult::MAV_MISSION_INVALID),
            MavMissionType::MAV_MISSION_TYPE_MISSION => {
                if self.busy_with_other(from) {
                    return reply(MavMissionResult::MAV_MISSION_ERROR);
                }
                // Whatever this client was doing, it has now started over.
                self.transfer = Transfer::Idle;
                if count == 0 {
                    self.clear_mission();
                    return MissionOutput { cleared: true, ..reply(MavMissionResult::MAV_MISSION_ACCEPTED) };
                }
                if count > MAX_MISSION_ITEMS {
                    return reply(MavMissionResult::MAV_MISSION_NO_SPACE);
                }
                let up = Upload {
                    peer: from,
                    count,
                    received: Vec::new(),
                    plan: PlanBuilder::new(ctx.cruise_speed_mps),
                    int_mode: true,
                    last_sent_s: now_s,
                    retries: 0,
                };
                let request = up.request();
                self.transfer = Transfer::Upload(up);
                MissionOutput { replies: vec![request], ..Default::default() }
            }
        }
    }

    fn on_item(
        &mut self,
        from: Peer,
        item: MISSION_ITEM_INT_DATA,
        int_mode: bool,
        now_s: f64,
        ctx: &MissionContext,
    ) -> MissionOutput {
        let reply = |msg| MissionOutput { replies: vec![msg], ..Default::default() };
        let uploading = matches!(&self.transfer, Transfer::Upload(u) if u.peer == from);
        if !uploading {
            // The client repeating the last item of a finished upload lost our ACK: repeat it.
            if let Some(last) = &self.last_upload
                && last.peer == from
                && last.last_seq == item.seq
                && item.mission_type == mission()
            {
                return reply(ack_msg(from, MavMissionResult::MAV_MISSION_ACCEPTED, mission(), self.mission_id));
            }
            return reply(ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, item.mission_type, 0));
        }
        let Transfer::Upload(mut up) = std::mem::take(&mut self.transfer) else { return MissionOutput::default() };
        if item.mission_type != mission() {
            // Errors end the transfer on both sides (spec); the stored mission is untouched.
            return reply(ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, mission(), 0));
        }
        up.int_mode = int_mode;
        up.last_sent_s = now_s;
        if item.seq != up.next_seq() {
            // Out of sequence (a duplicate, or one ahead of a lost item): drop it, ask again.
            let request = up.request();
            self.transfer = Transfer::Upload(up);
            return reply(request);
        }
        if let Err(result) = up.plan.push(&item, ctx) {
            return reply(ack_msg(from, result, mission(), 0));
        }
        up.received.push(item);
        up.retries = 0;
        if up.received.len() < usize::from(up.count) {
            let request = up.request();
            self.transfer = Transfer::Upload(up);
            return reply(request);
        }
        let last_seq = up.next_seq().saturating_sub(1);
        self.items = up.received;
        self.mission_id = opaque_id(&self.items);
        self.last_upload = Some(CompletedUpload { peer: from, last_seq });
        MissionOutput {
            replies: vec![ack_msg(from, MavMissionResult::MAV_MISSION_ACCEPTED, mission(), self.mission_id)],
            loaded: Some(up.plan.finish()),
            cleared: false,
        }
    }

    fn on_request_list(&mut self, from: Peer, kind: MavMissionType, now_s: f64) -> MissionOutput {
        let reply = |msg| MissionOutput { replies: vec![msg], ..Default::default() };
        if matches!(&self.transfer, Transfer::Upload(u) if u.peer != from) {
            return reply(ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, kind, 0));
        }
        if matches!(self.transfer, Transfer::Upload(_)) {
            // The uploading client gave up on its upload and now reads the mission instead.
            self.transfer = Transfer::Idle;
        }
        match kind {
            MavMissionType::MAV_MISSION_TYPE_MISSION => {
                if !self.items.is_empty() {
                    self.transfer = Transfer::Download(Download { peer: from, last_recv_s: now_s });
                }
                reply(count_msg(from, self.count(), kind, self.mission_id))
            }
            MavMissionType::MAV_MISSION_TYPE_FENCE | MavMissionType::MAV_MISSION_TYPE_RALLY => {
                reply(count_msg(from, 0, kind, 0))
            }
            MavMissionType::MAV_MISSION_TYPE_ALL => reply(ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, kind, 0)),
        }
    }

    fn on_request(
        &mut self,
        from: Peer,
        seq: u16,
        kind: MavMissionType,
        int_mode: bool,
        now_s: f64,
        ctx: &MissionContext,
    ) -> MissionOutput {
        let reply = |msg| MissionOutput { replies: vec![msg], ..Default::default() };
        let own_download = matches!(&self.transfer, Transfer::Download(d) if d.peer == from);
        if matches!(self.transfer, Transfer::Upload(_)) {
            return reply(ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, kind, 0));
        }
        let Some(stored) = self.items.get(usize::from(seq)).filter(|_| kind == mission()) else {
            if own_download {
                self.transfer = Transfer::Idle;
            }
            return reply(ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, kind, 0));
        };
        let mut item = stored.clone();
        item.target_system = from.0;
        item.target_component = from.1;
        item.mission_type = mission();
        item.current = u8::from(seq == ctx.current_seq);
        let msg =
            if int_mode { MavMessage::MISSION_ITEM_INT(item) } else { MavMessage::MISSION_ITEM(int_to_legacy(&item)) };
        if own_download {
            if usize::from(seq) + 1 >= self.items.len() {
                // All items sent: done even if the client's ACK never comes (PX4 does the same).
                self.transfer = Transfer::Idle;
            } else if let Transfer::Download(d) = &mut self.transfer {
                d.last_recv_s = now_s;
            }
        }
        reply(msg)
    }

    fn on_ack(&mut self, from: Peer, result: MavMissionResult, kind: MavMissionType) -> MissionOutput {
        match &mut self.transfer {
            Transfer::Upload(up) if up.peer == from && kind == mission() => match result {
                // PX4: the client cannot take this request form; switch INT <-> float.
                MavMissionResult::MAV_MISSION_UNSUPPORTED => {
                    up.int_mode = !up.int_mode;
                    return MissionOutput { replies: vec![up.request()], ..Default::default() };
                }
                MavMissionResult::MAV_MISSION_ACCEPTED => {}
                // Cancelled, or any error: the client has left the transfer.
                _ => self.transfer = Transfer::Idle,
            },
            // The end of a download, whatever the result.
            Transfer::Download(d) if d.peer == from => self.transfer = Transfer::Idle,
            _ => {}
        }
        MissionOutput::default()
    }

    fn on_clear(&mut self, from: Peer, kind: MavMissionType) -> MissionOutput {
        if matches!(&self.transfer, Transfer::Upload(u) if u.peer != from) {
            let replies = vec![ack_msg(from, MavMissionResult::MAV_MISSION_ERROR, kind, 0)];
            return MissionOutput { replies, ..Default::default() };
        }
        let mut out = MissionOutput {
            replies: vec![ack_msg(from, MavMissionResult::MAV_MISSION_ACCEPTED, kind, 0)],
            ..Default::default()
        };
        if matches!(kind, MavMissionType::MAV_MISSION_TYPE_MISSION | MavMissionType::MAV_MISSION_TYPE_ALL) {
            // Also ends any transfer: a download of a deleted mission has nothing left to read.
            self.transfer = Transfer::Idle;
            self.clear_mission();
            out.cleared = true;
        } else if matches!(self.transfer, Transfer::Upload(_)) {
            // Fence/rally clear from the uploading client: it abandoned the mission upload.
            self.transfer = Transfer::Idle;
        }
        out
    }
}

/// Converts a mission as stored (one `MISSION_ITEM_INT` per seq) into the autopilot's plan,
/// one [`MissionItem`] per seq so `MISSION_CURRENT` and `MISSION_ITEM_REACHED` numbers are
/// the client's own.
///
/// | MAVLink item | [`MissionItem`] |
/// |---|---|
/// | `NAV_WAYPOINT` (param1 hold s; NaN = 0) | `Waypoint` |
/// | `NAV_LOITER_TIME` (param1 s) at a position | `Waypoint` holding param1 |
/// | `NAV_LOITER_TIME` without position (lat/lon 0/0 or `INT32_MAX`) | `Loiter` |
/// | `NAV_LOITER_UNLIM` | as `LOITER_TIME` with [`HOLD_FOREVER_S`] |
/// | `NAV_TAKEOFF` (z = altitude; lat/lon ignored: climb in place) | `Takeoff` |
/// | `NAV_LAND` without position, or within [`LAND_POSITION_TOLERANCE_M`] of the previous item's target | `Land` |
/// | `NAV_RETURN_TO_LAUNCH` | `ReturnToLaunch` |
/// | `DO_CHANGE_SPEED` (param1 type 0/1, param2 m/s) | `ChangeSpeed` |
///
/// Positions: `x`/`y` are lat/lon in 1e-7 degrees in `MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT)`
/// (`z` above home) and `MAV_FRAME_GLOBAL(_INT)` (`z` AMSL, minus
/// [`MissionContext::home_alt_amsl_m`]). The non-INT frame names are accepted in
/// `MISSION_ITEM_INT` with the same 1e-7 encoding, as QGroundControl sends them and PX4 reads
/// them. `RETURN_TO_LAUNCH` and `DO_CHANGE_SPEED` carry no position and also accept
/// `MAV_FRAME_MISSION`.
///
/// `DO_CHANGE_SPEED` speed -1 ("no change") and 0 become a `ChangeSpeed` to the speed in
/// force at that point of the list (the default, or the last change before it), -2 to
/// [`MissionContext::cruise_speed_mps`]; climb/descent speed types (2, 3) keep the speed, as
/// the navigator flies fixed vertical speeds.
///
/// Ignored parameters: acceptance radius, yaw, pass radius, loiter radius, land abort
/// altitude and precision mode, and `LAND`'s altitude (the land detector finds the ground).
///
/// # Errors
/// The first refused item as `(seq, result)`: `MAV_MISSION_UNSUPPORTED` for any other
/// command, `MAV_MISSION_UNSUPPORTED_FRAME` for local, terrain-relative or other frames,
/// `MAV_MISSION_INVALID_PARAM5_X` / `PARAM6_Y` for latitude outside ±90° / longitude outside
/// ±180° (and for a `LAND` point away from the previous target), `PARAM7` for a non-finite
/// altitude or a takeoff altitude not above home, `PARAM1` / `PARAM2` for a negative or
/// non-finite hold time and an invalid speed type / speed.
pub fn to_plan(items: &[MISSION_ITEM_INT_DATA], ctx: &MissionContext) -> Result<MissionPlan, (u16, MavMissionResult)> {
    let mut plan = PlanBuilder::new(ctx.cruise_speed_mps);
    for (i, item) in items.iter().enumerate() {
        plan.push(item, ctx).map_err(|r| (u16::try_from(i).unwrap_or(u16::MAX), r))?;
    }
    Ok(plan.finish())
}

/// Altitude reference of a global frame.
#[derive(Clone, Copy, Debug)]
enum AltRef {
    /// Metres above home ground.
    Home,
    /// Metres AMSL.
    Amsl,
}

/// Builds a plan item by item, tracking what later items depend on.
#[derive(Debug)]
struct PlanBuilder {
    items: Vec<MissionItem>,
    /// The plan's default cruise speed, m/s.
    default_speed_mps: f64,
    /// Speed in force after the items so far, m/s (for DO_CHANGE_SPEED "no change").
    speed_mps: f64,
    /// Horizontal ENU position the items so far leave the drone at, if known, m.
    at_en_m: Option<Vector2<f64>>,
}

impl PlanBuilder {
    fn new(default_speed_mps: f64) -> Self {
        Self { items: Vec::new(), default_speed_mps, speed_mps: default_speed_mps, at_en_m: None }
    }

    fn finish(self) -> MissionPlan {
        MissionPlan { items: self.items, speed_mps: self.default_speed_mps }
    }

    fn push(&mut self, item: &MISSION_ITEM_INT_DATA, ctx: &MissionContext) -> Result<(), MavMissionResult> {
        use MavMissionResult as R;
        let converted = match item.command {
            MavCmd::MAV_CMD_NAV_WAYPOINT => {
                let hold_s = if item.param1.is_nan() { 0.0 } else { hold_time(item.param1)? };
                self.go_to(item, global(item)?, hold_s, ctx)?
            }
            MavCmd::MAV_CMD_NAV_LOITER_TIME => self.loiter(item, global(item)?, hold_time(item.param1)?, ctx)?,
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM => self.loiter(item, global(item)?, HOLD_FOREVER_S, ctx)?,
            MavCmd::MAV_CMD_NAV_TAKEOFF => {
                let alt_rel_home_m = altitude(item, global(item)?, ctx)?;
                if alt_rel_home_m <= 0.0 {
                    return Err(R::MAV_MISSION_INVALID_PARAM7);
                }
                // Climbs over wherever the drone is when the item starts: position unknown here.
                self.at_en_m = None;
                MissionItem::Takeoff { alt_rel_home_m }
            }
            MavCmd::MAV_CMD_NAV_LAND => {
                global(item)?;
                if !position_unset(item) {
                    let target = horizontal(item, ctx)?;
                    let near = self.at_en_m.is_some_and(|at| (at - target).norm() <= LAND_POSITION_TOLERANCE_M);
                    if !near {
                        return Err(R::MAV_MISSION_INVALID_PARAM5_X);
                    }
                }
                self.at_en_m = None;
                MissionItem::Land
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                positionless(item)?;
                self.at_en_m = None;
                MissionItem::ReturnToLaunch
            }
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
                positionless(item)?;
                self.change_speed(item)?
            }
            // Wait where the drone is (MAVSDK sends this for a mission item's
            // `loiter_time_s`). Only the relative delay (param1 >= 0) is supported; the
            // time-of-day form (param1 = -1 with hours/minutes/seconds) is refused.
            MavCmd::MAV_CMD_NAV_DELAY => MissionItem::Loiter { hold_s: hold_time(item.param1)? },
            _ => return Err(R::MAV_MISSION_UNSUPPORTED),
        };
        self.items.push(converted);
        Ok(())
    }

    fn go_to(
        &mut self,
        item: &MISSION_ITEM_INT_DATA,
        alt_ref: AltRef,
        hold_s: f64,
        ctx: &MissionContext,
    ) -> Result<MissionItem, MavMissionResult> {
        let target_en_m = horizontal(item, ctx)?;
        let alt_rel_home_m = altitude(item, alt_ref, ctx)?;
        self.at_en_m = Some(target_en_m);
        Ok(MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s })
    }

    /// A loiter at a position flies there first; without one it holds where the drone is
    /// (MAVLink: "NaN or INT32_MAX ... to use the component's current latitude").
    fn loiter(
        &mut self,
        item: &MISSION_ITEM_INT_DATA,
        alt_ref: AltRef,
        hold_s: f64,
        ctx: &MissionContext,
    ) -> Result<MissionItem, MavMissionResult> {
        if position_unset(item) { Ok(MissionItem::Loiter { hold_s }) } else { self.go_to(item, alt_ref, hold_s, ctx) }
    }

    fn change_speed(&mut self, item: &MISSION_ITEM_INT_DATA) -> Result<MissionItem, MavMissionResult> {
        let kind = item.param1;
        let horizontal = kind.is_nan() || kind == 0.0 || kind == 1.0;
        let vertical = kind == 2.0 || kind == 3.0;
        let v = f64::from(item.param2);
        let speed_mps = if vertical {
            self.speed_mps
        } else if !horizontal {
            return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
        } else if v.is_finite() && v > 0.0 {
            v
        } else if v == -2.0 {
            self.default_speed_mps
        } else if v == -1.0 || v == 0.0 {
            self.speed_mps
        } else {
            return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM2);
        };
        self.speed_mps = speed_mps;
        Ok(MissionItem::ChangeSpeed { speed_mps })
    }
}

/// The altitude reference of a positional item's frame; other frames are unsupported.
fn global(item: &MISSION_ITEM_INT_DATA) -> Result<AltRef, MavMissionResult> {
    global_alt_ref(item.frame).ok_or(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
}

/// Items without a position: `MAV_FRAME_MISSION` or any global frame (the frame is moot).
fn positionless(item: &MISSION_ITEM_INT_DATA) -> Result<(), MavMissionResult> {
    if item.frame == MavFrame::MAV_FRAME_MISSION || global_alt_ref(item.frame).is_some() {
        Ok(())
    } else {
        Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
    }
}

fn global_alt_ref(frame: MavFrame) -> Option<AltRef> {
    match frame {
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => Some(AltRef::Home),
        MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => Some(AltRef::Amsl),
        _ => None,
    }
}

/// Hold time in s: finite and non-negative.
fn hold_time(param: f32) -> Result<f64, MavMissionResult> {
    let s = f64::from(param);
    if s.is_finite() && s >= 0.0 { Ok(s) } else { Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1) }
}

/// MAVLink's "use the current position": lat/lon both 0, or `INT32_MAX`.
fn position_unset(item: &MISSION_ITEM_INT_DATA) -> bool {
    (item.x == 0 && item.y == 0) || item.x == i32::MAX || item.y == i32::MAX
}

/// Lat/lon (1e-7 degrees) -> ENU east/north from the run origin, m.
fn horizontal(item: &MISSION_ITEM_INT_DATA, ctx: &MissionContext) -> Result<Vector2<f64>, MavMissionResult> {
    let lat_deg = f64::from(item.x) * 1e-7;
    let lon_deg = f64::from(item.y) * 1e-7;
    if !(-90.0..=90.0).contains(&lat_deg) {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM5_X);
    }
    if !(-180.0..=180.0).contains(&lon_deg) {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y);
    }
    let (east_m, north_m) = ctx.frame.to_plane(lat_deg, lon_deg);
    Ok(Vector2::new(east_m, north_m))
}

/// `z` -> metres above home ground.
fn altitude(item: &MISSION_ITEM_INT_DATA, alt_ref: AltRef, ctx: &MissionContext) -> Result<f64, MavMissionResult> {
    let z = f64::from(item.z);
    if !z.is_finite() {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
    }
    Ok(match alt_ref {
        AltRef::Home => z,
        AltRef::Amsl => z - ctx.home_alt_amsl_m,
    })
}

/// A legacy `MISSION_ITEM` in the INT encoding: in global frames lat/lon degrees -> 1e-7
/// degrees (NaN, MAVLink's "current position" in float fields, -> `INT32_MAX`, its INT
/// spelling); elsewhere param5/6 rounded as they are. The frame is kept.
fn legacy_to_int(m: &MISSION_ITEM_DATA) -> MISSION_ITEM_INT_DATA {
    let global = global_alt_ref(m.frame).is_some();
    // `as` saturates: out-of-range degrees become ±INT32_MAX and fail the range check later.
    let encode = |v: f32| match (global, v.is_finite()) {
        (true, true) => (f64::from(v) * 1e7).round() as i32,
        (true, false) => i32::MAX,
        (false, _) => f64::from(v).round() as i32,
    };
    MISSION_ITEM_INT_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x: encode(m.x),
        y: encode(m.y),
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: m.target_system,
        target_component: m.target_component,
        frame: m.frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}

/// The stored item as a legacy `MISSION_ITEM`: float lat/lon degrees in the non-INT frame.
fn int_to_legacy(m: &MISSION_ITEM_INT_DATA) -> MISSION_ITEM_DATA {
    let frame = match m.frame {
        MavFrame::MAV_FRAME_GLOBAL_INT => MavFrame::MAV_FRAME_GLOBAL,
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        other => other,
    };
    let global = global_alt_ref(m.frame).is_some();
    let decode = |v: i32| match (global, v == i32::MAX) {
        (true, true) => f32::NAN,
        (true, false) => (f64::from(v) * 1e-7) as f32,
        (false, _) => v as f32,
    };
    MISSION_ITEM_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x: decode(m.x),
        y: decode(m.y),
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: m.target_system,
        target_component: m.target_component,
        frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}

fn mission() -> MavMissionType {
    MavMissionType::MAV_MISSION_TYPE_MISSION
}

fn ack_msg(to: Peer, result: MavMissionResult, kind: MavMissionType, opaque_id: u32) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: to.0,
        target_component: to.1,
        mavtype: result,
        mission_type: kind,
        opaque_id,
    })
}

fn count_msg(to: Peer, count: u16, kind: MavMissionType, opaque_id: u32) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count,
        target_system: to.0,
        target_component: to.1,
        mission_type: kind,
        opaque_id,
    })
}

/// Upload requests are always for the mission (fence and rally uploads are refused).
fn request_msg(to: Peer, seq: u16, int_mode: bool) -> MavMessage {
    let (target_system, target_component, mission_type) = (to.0, to.1, mission());
    if int_mode {
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA { seq, target_system, target_component, mission_type })
    } else {
        MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA { seq, target_system, target_component, mission_type })
    }
}

/// Opaque id of a mission: CRC-32 (IEEE) over each item's frame, command, autocontinue,
/// params 1–4, x, y, z (little-endian), the fields PX4 hashes. Never 0 for a non-empty
/// mission, since 0 means "no mission / ids unsupported".
fn opaque_id(items: &[MISSION_ITEM_INT_DATA]) -> u32 {
    if items.is_empty() {
        return 0;
    }
    let crc = items.iter().fold(0, |crc, m| {
        let mut bytes = Vec::with_capacity(32);
        bytes.push(m.frame as u8);
        bytes.extend_from_slice(&(m.command as u16).to_le_bytes());
        bytes.push(m.autocontinue);
        for p in [m.param1, m.param2, m.param3, m.param4] {
            bytes.extend_from_slice(&p.to_le_bytes());
        }
        bytes.extend_from_slice(&m.x.to_le_bytes());
        bytes.extend_from_slice(&m.y.to_le_bytes());
        bytes.extend_from_slice(&m.z.to_le_bytes());
        crc32(crc, &bytes)
    });
    crc.max(1)
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320), continuing from `crc` (0 to start)
/// like zlib's `crc32()`, so hashing in pieces equals hashing the concatenation.
fn crc32(crc: u32, bytes: &[u8]) -> u32 {
    let mut c = !crc;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            let mask = (c & 1).wrapping_neg();
            c = (c >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !c
}

#[cfg(test)]
mod tests;
