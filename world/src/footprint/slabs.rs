//! Vertical-slab (trapezoidal) decomposition of a footprint into convex pieces.
//!
//! Cut the plane at the east coordinate of every vertex. Inside one slab
//! `x0 <= east <= x1` no vertex lies strictly between, so every edge either spans the whole
//! slab or misses its interior, and (rings being simple and disjoint) the spanning edges do
//! not cross there: sorted by their north coordinate at the slab's middle, consecutive pairs
//! (1st-2nd, 3rd-4th, ...) bound the footprint's inside (even-odd rule). Each pair gives a
//! trapezoid with two vertical sides: convex, and the union over all slabs is the
//! footprint. O(v * e) for v distinct vertex coordinates and e edges; an L gives 2 pieces, a
//! square with a square courtyard 4.

use super::{Footprint, Point2};

/// Slabs narrower than this are left out, metres: a gap this thin lets no drone through.
pub const MIN_SLAB_WIDTH_M: f64 = 1e-3;

/// The footprint's trapezoids, each an open counter-clockwise ring (3 or 4 vertices: a
/// side of zero length is dropped).
pub fn trapezoids(footprint: &Footprint) -> Vec<Vec<Point2>> {
    let mut xs: Vec<f64> = footprint.rings().flatten().map(|p| p[0]).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let edges: Vec<(Point2, Point2)> = footprint.edges().filter(|(a, b)| a[0] != b[0]).collect();
    let mut pieces = Vec::new();
    for w in xs.windows(2) {
        let (x0, x1) = (w[0], w[1]);
        if x1 - x0 < MIN_SLAB_WIDTH_M {
            continue;
        }
        let xm = 0.5 * (x0 + x1);
        // (north at x0, north at x1, north at the middle) of every edge spanning the slab.
        let mut spans: Vec<[f64; 3]> = edges
            .iter()
            .filter(|(a, b)| a[0].min(b[0]) <= x0 && a[0].max(b[0]) >= x1)
            .map(|&(a, b)| {
                let at = |x: f64| a[1] + (x - a[0]) * (b[1] - a[1]) / (b[0] - a[0]);
                [at(x0), at(x1), at(xm)]
            })
            .collect();
        spans.sort_by(|p, q| p[2].total_cmp(&q[2]));
        for pair in spans.chunks_exact(2) {
            let (lo, hi) = (pair[0], pair[1]);
            let mut ring = vec![[x0, lo[0]], [x1, lo[1]]];
            if hi[1] > lo[1] {
                ring.push([x1, hi[1]]);
            }
            if hi[0] > lo[0] {
                ring.push([x0, hi[0]]);
            }
            if ring.len() >= 3 {
                pieces.push(ring);
            }
        }
    }
    pieces
}
