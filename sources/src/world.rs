//! A run's world, read at the I/O edge: the OpenStreetMap extract of `world.source: osm`
//! (`world.osm.file`) and the DEM of `world.terrain.dem.file`, read and handed to the pure
//! world library and planner. Every role that needs the world (runner, shards, assets,
//! report) builds it through here, so all build the same one.
//!
//! A file is a local path, a `file://` URL, or an object in object storage (`s3://`,
//! `gs://`, `az://`, credentials from the environment as for archives): what a cluster run
//! names, since its pods and the operator share no disk with the user.

use std::path::PathBuf;

use sadesim_crds::SimulationRunSpec;
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::run::WorldSource;
use sadesim_world::dem::{Dem, DemError};
use sadesim_world::osm::{self, OsmError};
use sadesim_world::{World, WorldData, WorldError, WorldInputs};

/// Why a run's world could not be read.
#[derive(Debug, thiserror::Error)]
pub enum WorldReadError {
    #[error("{field} {path}: failed to read: {source}")]
    Read {
        field: &'static str,
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// An object-store file could not be fetched (the error names the URL).
    #[error("{field}: {source}")]
    Fetch {
        field: &'static str,
        #[source]
        source: sadesim_evidence::archive::ArchiveError,
    },
    #[error("spec.world.osm.file {path}: {source}")]
    Osm {
        path: String,
        /// Boxed: the import's errors carry both bounding boxes.
        #[source]
        source: Box<OsmError>,
    },
    #[error("spec.world.terrain.dem.file {path}: {source}")]
    Dem {
        path: String,
        #[source]
        source: DemError,
    },
    #[error(transparent)]
    World(#[from] WorldError),
}

/// The local file of `world.osm.file` or `world.terrain.dem.file`: a path, or a `file://`
/// URL's path (object-store URLs are fetched instead, see [`read_data`]). Relative paths are
/// relative to the working directory (`sadesim` makes them absolute against the scenario's
/// folder when it loads the scenario).
pub fn file_path(file: &str) -> PathBuf {
    PathBuf::from(file.strip_prefix("file://").unwrap_or(file))
}

/// Makes `world.osm.file`, `world.terrain.dem.file`, `environment.gnss.constellation.file`
/// and `environment.wind.urban.case.dir` absolute against `base`, the scenario file's folder
/// (as a user expects of a path written in a scenario kept beside its data), so the plan
/// names the file wherever its roles run. Object-store URLs and absolute paths are kept.
pub fn resolve_paths(run: &mut sadesim_crds::SimulationRun, base: &std::path::Path) {
    let world = run.spec.world.as_mut();
    let (osm, dem) = match world {
        Some(w) => (w.osm.as_mut().map(|o| &mut o.file), w.terrain.as_mut().map(|t| &mut t.dem.file)),
        None => (None, None),
    };
    let environment = run.spec.environment.as_mut();
    let (gnss, wind) = match environment {
        Some(e) => (e.gnss.as_mut(), e.wind.as_mut()),
        None => (None, None),
    };
    let orbits = gnss.and_then(|g| g.constellation.as_mut()).and_then(|c| c.file.as_mut());
    let case = wind.and_then(|w| w.urban.as_mut()).and_then(|u| u.case.as_mut()).map(|c| &mut c.dir);
    for file in
        osm.into_iter().chain(dem).chain(orbits).chain(case).filter(|f| !sadesim_evidence::archive::is_object_store(f))
    {
        let path = file_path(file);
        if path.is_relative() {
            let absolute = std::path::absolute(base.join(&path)).unwrap_or_else(|_| base.join(&path));
            *file = absolute.display().to_string();
        }
    }
}

/// The files the run's world names, as `(field, file)` pairs in the order they are read:
/// the extract of `source: osm`, then the DEM.
pub fn world_files(spec: &SimulationRunSpec) -> Vec<(&'static str, String)> {
    let world = spec.world();
    let osm = world.osm.filter(|_| world.source == WorldSource::Osm).map(|o| ("spec.world.osm.file", o.file));
    let dem = world.terrain.map(|t| ("spec.world.terrain.dem.file", t.dem.file));
    osm.into_iter().chain(dem).collect()
}

/// The files the run's world names, read and decoded: the extract of `source: osm`, the
/// DEM of `terrain.dem`; empty for the procedural city. Local paths are read from disk,
/// object-store URLs fetched.
///
/// # Errors
/// [`WorldReadError`] naming the field and file: unreadable, not a PBF or DEM file, not
/// covering the world square, no building in it.
pub fn read_data(spec: &SimulationRunSpec) -> Result<WorldData, WorldReadError> {
    let world = spec.world();
    let mut data = WorldData::default();
    if let (WorldSource::Osm, Some(extract)) = (world.source, &world.osm) {
        let (path, bytes) = read_file("spec.world.osm.file", &extract.file)?;
        let frame = LocalFrame::new(spec.origin.geo());
        let city = osm::read_pbf(&bytes, &frame, world.extent_m)
            .map_err(|source| WorldReadError::Osm { path: path.clone(), source: Box::new(source) })?;
        data.osm = Some(city);
    }
    if let Some(terrain) = &world.terrain {
        let (path, bytes) = read_file("spec.world.terrain.dem.file", &terrain.dem.file)?;
        let dem = Dem::read(&bytes, &path).map_err(|source| WorldReadError::Dem { path, source })?;
        data.dem = Some(dem);
    }
    Ok(data)
}

pub(crate) fn read_file(field: &'static str, file: &str) -> Result<(String, Vec<u8>), WorldReadError> {
    if sadesim_evidence::archive::is_object_store(file) {
        let bytes =
            sadesim_evidence::archive::read_object(file).map_err(|source| WorldReadError::Fetch { field, source })?;
        return Ok((file.to_string(), bytes));
    }
    let path = file_path(file);
    let shown = path.display().to_string();
    let bytes = std::fs::read(&path).map_err(|source| WorldReadError::Read { field, path: shown.clone(), source })?;
    Ok((shown, bytes))
}

/// The run's world: generated, or built from the files it names.
///
/// # Errors
/// As [`read_data`], and a DEM without elevations somewhere in the world square.
pub fn load_world(spec: &SimulationRunSpec) -> Result<World, WorldReadError> {
    let data = read_data(spec)?;
    Ok(World::build(&WorldInputs::from_spec(spec, &[]), &data)?)
}
