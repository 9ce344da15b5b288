//! A run's GNSS sky, read at the I/O edge: the orbit file of
//! `environment.gnss.constellation.file` (a path, `file://` or an object-store URL, as the
//! world's files), parsed by the pure `sadesim-gnss` library and placed over the run's
//! origin with t = 0 at the constellation's epoch.

use sadesim_crds::SimulationRunSpec;
use sadesim_gnss::orbits::STALE_DAYS;
use sadesim_gnss::{Constellation, OrbitError, RunSky};

/// The field every error names.
const FIELD: &str = "spec.environment.gnss.constellation.file";

/// Why the run's sky could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SkyReadError {
    #[error(transparent)]
    File(#[from] crate::world::WorldReadError),
    #[error("{FIELD} {path}: not a text orbit file (TLE): byte {offset} is not UTF-8")]
    NotText { path: String, offset: usize },
    #[error("{FIELD} {path}: {source}")]
    Orbits {
        path: String,
        #[source]
        source: OrbitError,
    },
    #[error("spec.environment.gnss.constellation.epoch {0}")]
    Epoch(String),
}

/// The run's sky, `None` without a constellation (the statistical receiver). A file whose
/// element sets are more than [`STALE_DAYS`] from the run's epoch gets a warning on stderr
/// naming it (the sky is then not that day's, but a valid sky).
///
/// # Errors
/// [`SkyReadError`] naming the field and file: unreadable, not text, not TLE, no
/// navigation satellite; an epoch that is not RFC 3339.
pub fn load_sky(spec: &SimulationRunSpec) -> Result<Option<RunSky>, SkyReadError> {
    let Some(c) = spec.environment().gnss.and_then(|g| g.constellation) else { return Ok(None) };
    let (path, bytes) = crate::world::read_file(FIELD, &c.file)?;
    let text = String::from_utf8(bytes)
        .map_err(|e| SkyReadError::NotText { path: path.clone(), offset: e.utf8_error().valid_up_to() })?;
    let constellation =
        Constellation::from_tle(&text).map_err(|source| SkyReadError::Orbits { path: path.clone(), source })?;
    let epoch_unix_s = match &c.epoch {
        Some(text) => sadesim_gnss::parse_utc(text).map_err(SkyReadError::Epoch)?,
        None => constellation.newest_epoch_unix_s(),
    };
    let age_days = constellation.age_days(epoch_unix_s);
    if age_days > STALE_DAYS {
        eprintln!(
            "warning: {FIELD} {path}: element sets up to {age_days:.0} days from the run's epoch: SGP4 drifts by \
             kilometres per day from their epoch, so this is not that day's sky; use an orbit file from within a few days"
        );
    }
    let mask_deg = c.elevation_mask_deg.unwrap_or(DEFAULT_MASK_DEG);
    Ok(Some(RunSky::new(constellation, spec.origin.geo(), epoch_unix_s, mask_deg)))
}

/// Default elevation mask, degrees (`constellation.elevationMaskDeg`).
pub const DEFAULT_MASK_DEG: f64 = 10.0;
