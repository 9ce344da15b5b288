//! Behaviour of the generated world: determinism, layout rules, heights, terrain, queries.

use nalgebra::Vector3;
use proptest::prelude::*;
use sadesim_crds::fixtures::{CHICAGO, RunBuilder};
use sadesim_crds::fleet::{Area, HomePlacement, LatLon};
use sadesim_crds::geo::GeoPoint;
use sadesim_crds::run::{City, World as WorldSpec, WorldSource};
use std::sync::OnceLock;

use super::*;

fn inputs(extent_m: f64, city: Option<City>, open_areas: Vec<OpenArea>) -> WorldInputs {
    WorldInputs {
        origin: GeoPoint::new(CHICAGO.latitude_deg, CHICAGO.longitude_deg, 181.0),
        world: WorldSpec {
            source: WorldSource::Procedural,
            osm: None,
            terrain: None,
            extent_m,
            city,
            open_areas: Vec::new(),
            markers: Vec::new(),
        },
        open_areas,
    }
}

fn bits(world: &World) -> Vec<[u64; 6]> {
    world
        .buildings()
        .iter()
        .map(|b| {
            let r = b.footprint().axis_rect().expect("procedural buildings are rectangles");
            [r.center_east_m, r.center_north_m, r.half_east_m, r.half_north_m, b.base_up_m(), b.height_m()]
                .map(f64::to_bits)
        })
        .collect()
}

/// A 1.5 km world shared by the property tests (generated once).
fn shared() -> &'static World {
    static WORLD: OnceLock<World> = OnceLock::new();
    WORLD.get_or_init(|| World::generate(&inputs(1500.0, None, vec![])))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn same_inputs_give_a_bitwise_identical_world_and_another_origin_does_not() {
    let a = World::generate(&inputs(1000.0, None, vec![]));
    let b = World::generate(&inputs(1000.0, None, vec![]));
    assert!(!a.buildings().is_empty());
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.ground_up_m(321.0, -654.0).to_bits(), b.ground_up_m(321.0, -654.0).to_bits());

    let mut moved = inputs(1000.0, None, vec![]);
    moved.origin.longitude_deg += 0.01;
    let c = World::generate(&moved);
    assert_ne!(bits(&a), bits(&c));
    assert_ne!(a.ground_up_m(321.0, -654.0), c.ground_up_m(321.0, -654.0));
}

#[test]
fn the_run_seed_does_not_change_the_world() {
    let spec = |seed| {
        let park = Area { name: None, center: CHICAGO, radius_m: 100.0 };
        RunBuilder::test()
            .with_seed(seed)
            .with(|r| r.spec.fleet[0].homes = HomePlacement::RandomInArea(park))
            .build()
            .spec
    };
    let a = World::generate(&WorldInputs::from_spec(&spec(1), &[]));
    let b = World::generate(&WorldInputs::from_spec(&spec(99), &[]));
    assert_eq!(bits(&a), bits(&b));
}

#[test]
fn no_building_touches_an_open_area_or_an_explicit_home() {
    let park = |d_lat: f64, radius_m: f64| Area {
        name: None,
        center: LatLon { latitude_deg: CHICAGO.latitude_deg + d_lat, longitude_deg: CHICAGO.longitude_deg },
        radius_m,
    };
    let homes: Vec<LatLon> = (0..20)
        .map(|k| LatLon {
            latitude_deg: CHICAGO.latitude_deg - 0.004 + 0.0003 * f64::from(k),
            longitude_deg: CHICAGO.longitude_deg + 0.0021 * f64::from(k % 5),
        })
        .collect();
    let run = RunBuilder::test()
        .with(|r| r.spec.fleet[0].homes = HomePlacement::Areas(vec![park(0.003, 120.0), park(-0.006, 60.0)]))
        .with_group("bravo", 20)
        .with(|r| r.spec.fleet[1].homes = HomePlacement::Explicit(homes))
        .with(|r| r.spec.world = Some(WorldSpec { extent_m: 1500.0, ..WorldSpec::default() }))
        .build();
    let extra = OpenArea { east_m: -700.0, north_m: 300.0, radius_m: 90.0 };
    let inputs = WorldInputs::from_spec(&run.spec, &[extra]);
    assert_eq!(inputs.open_areas.len(), 2 + 20 + 1);
    let world = World::generate(&inputs);
    assert!(world.stats().dropped_for_open_areas > 20, "the test exercises the rule: {}", world.stats());
    for area in &inputs.open_areas {
        for b in world.buildings() {
            assert!(!b.footprint_touches_disc(area.east_m, area.north_m, area.radius_m), "{b:?} in {area:?}");
        }
    }
}

