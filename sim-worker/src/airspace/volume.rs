//! Zones as volumes in the local ENU frame.
//!
//! A zone is a polygon given in lat/lon, projected once onto the local horizontal plane
//! (`LocalFrame::to_plane`), extruded between a floor and a ceiling that are each either
//! above ground level (AGL: relative to the terrain directly below the point, so the
//! volume follows uneven ground) or above mean sea level (MSL: a fixed height,
//! `spec.origin.altitudeMslM + up`). A zone is active in `[active_from_s, active_until_s)`.

use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::polygon::Point;
use sadesim_crds::zones::{Zone, ZoneAltitude};

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
        let _ = (zone, frame);
        unimplemented!("airspace::volume")
    }

    /// Whether the zone is active at `time_s`.
    pub fn is_active(&self, time_s: f64) -> bool {
        let _ = time_s;
        unimplemented!("airspace::volume")
    }

    /// Whether the horizontal position is inside the outline (boundary counts as inside).
    pub fn contains_horizontal(&self, east_m: f64, north_m: f64) -> bool {
        let _ = (east_m, north_m);
        unimplemented!("airspace::volume")
    }

    /// Floor and ceiling as ENU up (metres) over a point whose ground is `ground_up_m`.
    pub fn vertical_limits_up_m(&self, ground_up_m: f64) -> (f64, f64) {
        let _ = ground_up_m;
        unimplemented!("airspace::volume")
    }

    /// Whether `p` is inside the volume (ignoring the time window); `ground_up_m` is the
    /// terrain height under `p`.
    pub fn contains(&self, p: Enu, ground_up_m: f64) -> bool {
        let _ = (p, ground_up_m);
        unimplemented!("airspace::volume")
    }

    /// Where the straight segment `a -> b` first is inside the volume, as a fraction of
    /// the way from `a` (0 when `a` is inside), or `None` when it never is. Ground heights
    /// under the segment come from `ground`. Catches a fast drone that passes through a
    /// corner between two samples.
    pub fn first_inside(&self, a: Enu, b: Enu, ground: &dyn Ground) -> Option<f64> {
        let _ = (a, b, ground);
        unimplemented!("airspace::volume")
    }

    /// Horizontal distance from the position to the outline, metres (positive outside and
    /// inside alike).
    pub fn distance_to_boundary_m(&self, east_m: f64, north_m: f64) -> f64 {
        let _ = (east_m, north_m);
        unimplemented!("airspace::volume")
    }
}
