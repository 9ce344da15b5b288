use super::*;

/// A 300 m x 290 m block, the size of the museum zone, counter-clockwise.
const BLOCK: [Point; 4] = [(0.0, 0.0), (300.0, 0.0), (300.0, 290.0), (0.0, 290.0)];
/// A "C" opening to the east: concave, with a 40 m notch between y = 30 and y = 70.
const C_SHAPE: [Point; 8] =
    [(0.0, 0.0), (100.0, 0.0), (100.0, 30.0), (30.0, 30.0), (30.0, 70.0), (100.0, 70.0), (100.0, 100.0), (0.0, 100.0)];

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn legs_through_near_or_past_a_polygon_are_told_apart() {
    // Straight through the block.
    assert_eq!(segment_polygon_distance((-50.0, 100.0), (350.0, 100.0), &BLOCK), 0.0);
    assert!(leg_enters(&BLOCK, (-50.0, 100.0), (350.0, 100.0), 0.0));
    // Past the north side, 10 m clear: enters only with a 15 m margin.
    assert!(close(segment_polygon_distance((-50.0, 300.0), (350.0, 300.0), &BLOCK), 10.0, 1e-9));
    assert!(!leg_enters(&BLOCK, (-50.0, 300.0), (350.0, 300.0), 5.0));
    assert!(leg_enters(&BLOCK, (-50.0, 300.0), (350.0, 300.0), 15.0));
    // Ending inside, and cutting a corner.
    assert_eq!(segment_polygon_distance((-50.0, 100.0), (10.0, 100.0), &BLOCK), 0.0);
    assert_eq!(segment_polygon_distance((-10.0, 20.0), (20.0, -10.0), &BLOCK), 0.0);
    // Diagonally past a corner: the distance is to the corner.
    assert!(close(segment_polygon_distance((-20.0, 10.0), (10.0, -20.0), &BLOCK), 10.0 / 2f64.sqrt(), 1e-9));
}

#[test]
fn a_leg_through_the_notch_of_a_concave_zone_keeps_its_distance() {
    // Along the middle of the notch (y = 50) from the east: 20 m from both arms.
    let d = segment_polygon_distance((150.0, 50.0), (40.0, 50.0), &C_SHAPE);
    assert!(close(d, 10.0, 1e-9), "10 m from the notch's back wall at x = 30: {d}");
    assert!(!leg_enters(&C_SHAPE, (150.0, 50.0), (50.0, 50.0), 15.0));
    // The centroid-free point deep in the notch is outside the polygon.
    assert_eq!(distance_to_polygon(&C_SHAPE, (60.0, 50.0)), 20.0);
    // A leg from the notch through the back wall enters.
    assert!(leg_enters(&C_SHAPE, (60.0, 50.0), (-10.0, 50.0), 0.0));
}

#[test]
fn the_offset_ring_surrounds_the_zone_at_the_offset() {
    let ring = offset_ring(&BLOCK, 30.0, 2.0);
    assert!(ring.len() > 600, "about every 2 m round a 1.2 km outline: {}", ring.len());
    for &p in &ring {
        assert!(!polygon::contains(&BLOCK, p));
        assert!(close(distance_to_polygon(&BLOCK, p), 30.0, 0.05), "{p:?}");
    }
    // Every side and corner is covered (no gap longer than ~3 m).
    for i in 0..ring.len() {
        assert!(distance(ring[i], ring[(i + 1) % ring.len()]) < 3.0, "gap after {:?}", ring[i]);
    }
    // A concave outline: points that would crowd the notch are dropped.
    let c_ring = offset_ring(&C_SHAPE, 30.0, 2.0);
    assert!(!c_ring.is_empty());
    assert!(c_ring.iter().all(|&p| distance_to_polygon(&C_SHAPE, p) >= 29.99));
}

