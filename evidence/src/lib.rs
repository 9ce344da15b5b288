//! What a run leaves behind, and where: the run report (`report.html` with its plots), the
//! archive on object storage (manifest with checksums, upload, verify), and the world asset
//! cache inside an archive. Used by the local runner, the coordinator role and the
//! Kubernetes operator alike, so a run folder has the same files everywhere.
//!
//! - `world`: the files a world names (OSM extract, DEM) read from disk or object storage,
//!   and the world built from them;
//! - `gnss`: the run's GNSS sky, its orbit file read at the edge;
//! - `wind`: the urban wind field's asset cache entry and file format;
//! - `assets`: the asset bundle (the world built once, content-addressed, loaded by every role);
//! - `gltf`: the world as glTF 2.0 binary (`world.glb`);
//! - `zarr`: Zarr v2 groups of dense arrays (the wind field, the sky grid);
//! - `archive`: run archives on object storage or a folder (manifest, upload, verify);
//! - `report`: `report.html` and its plots (feature `report`);
//! - `finish`: the end of every run: report, manifest, upload (feature `report`).

pub mod archive;
pub mod assets;
#[cfg(feature = "report")]
pub mod finish;
pub mod gltf;
pub mod gnss;
#[cfg(feature = "report")]
pub mod report;
pub mod wind;
pub mod world;
pub mod zarr;
