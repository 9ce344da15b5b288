//! Planar polygon geometry in the local ENU plane (metres): what zone validation and the
//! airspace monitor share. Points are `(east_m, north_m)`.

/// A point in the local horizontal plane, metres.
pub type Point = (f64, f64);

/// Twice the signed area (positive for counter-clockwise), shoelace formula.
pub fn signed_area2(polygon: &[Point]) -> f64 {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum()
}

/// Cross product of (b - a) x (c - a): > 0 when c is left of a->b.
fn orient(a: Point, b: Point, c: Point) -> f64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

fn on_segment(a: Point, b: Point, p: Point) -> bool {
    p.0 >= a.0.min(b.0) && p.0 <= a.0.max(b.0) && p.1 >= a.1.min(b.1) && p.1 <= a.1.max(b.1)
}

/// Whether closed segments a-b and c-d share a point (touching counts).
pub fn segments_intersect(a: Point, b: Point, c: Point, d: Point) -> bool {
    let (o1, o2, o3, o4) = (orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b));
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0)) && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0)) {
        return true;
    }
    (o1 == 0.0 && on_segment(a, b, c))
        || (o2 == 0.0 && on_segment(a, b, d))
        || (o3 == 0.0 && on_segment(c, d, a))
        || (o4 == 0.0 && on_segment(c, d, b))
}

/// The first pair of non-adjacent edges `(i, j)` that intersect, if any. Edge i joins
/// vertex i to vertex i+1 (wrapping). O(n^2): polygons have at most a few hundred vertices.
pub fn first_self_intersection(polygon: &[Point]) -> Option<(usize, usize)> {
    let n = polygon.len();
    for i in 0..n {
        for j in (i + 1)..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            if adjacent {
                continue;
            }
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            let (c, d) = (polygon[j], polygon[(j + 1) % n]);
            if segments_intersect(a, b, c, d) {
                return Some((i, j));
            }
        }
    }
    None
}

/// Shortest distance from `p` to the polygon's boundary, metres.
pub fn distance_to_boundary(polygon: &[Point], p: Point) -> f64 {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let len2 = dx * dx + dy * dy;
            let t = if len2 == 0.0 { 0.0 } else { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0) };
            (p.0 - (a.0 + t * dx)).hypot(p.1 - (a.1 + t * dy))
        })
        .fold(f64::INFINITY, f64::min)
}

/// Whether a disc overlaps the polygon (centre inside, or boundary closer than the radius).
pub fn disc_overlaps(polygon: &[Point], center: Point, radius: f64) -> bool {
    contains(polygon, center) || distance_to_boundary(polygon, center) < radius
}

/// Point-in-polygon by ray casting (even-odd rule); works for concave polygons.
pub fn contains(polygon: &[Point], p: Point) -> bool {
    let n = polygon.len();
    let mut inside = false;
    let mut j = n - 1;
    for i in 0..n {
        let (pi, pj) = (polygon[i], polygon[j]);
        if (pi.1 > p.1) != (pj.1 > p.1) && p.0 < (pj.0 - pi.0) * (p.1 - pi.1) / (pj.1 - pi.1) + pi.0 {
            inside = !inside;
        }
        j = i;
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Point; 4] = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)];
    // A "C" shape: concave, opening to the east.
    const C_SHAPE: [Point; 8] =
        [(0.0, 0.0), (10.0, 0.0), (10.0, 3.0), (3.0, 3.0), (3.0, 7.0), (10.0, 7.0), (10.0, 10.0), (0.0, 10.0)];

    #[test]
    fn area_sign_follows_orientation() {
        assert_eq!(signed_area2(&SQUARE), 200.0);
        let mut cw = SQUARE;
        cw.reverse();
        assert_eq!(signed_area2(&cw), -200.0);
    }

    #[test]
    fn bow_tie_is_self_intersecting_square_is_not() {
        assert_eq!(first_self_intersection(&SQUARE), None);
        assert_eq!(first_self_intersection(&C_SHAPE), None);
        let bow_tie = [(0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)];
        assert_eq!(first_self_intersection(&bow_tie), Some((0, 2)));
    }

    #[test]
    fn discs_overlap_by_centre_or_by_edge_distance() {
        assert_eq!(distance_to_boundary(&SQUARE, (15.0, 5.0)), 5.0);
        assert!(disc_overlaps(&SQUARE, (5.0, 5.0), 0.1));
        assert!(disc_overlaps(&SQUARE, (15.0, 5.0), 6.0));
        assert!(!disc_overlaps(&SQUARE, (15.0, 5.0), 4.0));
    }

    #[test]
    fn contains_handles_concave_polygons() {
        assert!(contains(&C_SHAPE, (1.0, 5.0)));
        assert!(!contains(&C_SHAPE, (6.0, 5.0)), "inside the notch is outside the polygon");
        assert!(contains(&C_SHAPE, (6.0, 1.5)));
        assert!(!contains(&C_SHAPE, (11.0, 5.0)));
    }
}
