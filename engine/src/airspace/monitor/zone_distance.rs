//! Each drone's closest horizontal approach to a zone it may not enter: the margin a
//! drone kept from the airspace it had no lease for (`closestZoneM` in `summary.json`).
//!
//! # Rules
//! At every window sample of an airborne drone, a zone counts when it is active, the
//! drone is between its floor and ceiling (over the ground under the drone, as the
//! monitor judges a volume) and the drone holds no valid lease for it. The distance is
//! horizontal: 0 inside the outline, else to its nearest edge. An unauthorized entry the
//! monitor finds between two samples (a clipped corner) also counts as 0.
//!
//! # Cost
//! The distance to a zone's bounding box bounds the distance to its outline from below,
//! so a zone that cannot beat the drone's closest approach so far costs one box test;
//! the lease is asked about, and the outline measured, only for zones that can.
//!
//! # Caveats
//! Sampled at window boundaries: a drone passing beside a zone's corner between two
//! samples may have come closer than the recorded minimum (by at most half the distance
//! flown in a window).

use super::{Monitor, Sample, WatchedZone};
use crate::airspace::authority::LeaseConstraints;

impl Monitor {
    /// Drone `i` airborne at `now`: its distance to every zone it may not be in, kept when
    /// it is the closest so far.
    pub(super) fn watch_zone_distance(
        &mut self,
        i: usize,
        now: &Sample,
        lease: &dyn Fn(u32, &str, f64) -> Option<LeaseConstraints>,
    ) {
        let Self { zones, drones, .. } = self;
        let closest = &mut drones[i].closest_zone_m;
        let (e, n) = (now.p.east_m, now.p.north_m);
        for zone in zones.iter() {
            if closest.is_some_and(|c| zone.box_distance_m(e, n) >= c) || !zone.volume.is_active(now.time_s) {
                continue;
            }
            let (floor, ceiling) = zone.volume.vertical_limits_up_m(now.ground_up_m);
            if now.p.up_m < floor || now.p.up_m > ceiling {
                continue;
            }
            if lease(i as u32, &zone.volume.name, now.time_s).is_some() {
                continue;
            }
            let distance_m =
                if zone.volume.contains_horizontal(e, n) { 0.0 } else { zone.volume.distance_to_boundary_m(e, n) };
            if closest.is_none_or(|c| distance_m < c) {
                *closest = Some(distance_m);
            }
        }
    }

    /// Per drone (index order), the closest horizontal approach to a zone it held no
    /// valid lease for, metres ([the rules](self)); `None` for a drone that never came
    /// within such a zone's altitude band while airborne, and for every drone of a run
    /// without zones.
    pub fn closest_zones_m(&self) -> Vec<Option<f64>> {
        self.drones.iter().map(|d| d.closest_zone_m).collect()
    }
}

impl WatchedZone {
    /// Horizontal distance from the position to the zone's bounding box, metres (0 inside
    /// it): never more than the distance to the outline.
    fn box_distance_m(&self, east_m: f64, north_m: f64) -> f64 {
        let de = (self.min.0 - east_m).max(east_m - self.max.0).max(0.0);
        let dn = (self.min.1 - north_m).max(north_m - self.max.1).max(0.0);
        de.hypot(dn)
    }
}
