//! The planner: a pure function `SimulationRun -> RunPlan` (DESIGN §4).
//!
//! It validates, numbers every drone, assigns MAVLink system ids and router segments,
//! shards, ports and homes, hashes the asset inputs and estimates resources. Everything is
//! deterministic: the same run always gives the same plan, byte for byte.

mod fleet_file;
mod ports;
mod resources;

use sadesim_crds::fleet::{Area, FleetGroup, HomePlacement};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::{Home, PLAN_FORMAT_VERSION, PlannedDrone, PlannedShard, RouterSegment, RunPlan, RunRef};
use sadesim_crds::random::{Purpose, Rng};
use sadesim_crds::{SimulationRun, ValidationErrors, validate};
use serde::Serialize;
use sha2::{Digest, Sha256};

pub use fleet_file::{Addressing, credential_env_var, fleet_file, zones_geojson};
pub use ports::{
    MAX_SEGMENTS, SYSTEM_IDS_PER_SEGMENT, api_udp_port, endpoint_port, gcs_tcp_port, gcs_udp_port, service_ports,
};

/// Namespace used for local runs and for documents without one.
pub const DEFAULT_NAMESPACE: &str = "default";
/// Bumped when the world generator changes what it builds from the same inputs, so old
/// cached assets are not reused.
pub const ASSETS_FORMAT_VERSION: u32 = 1;

/// Why a run could not be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The run failed validation; every problem is listed.
    #[error("invalid SimulationRun:\n{0}")]
    Invalid(#[from] ValidationErrors),
}

/// Plans a run.
///
/// # Errors
/// [`PlanError::Invalid`] with every validation problem when the run is not valid.
///
/// # Guarantees
/// Every drone is in exactly one shard and one segment; system ids are 1..=250 and unique
/// within a segment; ports are unique; the result depends only on the input.
pub fn plan(run: &SimulationRun) -> Result<RunPlan, PlanError> {
    validate(run)?;
    let spec = &run.spec;
    let frame = LocalFrame::new(spec.origin.geo());
    let seed = spec.seed();
    let sharding = spec.sharding();
    let per_shard = sharding.drones_per_shard;

    let mut drones = Vec::with_capacity(spec.total_drones() as usize);
    for (group_index, group) in spec.fleet.iter().enumerate() {
        for k in 0..group.count {
            let index = drones.len() as u32;
            drones.push(PlannedDrone {
                index,
                name: format!("{}-{k}", group.name),
                group: group.name.clone(),
                group_index: group_index as u32,
                operator: group.operator.clone(),
                role: group.role,
                airframe: group.airframe.clone(),
                system_id: (index % SYSTEM_IDS_PER_SEGMENT + 1) as u8,
                component_id: 1, // MAV_COMP_ID_AUTOPILOT1
                segment: index / SYSTEM_IDS_PER_SEGMENT,
                shard: index / per_shard,
                ports: sadesim_crds::plan::DronePorts { api_udp: api_udp_port(index), endpoint: endpoint_port(index) },
                home: home(&frame, group, k, index, seed),
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

    Ok(RunPlan {
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
        asset_cache_key: asset_cache_key(run),
        services: service_ports(),
        resources,
    })
}

/// Contiguous `(first, count)` ranges of at most `size` covering `0..total`.
fn ranges(total: u32, size: u32) -> impl Iterator<Item = (u32, u32)> {
    (0..total.div_ceil(size)).map(move |i| (i * size, size.min(total - i * size)))
}

/// Home of drone `k` of `group` (global index `index`), on the ground (`up` = 0).
///
/// Random placements draw from the drone's own `(seed, global index, Home)` stream
/// (DESIGN §5), so homes do not depend on sharding.
fn home(frame: &LocalFrame, group: &FleetGroup, k: u32, index: u32, seed: u64) -> Home {
    let in_area = |area: &Area| {
        let (cx, cy) = frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
        let (dx, dy) = Rng::stream(seed, index.into(), Purpose::Home).in_disc(area.radius_m);
        (cx + dx, cy + dy)
    };
    let (east_m, north_m) = match &group.homes {
        HomePlacement::Explicit(list) => {
            let at = list[k as usize];
            frame.to_plane(at.latitude_deg, at.longitude_deg)
        }
        HomePlacement::RandomInArea(area) => in_area(area),
        // Round-robin over the areas so each gets its share (the paper's "various parks").
        HomePlacement::Areas(areas) => in_area(&areas[k as usize % areas.len()]),
    };
    let local = Enu::new(east_m, north_m, 0.0);
    Home { local, global: frame.to_geodetic(local) }
}

/// Everything that shapes the world assets, hashed: origin, world, zones (baked into the
/// assets in the local frame) and the areas kept open for homes (parks). Not the fleet
/// size, the clock or the pilot: changing those reuses the cached world.
fn asset_cache_key(run: &SimulationRun) -> String {
    #[derive(Serialize)]
    struct AssetInputs<'a> {
        format: u32,
        origin: &'a sadesim_crds::run::Origin,
        world: sadesim_crds::run::World,
        zones: &'a [sadesim_crds::zones::Zone],
        open_areas: Vec<&'a Area>,
    }
    let spec = &run.spec;
    let open_areas = spec
        .fleet
        .iter()
        .flat_map(|g| match &g.homes {
            HomePlacement::Explicit(_) => vec![],
            HomePlacement::RandomInArea(a) => vec![a],
            HomePlacement::Areas(list) => list.iter().collect(),
        })
        .collect();
    let inputs = AssetInputs {
        format: ASSETS_FORMAT_VERSION,
        origin: &spec.origin,
        world: spec.world(),
        zones: &spec.zones,
        open_areas,
    };
    // serde_json writes struct fields in declaration order and floats with a fixed
    // shortest-round-trip format, so the bytes are canonical for these types.
    let bytes = serde_json::to_vec(&inputs).expect("asset inputs always serialize");
    let digest = Sha256::digest(&bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests;
