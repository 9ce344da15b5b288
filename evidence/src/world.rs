//! A run's world, read at the I/O edge: the OpenStreetMap extract of `world.source: osm`
//! read from `world.osm.file` and handed to the pure world library and planner. Every role
//! that needs the world (runner, shards, assets, report) builds it through here, so all
//! build the same one.

use std::path::PathBuf;

use sadesim_crds::SimulationRunSpec;
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::run::WorldSource;
use sadesim_world::osm::{self, OsmCity, OsmError};
use sadesim_world::{World, WorldError, WorldInputs};

/// Why a run's world could not be read.
#[derive(Debug, thiserror::Error)]
pub enum WorldReadError {
    #[error("spec.world.osm.file {path}: failed to read: {source}")]
    Read {
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
    #[error(transparent)]
    World(#[from] WorldError),
}

/// The file of `world.osm.file`: a path, or a `file://` URL's path. Relative paths are
/// relative to the working directory (`sadesim` makes them absolute against the scenario's
/// folder when it loads the scenario).
pub fn extract_path(file: &str) -> PathBuf {
    PathBuf::from(file.strip_prefix("file://").unwrap_or(file))
}

/// The extract of a `source: osm` world, read and imported; `None` for the procedural city.
///
/// # Errors
/// [`WorldReadError`] naming the field and file: unreadable, not a PBF file, not covering
/// the world square, no building in it.
pub fn read_extract(spec: &SimulationRunSpec) -> Result<Option<OsmCity>, WorldReadError> {
    let world = spec.world();
    let (WorldSource::Osm, Some(extract)) = (world.source, &world.osm) else { return Ok(None) };
    let path = extract_path(&extract.file);
    let shown = path.display().to_string();
    let bytes = std::fs::read(&path).map_err(|source| WorldReadError::Read { path: shown.clone(), source })?;
    let frame = LocalFrame::new(spec.origin.geo());
    osm::read_pbf(&bytes, &frame, world.extent_m)
        .map(Some)
        .map_err(|source| WorldReadError::Osm { path: shown, source: Box::new(source) })
}

/// The run's world: generated, or built from its extract.
///
/// # Errors
/// As [`read_extract`].
pub fn load_world(spec: &SimulationRunSpec) -> Result<World, WorldReadError> {
    let extract = read_extract(spec)?;
    Ok(World::build(&WorldInputs::from_spec(spec, &[]), extract.as_ref())?)
}
