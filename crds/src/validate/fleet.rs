//! `spec.fleet` and `spec.pilot`: groups (names, counts, airframes, operators, homes,
//! altitude limits), their scripted missions, and the pilot that flies the groups without one.

use std::collections::HashSet;

use crate::airframe;
use crate::fleet::{Credential, FleetGroup, HomePlacement, LatLon, MAX_DRONES, Mission, MissionItem};
use crate::run::SimulationRunSpec;

use super::problems::Problems;
use super::world::WorldBounds;

pub(super) fn check_fleet(spec: &SimulationRunSpec, bounds: Option<&WorldBounds>, p: &mut Problems) -> HashSet<String> {
    let mut names = HashSet::new();
    if spec.fleet.is_empty() {
        p.add("spec.fleet", "must list at least one drone group");
    }
    p.max_items("spec.fleet", spec.fleet.len(), 64);
    for (i, g) in spec.fleet.iter().enumerate() {
        let path = format!("spec.fleet[{i}]");
        p.dns_label(format!("{path}.name"), &g.name, 40);
        if !names.insert(g.name.clone()) {
            p.add(format!("{path}.name"), format!("duplicate group name {:?}: group names must be unique", g.name));
        }
        p.range_int(format!("{path}.count"), g.count.into(), 1, MAX_DRONES.into());
        if airframe::preset(&g.airframe).is_none() {
            p.add(
                format!("{path}.airframe"),
                format!("unknown airframe preset {:?}, expected one of: {}", g.airframe, airframe::preset_names()),
            );
        }
        let operator_ok = !g.operator.is_empty()
            && g.operator.len() <= 63
            && g.operator.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b))
            && g.operator.bytes().next().is_some_and(|b| b.is_ascii_alphanumeric())
            && g.operator.bytes().last().is_some_and(|b| b.is_ascii_alphanumeric());
        if !operator_ok {
            p.add(
                format!("{path}.operator"),
                format!(
                    "must be 1 to 63 letters, digits, '-', '_' or '.', starting and ending alphanumeric, got {:?}",
                    g.operator
                ),
            );
        }
        if let Some(Credential::Value(v)) = &g.credential
            && v.is_empty()
        {
            p.add(format!("{path}.credential.value"), "must not be empty");
        }
        check_homes(g, &path, bounds, p);
        let alt = &g.altitude;
        p.range(format!("{path}.altitude.maxAglM"), alt.max_agl_m, 1.0, 1000.0);
        if let Some(min) = alt.min_agl_m
            && p.range(format!("{path}.altitude.minAglM"), min, 0.0, 1000.0)
            && min >= alt.max_agl_m
        {
            p.add(
                format!("{path}.altitude.minAglM"),
                format!("must be below altitude.maxAglM ({}), got {min}", alt.max_agl_m),
            );
        }
        if let Some(m) = &g.mission {
            check_mission(g, m, &format!("{path}.mission"), bounds, p);
        }
    }
    let total = spec.total_drones();
    if total > u64::from(MAX_DRONES) {
        p.add("spec.fleet", format!("total drones must be at most {MAX_DRONES}, got {total}"));
    }
    names
}

pub(super) fn check_homes(g: &FleetGroup, path: &str, bounds: Option<&WorldBounds>, p: &mut Problems) {
    match &g.homes {
        HomePlacement::Explicit(list) => {
            if list.len() != g.count as usize {
                p.add(
                    format!("{path}.homes.explicit"),
                    format!("must list exactly `count` = {} positions, got {}", g.count, list.len()),
                );
            }
            if let Some(b) = bounds {
                for (k, at) in list.iter().enumerate() {
                    b.check(p, &format!("{path}.homes.explicit[{k}]"), at, 0.0);
                }
            }
        }
        HomePlacement::RandomInArea(area) => {
            if let Some(b) = bounds {
                b.check_area(p, &format!("{path}.homes.randomInArea"), area);
            }
        }
        HomePlacement::Areas(areas) => {
            if areas.is_empty() {
                p.add(format!("{path}.homes.areas"), "must list at least one area");
            }
            p.max_items(format!("{path}.homes.areas"), areas.len(), 256);
            if let Some(b) = bounds {
                for (k, area) in areas.iter().enumerate() {
                    b.check_area(p, &format!("{path}.homes.areas[{k}]"), area);
                }
            }
        }
    }
}

