//! The planner: a pure function `SimulationRun -> RunPlan` (DESIGN §4).
//!
//! It validates, numbers every drone, assigns MAVLink system ids and router segments,
//! shards, ports and homes, hashes the asset inputs and estimates resources. Everything is
//! deterministic: the same run always gives the same plan, byte for byte.
//!
//! The entry points are in this file: [`plan`] (builds the world itself), [`plan_with`]
//! (with the files a mapped world names, read at the edge), [`plan_in`] (in a world already
//! built or loaded) and [`asset_key`]. Its modules:
//!
//! - `ports`: the deterministic port plan (PX4 SITL conventions, router segments);
//! - `resources`: the resource estimate per role instance (Kubernetes requests);
//! - `fleet_file`: the fleet file a pilot reads, for the addressing of where it runs.

mod fleet_file;
mod ports;
mod resources;

#[cfg(test)]
mod fuzz_seeds;

use sadesim_crds::fleet::{Area, FleetGroup, HomePlacement};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::{Home, PLAN_FORMAT_VERSION, PlannedDrone, PlannedShard, RouterSegment, RunPlan, RunRef};
use sadesim_crds::polygon;
use sadesim_crds::random::{Purpose, Rng};
use sadesim_crds::validate::duration_s;
use sadesim_crds::zones::AltitudeReference;
use sadesim_crds::{SimulationRun, ValidationErrors, validate};
use sadesim_world::{World, WorldData, WorldError, WorldInputs};
use serde::Serialize;

pub use fleet_file::{
    Addressing, CAMERAS_URL_ENV, add_camera_urls, cluster_cameras_url, credential_env_var, fleet_file, zones_geojson,
};
pub use ports::{
    MAX_SEGMENTS, SYSTEM_IDS_PER_SEGMENT, api_udp_port, concurrent_offsets, endpoint_port, gcs_tcp_port, gcs_udp_port,
    offset_ports, service_ports,
};

/// Namespace used for local runs and for documents without one.
pub const DEFAULT_NAMESPACE: &str = "default";
/// Bumped when the world generator changes what it builds from the same inputs, or the
/// bundle's layout changes, so old cached assets are not reused. 2: the bundle carries the
/// world itself (`world.bin`, whose own format is `sadesim_world::bundle::FORMAT_VERSION`,
/// part of the key too).
pub const ASSETS_FORMAT_VERSION: u32 = 2;

/// Why a run could not be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The run failed validation; every problem is listed.
    #[error("invalid SimulationRun:\n{0}")]
    Invalid(#[from] ValidationErrors),
    /// Random home placement found no spot outside the ground-level zones.
    #[error(
        "spec.fleet[{group}].homes: no home found for drone {drone} outside the zones that reach the ground after {MAX_HOME_DRAWS} draws: enlarge the area or move it away from the zones"
    )]
    NoHome { group: usize, drone: u32 },
    /// The world cannot be built (its files were not read, or the DEM does not cover it).
    #[error("{0}")]
    World(#[from] WorldError),
    /// An explicit home inside a building of the map.
    #[error(
        "spec.fleet[{group}].homes.explicit[{home}]: inside a building of the map (roof {roof_m:.1} m): move the home to open ground"
    )]
    HomeInBuilding { group: usize, home: usize, roof_m: f64 },
}

/// Draws per drone before random placement gives up.
pub const MAX_HOME_DRAWS: usize = 1000;

/// Plans a run.
///
/// # Errors
/// [`PlanError::Invalid`] with every validation problem when the run is not valid.
///
/// # Guarantees
/// Every drone is in exactly one shard and one segment; system ids are 1..=250 and unique
/// within a segment; ports are unique; the result depends only on the input.
pub fn plan(run: &SimulationRun) -> Result<RunPlan, PlanError> {
    plan_with(run, &WorldData::default())
}

/// [`plan`] with the files the world names (the OpenStreetMap extract of `world.source:
/// osm`, the DEM of `world.terrain.dem`), read at the I/O edge
/// (`sadesim_sources::world::read_data`): they decide where homes may be and at what
/// ground height, and their bytes' digests are part of the asset cache key.
///
/// # Errors
/// As [`plan`]; [`PlanError::World`] when a file the world names is not in `data` (or
/// the DEM does not cover the world), and
/// [`PlanError::HomeInBuilding`] for an explicit home inside a mapped building.
pub fn plan_with(run: &SimulationRun, data: &WorldData) -> Result<RunPlan, PlanError> {
    plan_and_world(run, data).map(|(plan, _)| plan)
}

/// [`plan_with`], also returning the world it built, for callers that go on to simulate in
/// it (the local runner): the world is built once, not again after planning.
///
/// # Errors
/// As [`plan_with`].
pub fn plan_and_world(run: &SimulationRun, data: &WorldData) -> Result<(RunPlan, World), PlanError> {
    validate(run)?;
    let world = World::build(&WorldInputs::from_spec(&run.spec, &[]), data)?;
    let plan = plan_in(run, data, &world)?;
    Ok((plan, world))
}

