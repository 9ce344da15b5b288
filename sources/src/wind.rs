//! The urban wind field of a run (crate `sadesim-wind`; which field a run needs is
//! `sadesim_wind::request`): its asset cache entry and its file format.
//!
//! # The format: a Zarr v2 group `wind.zarr`
//! One format for the built-in model, OpenFOAM runs and imported cases; Python reads it with
//! `xarray.open_zarr("…/wind.zarr")` (or `zarr.open`):
//!
//! | array | type | dimensions | meaning |
//! |---|---|---|---|
//! | `east`, `north`, `up` | float32 | sector, up, north, east | wind at the cell centre as a factor of the reference wind (see below), ENU components |
//! | `direction_from_deg` | float64 | sector | where each stored sector's wind comes from, degrees clockwise from north |
//! | `solid` | uint8 | up, north, east | 1 inside a building or below the ground (the wind is 0 there) |
//! | `ground_up_m` | float64 | north, east | the ground's ENU up at each column's centre, metres |
//!
//! The group's attributes give the grid (`cornerEnuM`: ENU of the corner of cell (0,0,0),
//! the lowest east, north and up; `spacingM`: cell edge; cell centres are at
//! `corner + (i + 0.5) * spacing`), the run's `origin` (WGS84; ENU is metres east, north, up
//! from it), `sectorCount` (sector k blows from k·360/sectorCount degrees), per stored
//! sector its mass-conservation residual, the `profile` the factors refer to
//! (`referenceHeightM`, `roughnessLengthM`: multiply a factor by the scenario's wind
//! speed at the reference height over open ground to get m/s), and the `model` that made it.
//!
//! # The cache entry
//! `<cache>/assets/<asset cache key>/wind-<wind key>/` beside the world's `world/` entry:
//! `wind.zarr/` and `manifest.json`. The wind key adds to the asset key what the field
//! depends on besides the world (grid spacing and top, sector count, model and its version):
//! a scenario that changes only its wind speed or direction reuses the entry.

use sadesim_crds::geo::GeoPoint;
use sadesim_evidence::archive::{Archive, ArchiveError};
use sadesim_wind::request::{FieldModel, WindRequest};
use sadesim_wind::{DIAGNOSTIC_MODEL_VERSION, SectorField, UrbanWindField, WindGrid};
use serde_json::{Value, json};

use crate::assets::{ASSETS_NAMESPACE, AssetsError};
use crate::zarr::{self, ArrayOut, Compression, Dtype, ZarrError};

/// The group's folder inside a cache entry.
pub const WIND_ZARR: &str = "wind.zarr";
/// Version of the format above (part of the wind key).
pub const WIND_FORMAT_VERSION: u32 = 1;
/// Chunks are zlib level 1: factors of a city compress to about half (solid cells and
/// smooth flow), at a small fraction of the field's computing time.
const COMPRESSION: Compression = Compression::Zlib(1);

/// Version of the OpenFOAM case the asset phase writes (`sadesim_wind::foam_case`): part of
/// the wind key; bump it when the mesh, the boundary conditions or the solver settings
/// change.
pub const OPENFOAM_CASE_VERSION: u32 = 1;

/// The wind key of the field of `request` over the world of `asset_key`: SHA-256 of what
/// the field depends on (not the wind's speed; the direction only through the sectors an
/// OpenFOAM field holds). `None` for an imported case, which is not cached.
pub fn wind_key(asset_key: &str, request: &WindRequest) -> Option<String> {
    let version = match request.model {
        FieldModel::Diagnostic => DIAGNOSTIC_MODEL_VERSION,
        FieldModel::OpenFoam => OPENFOAM_CASE_VERSION,
        FieldModel::Imported(_) => return None,
    };
    let inputs = json!({
        "assetKey": asset_key,
        "formatVersion": WIND_FORMAT_VERSION,
        "model": request.model.name(),
        "modelVersion": version,
        "spacingM": request.grid.spacing_m,
        "topFactor": request.grid.top_factor,
        "sectors": request.sectors,
        "sectorsBuilt": request.sectors_built(),
    });
    Some(sadesim_crds::parts::sha256_hex(inputs.to_string().as_bytes()))
}

