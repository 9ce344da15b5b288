//! A recorded run's 3D replay: the live view's page on the run's `recording.mcap`,
//! `events.jsonl` and world (`sadesim view`, and `/replay/<id>/` in the console).

use std::sync::Arc;

use sadesim_crds::outcome::run_folder;
use sadesim_crds::plan::RunPlan;
use sadesim_world::World;
use sim_worker::view::{self, Content, Source};

/// What a replay holds, for the line that announces it.
#[derive(Debug, Clone)]
pub struct Replay {
    pub content: Content,
    pub plan: RunPlan,
    pub end_s: f64,
    pub frames: usize,
    /// Drawn on flat ground: the run's own world was not found.
    pub flat_ground: bool,
}

/// The replay of a run whose files `read` returns (by name in the run folder), resampled at
/// `rate_hz` frames per simulated second.
///
/// # Errors
/// A build without three.js, a missing `plan.json`, `events.jsonl` or `recording.mcap` (a
/// run recorded with `spec.recording.mcap: false` has no poses to replay), or damaged files.
pub fn replay(read: &dyn Fn(&str) -> Result<Vec<u8>, String>, rate_hz: f64) -> Result<Replay, String> {
    if !view::server::has_three() {
        return Err(view::server::NO_THREE.into());
    }
    let plan: RunPlan = serde_json::from_slice(&read(run_folder::PLAN)?)
        .map_err(|e| format!("{}: not a run plan: {e}", run_folder::PLAN))?;
    let mcap = read("recording.mcap").map_err(|e| {
        format!("{e} (the run needs recording.mcap for its poses: spec.recording.mcap must not be false)")
    })?;
    let events =
        String::from_utf8(read(run_folder::EVENTS)?).map_err(|e| format!("{}: not UTF-8: {e}", run_folder::EVENTS))?;
    let names: Vec<String> = plan.drones.iter().map(|d| d.name.clone()).collect();
    let replay = view::replay::replay(&mcap, &events, &names, rate_hz).map_err(|e| e.to_string())?;
    // The run's own world only: the bundle of its key, or rebuilt from its files, and
    // checked against the statistics the run wrote (another city's buildings would lie).
    let recorded: Option<serde_json::Value> =
        read("world.json").ok().and_then(|bytes| serde_json::from_slice(&bytes).ok());
    let world: Option<World> = sadesim_sources::assets::find_world(&plan)
        .filter(|w| recorded.as_ref().is_some_and(|r| serde_json::to_value(w.stats()).ok().as_ref() == Some(r)));
    let glb = world.as_ref().map(|w| Arc::new(sadesim_sources::gltf::world_glb(w, plan.spec.origin.geo())));
    let scene = view::scene::scene(&plan, world.as_ref(), "replay", glb.is_some());
    let content = Content {
        scene_json: Arc::new(serde_json::to_vec(&scene).expect("a scene is JSON")),
        world_glb: glb,
        source: Source::Replay(Arc::new(serde_json::to_vec(&replay).expect("a replay is JSON"))),
        frames: None,
    };
    Ok(Replay { content, plan, end_s: replay.end_s, frames: replay.frames.len(), flat_ground: world.is_none() })
}
