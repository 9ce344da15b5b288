//! Footprint validation, conventions and the convex decomposition.

use proptest::prelude::*;

use super::*;

fn square(x0: f64, y0: f64, side: f64) -> Vec<Point2> {
    vec![[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]]
}

#[test]
fn rings_are_stored_open_outer_counter_clockwise_and_holes_clockwise() {
    let mut cw_closed = square(0.0, 0.0, 10.0);
    cw_closed.reverse();
    cw_closed.push(cw_closed[0]);
    let f = Footprint::new(cw_closed, vec![square(2.0, 2.0, 2.0)]).unwrap();
    assert_eq!(f.outer().len(), 4, "closing vertex dropped");
    assert!(shoelace_m2(f.outer()) > 0.0 && shoelace_m2(&f.holes()[0]) < 0.0);
    assert_eq!(f.area_m2(), 96.0);
    assert_eq!(f.bounds(), [0.0, 0.0, 10.0, 10.0]);
    assert!(!f.is_convex() && f.axis_rect().is_none(), "a hole makes it neither");
    assert!(f.contains(1.0, 1.0) && !f.contains(3.0, 3.0) && f.contains(2.0, 3.0), "hole edges belong to it");
    assert!(f.contains(10.0, 5.0) && !f.contains(10.1, 5.0));
}

#[test]
fn invalid_rings_are_rejected_with_the_ring_named() {
    let nan = vec![[0.0, 0.0], [1.0, f64::NAN], [1.0, 1.0]];
    assert_eq!(Footprint::new(nan, vec![]), Err(FootprintError::NotFinite { ring: 0, vertex: 1 }));
    let two = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 0.0]];
    assert_eq!(Footprint::new(two, vec![]), Err(FootprintError::TooFewVertices { ring: 0, count: 2 }));
    let flat = vec![[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]];
    assert_eq!(Footprint::new(flat.clone(), vec![]), Err(FootprintError::ZeroArea { ring: 0 }));
    assert_eq!(Footprint::new(square(0.0, 0.0, 5.0), vec![flat]), Err(FootprintError::ZeroArea { ring: 1 }));
    let outside = square(4.0, 4.0, 2.0);
    assert_eq!(
        Footprint::new(square(0.0, 0.0, 5.0), vec![outside]),
        Err(FootprintError::HoleOutside { ring: 1, vertex: 1 })
    );
}

#[test]
fn an_axis_aligned_polygon_is_recognised_as_a_rectangle_and_a_rotated_one_is_not() {
    let f = Footprint::new(vec![[4.0, 1.0], [4.0, 3.0], [-2.0, 3.0], [-2.0, 1.0]], vec![]).unwrap();
    let r = f.axis_rect().expect("axis-aligned");
    assert_eq!((r.center_east_m, r.center_north_m, r.half_east_m, r.half_north_m), (1.0, 2.0, 3.0, 1.0));
    assert_eq!(f.area_m2(), 12.0);
    let diamond = Footprint::new(vec![[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]], vec![]).unwrap();
    assert!(diamond.axis_rect().is_none() && diamond.is_convex());
    assert!(diamond.contains(0.5, 0.5) && !diamond.contains(0.6, 0.6));
    assert!((diamond.distance_m(1.0, 1.0) - 0.5_f64.sqrt()).abs() < 1e-12);
}

#[test]
fn an_l_and_a_courtyard_decompose_into_convex_trapezoids_covering_them() {
    let l =
        Footprint::new(vec![[0.0, 0.0], [30.0, 0.0], [30.0, 10.0], [10.0, 10.0], [10.0, 30.0], [0.0, 30.0]], vec![])
            .unwrap();
    assert!(!l.is_convex());
    assert_eq!(l.convex_pieces().len(), 2);
    let yard = Footprint::new(square(0.0, 0.0, 40.0), vec![square(10.0, 10.0, 20.0)]).unwrap();
    assert_eq!(yard.convex_pieces().len(), 4);
    let convex = Footprint::new(vec![[0.0, 0.0], [4.0, 0.0], [5.0, 3.0], [1.0, 4.0]], vec![]).unwrap();
    assert_eq!(convex.convex_pieces(), vec![convex.outer().to_vec()], "a convex footprint is its own piece");
}