#[test]
fn buildings_stay_inside_blocks_off_the_street_corridors() {
    let city = City::default();
    let extent_m = 2000.0;
    let world = World::generate(&inputs(extent_m, None, vec![]));
    let pitch = city.block_size_m + city.street_width_m;
    let half_street = city.street_width_m / 2.0;
    let inside_one_block = |c: f64, h: f64| {
        let k = (c / pitch).floor();
        c - h >= k * pitch + half_street && c + h <= (k + 1.0) * pitch - half_street
    };
    for bl in world.buildings() {
        let b = bl.footprint().axis_rect().expect("procedural buildings are rectangles");
        assert!(inside_one_block(b.center_east_m, b.half_east_m), "{b:?} on a north-south street");
        assert!(inside_one_block(b.center_north_m, b.half_north_m), "{b:?} on an east-west street");
        let (lo, hi) = (bl.min_corner(), bl.max_corner());
        assert!(lo.x >= -extent_m && lo.y >= -extent_m && hi.x <= extent_m && hi.y <= extent_m);
        assert!(b.half_east_m > 0.0 && b.half_north_m > 0.0);
        assert_eq!(bl.base_up_m(), world.ground_up_m(b.center_east_m, b.center_north_m), "stands on the ground");
    }
}

#[test]
fn heights_are_capped_log_normal_around_the_configured_median() {
    let low_rise = City { median_building_height_m: 12.0, max_building_height_m: 40.0, ..City::default() };
    for city in [City::default(), low_rise] {
        let world = World::generate(&inputs(3000.0, Some(city.clone()), vec![]));
        let heights: Vec<f64> = world.buildings().iter().map(Building::height_m).collect();
        assert!(heights.len() > 1000);
        assert!(heights.iter().all(|&h| h > 0.0 && h <= city.max_building_height_m));
        let m = median(heights.clone());
        let want = city.median_building_height_m;
        assert!(m > want / 1.25 && m < want * 1.25, "median {m} for configured {want}");
        assert!((world.stats().median_height_m - m).abs() < 1e-9);
        // Log-normal spread: a real skyline, not a flat roofscape.
        let tall = heights.iter().filter(|&&h| h > 2.0 * want).count() as f64 / heights.len() as f64;
        assert!(tall > 0.05 && tall < 0.3, "share above twice the median: {tall}");
    }
}

#[test]
fn downtown_is_taller_than_the_edge() {
    let extent_m = 4000.0;
    let world = World::generate(&inputs(extent_m, None, vec![]));
    let mean_where = |keep: &dyn Fn(f64) -> bool| {
        let h: Vec<f64> = world
            .buildings()
            .iter()
            .filter(|b| {
                let [e, n] = b.footprint().bounds_center();
                keep(e.hypot(n))
            })
            .map(Building::height_m)
            .collect();
        assert!(h.len() > 50);
        h.iter().sum::<f64>() / h.len() as f64
    };
    let core = mean_where(&|r| r < 500.0);
    let edge = mean_where(&|r| r > 0.8 * extent_m);
    assert!(core > 2.0 * edge, "core {core:.1} m vs edge {edge:.1} m");
}

