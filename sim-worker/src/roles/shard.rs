//! `sim-worker shard`: builds one shard from the plan, connects to the coordinator and
//! serves the protocol until told to stop.

use std::net::TcpStream;
use std::sync::Arc;
use std::time::{Duration, Instant};

use sadesim_crds::plan::RunPlan;

use super::RoleError;
use crate::shard::Shard;
use crate::transport;
use crate::world::{World, WorldInputs};

/// How long a shard keeps trying to reach a coordinator that is not up yet.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);

/// Runs shard `index` of `plan` against the coordinator at `coordinator` (host:port).
///
/// # Errors
/// When the shard cannot be built or the coordinator cannot be reached.
pub fn run(
    plan: &RunPlan,
    index: u32,
    coordinator: &str,
    mavlink: Option<&crate::shard::MavlinkOptions>,
) -> Result<(), RoleError> {
    // The world is deterministic from the plan's inputs, so every shard builds the same
    // one (the assets role will fetch it from the cache instead).
    let world = Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])));
    let mut shard = Shard::new(plan, index, world)?;
    if let Some(options) = mavlink {
        shard.open_mavlink(plan, options)?;
    }
    let started = Instant::now();
    let stream = loop {
        match TcpStream::connect(coordinator) {
            Ok(s) => break s,
            Err(e) if started.elapsed() < CONNECT_TIMEOUT => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(100));
            }
            Err(e) => return Err(RoleError::Io(e)),
        }
    };
    transport::serve_tcp(shard, stream)?;
    Ok(())
}
