//! Geometry on the run's local plane: where to hold, film and watch around a zone, and how
//! to fly around zones without entering them.
//!
//! Everything here is horizontal and pure. Points are `(east_m, north_m)` in the run's
//! local ENU frame (metres from the run origin, x east, y north), the same plane the
//! airspace authority and the compliance monitor use; zone polygons are their outlines in
//! that plane, in any winding order, implicitly closed. Altitudes are the flight code's
//! business: downtown Chicago is flat and every zone here reaches from the ground to above
//! the drones' ceilings, so a drone without a lease keeps out horizontally.

use sadesim_crds::polygon::{self, Point};

#[cfg(test)]
mod tests;

/// Distance between two points, metres.
pub fn distance(a: Point, b: Point) -> f64 {
    (b.0 - a.0).hypot(b.1 - a.1)
}

/// Shortest distance from `p` to the segment `a`-`b`, metres.
pub fn point_segment_distance(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 == 0.0 { 0.0 } else { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0) };
    distance(p, (a.0 + t * dx, a.1 + t * dy))
}

/// Shortest distance between the segments `a`-`b` and `c`-`d`, metres (0 when they touch
/// or cross).
pub fn segment_segment_distance(a: Point, b: Point, c: Point, d: Point) -> f64 {
    if polygon::segments_intersect(a, b, c, d) {
        return 0.0;
    }
    point_segment_distance(a, c, d)
        .min(point_segment_distance(b, c, d))
        .min(point_segment_distance(c, a, b))
        .min(point_segment_distance(d, a, b))
}

/// Shortest distance from `p` to the polygon's area, metres: 0 inside or on the outline.
pub fn distance_to_polygon(poly: &[Point], p: Point) -> f64 {
    if polygon::contains(poly, p) { 0.0 } else { polygon::distance_to_boundary(poly, p) }
}

/// Shortest distance from the straight leg `a`-`b` to the polygon's area, metres: 0 when
/// any part of the leg is inside or on the outline. Works for concave polygons: a leg that
/// passes through a notch without touching the area keeps its true distance.
pub fn segment_polygon_distance(a: Point, b: Point, poly: &[Point]) -> f64 {
    if polygon::contains(poly, a) || polygon::contains(poly, b) {
        return 0.0;
    }
    (0..poly.len())
        .map(|i| segment_segment_distance(a, b, poly[i], poly[(i + 1) % poly.len()]))
        .fold(f64::INFINITY, f64::min)
}

/// Whether flying the straight leg `a`-`b` would enter the polygon or pass closer to it
/// than `margin_m` metres (the segment-polygon test a pilot runs before each leg).
pub fn leg_enters(poly: &[Point], a: Point, b: Point, margin_m: f64) -> bool {
    let d = segment_polygon_distance(a, b, poly);
    d == 0.0 || d < margin_m
}

/// The polygon with counter-clockwise winding (the outside is on the right of each edge).
fn counter_clockwise(poly: &[Point]) -> Vec<Point> {
    let mut v = poly.to_vec();
    if polygon::signed_area2(&v) < 0.0 {
        v.reverse();
    }
    v
}

/// Unit outward normal of the edge `a`-`b` of a counter-clockwise polygon.
fn outward_normal(a: Point, b: Point) -> Point {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len = dx.hypot(dy).max(f64::MIN_POSITIVE);
    (dy / len, -dx / len)
}

/// The area centroid (shoelace formula); the vertex mean for a degenerate polygon.
pub fn centroid(poly: &[Point]) -> Point {
    let a2 = polygon::signed_area2(poly);
    let n = poly.len();
    if a2.abs() < 1e-9 {
        let (sx, sy) = poly.iter().fold((0.0, 0.0), |s, p| (s.0 + p.0, s.1 + p.1));
        return (sx / n as f64, sy / n as f64);
    }
    let (mut cx, mut cy) = (0.0, 0.0);
    for i in 0..n {
        let (p, q) = (poly[i], poly[(i + 1) % n]);
        let cross = p.0 * q.1 - q.0 * p.1;
        cx += (p.0 + q.0) * cross;
        cy += (p.1 + q.1) * cross;
    }
    (cx / (3.0 * a2), cy / (3.0 * a2))
}

