//! The MAVLink mission protocol of one drone (<https://mavlink.io/en/services/mission.html>)
//! as PX4 speaks it to MAVSDK, QGroundControl and pymavlink: upload, download and clear.
//!
//! A pure state machine in the style of the session: messages and the time go in, replies
//! and (when an upload completes) a [`MissionPlan`](crate::autopilot::mission::MissionPlan)
//! for the autopilot come out. No sockets, no clock: `now_s` is whatever monotonic clock the
//! caller drives it with, in seconds.
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

mod convert;
mod download;
mod endpoint;
mod messages;
mod upload;

pub use convert::{HOLD_FOREVER_S, LAND_POSITION_TOLERANCE_M, to_plan};
pub use endpoint::{
    DOWNLOAD_TIMEOUT_S, MAX_MISSION_ITEMS, MAX_RETRIES, MissionContext, MissionOutput, MissionProtocol, Peer,
    RETRY_TIMEOUT_S,
};

// What the tests reach through `use super::*` besides the public API.
#[cfg(test)]
use crate::autopilot::mission::{MissionItem, MissionPlan};
#[cfg(test)]
use messages::{crc32, opaque_id};

#[cfg(test)]
mod tests;