#[test]
fn parks_and_coverage_follow_the_city_parameters() {
    for built_fraction in [0.3, 0.5, 0.7] {
        let city = City { built_fraction, ..City::default() };
        let world = World::generate(&inputs(4000.0, Some(city), vec![]));
        let s = world.stats();
        let parks = s.park_count as f64 / s.block_count as f64;
        // 6.5 % of ~3100 blocks: one standard deviation is 0.45 points.
        assert!((0.04..=0.09).contains(&parks), "park share {parks}");
        assert!((s.built_area_fraction - built_fraction).abs() < 0.06, "{s}");
    }
    let empty = World::generate(&inputs(1000.0, Some(City { built_fraction: 0.0, ..City::default() }), vec![]));
    assert!(empty.buildings().is_empty());
    assert_eq!(empty.segment_hits_building(Vector3::new(-900.0, -900.0, 1.0), Vector3::new(900.0, 900.0, 1.0)), None);
}

#[test]
fn terrain_is_zero_at_the_origin_smooth_bounded_and_not_flat() {
    for lon_shift in [0.0, 0.1, 0.2] {
        let mut i = inputs(4000.0, None, vec![]);
        i.origin.longitude_deg += lon_shift;
        let world = World::generate(&i);
        assert_eq!(world.ground_up_m(0.0, 0.0), 0.0);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let step = 25.0;
        let mut y = -4000.0;
        while y <= 4000.0 {
            let mut x = -4000.0;
            while x <= 4000.0 {
                let h = world.ground_up_m(x, y);
                let gx = (world.ground_up_m(x + 0.5, y) - world.ground_up_m(x - 0.5, y)) / 1.0;
                let gy = (world.ground_up_m(x, y + 0.5) - world.ground_up_m(x, y - 0.5)) / 1.0;
                assert!(gx.hypot(gy) <= 0.045, "slope {} at ({x}, {y})", gx.hypot(gy));
                assert!(h.abs() <= world.terrain().max_abs_up_m() && h.abs() <= 8.0);
                (lo, hi) = (lo.min(h), hi.max(h));
                x += step;
            }
            y += step;
        }
        assert!(hi - lo > 2.0, "relief {lo:.2}..{hi:.2} m: AGL and MSL should differ");
        assert!(world.stats().ground_min_up_m >= lo - 0.5 && world.stats().ground_max_up_m <= hi + 0.5);
    }
}

#[test]
fn segments_hit_a_box_from_outside_and_nothing_along_a_street() {
    let world = shared();
    let (k, bl, b) = world
        .buildings()
        .iter()
        .enumerate()
        .filter_map(|(k, bl)| Some((k, bl, bl.footprint().axis_rect()?)))
        .find(|(k, _, b)| {
            // Nothing else (a neighbour, a stacked part) within the 5 m west of its west face.
            let (w, n) = (b.center_east_m - b.half_east_m, b.center_north_m);
            let clear_west = world.buildings().iter().enumerate().all(|(j, other)| {
                let [e0, n0, e1, n1] = other.footprint().bounds();
                j == *k || e1 < w - 5.5 || e0 > w - 0.01 || n1 < n - 0.5 || n0 > n + 0.5
            });
            b.center_east_m > 200.0 && b.center_north_m > 200.0 && clear_west
        })
        .expect("a building north-east of the origin with its west side clear");
    let mid_z = bl.base_up_m() + 0.5 * bl.height_m();
    let target = Vector3::new(b.center_east_m, b.center_north_m, mid_z);
    // From 5 m west of the west face, level: the hit is on that face.
    let from = Vector3::new(b.center_east_m - b.half_east_m - 5.0, b.center_north_m, mid_z);
    let (hit_k, p) = world.segment_hits_building(from, target).expect("hits the box");
    assert_eq!(hit_k, k);
    assert!((p.x - (b.center_east_m - b.half_east_m)).abs() < 1e-6 && (p.z - mid_z).abs() < 1e-9, "{p:?}");
    // From above the roof straight down: the hit is on the roof.
    let above = Vector3::new(b.center_east_m, b.center_north_m, bl.roof_up_m() + 50.0);
    let (_, p) = world.segment_hits_building(above, target).expect("hits the roof");
    assert!((p.z - bl.roof_up_m()).abs() < 1e-6);
    // Above every roof: clear.
    let sky = 400.0;
    assert_eq!(world.segment_hits_building(Vector3::new(-1400.0, 0.0, sky), Vector3::new(1400.0, 0.0, sky)), None);
    // Along the street centrelines through the origin, 2 m above the ground: clear.
    for (a, b) in
        [((-1500.0, 0.0), (1500.0, 0.0)), ((0.0, -1500.0), (0.0, 1500.0)), ((145.0, -1400.0), (145.0, 1400.0))]
    {
        let z = 2.0 + world.terrain().max_abs_up_m();
        assert_eq!(world.segment_hits_building(Vector3::new(a.0, a.1, z), Vector3::new(b.0, b.1, z)), None);
    }
}

