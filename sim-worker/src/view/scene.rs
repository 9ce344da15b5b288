//! What the page draws that does not move: the run, its drones with their group colours,
//! and the zones as volumes. Pure (plan + world in, JSON out), served as `/scene.json`.
//!
//! Frame: world ENU metres from the run origin (x east, y north, z up from the origin's
//! ground), as everywhere else; the page maps it onto three.js's Y-up frame exactly as the
//! bundle's `world.glb` does (`x = e, y = u, z = -n`).

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_world::World;
use serde::Serialize;

use sadesim_engine::airspace::volume::ZoneVolume;

/// Group colours, in `spec.fleet` order, repeating after ten (Tableau 10: distinct on a grey
/// city and for the common colour-vision deficiencies). None is the zones' pink.
pub const GROUP_COLOURS: [&str; 10] =
    ["#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#76b7b2", "#edc948", "#b07aa1", "#9c755f", "#bab0ac", "#17becf"];

/// The zones' colour: the paper's translucent pink SADE Zone volumes.
pub const ZONE_COLOUR: &str = "#ff4fa3";

/// `/scene.json`.
#[derive(Serialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Scene {
    pub run: String,
    pub namespace: String,
    /// `live` (a running simulation) or `replay` (a recorded run).
    pub mode: &'static str,
    /// The run origin: WGS84 degrees and metres above mean sea level.
    pub origin: [f64; 3],
    /// Planned duration, simulated seconds.
    pub duration_s: f64,
    /// Half-width of the square world around the origin, m (the free camera's range).
    pub world_extent_m: f64,
    /// Whether `/world.glb` (the bundle's buildings and terrain) is served.
    pub world_model: bool,
    pub zone_colour: &'static str,
    pub groups: Vec<SceneGroup>,
    /// By global drone index (the order of every frame's arrays).
    pub drones: Vec<SceneDrone>,
    pub zones: Vec<SceneZone>,
}

#[derive(Serialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct SceneGroup {
    pub name: String,
    pub colour: &'static str,
    pub drones: u32,
}

#[derive(Serialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct SceneDrone {
    pub index: u32,
    pub name: String,
    pub group: String,
    pub colour: &'static str,
    /// Where it starts, ENU m.
    pub home_enu_m: [f64; 3],
}

#[derive(Serialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct SceneZone {
    pub name: String,
    /// Each corner of the outline as `[east, north, floor up, ceiling up]`, m: floor and
    /// ceiling over the ground at that corner (AGL limits follow the terrain), as the
    /// airspace monitor judges them.
    pub corners: Vec<[f64; 4]>,
    /// Simulated seconds.
    pub active_from_s: f64,
    /// Simulated seconds; `None` when active to the end.
    pub active_until_s: Option<f64>,
    pub authorized_operators: Vec<String>,
}

/// Half-width of the view's world when the run's world is not at hand (a replay whose map
/// is gone), m.
const UNKNOWN_EXTENT_M: f64 = 1000.0;

/// The scene of `plan` flown in `world` (`None`: a replay whose world cannot be found;
/// zone limits are then drawn over flat ground at the origin's level); `world_model` says
/// whether the glTF is served.
pub fn scene(plan: &RunPlan, world: Option<&World>, mode: &'static str, world_model: bool) -> Scene {
    let ground_up_m = |e: f64, n: f64| world.map_or(0.0, |w| w.ground_up_m(e, n));
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let origin = plan.spec.origin.geo();
    let colour = |group_index: usize| GROUP_COLOURS[group_index % GROUP_COLOURS.len()];
    let groups = plan
        .spec
        .fleet
        .iter()
        .enumerate()
        .map(|(i, g)| SceneGroup {
            name: g.name.clone(),
            colour: colour(i),
            drones: plan.drones.iter().filter(|d| d.group_index as usize == i).count() as u32,
        })
        .collect();
    let drones = plan
        .drones
        .iter()
        .map(|d| SceneDrone {
            index: d.index,
            name: d.name.clone(),
            group: d.group.clone(),
            colour: colour(d.group_index as usize),
            home_enu_m: [d.home.local.east_m, d.home.local.north_m, d.home.local.up_m],
        })
        .collect();
    let zones = plan
        .spec
        .zones
        .iter()
        .map(|zone| {
            let v = ZoneVolume::new(zone, &frame);
            let corners = v
                .polygon
                .iter()
                .map(|&(e, n)| {
                    let (floor, ceiling) = v.vertical_limits_up_m(ground_up_m(e, n));
                    [e, n, floor, ceiling]
                })
                .collect();
            SceneZone {
                name: zone.name.clone(),
                corners,
                active_from_s: v.active_from_s,
                active_until_s: v.active_until_s.is_finite().then_some(v.active_until_s),
                authorized_operators: zone.policy.authorized_operators.clone(),
            }
        })
        .collect();
    Scene {
        run: plan.run.name.clone(),
        namespace: plan.run.namespace.clone(),
        mode,
        origin: [origin.latitude_deg, origin.longitude_deg, origin.altitude_msl_m],
        duration_s: plan.duration_s,
        world_extent_m: world.map_or(UNKNOWN_EXTENT_M, World::extent_m),
        world_model,
        zone_colour: ZONE_COLOUR,
        groups,
        drones,
        zones,
    }
}
