//! What a run leaves behind, and where: the run report (`report.html` with its plots), the
//! archive on object storage (manifest with checksums, upload, verify). Used by the local
//! runner, the coordinator role and the Kubernetes operator alike, so a run folder has the
//! same files everywhere; `sadesim-sources` reads a run's input files through its archives.
//!
//! - `archive`: run archives on object storage or a folder (manifest, upload, verify), and
//!   single objects read by URL;
//! - `report`: `report.html` and its plots (feature `report`);
//! - `finish`: the end of every run: report, manifest, upload (feature `report`);
//! - `sweep`: the sweep report (`sweep.json`, `sweep.html`): pass rates with confidence
//!   intervals per cell, metric distributions, and the comparison of two sweeps;
//! - `markup`: the font and XML escaping every page and plot writes with.

pub mod archive;
#[cfg(feature = "report")]
pub mod finish;
pub mod markup;
#[cfg(feature = "report")]
pub mod report;
pub mod sweep;
