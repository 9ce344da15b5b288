//! A run's GNSS sky, read at the I/O edge: the orbit file of
//! `environment.gnss.constellation.file` (a path, `file://` or an object-store URL, as the
//! world's files), parsed by the pure `sadesim-gnss` library and placed over the run's
//! origin with t = 0 at the constellation's epoch. Without a file, the sky is the nominal
//! constellation shipped with the project (`sadesim_gnss::synthetic::NOMINAL_TLE`).

use sadesim_crds::SimulationRunSpec;
use sadesim_gnss::orbits::STALE_DAYS;
use sadesim_gnss::synthetic::{NOMINAL_NAME, NOMINAL_TLE};
use sadesim_gnss::{Constellation, OrbitError, RunSky};

/// The field every error names.
const FIELD: &str = "spec.environment.gnss.constellation.file";

/// Why the run's sky could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SkyReadError {
    #[error(transparent)]
    File(#[from] crate::world::WorldReadError),
    #[error("{FIELD} {path}: not a text orbit file (TLE or OMM): byte {offset} is not UTF-8")]
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
    let (path, text) = match &c.file {
        Some(file) => {
            let (path, bytes) = crate::world::read_file(FIELD, file)?;
            let text = String::from_utf8(bytes)
                .map_err(|e| SkyReadError::NotText { path: path.clone(), offset: e.utf8_error().valid_up_to() })?;
            (path, text)
        }
        None => (NOMINAL_NAME.to_string(), NOMINAL_TLE.to_string()),
    };
    let constellation =
        Constellation::parse(&text).map_err(|source| SkyReadError::Orbits { path: path.clone(), source })?;
    let epoch_unix_s = match &c.epoch {
        Some(text) => sadesim_gnss::parse_utc(text).map_err(SkyReadError::Epoch)?,
        None => constellation.newest_epoch_unix_s(),
    };
    let age_days = constellation.age_days(epoch_unix_s);
    // The nominal constellation is no day's sky at any epoch: nothing to warn about.
    if age_days > STALE_DAYS && c.file.is_some() {
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

#[cfg(test)]
mod tests {
    use sadesim_crds::fixtures::RunBuilder;

    use super::*;

    /// The fixture run with a constellation file holding `bytes` (written to a fresh file).
    fn sky_of(name: &str, bytes: &[u8], epoch: Option<&str>) -> Result<Option<RunSky>, SkyReadError> {
        let path = std::env::temp_dir().join(format!("sadesim-sky-{}-{name}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        let file = path.display().to_string();
        let run = RunBuilder::test()
            .with(|r| {
                r.spec.environment = Some(
                    serde_json::from_value(
                        serde_json::json!({"gnss": {"constellation": {"file": file, "epoch": epoch}}}),
                    )
                    .unwrap(),
                );
            })
            .build();
        let sky = load_sky(&run.spec);
        std::fs::remove_file(&path).unwrap();
        sky
    }

    #[test]
    fn a_tle_file_makes_the_sky_at_its_own_epoch_unless_the_scenario_gives_one() {
        let tle = sadesim_gnss::synthetic::walker_gps_galileo_tle();
        let sky = sky_of("ok", tle.as_bytes(), None).unwrap().unwrap();
        assert_eq!(sky.constellation().satellites.len(), 48);
        assert_eq!(sky.epoch_unix_s(), 1_606_737_600.0);
        assert_eq!(sky.mask_deg(), DEFAULT_MASK_DEG);
        let later = sky_of("epoch", tle.as_bytes(), Some("2020-12-01T00:00:00Z")).unwrap().unwrap();
        assert_eq!(later.epoch_unix_s(), 1_606_780_800.0);
        let run = RunBuilder::test().build();
        assert!(load_sky(&run.spec).unwrap().is_none(), "no constellation, no sky");
    }

    #[test]
    fn an_omm_file_makes_the_sky_as_a_tle_file_does() {
        let kvn = "CCSDS_OMM_VERS = 2.0\nOBJECT_NAME = NAVSTAR 43 (USA 132)\nNORAD_CAT_ID = 24876\n\
                   EPOCH = 2020-11-29T23:14:27.067776\nMEAN_MOTION = 2.00562032 [rev/day]\nECCENTRICITY = .0046391\n\
                   INCLINATION = 55.4606\nRA_OF_ASC_NODE = 177.6943\nARG_OF_PERICENTER = 58.6753\n\
                   MEAN_ANOMALY = 301.8606\nBSTAR = 0\n";
        let sky = sky_of("omm", kvn.as_bytes(), None).unwrap().unwrap();
        assert_eq!(sky.constellation().satellites[0].norad_id, 24876);
        assert!((sky.epoch_unix_s() - 1_606_691_667.067_776).abs() < 1e-6, "{}", sky.epoch_unix_s());
        let e = sky_of("omm-bad", kvn.replace("BSTAR = 0\n", "").as_bytes(), None).unwrap_err().to_string();
        assert!(e.ends_with("line 1 (NAVSTAR 43 (USA 132)): BSTAR: missing: an SGP4 element set needs it"), "{e}");
    }

    #[test]
    fn a_constellation_without_a_file_is_the_shipped_nominal_one_at_any_epoch() {
        let run = |epoch: &str| {
            RunBuilder::test()
                .with(|r| {
                    r.spec.environment = Some(
                        serde_json::from_value(serde_json::json!({"gnss": {"constellation": {"epoch": epoch}}}))
                            .unwrap(),
                    );
                })
                .build()
        };
        let sky = load_sky(&run("2026-06-01T08:00:00Z").spec).unwrap().expect("a sky");
        assert_eq!(sky.constellation().satellites.len(), 48);
        assert_eq!(sky.epoch_unix_s(), 1_780_300_800.0);
        // Six years from its element sets the nominal sky still has a dual-constellation
        // receiver's dozen-plus satellites above the mask.
        let mask_sin = sky.mask_deg().to_radians().sin();
        let above = sky.at(0.0).iter().filter(|s| s.position_enu_m.z / s.position_enu_m.norm() > mask_sin).count();
        assert!((12..=24).contains(&above), "{above} above the mask");
    }

    #[test]
    fn bad_orbit_files_name_the_field_the_file_and_what_is_wrong() {
        let binary = sky_of("pbf", b"\x00\x00\x00\x0d\n\x09OSMHeader\xff", None).unwrap_err().to_string();
        assert!(binary.starts_with("spec.environment.gnss.constellation.file "), "{binary}");
        assert!(binary.ends_with("not a text orbit file (TLE or OMM): byte 15 is not UTF-8"), "{binary}");
        let csv = sky_of("csv", b"name,lat,lon\nfoo,1,2\n", None).unwrap_err().to_string();
        assert!(csv.ends_with(r#"not an orbit file: neither TLE (no line starts with "1 ", a TLE line 1) nor OMM; first line "name,lat,lon". Expected element sets as CelesTrak publishes them: FORMAT=tle, 3le, kvn, xml, json or csv"#), "{csv}");
        let missing = load_sky(
            &RunBuilder::test()
                .with(|r| {
                    r.spec.environment = Some(
                        serde_json::from_value(
                            serde_json::json!({"gnss": {"constellation": {"file": "/nonexistent/gps.tle"}}}),
                        )
                        .unwrap(),
                    );
                })
                .build()
                .spec,
        )
        .unwrap_err()
        .to_string();
        assert!(
            missing.starts_with("spec.environment.gnss.constellation.file /nonexistent/gps.tle: failed to read"),
            "{missing}"
        );
    }
}
