//! Zones as volumes in the local ENU frame.
//!
//! A zone is a polygon given in lat/lon, projected once onto the local horizontal plane
//! (`LocalFrame::to_plane`), extruded between a floor and a ceiling that are each either
//! above ground level (AGL: relative to the terrain directly below the point, so the
//! volume follows uneven ground) or above mean sea level (MSL: a fixed height,
//! `spec.origin.altitudeMslM + up`). A zone is active in `[active_from_s, active_until_s)`.

use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::polygon::{self, Point};
use sadesim_crds::validate::duration_s;
use sadesim_crds::zones::{AltitudeReference, Zone, ZoneAltitude};

/// A horizontal position this close to the outline counts as on it, hence inside, metres.
/// Absorbs rounding in the ray-casting test and in segment/edge intersections (1 µm).
pub const BOUNDARY_TOLERANCE_M: f64 = 1e-6;

/// Largest horizontal spacing, metres, between the terrain samples [`ZoneVolume::first_inside`]
/// takes under a segment when a limit is AGL; between samples the ground is taken as linear.
pub const GROUND_SAMPLE_SPACING_M: f64 = 1.0;

/// Most terrain samples per horizontal interval inside the outline (bounds the cost of a
/// teleport-length segment; 100 km at 1 m spacing).
pub const MAX_GROUND_SAMPLES: usize = 100_000;

pub use sadesim_world::{FlatGround, Ground};

/// One zone, ready for queries.
#[derive(Clone, Debug, PartialEq)]
pub struct ZoneVolume {
    /// The zone's name (unique in the run).
    pub name: String,
    /// Outline in the local plane, (east_m, north_m), as given (either winding).
    pub polygon: Vec<Point>,
    pub floor: ZoneAltitude,
    pub ceiling: ZoneAltitude,
    /// Sim seconds; 0 when the zone is active from the start.
    pub active_from_s: f64,
    /// Sim seconds; `f64::INFINITY` when active until the end.
    pub active_until_s: f64,
    /// MSL altitude of ENU up = 0 (the origin's altitude), metres.
    pub origin_msl_m: f64,
}

impl ZoneVolume {
    /// Projects a validated zone onto the run's frame.
    pub fn new(zone: &Zone, frame: &LocalFrame) -> Self {
        Self {
            name: zone.name.clone(),
            polygon: zone.polygon.iter().map(|v| frame.to_plane(v.latitude_deg, v.longitude_deg)).collect(),
            floor: zone.floor(),
            ceiling: zone.ceiling,
            active_from_s: zone.active_from.as_ref().map_or(0.0, duration_s),
            active_until_s: zone.active_until.as_ref().map_or(f64::INFINITY, duration_s),
            origin_msl_m: frame.origin().altitude_msl_m,
        }
    }

    /// Whether the zone is active at `time_s` (from included, until excluded).
    pub fn is_active(&self, time_s: f64) -> bool {
        time_s >= self.active_from_s && time_s < self.active_until_s
    }

    /// Whether the horizontal position is inside the outline (boundary counts as inside,
    /// within [`BOUNDARY_TOLERANCE_M`]). Even-odd ray casting: concave outlines and either
    /// winding work.
    pub fn contains_horizontal(&self, east_m: f64, north_m: f64) -> bool {
        let p = (east_m, north_m);
        polygon::contains(&self.polygon, p) || polygon::distance_to_boundary(&self.polygon, p) <= BOUNDARY_TOLERANCE_M
    }

    /// Floor and ceiling as ENU up (metres) over a point whose ground is `ground_up_m`.
    pub fn vertical_limits_up_m(&self, ground_up_m: f64) -> (f64, f64) {
        (self.altitude_up_m(self.floor, ground_up_m), self.altitude_up_m(self.ceiling, ground_up_m))
    }

