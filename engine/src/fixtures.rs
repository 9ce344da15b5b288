//! Test support (feature `fixtures`, for this crate's tests and its users'): a `RunPlan`
//! planned from a fixture run by the real planner, zones given as ENU rectangles, and
//! drone snapshots.

use sadesim_crds::fixtures::{RunBuilder, zone};
use sadesim_crds::fleet::LatLon;
use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::SimulationRun;
use sadesim_crds::zones::{AltitudeReference, Zone, ZoneAltitude};

use crate::airspace::volume::ZoneVolume;
use crate::events::FlightMode;
use crate::protocol::DroneSnapshot;

/// The plan of `run`, made by the real planner (`sadesim-planner`, as `sadesim run` and the
/// operator make it): drones `<group>-<k>` in fleet order, MAVLink ids, shards, ports and
/// homes exactly as a run gets them.
///
/// # Panics
/// When the planner refuses `run`: a test fixture must be a valid run.
pub fn plan_of(run: SimulationRun) -> RunPlan {
    match sadesim_planner::plan(&run) {
        Ok(plan) => plan,
        Err(e) => panic!("the test run does not plan: {e}"),
    }
}

/// The procedural world of `plan` (fixture runs fly over the generated city), as the
/// runner builds it.
pub fn world_of(plan: &RunPlan) -> sadesim_world::World {
    sadesim_world::World::generate(&sadesim_world::WorldInputs::from_spec(&plan.spec, &[]))
}

/// A run over the fixture origin with the given groups (name, count), no zones.
pub fn run_with_groups(groups: &[(&str, u32)]) -> RunBuilder {
    let mut b = RunBuilder::test().with(|r| r.spec.fleet.clear());
    for (name, n) in groups {
        b = b.with_group(name, *n);
    }
    b
}

/// A rectangular zone `[east0, east1] x [north0, north1]` (ENU metres from the fixture's
/// origin) from `floor_m` to `ceiling_m` AGL, open to operator `acme`.
pub fn rect_zone(name: &str, east: (f64, f64), north: (f64, f64), floor_m: f64, ceiling_m: f64) -> Zone {
    let frame = LocalFrame::new(RunBuilder::test().build().spec.origin.geo());
    let corner = |e: f64, n: f64| {
        let g: GeoPoint = frame.to_geodetic(Enu::new(e, n, 0.0));
        LatLon { latitude_deg: g.latitude_deg, longitude_deg: g.longitude_deg }
    };
    let polygon =
        vec![corner(east.0, north.0), corner(east.1, north.0), corner(east.1, north.1), corner(east.0, north.1)];
    Zone {
        floor: Some(ZoneAltitude { height_m: floor_m, reference: AltitudeReference::Agl }),
        ..zone(name, polygon, ceiling_m)
    }
}

/// The volumes of the plan's zones, as the airspace state builds them.
pub fn volumes(plan: &RunPlan) -> Vec<ZoneVolume> {
    let frame = LocalFrame::new(plan.spec.origin.geo());
    plan.spec.zones.iter().map(|z| ZoneVolume::new(z, &frame)).collect()
}

/// An airborne drone at ENU (e, n, up) over ground at `ground_up_m`.
pub fn over(index: u32, p: [f64; 3], ground_up_m: f64) -> DroneSnapshot {
    DroneSnapshot {
        index,
        position_enu_m: p,
        velocity_enu_mps: [0.0; 3],
        attitude_wxyz: [1.0, 0.0, 0.0, 0.0],
        height_agl_m: p[2] - ground_up_m,
        mode: FlightMode::Offboard,
        armed: true,
        on_ground: false,
        crashed: false,
        battery_remaining: 1.0,
        position_valid: true,
        detail: Default::default(),
    }
}