#[test]
fn point_queries_agree_with_the_boxes() {
    let world = shared();
    let b = &world.buildings()[world.buildings().len() / 3];
    let [e, n] = b.footprint().bounds_center();
    assert_eq!(world.building_at(e, n), Some(b));
    assert_eq!(world.surface_up_m(e, n), b.roof_up_m());
    assert!(world.is_inside_building(Vector3::new(e, n, b.base_up_m() + 1.0)));
    assert!(!world.is_inside_building(Vector3::new(e, n, b.roof_up_m() + 0.1)));
    let ground = world.ground_up_m(e, n);
    assert!((world.height_agl_m(Vector3::new(e, n, ground + 10.0)) - 10.0).abs() < 1e-9);
    // The origin is a street intersection: open ground.
    assert_eq!(world.building_at(0.0, 0.0), None);
    assert_eq!(world.surface_up_m(0.0, 0.0), 0.0);
    assert!(world.building_at(5000.0, 0.0).is_none(), "outside the world");
}

#[test]
fn tiny_and_huge_parameters_still_generate() {
    let tiny = World::generate(&inputs(100.0, None, vec![]));
    assert!(tiny.buildings().iter().all(|b| b.max_corner().x <= 100.0 && b.min_corner().x >= -100.0));
    let whole = OpenArea { east_m: 0.0, north_m: 0.0, radius_m: 20_000.0 };
    let cleared = World::generate(&inputs(2000.0, None, vec![whole]));
    assert!(cleared.buildings().is_empty(), "{}", cleared.stats());
}

/// Brute force: the first building along a segment, lowest index on ties.
fn brute_hit(world: &World, a: Vector3<f64>, b: Vector3<f64>) -> Option<(usize, f64)> {
    world
        .buildings()
        .iter()
        .enumerate()
        .filter_map(|(k, bl)| bl.segment_entry_t(&a, &b).map(|t| (k, t)))
        .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)))
}

proptest! {
    #[test]
    fn index_point_queries_match_brute_force(e in -1600.0..1600.0_f64, n in -1600.0..1600.0_f64, z in -5.0..250.0_f64) {
        let world = shared();
        let brute = world.buildings().iter().find(|b| b.footprint_contains(e, n));
        prop_assert_eq!(world.building_at(e, n), brute);
        let pos = Vector3::new(e, n, z);
        prop_assert_eq!(world.is_inside_building(pos), world.buildings().iter().any(|b| b.contains(&pos)));
    }

    #[test]
    fn index_segment_queries_match_brute_force(
        a in (-1600.0..1600.0_f64, -1600.0..1600.0_f64, -5.0..300.0_f64),
        len in 0.0..2500.0_f64,
        heading in 0.0..std::f64::consts::TAU,
        climb in -0.6..0.6_f64,
    ) {
        let world = shared();
        let a = Vector3::new(a.0, a.1, a.2);
        let b = a + Vector3::new(heading.cos(), heading.sin(), climb) * len;
        let got = world.segment_hits_building(a, b);
        let want = brute_hit(world, a, b);
        prop_assert_eq!(got.map(|g| g.0), want.map(|w| w.0));
        if let (Some((_, p)), Some((_, t))) = (got, want) {
            prop_assert!((p - (a + (b - a) * t)).norm() < 1e-9);
        }
    }
}

