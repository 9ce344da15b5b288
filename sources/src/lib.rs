//! The files a run reads, wherever they live (a path, `file://`, or object storage through
//! `sadesim-evidence`'s archives): read at the I/O edge and handed to the pure crates as
//! bytes and values. Used by the local runner, the roles, the operator (the world's files
//! when it plans) and the CLI alike, so every one of them reads the same world.
//!
//! - `world`: the files a world names (OSM extract, DEM) read from disk or object storage,
//!   and the world built from them;
//! - `gnss`: the run's GNSS sky, its orbit file read at the edge;
//! - `wind`: the urban wind field's asset cache entry and file format;
//! - `assets`: the asset bundle (the world built once, content-addressed, loaded by every
//!   role) and the lookup of a finished run's world;
//! - `gltf`: the world as glTF 2.0 binary (`world.glb`);
//! - `zarr`: Zarr v2 groups of dense arrays (the wind field, the sky grid).

pub mod assets;
pub mod gltf;
pub mod gnss;
pub mod wind;
pub mod world;
pub mod zarr;
