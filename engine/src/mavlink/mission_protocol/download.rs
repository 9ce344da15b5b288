//! Download (drone -> client): the download state and the `MISSION_REQUEST_LIST` /
//! `MISSION_REQUEST(_INT)` handlers that send the stored items.

use ::mavlink::dialects::common::{MavMessage, MavMissionResult, MavMissionType};

use super::convert::int_to_legacy;
use super::endpoint::{MissionContext, MissionOutput, MissionProtocol, Peer, Transfer};
use super::messages::{ack_msg, count_msg, mission};

#[derive(Debug)]
pub(super) struct Download {
    pub(super) peer: Peer,
    pub(super) last_recv_s: f64,
}

impl MissionProtocol {
    pub(super) fn on_request_list(&mut self, from: Peer, kind: MavMissionType, now_s: f64) -> MissionOutput {
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

    pub(super) fn on_request(
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
}
