use super::*;
use crate::geometry::{distance, distance_to_polygon, leg_enters, route};
use sadesim_crds::polygon;

/// The case study's scenario, as shipped.
const SCENARIO: &str = include_str!("../../../../chicago-museum.yaml");

struct Case {
    frame: LocalFrame,
    zone: Vec<Point>,
    parks: Vec<Disc>,
}

fn case() -> Case {
    let run = sadesim_crds::document::parse_run(SCENARIO).expect("the example parses");
    let frame = LocalFrame::new(run.spec.origin.geo());
    let zone = run.spec.zones[0].polygon.iter().map(|v| frame.to_plane(v.latitude_deg, v.longitude_deg)).collect();
    let parks = parks(&run.spec, &frame);
    Case { frame, zone, parks }
}

fn at(c: &Case, lat: f64, lon: f64) -> Point {
    c.frame.to_plane(lat, lon)
}

/// The five DPS homes of the example (Daley Plaza, Engine 42, Engine 5, Quinn Fire
/// Academy, 1st District), ten journalists west of the zone and three hobbyists.
fn members(c: &Case) -> Vec<Member> {
    let ps = [(41.8837, -87.6300), (41.8907, -87.6303), (41.8777, -87.6441), (41.8690, -87.6418), (41.8587, -87.6279)];
    let mut m: Vec<Member> =
        ps.iter().map(|&(la, lo)| Member { role: Role::PublicSafety, home: at(c, la, lo) }).collect();
    for k in 0..10 {
        let home = at(c, 41.8806 + 0.002 * (f64::from(k) - 5.0), -87.6370 - 0.001 * f64::from(k));
        m.push(Member { role: Role::Journalist, home });
    }
    for (la, lo) in [(41.8826, -87.6225), (41.8758, -87.6190), (41.8590, -87.6083)] {
        m.push(Member { role: Role::Recreational, home: at(c, la, lo) });
    }
    m.push(Member { role: Role::Delivery, home: at(c, 41.87, -87.63) });
    m
}

#[test]
fn the_scenario_gives_nine_parks() {
    let c = case();
    assert_eq!(c.parks.len(), 1 + 8, "Millennium Park (open area) and the hobbyists' eight parks");
    let millennium = c.parks[0];
    assert_eq!(millennium.radius_m, 150.0);
    assert!(distance(millennium.center, at(&c, 41.8826, -87.6225)) < 1e-6);
}

#[test]
fn public_safety_holds_outside_facing_home_and_watches_from_spread_points_inside() {
    let c = case();
    let m = members(&c);
    let tasks = assign(&m, &c.zone, &c.parks);
    let mut holds = Vec::new();
    let mut watches = Vec::new();
    for (member, task) in m.iter().zip(&tasks).filter(|(m, _)| m.role == Role::PublicSafety) {
        let Task::PublicSafety { hold, watch } = *task else { panic!("{task:?}") };
        let out = distance_to_polygon(&c.zone, hold);
        assert!((out - HOLD_OFFSET_M).abs() < 0.1, "hold {out} m outside");
        // The way there from home does not need to cross the zone, and exists round it.
        assert!(route(member.home, hold, std::slice::from_ref(&c.zone), 20.0).is_some());
        assert!(
            distance(member.home, hold) < distance_to_polygon(&c.zone, member.home) + 80.0,
            "the hold point is on the side facing home"
        );
        assert!(polygon::contains(&c.zone, watch));
        assert!(polygon::distance_to_boundary(&c.zone, watch) >= WATCH_MARGIN_M);
        holds.push(hold);
        watches.push(watch);
    }
    assert_eq!(holds.len(), 5);
    for i in 0..5 {
        for j in 0..i {
            assert!(distance(holds[i], holds[j]) >= HOLD_SEPARATION_M, "holds {i} and {j}");
            assert!(distance(watches[i], watches[j]) >= 30.0, "watch points {i} and {j}");
            assert!(
                !polygon::segments_intersect(holds[i], watches[i], holds[j], watches[j]),
                "the legs in of {i} and {j} cross"
            );
        }
    }
}

#[test]
fn journalists_film_from_north_of_the_zone_in_the_order_of_their_homes() {
    let c = case();
    let m = members(&c);
    let tasks = assign(&m, &c.zone, &c.parks);
    let (_, _, _, zone_north) = crate::geometry::bounds(&c.zone);
    let mut by_home: Vec<(f64, Point, Point)> = Vec::new();
    for (member, task) in m.iter().zip(&tasks).filter(|(m, _)| m.role == Role::Journalist) {
        let Task::Journalist { spot, inside } = *task else { panic!("{task:?}") };
        assert!(spot.1 > zone_north, "north of the zone: {spot:?}");
        assert!(distance_to_polygon(&c.zone, spot) >= SPOT_OFFSET_M - 0.01);
        assert!(polygon::contains(&c.zone, inside));
        // Straight in from the spot, beyond the corner insets.
        assert!((spot.1 - inside.1 - SPOT_OFFSET_M - INTRUSION_DEPTH_M).abs() < 1.0, "{spot:?} -> {inside:?}");
        assert!(polygon::distance_to_boundary(&c.zone, inside) >= SPOT_INSET_M - 0.01);
        by_home.push((member.home.0, spot, inside));
    }
    assert_eq!(by_home.len(), 10);
    by_home.sort_by(|a, b| a.0.total_cmp(&b.0));
    for w in by_home.windows(2) {
        assert!(w[1].1.0 - w[0].1.0 >= 25.0, "west to east, spread: {:?} {:?}", w[0].1, w[1].1);
    }
}