/// Prints the stats and generation time of a Chicago-like world (run with
/// `cargo test --release -p sim-worker world::tests::chicago -- --nocapture`).
#[test]
fn chicago_world_stats() {
    let started = std::time::Instant::now();
    let world = World::generate(&inputs(4000.0, None, vec![]));
    let elapsed = started.elapsed();
    println!("{}", world.stats());
    println!("generated in {:.1} ms", elapsed.as_secs_f64() * 1e3);
    assert!(world.stats().building_count > 5000);
}

/// Ball contact (`World::ball_touches_building`): a drone's rotor disc against prisms.
mod ball_contact {
    use nalgebra::Vector3;

    use crate::footprint::Footprint;
    use crate::{Building, World};

    fn tower() -> Building {
        let square = vec![[40.0, -10.0], [60.0, -10.0], [60.0, 10.0], [40.0, 10.0]];
        Building::new(Footprint::new(square, vec![]).unwrap(), 0.0, 60.0).unwrap()
    }

    /// An L: the 30 m square at the origin without its north-east 20 m quarter; roof 20 m.
    fn l_shape() -> Building {
        let outer = vec![[0.0, 0.0], [30.0, 0.0], [30.0, 10.0], [10.0, 10.0], [10.0, 30.0], [0.0, 30.0]];
        Building::new(Footprint::new(outer, vec![]).unwrap(), 0.0, 20.0).unwrap()
    }

    /// A 40 m block at the origin around a 20 m courtyard, on ground at 2 m; roof at 17 m.
    fn courtyard() -> Building {
        let outer = vec![[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]];
        let hole = vec![[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]];
        Building::new(Footprint::new(outer, vec![hole]).unwrap(), 2.0, 15.0).unwrap()
    }

    /// A diamond (convex, not axis-aligned) centred at (100, 100), 10 m to each corner.
    fn diamond() -> Building {
        let outer = vec![[100.0, 90.0], [110.0, 100.0], [100.0, 110.0], [90.0, 100.0]];
        Building::new(Footprint::new(outer, vec![]).unwrap(), 0.0, 30.0).unwrap()
    }

    fn world(buildings: Vec<Building>) -> World {
        World::of_buildings(500.0, buildings)
    }

    /// Drops a ball of `radius_m` from 40 m straight down at (east, north) in 5 cm steps and
    /// returns the height of its centre at first contact, or `None`.
    fn drop_ball(building: &Building, east_m: f64, north_m: f64, radius_m: f64) -> Option<f64> {
        let w = world(vec![building.clone()]);
        (0..=800)
            .map(|k| 40.0 - 0.05 * k as f64)
            .find(|&z| w.ball_touches_building(Vector3::new(east_m, north_m, z), radius_m).is_some())
    }

    #[test]
    fn a_ball_falling_into_a_courtyard_does_not_touch_and_one_over_the_wing_does() {
        let b = courtyard();
        assert_eq!(drop_ball(&b, 20.0, 20.0, 0.4), None, "the courtyard is open down to the ground");
        assert_eq!(drop_ball(&b, 11.0, 20.0, 0.4), None, "0.6 m clear of the courtyard's west wall");
        let z = drop_ball(&b, 5.0, 20.0, 0.4).expect("the west wing is solid");
        assert!((17.35..=17.4).contains(&z), "roof at 17 m, ball radius 0.4 m: first contact at {z}");
        let z = drop_ball(&b, 10.2, 20.0, 0.4).expect("grazes the courtyard's west wall");
        assert!(z <= 17.4 && z > 17.0, "{z}");
    }

