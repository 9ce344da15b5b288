//! A run's world, read at the I/O edge: the OpenStreetMap extract of `world.source: osm`
//! (`world.osm.file`) and the DEM of `world.terrain.dem.file`, read and handed to the pure
//! world library and planner. Every role that needs the world (runner, shards, assets,
//! report) builds it through here, so all build the same one.

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

/// The file of `world.osm.file` or `world.terrain.dem.file`: a path, or a `file://` URL's
/// path. Relative paths are relative to the working directory (`sadesim` makes them
/// absolute against the scenario's folder when it loads the scenario).
pub fn file_path(file: &str) -> PathBuf {
    PathBuf::from(file.strip_prefix("file://").unwrap_or(file))
}

/// The files the run's world names, read and decoded: the extract of `source: osm`, the
/// DEM of `terrain.dem`; empty for the procedural city.
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

fn read_file(field: &'static str, file: &str) -> Result<(String, Vec<u8>), WorldReadError> {
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
