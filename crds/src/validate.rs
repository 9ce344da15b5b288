//! Semantic validation of a `SimulationRun`: everything the schema cannot say.
//!
//! `validate` returns *all* problems at once, each naming the field path and what is
//! expected (`spec.fleet[2].count: must be between 1 and 10000, got 0`), so a user fixes a
//! scenario in one pass. It is pure: no I/O, no clock.

use std::collections::{BTreeSet, HashSet};
use std::fmt;

use kube::core::Duration;

use crate::airframe;
use crate::criteria::Criterion;
use crate::fleet::{Area, Credential, FleetGroup, HomePlacement, LatLon, MAX_DRONES, Mission, MissionItem};
use crate::geo::LocalFrame;
use crate::polygon;
use crate::run::{ClockMode, SimulationRun, SimulationRunSpec};
use crate::zones::{AltitudeReference, MAX_POLYGON_VERTICES, Zone, ZoneAltitude};

/// Longest run name: children are named `<run>-<role>-<n>` and must fit 63 characters.
pub const MAX_RUN_NAME_LEN: usize = 40;
/// Longest simulated duration, seconds (24 h).
pub const MAX_DURATION_S: f64 = 86_400.0;

/// One problem: where and what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    /// Path from the document root, e.g. `spec.fleet[2].count`.
    pub path: String,
    /// What is wrong and what is expected.
    pub message: String,
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

/// Every problem found in one run, in document order.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct ValidationErrors(pub Vec<FieldError>);

impl fmt::Display for ValidationErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

/// Validates a run.
///
/// # Errors
/// Every problem found, with its field path.
pub fn validate(run: &SimulationRun) -> Result<(), ValidationErrors> {
    let mut p = Problems::default();
    match run.metadata.name.as_deref() {
        None | Some("") => p.add("metadata.name", "is required (a DNS label such as `chicago-museum`)"),
        Some(name) => p.dns_label("metadata.name", name, MAX_RUN_NAME_LEN),
    }
    check_spec(&run.spec, &mut p);
    if p.0.is_empty() { Ok(()) } else { Err(ValidationErrors(p.0)) }
}

/// Collects problems with helpers that phrase range checks the same way everywhere.
#[derive(Default)]
struct Problems(Vec<FieldError>);

impl Problems {
    fn add(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.0.push(FieldError { path: path.into(), message: message.into() });
    }

    /// `lo <= value <= hi` and finite. Returns whether the value passed.
    fn range(&mut self, path: impl Into<String>, value: f64, lo: f64, hi: f64) -> bool {
        if !value.is_finite() {
            self.add(path, format!("must be a finite number between {lo} and {hi}, got {value}"));
            false
        } else if value < lo || value > hi {
            self.add(path, format!("must be between {lo} and {hi}, got {value}"));
            false
        } else {
            true
        }
    }

    fn range_int(&mut self, path: impl Into<String>, value: u64, lo: u64, hi: u64) -> bool {
        if value < lo || value > hi {
            self.add(path, format!("must be between {lo} and {hi}, got {value}"));
            false
        } else {
            true
        }
    }

    /// At most `max` list entries (the CRD's `maxItems`, so a file that passes here also
    /// passes `kubectl apply`).
    fn max_items(&mut self, path: impl Into<String>, len: usize, max: usize) {
        if len > max {
            self.add(path, format!("must have at most {max} entries, got {len}"));
        }
    }

    /// A positive duration no longer than `max_s`.
    fn duration(&mut self, path: impl Into<String>, d: &Duration, max_s: f64) -> Option<f64> {
        let s = duration_s(d);
        if s <= 0.0 {
            self.add(path, format!("must be a positive duration such as `90s` or `15m`, got {d}"));
            None
        } else if s > max_s {
            self.add(path, format!("must be at most {max_s} s, got {d}"));
            None
        } else {
            Some(s)
        }
    }

    /// RFC 1123 label: lowercase alphanumerics and '-', starting and ending alphanumeric.
    fn dns_label(&mut self, path: impl Into<String>, value: &str, max_len: usize) {
        let ok = !value.is_empty()
            && value.len() <= max_len
            && value.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
            && !value.starts_with('-')
            && !value.ends_with('-');
        if !ok {
            self.add(
                path,
                format!(
                    "must be a DNS label of at most {max_len} characters (lowercase letters, digits, '-'), got {value:?}"
                ),
            );
        }
    }
}

/// Simulated seconds of a (possibly negative) Go duration.
pub fn duration_s(d: &Duration) -> f64 {
    let s = std::time::Duration::from(*d).as_secs_f64();
    if d.is_negative() { -s } else { s }
}

