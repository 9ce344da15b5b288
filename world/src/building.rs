//! One building: a vertical prism over a polygon footprint (holes allowed) in world ENU,
//! and the prism geometry the queries need.
//!
//! Frame and units: world ENU metres (x east, y north, z up from the origin's ground). The
//! prism is `{(e, n, u) : (e, n) on the footprint, base_up_m <= u <= roof_up_m}`: vertical
//! walls, a flat base and a flat roof; closed (a point on a face is inside).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::footprint::{AxisRect, Footprint};

/// Why a prism cannot be a building.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum BuildingError {
    /// The base or the height is NaN or infinite.
    #[error("failed to build a building: base {base_up_m} m or height {height_m} m is not finite")]
    NotFinite { base_up_m: f64, height_m: f64 },
    /// The roof is not above the base.
    #[error("failed to build a building: height {height_m} m must be > 0")]
    NotTall { height_m: f64 },
}

/// A vertical prism standing on (or above) the ground, world ENU metres.
///
/// The roof altitude is `base_up_m + height_m` ([`Building::roof_up_m`]), computed the same
/// way for every query, so the top face is one value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Building {
    footprint: Footprint,
    base_up_m: f64,
    height_m: f64,
}

impl Building {
    /// A prism over `footprint` from `base_up_m` (ENU up, metres: for a building on the
    /// ground, the terrain height; plus `min_height` for an OpenStreetMap `building:part`)
    /// up `height_m` metres.
    ///
    /// # Errors
    /// A non-finite base or height, or a height that is not positive.
    pub fn new(footprint: Footprint, base_up_m: f64, height_m: f64) -> Result<Self, BuildingError> {
        if !base_up_m.is_finite() || !height_m.is_finite() {
            return Err(BuildingError::NotFinite { base_up_m, height_m });
        }
        if height_m <= 0.0 {
            return Err(BuildingError::NotTall { height_m });
        }
        Ok(Self { footprint, base_up_m, height_m })
    }

    /// The procedural city's box: an axis-aligned rectangle prism. `height_m > 0` and finite
    /// values are the caller's to ensure.
    pub(crate) fn boxed(rect: AxisRect, base_up_m: f64, height_m: f64) -> Self {
        Self { footprint: Footprint::rectangle(rect), base_up_m, height_m }
    }

    /// The footprint polygon.
    pub fn footprint(&self) -> &Footprint {
        &self.footprint
    }

    /// Height of the prism's bottom (ENU up), metres.
    pub fn base_up_m(&self) -> f64 {
        self.base_up_m
    }

    /// Height of the roof above the base, metres (> 0).
    pub fn height_m(&self) -> f64 {
        self.height_m
    }

    /// Roof altitude in ENU up, metres: `base_up_m + height_m`.
    pub fn roof_up_m(&self) -> f64 {
        self.base_up_m + self.height_m
    }

    /// Footprint area, square metres.
    pub fn footprint_area_m2(&self) -> f64 {
        self.footprint.area_m2()
    }

    /// Lower corner of the bounding box (west, south, base), ENU metres.
    pub fn min_corner(&self) -> Vector3<f64> {
        let r = self.footprint.bounds();
        Vector3::new(r[0], r[1], self.base_up_m)
    }

    /// Upper corner of the bounding box (east, north, roof), ENU metres.
    pub fn max_corner(&self) -> Vector3<f64> {
        let r = self.footprint.bounds();
        Vector3::new(r[2], r[3], self.roof_up_m())
    }

    /// Whether the horizontal point lies on the footprint (edges included, holes not).
    pub fn footprint_contains(&self, east_m: f64, north_m: f64) -> bool {
        self.footprint.contains(east_m, north_m)
    }

    /// Whether the ENU point lies inside the closed prism.
    pub fn contains(&self, pos: &Vector3<f64>) -> bool {
        pos.z >= self.base_up_m && pos.z <= self.roof_up_m() && self.footprint_contains(pos.x, pos.y)
    }

    /// Whether the footprint and the closed disc of `radius_m` around (east, north) share a
    /// point: the distance from the disc centre to the nearest footprint point is <= radius.
    pub fn footprint_touches_disc(&self, east_m: f64, north_m: f64, radius_m: f64) -> bool {
        self.footprint.touches_disc(east_m, north_m, radius_m)
    }

