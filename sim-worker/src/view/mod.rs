//! The visual simulator's browser side (issue 18): a live 3D view of a running simulation
//! and the replay of a recorded one, served over HTTP by the renderer role (in-process in
//! `sadesim run`, `sim-worker renderer` on a cluster) and by `sadesim view`.
//!
//! - [`feed`]: the coordinator's merged poses and events, published to any number of
//!   browsers without ever waiting for one;
//! - [`scene`]: what does not move (drones and their group colours, zones as volumes);
//! - [`replay`]: a run folder's `recording.mcap` and `events.jsonl` as the same frames;
//! - [`server`]: the page (`sim-worker/web/`), three.js from npm (embedded at build time),
//!   the world's glTF from the asset bundle, the stream.

pub mod feed;
pub mod frames;
pub mod relay;
pub mod replay;
pub mod scene;
pub mod server;

pub use feed::{Feed, Publisher};
pub use server::{Content, Source, ViewHandle};

use std::net::SocketAddr;
use std::sync::Arc;

use sadesim_crds::plan::RunPlan;
use sadesim_world::World;

/// What [`serve_live`] started: the server and the feed the coordinator publishes into.
#[derive(Debug)]
pub struct LiveView {
    pub server: ViewHandle,
    pub feed: Arc<Feed>,
}

/// Serves the live view of `plan` flying in `world` on `bind` (with the onboard cameras'
/// `frames` when the run has cameras), or on a free port of the
/// same host when that port is taken (another run on this machine); the world model is
/// the bundle's `world.glb`, made from the loaded world by the same function (same bytes).
///
/// # Errors
/// The build has no three.js, or no port of the host can be bound.
pub fn serve_live(
    plan: &RunPlan,
    world: &World,
    bind: SocketAddr,
    frames: Option<Arc<frames::FrameStore>>,
) -> Result<LiveView, String> {
    if !server::has_three() {
        return Err(server::NO_THREE.into());
    }
    let feed = Feed::new();
    let glb = sadesim_sources::gltf::world_glb(world, plan.spec.origin.geo());
    let scene = scene::scene(plan, Some(world), "live", true);
    let content = Content {
        scene_json: Arc::new(serde_json::to_vec(&scene).expect("a scene is JSON")),
        world_glb: Some(Arc::new(glb)),
        source: Source::Live(feed.clone()),
        frames,
    };
    let server = crate::http_thread::or_free_port(bind, |addr| server::start(addr, content.clone()))
        .map_err(|e| format!("live view: cannot listen on {bind}: {e}"))?;
    Ok(LiveView { server, feed })
}