/// The square world around the origin, for "inside the world" checks.
struct WorldBounds {
    frame: LocalFrame,
    extent_m: f64,
}

impl WorldBounds {
    /// Checks a horizontal position; `margin_m` extends the check to a disc around it.
    fn check(&self, p: &mut Problems, path: &str, at: &LatLon, margin_m: f64) {
        if !at.latitude_deg.is_finite() || !at.longitude_deg.is_finite() {
            p.add(path, "latitude and longitude must be finite numbers");
            return;
        }
        let ok_lat = p.range(format!("{path}.latitudeDeg"), at.latitude_deg, -90.0, 90.0);
        let ok_lon = p.range(format!("{path}.longitudeDeg"), at.longitude_deg, -180.0, 180.0);
        if !(ok_lat && ok_lon && self.extent_m.is_finite()) {
            return;
        }
        let (east, north) = self.frame.to_plane(at.latitude_deg, at.longitude_deg);
        let reach = self.extent_m - margin_m;
        if east.abs() > reach || north.abs() > reach {
            let what = if margin_m > 0.0 { format!("with its {margin_m} m radius ") } else { String::new() };
            p.add(
                path,
                format!(
                    "must lie {what}inside the world (spec.world.extentM = {} m around the origin), is {:.0} m {} and {:.0} m {} of the origin",
                    self.extent_m,
                    east.abs(),
                    if east >= 0.0 { "east" } else { "west" },
                    north.abs(),
                    if north >= 0.0 { "north" } else { "south" },
                ),
            );
        }
    }

    fn check_area(&self, p: &mut Problems, path: &str, area: &Area) {
        if p.range(format!("{path}.radiusM"), area.radius_m, 1.0, 20_000.0) {
            self.check(p, &format!("{path}.center"), &area.center, area.radius_m);
        }
    }
}

fn check_spec(spec: &SimulationRunSpec, p: &mut Problems) {
    // Origin first: every horizontal check below depends on it.
    let o = &spec.origin;
    let origin_ok = p.range("spec.origin.latitudeDeg", o.latitude_deg, -85.0, 85.0)
        & p.range("spec.origin.longitudeDeg", o.longitude_deg, -180.0, 180.0)
        & p.range("spec.origin.altitudeMslM", o.altitude_msl_m, -500.0, 9000.0);

    let duration_s = p.duration("spec.duration", &spec.duration, MAX_DURATION_S);

    if let Some(clock) = &spec.clock {
        match (clock.mode, clock.factor) {
            (ClockMode::Scaled, Some(f)) => {
                p.range("spec.clock.factor", f, 0.01, 1000.0);
            }
            (ClockMode::Scaled, None) => p.add("spec.clock.factor", "is required with mode `scaled` (e.g. 4.0)"),
            (_, Some(_)) => p.add("spec.clock.factor", "is only allowed with mode `scaled`"),
            (_, None) => {}
        }
    }
    if let Some(seed) = spec.seed
        && seed > i64::MAX as u64
    {
        p.add("spec.seed", format!("must be at most {} (Kubernetes integers are 64-bit signed), got {seed}", i64::MAX));
    }
    if let Some(rate) = spec.physics_rate_hz {
        p.range_int("spec.physicsRateHz", rate.into(), 50, 10_000);
    }

    let world = spec.world();
    p.range("spec.world.extentM", world.extent_m, 100.0, 50_000.0);
    if let Some(city) = &world.city {
        p.range("spec.world.city.blockSizeM", city.block_size_m, 20.0, 1000.0);
        p.range("spec.world.city.streetWidthM", city.street_width_m, 5.0, 200.0);
        p.range("spec.world.city.medianBuildingHeightM", city.median_building_height_m, 3.0, 300.0);
        p.range("spec.world.city.maxBuildingHeightM", city.max_building_height_m, 3.0, 1000.0);
        p.range("spec.world.city.builtFraction", city.built_fraction, 0.0, 1.0);
        if city.max_building_height_m < city.median_building_height_m {
            p.add("spec.world.city.maxBuildingHeightM", "must be at least medianBuildingHeightM");
        }
    }
    let bounds = origin_ok.then(|| WorldBounds { frame: LocalFrame::new(o.geo()), extent_m: world.extent_m });
    p.max_items("spec.world.openAreas", world.open_areas.len(), 256);
    if let Some(b) = &bounds {
        for (k, area) in world.open_areas.iter().enumerate() {
            b.check_area(p, &format!("spec.world.openAreas[{k}]"), area);
        }
    }

    let group_names = check_fleet(spec, bounds.as_ref(), p);
    let zone_names = check_zones(spec, bounds.as_ref(), duration_s, p);
    if let Some(b) = &bounds {
        check_zone_interactions(spec, b, p);
    }
    check_environment(spec, &group_names, p);
    check_pilot(spec, p);

    let sharding = spec.sharding();
    p.range_int("spec.sharding.dronesPerShard", sharding.drones_per_shard.into(), 1, 2000);
    p.range_int("spec.sharding.syncWindowSteps", sharding.sync_window_steps.into(), 1, 1000);
    let rates = spec.recording().rates;
    for (field, hz) in [
        ("groundTruthHz", rates.ground_truth_hz),
        ("estimatorHz", rates.estimator_hz),
        ("actuatorsHz", rates.actuators_hz),
        ("statusHz", rates.status_hz),
    ] {
        p.range(format!("spec.recording.rates.{field}"), hz, 0.1, 1000.0);
    }

    if let Some(archive) = &spec.archive {
        check_archive_url(&archive.url, p);
    }
    if let Some(queue) = &spec.queue {
        p.dns_label("spec.queue", queue, 63);
    }
    check_criteria(spec, &group_names, &zone_names, p);
}

