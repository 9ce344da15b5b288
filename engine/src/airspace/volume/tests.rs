use proptest::prelude::*;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::geo::GeoPoint;
use sadesim_crds::zones::AltitudeReference::{Agl, Msl};

use super::*;

/// The origin's altitude in these tests (downtown Chicago), metres MSL.
const ORIGIN_MSL_M: f64 = 181.0;

/// A "U" open to the north, counter-clockwise: arms x in [0, 10] and [20, 30], base
/// y in [0, 10]; the notch x in (10, 20), y in (10, 30] is outside.
const U_SHAPE: [Point; 8] =
    [(0.0, 0.0), (30.0, 0.0), (30.0, 30.0), (20.0, 30.0), (20.0, 10.0), (10.0, 10.0), (10.0, 30.0), (0.0, 30.0)];

fn alt(height_m: f64, reference: AltitudeReference) -> ZoneAltitude {
    ZoneAltitude { height_m, reference }
}

fn volume(polygon: &[Point], floor: ZoneAltitude, ceiling: ZoneAltitude) -> ZoneVolume {
    ZoneVolume {
        name: "test-zone".into(),
        polygon: polygon.to_vec(),
        floor,
        ceiling,
        active_from_s: 0.0,
        active_until_s: f64::INFINITY,
        origin_msl_m: ORIGIN_MSL_M,
    }
}

/// The U, 0-150 m AGL, in both windings.
fn u_volumes() -> [ZoneVolume; 2] {
    let ccw = volume(&U_SHAPE, alt(0.0, Agl), alt(150.0, Agl));
    let mut cw = ccw.clone();
    cw.polygon.reverse();
    [ccw, cw]
}

/// A cone-shaped hill on flat ground at 0: `height_m` at `center`, 0 from `radius_m` out.
struct Hill {
    center: Point,
    height_m: f64,
    radius_m: f64,
}

impl Ground for Hill {
    fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64 {
        let d = (east_m - self.center.0).hypot(north_m - self.center.1);
        (self.height_m * (1.0 - d / self.radius_m)).max(0.0)
    }
}

/// A valley west of x = 0 (ground -30 m) and a plateau east of it (ground +70 m).
struct ValleyAndPlateau;

