//! A shard's MAVLink I/O: the drones' sockets ([`ShardSockets`]) and the thread that
//! carries the shard core's queues to them ([`MavlinkThread`]). Used by in-process shard
//! threads (`transport::spawn_thread`) and the `sim-worker shard` role alike.

mod io_thread;
mod sockets;

pub use io_thread::MavlinkThread;
pub use sockets::{MavlinkOptions, ShardSockets, StartError};