/// The entry folder of a wind key under an asset key: `wind-<first 16 hex digits>`.
pub fn wind_folder(wind_key: &str) -> String {
    format!("wind-{}", &wind_key[..16])
}

/// The URL of the wind entry beside the world entry `world_entry_url`
/// (`<cache>/assets/<key>/world/`, what roles get as `--assets`).
pub fn wind_entry_url_beside(world_entry_url: &str, wind_key: &str) -> String {
    let base = world_entry_url.trim_end_matches('/');
    let parent = base.rsplit_once('/').map_or(base, |(p, _)| p);
    format!("{parent}/{}/", wind_folder(wind_key))
}

/// The group's files (paths relative to `wind.zarr/`) of `field`, computed by `model`, in
/// the ENU frame of `origin`.
pub fn field_files(field: &UrbanWindField, origin: GeoPoint, model: &str) -> Vec<(String, Vec<u8>)> {
    let g = &field.grid;
    let [nx, ny, nz] = g.dims;
    let sectors: Vec<&SectorField> = field.sectors.iter().map(|(_, s)| s).collect();
    let attrs = json!({
        "description": "SADE-SIM urban wind field: per inflow sector, the wind at each cell centre as a factor of the reference wind",
        "frame": "run ENU: metres east, north, up from the origin",
        "origin": {"latitudeDeg": origin.latitude_deg, "longitudeDeg": origin.longitude_deg, "altitudeMslM": origin.altitude_msl_m},
        "cornerEnuM": g.corner_m,
        "spacingM": g.spacing_m,
        "sectorCount": field.sector_count,
        "sectors": field.sectors.iter().map(|(k, s)| json!({
            "index": k, "directionFromDeg": s.direction_from_deg, "residual": s.residual,
            "firstGuessResidual": s.first_guess_residual, "iterations": s.iterations,
        })).collect::<Vec<_>>(),
        "profile": {"referenceHeightM": field.profile.reference_height_m, "roughnessLengthM": field.profile.roughness_length_m},
        "units": "factor of the wind speed at profile.referenceHeightM above open ground (multiply by it for m/s)",
        "model": model,
        "formatVersion": WIND_FORMAT_VERSION,
    });
    let shape = vec![sectors.len(), nz, ny, nx];
    let dims = ["sector", "up", "north", "east"];
    let component = |name: &str, pick: fn(&SectorField) -> &Vec<f32>| {
        let values: Vec<f32> = sectors.iter().flat_map(|s| pick(s).iter().copied()).collect();
        ArrayOut::f32(name, &dims, shape.clone(), &values).per_slice()
    };
    let arrays = [
        component("east", |s| &s.east),
        component("north", |s| &s.north),
        component("up", |s| &s.up),
        ArrayOut::f64(
            "direction_from_deg",
            &["sector"],
            vec![sectors.len()],
            &sectors.iter().map(|s| s.direction_from_deg).collect::<Vec<_>>(),
        ),
        ArrayOut::u8(
            "solid",
            &["up", "north", "east"],
            vec![nz, ny, nx],
            g.solid.iter().map(|&s| u8::from(s)).collect(),
        ),
        ArrayOut::f64("ground_up_m", &["north", "east"], vec![ny, nx], &g.ground_up_m),
    ];
    zarr::group_files(&attrs, &arrays, COMPRESSION)
}

