//! A building's footprint: a polygon with holes in the horizontal plane, and the 2D
//! geometry the prism queries need (point in polygon, distance to a disc, where a line
//! crosses the boundary, a decomposition into convex pieces).
//!
//! Frame and units: world ENU metres, a vertex is `[east_m, north_m]`.
//!
//! Conventions (those of GeoJSON, RFC 7946 §3.1.6, after [`Footprint::new`] normalises):
//! - Rings are stored **open**: the last vertex does not repeat the first (a closing
//!   duplicate given to [`Footprint::new`] is dropped, as are repeated consecutive vertices).
//! - The outer ring runs **counter-clockwise** (positive shoelace area, seen from above),
//!   every hole **clockwise**; rings given the other way round are reversed.
//! - The footprint is **closed**: a point on an edge belongs to it. Inside is decided by the
//!   even-odd rule over all rings, so a point in a hole is outside.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::index::Rect;

mod slabs;

/// A horizontal point, world ENU metres: `[east_m, north_m]`.
pub type Point2 = [f64; 2];

/// Why a ring cannot be a footprint. `ring` is 0 for the outer ring, `k + 1` for hole `k`.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum FootprintError {
    /// A coordinate is NaN or infinite.
    #[error("failed to build a footprint: ring {ring} vertex {vertex} is not finite")]
    NotFinite { ring: usize, vertex: usize },
    /// Fewer than 3 distinct vertices once the closing and repeated vertices are dropped.
    #[error("failed to build a footprint: ring {ring} has {count} distinct vertices, needs at least 3")]
    TooFewVertices { ring: usize, count: usize },
    /// The ring encloses no area (all vertices on one line).
    #[error("failed to build a footprint: ring {ring} encloses no area (collinear vertices)")]
    ZeroArea { ring: usize },
    /// A hole's vertex lies outside the outer ring.
    #[error("failed to build a footprint: hole ring {ring} vertex {vertex} lies outside the outer ring")]
    HoleOutside { ring: usize, vertex: usize },
}

/// An axis-aligned rectangle given by its centre and half sides, metres (the procedural
/// city's footprints). Kept exactly as given so queries and colliders built from it are
/// bit-for-bit those of the original boxes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisRect {
    /// Centre, metres east of the origin.
    pub center_east_m: f64,
    /// Centre, metres north of the origin.
    pub center_north_m: f64,
    /// Half the east-west side, metres (> 0).
    pub half_east_m: f64,
    /// Half the north-south side, metres (> 0).
    pub half_north_m: f64,
}

/// A validated polygon footprint with zero or more holes (see the module docs for the
/// orientation, closure and inside conventions).
///
/// # Assumptions
/// Rings are simple (no self-intersections) and holes do not overlap each other; this is
/// not checked (it costs O(n^2)). Queries stay defined on other input (even-odd rule) but
/// the convex decomposition then no longer covers exactly the even-odd area.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Footprint {
    outer: Vec<Point2>,
    holes: Vec<Vec<Point2>>,
    /// `[min_east, min_north, max_east, max_north]`, metres.
    bounds: Rect,
    /// Set when the footprint is an axis-aligned rectangle: its queries use the box formulas.
    rect: Option<AxisRect>,
    /// No holes and every turn of the outer ring is left or straight.
    convex: bool,
    area_m2: f64,
}

impl Footprint {
    /// An axis-aligned rectangle `[center ± half]` (both halves > 0, finite; not checked:
    /// the procedural city constructs these). Its vertices run SW, SE, NE, NW.
    pub(crate) fn rectangle(rect: AxisRect) -> Self {
        let AxisRect { center_east_m: ce, center_north_m: cn, half_east_m: he, half_north_m: hn } = rect;
        let bounds = [ce - he, cn - hn, ce + he, cn + hn];
        let outer =
            vec![[bounds[0], bounds[1]], [bounds[2], bounds[1]], [bounds[2], bounds[3]], [bounds[0], bounds[3]]];
        Self { outer, holes: Vec::new(), bounds, rect: Some(rect), convex: true, area_m2: 4.0 * he * hn }
    }