fn check_fleet(spec: &SimulationRunSpec, bounds: Option<&WorldBounds>, p: &mut Problems) -> HashSet<String> {
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

fn check_homes(g: &FleetGroup, path: &str, bounds: Option<&WorldBounds>, p: &mut Problems) {
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

fn check_mission(g: &FleetGroup, m: &Mission, path: &str, bounds: Option<&WorldBounds>, p: &mut Problems) {
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

fn reference_name(r: AltitudeReference) -> &'static str {
    match r {
        AltitudeReference::Agl => "agl",
        AltitudeReference::Msl => "msl",
    }
}

/// Altitude MSL of a zone boundary, using the origin's ground for AGL values. Only for
/// comparing floor and ceiling; the monitor uses the real ground under the drone.
fn approx_msl(a: &ZoneAltitude, origin_alt_m: f64) -> f64 {
    match a.reference {
        AltitudeReference::Msl => a.height_m,
        AltitudeReference::Agl => a.height_m + origin_alt_m,
    }
}

fn check_zones(
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
fn zone_points(z: &Zone, frame: &LocalFrame) -> Option<Vec<polygon::Point>> {
    let ok = z.polygon.len() >= 3
        && z.polygon
            .iter()
            .all(|v| v.latitude_deg.is_finite() && v.longitude_deg.is_finite() && v.latitude_deg.abs() <= 90.0);
    ok.then(|| z.polygon.iter().map(|v| frame.to_plane(v.latitude_deg, v.longitude_deg)).collect())
}

fn disc_inside(polygon_pts: &[polygon::Point], c: polygon::Point, r: f64) -> bool {
    polygon::contains(polygon_pts, c) && polygon::distance_to_boundary(polygon_pts, c) >= r
}

/// Fleet against zones: nobody starts inside a zone that reaches the ground, and no
/// authorized group is too low to ever meet a zone's minimum altitude.
fn check_zone_interactions(spec: &SimulationRunSpec, b: &WorldBounds, p: &mut Problems) {
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

fn check_polygon(z: &Zone, path: &str, bounds: Option<&WorldBounds>, p: &mut Problems) {
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

fn check_environment(spec: &SimulationRunSpec, groups: &HashSet<String>, p: &mut Problems) {
    let env = spec.environment();
    if let Some(w) = &env.wind {
        p.range("spec.environment.wind.speedMps", w.speed_mps, 0.0, 40.0);
        p.range("spec.environment.wind.directionFromDeg", w.direction_from_deg, 0.0, 360.0);
        if let Some(h) = w.reference_height_m {
            p.range("spec.environment.wind.referenceHeightM", h, 1.0, 500.0);
        }
    }
    if let Some(g) = &env.gnss {
        let base = "spec.environment.gnss";
        if let Some(r) = g.rate_hz {
            p.range(format!("{base}.rateHz"), r, 1.0, 20.0);
        }
        let limits = [
            ("horizontalSigmaM", g.horizontal_sigma_m, 100.0),
            ("verticalSigmaM", g.vertical_sigma_m, 100.0),
            ("biasWalkMPerSqrtS", g.bias_walk_m_per_sqrt_s, 10.0),
        ];
        for (field, value, hi) in limits {
            if let Some(v) = value {
                p.range(format!("{base}.{field}"), v, 0.0, hi);
            }
        }
        p.max_items(format!("{base}.dropouts"), g.dropouts.len(), 256);
        for (k, d) in g.dropouts.iter().enumerate() {
            let dp = format!("{base}.dropouts[{k}]");
            let start = duration_s(&d.start);
            if start < 0.0 {
                p.add(format!("{dp}.start"), "must not be negative");
            } else if start >= spec.duration_s() {
                p.add(
                    format!("{dp}.start"),
                    format!("is after the run ends ({} s): the dropout would never happen", spec.duration_s()),
                );
            }
            p.duration(format!("{dp}.duration"), &d.duration, MAX_DURATION_S);
            check_group_refs(&d.groups, groups, &format!("{dp}.groups"), p);
        }
    }
}

fn check_pilot(spec: &SimulationRunSpec, p: &mut Problems) {
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
        }
    }
}

fn check_archive_url(url: &str, p: &mut Problems) {
    let path = "spec.archive.url";
    let Some((scheme, rest)) = url.split_once("://") else {
        p.add(path, format!("must be a URL such as file://runs or s3://bucket/prefix, got {url:?}"));
        return;
    };
    match scheme {
        "file" if rest.is_empty() => p.add(path, "file:// needs a folder, e.g. file://runs or file:///var/sadesim"),
        "file" => {}
        "s3" | "gs" | "az" if rest.split('/').next().is_none_or(str::is_empty) => {
            p.add(path, format!("{scheme}:// needs a bucket name, e.g. {scheme}://my-bucket/runs"))
        }
        "s3" | "gs" | "az" => {}
        other => p.add(path, format!("unsupported scheme {other:?}: expected file, s3, gs or az")),
    }
}

fn non_empty(p: &mut Problems, path: String, list: &[String]) {
    if list.is_empty() {
        p.add(path, "must name at least one group");
    }
}

/// Names in a stable order for messages.
fn sorted(names: &HashSet<String>) -> String {
    let names: BTreeSet<&str> = names.iter().map(String::as_str).collect();
    if names.is_empty() { "(none defined)".into() } else { names.into_iter().collect::<Vec<_>>().join(", ") }
}

fn check_group_refs(refs: &[String], groups: &HashSet<String>, path: &str, p: &mut Problems) {
    p.max_items(path, refs.len(), 64);
    for (k, g) in refs.iter().enumerate() {
        if !groups.contains(g) {
            p.add(format!("{path}[{k}]"), format!("unknown group {g:?}, expected one of: {}", sorted(groups)));
        }
    }
}

fn check_criteria(spec: &SimulationRunSpec, groups: &HashSet<String>, zones: &HashSet<String>, p: &mut Problems) {
    let zone_ref = |p: &mut Problems, path: String, z: &str| {
        if !zones.contains(z) {
            p.add(path, format!("unknown zone {z:?}, expected one of: {}", sorted(zones)));
        }
    };
    p.max_items("spec.criteria", spec.criteria.len(), 64);
    for (i, c) in spec.criteria.iter().enumerate() {
        let path = format!("spec.criteria[{i}]");
        match c {
            Criterion::MinSeparation { distance_m } => {
                p.range(format!("{path}.minSeparation.distanceM"), *distance_m, 0.1, 10_000.0);
            }
            Criterion::ReachZone { groups: gs, zone, within } => {
                non_empty(p, format!("{path}.reachZone.groups"), gs);
                check_group_refs(gs, groups, &format!("{path}.reachZone.groups"), p);
                zone_ref(p, format!("{path}.reachZone.zone"), zone);
                if let Some(w) = p.duration(format!("{path}.reachZone.within"), within, MAX_DURATION_S)
                    && w > spec.duration_s()
                {
                    p.add(
                        format!("{path}.reachZone.within"),
                        format!("is longer than the run ({} s): it could never be checked", spec.duration_s()),
                    );
                }
            }
            Criterion::ZoneVerdicts { groups: gs, zone, .. } => {
                non_empty(p, format!("{path}.zoneVerdicts.groups"), gs);
                check_group_refs(gs, groups, &format!("{path}.zoneVerdicts.groups"), p);
                zone_ref(p, format!("{path}.zoneVerdicts.zone"), zone);
            }
            Criterion::NoUnauthorizedEntries {}
            | Criterion::ZoneConstraintsRespected {}
            | Criterion::AltitudeLimitsRespected {}
            | Criterion::NoCrashes {} => {}
        }
    }
}