    /// One limit as ENU up: AGL heights ride on the ground below, MSL heights are fixed
    /// (`height - origin MSL`, since ENU up 0 is the origin's altitude).
    fn altitude_up_m(&self, altitude: ZoneAltitude, ground_up_m: f64) -> f64 {
        match altitude.reference {
            AltitudeReference::Agl => ground_up_m + altitude.height_m,
            AltitudeReference::Msl => altitude.height_m - self.origin_msl_m,
        }
    }

    /// Whether either limit follows the terrain.
    fn follows_ground(&self) -> bool {
        self.floor.reference == AltitudeReference::Agl || self.ceiling.reference == AltitudeReference::Agl
    }

    /// Whether `p` is inside the volume (ignoring the time window); `ground_up_m` is the
    /// terrain height under `p`. Floor and ceiling are included.
    pub fn contains(&self, p: Enu, ground_up_m: f64) -> bool {
        let (floor, ceiling) = self.vertical_limits_up_m(ground_up_m);
        self.contains_horizontal(p.east_m, p.north_m) && floor <= p.up_m && p.up_m <= ceiling
    }

    /// Where the straight segment `a -> b` first is inside the volume, as a fraction of
    /// the way from `a` (0 when `a` is inside), or `None` when it never is. Ground heights
    /// under the segment come from `ground`. Catches a fast drone that passes through a
    /// corner between two samples.
    ///
    /// How: the segment is cut at every crossing with an outline edge, which splits it
    /// into pieces that are wholly inside or wholly outside horizontally (a piece's
    /// midpoint tells which); touching points are checked too. Within each inside piece,
    /// in order, the heights are solved exactly: the segment's `up` is linear in the
    /// fraction, and so are the limits (constant for MSL).
    ///
    /// # Caveats
    /// With an AGL limit the terrain is sampled every [`GROUND_SAMPLE_SPACING_M`]
    /// horizontally (at most [`MAX_GROUND_SAMPLES`] per piece) and taken as linear between
    /// samples: a terrain feature narrower than that can be missed. The returned fraction
    /// is exact up to rounding (a point within about 1e-9 m of the volume's surface).
    pub fn first_inside(&self, a: Enu, b: Enu, ground: &dyn Ground) -> Option<f64> {
        let at = |t: f64| {
            Enu::new(
                a.east_m + t * (b.east_m - a.east_m),
                a.north_m + t * (b.north_m - a.north_m),
                a.up_m + t * (b.up_m - a.up_m),
            )
        };
        let contains_at = |t: f64| {
            let p = at(t);
            self.contains(p, ground.ground_up_m(p.east_m, p.north_m))
        };
        if contains_at(0.0) {
            return Some(0.0);
        }
        let cuts = self.edge_crossings((a.east_m, a.north_m), (b.east_m, b.north_m));
        for pair in cuts.windows(2) {
            let (t0, t1) = (pair[0], pair[1]);
            // The cut itself: a touch on a vertex or an edge may be the only contact.
            if contains_at(t0) {
                return Some(t0);
            }
            let mid = at(0.5 * (t0 + t1));
            if t1 > t0
                && self.contains_horizontal(mid.east_m, mid.north_m)
                && let Some(t) = self.first_within_limits(&at, t0, t1, ground)
            {
                return Some(t);
            }
        }
        cuts.last().copied().filter(|&t| contains_at(t))
    }