    /// Where the segment `a + t (b - a)`, `t` in [0, 1], first meets the closed prism: the
    /// smallest such `t`, or `None`. A segment starting inside the prism meets it at `t = 0`.
    pub fn segment_entry_t(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Option<f64> {
        if self.footprint.axis_rect().is_some() {
            return clip_segment(a, &(b - a), &self.min_corner(), &self.max_corner()).map(|(t_enter, _)| t_enter);
        }
        self.segment_intervals(a, b).first().map(|&(t_enter, _)| t_enter)
    }

    /// The parameter intervals `[t_enter, t_exit]` within [0, 1], ascending and disjoint,
    /// where `a + t (b - a)` lies in the closed prism: one for a convex footprint, several
    /// when the segment crosses a courtyard or a concave notch. A grazing contact gives
    /// `t_enter == t_exit`.
    ///
    /// Exact up to rounding: the segment's height band `[base, roof]` is one slab
    /// (Kay & Kajiya), and the footprint's boundary crossings cut the horizontal projection
    /// into pieces that lie wholly inside or outside, each tested at its middle.
    pub fn segment_intervals(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Vec<(f64, f64)> {
        let d = b - a;
        if self.footprint.axis_rect().is_some() {
            return clip_segment(a, &d, &self.min_corner(), &self.max_corner()).into_iter().collect();
        }
        let Some((z_enter, z_exit)) = clip_axis(a.z, d.z, self.base_up_m, self.roof_up_m()) else {
            return Vec::new();
        };
        let at = |t: f64| self.footprint.contains(a.x + t * d.x, a.y + t * d.y);
        if d.x == 0.0 && d.y == 0.0 {
            return if at(0.0) { vec![(z_enter, z_exit)] } else { Vec::new() };
        }
        let mut ts = self.footprint.boundary_crossings([a.x, a.y], [d.x, d.y]);
        ts.push(0.0);
        ts.push(1.0);
        ts.sort_by(f64::total_cmp);
        ts.dedup();
        let mut horizontal: Vec<(f64, f64)> = Vec::new();
        let mut push = |lo: f64, hi: f64| match horizontal.last_mut() {
            Some(last) if last.1 >= lo => last.1 = last.1.max(hi),
            _ => horizontal.push((lo, hi)),
        };
        for (k, &t) in ts.iter().enumerate() {
            // The crossing itself (a grazed vertex is inside alone), then the piece after it.
            if at(t) {
                push(t, t);
            }
            if let Some(&next) = ts.get(k + 1)
                && at(0.5 * (t + next))
            {
                push(t, next);
            }
        }
        horizontal
            .into_iter()
            .filter_map(|(lo, hi)| {
                let (lo, hi) = (lo.max(z_enter), hi.min(z_exit));
                (lo <= hi).then_some((lo, hi))
            })
            .collect()
    }
}

/// The interval of `t` in [0, 1] where `a + t d` lies in `[lo, hi]` along one axis.
fn clip_axis(a: f64, d: f64, lo: f64, hi: f64) -> Option<(f64, f64)> {
    if d == 0.0 {
        return (a >= lo && a <= hi).then_some((0.0, 1.0));
    }
    let (t0, t1) = ((lo - a) / d, (hi - a) / d);
    let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    let (t_enter, t_exit) = (near.max(0.0), far.min(1.0));
    (t_enter <= t_exit).then_some((t_enter, t_exit))
}

/// The parameter interval `[t0, t1]` within [0, 1] where `a + t d` lies in the closed box
/// `[lo, hi]`, or `None`. Slab method (Kay & Kajiya 1986): intersect, axis by axis, the
/// interval where the segment lies between the two faces normal to that axis.
pub fn clip_segment(a: &Vector3<f64>, d: &Vector3<f64>, lo: &Vector3<f64>, hi: &Vector3<f64>) -> Option<(f64, f64)> {
    let (mut t_enter, mut t_exit) = (0.0_f64, 1.0_f64);
    for axis in 0..3 {
        if d[axis] == 0.0 {
            // Parallel to this pair of faces: inside the slab for every t, or never.
            if a[axis] < lo[axis] || a[axis] > hi[axis] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[axis];
        let (t0, t1) = ((lo[axis] - a[axis]) * inv, (hi[axis] - a[axis]) * inv);
        let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        t_enter = t_enter.max(near);
        t_exit = t_exit.min(far);
        if t_enter > t_exit {
            return None;
        }
    }
    Some((t_enter, t_exit))
}

#[cfg(test)]
mod tests;
