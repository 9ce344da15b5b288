//! What a run leaves behind, and where: the run report (`report.html` with its plots), the
//! archive on object storage (manifest with checksums, upload, verify), and the world asset
//! cache inside an archive. Used by the local runner, the coordinator role and the
//! Kubernetes operator alike, so a run folder has the same files everywhere.

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