/// A point deep inside the polygon: its centroid when that lies inside, otherwise the
/// point of a 2 m grid farthest from the outline (a concave polygon's centroid may lie
/// outside it).
pub fn interior_anchor(poly: &[Point]) -> Point {
    let c = centroid(poly);
    if polygon::contains(poly, c) {
        return c;
    }
    let (x0, y0, x1, y1) = bounds(poly);
    let step = ((x1 - x0).max(y1 - y0) / 200.0).max(0.5);
    let mut best = (c, -1.0);
    let mut y = y0;
    while y <= y1 {
        let mut x = x0;
        while x <= x1 {
            if polygon::contains(poly, (x, y)) {
                let d = polygon::distance_to_boundary(poly, (x, y));
                if d > best.1 {
                    best = ((x, y), d);
                }
            }
            x += step;
        }
        y += step;
    }
    best.0
}

/// `(min_east, min_north, max_east, max_north)` of the polygon, metres.
pub fn bounds(poly: &[Point]) -> (f64, f64, f64, f64) {
    poly.iter().fold((f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY), |b, p| {
        (b.0.min(p.0), b.1.min(p.1), b.2.max(p.0), b.3.max(p.1))
    })
}

/// Points `offset_m` outside the polygon all round it, about `step_m` apart: the polygon's
/// outline pushed out along each edge's normal, with arcs round the convex corners. Points
/// of the pushed outline that come closer than `offset_m` to another part of the polygon
/// (in the notches of a concave polygon) are left out.
pub fn offset_ring(poly: &[Point], offset_m: f64, step_m: f64) -> Vec<Point> {
    let v = counter_clockwise(poly);
    let n = v.len();
    let step_m = step_m.max(0.1);
    let mut out = Vec::new();
    for i in 0..n {
        let (a, b, c) = (v[i], v[(i + 1) % n], v[(i + 2) % n]);
        let normal = outward_normal(a, b);
        let samples = (distance(a, b) / step_m).ceil().max(1.0) as usize;
        for k in 0..samples {
            let t = k as f64 / samples as f64;
            out.push((a.0 + t * (b.0 - a.0) + offset_m * normal.0, a.1 + t * (b.1 - a.1) + offset_m * normal.1));
        }
        // The arc round the corner at b, from this edge's normal to the next one's
        // (counter-clockwise polygon: a left turn is a convex corner).
        let turn = (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0);
        if turn > 0.0 {
            let next = outward_normal(b, c);
            let (from, mut to) = (normal.1.atan2(normal.0), next.1.atan2(next.0));
            if to < from {
                to += std::f64::consts::TAU;
            }
            let arc_samples = ((to - from) * offset_m / step_m).ceil().max(1.0) as usize;
            for k in 0..arc_samples {
                let angle = from + (to - from) * k as f64 / arc_samples as f64;
                out.push((b.0 + offset_m * angle.cos(), b.1 + offset_m * angle.sin()));
            }
        }
    }
    out.retain(|&p| !polygon::contains(poly, p) && polygon::distance_to_boundary(poly, p) >= offset_m - 0.01);
    out
}

/// One hold point per drone, each `offset_m` outside the polygon on the side facing the
/// drone's home (the point of the offset outline nearest to it), and at least
/// `min_separation_m` from the hold points of earlier drones: drones are served in order,
/// so two drones coming from the same direction wait side by side. When the outline has no
/// room left for the separation, the nearest free-or-not point is used.
pub fn hold_points(poly: &[Point], homes: &[Point], offset_m: f64, min_separation_m: f64) -> Vec<Point> {
    let ring = offset_ring(poly, offset_m, 2.0);
    let mut chosen: Vec<Point> = Vec::new();
    for &home in homes {
        let nearest = |ok: &dyn Fn(Point) -> bool| {
            ring.iter().copied().filter(|&p| ok(p)).min_by(|&p, &q| distance(p, home).total_cmp(&distance(q, home)))
        };
        let spaced = |p: Point| chosen.iter().all(|&c| distance(p, c) >= min_separation_m);
        let point = nearest(&spaced).or_else(|| nearest(&|_| true)).unwrap_or(home);
        chosen.push(point);
    }
    chosen
}