#[test]
fn hold_points_face_home_and_keep_apart() {
    // Two drones from the north-west, one from the south, one from the east.
    let homes = [(-600.0, 900.0), (-300.0, 1200.0), (150.0, -2000.0), (2000.0, 145.0)];
    let holds = hold_points(&BLOCK, &homes, 30.0, 40.0);
    assert_eq!(holds.len(), 4);
    for (h, home) in holds.iter().zip(&homes) {
        assert!(close(distance_to_polygon(&BLOCK, *h), 30.0, 0.05), "{h:?} is 30 m outside");
        // On the side facing home: no nearer to home than 30 m short of the zone, and not
        // much farther (the first one of a direction gets the nearest point).
        assert!(distance(*h, *home) >= distance_to_polygon(&BLOCK, *home) - 30.0 - 0.05);
        assert!(distance(*h, *home) <= distance_to_polygon(&BLOCK, *home) - 30.0 + 60.0, "{h:?} for {home:?}");
    }
    assert!(close(distance(holds[0], homes[0]), distance_to_polygon(&BLOCK, homes[0]) - 30.0, 0.5));
    assert!(holds[0].0 < 0.0 && holds[0].1 > 290.0, "north-west corner: {:?}", holds[0]);
    assert!(holds[2].1 < 0.0 && close(holds[2].0, 150.0, 1.0), "south side, facing home: {:?}", holds[2]);
    assert!(holds[3].0 > 300.0 && close(holds[3].1, 145.0, 1.0), "east side: {:?}", holds[3]);
    for i in 0..holds.len() {
        for j in 0..i {
            assert!(distance(holds[i], holds[j]) >= 40.0, "{:?} and {:?}", holds[i], holds[j]);
        }
    }
}

#[test]
fn watch_points_spread_inside_in_the_order_drones_come_from() {
    // Approaches from the west, north, east and south of the block.
    let approaches = [(-30.0, 145.0), (150.0, 320.0), (330.0, 145.0), (150.0, -30.0)];
    let points = inside_points(&BLOCK, &approaches, 60.0, 30.0);
    for &p in &points {
        assert!(polygon::contains(&BLOCK, p) && polygon::distance_to_boundary(&BLOCK, p) >= 30.0, "{p:?}");
    }
    for i in 0..points.len() {
        for j in 0..i {
            assert!(distance(points[i], points[j]) >= 30.0);
        }
    }
    let (w, n, e, s) = (points[0], points[1], points[2], points[3]);
    assert!(w.0 < n.0 && w.0 < e.0 && w.0 < s.0, "west drone on the west: {points:?}");
    assert!(n.1 > w.1 && n.1 > e.1 && n.1 > s.1, "north drone on the north: {points:?}");
    assert!(e.0 > n.0 && e.0 > s.0 && s.1 < w.1, "{points:?}");
    // Legs in from each approach do not cross each other.
    for i in 0..4 {
        for j in 0..i {
            assert!(!polygon::segments_intersect(approaches[i], points[i], approaches[j], points[j]));
        }
    }
    // A circle too big for a small zone shrinks until it fits.
    let small = [(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)];
    let pts = inside_points(&small, &approaches, 60.0, 30.0);
    assert!(pts.iter().all(|&p| polygon::distance_to_boundary(&small, p) >= 30.0 && polygon::contains(&small, p)));
    assert!(inside_points(&BLOCK, &[], 60.0, 30.0).is_empty());
}

#[test]
fn north_side_spots_line_up_north_of_the_zone() {
    let spots = north_side_spots(&BLOCK, 10, 40.0, 15.0);
    assert_eq!(spots.len(), 10);
    for (i, &s) in spots.iter().enumerate() {
        assert!(close(s.1, 330.0, 1e-9), "40 m north of the north side: {s:?}");
        assert!(distance_to_polygon(&BLOCK, s) >= 40.0 - 1e-9);
        assert!((15.0..=285.0).contains(&s.0));
        if i > 0 {
            assert!(s.0 - spots[i - 1].0 >= 29.99, "west to east, 30 m apart: {spots:?}");
        }
    }
    assert_eq!(north_side_spots(&BLOCK, 1, 40.0, 15.0), vec![(150.0, 330.0)]);
    // A sloping north side: spots are pushed north until they keep the distance.
    let slope = [(0.0, 0.0), (200.0, 0.0), (200.0, 100.0), (0.0, 200.0)];
    for s in north_side_spots(&slope, 5, 40.0, 15.0) {
        assert!(distance_to_polygon(&slope, s) >= 40.0 - 0.01 && distance_to_polygon(&slope, s) < 41.0, "{s:?}");
    }
}