    /// Validates and normalises a polygon: `outer` and each of `holes` is a ring of
    /// `[east_m, north_m]` vertices, open or closed, in either orientation.
    ///
    /// # Errors
    /// A non-finite coordinate, a ring with fewer than 3 distinct vertices or no area, a
    /// hole vertex outside the outer ring.
    pub fn new(outer: Vec<Point2>, holes: Vec<Vec<Point2>>) -> Result<Self, FootprintError> {
        let outer = normalise(outer, 0, true)?;
        let mut normalised = Vec::with_capacity(holes.len());
        for (k, hole) in holes.into_iter().enumerate() {
            // Vertex numbers in errors count in the ring as given.
            if let Some(vertex) =
                hole.iter().position(|&p| p[0].is_finite() && p[1].is_finite() && !ring_contains(&outer, p))
            {
                normalise(hole, k + 1, false)?;
                return Err(FootprintError::HoleOutside { ring: k + 1, vertex });
            }
            normalised.push(normalise(hole, k + 1, false)?);
        }
        let holes = normalised;
        let bounds = outer.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |r, p| {
            [r[0].min(p[0]), r[1].min(p[1]), r[2].max(p[0]), r[3].max(p[1])]
        });
        let area_m2 = shoelace_m2(&outer) + holes.iter().map(|h| shoelace_m2(h)).sum::<f64>();
        let convex = holes.is_empty() && is_convex(&outer);
        let rect = (holes.is_empty() && is_axis_rectangle(&outer)).then(|| AxisRect {
            center_east_m: 0.5 * (bounds[0] + bounds[2]),
            center_north_m: 0.5 * (bounds[1] + bounds[3]),
            half_east_m: 0.5 * (bounds[2] - bounds[0]),
            half_north_m: 0.5 * (bounds[3] - bounds[1]),
        });
        Ok(Self { outer, holes, bounds, rect, convex, area_m2 })
    }

    /// The outer ring, open, counter-clockwise.
    pub fn outer(&self) -> &[Point2] {
        &self.outer
    }

    /// The holes, each open and clockwise.
    pub fn holes(&self) -> &[Vec<Point2>] {
        &self.holes
    }

    /// Every ring: the outer ring first, then the holes.
    pub fn rings(&self) -> impl Iterator<Item = &[Point2]> {
        std::iter::once(self.outer.as_slice()).chain(self.holes.iter().map(Vec::as_slice))
    }

    /// Bounding rectangle `[min_east, min_north, max_east, max_north]`, metres.
    pub fn bounds(&self) -> Rect {
        self.bounds
    }

    /// The centre of the bounding rectangle, `[east_m, north_m]` (exactly the rectangle's
    /// given centre for an [`AxisRect`]). Not necessarily on the footprint (a courtyard).
    pub fn bounds_center(&self) -> Point2 {
        match self.rect {
            Some(r) => [r.center_east_m, r.center_north_m],
            None => [0.5 * (self.bounds[0] + self.bounds[2]), 0.5 * (self.bounds[1] + self.bounds[3])],
        }
    }

    /// `Some` when the footprint is an axis-aligned rectangle.
    pub fn axis_rect(&self) -> Option<AxisRect> {
        self.rect
    }

    /// Whether the footprint is convex (then it has no holes).
    pub fn is_convex(&self) -> bool {
        self.convex
    }

    /// Area, square metres: the outer ring's minus the holes'.
    pub fn area_m2(&self) -> f64 {
        self.area_m2
    }

    /// Whether the point lies on the closed footprint (edges included, holes excluded but
    /// their edges included).
    pub fn contains(&self, east_m: f64, north_m: f64) -> bool {
        if let Some(r) = self.rect {
            return (east_m - r.center_east_m).abs() <= r.half_east_m
                && (north_m - r.center_north_m).abs() <= r.half_north_m;
        }
        let p = [east_m, north_m];
        if p[0] < self.bounds[0] || p[0] > self.bounds[2] || p[1] < self.bounds[1] || p[1] > self.bounds[3] {
            return false;
        }
        let mut inside = false;
        for ring in self.rings() {
            match classify(ring, p) {
                Side::Boundary => return true,
                Side::Odd => inside = !inside,
                Side::Even => {}
            }
        }
        inside
    }

    /// Distance from the point to the nearest point of the footprint, metres (0 inside).
    pub fn distance_m(&self, east_m: f64, north_m: f64) -> f64 {
        if let Some(r) = self.rect {
            let dx = ((east_m - r.center_east_m).abs() - r.half_east_m).max(0.0);
            let dy = ((north_m - r.center_north_m).abs() - r.half_north_m).max(0.0);
            return dx.hypot(dy);
        }
        if self.contains(east_m, north_m) {
            return 0.0;
        }
        self.boundary_distance_m(east_m, north_m)
    }

    /// Whether the footprint and the closed disc of `radius_m` around the point share a
    /// point: [`Footprint::distance_m`] <= `radius_m`.
    pub fn touches_disc(&self, east_m: f64, north_m: f64, radius_m: f64) -> bool {
        if let Some(r) = self.rect {
            // The box formula, squared (no square root): as the original boxes decided.
            let dx = ((east_m - r.center_east_m).abs() - r.half_east_m).max(0.0);
            let dy = ((north_m - r.center_north_m).abs() - r.half_north_m).max(0.0);
            return dx * dx + dy * dy <= radius_m * radius_m;
        }
        self.distance_m(east_m, north_m) <= radius_m
    }

    /// Distance from the point to the nearest edge of any ring, metres.
    pub fn boundary_distance_m(&self, east_m: f64, north_m: f64) -> f64 {
        let p = [east_m, north_m];
        self.edges().map(|(a, b)| segment_distance_m(p, a, b)).fold(f64::INFINITY, f64::min)
    }

    /// Every edge of every ring, as (start, end).
    pub fn edges(&self) -> impl Iterator<Item = (Point2, Point2)> + '_ {
        self.rings().flat_map(|ring| (0..ring.len()).map(move |i| (ring[i], ring[(i + 1) % ring.len()])))
    }

    /// Line parameters `t` in the open interval (0, 1) where the horizontal segment
    /// `a + t d` meets the footprint's boundary: edge crossings, and both ends of every edge
    /// the segment runs along. Unsorted, may repeat. Between two consecutive values the
    /// segment is wholly inside or wholly outside (or on the boundary).
    pub fn boundary_crossings(&self, a: Point2, d: Point2) -> Vec<f64> {
        let mut out = Vec::new();
        for (p, q) in self.edges() {
            let e = [q[0] - p[0], q[1] - p[1]];
            let ap = [p[0] - a[0], p[1] - a[1]];
            let denom = cross(d, e);
            if denom != 0.0 {
                let t = cross(ap, e) / denom;
                let s = cross(ap, d) / denom;
                if (0.0..=1.0).contains(&s) && t > 0.0 && t < 1.0 {
                    out.push(t);
                }
            } else if cross(ap, d) == 0.0 {
                // Collinear: the segment runs along this edge; its ends bound the overlap.
                let dd = d[0] * d[0] + d[1] * d[1];
                let aq = [q[0] - a[0], q[1] - a[1]];
                for t in [(ap[0] * d[0] + ap[1] * d[1]) / dd, (aq[0] * d[0] + aq[1] * d[1]) / dd] {
                    if t > 0.0 && t < 1.0 {
                        out.push(t);
                    }
                }
            }
        }
        out
    }

    /// Convex pieces whose union is the footprint, each an open counter-clockwise ring:
    /// the outer ring itself when the footprint is convex, else vertical trapezoids (see
    /// `slabs`). Pieces share edges but not area; slabs narrower than
    /// [`slabs::MIN_SLAB_WIDTH_M`] are left out.
    pub fn convex_pieces(&self) -> Vec<Vec<Point2>> {
        if self.convex {
            return vec![self.outer.clone()];
        }
        slabs::trapezoids(self)
    }

    /// The same footprint without the rectangle shortcut: queries take the polygon path.
    #[cfg(test)]
    pub(crate) fn into_general_polygon(mut self) -> Self {
        self.rect = None;
        self
    }
}

