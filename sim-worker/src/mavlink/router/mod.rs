//! The MAVLink router of one segment (DESIGN §3): one GCS-facing endpoint (UDP and TCP)
//! multiplexing every drone of the segment, like mavlink-router or MAVProxy but small.
//!
//! Why it exists: every simulated drone has its own endpoint port, but a ground station
//! (QGroundControl) connects to one address and tells vehicles apart by system id. The
//! planner gives the drones of a segment distinct system ids (1..=250), so one router per
//! segment can merge their streams without rewriting anything.
//!
//! # How it works
//! - **Drone side**: one UDP socket on an ephemeral port. A drone endpoint sends its
//!   telemetry to every peer that has sent it a datagram, so the router registers by
//!   sending its own HEARTBEAT to every endpoint once a second (which also re-registers
//!   after a drone's endpoint restarts). Frames from the endpoints go to every GCS client
//!   unchanged; only the router's own heartbeat (should a drone echo it) and bad frames are
//!   taken out. Frames of datagrams that arrive together (a shard sends all its drones'
//!   telemetry at once) share datagrams of up to 1 400 bytes, sent when no datagram came
//!   for 1 ms (at most 5 ms after the first): one send per shared datagram instead of one
//!   per drone, for the router and for each ground station.
//! - **GCS side**: UDP clients are whoever sent a valid frame to the GCS UDP port, at most
//!   [`MAX_UDP_GCS`]: a client keeps its place while it is heard within
//!   [`UDP_GCS_LIVENESS`] (5 s; ground stations heartbeat at 1 Hz); a newcomer while all
//!   places are live is refused (its frames go nowhere, it gets no telemetry; counted in
//!   [`RouterStats::refused_udp_gcs_frames`] and logged like garbage), and takes the place of
//!   a client silent for longer than that. TCP clients are connections on the GCS TCP port
//!   (at most [`MAX_TCP_GCS`]; further ones are closed at once). Their frames go to the drone whose system id
//!   is the message's `target_system`, to every drone when the target is 0 or the message
//!   has none, and nowhere (counted) for a system id outside the segment. Each GCS also
//!   receives the other GCS clients' frames, so two ground stations see each other, as
//!   with mavlink-router.
//! - **Garbage** from a ground station (bytes that start no MAVLink 2 frame, frames with a
//!   bad checksum) is dropped, counted ([`RouterStats::garbage_bytes`],
//!   [`RouterStats::bad_checksum`]) and logged on stderr: the first from an address at once,
//!   naming the address, the offending byte and its offset, and why it starts no frame;
//!   then a sum every 10 s. Good frames before and after it still go through, and the
//!   other ground stations are not affected.
//!
//! Frames are forwarded byte for byte, never re-encoded: sequence numbers, signatures and
//! extension fields survive, and a frame costs one checksum check and a copy.
//!
//! # Signing
//! With a key ([`RouterConfig::signing`], `spec.groundStations.signing`), the GCS side speaks
//! signed MAVLink 2 only (<https://mavlink.io/en/guide/message_signing.html>):
//! - A ground station's frame is taken only when signed with the key, with a timestamp after
//!   the last one of its stream (link id, system id, component id); others are dropped,
//!   counted ([`RouterStats::refused_unsigned`] and the next two) and logged on stderr, the
//!   first per source address at once, then a sum every 10 s (as for garbage). A UDP sender becomes a client
//!   only with a frame that passes.
//! - Drone frames are signed on their way to the ground stations (flag set, CRC recomputed,
//!   link id [`ROUTER_LINK_ID`], timestamps from the wall clock, strictly increasing).
//!   Frames from one ground station reach the others as they came, signed by their sender,
//!   except SETUP_SIGNING, which carries the key in plain text and goes nowhere.
//! - The drone side stays unsigned: it is inside the run.
//!
//! Signing authenticates, it does not encrypt: a TCP client that connects still reads the
//! telemetry. `spec.groundStations.allowFrom` limits who can connect at all.
//!
//! # Threads
//! Plain std threads with blocking sockets and short read timeouts ([`POLL`]), so
//! [`RouterHandle::stop`] returns within about 100 ms: one for the drone side, one for GCS
//! UDP, one accepting TCP, and per TCP client a reader and a writer. The writer drains a
//! bounded queue, so a stalled TCP client loses whole datagrams (counted) instead of
//! stalling telemetry for everyone else.
//!
//! # Caveats
//! - The router's heartbeat is `MAV_TYPE_ONBOARD_CONTROLLER`, not `MAV_TYPE_GCS`, so it
//!   cannot keep a drone's GCS-link-loss failsafe from triggering: only a real GCS's
//!   heartbeats (forwarded to every drone) count as a ground station.
//! - Within one GCS datagram, frames keep their order per drone; frames to different drones
//!   are sent as separate datagrams.
//! - With signing, two ground stations that use the same system id, component id and link
//!   id at once share one replay stream, so each loses the frames whose timestamps fall
//!   behind the other's: give each its own system id (as MAVLink requires anyway).
//!
//! # Layout
//! `config` (what a router serves, its limits, errors and counters), `handle` (start and
//! stop), `routing_table` (the state the threads share and how a frame is routed),
//! `gcs_signing` (signing state), `refusal_log` (the bounded log of what was dropped from
//! ground stations), `sockets` (the threads), `tests` (against real sockets on loopback).

mod config;
mod gcs_signing;
mod handle;
mod refusal_log;
mod routing_table;
mod sockets;

pub use config::{
    MAX_DRONES, MAX_TCP_GCS, MAX_UDP_GCS, POLL, ROUTER_COMPONENT_ID, ROUTER_SYSTEM_ID, RoutedDrone, RouterConfig,
    RouterError, RouterStats, UDP_GCS_LIVENESS,
};
pub use gcs_signing::ROUTER_LINK_ID;
pub use handle::{RouterHandle, start};

#[cfg(test)]
mod tests;
