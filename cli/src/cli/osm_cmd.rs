//! `sadesim osm`: an OpenStreetMap extract as the world reads it (statistics, GeoJSON).

use std::io::Write;
use std::path::Path;

use sadesim_crds::geo::{GeoPoint, LocalFrame};
use sadesim_sources::assets::footprint_polygon;
use sadesim_world::osm::{self, DEFAULT_HEIGHT_M, ElementId, OsmCity};
use sadesim_world::{World, WorldData, WorldInputs};
use serde_json::{Value, json};

use super::{CliError, Outcome};

/// Files `sadesim osm` writes besides its summary.
pub(super) struct Targets<'a> {
    pub geojson: Option<&'a Path>,
    pub glb: Option<&'a Path>,
}

pub(super) fn osm_file(
    file: &Path,
    (latitude_deg, longitude_deg): (f64, f64),
    extent_m: f64,
    targets: Targets,
    as_json: bool,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let path = file.display().to_string();
    let bytes = std::fs::read(file).map_err(|source| CliError::Read { path: path.clone(), source })?;
    let frame = LocalFrame::new(GeoPoint::new(latitude_deg, longitude_deg, 0.0));
    let city = osm::read_pbf(&bytes, &frame, extent_m).map_err(|e| CliError::Failed(format!("{path}: {e}")))?;
    let write = |target: &Path, bytes: &[u8]| {
        std::fs::write(target, bytes).map_err(|e| CliError::Failed(format!("{}: cannot write: {e}", target.display())))
    };
    if let Some(target) = targets.geojson {
        let text = serde_json::to_string(&feature_collection(&city, &frame)).map_err(std::io::Error::from)?;
        write(target, (text + "\n").as_bytes())?;
    }
    if let Some(target) = targets.glb {
        let spec = sadesim_crds::run::World {
            source: sadesim_crds::run::WorldSource::Osm,
            osm: Some(sadesim_crds::run::OsmExtract { file: path.clone(), default_height_m: None }),
            extent_m,
            ..Default::default()
        };
        let inputs = WorldInputs { origin: frame.origin(), world: spec, open_areas: Vec::new() };
        let data = WorldData { osm: Some(city.clone()), dem: None };
        let world = World::build(&inputs, &data).map_err(|e| CliError::Failed(format!("{path}: {e}")))?;
        write(target, &sadesim_sources::gltf::world_glb(&world, frame.origin()))?;
    }
    let area_m2: f64 = city.buildings.iter().map(|b| b.building.footprint_area_m2()).sum();
    let mut roofs: Vec<f64> = city.buildings.iter().map(|b| b.building.roof_up_m()).collect();
    roofs.sort_by(f64::total_cmp);
    let s = &city.stats;
    if as_json {
        let summary = json!({
            "file": path,
            "origin": {"latitudeDeg": latitude_deg, "longitudeDeg": longitude_deg},
            "extentM": extent_m,
            "stats": s,
            "footprintAreaM2": area_m2,
            "roofM": {"min": roofs[0], "median": roofs[roofs.len() / 2], "max": roofs[roofs.len() - 1]},
        });
        serde_json::to_writer_pretty(&mut *out, &summary).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        writeln!(
            out,
            "{path}: {} buildings, {} open areas within {extent_m} m of {latitude_deg:.5}, {longitude_deg:.5}",
            s.buildings, s.open_areas
        )?;
        writeln!(
            out,
            "  roof heights: {} tagged, {} from building:levels, {} defaulted to {DEFAULT_HEIGHT_M} m; {:.1} to {:.1} m, median {:.1} m",
            s.heights_tagged,
            s.heights_from_levels,
            s.heights_defaulted,
            roofs[0],
            roofs[roofs.len() - 1],
            roofs[roofs.len() / 2]
        )?;
        if s.parts > 0 || s.outlines_replaced_by_parts > 0 {
            writeln!(
                out,
                "  building:part: {} of the buildings are parts, replacing {} building outlines",
                s.parts, s.outlines_replaced_by_parts
            )?;
        }
        writeln!(out, "  footprint area: {area_m2:.0} m²")?;
        writeln!(
            out,
            "  skipped: {} cut by the extract, {} unclosed area ways, {} invalid polygons",
            s.skipped_incomplete, s.skipped_open_ways, s.skipped_invalid
        )?;
        for target in [targets.geojson, targets.glb].into_iter().flatten() {
            writeln!(out, "  wrote {}", target.display())?;
        }
    }
    Ok(Outcome::Success)
}

/// The city as an RFC 7946 FeatureCollection (geometries as in the asset cache's
/// `buildings.geojson`): `feature` is `building` for an outline, `buildingPart` for a
/// `building:part` prism, `openArea` for a park.
fn feature_collection(city: &OsmCity, frame: &LocalFrame) -> Value {
    let mut features = Vec::new();
    for b in &city.buildings {
        let (kind, id) = element(b.id);
        features.push(json!({
            "type": "Feature",
            "geometry": footprint_polygon(b.building.footprint(), frame, 0.0),
            "properties": {
                "feature": if b.part { "buildingPart" } else { "building" },
                "osmType": kind,
                "osmId": id,
                "heightM": b.building.roof_up_m(),
                "minHeightM": b.building.base_up_m(),
                "heightSource": b.height_source,
                "areaM2": b.building.footprint_area_m2(),
            },
        }));
    }
    for a in &city.open_areas {
        let (kind, id) = element(a.id);
        features.push(json!({
            "type": "Feature",
            "geometry": footprint_polygon(&a.footprint, frame, 0.0),
            "properties": {
                "feature": "openArea",
                "osmType": kind,
                "osmId": id,
                "kind": a.kind,
                "name": a.name,
                "areaM2": a.footprint.area_m2(),
            },
        }));
    }
    json!({"type": "FeatureCollection", "features": features})
}

fn element(id: ElementId) -> (&'static str, i64) {
    match id {
        ElementId::Way(id) => ("way", id),
        ElementId::Relation(id) => ("relation", id),
    }
}
