//! The ground-height query every consumer of terrain needs (zones with AGL limits, the
//! monitor, the geofence), so that they can be tested over level ground without a city.

/// Terrain height under a horizontal position: ENU up (metres above the origin's ground).
pub trait Ground {
    fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64;
}

/// Level ground at one height: for tests and flat worlds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlatGround(pub f64);

impl Ground for FlatGround {
    fn ground_up_m(&self, _east_m: f64, _north_m: f64) -> f64 {
        self.0
    }
}
