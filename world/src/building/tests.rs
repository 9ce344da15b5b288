//! Prism geometry: the box behaviour of the procedural city, and polygon prisms (an L, a
//! courtyard, random star-shaped footprints with holes) checked against brute force.

use proptest::prelude::*;

use super::*;
use crate::footprint::Point2;

fn unit_box() -> Building {
    // 10 m x 20 m footprint centred at (100, 50), base 2 m, 30 m tall.
    let rect = AxisRect { center_east_m: 100.0, center_north_m: 50.0, half_east_m: 5.0, half_north_m: 10.0 };
    Building::boxed(rect, 2.0, 30.0)
}

/// An L: the 30 m x 30 m square at the origin without its north-east 20 m x 20 m quarter;
/// base 0, roof 20 m.
fn l_shape() -> Building {
    let outer = vec![[0.0, 0.0], [30.0, 0.0], [30.0, 10.0], [10.0, 10.0], [10.0, 30.0], [0.0, 30.0]];
    Building::new(Footprint::new(outer, vec![]).unwrap(), 0.0, 20.0).unwrap()
}

/// A 40 m x 40 m block at the origin around a 20 m x 20 m courtyard; base 0, roof 15 m.
pub(crate) fn courtyard() -> Building {
    let outer = vec![[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0], [0.0, 0.0]];
    let hole = vec![[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]];
    Building::new(Footprint::new(outer, vec![hole]).unwrap(), 0.0, 15.0).unwrap()
}