    #[test]
    fn an_l_shape_is_solid_in_its_arms_and_open_in_its_notch() {
        let b = l_shape();
        assert_eq!(drop_ball(&b, 20.0, 20.0, 0.4), None, "the missing quarter");
        assert_eq!(drop_ball(&b, 11.0, 11.0, 0.4), None, "near the inner corner, 1 m off both walls");
        for (e, n) in [(5.0, 25.0), (25.0, 5.0), (5.0, 5.0)] {
            let z = drop_ball(&b, e, n, 0.4).expect("the arms are solid");
            assert!((20.35..=20.4).contains(&z), "{z}");
        }
    }

    /// Against brute force: the exact distance from the ball's centre to each prism (a 3-D
    /// lattice around the buildings, corners and edges included).
    #[test]
    fn contact_is_the_exact_distance_to_the_prism() {
        let radius_m = 0.4;
        let buildings = vec![l_shape(), courtyard(), diamond(), tower()];
        let w = world(buildings.clone());
        let distance = |b: &Building, p: &Vector3<f64>| {
            let horizontal = b.footprint().distance_m(p.x, p.y);
            let vertical = (b.base_up_m() - p.z).max(p.z - b.roof_up_m()).max(0.0);
            horizontal.hypot(vertical)
        };
        let mut touching = 0;
        for b in &buildings {
            let [lo_e, lo_n, hi_e, hi_n] = b.footprint().bounds();
            for i in 0..=((hi_e - lo_e + 4.0) / 0.7) as usize {
                for j in 0..=((hi_n - lo_n + 4.0) / 0.7) as usize {
                    for z in [
                        b.base_up_m() + 0.2,
                        b.base_up_m() + b.height_m() / 2.0,
                        b.roof_up_m() + 0.25,
                        b.roof_up_m() + 0.45,
                    ] {
                        let p =
                            Vector3::new(lo_e - 2.0 + 0.7 * i as f64 + 0.013, lo_n - 2.0 + 0.7 * j as f64 + 0.029, z);
                        let nearest = buildings.iter().map(|b| distance(b, &p)).fold(f64::INFINITY, f64::min);
                        if (nearest - radius_m).abs() < 1e-9 {
                            continue;
                        }
                        let hit = w.ball_touches_building(p, radius_m);
                        assert_eq!(
                            hit.is_some(),
                            nearest <= radius_m,
                            "ball at {p:?}, {nearest} m from the nearest prism"
                        );
                        if let Some(k) = hit {
                            assert!(distance(&buildings[k], &p) <= radius_m);
                            touching += 1;
                        }
                    }
                }
            }
        }
        assert!(touching > 1000, "the lattice covers the buildings: {touching}");
    }

    #[test]
    fn a_drone_flying_into_a_building_touches_it_and_one_above_does_not() {
        let w = world(vec![tower()]);
        let hit_at = (0..1000)
            .map(|step| step as f64 * 0.05) // 50 m/s east, 1 ms steps
            .find(|&x| w.ball_touches_building(Vector3::new(x, 0.0, 30.0), 0.4).is_some())
            .expect("the drone hits the tower's west face at x = 40 m");
        assert!((39.55..=39.65).contains(&hit_at), "first contact at {hit_at} (face at 40, ball radius 0.4)");
        assert!(
            (0..1000).all(|step| w
                .ball_touches_building(Vector3::new(50.0, 0.0, 60.41 + step as f64 * 0.01), 0.4)
                .is_none())
        );
        assert!(w.ball_touches_building(Vector3::new(50.0, 0.0, 60.39), 0.4).is_some(), "0.39 m over the roof");
    }
}
