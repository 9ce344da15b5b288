//! A shard's MAVLink I/O: the drones' sockets ([`ShardSockets`]) and the thread that
//! carries the shard core's queues to them ([`MavlinkThread`]). Used by in-process shard
//! threads (`transport::spawn_thread`) and the `sim-worker shard` role alike.

mod io_thread;
mod sockets;

pub use io_thread::MavlinkThread;
pub use sockets::{MavlinkOptions, ShardSockets, StartError};

use sadesim_crds::plan::RunPlan;
use sadesim_engine::shard::{Shard, Surroundings};

/// Builds shard `index` of `plan` in `surroundings` and, with `mavlink`, opens its drones'
/// sockets on a thread of their own: how every shard starts, on a thread of `sadesim run`
/// or in a `sim-worker shard` process, before it serves the protocol.
///
/// # Errors
/// The shard cannot be built (its plan, its airframes, its surroundings) or an endpoint
/// cannot bind.
pub fn start(
    plan: &RunPlan,
    index: u32,
    surroundings: &Surroundings,
    mavlink: Option<&MavlinkOptions>,
) -> Result<(Shard, Option<MavlinkThread>), StartError> {
    let mut shard = Shard::new(plan, index, surroundings)?;
    let sockets = mavlink
        .map(|options| ShardSockets::open(&mut shard, plan, options))
        .transpose()?
        .map(|sockets| MavlinkThread::spawn(sockets, format!("shard-{index}-mavlink")));
    Ok((shard, sockets))
}