/// The asset cache key of the run's world (the plan's `asset_cache_key`), without building
/// the world: what the local runner looks the world up by before it plans.
///
/// # Errors
/// [`PlanError::Invalid`] when the run does not validate.
pub fn asset_key(run: &SimulationRun, data: &WorldData) -> Result<String, PlanError> {
    validate(run)?;
    Ok(key_of(run, data))
}

/// [`asset_key`] without validating the whole run: for a run whose `spec.origin` and
/// `spec.world` validate while other parts may not yet (the console draws the world of a
/// scenario being edited).
pub fn world_key(run: &SimulationRun, data: &WorldData) -> String {
    key_of(run, data)
}

fn key_of(run: &SimulationRun, data: &WorldData) -> String {
    let digests = [data.osm.as_ref().map(|c| c.source_sha256.as_str()), data.dem.as_ref().map(|d| d.source_sha256())];
    asset_cache_key(&WorldInputs::from_spec(&run.spec, &[]), digests, &run.spec.zones)
}

/// [`plan_with`] in a world already built (or loaded from the asset bundle of
/// [`asset_key`]): homes are drawn on its open ground and checked against its buildings.
///
/// # Errors
/// As [`plan_with`].
pub fn plan_in(run: &SimulationRun, data: &WorldData, world: &World) -> Result<RunPlan, PlanError> {
    validate(run)?;
    let spec = &run.spec;
    let frame = LocalFrame::new(spec.origin.geo());
    let seed = spec.seed();
    let sharding = spec.sharding();
    let per_shard = sharding.drones_per_shard;

    let keep_out = ground_zones(spec, &frame);
    // Random homes must not fall inside buildings: they are drawn on the world's open
    // ground.
    let mut drones = Vec::with_capacity(spec.total_drones() as usize);
    for (group_index, group) in spec.fleet.iter().enumerate() {
        for k in 0..group.count {
            let index = drones.len() as u32;
            let home = home(&frame, group, k, index, seed, &keep_out, world)
                .ok_or(PlanError::NoHome { group: group_index, drone: index })?;
            // The procedural city keeps explicit homes clear; a mapped one cannot move its
            // buildings.
            if let Some(b) = world.building_at(home.local.east_m, home.local.north_m)
                && matches!(group.homes, HomePlacement::Explicit(_))
            {
                return Err(PlanError::HomeInBuilding { group: group_index, home: k as usize, roof_m: b.roof_up_m() });
            }
            drones.push(PlannedDrone {
                index,
                name: format!("{}-{k}", group.name),
                group: group.name.clone(),
                group_index: group_index as u32,
                member: k,
                operator: group.operator.clone(),
                role: group.role,
                airframe: group.airframe.clone(),
                system_id: (index % SYSTEM_IDS_PER_SEGMENT + 1) as u8,
                component_id: 1, // MAV_COMP_ID_AUTOPILOT1
                segment: index / SYSTEM_IDS_PER_SEGMENT,
                shard: index / per_shard,
                ports: sadesim_crds::plan::DronePorts { api_udp: api_udp_port(index), endpoint: endpoint_port(index) },
                home,
                scripted: group.mission.is_some(),
            });
        }
    }
    let total = drones.len() as u32;
    let shards = ranges(total, per_shard)
        .enumerate()
        .map(|(i, (first, count))| PlannedShard { index: i as u32, first_drone: first, drone_count: count })
        .collect::<Vec<_>>();
    let segments = ranges(total, SYSTEM_IDS_PER_SEGMENT)
        .enumerate()
        .map(|(i, (first, count))| RouterSegment {
            index: i as u32,
            first_drone: first,
            drone_count: count,
            gcs_udp: gcs_udp_port(i as u32),
            gcs_tcp: gcs_tcp_port(i as u32),
        })
        .collect::<Vec<_>>();
    let resources = resources::estimate(spec, &shards);

    let mut plan = RunPlan {
        format_version: PLAN_FORMAT_VERSION,
        run: RunRef {
            name: run.metadata.name.clone().unwrap_or_default(),
            namespace: run.metadata.namespace.clone().unwrap_or_else(|| DEFAULT_NAMESPACE.to_string()),
            uid: run.metadata.uid.clone(),
        },
        spec: spec.clone(),
        duration_s: spec.duration_s(),
        physics_rate_hz: spec.physics_rate_hz(),
        sync_window_steps: sharding.sync_window_steps,
        seed,
        drones,
        shards,
        segments,
        asset_cache_key: String::new(),
        services: service_ports(),
        resources,
    };
    plan.asset_cache_key = key_of(run, data);
    Ok(plan)
}

/// Contiguous `(first, count)` ranges of at most `size` covering `0..total`.
fn ranges(total: u32, size: u32) -> impl Iterator<Item = (u32, u32)> {
    (0..total.div_ceil(size)).map(move |i| (i * size, size.min(total - i * size)))
}

