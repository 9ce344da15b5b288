//! The sweep report: `sweep.json` (the data, [`model::SweepReport`]) and `sweep.html`
//! (self-contained: inline CSS and SVG) in a sweep's folder, built from the summaries of
//! its runs; and the comparison of two sweeps of the same parameter space.
//!
//! - `stats`: the Wilson interval and Fisher's exact test;
//! - `model`: the report's data, [`build`] and [`compare`];
//! - `svg`: the plots (pass rate against a parameter, heat map, metric box plots);
//! - `html`: the page.
//!
//! Everything is pure except [`write`] and [`read`].

use std::path::Path;

pub mod html;
pub mod model;
pub mod stats;
pub mod svg;

#[cfg(test)]
mod tests;

pub use model::{Comparison, SweepRecord, SweepReport, build, compare};

/// The report's data in the sweep's folder.
pub const SWEEP_JSON: &str = "sweep.json";
/// The report's page in the sweep's folder.
pub const SWEEP_HTML: &str = "sweep.html";

/// Writes `sweep.json` (pretty, with a trailing newline) and `sweep.html` into `dir`,
/// which must exist.
///
/// # Errors
/// The first file that could not be written.
pub fn write(dir: &Path, report: &SweepReport) -> std::io::Result<()> {
    let mut json = serde_json::to_string_pretty(report).expect("a report always serializes");
    json.push('\n');
    std::fs::write(dir.join(SWEEP_JSON), json)?;
    std::fs::write(dir.join(SWEEP_HTML), html::page(report))
}

/// Why `sweep.json` could not be read.
#[derive(Debug, thiserror::Error)]
pub enum SweepReadError {
    /// The file is missing or unreadable.
    #[error("{path}: failed to read: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a sweep report: the field (`cells[2].passed`) and what is wrong.
    #[error("{path}: {field}: {message}")]
    Field { path: String, field: String, message: String },
}

/// Reads `sweep.json` from `dir`.
///
/// # Errors
/// A message naming the file, and for malformed content the field.
pub fn read(dir: &Path) -> Result<SweepReport, SweepReadError> {
    let path = dir.join(SWEEP_JSON);
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(&path).map_err(|source| SweepReadError::Io { path: shown.clone(), source })?;
    let mut de = serde_json::Deserializer::from_str(&text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let field = e.path().to_string();
        SweepReadError::Field {
            path: shown,
            field: if field == "." { "(document root)".into() } else { field },
            message: e.into_inner().to_string(),
        }
    })
}
