//! The shard core's MAVLink boundary: every drone's session reads the frames that arrived
//! for it from an inbound queue and writes what it sends to an outbound queue. The queues
//! belong to the shard; whatever moves them to and from the network (the sockets of
//! `sim_worker::shard_io::ShardSockets`, or nothing at all in tests) implements [`MavlinkIo`] and
//! is called by [`super::Shard::advance_with`] at fixed points of a window, so the core
//! never waits on a socket.
//!
//! When the I/O side runs, relative to the windows, is told at [`MavlinkIo`].

use crate::mavlink::frame::Frame;
use crate::mavlink::session::Outgoing;

/// One drone's MAVLink traffic between two visits of the I/O side.
///
/// Every outbound message is for every peer of the drone: its endpoint's UDP and TCP
/// clients and its API link (MAVLink broadcast, as PX4's streams; the API link's own
/// back-off while nobody listens is the endpoint's business). Replies to one client are no
/// exception, as on PX4.
#[derive(Debug, Default)]
pub struct MavlinkQueues {
    /// Checksummed frames from the drone's peers, oldest first; the session empties it at
    /// the next exchange.
    pub inbound: Vec<Frame>,
    /// Messages the session built (telemetry when due, replies), oldest first; the I/O side
    /// empties it after every window.
    pub outbound: Vec<Outgoing>,
}

/// What carries the shard's MAVLink queues to the network (index in the slices = the
/// drone's position in the shard).
///
/// # When the I/O runs (the timing MAVLink clients see)
/// At the end of every window the core builds each drone's due telemetry. Every
/// [`MAVLINK_IO_PERIOD_S`](super::MAVLINK_IO_PERIOD_S) of sim time that window end is also an *exchange*:
/// 1. [`MavlinkIo::receive`] fills the inbound queues (what peers sent since the last one);
/// 2. each session handles its inbound frames (commands act on the autopilot) and builds
///    its telemetry and replies into its outbound queue;
/// 3. [`MavlinkIo::send`] takes the outbound queues, with `flush` set: everything leaves.
///
/// At the other window ends only 2 (without frames) and 3 (with `flush` unset: the I/O side
/// encodes what was built, and sends it at the next exchange) run.
pub trait MavlinkIo {
    /// At an exchange, before the sessions act: appends what arrived for each drone to its
    /// `inbound` queue.
    fn receive(&mut self, queues: &mut [MavlinkQueues]);
    /// After every window: takes each drone's `outbound` queue (leaving it empty); when
    /// `flush` (an exchange), sends everything taken so far.
    fn send(&mut self, queues: &mut [MavlinkQueues], flush: bool);
    /// At the end of the run: everything taken so far leaves. Returns the CPU seconds the
    /// I/O spent on threads of its own (none by default), so the shard's cost counts it.
    fn finish(&mut self) -> f64 {
        0.0
    }
}

/// No network: the queues are left as they are (a test, or a shard without MAVLink). The
/// outbound queues then grow until someone empties them.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoMavlinkIo;

impl MavlinkIo for NoMavlinkIo {
    fn receive(&mut self, _queues: &mut [MavlinkQueues]) {}
    fn send(&mut self, _queues: &mut [MavlinkQueues], _flush: bool) {}
}

/// Sockets when there are some: `None` is [`NoMavlinkIo`].
impl<T: MavlinkIo> MavlinkIo for Option<T> {
    fn receive(&mut self, queues: &mut [MavlinkQueues]) {
        if let Some(io) = self {
            io.receive(queues);
        }
    }
    fn send(&mut self, queues: &mut [MavlinkQueues], flush: bool) {
        if let Some(io) = self {
            io.send(queues, flush);
        }
    }
    fn finish(&mut self) -> f64 {
        self.as_mut().map_or(0.0, MavlinkIo::finish)
    }
}