/// Reads a field written by [`field_files`]; `fetch` gets a path relative to `wind.zarr/`.
///
/// # Errors
/// A file is missing or unreadable, or the arrays disagree with the attributes (shapes,
/// sector list): naming the file.
pub fn read_field(fetch: &mut zarr::Fetch) -> Result<UrbanWindField, ZarrError> {
    let attrs = zarr::read_group_attrs(fetch)?;
    let bad = |what: String| ZarrError { file: ".zattrs".into(), problem: what };
    let number = |v: &Value, what: &str| v.as_f64().ok_or_else(|| bad(format!("{what}: expected a number, found {v}")));
    let corner = attrs["cornerEnuM"]
        .as_array()
        .filter(|c| c.len() == 3)
        .ok_or_else(|| bad("cornerEnuM: expected [east, north, up]".into()))?;
    let corner_m =
        [number(&corner[0], "cornerEnuM")?, number(&corner[1], "cornerEnuM")?, number(&corner[2], "cornerEnuM")?];
    let spacing_m = number(&attrs["spacingM"], "spacingM")?;
    let sector_count =
        attrs["sectorCount"].as_u64().filter(|&n| n >= 1).ok_or_else(|| bad("sectorCount: expected a count".into()))?
            as u32;
    let profile = sadesim_wind::profile::LogProfile {
        reference_height_m: number(&attrs["profile"]["referenceHeightM"], "profile.referenceHeightM")?,
        roughness_length_m: number(&attrs["profile"]["roughnessLengthM"], "profile.roughnessLengthM")?,
    };
    let listed = attrs["sectors"].as_array().ok_or_else(|| bad("sectors: expected a list".into()))?.clone();
    let solid = zarr::read_array(fetch, "solid", Dtype::U8, 3)?;
    let [nz, ny, nx] = [solid.shape[0], solid.shape[1], solid.shape[2]];
    let ground = zarr::read_array(fetch, "ground_up_m", Dtype::F64, 2)?;
    if ground.shape != [ny, nx] {
        return Err(ZarrError {
            file: "ground_up_m/.zarray".into(),
            problem: format!("shape {:?}: expected [{ny}, {nx}] (solid's north, east)", ground.shape),
        });
    }
    let grid = WindGrid {
        corner_m,
        spacing_m,
        dims: [nx, ny, nz],
        solid: solid.data.iter().map(|&b| b != 0).collect(),
        ground_up_m: ground.to_f64(),
    };
    let mut components = Vec::new();
    for name in ["east", "north", "up"] {
        let a = zarr::read_array(fetch, name, Dtype::F32, 4)?;
        if a.shape != [listed.len(), nz, ny, nx] {
            return Err(ZarrError {
                file: format!("{name}/.zarray"),
                problem: format!(
                    "shape {:?}: expected [{}, {nz}, {ny}, {nx}] (the listed sectors, solid's shape)",
                    a.shape,
                    listed.len()
                ),
            });
        }
        components.push(a.to_f32());
    }
    let cells = nx * ny * nz;
    let mut sectors = Vec::with_capacity(listed.len());
    for (s, entry) in listed.iter().enumerate() {
        let index = entry["index"]
            .as_u64()
            .filter(|&k| k < u64::from(sector_count))
            .ok_or_else(|| bad(format!("sectors[{s}].index: expected 0..{sector_count}")))? as u32;
        let slice = |c: &Vec<f32>| c[s * cells..(s + 1) * cells].to_vec();
        sectors.push((
            index,
            SectorField {
                direction_from_deg: number(&entry["directionFromDeg"], "sectors[].directionFromDeg")?,
                east: slice(&components[0]),
                north: slice(&components[1]),
                up: slice(&components[2]),
                residual: entry["residual"].as_f64().unwrap_or(f64::NAN),
                first_guess_residual: entry["firstGuessResidual"].as_f64().unwrap_or(f64::NAN),
                iterations: entry["iterations"].as_u64().unwrap_or(0) as usize,
            },
        ));
    }
    Ok(UrbanWindField { grid, sector_count, sectors, profile })
}

/// What [`ensure_wind`] did.
#[derive(Clone, Debug, PartialEq)]
pub enum WindOutcome {
    /// A verified entry was there and loaded.
    CacheHit { url: String },
    /// Computed and stored; `replaced` says what was wrong with an entry that was there.
    Built { url: String, replaced: Option<String> },
}

impl WindOutcome {
    pub fn url(&self) -> &str {
        match self {
            Self::CacheHit { url } | Self::Built { url, .. } => url,
        }
    }
}

impl std::fmt::Display for WindOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::CacheHit { url } => write!(f, "urban wind field found in the asset cache: {url}"),
            Self::Built { url, replaced: None } => write!(f, "urban wind field computed and stored: {url}"),
            Self::Built { url, replaced: Some(why) } => {
                write!(f, "urban wind field computed and stored: {url} (replacing a damaged entry: {why})")
            }
        }
    }
}

