//! The mission protocol endpoint of one drone: its stored mission, the transfer under way,
//! message dispatch, timers, acknowledgements and clears.

use ::mavlink::dialects::common::{
    MISSION_CURRENT_DATA, MISSION_ITEM_INT_DATA, MISSION_ITEM_REACHED_DATA, MavMessage, MavMissionResult,
    MavMissionType, MissionState,
};
use sadesim_crds::geo::LocalFrame;

use crate::autopilot::mission::MissionPlan;

use super::convert::legacy_to_int;
use super::download::Download;
use super::messages::{ack_msg, mission};
use super::upload::{CompletedUpload, Upload};

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
/// `MAV_COMP_ID_MISSIONPLANNER`: PX4 accepts mission messages addressed to it too.
pub(super) const COMP_ID_MISSIONPLANNER: u8 = 190;
/// `MAV_COMP_ID_ALL`.
pub(super) const COMP_ID_ALL: u8 = 0;

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
    pub(super) items: Vec<MISSION_ITEM_INT_DATA>,
    /// Opaque id of `items` (0 when empty).
    pub(super) mission_id: u32,
    pub(super) transfer: Transfer,
    /// The last completed upload, to re-acknowledge a repeated last item whose ACK was lost.
    pub(super) last_upload: Option<CompletedUpload>,
}

#[derive(Debug, Default)]
pub(super) enum Transfer {
    #[default]
    Idle,
    Upload(Upload),
    Download(Download),
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

    pub(super) fn expire_download(&mut self, now_s: f64) {
        if let Transfer::Download(d) = &self.transfer
            && now_s - d.last_recv_s > DOWNLOAD_TIMEOUT_S
        {
            self.transfer = Transfer::Idle;
        }
    }

    /// Another client's upload is under way (or its download, which an upload would
    /// change under its feet).
    pub(super) fn busy_with_other(&self, from: Peer) -> bool {
        match &self.transfer {
            Transfer::Idle => false,
            Transfer::Upload(u) => u.peer != from,
            Transfer::Download(d) => d.peer != from,
        }
    }

    pub(super) fn clear_mission(&mut self) {
        self.items.clear();
        self.mission_id = 0;
        self.last_upload = None;
    }

    pub(super) fn on_ack(&mut self, from: Peer, result: MavMissionResult, kind: MavMissionType) -> MissionOutput {
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

    pub(super) fn on_clear(&mut self, from: Peer, kind: MavMissionType) -> MissionOutput {
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