pub(super) fn check_mission(g: &FleetGroup, m: &Mission, path: &str, bounds: Option<&WorldBounds>, p: &mut Problems) {
    if let Some(speed) = m.speed_mps {
        p.range(format!("{path}.speedMps"), speed, 0.5, 30.0);
    }
    p.max_items(format!("{path}.items"), m.items.len(), 1000);
    if m.items.is_empty() {
        p.add(format!("{path}.items"), "must list at least one item, starting with `takeoff`");
        return;
    }
    if !matches!(m.items[0], MissionItem::Takeoff { .. }) {
        p.add(format!("{path}.items[0]"), "a mission must start with a `takeoff` item");
    }
    let max = g.altitude.max_agl_m;
    let alt = |p: &mut Problems, field: String, a: f64| {
        if p.range(field.clone(), a, 1.0, 1000.0) && a > max {
            p.add(field, format!("is above the group's altitude.maxAglM ({max} m), got {a}"));
        }
    };
    for (k, item) in m.items.iter().enumerate() {
        let ip = format!("{path}.items[{k}]");
        match item {
            MissionItem::Takeoff { altitude_agl_m } => alt(p, format!("{ip}.takeoff.altitudeAglM"), *altitude_agl_m),
            MissionItem::Waypoint { latitude_deg, longitude_deg, altitude_agl_m, hold_s } => {
                let at = LatLon { latitude_deg: *latitude_deg, longitude_deg: *longitude_deg };
                if let Some(b) = bounds {
                    b.check(p, &format!("{ip}.waypoint"), &at, 0.0);
                }
                alt(p, format!("{ip}.waypoint.altitudeAglM"), *altitude_agl_m);
                if let Some(h) = hold_s {
                    p.range(format!("{ip}.waypoint.holdS"), *h, 0.0, 86_400.0);
                }
            }
            MissionItem::Loiter { hold_s } => {
                p.range(format!("{ip}.loiter.holdS"), *hold_s, 0.0, 86_400.0);
            }
            MissionItem::RandomWaypoints { area, count, min_altitude_agl_m, max_altitude_agl_m, hold_s } => {
                match (area, &g.homes) {
                    (Some(area), _) => {
                        if let Some(b) = bounds {
                            b.check_area(p, &format!("{ip}.randomWaypoints.area"), area);
                        }
                    }
                    (None, HomePlacement::Explicit(_)) => p.add(
                        format!("{ip}.randomWaypoints.area"),
                        "is required for a group with explicit homes (without it, waypoints are drawn in the drone's home area)",
                    ),
                    (None, _) => {}
                }
                p.range_int(format!("{ip}.randomWaypoints.count"), (*count).into(), 1, 10_000);
                alt(p, format!("{ip}.randomWaypoints.minAltitudeAglM"), *min_altitude_agl_m);
                alt(p, format!("{ip}.randomWaypoints.maxAltitudeAglM"), *max_altitude_agl_m);
                if min_altitude_agl_m > max_altitude_agl_m {
                    p.add(format!("{ip}.randomWaypoints.minAltitudeAglM"), "must not exceed maxAltitudeAglM");
                }
                if let Some(h) = hold_s {
                    p.range(format!("{ip}.randomWaypoints.holdS"), *h, 0.0, 86_400.0);
                }
            }
            MissionItem::ReturnToLaunch {} | MissionItem::Land {} => {}
        }
    }
}

pub(super) fn check_pilot(spec: &SimulationRunSpec, p: &mut Problems) {
    let mavlink_groups: Vec<&str> =
        spec.fleet.iter().filter(|g| g.mission.is_none()).map(|g| g.name.as_str()).collect();
    match &spec.pilot {
        None if !mavlink_groups.is_empty() => p.add(
            "spec.pilot",
            format!(
                "is required: groups without a mission ({}) are flown over MAVLink by the pilot; add spec.pilot.command or a mission to each group",
                mavlink_groups.join(", ")
            ),
        ),
        None => {}
        Some(pilot) => {
            if pilot.command.is_empty() && pilot.image.is_none() {
                p.add("spec.pilot", "needs `command` (local runs) or `image` (Kubernetes)");
            }
            if pilot.command.first().is_some_and(|c| c.trim().is_empty()) {
                p.add("spec.pilot.command[0]", "must name a program");
            }
            p.max_items("spec.pilot.command", pilot.command.len(), 64);
            if let Some(container) = &pilot.container_command {
                if pilot.image.is_none() {
                    p.add("spec.pilot.containerCommand", "is the command in the pilot's image: it needs spec.pilot.image");
                }
                if container.first().is_some_and(|c| c.trim().is_empty()) {
                    p.add("spec.pilot.containerCommand[0]", "must name a program");
                }
                p.max_items("spec.pilot.containerCommand", container.len(), 64);
            }
            p.max_items("spec.pilot.env", pilot.env.len(), 128);
            let mut seen = HashSet::new();
            for (k, e) in pilot.env.iter().enumerate() {
                let ok = e.name.bytes().next().is_some_and(|b| b.is_ascii_alphabetic() || b == b'_')
                    && e.name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_');
                if !ok {
                    p.add(format!("spec.pilot.env[{k}].name"), format!("must be an environment variable name ([A-Za-z_][A-Za-z0-9_]*), got {:?}", e.name));
                }
                if e.name.starts_with("SADESIM_") {
                    p.add(format!("spec.pilot.env[{k}].name"), "the SADESIM_ prefix is reserved for variables the platform sets");
                }
                if !seen.insert(&e.name) {
                    p.add(format!("spec.pilot.env[{k}].name"), format!("duplicate variable {:?}", e.name));
                }
            }
            if let Some(r) = &pilot.resources {
                p.range_int("spec.pilot.resources.cpuMillis", r.cpu_millis.into(), 10, 64_000);
                p.range_int("spec.pilot.resources.memoryMib", r.memory_mib.into(), 16, 262_144);
            }
            if let Some(s) = pilot.connect_timeout_s {
                p.range_int("spec.pilot.connectTimeoutS", s.into(), 1, 3600);
            }
        }
    }
}
