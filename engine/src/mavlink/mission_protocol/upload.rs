//! Upload (client -> drone): the upload state and the `MISSION_COUNT` / `MISSION_ITEM(_INT)`
//! handlers that request, convert and store items.

use ::mavlink::dialects::common::{MISSION_ITEM_INT_DATA, MavMessage, MavMissionResult, MavMissionType};

use super::convert::PlanBuilder;
use super::endpoint::{MAX_MISSION_ITEMS, MissionContext, MissionOutput, MissionProtocol, Peer, Transfer};
use super::messages::{ack_msg, mission, opaque_id, request_msg};

#[derive(Debug)]
pub(super) struct Upload {
    pub(super) peer: Peer,
    pub(super) count: u16,
    pub(super) received: Vec<MISSION_ITEM_INT_DATA>,
    pub(super) plan: PlanBuilder,
    /// Request items with MISSION_REQUEST_INT (true) or legacy MISSION_REQUEST.
    pub(super) int_mode: bool,
    pub(super) last_sent_s: f64,
    pub(super) retries: u32,
}

impl Upload {
    pub(super) fn next_seq(&self) -> u16 {
        u16::try_from(self.received.len()).unwrap_or(u16::MAX)
    }

    pub(super) fn request(&self) -> MavMessage {
        request_msg(self.peer, self.next_seq(), self.int_mode)
    }
}

#[derive(Debug)]
pub(super) struct CompletedUpload {
    pub(super) peer: Peer,
    pub(super) last_seq: u16,
}

impl MissionProtocol {
    pub(super) fn on_count(
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

    pub(super) fn on_item(
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
}