fn p(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

#[test]
fn contains_is_closed_and_bounded_by_base_and_roof() {
    let b = unit_box();
    assert_eq!(b.roof_up_m(), 32.0);
    assert!(b.contains(&p(100.0, 50.0, 10.0)));
    assert!(b.contains(&p(105.0, 60.0, 32.0)), "faces belong to the box");
    assert!(!b.contains(&p(100.0, 50.0, 32.1)), "above the roof");
    assert!(!b.contains(&p(100.0, 50.0, 1.9)), "below the base");
    assert!(!b.contains(&p(105.1, 50.0, 10.0)));
}

#[test]
fn segment_entry_hits_the_near_face_and_misses_beside_and_above() {
    let b = unit_box();
    let a = p(0.0, 50.0, 10.0);
    let t = b.segment_entry_t(&a, &p(200.0, 50.0, 10.0)).expect("crosses the box");
    assert!((a.x + t * 200.0 - 95.0).abs() < 1e-9, "enters through the west face at x = 95");
    assert_eq!(b.segment_entry_t(&a, &p(90.0, 50.0, 10.0)), None, "stops short");
    assert_eq!(b.segment_entry_t(&p(0.0, 70.0, 10.0), &p(200.0, 70.0, 10.0)), None);
    assert_eq!(b.segment_entry_t(&p(0.0, 50.0, 40.0), &p(200.0, 50.0, 40.0)), None);
    assert_eq!(b.segment_entry_t(&p(100.0, 50.0, 5.0), &p(0.0, 0.0, 0.0)), Some(0.0));
}

#[test]
fn disc_touch_uses_distance_to_the_nearest_footprint_point() {
    let b = unit_box();
    assert!(b.footprint_touches_disc(100.0, 50.0, 0.1), "centre inside");
    assert!(b.footprint_touches_disc(110.0, 50.0, 5.0), "touches the east face");
    assert!(!b.footprint_touches_disc(110.0, 50.0, 4.9));
    // Corner (105, 60): distance from (108, 64) is 5.
    assert!(b.footprint_touches_disc(108.0, 64.0, 5.0));
    assert!(!b.footprint_touches_disc(108.0, 64.0, 4.99));
}

#[test]
fn an_invalid_height_is_rejected() {
    let f =
        Footprint::rectangle(AxisRect { center_east_m: 0.0, center_north_m: 0.0, half_east_m: 1.0, half_north_m: 1.0 });
    assert_eq!(Building::new(f.clone(), 0.0, 0.0), Err(BuildingError::NotTall { height_m: 0.0 }));
    assert!(matches!(Building::new(f.clone(), f64::NAN, 3.0), Err(BuildingError::NotFinite { .. })));
    assert!(Building::new(f, -2.0, 3.0).is_ok());
}

#[test]
fn an_l_shape_blocks_its_arms_but_not_its_notch() {
    let b = l_shape();
    assert!(b.contains(&p(5.0, 25.0, 10.0)) && b.contains(&p(25.0, 5.0, 10.0)));
    assert!(!b.contains(&p(20.0, 20.0, 10.0)), "the missing quarter");
    assert_eq!(b.footprint_area_m2(), 500.0);
    // Through the notch only (north-east of the inner corner): clear.
    assert_eq!(b.segment_entry_t(&p(12.0, 40.0, 10.0), &p(40.0, 12.0, 10.0)), None);
    // Through both arms, west to east at north = 5: enters at x = 0.
    let t = b.segment_entry_t(&p(-10.0, 5.0, 10.0), &p(50.0, 5.0, 10.0)).unwrap();
    assert!((t - 10.0 / 60.0).abs() < 1e-12);
    // Through the upper arm then the notch at north = 20: inside for x in [0, 10] only.
    let got = b.segment_intervals(&p(-10.0, 20.0, 10.0), &p(50.0, 20.0, 10.0));
    assert_eq!(got.len(), 1);
    assert!((got[0].0 - 10.0 / 60.0).abs() < 1e-12 && (got[0].1 - 20.0 / 60.0).abs() < 1e-12, "{got:?}");
    // Over the roof: clear; a disc in the notch 2 m from both inner walls touches from 2 m.
    assert_eq!(b.segment_entry_t(&p(-10.0, 5.0, 21.0), &p(50.0, 5.0, 21.0)), None);
    assert!(!b.footprint_touches_disc(12.0, 12.0, 1.99) && b.footprint_touches_disc(12.0, 12.0, 2.0));
}

#[test]
fn line_of_sight_through_a_courtyard_is_clear_and_through_the_wall_blocked() {
    let b = courtyard();
    assert_eq!(b.footprint_area_m2(), 1600.0 - 400.0);
    assert!(!b.contains(&p(20.0, 20.0, 5.0)), "courtyard");
    assert!(b.contains(&p(10.0, 20.0, 5.0)), "the courtyard's wall face belongs to the building");
    // Inside the courtyard, drone to drone: clear.
    assert_eq!(b.segment_entry_t(&p(12.0, 12.0, 5.0), &p(28.0, 27.0, 14.0)), None);
    // From the courtyard up out of it, steeply: clear.
    assert_eq!(b.segment_entry_t(&p(20.0, 20.0, 2.0), &p(25.0, 25.0, 100.0)), None);
    // From the courtyard to the street at the same height: blocked by the east wing, at x = 30.
    let (a, end) = (p(20.0, 20.0, 5.0), p(60.0, 20.0, 5.0));
    let t = b.segment_entry_t(&a, &end).expect("the wing is in the way");
    assert!((a.x + t * 40.0 - 30.0).abs() < 1e-9);
    // Across the whole block: two stretches inside, the courtyard between them.
    let got = b.segment_intervals(&p(-10.0, 20.0, 5.0), &p(50.0, 20.0, 5.0));
    let want = [(10.0 / 60.0, 20.0 / 60.0), (40.0 / 60.0, 50.0 / 60.0)];
    assert_eq!(got.len(), 2, "{got:?}");
    for (g, w) in got.iter().zip(want) {
        assert!((g.0 - w.0).abs() < 1e-12 && (g.1 - w.1).abs() < 1e-12, "{got:?}");
    }
    // A disc in the courtyard's middle clear of the walls does not touch; one at a wall does.
    assert!(!b.footprint_touches_disc(20.0, 20.0, 9.9) && b.footprint_touches_disc(20.0, 20.0, 10.0));
}

/// A star-shaped ring around `c`: vertex `k` at angle `2 pi (k + 0.4 jitter_k) / n`, radius
/// `r_k` (gaps under pi, so `c` is inside).
fn star(c: Point2, radii: &[f64], jitter: &[f64], phase: f64) -> Vec<Point2> {
    let n = radii.len() as f64;
    radii
        .iter()
        .zip(jitter)
        .enumerate()
        .map(|(k, (r, j))| {
            let a = phase + std::f64::consts::TAU * (k as f64 + 0.4 * j) / n;
            [c[0] + r * a.cos(), c[1] + r * a.sin()]
        })
        .collect()
}

/// Distance from `c` to the nearest line through an edge of the ring: a disc this wide
/// around `c` lies inside a star-shaped ring.
fn inradius(ring: &[Point2], c: Point2) -> f64 {
    (0..ring.len())
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            ((c[0] - a[0]) * dy - (c[1] - a[1]) * dx).abs() / dx.hypot(dy)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Brute force, independent of the implementation: count the ring edges a ray from `q` in
/// the direction `heading` crosses; odd means inside.
fn ray_count_inside(rings: &[Vec<Point2>], q: Point2, heading: f64) -> bool {
    let d = [heading.cos(), heading.sin()];
    let mut count = 0;
    for ring in rings {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let denom = d[0] * e[1] - d[1] * e[0];
            if denom == 0.0 {
                continue;
            }
            let w = [a[0] - q[0], a[1] - q[1]];
            let t = (w[0] * e[1] - w[1] * e[0]) / denom;
            let s = (w[0] * d[1] - w[1] * d[0]) / denom;
            if t > 0.0 && (0.0..1.0).contains(&s) {
                count += 1;
            }
        }
    }
    count % 2 == 1
}

/// A random star-shaped footprint around (50, -20), with a star-shaped hole half the time.
fn footprints() -> impl Strategy<Value = (Vec<Vec<Point2>>, Footprint)> {
    (3..14_usize)
        .prop_flat_map(|n| {
            (
                prop::collection::vec(5.0..40.0_f64, n),
                prop::collection::vec(0.0..1.0_f64, n),
                0.0..std::f64::consts::TAU,
                prop::option::of((3..9_usize).prop_flat_map(|m| {
                    (prop::collection::vec(0.2..0.8_f64, m), prop::collection::vec(0.0..1.0_f64, m))
                })),
            )
        })
        .prop_map(|(radii, jitter, phase, hole)| {
            let c = [50.0, -20.0];
            let outer = star(c, &radii, &jitter, phase);
            let mut rings = vec![outer.clone()];
            if let Some((scale, jitter)) = hole {
                let r = inradius(&outer, c);
                let radii: Vec<f64> = scale.iter().map(|s| s * r).collect();
                rings.push(star(c, &radii, &jitter, 0.3));
            }
            let footprint = Footprint::new(outer, rings[1..].to_vec()).expect("a star-shaped ring is valid");
            (rings, footprint)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn contains_agrees_with_a_brute_force_ray_count(
        (rings, footprint) in footprints(),
        q in (0.0..100.0_f64, -70.0..30.0_f64),
        heading in 0.1..6.2_f64,
    ) {
        let q = [q.0, q.1];
        prop_assume!(footprint.boundary_distance_m(q[0], q[1]) > 1e-6);
        prop_assert_eq!(footprint.contains(q[0], q[1]), ray_count_inside(&rings, q, heading));
        prop_assert_eq!(footprint.distance_m(q[0], q[1]) == 0.0, footprint.contains(q[0], q[1]));
    }

    #[test]
    fn segment_intervals_agree_with_dense_sampling(
        (_, footprint) in footprints(),
        a in (-10.0..110.0_f64, -80.0..40.0_f64, -5.0..25.0_f64),
        b in (-10.0..110.0_f64, -80.0..40.0_f64, -5.0..25.0_f64),
    ) {
        let building = Building::new(footprint, 2.0, 15.0).unwrap();
        let (a, b) = (p(a.0, a.1, a.2), p(b.0, b.1, b.2));
        let got = building.segment_intervals(&a, &b);
        for w in got.windows(2) {
            prop_assert!(w[0].1 < w[1].0, "ascending and disjoint: {:?}", got);
        }
        prop_assert_eq!(building.segment_entry_t(&a, &b), got.first().map(|g| g.0));
        const SAMPLES: usize = 2000;
        for k in 0..=SAMPLES {
            let t = k as f64 / SAMPLES as f64;
            let q = a + (b - a) * t;
            let near_wall = building.footprint().boundary_distance_m(q.x, q.y) < 1e-6;
            let near_cap = (q.z - 2.0).abs() < 1e-6 || (q.z - 15.0).abs() < 1e-6;
            if near_wall || near_cap {
                continue;
            }
            let in_interval = got.iter().any(|&(t0, t1)| t >= t0 - 1e-12 && t <= t1 + 1e-12);
            prop_assert_eq!(building.contains(&q), in_interval, "t = {}, intervals {:?}", t, got);
        }
    }

    #[test]
    fn the_rectangle_shortcut_agrees_with_the_polygon_path(
        c in (-500.0..500.0_f64, -500.0..500.0_f64),
        half in (0.5..40.0_f64, 0.5..40.0_f64),
        a in (-600.0..600.0_f64, -600.0..600.0_f64, -5.0..60.0_f64),
        b in (-600.0..600.0_f64, -600.0..600.0_f64, -5.0..60.0_f64),
    ) {
        let rect = AxisRect { center_east_m: c.0, center_north_m: c.1, half_east_m: half.0, half_north_m: half.1 };
        let boxed = Building::boxed(rect, 1.0, 50.0);
        let general = Building::new(boxed.footprint().clone().into_general_polygon(), 1.0, 50.0).unwrap();
        let (a, b) = (p(a.0, a.1, a.2), p(b.0, b.1, b.2));
        prop_assert_eq!(boxed.contains(&a), general.contains(&a));
        prop_assert_eq!(boxed.footprint_touches_disc(a.x, a.y, 3.0), general.footprint_touches_disc(a.x, a.y, 3.0));
        let (x, y) = (boxed.segment_intervals(&a, &b), general.segment_intervals(&a, &b));
        prop_assert_eq!(x.len(), y.len(), "{:?} vs {:?}", x, y);
        for (x, y) in x.iter().zip(&y) {
            prop_assert!((x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9, "{:?} vs {:?}", x, y);
        }
    }
}
