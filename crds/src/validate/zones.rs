//! `spec.zones`: names, polygons, floor and ceiling, activity windows and policies, and
//! how the fleet meets them (nobody starts inside a zone that reaches the ground).

use std::collections::HashSet;

use crate::fleet::HomePlacement;
use crate::geo::LocalFrame;
use crate::polygon;
use crate::run::SimulationRunSpec;
use crate::zones::{AltitudeReference, MAX_POLYGON_VERTICES, Zone, ZoneAltitude};

use super::MAX_DURATION_S;
use super::problems::{Problems, duration_s};
use super::world::WorldBounds;

pub(super) fn reference_name(r: AltitudeReference) -> &'static str {
    match r {
        AltitudeReference::Agl => "agl",
        AltitudeReference::Msl => "msl",
    }
}

/// Altitude MSL of a zone boundary, using the origin's ground for AGL values. Only for
/// comparing floor and ceiling; the monitor uses the real ground under the drone.
pub(super) fn approx_msl(a: &ZoneAltitude, origin_alt_m: f64) -> f64 {
    match a.reference {
        AltitudeReference::Msl => a.height_m,
        AltitudeReference::Agl => a.height_m + origin_alt_m,
    }
}

pub(super) fn check_zones(
    spec: &SimulationRunSpec,
    bounds: Option<&WorldBounds>,
    run_duration_s: Option<f64>,
    p: &mut Problems,
) -> HashSet<String> {
    let mut names = HashSet::new();
    p.max_items("spec.zones", spec.zones.len(), 64);
    for (i, z) in spec.zones.iter().enumerate() {
        let path = format!("spec.zones[{i}]");
        p.dns_label(format!("{path}.name"), &z.name, 63);
        if !names.insert(z.name.clone()) {
            p.add(format!("{path}.name"), format!("duplicate zone name {:?}: zone names must be unique", z.name));
        }
        check_polygon(z, &path, bounds, p);
        let floor = z.floor();
        let floor_ok = p.range(format!("{path}.floor.heightM"), floor.height_m, -500.0, 20_000.0);
        let ceil_ok = p.range(format!("{path}.ceiling.heightM"), z.ceiling.height_m, -500.0, 20_000.0);
        if floor_ok && ceil_ok {
            let origin_alt = spec.origin.altitude_msl_m;
            if approx_msl(&floor, origin_alt) >= approx_msl(&z.ceiling, origin_alt) {
                p.add(
                    format!("{path}.ceiling"),
                    format!(
                        "floor must be below ceiling: floor {} m {}, ceiling {} m {}",
                        floor.height_m,
                        reference_name(floor.reference),
                        z.ceiling.height_m,
                        reference_name(z.ceiling.reference)
                    ),
                );
            }
        }
        let from = z.active_from.as_ref().map(duration_s);
        let until = z.active_until.as_ref().map(duration_s);
        if let Some(f) = from
            && f < 0.0
        {
            p.add(format!("{path}.activeFrom"), "must not be negative");
        }
        if let Some(u) = until
            && u <= from.unwrap_or(0.0)
        {
            p.add(format!("{path}.activeUntil"), "must be after activeFrom (and after the start)");
        }
        if let (Some(f), Some(d)) = (from, run_duration_s)
            && f >= d
        {
            p.add(
                format!("{path}.activeFrom"),
                format!("is after the run ends ({d} s): the zone would never be active"),
            );
        }
        let pol = &z.policy;
        if let Some(c) = pol.capacity {
            p.range_int(format!("{path}.policy.capacity"), c.into(), 1, 10_000);
        }
        if let Some(d) = &pol.lease_duration {
            p.duration(format!("{path}.policy.leaseDuration"), d, MAX_DURATION_S);
        }
        p.max_items(format!("{path}.policy.authorizedOperators"), pol.authorized_operators.len(), 64);
        for (k, op) in pol.authorized_operators.iter().enumerate() {
            if op.is_empty() || op.len() > 63 {
                p.add(format!("{path}.policy.authorizedOperators[{k}]"), "must be 1 to 63 characters");
            }
        }
        let min =
            pol.min_altitude_agl_m.filter(|v| p.range(format!("{path}.policy.minAltitudeAglM"), *v, 0.0, 20_000.0));
        let max =
            pol.max_altitude_agl_m.filter(|v| p.range(format!("{path}.policy.maxAltitudeAglM"), *v, 0.0, 20_000.0));
        if let (Some(lo), Some(hi)) = (min, max)
            && lo >= hi
        {
            p.add(
                format!("{path}.policy.minAltitudeAglM"),
                format!("must be below policy.maxAltitudeAglM ({hi}), got {lo}"),
            );
        }
        if let Some(lo) = min
            && z.ceiling.reference == AltitudeReference::Agl
            && lo >= z.ceiling.height_m
        {
            p.add(
                format!("{path}.policy.minAltitudeAglM"),
                format!(
                    "must be below the zone ceiling ({} m AGL) or no drone could comply, got {lo}",
                    z.ceiling.height_m
                ),
            );
        }
    }
    names
}