/// Clearance a random home keeps from any building footprint, m (rotor disc plus margin).
const HOME_BUILDING_CLEARANCE_M: f64 = 3.0;

fn clear_of_buildings(world: &World, (e, n): polygon::Point) -> bool {
    let c = HOME_BUILDING_CLEARANCE_M;
    [(0.0, 0.0), (c, 0.0), (-c, 0.0), (0.0, c), (0.0, -c)]
        .iter()
        .all(|(de, dn)| world.building_at(e + de, n + dn).is_none())
}

/// Polygons (local plane) of the zones a drone must not start in: active at the start and
/// reaching the ground.
fn ground_zones(spec: &sadesim_crds::SimulationRunSpec, frame: &LocalFrame) -> Vec<Vec<polygon::Point>> {
    let origin_alt = spec.origin.altitude_msl_m;
    spec.zones
        .iter()
        .filter(|z| z.active_from.as_ref().is_none_or(|d| duration_s(d) <= 0.0))
        .filter(|z| {
            let f = z.floor();
            match f.reference {
                AltitudeReference::Agl => f.height_m <= 0.0,
                AltitudeReference::Msl => f.height_m <= origin_alt,
            }
        })
        .map(|z| z.polygon.iter().map(|v| frame.to_plane(v.latitude_deg, v.longitude_deg)).collect())
        .collect()
}

/// Home of drone `k` of `group` (global index `index`), on the ground; `None` when random
/// placement finds no spot outside `keep_out`.
///
/// Random placements draw from the drone's own `(seed, global index, Home)` stream
/// (DESIGN §5), so homes do not depend on sharding; draws inside a ground-level zone are
/// rejected and drawn again (explicit homes inside zones are refused by validation).
fn home(
    frame: &LocalFrame,
    group: &FleetGroup,
    k: u32,
    index: u32,
    seed: u64,
    keep_out: &[Vec<polygon::Point>],
    world: &World,
) -> Option<Home> {
    let in_area = |area: &Area| {
        let (cx, cy) = frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
        let mut rng = Rng::stream(seed, index.into(), Purpose::Home);
        (0..MAX_HOME_DRAWS)
            .map(|_| rng.in_disc(area.radius_m))
            .map(|(dx, dy)| (cx + dx, cy + dy))
            .find(|p| !keep_out.iter().any(|zone| polygon::contains(zone, *p)) && clear_of_buildings(world, *p))
    };
    let (east_m, north_m) = match &group.homes {
        HomePlacement::Explicit(list) => {
            let at = list[k as usize];
            frame.to_plane(at.latitude_deg, at.longitude_deg)
        }
        HomePlacement::RandomInArea(area) => in_area(area)?,
        // Round-robin over the areas so each gets its share (the paper's "various parks").
        HomePlacement::Areas(areas) => in_area(&areas[k as usize % areas.len()])?,
    };
    // On the world's ground there (gentle terrain and the Earth's curvature included), so
    // the fleet file's home altitude is the ground's MSL altitude under the drone.
    let local = Enu::new(east_m, north_m, world.ground_up_m(east_m, north_m));
    Some(Home { local, global: frame.to_geodetic(local) })
}

/// Everything that shapes the world assets, hashed: exactly the world generator's inputs
/// (origin, world parameters, open areas including parks and the clearance around every
/// home) and the zones (baked into the assets in the local frame). Not the run seed, the
/// clock or the pilot: changing those reuses the cached world.
fn asset_cache_key(
    world: &WorldInputs,
    [extract_sha256, dem_sha256]: [Option<&str>; 2],
    zones: &[sadesim_crds::zones::Zone],
) -> String {
    #[derive(Serialize)]
    struct AssetInputs<'a> {
        format: u32,
        world_format: u32,
        world: WorldInputs,
        /// The files' bytes (absent for the procedural city: its keys are unchanged).
        #[serde(skip_serializing_if = "Option::is_none")]
        extract_sha256: Option<&'a str>,
        #[serde(skip_serializing_if = "Option::is_none")]
        dem_sha256: Option<&'a str>,
        zones: &'a [sadesim_crds::zones::Zone],
    }
    // The files count by their bytes (the digests), not by where they are: the same extract
    // on a laptop and in a bucket is the same world, and a moved file keeps its entry.
    let mut world = world.clone();
    if let Some(osm) = world.world.osm.as_mut() {
        osm.file.clear();
    }
    if let Some(terrain) = world.world.terrain.as_mut() {
        terrain.dem.file.clear();
    }
    let inputs = AssetInputs {
        format: ASSETS_FORMAT_VERSION,
        world_format: sadesim_world::bundle::FORMAT_VERSION,
        world,
        extract_sha256,
        dem_sha256,
        zones,
    };
    // serde_json writes struct fields in declaration order and floats with a fixed
    // shortest-round-trip format, so the bytes are canonical for these types.
    sadesim_crds::parts::sha256_hex(&serde_json::to_vec(&inputs).expect("asset inputs always serialize"))
}

#[cfg(test)]
mod tests;