/// Where a point lies relative to one ring: on an edge, or an odd or even number of the
/// ring's edges to its east (ray to +east, half-open rule on vertices).
enum Side {
    Boundary,
    Odd,
    Even,
}

fn classify(ring: &[Point2], p: Point2) -> Side {
    let mut odd = false;
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        let ab = [b[0] - a[0], b[1] - a[1]];
        let ap = [p[0] - a[0], p[1] - a[1]];
        if cross(ab, ap) == 0.0
            && p[0] >= a[0].min(b[0])
            && p[0] <= a[0].max(b[0])
            && p[1] >= a[1].min(b[1])
            && p[1] <= a[1].max(b[1])
        {
            return Side::Boundary;
        }
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) * ab[0] / ab[1];
            if p[0] < x {
                odd = !odd;
            }
        }
    }
    if odd { Side::Odd } else { Side::Even }
}

pub(crate) fn ring_contains(ring: &[Point2], p: Point2) -> bool {
    !matches!(classify(ring, p), Side::Even)
}

fn cross(u: Point2, v: Point2) -> f64 {
    u[0] * v[1] - u[1] * v[0]
}

/// Signed shoelace area, square metres: positive for a counter-clockwise ring.
pub(crate) fn shoelace_m2(ring: &[Point2]) -> f64 {
    let n = ring.len();
    0.5 * (0..n).map(|i| cross(ring[i], ring[(i + 1) % n])).sum::<f64>()
}

