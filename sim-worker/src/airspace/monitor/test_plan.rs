//! Test support: a `RunPlan` made from a fixture run without the operator's planner (which
//! sim-worker cannot depend on), and zones given as ENU rectangles.

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::LatLon;
use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};
use sadesim_crds::plan::{
    DronePorts, Home, PLAN_FORMAT_VERSION, PlannedDrone, ResourcePlan, RoleResources, RunPlan, RunRef, ServicePorts,
};
use sadesim_crds::run::SimulationRun;
use sadesim_crds::zones::{AltitudeReference, Zone, ZoneAltitude, ZonePolicy};

use crate::airspace::volume::ZoneVolume;

/// The plan of `run`: drones `<group>-<k>` in fleet order, all in shard 0, homes at the
/// origin. Only what the airspace code reads is meaningful.
pub(crate) fn plan_of(run: SimulationRun) -> RunPlan {
    let none = RoleResources { cpu_millis: 0, memory_mib: 0 };
    let mut drones = Vec::new();
    for (gi, g) in run.spec.fleet.iter().enumerate() {
        for k in 0..g.count {
            let index = drones.len() as u32;
            drones.push(PlannedDrone {
                index,
                name: format!("{}-{k}", g.name),
                group: g.name.clone(),
                group_index: gi as u32,
                member: k,
                operator: g.operator.clone(),
                role: g.role,
                airframe: g.airframe.clone(),
                system_id: (index % 250 + 1) as u8,
                component_id: 1,
                segment: index / 250,
                shard: 0,
                ports: DronePorts { api_udp: 14540, endpoint: 24600 },
                home: Home { local: Enu::default(), global: run.spec.origin.geo() },
                scripted: true,
            });
        }
    }
    RunPlan {
        format_version: PLAN_FORMAT_VERSION,
        run: RunRef { name: "test-run".into(), namespace: "default".into(), uid: None },
        duration_s: run.spec.duration_s(),
        spec: run.spec,
        physics_rate_hz: 1000,
        sync_window_steps: 10,
        seed: 7,
        drones,
        shards: Vec::new(),
        segments: Vec::new(),
        asset_cache_key: String::new(),
        services: ServicePorts { coordinator: 7400, airspace_http: 8480, renderer_http: 8490, metrics: 9090 },
        resources: ResourcePlan {
            assets: none,
            shards: Vec::new(),
            coordinator: none,
            router: none,
            renderer: None,
            pilot: None,
        },
    }
}

/// A run over the fixture origin with the given groups (name, count), no zones.
pub(crate) fn run_with_groups(groups: &[(&str, u32)]) -> RunBuilder {
    let mut b = RunBuilder::test().with(|r| r.spec.fleet.clear());
    for (name, n) in groups {
        b = b.with_group(name, *n);
    }
    b
}

/// A rectangular zone `[east0, east1] x [north0, north1]` (ENU metres from the fixture's
/// origin) from `floor_m` to `ceiling_m` AGL, open to operator `acme`.
pub(crate) fn rect_zone(name: &str, east: (f64, f64), north: (f64, f64), floor_m: f64, ceiling_m: f64) -> Zone {
    let frame = LocalFrame::new(RunBuilder::test().build().spec.origin.geo());
    let corner = |e: f64, n: f64| {
        let g: GeoPoint = frame.to_geodetic(Enu::new(e, n, 0.0));
        LatLon { latitude_deg: g.latitude_deg, longitude_deg: g.longitude_deg }
    };
    Zone {
        name: name.into(),
        polygon: vec![
            corner(east.0, north.0),
            corner(east.1, north.0),
            corner(east.1, north.1),
            corner(east.0, north.1),
        ],
        floor: Some(ZoneAltitude { height_m: floor_m, reference: AltitudeReference::Agl }),
        ceiling: ZoneAltitude { height_m: ceiling_m, reference: AltitudeReference::Agl },
        active_from: None,
        active_until: None,
        policy: ZonePolicy {
            authorized_operators: vec!["acme".into()],
            capacity: None,
            lease_duration: None,
            min_altitude_agl_m: None,
            max_altitude_agl_m: None,
        },
    }
}

/// The volumes of the plan's zones, as the airspace state builds them.
pub(crate) fn volumes(plan: &RunPlan) -> Vec<ZoneVolume> {
    let frame = LocalFrame::new(plan.spec.origin.geo());
    plan.spec.zones.iter().map(|z| ZoneVolume::new(z, &frame)).collect()
}