/// Pieces are convex counter-clockwise rings whose areas sum to the footprint's, and a
/// point lies on the footprint exactly when it lies on a piece.
fn check_pieces(f: &Footprint, probes: &[Point2]) -> Result<(), TestCaseError> {
    let pieces = f.convex_pieces();
    let total: f64 = pieces.iter().map(|p| shoelace_m2(p)).sum();
    // Slabs narrower than MIN_SLAB_WIDTH_M between two vertices' east coordinates are left
    // out (a slit that thin lets no drone through): the pieces may miss at most those
    // slabs' area, bounded by their width times the footprint's north-south extent.
    let mut xs: Vec<f64> = f.rings().flatten().map(|p| p[0]).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let thin_m: f64 = xs.windows(2).map(|w| w[1] - w[0]).filter(|&gap| gap < super::slabs::MIN_SLAB_WIDTH_M).sum();
    let [_, south, _, north] = f.bounds();
    let missing_max = if f.is_convex() { 0.0 } else { thin_m * (north - south) };
    let missing = f.area_m2() - total;
    prop_assert!(
        missing > -1e-6 * f.area_m2().max(1.0) && missing < missing_max + 1e-6 * f.area_m2().max(1.0),
        "{total} vs {} (thin slabs may miss {missing_max})",
        f.area_m2()
    );
    for piece in &pieces {
        prop_assert!(is_convex(piece) && shoelace_m2(piece) > 0.0, "{:?}", piece);
    }
    for &q in probes {
        let in_thin_slab =
            xs.windows(2).any(|w| w[1] - w[0] < super::slabs::MIN_SLAB_WIDTH_M && w[0] <= q[0] && q[0] <= w[1]);
        if f.boundary_distance_m(q[0], q[1]) < 1e-6 || in_thin_slab {
            continue;
        }
        let on_piece = pieces.iter().any(|p| ring_contains(p, q));
        prop_assert_eq!(f.contains(q[0], q[1]), on_piece, "{:?}", q);
    }
    Ok(())
}

proptest! {
    #[test]
    fn convex_pieces_cover_random_star_footprints_with_holes(
        radii in prop::collection::vec(5.0..40.0_f64, 3..14),
        hole in prop::option::of(prop::collection::vec(0.2..0.9_f64, 3..8)),
        probes in prop::collection::vec((-45.0..45.0_f64, -45.0..45.0_f64), 50),
    ) {
        let n = radii.len() as f64;
        let outer: Vec<Point2> = radii
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let a = std::f64::consts::TAU * k as f64 / n;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        // The largest disc around the origin inside the outer ring bounds the hole.
        let r_in = (0..outer.len())
            .map(|i| {
                let (a, b) = (outer[i], outer[(i + 1) % outer.len()]);
                cross(a, b).abs() / (b[0] - a[0]).hypot(b[1] - a[1])
            })
            .fold(f64::INFINITY, f64::min);
        let holes: Vec<Vec<Point2>> = hole
            .into_iter()
            .map(|scales| {
                let m = scales.len() as f64;
                scales
                    .iter()
                    .enumerate()
                    .map(|(k, s)| {
                        let a = 0.4 + std::f64::consts::TAU * k as f64 / m;
                        [s * r_in * a.cos(), s * r_in * a.sin()]
                    })
                    .collect()
            })
            .collect();
        let f = Footprint::new(outer, holes).unwrap();
        let probes: Vec<Point2> = probes.into_iter().map(|(x, y)| [x, y]).collect();
        check_pieces(&f, &probes)?;
    }
}
