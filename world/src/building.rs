//! One building: an axis-aligned box in world ENU, and the box geometry the queries need.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// An axis-aligned box standing on the ground, world ENU metres.
///
/// The footprint is `[center_east_m ± half_east_m] x [center_north_m ± half_north_m]`; the
/// box spans `up` from `base_up_m` (the ground at the footprint's centre) to
/// [`Building::roof_up_m`]. Boxes are closed: a point on a face is inside.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Building {
    /// Footprint centre, metres east of the origin.
    pub center_east_m: f64,
    /// Footprint centre, metres north of the origin.
    pub center_north_m: f64,
    /// Half the footprint's east-west side, metres (> 0).
    pub half_east_m: f64,
    /// Half the footprint's north-south side, metres (> 0).
    pub half_north_m: f64,
    /// Height of the box's bottom above the origin's ground (ENU up), metres: the terrain
    /// height at the footprint's centre.
    pub base_up_m: f64,
    /// Height of the roof above the base, metres (> 0).
    pub height_m: f64,
}

impl Building {
    /// Roof altitude in ENU up, metres: `base_up_m + height_m`.
    pub fn roof_up_m(&self) -> f64 {
        self.base_up_m + self.height_m
    }

    /// Footprint area, square metres.
    pub fn footprint_area_m2(&self) -> f64 {
        4.0 * self.half_east_m * self.half_north_m
    }

    /// Lower corner (west, south, base), ENU metres.
    pub fn min_corner(&self) -> Vector3<f64> {
        Vector3::new(self.center_east_m - self.half_east_m, self.center_north_m - self.half_north_m, self.base_up_m)
    }

    /// Upper corner (east, north, roof), ENU metres.
    pub fn max_corner(&self) -> Vector3<f64> {
        Vector3::new(self.center_east_m + self.half_east_m, self.center_north_m + self.half_north_m, self.roof_up_m())
    }

    /// Whether the horizontal point lies on the footprint (edges included).
    pub fn footprint_contains(&self, east_m: f64, north_m: f64) -> bool {
        (east_m - self.center_east_m).abs() <= self.half_east_m
            && (north_m - self.center_north_m).abs() <= self.half_north_m
    }

    /// Whether the ENU point lies inside the closed box.
    pub fn contains(&self, pos: &Vector3<f64>) -> bool {
        self.footprint_contains(pos.x, pos.y) && pos.z >= self.base_up_m && pos.z <= self.roof_up_m()
    }

    /// Whether the footprint and the closed disc of `radius_m` around (east, north) share a
    /// point: the distance from the disc centre to the nearest footprint point is <= radius.
    pub fn footprint_touches_disc(&self, east_m: f64, north_m: f64, radius_m: f64) -> bool {
        let dx = ((east_m - self.center_east_m).abs() - self.half_east_m).max(0.0);
        let dy = ((north_m - self.center_north_m).abs() - self.half_north_m).max(0.0);
        dx * dx + dy * dy <= radius_m * radius_m
    }

    /// Where the segment `a + t (b - a)`, `t` in [0, 1], first meets the closed box: the
    /// smallest such `t`, or `None`. A segment starting inside the box meets it at `t = 0`.
    pub fn segment_entry_t(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Option<f64> {
        clip_segment(a, &(b - a), &self.min_corner(), &self.max_corner()).map(|(t_enter, _)| t_enter)
    }
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
mod tests {
    use super::*;

    fn unit_box() -> Building {
        // 10 m x 20 m footprint centred at (100, 50), base 2 m, 30 m tall.
        Building {
            center_east_m: 100.0,
            center_north_m: 50.0,
            half_east_m: 5.0,
            half_north_m: 10.0,
            base_up_m: 2.0,
            height_m: 30.0,
        }
    }

    #[test]
    fn contains_is_closed_and_bounded_by_base_and_roof() {
        let b = unit_box();
        assert_eq!(b.roof_up_m(), 32.0);
        assert!(b.contains(&Vector3::new(100.0, 50.0, 10.0)));
        assert!(b.contains(&Vector3::new(105.0, 60.0, 32.0)), "faces belong to the box");
        assert!(!b.contains(&Vector3::new(100.0, 50.0, 32.1)), "above the roof");
        assert!(!b.contains(&Vector3::new(100.0, 50.0, 1.9)), "below the base");
        assert!(!b.contains(&Vector3::new(105.1, 50.0, 10.0)));
    }

    #[test]
    fn segment_entry_hits_the_near_face_and_misses_beside_and_above() {
        let b = unit_box();
        let a = Vector3::new(0.0, 50.0, 10.0);
        let t = b.segment_entry_t(&a, &Vector3::new(200.0, 50.0, 10.0)).expect("crosses the box");
        assert!((a.x + t * 200.0 - 95.0).abs() < 1e-9, "enters through the west face at x = 95");
        assert_eq!(b.segment_entry_t(&a, &Vector3::new(90.0, 50.0, 10.0)), None, "stops short");
        assert_eq!(b.segment_entry_t(&Vector3::new(0.0, 70.0, 10.0), &Vector3::new(200.0, 70.0, 10.0)), None);
        assert_eq!(b.segment_entry_t(&Vector3::new(0.0, 50.0, 40.0), &Vector3::new(200.0, 50.0, 40.0)), None);
        assert_eq!(b.segment_entry_t(&Vector3::new(100.0, 50.0, 5.0), &Vector3::new(0.0, 0.0, 0.0)), Some(0.0));
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
}