impl Ground for ValleyAndPlateau {
    fn ground_up_m(&self, east_m: f64, _north_m: f64) -> f64 {
        if east_m < 0.0 { -30.0 } else { 70.0 }
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn lerp(a: Enu, b: Enu, t: f64) -> Enu {
    Enu::new(
        a.east_m + t * (b.east_m - a.east_m),
        a.north_m + t * (b.north_m - a.north_m),
        a.up_m + t * (b.up_m - a.up_m),
    )
}

// ---- Horizontal: concave outlines, boundary, winding ----

#[test]
fn concave_outline_contains_the_arms_and_base_but_not_the_notch() {
    for v in u_volumes() {
        assert!(v.contains_horizontal(5.0, 20.0), "west arm");
        assert!(v.contains_horizontal(25.0, 20.0), "east arm");
        assert!(v.contains_horizontal(15.0, 5.0), "base");
        assert!(!v.contains_horizontal(15.0, 20.0), "the notch is outside");
        assert!(!v.contains_horizontal(15.0, 10.5), "just inside the notch is outside");
        assert!(!v.contains_horizontal(15.0, 35.0), "north of the notch");
        assert!(!v.contains_horizontal(-1.0, 5.0));
        assert!(!v.contains_horizontal(31.0, 5.0));
    }
}

#[test]
fn boundary_points_and_vertices_count_as_inside() {
    for v in u_volumes() {
        for (e, n) in [
            (0.0, 15.0),  // outer west edge
            (15.0, 0.0),  // outer south edge
            (15.0, 10.0), // bottom of the notch
            (10.0, 20.0), // notch's west side
            (20.0, 25.0), // notch's east side
            (30.0, 0.0),  // convex vertex
            (20.0, 10.0), // reflex vertex
            (10.0, 30.0), // top of the west arm
            (25.0, 30.0), // top edge of the east arm
        ] {
            assert!(v.contains_horizontal(e, n), "({e}, {n}) is on the outline");
        }
        assert!(!v.contains_horizontal(30.001, 15.0), "1 mm outside the east edge");
        assert!(!v.contains_horizontal(15.0, 10.001), "1 mm into the notch");
    }
}

#[test]
fn distance_to_boundary_is_positive_inside_and_outside() {
    let [v, _] = u_volumes();
    assert!(close(v.distance_to_boundary_m(5.0, 20.0), 5.0, 1e-12), "centre of the west arm");
    assert!(close(v.distance_to_boundary_m(15.0, 20.0), 5.0, 1e-12), "centre of the notch");
    assert!(close(v.distance_to_boundary_m(40.0, 0.0), 10.0, 1e-12));
    assert_eq!(v.distance_to_boundary_m(15.0, 10.0), 0.0);
}

// ---- Vertical: AGL and MSL ----

#[test]
fn agl_limits_ride_on_the_ground_and_msl_limits_do_not() {
    let agl = volume(&U_SHAPE, alt(20.0, Agl), alt(150.0, Agl));
    assert_eq!(agl.vertical_limits_up_m(0.0), (20.0, 150.0));
    assert_eq!(agl.vertical_limits_up_m(-30.0), (-10.0, 120.0));
    assert_eq!(agl.vertical_limits_up_m(70.0), (90.0, 220.0));
    // MSL heights are measured from sea level: ENU up = height - 181 m.
    let msl = volume(&U_SHAPE, alt(201.0, Msl), alt(331.0, Msl));
    assert_eq!(msl.vertical_limits_up_m(0.0), (20.0, 150.0));
    assert_eq!(msl.vertical_limits_up_m(70.0), (20.0, 150.0));
    // Mixed: AGL floor, MSL ceiling.
    let mixed = volume(&U_SHAPE, alt(0.0, Agl), alt(331.0, Msl));
    assert_eq!(mixed.vertical_limits_up_m(40.0), (40.0, 150.0));
}

#[test]
fn the_same_point_is_inside_an_agl_zone_over_a_valley_and_outside_over_a_hill() {
    // 50-150 m AGL over a big square; the point is 100 m above the origin's ground.
    let square = [(-500.0, -500.0), (500.0, -500.0), (500.0, 500.0), (-500.0, 500.0)];
    let agl = volume(&square, alt(50.0, Agl), alt(150.0, Agl));
    let msl = volume(&square, alt(ORIGIN_MSL_M + 50.0, Msl), alt(ORIGIN_MSL_M + 150.0, Msl));
    let p = Enu::new(100.0, 0.0, 100.0);
    // Over a valley the point is 130 m above the ground, over a 70 m hill only 30 m.
    assert!(agl.contains(p, -30.0));
    assert!(!agl.contains(p, 70.0), "30 m AGL is below the 50 m AGL floor");
    assert!(msl.contains(p, -30.0) && msl.contains(p, 70.0), "MSL limits ignore the ground");

    // The same through a terrain model: one height, two places.
    let over_valley = Enu::new(-100.0, 0.0, 100.0);
    let over_plateau = Enu::new(100.0, 0.0, 100.0);
    let ground = |p: Enu| ValleyAndPlateau.ground_up_m(p.east_m, p.north_m);
    assert!(agl.contains(over_valley, ground(over_valley)));
    assert!(!agl.contains(over_plateau, ground(over_plateau)));
    assert!(msl.contains(over_valley, ground(over_valley)));
    assert!(msl.contains(over_plateau, ground(over_plateau)));

    // And a hill: 100 m up is outside over its 60 m summit, inside 40 m from it (ground 36 m).
    let hill = Hill { center: (0.0, 0.0), height_m: 60.0, radius_m: 100.0 };
    assert!(!agl.contains(Enu::new(0.0, 0.0, 100.0), hill.ground_up_m(0.0, 0.0)));
    assert!(agl.contains(Enu::new(40.0, 0.0, 100.0), hill.ground_up_m(40.0, 0.0)));
}

#[test]
fn floor_and_ceiling_are_included_and_the_outline_must_match_too() {
    for v in u_volumes() {
        assert!(v.contains(Enu::new(5.0, 5.0, 0.0), 0.0), "on the floor");
        assert!(v.contains(Enu::new(5.0, 5.0, 150.0), 0.0), "on the ceiling");
        assert!(!v.contains(Enu::new(5.0, 5.0, 150.01), 0.0), "above the ceiling");
        assert!(!v.contains(Enu::new(5.0, 5.0, -0.01), 0.0), "below the floor");
        assert!(!v.contains(Enu::new(15.0, 20.0, 50.0), 0.0), "right height, in the notch");
    }
}

// ---- Construction and time windows ----

#[test]
fn new_projects_the_zone_and_defaults_the_floor_and_window() {
    let run = RunBuilder::test().with_zone("box").build();
    let frame = LocalFrame::new(run.spec.origin.geo());
    let v = ZoneVolume::new(&run.spec.zones[0], &frame);
    assert_eq!(v.name, "box");
    assert_eq!(v.floor, alt(0.0, Agl), "no floor means the ground");
    assert_eq!(v.ceiling, alt(150.0, Agl));
    assert_eq!((v.active_from_s, v.active_until_s), (0.0, f64::INFINITY));
    assert_eq!(v.origin_msl_m, 181.0);
    assert!(v.is_active(0.0) && v.is_active(1e9));
    // The fixture's square is +-0.0009 deg around the origin: ~100 m north and south,
    // ~75 m east and west at 41.9 deg N.
    assert_eq!(v.polygon.len(), 4);
    let (sw, ne) = (v.polygon[0], v.polygon[2]);
    assert!(close(sw.1, -100.0, 1.0) && close(ne.1, 100.0, 1.0), "{sw:?} {ne:?}");
    assert!(close(sw.0, -74.6, 1.0) && close(ne.0, 74.6, 1.0), "{sw:?} {ne:?}");
    assert!(v.contains_horizontal(0.0, 0.0));
}

#[test]
fn a_zone_is_active_from_its_start_until_just_before_its_end() {
    let run = RunBuilder::test()
        .with_zone("later")
        .with(|r| {
            r.spec.zones[0].active_from = Some(serde_yaml::from_str("1m").unwrap());
            r.spec.zones[0].active_until = Some(serde_yaml::from_str("5m").unwrap());
        })
        .build();
    let v = ZoneVolume::new(&run.spec.zones[0], &LocalFrame::new(run.spec.origin.geo()));
    assert_eq!((v.active_from_s, v.active_until_s), (60.0, 300.0));
    assert!(!v.is_active(0.0));
    assert!(!v.is_active(59.999));
    assert!(v.is_active(60.0));
    assert!(v.is_active(299.999));
    assert!(!v.is_active(300.0));
}

#[test]
fn the_chicago_museum_zone_is_a_300_by_290_m_block_around_the_origin() {
    let run = sadesim_crds::document::parse_run(include_str!("../../../../examples/chicago-museum.yaml"))
        .expect("the example parses");
    let zone = run.spec.zones.iter().find(|z| z.name == "museum-tfr").expect("museum zone");
    let frame = LocalFrame::new(run.spec.origin.geo());
    let v = ZoneVolume::new(zone, &frame);
    let east: Vec<f64> = v.polygon.iter().map(|p| p.0).collect();
    let north: Vec<f64> = v.polygon.iter().map(|p| p.1).collect();
    let span = |xs: &[f64]| {
        xs.iter().copied().fold(f64::NEG_INFINITY, f64::max) - xs.iter().copied().fold(f64::INFINITY, f64::min)
    };
    // 0.0037 deg of longitude at 41.88 N and 0.0026 deg of latitude.
    assert!(close(span(&east), 307.0, 2.0), "east-west {} m", span(&east));
    assert!(close(span(&north), 289.0, 2.0), "north-south {} m", span(&north));
    // The origin (in front of the museum) is inside; 200 m north of it is Monroe St and beyond.
    assert!(v.contains_horizontal(0.0, 0.0));
    assert!(!v.contains_horizontal(0.0, 200.0));
    // Round trip: each vertex projects back to its lat/lon (centimetres).
    for (ll, p) in zone.polygon.iter().zip(&v.polygon) {
        let g = frame.to_geodetic(Enu::new(p.0, p.1, 0.0));
        assert!(close(g.latitude_deg, ll.latitude_deg, 1e-7) && close(g.longitude_deg, ll.longitude_deg, 1e-7));
    }
    // 500 ft AGL ceiling: 400 ft inside, 600 ft outside.
    assert!(v.contains(Enu::new(0.0, 0.0, 400.0 * 0.3048), 0.0));
    assert!(!v.contains(Enu::new(0.0, 0.0, 600.0 * 0.3048), 0.0));
    assert_eq!(frame.origin(), GeoPoint::new(41.8796, -87.6237, 181.0));
}

// ---- Segments: crossings at speed ----

#[test]
fn a_segment_starting_inside_is_inside_at_zero() {
    for v in u_volumes() {
        assert_eq!(v.first_inside(Enu::new(5.0, 5.0, 50.0), Enu::new(50.0, 50.0, 50.0), &FlatGround(0.0)), Some(0.0));
    }
}

#[test]
fn one_second_at_30_mps_from_the_notch_through_the_east_arm_is_caught() {
    // Both ends are outside (in the notch, then east of the U): a 1 s sampler would miss
    // the 10 m of arm in between.
    let (a, b) = (Enu::new(5.0 + 10.0, 20.0, 50.0), Enu::new(45.0, 20.0, 50.0));
    for v in u_volumes() {
        assert!(!v.contains(a, 0.0) && !v.contains(b, 0.0));
        let t = v.first_inside(a, b, &FlatGround(0.0)).expect("crosses the east arm");
        assert!(close(t, 5.0 / 30.0, 1e-12), "enters at x = 20: {t}");
    }
}

#[test]
fn a_segment_clipping_a_corner_between_samples_is_caught() {
    // 30 m/s heading north-east: clips the U's south-east corner, x in [29, 30], y in [0, 1].
    let (a, b) = (Enu::new(24.0, -5.0, 50.0), Enu::new(34.0, 5.0, 50.0));
    for v in u_volumes() {
        let t = v.first_inside(a, b, &FlatGround(0.0)).expect("clips the corner");
        assert!(close(t, 0.5, 1e-12), "{t}");
        // Sampled every 0.01 s (0.3 m at 30 m/s over this 14 m segment): one sample lands
        // in the 1.4 m clip, later than the exact entry.
        let first_sample = (0..=47).map(|k| k as f64 / 47.0).find(|&s| v.contains(lerp(a, b, s), 0.0));
        assert!(first_sample.is_some_and(|s| s >= t), "{first_sample:?}");
    }
}

#[test]
fn a_segment_clipping_the_notch_corner_is_caught() {
    // From the notch north-west across the top corner of the west arm (10, 30): the line
    // y = 39 - x is inside the arm for x in [9, 10] only (1.4 m of a 8.5 m segment).
    let (a, b) = (Enu::new(12.0, 27.0, 50.0), Enu::new(6.0, 33.0, 50.0));
    for v in u_volumes() {
        assert!(!v.contains(a, 0.0) && !v.contains(b, 0.0));
        assert!(!v.contains(lerp(a, b, 0.25), 0.0) && !v.contains(lerp(a, b, 0.75), 0.0), "samples miss it");
        let t = v.first_inside(a, b, &FlatGround(0.0)).expect("clips the arm's corner");
        assert!(close(t, 1.0 / 3.0, 1e-12), "enters at x = 10: {t}");
    }
}

#[test]
fn touching_a_vertex_or_sliding_along_an_edge_counts() {
    for v in u_volumes() {
        // Touches only the south-east vertex (30, 0), halfway.
        let t = v.first_inside(Enu::new(25.0, -5.0, 50.0), Enu::new(35.0, 5.0, 50.0), &FlatGround(0.0));
        assert!(t.is_some_and(|t| close(t, 0.5, 1e-12)), "{t:?}");
        // Slides along the south edge from outside: reaches it at x = 0.
        let t = v.first_inside(Enu::new(-5.0, 0.0, 50.0), Enu::new(5.0, 0.0, 50.0), &FlatGround(0.0));
        assert!(t.is_some_and(|t| close(t, 0.5, 1e-12)), "{t:?}");
        // Misses the vertex by 1 cm.
        let t = v.first_inside(Enu::new(25.01, -5.0, 50.0), Enu::new(35.01, 5.0, 50.0), &FlatGround(0.0));
        assert_eq!(t, None);
    }
}

#[test]
fn a_segment_passing_over_the_zone_above_its_ceiling_never_enters() {
    for v in u_volumes() {
        // 30 m/s, 1 s sampling: across the base 10 m above the 150 m ceiling.
        let (a, b) = (Enu::new(-10.0, 5.0, 160.0), Enu::new(40.0, 5.0, 160.0));
        assert_eq!(v.first_inside(a, b, &FlatGround(0.0)), None);
        // Below the floor of a zone starting at 50 m AGL.
        let mut high = v.clone();
        high.floor = alt(50.0, Agl);
        assert_eq!(high.first_inside(Enu::new(-10.0, 5.0, 40.0), Enu::new(40.0, 5.0, 40.0), &FlatGround(0.0)), None);
        // Over the notch, inside the height band: never over the outline.
        assert_eq!(v.first_inside(Enu::new(15.0, 12.0, 50.0), Enu::new(15.0, 40.0, 50.0), &FlatGround(0.0)), None);
    }
}

#[test]
fn a_segment_diving_through_the_zone_enters_where_it_crosses_the_ceiling() {
    for v in u_volumes() {
        // Straight down at 30 m/s over the base: 200 m -> 140 m, ceiling 150 m at 5/6.
        let t = v.first_inside(Enu::new(5.0, 5.0, 200.0), Enu::new(5.0, 5.0, 140.0), &FlatGround(0.0));
        assert!(t.is_some_and(|t| close(t, 50.0 / 60.0, 1e-12)), "{t:?}");
        // Slanted: crosses the west edge (x = 0) at t = 1/3 still at 180 m, then descends
        // through the ceiling at t = 5/6 (x = 15, over the base).
        let (a, b) = (Enu::new(-10.0, 5.0, 200.0), Enu::new(20.0, 5.0, 140.0));
        let t = v.first_inside(a, b, &FlatGround(0.0)).expect("dives into the base");
        assert!(close(t, 5.0 / 6.0, 1e-12), "{t}");
        // Enters sideways below the ceiling: at the edge, t = 1/2.
        let t = v.first_inside(Enu::new(-30.0, 5.0, 170.0), Enu::new(30.0, 5.0, 110.0), &FlatGround(0.0));
        assert!(t.is_some_and(|t| close(t, 0.5, 1e-12)), "{t:?}");
        // Diving through the notch then the east arm: only the arm counts.
        let (a, b) = (Enu::new(15.0, 20.0, 300.0), Enu::new(35.0, 20.0, 100.0));
        let t = v.first_inside(a, b, &FlatGround(0.0)).expect("reaches the east arm below 150 m");
        // Over the arm (x 20..30, t 0.25..0.75) the height goes 250 -> 150: at 150 m at t = 0.75.
        assert!(close(t, 0.75, 1e-12), "{t}");
    }
}

#[test]
fn a_level_flight_enters_an_agl_zone_where_a_hill_lifts_it_and_not_an_msl_zone() {
    // Zone 0-60 m AGL over x in [0, 200]; a 50 m cone hill at x = 100, radius 50 m. Flying
    // level at 80 m: over flat ground that is 80 m AGL (above the ceiling); on the hill's
    // side at distance d from the top the ground is 50 - d, so 80 m is 30 + d m AGL, at
    // the ceiling for d = 30 m: x = 70.
    let square = [(0.0, -50.0), (200.0, -50.0), (200.0, 50.0), (0.0, 50.0)];
    let hill = Hill { center: (100.0, 0.0), height_m: 50.0, radius_m: 50.0 };
    let (a, b) = (Enu::new(-50.0, 0.0, 80.0), Enu::new(250.0, 0.0, 80.0));
    let agl = volume(&square, alt(0.0, Agl), alt(60.0, Agl));
    let t = agl.first_inside(a, b, &hill).expect("the hill brings the zone up to the drone");
    assert!(close(t, 120.0 / 300.0, 1e-9), "{t}");
    assert_eq!(agl.first_inside(a, b, &FlatGround(0.0)), None, "over flat ground it stays above");
    let msl = volume(&square, alt(ORIGIN_MSL_M, Msl), alt(ORIGIN_MSL_M + 60.0, Msl));
    assert_eq!(msl.first_inside(a, b, &hill), None, "MSL limits ignore the hill");
    // A descent that reaches 60 m over flat ground enters an MSL zone where it crosses 60 m.
    let t = msl.first_inside(Enu::new(0.0, 0.0, 100.0), Enu::new(200.0, 0.0, 0.0), &hill);
    assert!(t.is_some_and(|t| close(t, 0.4, 1e-12)), "{t:?}");
}

#[test]
fn an_agl_floor_over_a_cliff_is_found_between_samples() {
    // Zone 50-150 m AGL in a big square; level flight at 100 m up from over the plateau
    // (30 m AGL, below the floor) west into the valley (130 m AGL, inside).
    let square = [(-500.0, -500.0), (500.0, -500.0), (500.0, 500.0), (-500.0, 500.0)];
    let v = volume(&square, alt(50.0, Agl), alt(150.0, Agl));
    let (a, b) = (Enu::new(15.0, 0.0, 100.0), Enu::new(-15.0, 0.0, 100.0));
    let t = v.first_inside(a, b, &ValleyAndPlateau).expect("inside over the valley");
    // The cliff at x = 0 (t = 0.5) is a step: the ground is linear between samples 1 m
    // (1/30 of the segment) apart, so the entry is found within one spacing after it.
    assert!((0.5..=0.5 + 1.0 / 30.0).contains(&t), "{t}");
    let after = lerp(a, b, t + 1.0 / 30.0);
    assert!(v.contains(after, ValleyAndPlateau.ground_up_m(after.east_m, after.north_m)));
    assert_eq!(v.first_inside(b, a, &ValleyAndPlateau), Some(0.0), "starting over the valley: inside at once");
}

// ---- Property: agrees with dense sampling ----

/// `first_inside` is never later than any of 2001 samples along the segment that is inside,
/// and the point it returns is on or in the volume (within 1 µm).
fn check_against_sampling(v: &ZoneVolume, a: Enu, b: Enu) {
    let ground = FlatGround(0.0);
    let found = v.first_inside(a, b, &ground);
    let first_sample = (0..=2000).map(|k| k as f64 / 2000.0).find(|&s| v.contains(lerp(a, b, s), 0.0));
    match (found, first_sample) {
        (None, Some(s)) => panic!("missed: sample at {s} is inside"),
        (Some(t), Some(s)) => assert!(t <= s + 1e-9, "first_inside {t} after inside sample {s}"),
        _ => {}
    }
    if let Some(t) = found {
        let p = lerp(a, b, t);
        let (floor, ceiling) = v.vertical_limits_up_m(0.0);
        assert!(v.distance_to_boundary_m(p.east_m, p.north_m) <= 1e-6 || v.contains_horizontal(p.east_m, p.north_m));
        assert!(p.up_m >= floor - 1e-6 && p.up_m <= ceiling + 1e-6, "{p:?}");
    }
}

proptest! {
    #[test]
    fn first_inside_agrees_with_dense_sampling(
        ax in -20.0..50.0f64, ay in -20.0..50.0f64, az in -20.0..200.0f64,
        bx in -20.0..50.0f64, by in -20.0..50.0f64, bz in -20.0..200.0f64,
        reversed in any::<bool>(),
    ) {
        let mut v = volume(&U_SHAPE, alt(ORIGIN_MSL_M + 20.0, Msl), alt(ORIGIN_MSL_M + 150.0, Msl));
        if reversed {
            v.polygon.reverse();
        }
        check_against_sampling(&v, Enu::new(ax, ay, az), Enu::new(bx, by, bz));
    }
}