/// The field of `request` over the world of `asset_key` from the cache at `cache_url`:
/// loaded from a verified entry, else computed by `build` (the sectors of
/// [`WindRequest::sectors_built`]) and stored. What the local runner and the `<run>-assets` Job do.
///
/// # Errors
/// Archive errors (open, upload) and local writes, naming the URL or file. An entry that
/// verifies but does not read as a field is rebuilt.
pub fn ensure_wind(
    asset_key: &str,
    request: &WindRequest,
    origin: GeoPoint,
    cache_url: &str,
    scratch: &std::path::Path,
    build: impl FnOnce() -> Result<UrbanWindField, AssetsError>,
) -> Result<(WindOutcome, UrbanWindField), AssetsError> {
    let archive = Archive::open(cache_url)?;
    let key = wind_key(asset_key, request).ok_or_else(|| {
        AssetsError::WindBuild("an imported OpenFOAM case is read from its folder, not cached".into())
    })?;
    let folder = wind_folder(&key);
    let entry = format!("{ASSETS_NAMESPACE}/{asset_key}/{folder}");
    let url = format!("{}/{entry}/", cache_url.trim_end_matches('/'));
    let replaced = match archive.verify(&entry) {
        Ok(report) if report.passed() => match load_wind(&url) {
            Ok(field) => return Ok((WindOutcome::CacheHit { url }, field)),
            Err(e) => Some(e.to_string()),
        },
        Ok(report) => Some(report.problems.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("; ")),
        Err(ArchiveError::NotFound { .. }) => None,
        Err(e) => Some(e.to_string()),
    };
    let field = build()?;
    let dir = scratch.join(format!("{asset_key}-{folder}"));
    let files = field_files(&field, origin, request.model.name());
    zarr::write_group(&dir.join(WIND_ZARR), &files)
        .map_err(|source| AssetsError::Write { path: dir.display().to_string(), source })?;
    archive.upload_run(&dir, ASSETS_NAMESPACE, asset_key, &folder)?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok((WindOutcome::Built { url, replaced }, field))
}

