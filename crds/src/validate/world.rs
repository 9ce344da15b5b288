//! The world: its extent and generated city, and the "inside the world" checks every
//! horizontal position goes through.

use crate::fleet::{Area, LatLon};
use crate::geo::LocalFrame;
use crate::run::{SimulationRunSpec, WorldSource};

use super::problems::Problems;

/// The square world around the origin, for "inside the world" checks.
pub(super) struct WorldBounds {
    pub(super) frame: LocalFrame,
    pub(super) extent_m: f64,
}

impl WorldBounds {
    /// Checks a horizontal position; `margin_m` extends the check to a disc around it.
    pub(super) fn check(&self, p: &mut Problems, path: &str, at: &LatLon, margin_m: f64) {
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

    pub(super) fn check_area(&self, p: &mut Problems, path: &str, area: &Area) {
        if p.range(format!("{path}.radiusM"), area.radius_m, 1.0, 20_000.0) {
            self.check(p, &format!("{path}.center"), &area.center, area.radius_m);
        }
    }
}

/// A world file: a path, a `file://` URL, or an object-store URL of a file
/// (`s3://bucket/key`, `gs://bucket/key`, `az://container/key`).
pub(super) fn check_file_url(p: &mut Problems, field: &str, file: &str) {
    let Some((scheme, rest)) = file.split_once("://") else { return };
    match scheme {
        "file" => {}
        "s3" | "gs" | "az" => {
            if !rest.trim_end_matches('/').contains('/') || rest.ends_with('/') {
                p.add(
                    field,
                    format!("{scheme}:// must name a file inside a bucket, e.g. {scheme}://maps/helsinki.osm.pbf"),
                );
            }
        }
        _ => p.add(
            field,
            format!(
                "unsupported scheme {scheme:?}: expected a path, file://, s3://, gs:// or az:// (http is not fetched)"
            ),
        ),
    }
}

/// `spec.world`: extent, city and open areas. Returns the world's bounds when the origin
/// is usable (`origin_ok`), for the horizontal checks of the other sections.
pub(super) fn check_world(spec: &SimulationRunSpec, origin_ok: bool, p: &mut Problems) -> Option<WorldBounds> {
    let o = &spec.origin;
    let world = spec.world();
    p.range("spec.world.extentM", world.extent_m, 100.0, 50_000.0);
    match (world.source, &world.osm) {
        (WorldSource::Osm, None) => p.add("spec.world.osm", "is required with source osm: the extract's file"),
        (WorldSource::Procedural, Some(_)) => p.add("spec.world.osm", "is only allowed with source osm"),
        (WorldSource::Osm, Some(osm)) => {
            if osm.file.trim().is_empty() || osm.file.len() > 4096 {
                p.add("spec.world.osm.file", "must name the .osm.pbf file (1 to 4096 characters)");
            } else {
                check_file_url(p, "spec.world.osm.file", &osm.file);
                if let Some(h) = osm.default_height_m {
                    p.range("spec.world.osm.defaultHeightM", h, 2.0, 300.0);
                }
            }
        }
        (WorldSource::Procedural, None) => {}
    }
    if let Some(terrain) = &world.terrain {
        let file = &terrain.dem.file;
        if file.trim().is_empty() || file.len() > 4096 {
            p.add("spec.world.terrain.dem.file", "must name the DEM file (1 to 4096 characters)");
        } else {
            check_file_url(p, "spec.world.terrain.dem.file", file);
        }
    }
    if world.source == WorldSource::Osm {
        let why = "shapes the procedural city only: with source osm the map's buildings and parks are the world";
        if world.city.is_some() {
            p.add("spec.world.city", why);
        }
        if !world.open_areas.is_empty() {
            p.add("spec.world.openAreas", why);
        }
    }
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
    bounds
}