/// Zone polygon in the local plane, when all its vertices are usable.
pub(super) fn zone_points(z: &Zone, frame: &LocalFrame) -> Option<Vec<polygon::Point>> {
    let ok = z.polygon.len() >= 3
        && z.polygon
            .iter()
            .all(|v| v.latitude_deg.is_finite() && v.longitude_deg.is_finite() && v.latitude_deg.abs() <= 90.0);
    ok.then(|| z.polygon.iter().map(|v| frame.to_plane(v.latitude_deg, v.longitude_deg)).collect())
}

pub(super) fn disc_inside(polygon_pts: &[polygon::Point], c: polygon::Point, r: f64) -> bool {
    polygon::contains(polygon_pts, c) && polygon::distance_to_boundary(polygon_pts, c) >= r
}

/// Fleet against zones: nobody starts inside a zone that reaches the ground, and no
/// authorized group is too low to ever meet a zone's minimum altitude.
pub(super) fn check_zone_interactions(spec: &SimulationRunSpec, b: &WorldBounds, p: &mut Problems) {
    let origin_alt = spec.origin.altitude_msl_m;
    for z in &spec.zones {
        let Some(pts) = zone_points(z, &b.frame) else { continue };
        let floor = z.floor();
        let reaches_ground = approx_msl(&floor, origin_alt) <= origin_alt;
        let active_at_start = z.active_from.as_ref().is_none_or(|d| duration_s(d) <= 0.0);
        for (i, g) in spec.fleet.iter().enumerate() {
            let path = format!("spec.fleet[{i}]");
            if reaches_ground && active_at_start {
                let msg = |what: &str| {
                    format!(
                        "{what} zone {:?}, which reaches the ground: drones would start inside restricted airspace",
                        z.name
                    )
                };
                match &g.homes {
                    HomePlacement::Explicit(list) => {
                        for (k, at) in list.iter().enumerate() {
                            if polygon::contains(&pts, b.frame.to_plane(at.latitude_deg, at.longitude_deg)) {
                                p.add(format!("{path}.homes.explicit[{k}]"), msg("is inside"));
                            }
                        }
                    }
                    // Random homes are drawn outside zones by the planner; only a disc
                    // entirely inside a zone leaves it nowhere to put them.
                    HomePlacement::RandomInArea(area) => {
                        let c = b.frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
                        if disc_inside(&pts, c, area.radius_m) {
                            p.add(format!("{path}.homes.randomInArea"), msg("lies entirely inside"));
                        }
                    }
                    HomePlacement::Areas(areas) => {
                        for (k, area) in areas.iter().enumerate() {
                            let c = b.frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
                            if disc_inside(&pts, c, area.radius_m) {
                                p.add(format!("{path}.homes.areas[{k}]"), msg("lies entirely inside"));
                            }
                        }
                    }
                }
            }
            if let Some(min) = z.policy.min_altitude_agl_m
                && z.policy.authorized_operators.contains(&g.operator)
                && g.altitude.max_agl_m < min
            {
                p.add(
                    format!("{path}.altitude.maxAglM"),
                    format!(
                        "is {} m, below zone {:?}'s minimum altitude inside ({min} m): the group is authorized there but could never comply",
                        g.altitude.max_agl_m, z.name
                    ),
                );
            }
        }
    }
}

pub(super) fn check_polygon(z: &Zone, path: &str, bounds: Option<&WorldBounds>, p: &mut Problems) {
    let n = z.polygon.len();
    let ppath = format!("{path}.polygon");
    if n < 3 {
        p.add(ppath, format!("must have at least 3 vertices, got {n}"));
        return;
    }
    if n > MAX_POLYGON_VERTICES {
        p.add(ppath, format!("must have at most {MAX_POLYGON_VERTICES} vertices, got {n}"));
        return;
    }
    let Some(b) = bounds else { return };
    let before = p.0.len();
    for (k, v) in z.polygon.iter().enumerate() {
        b.check(p, &format!("{ppath}[{k}]"), v, 0.0);
    }
    if p.0.len() > before {
        return; // geometry below needs valid vertices
    }
    let pts: Vec<polygon::Point> =
        z.polygon.iter().map(|v| b.frame.to_plane(v.latitude_deg, v.longitude_deg)).collect();
    let same = |a: polygon::Point, c: polygon::Point| (a.0 - c.0).hypot(a.1 - c.1) < 0.01;
    if same(pts[0], pts[n - 1]) {
        p.add(
            format!("{ppath}[{}]", n - 1),
            "repeats vertex 0: polygons are closed implicitly, drop the closing vertex (GeoJSON rings repeat it, zones do not)",
        );
        return;
    }
    for k in 0..n - 1 {
        if same(pts[k], pts[k + 1]) {
            p.add(format!("{ppath}[{}]", k + 1), format!("repeats vertex {k}: consecutive vertices must differ"));
            return;
        }
    }
    if let Some((i, j)) = polygon::first_self_intersection(&pts) {
        p.add(ppath, format!("must not self-intersect: edge {i}->{} crosses edge {j}->{}", (i + 1) % n, (j + 1) % n));
    } else if polygon::signed_area2(&pts).abs() < 2.0 {
        p.add(ppath, "must enclose an area (at least 1 m^2)");
    }
}