#[test]
fn a_point_inside_from_a_spot_is_straight_in() {
    let p = point_inside_from(&BLOCK, (150.0, 330.0), 60.0);
    assert!(close(p.0, 150.0, 1e-9) && close(p.1, 230.0, 1e-9), "{p:?}");
    // Too deep for the polygon: falls back to its middle.
    assert_eq!(point_inside_from(&BLOCK, (150.0, 330.0), 400.0), centroid(&BLOCK));
}

#[test]
fn centroid_and_anchor_of_a_concave_polygon() {
    assert_eq!(centroid(&BLOCK), (150.0, 145.0));
    let u = [
        (0.0, 0.0),
        (100.0, 0.0),
        (100.0, 100.0),
        (90.0, 100.0),
        (90.0, 10.0),
        (10.0, 10.0),
        (10.0, 100.0),
        (0.0, 100.0),
    ];
    assert!(!polygon::contains(&u, centroid(&u)), "the U's centroid is in its cup");
    let a = interior_anchor(&u);
    assert!(polygon::contains(&u, a) && polygon::distance_to_boundary(&u, a) >= 4.0, "{a:?}");
}

#[test]
fn routes_go_round_zones_with_clearance() {
    let start = (-200.0, 145.0);
    let goal = (500.0, 145.0);
    let obstacles = vec![BLOCK.to_vec()];
    let path = route(start, goal, &obstacles, 20.0).expect("a way round");
    assert_eq!(*path.last().unwrap(), goal);
    assert!(path.len() >= 3, "two turns round the block: {path:?}");
    let mut at = start;
    for &p in &path {
        assert!(segment_polygon_distance(at, p, &BLOCK) >= 20.0 - 1e-6, "leg {at:?} -> {p:?}");
        at = p;
    }
    // Shortest way round: over the north or south side, not much longer than needed.
    let length = path_length(start, &path);
    assert!(length < 700.0 + 2.0 * 200.0, "{length}");
    // A clear leg is flown straight.
    assert_eq!(route((-200.0, 400.0), (500.0, 400.0), &obstacles, 20.0), Some(vec![(500.0, 400.0)]));
    // Leaving a zone one is inside: straight out.
    assert_eq!(route((150.0, 145.0), goal, &obstacles, 20.0), Some(vec![goal]));
}

#[test]
fn a_start_close_to_a_zone_can_still_leave() {
    // 5 m from the west side, going round to the east: the clearance shrinks to 5 m.
    let path = route((-5.0, 145.0), (400.0, 145.0), &[BLOCK.to_vec()], 20.0).expect("a way out");
    let mut at = (-5.0, 145.0);
    for &p in &path {
        assert!(segment_polygon_distance(at, p, &BLOCK) >= 5.0 - 1e-6);
        at = p;
    }
}

#[test]
fn routes_enter_the_cup_of_a_concave_zone_through_its_opening() {
    // Goal deep in the notch of the C (opening east), start west of it.
    let goal = (70.0, 50.0);
    let path = route((-100.0, 50.0), goal, &[C_SHAPE.to_vec()], 5.0).expect("through the opening");
    let mut at = (-100.0, 50.0);
    for &p in &path {
        assert!(segment_polygon_distance(at, p, &C_SHAPE) >= 5.0 - 1e-6, "leg {at:?} -> {p:?}");
        at = p;
    }
    assert!(path.iter().any(|p| p.0 > 100.0), "comes in from the east: {path:?}");
}

#[test]
fn a_walled_in_goal_has_no_route() {
    // Four overlapping walls round (0, 0).
    let wall = |x0: f64, y0: f64, x1: f64, y1: f64| vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
    let walls = vec![
        wall(-60.0, 40.0, 60.0, 60.0),
        wall(-60.0, -60.0, 60.0, -40.0),
        wall(-60.0, -60.0, -40.0, 60.0),
        wall(40.0, -60.0, 60.0, 60.0),
    ];
    assert_eq!(route((500.0, 0.0), (0.0, 0.0), &walls, 5.0), None);
}
