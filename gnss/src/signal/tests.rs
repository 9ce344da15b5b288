use nalgebra::Vector3;
use sadesim_crds::random::{Purpose, Rng};
use sadesim_world::{Building, Footprint, World};

use super::*;

fn block(e0: f64, n0: f64, e1: f64, n1: f64, roof_m: f64) -> Building {
    let square = vec![[e0, n0], [e1, n0], [e1, n1], [e0, n1]];
    Building::new(Footprint::new(square, vec![]).unwrap(), 0.0, roof_m).unwrap()
}

/// A north-south street 20 m wide between two 60 m slabs 30 m deep and 400 m long.
fn canyon() -> World {
    World::of_buildings(500.0, vec![block(-40.0, -200.0, -10.0, 200.0, 60.0), block(10.0, -200.0, 40.0, 200.0, 60.0)])
}

/// Unit vector towards azimuth `az_deg` (clockwise from north), elevation `el_deg`, ENU.
fn towards(az_deg: f64, el_deg: f64) -> Vector3<f64> {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    Vector3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin())
}

#[test]
fn along_the_street_and_overhead_the_sky_is_open() {
    let w = canyon();
    let antenna = Vector3::new(0.0, 0.0, 20.0);
    assert_eq!(signal_path(&w, &antenna, &towards(0.0, 30.0)), SignalPath::LineOfSight);
    assert_eq!(signal_path(&w, &antenna, &towards(180.0, 15.0)), SignalPath::LineOfSight);
    assert_eq!(signal_path(&w, &antenna, &towards(90.0, 80.0)), SignalPath::LineOfSight);
}

#[test]
fn across_the_street_a_high_satellite_arrives_off_the_opposite_facade() {
    // East at 60 deg: the direct ray meets the east slab at 20 + 10 tan 60 = 37.3 m; the
    // west facade (10 m away) reflects it from 37.3 m up, and that leg clears the east roof
    // (37.3 + 20 tan 60 = 71.9 m > 60 m). Detour 2 d cos(el) = 10 m.
    let w = canyon();
    let antenna = Vector3::new(0.0, 0.0, 20.0);
    match signal_path(&w, &antenna, &towards(90.0, 60.0)) {
        SignalPath::Reflected { excess_m, arrival_enu, building } => {
            assert!((excess_m - 10.0).abs() < 1e-9, "{excess_m}");
            assert_eq!(building, 0, "the west slab reflects");
            let expected = Vector3::new(-10.0, 0.0, 10.0 * 3f64.sqrt()).normalize();
            assert!((arrival_enu - expected).norm() < 1e-9, "{arrival_enu:?}");
        }
        other => panic!("expected a reflection, got {other:?}"),
    }
}

#[test]
fn a_low_satellite_across_the_street_is_lost_and_above_the_roofs_everything_is_in_sight() {
    // East at 30 deg: the reflection point on the west facade is only 25.8 m up, and its
    // leg to the satellite meets the east slab below its roof: no path.
    let w = canyon();
    assert_eq!(signal_path(&w, &Vector3::new(0.0, 0.0, 20.0), &towards(90.0, 30.0)), SignalPath::Blocked);
    for az in [0.0, 90.0, 180.0, 270.0] {
        assert_eq!(signal_path(&w, &Vector3::new(0.0, 0.0, 80.0), &towards(az, 30.0)), SignalPath::LineOfSight);
    }
    assert!(!line_of_sight(&w, &Vector3::new(0.0, 0.0, 80.0), &towards(0.0, -1.0)), "below the horizon");
}

#[test]
fn a_reflection_needs_a_facade_in_reach_and_a_clear_first_leg() {
    // A lone slab east of the antenna: a satellite west of it is in sight, one east of it
    // behind the slab has no facade to bounce off (the slab's own west face faces away
    // from the satellite).
    let w = World::of_buildings(500.0, vec![block(10.0, -200.0, 40.0, 200.0, 60.0)]);
    let antenna = Vector3::new(0.0, 0.0, 5.0);
    assert_eq!(signal_path(&w, &antenna, &towards(270.0, 20.0)), SignalPath::LineOfSight);
    assert_eq!(signal_path(&w, &antenna, &towards(90.0, 20.0)), SignalPath::Blocked);
    // A reflector out of reach: the west slab 200 m away is beyond the search radius.
    let far = World::of_buildings(
        1000.0,
        vec![block(-230.0, -200.0, -200.0, 200.0, 200.0), block(10.0, -200.0, 40.0, 200.0, 60.0)],
    );
    assert_eq!(signal_path(&far, &antenna, &towards(90.0, 60.0)), SignalPath::Blocked);
}