/// Loads the field of the wind entry at `entry_url` (`<cache>/assets/<key>/wind-<k>/`),
/// every file checked against the entry's manifest.
///
/// # Errors
/// The entry cannot be opened, has no manifest, a file does not match it, or the group does
/// not read as a field.
pub fn load_wind(entry_url: &str) -> Result<UrbanWindField, AssetsError> {
    let archive = Archive::open(entry_url)?;
    let mut fetch = |rel: &str| archive.read_checked("", &format!("{WIND_ZARR}/{rel}")).map_err(|e| e.to_string());
    read_field(&mut fetch).map_err(|source| AssetsError::Wind { url: format!("{entry_url}{WIND_ZARR}"), source })
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use sadesim_wind::GridSpec;
    use sadesim_world::{Building, Footprint, World};

    use super::*;

    fn small() -> (World, UrbanWindField) {
        let footprint =
            Footprint::new(vec![[-10.0, -10.0], [10.0, -10.0], [10.0, 10.0], [-10.0, 10.0]], vec![]).unwrap();
        let world = World::of_buildings(100.0, vec![Building::new(footprint, 0.0, 20.0).unwrap()]);
        let mut field = UrbanWindField::new(&world, GridSpec { spacing_m: 5.0, top_factor: 2.0 }, 8);
        field.ensure_sector(&world, 6);
        field.ensure_sector(&world, 7);
        (world, field)
    }

    fn origin() -> GeoPoint {
        GeoPoint { latitude_deg: 60.17, longitude_deg: 24.94, altitude_msl_m: 10.0 }
    }

    #[test]
    fn a_field_reads_back_bit_for_bit_from_its_files() {
        let (_, field) = small();
        let files: BTreeMap<String, Vec<u8>> = field_files(&field, origin(), "diagnostic").into_iter().collect();
        let mut fetch = |p: &str| files.get(p).cloned().ok_or_else(|| "missing".to_string());
        assert_eq!(read_field(&mut fetch).unwrap(), field);
        assert!(files.contains_key("east/1.0.0.0"), "one chunk per stored sector");
    }

    #[test]
    fn arrays_that_disagree_with_the_attributes_name_the_file() {
        let (_, field) = small();
        let mut files: BTreeMap<String, Vec<u8>> = field_files(&field, origin(), "diagnostic").into_iter().collect();
        let mut attrs: Value = serde_json::from_slice(&files[".zattrs"]).unwrap();
        attrs["sectors"].as_array_mut().unwrap().pop();
        files.insert(".zattrs".into(), attrs.to_string().into_bytes());
        let mut fetch = |p: &str| files.get(p).cloned().ok_or_else(|| "missing".to_string());
        let e = read_field(&mut fetch).unwrap_err();
        assert_eq!(e.file, "east/.zarray");
        assert!(e.problem.contains("the listed sectors"), "{e}");
    }

    #[test]
    fn the_key_changes_with_the_grid_and_sectors_but_not_the_wind_speed_or_direction() {
        let r = WindRequest {
            grid: GridSpec { spacing_m: 5.0, top_factor: 2.0 },
            sectors: 8,
            direction_from_deg: 270.0,
            model: FieldModel::Diagnostic,
        };
        let key = |r: &WindRequest| wind_key("abc", r).expect("cached");
        let k = key(&r);
        assert_eq!(k, key(&WindRequest { direction_from_deg: 10.0, ..r.clone() }));
        assert_ne!(Some(k.clone()), wind_key("abd", &r));
        assert_ne!(k, key(&WindRequest { sectors: 12, ..r.clone() }));
        assert_ne!(k, key(&WindRequest { grid: GridSpec { spacing_m: 4.0, top_factor: 2.0 }, ..r.clone() }));
        assert_eq!(
            wind_entry_url_beside("file:///c/assets/abc/world/", &k),
            format!("file:///c/assets/abc/{}/", wind_folder(&k))
        );
        // OpenFOAM holds only the run direction's sectors: another direction is another
        // entry unless it blends the same sectors.
        let foam = WindRequest { model: FieldModel::OpenFoam, ..r.clone() };
        assert_eq!(foam.sectors_built(), [6]);
        assert_eq!(WindRequest { direction_from_deg: 280.0, ..foam.clone() }.sectors_built(), [6, 7]);
        assert_ne!(key(&foam), k);
        assert_ne!(key(&foam), key(&WindRequest { direction_from_deg: 280.0, ..foam.clone() }));
        // An imported case is read from its folder, never cached.
        let case = sadesim_crds::environment::OpenFoamCase {
            dir: "case".into(),
            direction_from_deg: 270.0,
            reference_speed_mps: 10.0,
        };
        assert_eq!(wind_key("abc", &WindRequest { model: FieldModel::Imported(case), ..r }), None);
    }

    #[test]
    fn the_cache_stores_every_sector_once_then_hits_and_rebuilds_a_damaged_entry() {
        let dir = std::env::temp_dir().join(format!("sadesim-wind-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let cache = format!("file://{}", dir.display());
        let (world, _) = small();
        let request = WindRequest {
            grid: GridSpec { spacing_m: 5.0, top_factor: 2.0 },
            sectors: 4,
            direction_from_deg: 270.0,
            model: FieldModel::Diagnostic,
        };
        let build = || {
            let mut f = UrbanWindField::new(&world, request.grid, request.sectors);
            f.ensure_all(&world, |_, _| {});
            Ok(f)
        };
        let scratch = dir.join("scratch");
        let (first, field) = ensure_wind("key1", &request, origin(), &cache, &scratch, build).unwrap();
        assert!(matches!(first, WindOutcome::Built { replaced: None, .. }), "{first}");
        assert_eq!(field.sectors.len(), 4);
        let (second, again) =
            ensure_wind("key1", &request, origin(), &cache, &scratch, || panic!("no rebuild")).unwrap();
        assert_eq!(second, WindOutcome::CacheHit { url: first.url().to_string() });
        assert_eq!(again, field);
        // A flipped byte in a chunk: the manifest catches it and the entry is rebuilt.
        let entry = dir.join("assets/key1").join(wind_folder(&wind_key("key1", &request).unwrap()));
        let chunk = entry.join("wind.zarr/east/0.0.0.0");
        let mut bytes = std::fs::read(&chunk).unwrap();
        bytes[10] ^= 1;
        std::fs::write(&chunk, bytes).unwrap();
        let (third, _) = ensure_wind("key1", &request, origin(), &cache, &scratch, build).unwrap();
        assert!(
            matches!(&third, WindOutcome::Built { replaced: Some(why), .. } if why.contains("east/0.0.0.0")),
            "{third}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
