//! Who does what: each drone's task and the places it flies to, decided once for the whole
//! fleet before anyone takes off. Pure: roles, homes, the zone and the parks in; tasks out.
//!
//! Places are `(east_m, north_m)` on the run's local plane; altitudes are metres above the
//! drone's home (downtown is flat, so that is the height above ground).

use sadesim_crds::fleet::{HomePlacement, Role};
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::polygon::Point;
use sadesim_crds::run::SimulationRunSpec;

use crate::airspace::AltitudeBand;
use crate::geometry;

#[cfg(test)]
mod tests;

/// Public safety cruises at 375 ft, above the 350 ft the zone demands and every rooftop.
pub const PUBLIC_SAFETY_CRUISE_AGL_M: f64 = 114.3;
/// ...and asks for 110-121 m inside (under the 400 ft ceiling).
pub const PUBLIC_SAFETY_BAND: AltitudeBand = AltitudeBand { min_agl_m: 110.0, max_agl_m: 121.0 };
/// Where public safety waits for the verdict: this far outside the zone, metres.
pub const HOLD_OFFSET_M: f64 = 30.0;
/// Hold points of different drones are at least this far apart, metres.
pub const HOLD_SEPARATION_M: f64 = 40.0;
/// Watch points inside: on a circle of this radius round the zone's middle, metres...
pub const WATCH_RADIUS_M: f64 = 60.0;
/// ...each at least this far inside the outline, metres.
pub const WATCH_MARGIN_M: f64 = 30.0;
/// How long public safety watches the crowd, sim seconds.
pub const WATCH_S: f64 = 120.0;
/// Public safety denied entry waits this long at its hold point before going home, sim s.
pub const DENIED_HOLD_S: f64 = 60.0;

/// News crews cruise at 330 ft (above every rooftop)...
pub const JOURNALIST_CRUISE_AGL_M: f64 = 100.0;
/// ...and would film from 90-110 m inside.
pub const JOURNALIST_BAND: AltitudeBand = AltitudeBand { min_agl_m: 90.0, max_agl_m: 110.0 };
/// Their spots: this far north of the zone, metres (over Millennium Park)...
pub const SPOT_OFFSET_M: f64 = 40.0;
/// ...spread over the zone's width, kept this far in from its west and east ends, metres.
pub const SPOT_INSET_M: f64 = 15.0;
/// Denied, they loiter at their spot this long, sim seconds.
pub const LOITER_S: f64 = 120.0;
/// With `--journalists-ignore-denials` they go this far into the zone, metres...
pub const INTRUSION_DEPTH_M: f64 = 60.0;
/// ...and stay this long, sim seconds.
pub const INTRUSION_S: f64 = 30.0;

/// Hobbyists take off to 20 m...
pub const RECREATIONAL_TAKEOFF_AGL_M: f64 = 20.0;
/// ...and fly their waypoints at 15-27 m (below 100 ft), the band they ask for.
pub const RECREATIONAL_BAND: AltitudeBand = AltitudeBand { min_agl_m: 15.0, max_agl_m: 27.0 };
/// Waypoints per hobbyist after the denied look at the museum.
pub const RECREATIONAL_WAYPOINTS: usize = 6;
/// Hold at each waypoint, sim seconds.
pub const RECREATIONAL_HOLD_S: f64 = 5.0;
/// Waypoints are within this distance of home, metres...
pub const WANDER_RADIUS_M: f64 = 300.0;
/// ...and this far inside the park the drone launched from, metres (the parks are the
/// only ground known to be free of buildings at hobby altitudes).
pub const PARK_MARGIN_M: f64 = 10.0;

/// A disc on the local plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disc {
    pub center: Point,
    pub radius_m: f64,
}

/// One drone as the planner sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Member {
    pub role: Role,
    pub home: Point,
}

/// What one drone does.
#[derive(Clone, Debug, PartialEq)]
pub enum Task {
    /// Fly to `hold` (outside the zone), ask, enter to `watch` when granted, watch.
    PublicSafety { hold: Point, watch: Point },
    /// Fly to `spot` (north of the zone), ask, loiter when denied; `inside` is where a
    /// granted (or non-compliant) crew films from.
    Journalist { spot: Point, inside: Point },
    /// Ask for a look inside the zone, then wander between random waypoints in `area`.
    Recreational { area: Disc },
    /// A role the case study has no behaviour for: the drone stays on the ground.
    Unassigned,
}

