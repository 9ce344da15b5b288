//! Simple 3D Buildings (<https://wiki.openstreetmap.org/wiki/Simple_3D_Buildings>): areas
//! tagged `building:part` are the prisms of a building, and the building's outline (the
//! area tagged `building`) is then no prism of its own: its parts replace it, as 3D
//! renderers draw it.
//!
//! Which outline a part belongs to (the rule, without `type=building` relations): the
//! part's **interior point** lies inside the outline (on its outer ring's area, not in a
//! courtyard). The interior point is the one GEOS (`PointOnSurface`, shapely's
//! `representative_point`) picks, so a check with shapely gives the same answer even for a
//! part that straddles two outlines: per polygon, a horizontal scan line half-way between
//! the vertex northings nearest the middle of the polygon's bounding box (so it passes
//! through no vertex); the midpoint of the widest stretch of that line inside the polygon;
//! over several polygons, the widest stretch wins (the first on ties).
//!
//! Frame: world ENU metres, before clipping to the world square (which outline a part
//! belongs to does not depend on the extent).

use crate::footprint::{Point2, ring_contains};

/// One area in the plane: outer ring and holes, world ENU metres (rings closed or open).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanePolygon {
    pub outer: Vec<Point2>,
    pub holes: Vec<Vec<Point2>>,
}

impl PlanePolygon {
    /// Every ring, the outer one first.
    fn rings(&self) -> impl Iterator<Item = &[Point2]> {
        std::iter::once(self.outer.as_slice()).chain(self.holes.iter().map(Vec::as_slice))
    }

    /// Whether `p` is on the outer ring's area and in none of the holes.
    fn contains(&self, p: Point2) -> bool {
        ring_contains(&self.outer, p) && !self.holes.iter().any(|h| ring_contains(h, p))
    }
}

/// The interior point of an area of one or more polygons (see the module docs), `None`
/// for an area without polygons or whose polygons all enclose nothing.
pub fn interior_point(polygons: &[PlanePolygon]) -> Option<Point2> {
    let mut best: Option<(f64, Point2)> = None;
    for polygon in polygons {
        if let Some((width, point)) = widest_section(polygon)
            && best.is_none_or(|(w, _)| width > w)
        {
            best = Some((width, point));
        }
    }
    best.map(|(_, p)| p)
}

/// The widest stretch of the polygon's scan line inside it: `(width_m, midpoint)`.
fn widest_section(polygon: &PlanePolygon) -> Option<(f64, Point2)> {
    let y = scan_line_north_m(polygon)?;
    let mut crossings = Vec::new();
    for ring in polygon.rings() {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            // The scan line passes through no vertex: an edge crosses it when its ends are
            // on either side (horizontal edges never do).
            if (a[1] < y) != (b[1] < y) {
                let x = if a[0] == b[0] { a[0] } else { a[0] + (y - a[1]) / ((b[1] - a[1]) / (b[0] - a[0])) };
                crossings.push(x);
            }
        }
    }
    crossings.sort_by(f64::total_cmp);
    let mut best: Option<(f64, Point2)> = None;
    for pair in crossings.chunks_exact(2) {
        let width = pair[1] - pair[0];
        if best.is_none_or(|(w, _)| width > w) {
            best = Some((width, [(pair[0] + pair[1]) / 2.0, y]));
        }
    }
    best
}

/// The scan line's northing: half-way between the vertex northings nearest the middle of
/// the bounding box, below (or at) and above it. `None` for a polygon with no extent north.
fn scan_line_north_m(polygon: &PlanePolygon) -> Option<f64> {
    let (lo, hi) =
        polygon.outer.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
    let centre = (lo + hi) / 2.0;
    // (min and max skip NaN coordinates: lo and hi are never NaN.)
    if hi <= lo {
        return None;
    }
    let (mut below, mut above) = (lo, hi);
    for p in polygon.rings().flatten() {
        if p[1] <= centre {
            below = below.max(p[1]);
        } else {
            above = above.min(p[1]);
        }
    }
    Some((below + above) / 2.0)
}

/// Which of `outlines` hold one of `points` (the parts' interior points): `true` at the
/// index of an outline its parts replace. O((outlines + points) log points + matches).
pub fn holding(outlines: &[&[PlanePolygon]], points: &[Point2]) -> Vec<bool> {
    let mut sorted: Vec<Point2> = points.iter().copied().filter(|p| p[0].is_finite() && p[1].is_finite()).collect();
    sorted.sort_by(|a, b| a[0].total_cmp(&b[0]));
    outlines
        .iter()
        .map(|polygons| {
            polygons.iter().any(|polygon| {
                let (w, s, e, n) =
                    polygon.outer.iter().fold(
                        (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
                        |(w, s, e, n), p| (w.min(p[0]), s.min(p[1]), e.max(p[0]), n.max(p[1])),
                    );
                let first = sorted.partition_point(|p| p[0] < w);
                sorted[first..].iter().take_while(|p| p[0] <= e).any(|&p| p[1] >= s && p[1] <= n && polygon.contains(p))
            })
        })
        .collect()
}
