//! `sim-worker renderer`: the renderer pod of a run with `spec.rendering.enabled`. It
//! follows the coordinator's live stream ([`crate::view::relay`]) and serves the live view
//! to any number of browsers ([`crate::view::server`]).

use std::net::SocketAddr;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use sadesim_crds::plan::RunPlan;
use sadesim_world::World;

use super::RoleError;

/// Wait between two attempts to reach the coordinator's stream.
const RETRY: Duration = Duration::from_secs(1);

/// Serves the view on `listen` and follows `feed` (`host:port` of the coordinator's
/// `--view-bind`) until `stop`.
///
/// # Errors
/// The build has no three.js, or `listen` cannot be bound.
pub fn run(plan: &RunPlan, world: &World, listen: SocketAddr, feed: &str, stop: &AtomicBool) -> Result<(), RoleError> {
    if !plan.spec.rendering().enabled {
        return Err(RoleError::Protocol("spec.rendering.enabled is false: this run has no renderer".into()));
    }
    let live = crate::view::serve_live(plan, world, listen, None).map_err(RoleError::Protocol)?;
    eprintln!("renderer: serving {} (following {feed})", live.server.url());
    crate::view::relay::follow_forever(feed, &live.feed, stop, RETRY, &mut |line| eprintln!("renderer: {line}"));
    Ok(())
}
