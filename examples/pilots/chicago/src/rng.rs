//! A small seeded random generator for the hobbyists' waypoints: SplitMix64 (Steele, Lea,
//! Flood 2014). Written out rather than taken from a crate so that a dependency upgrade
//! cannot change which waypoints a seed gives.

use sadesim_crds::polygon::{self, Point};

use crate::geometry;

/// SplitMix64: a 64-bit state advanced by a constant and mixed.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// The stream of drone `index` under the pilot's `seed` (same seed and index, same
    /// waypoints).
    pub fn for_drone(seed: u64, index: u32) -> Self {
        let mut rng = Self { state: seed ^ (u64::from(index) + 1).wrapping_mul(0xA076_1D64_78BD_642F) };
        rng.next_u64(); // decorrelate neighbouring indices
        rng
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform over the disc of `radius_m` round `center` (by area).
    pub fn point_in_disc(&mut self, center: Point, radius_m: f64) -> Point {
        let r = radius_m * self.unit().sqrt();
        let angle = std::f64::consts::TAU * self.unit();
        (center.0 + r * angle.cos(), center.1 + r * angle.sin())
    }

    /// Uniform over the part of the polygon at least `margin_m` inside its outline
    /// (rejection sampling over its bounds); `None` after 10 000 misses (a sliver).
    pub fn point_in_polygon(&mut self, poly: &[Point], margin_m: f64) -> Option<Point> {
        let (x0, y0, x1, y1) = geometry::bounds(poly);
        (0..10_000).find_map(|_| {
            let p = (self.range(x0, x1), self.range(y0, y1));
            (polygon::contains(poly, p) && polygon::distance_to_boundary(poly, p) >= margin_m).then_some(p)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_and_drone_give_the_same_stream_and_drones_differ() {
        let (mut a, mut b, mut c) = (Rng::for_drone(7, 3), Rng::for_drone(7, 3), Rng::for_drone(7, 4));
        let xs: Vec<u64> = (0..5).map(|_| a.next_u64()).collect();
        let ys: Vec<u64> = (0..5).map(|_| b.next_u64()).collect();
        let zs: Vec<u64> = (0..5).map(|_| c.next_u64()).collect();
        assert_eq!(xs, ys);
        assert_ne!(xs, zs);
    }

    #[test]
    fn samples_stay_in_their_disc_and_polygon() {
        let mut rng = Rng::for_drone(1, 0);
        for _ in 0..1000 {
            let u = rng.unit();
            assert!((0.0..1.0).contains(&u));
            let p = rng.point_in_disc((100.0, -50.0), 30.0);
            assert!(geometry::distance(p, (100.0, -50.0)) <= 30.0);
        }
        let square = [(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)];
        for _ in 0..200 {
            let p = rng.point_in_polygon(&square, 20.0).expect("room inside");
            assert!((20.0..=80.0).contains(&p.0) && (20.0..=80.0).contains(&p.1), "{p:?}");
        }
        assert_eq!(rng.point_in_polygon(&square, 60.0), None, "no point is 60 m inside a 100 m square");
    }
}