    /// Fractions along the horizontal segment `a -> b` where it meets an outline edge,
    /// with 0 and 1, sorted and without duplicates. A segment running along an edge
    /// contributes the ends of the overlap.
    fn edge_crossings(&self, a: Point, b: Point) -> Vec<f64> {
        let cross = |u: Point, v: Point| u.0 * v.1 - u.1 * v.0;
        let r = (b.0 - a.0, b.1 - a.1);
        let r_len2 = r.0 * r.0 + r.1 * r.1;
        let mut cuts = vec![0.0, 1.0];
        if r_len2 > 0.0 {
            // Relative tolerance on the fractions for the parallel test and the [0, 1] ranges.
            let eps = 1e-12;
            let n = self.polygon.len();
            for i in 0..n {
                let (c, d) = (self.polygon[i], self.polygon[(i + 1) % n]);
                let s = (d.0 - c.0, d.1 - c.1);
                let ca = (c.0 - a.0, c.1 - a.1);
                let denom = cross(r, s);
                let scale = r_len2.sqrt() * s.0.hypot(s.1);
                if denom.abs() > eps * scale {
                    // a + t r = c + u s: t along the segment, u along the edge.
                    let t = cross(ca, s) / denom;
                    let u = cross(ca, r) / denom;
                    if (-eps..=1.0 + eps).contains(&t) && (-eps..=1.0 + eps).contains(&u) {
                        cuts.push(t.clamp(0.0, 1.0));
                    }
                } else if cross(ca, r).abs() <= eps * scale.max(r_len2) {
                    // Collinear: the edge's ends projected onto the segment.
                    for e in [c, d] {
                        let t = ((e.0 - a.0) * r.0 + (e.1 - a.1) * r.1) / r_len2;
                        if (0.0..=1.0).contains(&t) {
                            cuts.push(t);
                        }
                    }
                }
            }
        }
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        cuts
    }

    /// The first fraction in `[t0, t1]` (a piece of the segment inside the outline) where
    /// the height is between floor and ceiling.
    fn first_within_limits(&self, at: &dyn Fn(f64) -> Enu, t0: f64, t1: f64, ground: &dyn Ground) -> Option<f64> {
        let steps = if self.follows_ground() {
            let (p0, p1) = (at(t0), at(t1));
            let len_m = (p1.east_m - p0.east_m).hypot(p1.north_m - p0.north_m);
            ((len_m / GROUND_SAMPLE_SPACING_M).ceil() as usize).clamp(1, MAX_GROUND_SAMPLES)
        } else {
            1
        };
        // Margins above the floor and below the ceiling at fraction t: inside when both >= 0.
        let margins = |t: f64| {
            let p = at(t);
            let (floor, ceiling) = self.vertical_limits_up_m(ground.ground_up_m(p.east_m, p.north_m));
            (p.up_m - floor, ceiling - p.up_m)
        };
        let mut s0 = t0;
        let mut m0 = margins(s0);
        for k in 1..=steps {
            let s1 = if k == steps { t1 } else { t0 + (t1 - t0) * k as f64 / steps as f64 };
            let m1 = margins(s1);
            // Both margins are linear on [s0, s1]: intersect where each is >= 0.
            let (lo_a, hi_a) = nonnegative_part(s0, s1, m0.0, m1.0);
            let (lo_b, hi_b) = nonnegative_part(s0, s1, m0.1, m1.1);
            let (lo, hi) = (lo_a.max(lo_b), hi_a.min(hi_b));
            if lo <= hi {
                return Some(lo);
            }
            (s0, m0) = (s1, m1);
        }
        None
    }

    /// Horizontal distance from the position to the outline, metres (positive outside and
    /// inside alike).
    pub fn distance_to_boundary_m(&self, east_m: f64, north_m: f64) -> f64 {
        polygon::distance_to_boundary(&self.polygon, (east_m, north_m))
    }
}

/// Where a function linear on `[s0, s1]` with end values `v0`, `v1` is >= 0, as
/// `(lo, hi)`; empty (lo > hi) when nowhere.
fn nonnegative_part(s0: f64, s1: f64, v0: f64, v1: f64) -> (f64, f64) {
    match (v0 >= 0.0, v1 >= 0.0) {
        (true, true) => (s0, s1),
        (false, false) => (f64::INFINITY, f64::NEG_INFINITY),
        (up, _) => {
            let zero = s0 + (s1 - s0) * v0 / (v0 - v1);
            if up { (s0, zero.clamp(s0, s1)) } else { (zero.clamp(s0, s1), s1) }
        }
    }
}

#[cfg(test)]
mod tests;