/// `count` spots `offset_m` north of the polygon, spread evenly from west to east over its
/// width (kept `inset_m` in from each end): where the news crews film from. Each spot is
/// at least `offset_m` from the polygon (pushed further north where the outline slopes).
pub fn north_side_spots(poly: &[Point], count: usize, offset_m: f64, inset_m: f64) -> Vec<Point> {
    let (x0, _, x1, _) = bounds(poly);
    let inset = inset_m.min((x1 - x0) / 4.0);
    let (from, to) = (x0 + inset, x1 - inset);
    (0..count)
        .map(|i| {
            let x = if count == 1 { (from + to) / 2.0 } else { from + (to - from) * i as f64 / (count - 1) as f64 };
            let mut spot = (x, top_at(poly, x) + offset_m);
            while distance_to_polygon(poly, spot) < offset_m - 0.01 {
                spot.1 += 0.5;
            }
            spot
        })
        .collect()
}

/// The northernmost point of the outline on the north-south line at `x` (the top of the
/// polygon's bounds when the line misses it).
fn top_at(poly: &[Point], x: f64) -> f64 {
    let n = poly.len();
    let mut top = f64::NEG_INFINITY;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        if (a.0 <= x && x <= b.0) || (b.0 <= x && x <= a.0) {
            let y = if a.0 == b.0 { a.1.max(b.1) } else { a.1 + (x - a.0) / (b.0 - a.0) * (b.1 - a.1) };
            top = top.max(y);
        }
    }
    if top.is_finite() { top } else { bounds(poly).3 }
}

/// One point inside the polygon per drone, spread evenly on a circle of `radius_m` round
/// the polygon's [`interior_anchor`], each at least `margin_m` from the outline. Drones are
/// given the circle's points in the angular order of the places they approach from
/// (`approaches`, e.g. their hold points), with the circle turned to match those
/// directions best, so that their legs in do not cross. The circle shrinks (5 m at a
/// time) until every point keeps the margin.
pub fn inside_points(poly: &[Point], approaches: &[Point], radius_m: f64, margin_m: f64) -> Vec<Point> {
    use std::f64::consts::TAU;
    let n = approaches.len();
    if n == 0 {
        return Vec::new();
    }
    let anchor = interior_anchor(poly);
    let bearing = |p: Point| (p.1 - anchor.1).atan2(p.0 - anchor.0).rem_euclid(TAU);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| bearing(approaches[i]).total_cmp(&bearing(approaches[j])));
    // Wrapped angular difference, radians in [-pi, pi).
    let wrap = |d: f64| (d + TAU / 2.0).rem_euclid(TAU) - TAU / 2.0;
    let slot = |phase: f64, k: usize| phase + TAU * k as f64 / n as f64;
    let cost = |phase: f64| {
        order.iter().enumerate().map(|(k, &i)| wrap(bearing(approaches[i]) - slot(phase, k)).powi(2)).sum::<f64>()
    };
    let phase =
        (0..720).map(|d| f64::from(d) * TAU / 720.0).min_by(|&a, &b| cost(a).total_cmp(&cost(b))).unwrap_or(0.0);
    let mut radius = radius_m.max(0.0);
    loop {
        let mut points = vec![anchor; n];
        for (k, &i) in order.iter().enumerate() {
            let angle = slot(phase, k);
            points[i] = (anchor.0 + radius * angle.cos(), anchor.1 + radius * angle.sin());
        }
        let fits =
            points.iter().all(|&p| polygon::contains(poly, p) && polygon::distance_to_boundary(poly, p) >= margin_m);
        if fits || radius <= 0.0 {
            return points;
        }
        radius = (radius - 5.0).max(0.0);
    }
}