#[test]
fn hobbyists_wander_over_their_own_park_clear_of_the_zone() {
    let c = case();
    let m = members(&c);
    let tasks = assign(&m, &c.zone, &c.parks);
    let areas: Vec<Disc> = tasks
        .iter()
        .filter_map(|t| match t {
            Task::Recreational { area } => Some(*area),
            _ => None,
        })
        .collect();
    assert_eq!(areas.len(), 3);
    let millennium = areas[0];
    assert_eq!(millennium.radius_m, 150.0 - PARK_MARGIN_M);
    assert_eq!(areas[1].radius_m, 120.0 - PARK_MARGIN_M, "Grant Park (Buckingham Fountain)");
    for a in &areas {
        assert!(distance_to_polygon(&c.zone, a.center) - a.radius_m > 15.0, "no park reaches the zone");
    }
    // A leg across Millennium Park stays clear of the zone.
    let (w, e) =
        ((millennium.center.0 - 140.0, millennium.center.1), (millennium.center.0 + 140.0, millennium.center.1));
    assert!(!leg_enters(&c.zone, w, e, 15.0));
    assert_eq!(tasks.last(), Some(&Task::Unassigned), "no behaviour for delivery drones");
}

#[test]
fn without_a_park_a_hobbyist_wanders_round_home() {
    let parks = [Disc { center: (0.0, 0.0), radius_m: 100.0 }, Disc { center: (10.0, 0.0), radius_m: 50.0 }];
    assert_eq!(operating_area((20.0, 0.0), &parks), Disc { center: (10.0, 0.0), radius_m: 40.0 }, "the smallest");
    assert_eq!(operating_area((80.0, 0.0), &parks), Disc { center: (0.0, 0.0), radius_m: 90.0 });
    assert_eq!(operating_area((500.0, 0.0), &parks), Disc { center: (500.0, 0.0), radius_m: WANDER_RADIUS_M });
}

#[test]
fn inside_altitudes_keep_the_lease_minimum_the_band_and_the_ceiling() {
    let ps = inside_altitude(114.3, PUBLIC_SAFETY_BAND, Some(106.68), None, 121.92, 3.0);
    assert_eq!(ps, Some(114.3), "375 ft is above the 350 ft minimum");
    // A stricter lease lifts the drone into the band's upper part.
    assert_eq!(inside_altitude(114.3, PUBLIC_SAFETY_BAND, Some(115.0), None, 121.92, 3.0), Some(118.0));
    // ...or makes entering impossible under the ceiling.
    assert_eq!(inside_altitude(114.3, PUBLIC_SAFETY_BAND, Some(119.0), None, 121.92, 3.0), None);
    // A hobbyist under 100 ft can never keep 350 ft.
    assert_eq!(inside_altitude(20.0, RECREATIONAL_BAND, Some(106.68), None, 30.48, 3.0), None);
    assert_eq!(inside_altitude(20.0, RECREATIONAL_BAND, None, Some(20.0), 30.48, 3.0), Some(17.0));
    assert_eq!(inside_altitude(5.0, RECREATIONAL_BAND, None, None, 30.48, 3.0), Some(15.0));
}

#[test]
fn the_way_home_costs_more_into_the_wind() {
    let run = sadesim_crds::document::parse_run(SCENARIO).unwrap();
    let w = wind(&run.spec);
    assert!((w.from.0 + 1.0).abs() < 1e-9 && w.from.1.abs() < 1e-9, "a westerly comes from the west: {w:?}");
    assert_eq!(w.speed_mps, 5.0);
    let west = return_cost_factor((-500.0, 0.0), Some(w));
    let south = return_cost_factor((0.0, -500.0), Some(w));
    let east = return_cost_factor((500.0, 0.0), Some(w));
    assert!((west - 2.15).abs() < 1e-9 && (south - 1.25).abs() < 1e-9 && east == 1.0, "{west} {south} {east}");
    assert_eq!(return_cost_factor((0.0, 1.0), None), west, "unknown wind: assume a headwind");
    let calm = Wind { from: (0.0, 1.0), speed_mps: 0.0 };
    assert_eq!(return_cost_factor((1.0, 1.0), Some(calm)), 1.25);
}