/// The line-of-sight verdict against a brute-force march along the ray (0.05 m steps,
/// inside-a-prism test) for random antennas and directions over a random little city.
#[test]
fn line_of_sight_agrees_with_a_brute_force_march() {
    let mut rng = Rng::stream(11, 0, Purpose::World);
    let mut buildings = Vec::new();
    for _ in 0..25 {
        let (e, n) = (rng.uniform(-150.0, 150.0), rng.uniform(-150.0, 150.0));
        let (w, d) = (rng.uniform(5.0, 30.0), rng.uniform(5.0, 30.0));
        buildings.push(block(e, n, e + w, n + d, rng.uniform(5.0, 60.0)));
    }
    let world = World::of_buildings(400.0, buildings);
    let mut disagreements = 0;
    for _ in 0..300 {
        let antenna = Vector3::new(rng.uniform(-150.0, 150.0), rng.uniform(-150.0, 150.0), rng.uniform(1.0, 50.0));
        if world.is_inside_building(antenna) {
            continue;
        }
        let to_sat = towards(rng.uniform(0.0, 360.0), rng.uniform(5.0, 85.0));
        let marched = (1..40_000).all(|k| !world.is_inside_building(antenna + to_sat * (0.05 * k as f64)));
        // A march step can skip a sliver of a corner the exact test sees: allow none here,
        // the random boxes are at least 5 m.
        if line_of_sight(&world, &antenna, &to_sat) != marched {
            disagreements += 1;
        }
    }
    assert_eq!(disagreements, 0);
}

#[test]
fn reflected_and_low_signals_are_weaker() {
    let reflected = SignalPath::Reflected { excess_m: 5.0, arrival_enu: Vector3::z(), building: 0 };
    let high = cn0_dbhz(80.0, &SignalPath::LineOfSight).unwrap();
    let low = cn0_dbhz(10.0, &SignalPath::LineOfSight).unwrap();
    assert!(high > low && high <= CN0_ZENITH_DBHZ && low >= CN0_HORIZON_DBHZ);
    assert_eq!(cn0_dbhz(80.0, &reflected), Some(high - REFLECTION_LOSS_DB));
    assert_eq!(cn0_dbhz(80.0, &SignalPath::Blocked), None);
}

#[test]
fn a_ridge_hides_the_low_satellites_behind_it() {
    // Ground at 0 m but a 100 m ridge from 150 to 200 m east (sampled every 10 m).
    let grid =
        sadesim_world::GroundGrid::sample(500.0, 101, |e, _| if (150.0..=200.0).contains(&e) { 100.0 } else { 0.0 });
    let world = World::of_buildings_on(500.0, sadesim_world::Terrain::from_grid(grid), vec![]);
    let antenna = Vector3::new(0.0, 0.0, 2.0);
    // East at 20 deg: 2 + 150 tan 20 = 56.6 m where the ridge starts: blocked, and no facade
    // to reflect it.
    assert!(!line_of_sight(&world, &antenna, &towards(90.0, 20.0)));
    assert_eq!(signal_path(&world, &antenna, &towards(90.0, 20.0)), SignalPath::Blocked);
    // East at 45 deg clears it (152 m at its foot); west at 20 deg has open ground.
    assert!(line_of_sight(&world, &antenna, &towards(90.0, 45.0)));
    assert!(line_of_sight(&world, &antenna, &towards(270.0, 20.0)));
    // From the ridge's top everything above the horizon is in sight.
    assert!(line_of_sight(&world, &Vector3::new(175.0, 0.0, 102.0), &towards(270.0, 5.0)));
}