/// The point `depth_m` inside the polygon straight in from `outside`: towards the nearest
/// point of the outline and on past it (used for where a drone goes in from its spot). Falls
/// back to the [`interior_anchor`] when that point is not inside.
pub fn point_inside_from(poly: &[Point], outside: Point, depth_m: f64) -> Point {
    let n = poly.len();
    let nearest = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let len2 = dx * dx + dy * dy;
            let t = if len2 == 0.0 {
                0.0
            } else {
                (((outside.0 - a.0) * dx + (outside.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
            };
            (a.0 + t * dx, a.1 + t * dy)
        })
        .min_by(|&p, &q| distance(p, outside).total_cmp(&distance(q, outside)));
    if let Some(q) = nearest {
        let d = distance(outside, q);
        if d > 0.0 {
            let (ux, uy) = ((q.0 - outside.0) / d, (q.1 - outside.1) / d);
            let p = (q.0 + depth_m * ux, q.1 + depth_m * uy);
            if polygon::contains(poly, p) {
                return p;
            }
        }
    }
    interior_anchor(poly)
}

/// A route from `start` to `goal` whose legs stay at least `clearance_m` from every
/// obstacle polygon, as a list of points to fly to in order (ending with `goal`; just
/// `[goal]` when the straight leg is clear). Shortest path over the corners of the
/// obstacles pushed out beyond the clearance (a visibility graph, Dijkstra).
///
/// An obstacle that contains `start` or `goal` is ignored (the route is the way out of it,
/// or the caller has a lease for it). When `start` or `goal` lies closer than
/// `clearance_m` to an obstacle, the clearance shrinks to that distance, so a drone
/// already close to a zone can still leave.
///
/// `None` when no route exists (the goal is walled in by obstacles).
pub fn route(start: Point, goal: Point, obstacles: &[Vec<Point>], clearance_m: f64) -> Option<Vec<Point>> {
    let active: Vec<&Vec<Point>> = obstacles
        .iter()
        .filter(|o| o.len() >= 3 && !polygon::contains(o, start) && !polygon::contains(o, goal))
        .collect();
    let clearance =
        active.iter().fold(clearance_m, |c, o| c.min(distance_to_polygon(o, start)).min(distance_to_polygon(o, goal)));
    let clear = |a: Point, b: Point| active.iter().all(|o| segment_polygon_distance(a, b, o) >= clearance * 0.999);
    if clear(start, goal) {
        return Some(vec![goal]);
    }
    let mut nodes = vec![start, goal];
    for o in &active {
        nodes.extend(pushed_corners(o, clearance_m.max(clearance) + 5.0));
    }
    nodes.retain(|&p| p == start || p == goal || active.iter().all(|o| distance_to_polygon(o, p) >= clearance));
    // Dijkstra from node 0 (start) to node 1 (goal), edges tested lazily.
    let n = nodes.len();
    let mut dist = vec![f64::INFINITY; n];
    let mut prev = vec![usize::MAX; n];
    let mut done = vec![false; n];
    dist[0] = 0.0;
    loop {
        let next = (0..n).filter(|&i| !done[i] && dist[i].is_finite()).min_by(|&i, &j| dist[i].total_cmp(&dist[j]));
        let u = next?;
        if u == 1 {
            break;
        }
        done[u] = true;
        for v in 0..n {
            if done[v] || v == u {
                continue;
            }
            let d = dist[u] + distance(nodes[u], nodes[v]);
            if d < dist[v] && clear(nodes[u], nodes[v]) {
                dist[v] = d;
                prev[v] = u;
            }
        }
    }
    let mut path = vec![nodes[1]];
    let mut at = 1;
    while prev[at] != 0 {
        at = prev[at];
        path.push(nodes[at]);
    }
    path.reverse();
    Some(path)
}

/// Each convex corner of the polygon pushed out along its bisector until it is
/// `distance_m` from the polygon: the turning points of routes round it.
fn pushed_corners(poly: &[Point], distance_m: f64) -> Vec<Point> {
    let v = counter_clockwise(poly);
    let n = v.len();
    let mut out = Vec::new();
    for i in 0..n {
        let (a, b, c) = (v[(i + n - 1) % n], v[i], v[(i + 1) % n]);
        let turn = (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0);
        if turn <= 0.0 {
            continue; // a reflex corner: routes never turn there
        }
        let (n1, n2) = (outward_normal(a, b), outward_normal(b, c));
        let (bx, by) = (n1.0 + n2.0, n1.1 + n2.1);
        let len = bx.hypot(by);
        if len < 1e-9 {
            continue;
        }
        let dir = (bx / len, by / len);
        // At the push p the corner point is p * cos(half the turn) from each edge's line.
        let mut push = distance_m / (n1.0 * dir.0 + n1.1 * dir.1).max(0.2);
        let mut p = (b.0 + push * dir.0, b.1 + push * dir.1);
        for _ in 0..20 {
            if distance_to_polygon(poly, p) >= distance_m - 0.01 {
                break;
            }
            push *= 1.2;
            p = (b.0 + push * dir.0, b.1 + push * dir.1);
        }
        out.push(p);
    }
    out
}

/// Length of the path from `start` through `points`, metres.
pub fn path_length(start: Point, points: &[Point]) -> f64 {
    let mut at = start;
    let mut total = 0.0;
    for &p in points {
        total += distance(at, p);
        at = p;
    }
    total
}