/// Every drone's task for the zone `outline`. Public safety drones get hold points on the
/// side facing their homes (served in fleet order, kept apart) and watch points spread
/// inside in the same angular order; journalists get spots north of the zone in west-to-east
/// order of their homes; hobbyists get the park round their home (`parks`), see
/// [`operating_area`].
pub fn assign(members: &[Member], outline: &[Point], parks: &[Disc]) -> Vec<Task> {
    let of_role = |role: Role| -> Vec<usize> { (0..members.len()).filter(|&i| members[i].role == role).collect() };
    let mut tasks = vec![Task::Unassigned; members.len()];

    let safety = of_role(Role::PublicSafety);
    let homes: Vec<Point> = safety.iter().map(|&i| members[i].home).collect();
    let holds = geometry::hold_points(outline, &homes, HOLD_OFFSET_M, HOLD_SEPARATION_M);
    let watches = geometry::inside_points(outline, &holds, WATCH_RADIUS_M, WATCH_MARGIN_M);
    for (k, &i) in safety.iter().enumerate() {
        tasks[i] = Task::PublicSafety { hold: holds[k], watch: watches[k] };
    }

    let mut crews = of_role(Role::Journalist);
    crews.sort_by(|&i, &j| members[i].home.0.total_cmp(&members[j].home.0).then(i.cmp(&j)));
    let spots = geometry::north_side_spots(outline, crews.len(), SPOT_OFFSET_M, SPOT_INSET_M);
    for (k, &i) in crews.iter().enumerate() {
        let inside = geometry::point_inside_from(outline, spots[k], INTRUSION_DEPTH_M);
        tasks[i] = Task::Journalist { spot: spots[k], inside };
    }

    for i in of_role(Role::Recreational) {
        tasks[i] = Task::Recreational { area: operating_area(members[i].home, parks) };
    }
    tasks
}

/// Where a hobbyist flies: the smallest park containing its home, shrunk by
/// [`PARK_MARGIN_M`] (waypoints are also kept within [`WANDER_RADIUS_M`] of home by the
/// caller). Without a park round the home: the disc of [`WANDER_RADIUS_M`] round it.
pub fn operating_area(home: Point, parks: &[Disc]) -> Disc {
    parks
        .iter()
        .filter(|p| geometry::distance(p.center, home) <= p.radius_m)
        .min_by(|a, b| a.radius_m.total_cmp(&b.radius_m))
        .map(|p| Disc { center: p.center, radius_m: (p.radius_m - PARK_MARGIN_M).max(1.0) })
        .unwrap_or(Disc { center: home, radius_m: WANDER_RADIUS_M })
}

/// The ground a scenario keeps free of buildings: `world.openAreas` and every group's
/// park-style home `areas`, on `frame`'s plane.
pub fn parks(spec: &SimulationRunSpec, frame: &LocalFrame) -> Vec<Disc> {
    let world = spec.world();
    let mut areas: Vec<&sadesim_crds::fleet::Area> = world.open_areas.iter().collect();
    for group in &spec.fleet {
        if let HomePlacement::Areas(list) = &group.homes {
            areas.extend(list);
        }
    }
    areas
        .into_iter()
        .map(|a| Disc { center: frame.to_plane(a.center.latitude_deg, a.center.longitude_deg), radius_m: a.radius_m })
        .collect()
}

/// The wind a pilot plans with (a forecast): where it blows from and how hard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wind {
    /// Unit vector on the local plane pointing towards where the wind comes from (a
    /// westerly: `(-1, 0)`).
    pub from: Point,
    /// Mean speed near the ground, m/s.
    pub speed_mps: f64,
}

/// The scenario's mean wind (`environment.wind`), calm when it has none.
pub fn wind(spec: &SimulationRunSpec) -> Wind {
    match spec.environment().wind {
        Some(w) => {
            let d = w.direction_from_deg.to_radians();
            Wind { from: (d.sin(), d.cos()), speed_mps: w.speed_mps }
        }
        None => Wind { from: (0.0, 1.0), speed_mps: 0.0 },
    }
}

/// How much more charge per second a leg in direction `direction` costs than the
/// average since takeoff: 1.25 in calm air or across the wind, up to 1.25 + 0.18 per m/s of
/// wind straight into it (2.15 into a 5 m/s westerly, as measured on x500s flying 2 km
/// west at 100 m), never under 1. Unknown wind (`None`): assume a 5 m/s headwind.
pub fn return_cost_factor(direction: Point, wind: Option<Wind>) -> f64 {
    let Some(w) = wind else { return 1.25 + 0.18 * 5.0 };
    let len = direction.0.hypot(direction.1);
    if len < 1e-9 {
        return 1.25;
    }
    let into_wind = (direction.0 * w.from.0 + direction.1 * w.from.1) / len;
    (1.25 + 0.18 * w.speed_mps * into_wind).max(1.0)
}

/// The altitude to fly inside a zone under a lease: `preferred_m` moved into the band the
/// drone asked for, at least `margin_m` above the lease's minimum and below its maximum,
/// and `margin_m` under the drone's own ceiling. `None` when no altitude satisfies all of
/// them (a hobbyist under 100 ft cannot keep a 350 ft minimum): the drone must not enter.
pub fn inside_altitude(
    preferred_m: f64,
    band: AltitudeBand,
    lease_min_m: Option<f64>,
    lease_max_m: Option<f64>,
    ceiling_m: f64,
    margin_m: f64,
) -> Option<f64> {
    let low = band.min_agl_m.max(lease_min_m.map_or(f64::NEG_INFINITY, |m| m + margin_m));
    let high = band.max_agl_m.min(lease_max_m.map_or(f64::INFINITY, |m| m - margin_m)).min(ceiling_m - margin_m);
    (low <= high).then(|| preferred_m.clamp(low, high))
}
