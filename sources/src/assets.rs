//! The asset bundle: a run's world built once, content-addressed, and loaded by every role
//! that needs it (the runner, shards, the coordinator's report, renderers) instead of
//! re-reading the map and the DEM or regenerating the city.
//!
//! An entry is `<cache>/assets/<asset cache key>/world/`: the key is the SHA-256 of every
//! world parameter and of the bytes of the files the world is read from (the planner's
//! `asset_cache_key`), so a changed extract or DEM is a new entry, and a changed seed or
//! pilot reuses the old one. The cache is an archive URL: on a cluster the run's object
//! store (the `<run>-assets` Job fills it), locally a folder under the user cache directory
//! ([`local_cache_url`]). An entry holds
//! - `world.bin`: the world itself (`sadesim_world::bundle`), what the roles load;
//! - `world.json`: its statistics; `buildings.geojson`: the footprints (WGS84) for map
//!   tools; `world.glb`: buildings and ground as glTF 2.0 for renderers and 3D viewers;
//! - `manifest.json`: every file's size and SHA-256, written last.
//!
//! An entry is used only when it verifies (`sadesim archive verify` passes on it): a
//! missing, partial or damaged entry is a miss and is rebuilt, and a role loading
//! `world.bin` checks it against the manifest first.

use std::path::Path;

use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_evidence::archive::{Archive, ArchiveError};
use sadesim_world::{Footprint, World};
use serde_json::json;

/// Namespace segment of the cache inside an archive.
pub const ASSETS_NAMESPACE: &str = "assets";
/// Folder of one cache entry under the key.
pub const WORLD_FOLDER: &str = "world";
/// The city (buildings and ground) as glTF 2.0 binary in a cache entry.
pub const WORLD_GLB: &str = "world.glb";
/// The world itself (`sadesim_world::bundle`) in a cache entry.
pub const WORLD_BIN: &str = "world.bin";
/// Environment variable naming the local asset cache folder (default: `sadesim` under the
/// user cache directory).
pub const CACHE_DIR_ENV: &str = "SADESIM_CACHE_DIR";

/// What [`build_assets`] and [`ensure_bundle`] did (the contract the operator reads).
pub use sadesim_crds::outcome::assets::AssetsOutcome;

