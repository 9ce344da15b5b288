//! `sadesim assets`: builds a run's world assets once into the archive's asset cache, where
//! renderers, reports and people load the city from.
//!
//! The physics roles do not wait for these files: the procedural city is generated from
//! the plan in tens of milliseconds by every shard, bit for bit the same, so the cache
//! holds what is expensive to *re*-derive outside the simulator (the city as GeoJSON for
//! map tools, its statistics). Sources that are costly to build (OSM extracts, DEMs) will
//! plug in here; their roles will then read the cache.
//!
//! Layout: `<archive>/assets/<asset cache key>/world/` with `world.json`,
//! `buildings.geojson`, `world.glb` (glTF 2.0: buildings and ground) and `manifest.json` (checksums, written last) — a cache entry is
//! complete exactly when `sadesim archive verify <archive>/assets/<key>/world` passes.

use std::path::Path;

use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_world::{Footprint, World};
use serde_json::json;

use crate::archive::{Archive, ArchiveError};

/// Namespace segment of the cache inside an archive.
pub const ASSETS_NAMESPACE: &str = "assets";
/// Folder of one cache entry under the key.
pub const WORLD_FOLDER: &str = "world";
/// The city (buildings and ground) as glTF 2.0 binary in a cache entry.
pub const WORLD_GLB: &str = "world.glb";

/// What [`build_assets`] did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AssetsOutcome {
    /// The cache already held a complete, verified entry for the key.
    CacheHit { url: String },
    /// The assets were built and uploaded.
    Built { url: String, buildings: usize },
}