fn segment_distance_m(p: Point2, a: Point2, b: Point2) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let ap = [p[0] - a[0], p[1] - a[1]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let s = if len2 > 0.0 { ((ap[0] * ab[0] + ap[1] * ab[1]) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (ap[0] - s * ab[0]).hypot(ap[1] - s * ab[1])
}

/// Drops the closing and repeated vertices, checks the ring and orients it
/// counter-clockwise (`ccw`) or clockwise.
fn normalise(mut ring: Vec<Point2>, index: usize, ccw: bool) -> Result<Vec<Point2>, FootprintError> {
    if let Some(vertex) = ring.iter().position(|p| !p[0].is_finite() || !p[1].is_finite()) {
        return Err(FootprintError::NotFinite { ring: index, vertex });
    }
    ring.dedup();
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    if ring.len() < 3 {
        return Err(FootprintError::TooFewVertices { ring: index, count: ring.len() });
    }
    let area = shoelace_m2(&ring);
    if area == 0.0 {
        return Err(FootprintError::ZeroArea { ring: index });
    }
    if (area > 0.0) != ccw {
        ring.reverse();
    }
    Ok(ring)
}

/// A counter-clockwise ring is convex when no turn is to the right.
fn is_convex(ring: &[Point2]) -> bool {
    let n = ring.len();
    (0..n).all(|i| {
        let (a, b, c) = (ring[i], ring[(i + 1) % n], ring[(i + 2) % n]);
        cross([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]) >= 0.0
    })
}

/// Four vertices, edges alternately parallel to the east and north axes.
fn is_axis_rectangle(ring: &[Point2]) -> bool {
    if ring.len() != 4 {
        return false;
    }
    let east_first = ring[0][1] == ring[1][1];
    (0..4).all(|i| {
        let (a, b) = (ring[i], ring[(i + 1) % 4]);
        if (i % 2 == 0) == east_first { a[1] == b[1] } else { a[0] == b[0] }
    })
}

#[cfg(test)]
mod tests;