/// Errors of [`build_assets`].
#[derive(Debug, thiserror::Error)]
pub enum AssetsError {
    #[error("asset cache: {0}")]
    Archive(#[from] ArchiveError),
    #[error("asset cache: cannot write {path}: {source}")]
    Write { path: String, source: std::io::Error },
    #[error("asset cache: {0}")]
    World(#[from] crate::world::WorldReadError),
    #[error("asset bundle {url}: {source}")]
    Bundle {
        url: String,
        #[source]
        source: sadesim_world::bundle::BundleError,
    },
    #[error("urban wind field {url}: {source}")]
    Wind {
        url: String,
        #[source]
        source: crate::zarr::ZarrError,
    },
    #[error("urban wind field: {0}")]
    WindBuild(String),
    #[error("asset cache: no cache folder: set {CACHE_DIR_ENV}, XDG_CACHE_HOME or HOME")]
    NoCacheDir,
}

/// The local asset cache as an archive URL: `$SADESIM_CACHE_DIR`, else
/// `$XDG_CACHE_HOME/sadesim`, else `$HOME/.cache/sadesim` (the XDG base directory rules).
///
/// # Errors
/// [`AssetsError::NoCacheDir`] when none of the three is set.
pub fn local_cache_url(env: &dyn Fn(&str) -> Option<String>) -> Result<String, AssetsError> {
    let set = |k: &str| env(k).filter(|v| !v.is_empty());
    let dir = set(CACHE_DIR_ENV)
        .map(std::path::PathBuf::from)
        .or_else(|| set("XDG_CACHE_HOME").map(|d| Path::new(&d).join("sadesim")))
        .or_else(|| set("HOME").map(|h| Path::new(&h).join(".cache").join("sadesim")))
        .ok_or(AssetsError::NoCacheDir)?;
    let dir = if dir.is_absolute() { dir } else { std::env::current_dir().unwrap_or_default().join(dir) };
    Ok(format!("file://{}", dir.display()))
}

/// The entry of `key` in the cache at `cache_url`: relative folder and URL.
fn entry_of(archive: &Archive, key: &str) -> (String, String) {
    let entry = format!("{ASSETS_NAMESPACE}/{key}/{WORLD_FOLDER}");
    (entry, entry_url(archive.url(), key))
}

/// The URL of the bundle of asset cache key `key` in the cache at `cache_url`:
/// `<cache>/assets/<key>/world/`, what [`load_bundle`] and `--assets` take.
pub fn entry_url(cache_url: &str, key: &str) -> String {
    format!("{}/{ASSETS_NAMESPACE}/{key}/{WORLD_FOLDER}/", cache_url.trim_end_matches('/'))
}

/// Loads the world of the bundle at `entry_url` (`<cache>/assets/<key>/world/`, as
/// [`AssetsOutcome::url`] or the operator's `asset_cache_location` give it): `world.bin`,
/// checked against the entry's manifest, then decoded.
///
/// # Errors
/// The entry cannot be opened or read, has no manifest (partial), its `world.bin` does not
/// match the manifest, or does not decode as a world of this build's format.
pub fn load_bundle(entry_url: &str) -> Result<World, AssetsError> {
    let archive = Archive::open(entry_url)?;
    let bytes = archive.read_checked("", WORLD_BIN)?;
    World::from_bytes(&bytes).map_err(|source| AssetsError::Bundle { url: format!("{entry_url}{WORLD_BIN}"), source })
}

/// The run's world when the caller does not have it (`sadesim report` and `sadesim view` on
/// a run folder): the bundle of the plan's asset cache key in the local asset cache, else
/// built from the plan and the files it names; `None` when neither works (an extract that
/// is gone: a map without buildings).
pub fn find_world(plan: &RunPlan) -> Option<World> {
    let cache = local_cache_url(&|k| std::env::var(k).ok()).ok();
    let cached = cache.and_then(|url| load_bundle(&entry_url(&url, &plan.asset_cache_key)).ok());
    cached.or_else(|| crate::world::load_world(&plan.spec).ok())
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

/// Builds the world of `plan` into the archive at `archive_url` unless an entry for the
/// plan's asset cache key is there that verifies and loads ([`ensure_bundle`]; the urban
/// wind field too: [`build_run_assets`]).
///
/// # Errors
/// Archive errors (open, verify listing, upload), the world's files (unreadable, not a map
/// or DEM) and local write errors, each naming the URL or file.
pub fn build_assets(plan: &RunPlan, archive_url: &str, scratch: &Path) -> Result<AssetsOutcome, AssetsError> {
    let key = &plan.asset_cache_key;
    let build = || Ok(crate::world::load_world(&plan.spec)?);
    ensure_bundle(key, plan.spec.origin.geo(), archive_url, scratch, build).map(|(outcome, _)| outcome)
}

/// [`build_assets`], and the urban wind field of a run that has one
/// ([`crate::wind::ensure_wind`], made by `build_wind` on a miss): what the `<run>-assets`
/// Job does, so the run's roles load the field instead of computing it. An imported
/// OpenFOAM case is not cached (every role reads it).
///
/// # Errors
/// As [`build_assets`], and `build_wind`'s.
pub fn build_run_assets(
    plan: &RunPlan,
    archive_url: &str,
    scratch: &Path,
    build_wind: impl FnOnce(
        &World,
        &sadesim_wind::request::WindRequest,
    ) -> Result<sadesim_wind::UrbanWindField, AssetsError>,
) -> Result<(AssetsOutcome, Option<crate::wind::WindOutcome>), AssetsError> {
    let key = &plan.asset_cache_key;
    let origin = plan.spec.origin.geo();
    let build = || Ok(crate::world::load_world(&plan.spec)?);
    let (outcome, world) = ensure_bundle(key, origin, archive_url, scratch, build)?;
    let request = sadesim_wind::request::wind_request(&plan.spec, &world);
    let Some(request) = request.filter(|r| !matches!(r.model, sadesim_wind::request::FieldModel::Imported(_))) else {
        return Ok((outcome, None));
    };
    let field = || build_wind(&world, &request);
    let (wind, _) = crate::wind::ensure_wind(key, &request, origin, archive_url, scratch, field)?;
    Ok((outcome, Some(wind)))
}

/// The world of asset cache key `key` (the planner's `asset_key`; `origin` is the run's)
/// from the cache at `cache_url`: loaded from a verified entry, else made with `build` and
/// stored. What the local runner does before every run, and the `<run>-assets` Job.
///
/// # Errors
/// As [`build_assets`] and [`load_bundle`]; a bundle that verifies but does not decode
/// (written by another format version under the same key) is rebuilt, not an error.
pub fn ensure_bundle(
    key: &str,
    origin: GeoPoint,
    cache_url: &str,
    scratch: &Path,
    build: impl FnOnce() -> Result<World, AssetsError>,
) -> Result<(AssetsOutcome, World), AssetsError> {
    let archive = Archive::open(cache_url)?;
    let (entry, url) = entry_of(&archive, key);
    let replaced = match entry_state(&archive, &entry) {
        EntryState::Missing => None,
        EntryState::Damaged(why) => Some(why),
        EntryState::Verified => match load_bundle(&url) {
            Ok(world) => return Ok((AssetsOutcome::CacheHit { url }, world)),
            Err(e) => Some(e.to_string()),
        },
    };
    let world = build()?;
    store_bundle(&archive, key, origin, &world, scratch)?;
    let buildings = world.buildings().len();
    Ok((AssetsOutcome::Built { url, buildings, replaced }, world))
}

/// What a cache entry is before it is used.
enum EntryState {
    /// It verifies against its manifest.
    Verified,
    /// Nothing is there.
    Missing,
    /// Partial or damaged: what is wrong.
    Damaged(String),
}

fn entry_state(archive: &Archive, entry: &str) -> EntryState {
    match archive.verify(entry) {
        Ok(report) if report.passed() => EntryState::Verified,
        Ok(report) => EntryState::Damaged(report.problems.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("; ")),
        Err(ArchiveError::NotFound { .. }) => EntryState::Missing,
        Err(e) => EntryState::Damaged(e.to_string()),
    }
}

/// Writes the bundle's files for `world` under `scratch` and uploads them as the entry of
/// `key` (manifest last).
fn store_bundle(
    archive: &Archive,
    key: &str,
    origin: GeoPoint,
    world: &World,
    scratch: &Path,
) -> Result<(), AssetsError> {
    let frame = LocalFrame::new(origin);
    let dir = scratch.join(key);
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.join(name);
        std::fs::create_dir_all(&dir)
            .and_then(|()| std::fs::write(&path, bytes))
            .map_err(|source| AssetsError::Write { path: path.display().to_string(), source })
    };
    let json = |value: &serde_json::Value| serde_json::to_vec(value).expect("JSON values always serialize");
    write(WORLD_BIN, &world.to_bytes())?;
    write("world.json", &json(&serde_json::to_value(world.stats()).expect("stats always serialize")))?;
    write("buildings.geojson", &json(&buildings_geojson(world, &frame)))?;
    write(WORLD_GLB, &crate::gltf::world_glb(world, origin))?;
    archive.upload_run(&dir, ASSETS_NAMESPACE, key, WORLD_FOLDER)?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
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
        let AssetsOutcome::Built { url, buildings, replaced: None } = &first else {
            panic!("expected a build, got {first:?}")
        };
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
        let AssetsOutcome::Built { replaced: Some(why), .. } = &third else {
            panic!("expected a rebuild, got {third:?}")
        };
        assert!(why.contains("world.json"), "says which file was damaged: {why}");
        assert!(archive_verifies(&entry), "the rebuilt entry verifies");
        let _ = std::fs::remove_dir_all(&tmp);
    }

    fn archive_verifies(entry: &Path) -> bool {
        let url = format!("file://{}", entry.display());
        Archive::open(&url).and_then(|a| a.verify("")).is_ok_and(|r| r.passed())
    }

    #[test]
    fn the_runner_loads_a_verified_bundle_and_rebuilds_one_with_a_flipped_byte() {
        let tmp = std::env::temp_dir().join(format!("sadesim-bundle-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        let cache = format!("file://{}", tmp.join("cache").display());
        let plan = plan();
        let generated = World::generate(&WorldInputs::from_spec(&plan.spec, &[]));
        let builds = std::cell::Cell::new(0);
        let build = || {
            builds.set(builds.get() + 1);
            Ok(generated.clone())
        };
        let (first, _) = ensure_bundle(&plan.asset_cache_key, plan.spec.origin.geo(), &cache, &tmp.join("s1"), build)
            .expect("builds");
        assert!(matches!(first, AssetsOutcome::Built { replaced: None, .. }), "{first:?}");
        let (second, loaded) =
            ensure_bundle(&plan.asset_cache_key, plan.spec.origin.geo(), &cache, &tmp.join("s2"), build).expect("hits");
        assert!(matches!(second, AssetsOutcome::CacheHit { .. }), "{second:?}");
        assert_eq!(builds.get(), 1, "a hit does not build the world");
        assert!(loaded == generated, "the loaded world is the built one, bit for bit");

        // One flipped byte in world.bin: the entry no longer verifies; loading it directly
        // is refused, and the runner rebuilds it.
        let bin =
            tmp.join("cache").join(ASSETS_NAMESPACE).join(&plan.asset_cache_key).join(WORLD_FOLDER).join(WORLD_BIN);
        let mut bytes = std::fs::read(&bin).expect("world.bin");
        let middle = bytes.len() / 2;
        bytes[middle] ^= 0x01;
        std::fs::write(&bin, bytes).expect("flip");
        let err = load_bundle(first.url()).expect_err("a damaged world.bin is refused").to_string();
        assert!(err.contains("world.bin: does not match the manifest"), "{err}");
        let (third, rebuilt) =
            ensure_bundle(&plan.asset_cache_key, plan.spec.origin.geo(), &cache, &tmp.join("s3"), build)
                .expect("rebuilds");
        let AssetsOutcome::Built { replaced: Some(why), .. } = &third else {
            panic!("expected a rebuild, got {third:?}")
        };
        assert!(why.contains("world.bin"), "{why}");
        assert_eq!(builds.get(), 2);
        assert!(rebuilt == generated);
        assert!(load_bundle(third.url()).is_ok_and(|w| w == generated), "the rebuilt entry loads");
        let _ = std::fs::remove_dir_all(&tmp);
    }

    #[test]
    fn the_local_cache_follows_the_xdg_rules() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
        };
        let url = |pairs| local_cache_url(&env(pairs)).map_err(|e| e.to_string());
        assert_eq!(url(&[("HOME", "/home/u")]), Ok("file:///home/u/.cache/sadesim".into()));
        assert_eq!(url(&[("HOME", "/home/u"), ("XDG_CACHE_HOME", "/c")]), Ok("file:///c/sadesim".into()));
        assert_eq!(url(&[("XDG_CACHE_HOME", "/c"), (CACHE_DIR_ENV, "/mine")]), Ok("file:///mine".into()));
        assert!(url(&[]).is_err_and(|e| e.contains(CACHE_DIR_ENV)));
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