/// Errors of [`build_assets`].
#[derive(Debug, thiserror::Error)]
pub enum AssetsError {
    #[error("asset cache: {0}")]
    Archive(#[from] ArchiveError),
    #[error("asset cache: cannot write {path}: {source}")]
    Write { path: String, source: std::io::Error },
    #[error("asset cache: {0}")]
    World(#[from] crate::world::WorldReadError),
}

/// The city's buildings as a GeoJSON FeatureCollection (WGS84 polygons; `heightM` and
/// `baseAltitudeMslM` properties), for map tools and 3D viewers.
pub fn buildings_geojson(world: &World, frame: &LocalFrame) -> serde_json::Value {
    let origin_alt = frame.origin().altitude_msl_m;
    let features: Vec<_> = world
        .buildings()
        .iter()
        .map(|b| {
            json!({
                "type": "Feature",
                "geometry": footprint_polygon(b.footprint(), frame, b.base_up_m()),
                "properties": {
                    "heightM": (b.height_m() * 100.0).round() / 100.0,
                    "baseAltitudeMslM": ((origin_alt + b.base_up_m()) * 100.0).round() / 100.0,
                },
            })
        })
        .collect();
    json!({"type": "FeatureCollection", "features": features})
}

/// A footprint as a GeoJSON Polygon geometry (RFC 7946): WGS84 `[lon, lat]` of its vertices
/// at `up_m` above the origin; rings closed, the outer one counter-clockwise, holes
/// clockwise (the footprint's own orientations). Not rounded: rounding to 1e-7 deg (~1 cm)
/// makes some mapped footprints invalid (vertices a few millimetres apart after clipping
/// collapse onto each other), which GIS tools then refuse.
pub fn footprint_polygon(footprint: &Footprint, frame: &LocalFrame, up_m: f64) -> serde_json::Value {
    let corner = |v: &[f64; 2]| {
        let p = frame.to_geodetic(Enu { east_m: v[0], north_m: v[1], up_m });
        json!([p.longitude_deg, p.latitude_deg])
    };
    let rings: Vec<Vec<_>> =
        footprint.rings().map(|ring| ring.iter().chain(&ring[..1]).map(corner).collect()).collect();
    json!({"type": "Polygon", "coordinates": rings})
}

/// Builds the assets of `plan` into the archive at `archive_url` unless a verified entry
/// for the plan's asset cache key is there already.
///
/// # Errors
/// Archive errors (open, verify listing, upload) and local write errors, each naming the
/// URL or file.
pub fn build_assets(plan: &RunPlan, archive_url: &str, scratch: &Path) -> Result<AssetsOutcome, AssetsError> {
    let archive = Archive::open(archive_url)?;
    let entry = format!("{ASSETS_NAMESPACE}/{}/{WORLD_FOLDER}", plan.asset_cache_key);
    let url = format!("{}/{entry}/", archive.url().trim_end_matches('/'));
    // A missing or incomplete entry is a miss; only a complete, matching one is a hit.
    if let Ok(report) = archive.verify(&entry)
        && report.passed()
    {
        return Ok(AssetsOutcome::CacheHit { url });
    }
    let world = crate::world::load_world(&plan.spec)?;
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let dir = scratch.join(&plan.asset_cache_key);
    let write = |name: &str, value: &serde_json::Value| {
        let path = dir.join(name);
        std::fs::create_dir_all(&dir)
            .and_then(|()| std::fs::write(&path, serde_json::to_vec(value).map_err(std::io::Error::other)?))
            .map_err(|source| AssetsError::Write { path: path.display().to_string(), source })
    };
    write(
        "world.json",
        &serde_json::to_value(world.stats())
            .map_err(|e| AssetsError::Write { path: "world.json".into(), source: std::io::Error::other(e) })?,
    )?;
    write("buildings.geojson", &buildings_geojson(&world, &frame))?;
    let glb = dir.join(WORLD_GLB);
    std::fs::write(&glb, crate::gltf::world_glb(&world, plan.spec.origin.geo()))
        .map_err(|source| AssetsError::Write { path: glb.display().to_string(), source })?;
    archive.upload_run(&dir, ASSETS_NAMESPACE, &plan.asset_cache_key, WORLD_FOLDER)?;
    Ok(AssetsOutcome::Built { url, buildings: world.buildings().len() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_world::WorldInputs;

    fn plan() -> RunPlan {
        let run = sadesim_crds::fixtures::RunBuilder::test().build();
        sadesim_planner::plan(&run).expect("the fixture plans")
    }

    #[test]
    fn builds_once_then_hits_the_cache_and_rebuilds_a_damaged_entry() {
        let tmp = std::env::temp_dir().join(format!("sadesim-assets-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        let archive = format!("file://{}", tmp.join("archive").display());
        let plan = plan();
        let first = build_assets(&plan, &archive, &tmp.join("scratch1")).expect("builds");
        let AssetsOutcome::Built { url, buildings } = &first else { panic!("expected a build, got {first:?}") };
        assert!(url.ends_with(&format!("/assets/{}/world/", plan.asset_cache_key)), "{url}");
        let entry = tmp.join("archive").join("assets").join(&plan.asset_cache_key).join("world");
        let geo: serde_json::Value =
            serde_json::from_slice(&std::fs::read(entry.join("buildings.geojson")).expect("geojson")).expect("json");
        assert_eq!(geo["features"].as_array().expect("features").len(), *buildings);
        let glb = std::fs::read(entry.join(WORLD_GLB)).expect("world.glb");
        assert_eq!(&glb[..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len(), "the GLB header's length");
        assert!(entry.join("manifest.json").exists());

        let second = build_assets(&plan, &archive, &tmp.join("scratch2")).expect("hits");
        assert!(matches!(second, AssetsOutcome::CacheHit { .. }), "{second:?}");

        // A damaged entry no longer verifies: it is rebuilt, not trusted.
        std::fs::write(entry.join("world.json"), b"{}").expect("damage");
        let third = build_assets(&plan, &archive, &tmp.join("scratch3")).expect("rebuilds");
        assert!(matches!(third, AssetsOutcome::Built { .. }), "{third:?}");
        let _ = std::fs::remove_dir_all(&tmp);
    }

    #[test]
    fn footprints_are_closed_rings_near_the_origin() {
        let plan = plan();
        let world = World::generate(&WorldInputs::from_spec(&plan.spec, &[]));
        let frame = LocalFrame::new(plan.spec.origin.geo());
        let geo = buildings_geojson(&world, &frame);
        let first = &geo["features"][0]["geometry"]["coordinates"][0];
        assert_eq!(first[0], first[4], "closed ring");
        let origin = frame.origin();
        let lon = first[0][0].as_f64().expect("lon");
        let lat = first[0][1].as_f64().expect("lat");
        // Inside the world square (a few km): within 0.1 deg of the origin.
        assert!((lat - origin.latitude_deg).abs() < 0.1 && (lon - origin.longitude_deg).abs() < 0.1);
    }
}
