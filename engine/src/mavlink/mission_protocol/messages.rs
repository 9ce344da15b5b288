//! Mission protocol messages as sent (ACK, COUNT, item requests) and the missions' opaque
//! ids (CRC-32 over the items).

use ::mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_DATA, MISSION_REQUEST_INT_DATA,
    MavMessage, MavMissionResult, MavMissionType,
};

use super::endpoint::Peer;

pub(super) fn mission() -> MavMissionType {
    MavMissionType::MAV_MISSION_TYPE_MISSION
}

pub(super) fn ack_msg(to: Peer, result: MavMissionResult, kind: MavMissionType, opaque_id: u32) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: to.0,
        target_component: to.1,
        mavtype: result,
        mission_type: kind,
        opaque_id,
    })
}

pub(super) fn count_msg(to: Peer, count: u16, kind: MavMissionType, opaque_id: u32) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count,
        target_system: to.0,
        target_component: to.1,
        mission_type: kind,
        opaque_id,
    })
}

/// Upload requests are always for the mission (fence and rally uploads are refused).
pub(super) fn request_msg(to: Peer, seq: u16, int_mode: bool) -> MavMessage {
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
pub(super) fn opaque_id(items: &[MISSION_ITEM_INT_DATA]) -> u32 {
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
pub(super) fn crc32(crc: u32, bytes: &[u8]) -> u32 {
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
