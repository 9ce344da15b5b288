//! A GNSS constellation from an orbit file as CelesTrak and Space-Track publish them
//! (CelesTrak's `gnss`, `gps-ops`, `galileo`, `glo-ops`, `beidou` groups): two-line (TLE) or
//! three-line (3LE, a name line first) element sets, or Orbit Mean-Elements Messages (OMM,
//! [`crate::omm`]) in KVN, XML, JSON or CSV; or a whole catalogue from which the navigation
//! satellites are picked by name.
//!
//! Satellites are propagated with SGP4 (the `sgp4` crate, the Vallado reference
//! implementation) to TEME positions, then rotated into Earth-fixed coordinates by the
//! Greenwich mean sidereal time (IAU 1982). Polar motion and the TEME/pseudo-Earth-fixed
//! difference (equation of the equinoxes, under 1.1 arc-seconds here) are left out: they
//! move a satellite 20 000 km away by tens of metres, well under 0.01 degree seen from the
//! ground. SGP4's own error for navigation satellites is about a kilometre at the elements'
//! epoch and grows by kilometres per day away from it, so an orbit file should be within
//! days of the scenario's epoch for the sky to be the sky of that day; [`Constellation::age_days`]
//! says how far it is.

use nalgebra::Vector3;
use sadesim_crds::geo::Ecef;

use crate::omm::{self, At};

/// A navigation system, from the satellite's name in the orbit file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum System {
    /// GPS (`NAVSTAR 43 (USA 132)`, `GPS BIIR-2 (PRN 13)`, `G13 ...`).
    Gps,
    /// Galileo (`GALILEO`, `GSAT0101`).
    Galileo,
    /// GLONASS (`COSMOS 2471 (GLONASS-K1)`, `GLONASS`).
    Glonass,
    /// BeiDou (`BEIDOU`, `COMPASS`).
    Beidou,
}

impl System {
    /// The system a satellite name denotes, `None` for anything else (a catalogue holds
    /// thousands of other objects).
    pub fn of_name(name: &str) -> Option<System> {
        let n = name.to_ascii_uppercase();
        // A RINEX satellite id first (`G13 ...`, `E11 ...`), as files cut with a PRN table.
        let b = n.as_bytes();
        if b.len() >= 3 && b[1].is_ascii_digit() && b[2].is_ascii_digit() && (b.len() == 3 || b[3] == b' ') {
            match b[0] {
                b'G' => return Some(System::Gps),
                b'E' => return Some(System::Galileo),
                b'R' => return Some(System::Glonass),
                b'C' => return Some(System::Beidou),
                _ => {}
            }
        }
        if n.contains("NAVSTAR") || n.starts_with("GPS ") || n.contains("(PRN ") {
            Some(System::Gps)
        } else if n.contains("GALILEO") || n.starts_with("GSAT0") {
            Some(System::Galileo)
        } else if n.contains("GLONASS") {
            Some(System::Glonass)
        } else if n.contains("BEIDOU") || n.contains("COMPASS") {
            Some(System::Beidou)
        } else {
            None
        }
    }

    /// One-letter RINEX system code (`G`, `E`, `R`, `C`).
    pub fn code(self) -> char {
        match self {
            System::Gps => 'G',
            System::Galileo => 'E',
            System::Glonass => 'R',
            System::Beidou => 'C',
        }
    }
}

/// One satellite: its name, catalogue number, system and SGP4 propagator.
#[derive(Debug)]
pub struct Satellite {
    pub name: String,
    /// NORAD catalogue number.
    pub norad_id: u64,
    pub system: System,
    /// Epoch of the element set, UNIX seconds.
    pub epoch_unix_s: f64,
    elements: sgp4::Elements,
    constants: sgp4::Constants,
}

/// Why an orbit file cannot be a constellation. The caller adds the file's name.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OrbitError {
    /// A line that should be a TLE line is not one, or an OMM file's syntax is broken there.
    #[error("line {line}: {reason}")]
    Line { line: usize, reason: String },
    /// An OMM element set with a key missing or wrong (the reason names the key).
    #[error("{at}{}: {reason}", shown_name(.name.as_deref()))]
    Set { at: At, name: Option<String>, reason: String },
    /// An element set that SGP4 refuses (e.g. an eccentricity out of range).
    #[error("{at} ({name}): the elements cannot be propagated: {reason}")]
    Elements { at: At, name: String, reason: String },
    /// Nothing in the file looks like element sets (another kind of file: RINEX, HTML...).
    #[error(
        "not an orbit file: neither TLE (no line starts with \"1 \", a TLE line 1) nor OMM; first line {first:?}. Expected element sets as CelesTrak publishes them: FORMAT=tle, 3le, kvn, xml, json or csv"
    )]
    UnknownFormat { first: String },
    /// The file has no navigation satellite.
    #[error(
        "no GPS, Galileo, GLONASS or BeiDou satellite among {objects} element sets: expected an orbit file of navigation satellites (e.g. CelesTrak's gnss group)"
    )]
    NoNavigationSatellites { objects: usize },
}

fn shown_name(name: Option<&str>) -> String {
    name.map(|n| format!(" ({n})")).unwrap_or_default()
}

/// Element sets farther than this many days from the time they are used at deserve a
/// warning: SGP4's error for navigation satellites grows by kilometres per day away from the
/// elements' epoch.
pub const STALE_DAYS: f64 = 7.0;

/// The navigation satellites of an orbit file.
#[derive(Debug)]
pub struct Constellation {
    pub satellites: Vec<Satellite>,
}

/// A satellite's Earth-fixed position at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SatellitePosition {
    /// Index into [`Constellation::satellites`].
    pub index: usize,
    pub ecef: Ecef,
}

impl Satellite {
    /// A satellite from its element set, found at `at` in its file.
    ///
    /// # Errors
    /// [`OrbitError::Elements`]: SGP4 cannot propagate the set, or it is of another theory
    /// (ephemeris type 4 is SGP4-XP).
    fn new(at: At, name: Option<&str>, system: System, elements: sgp4::Elements) -> Result<Self, OrbitError> {
        let shown = name.map_or_else(|| format!("NORAD {}", elements.norad_id), str::to_string);
        let refused = |reason: String| OrbitError::Elements { at, name: shown.clone(), reason };
        check_ephemeris_type(elements.ephemeris_type.into())
            .map_err(|reason| refused(format!("ephemeris type {reason}")))?;
        let constants = sgp4::Constants::from_elements(&elements).map_err(|e| refused(format!("{e:?}")))?;
        let epoch_unix_s = elements.datetime.and_utc().timestamp_micros() as f64 * 1e-6;
        Ok(Satellite { name: shown, norad_id: elements.norad_id, system, epoch_unix_s, elements, constants })
    }
}

/// Refuses an element set of a theory other than SGP4 (`reason` starts with the type):
/// ephemeris type 0 is SGP4; 4 is SGP4-XP, whose elements SGP4 would propagate to a wrong
/// place.
pub(crate) fn check_ephemeris_type(ephemeris_type: u64) -> Result<(), String> {
    if ephemeris_type == 0 {
        return Ok(());
    }
    Err(format!(
        "{ephemeris_type} is not supported: expected 0 (SGP4); 4 is SGP4-XP, a different theory sadesim does not propagate"
    ))
}

/// The system of an element set named `name`, `None` to skip it. Unnamed sets are kept (as
/// GPS) only when the whole file is unnamed: CelesTrak's 2LE files of a GNSS group.
fn system_of(name: Option<&str>, all_unnamed: bool) -> Option<System> {
    match name {
        Some(name) => System::of_name(name),
        None if all_unnamed => Some(System::Gps),
        None => None,
    }
}

impl Constellation {
    /// Parses an orbit file, its format told from its text: two- or three-line element sets
    /// (TLE, see [`Constellation::from_tle`]) or an Orbit Mean-Elements Message in any of
    /// its encodings (KVN, XML, JSON, CSV; see [`crate::omm`]). The navigation satellites
    /// are kept, by name.
    ///
    /// # Errors
    /// [`OrbitError`] naming the line (or JSON object) and, for OMM, the key: a malformed
    /// file or element set, elements SGP4 cannot propagate, a file of no known format, or
    /// no navigation satellite at all.
    pub fn parse(text: &str) -> Result<Self, OrbitError> {
        match omm::Encoding::of(text) {
            Some(encoding) => Self::from_omm(text, encoding),
            None => Self::from_tle(text),
        }
    }

    /// Parses an OMM file in `encoding`: every element set's syntax is checked, the keys of
    /// the navigation satellites' sets (see [`omm::Record::elements`]).
    ///
    /// # Errors
    /// As [`Constellation::parse`].
    pub fn from_omm(text: &str, encoding: omm::Encoding) -> Result<Self, OrbitError> {
        let records = omm::records(text, encoding)?;
        let all_unnamed = records.iter().all(|r| r.name().is_none());
        let mut satellites = Vec::new();
        for record in &records {
            let Some(system) = system_of(record.name(), all_unnamed) else { continue };
            satellites.push(Satellite::new(record.at, record.name(), system, record.elements()?)?);
        }
        Self::of(satellites, records.len())
    }

    fn of(satellites: Vec<Satellite>, objects: usize) -> Result<Self, OrbitError> {
        if satellites.is_empty() {
            return Err(OrbitError::NoNavigationSatellites { objects });
        }
        Ok(Self { satellites })
    }

    /// Parses TLE `text`: element sets of two lines (`1 ...`, `2 ...`) or three (a name line
    /// first, `0 NAME` or `NAME`). Every element set's lines are checked (length, checksum,
    /// fields); the navigation satellites (by name; unnamed sets are kept when the file
    /// holds nothing but unnamed sets, as CelesTrak's 2LE files of a GNSS group) are kept.
    ///
    /// # Errors
    /// [`OrbitError`] naming the line: a malformed line or element set, no line 1 at all, or
    /// no navigation satellite.
    pub fn from_tle(text: &str) -> Result<Self, OrbitError> {
        let lines: Vec<(usize, &str)> =
            text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end())).filter(|(_, l)| !l.is_empty()).collect();
        if !lines.iter().any(|(_, l)| l.starts_with("1 ")) {
            let first: String = lines.first().map_or("", |(_, l)| l).chars().take(60).collect();
            return Err(OrbitError::UnknownFormat { first });
        }
        let mut sets: Vec<(usize, usize, Option<String>, &str, &str)> = Vec::new();
        // The sgp4 crate reads a line's checksum digit as `byte - b'0'`, which overflows
        // (a panic with overflow checks) when it is not a digit: refused here first.
        let checksum_digit = |n: usize, line: &str| match line.as_bytes().get(68) {
            Some(c) if !c.is_ascii_digit() => Err(OrbitError::Line {
                line: n,
                reason: format!("column 69 is the checksum, a digit 0-9; found {:?}", char::from(*c)),
            }),
            _ => Ok(()),
        };
        let mut k = 0;
        while k < lines.len() {
            let (n, line) = lines[k];
            let name =
                if line.starts_with("1 ") { None } else { Some(line.trim_start_matches("0 ").trim().to_string()) };
            let first = if name.is_some() { k + 1 } else { k };
            let (Some(&(n1, l1)), Some(&(n2, l2))) = (lines.get(first), lines.get(first + 1)) else {
                return Err(OrbitError::Line {
                    line: n,
                    reason: "an element set ends early: expected lines 1 and 2".into(),
                });
            };
            if !l1.starts_with("1 ") {
                return Err(OrbitError::Line {
                    line: n1,
                    reason: format!("expected a TLE line 1 (\"1 NNNNN...\"), found {l1:?}"),
                });
            }
            sets.push((n1, n2, name, l1, l2));
            k = first + 2;
        }
        let all_unnamed = sets.iter().all(|(_, _, name, _, _)| name.is_none());
        let mut satellites = Vec::new();
        for (line, line2, name, l1, l2) in &sets {
            let Some(system) = system_of(name.as_deref(), all_unnamed) else { continue };
            checksum_digit(*line, l1)?;
            checksum_digit(*line2, l2)?;
            let elements = sgp4::Elements::from_tle(name.clone(), l1.as_bytes(), l2.as_bytes())
                .map_err(|e| OrbitError::Line { line: *line, reason: e.to_string() })?;
            satellites.push(Satellite::new(At::Line(*line), name.as_deref(), system, elements)?);
        }
        Self::of(satellites, sets.len())
    }

    /// Days from the element sets' epochs to `unix_s`: the largest absolute difference (a
    /// warning is due when it is more than a few days).
    pub fn age_days(&self, unix_s: f64) -> f64 {
        self.satellites.iter().map(|s| ((unix_s - s.epoch_unix_s) / 86_400.0).abs()).fold(0.0, f64::max)
    }

    /// Earth-fixed positions of every satellite at `unix_s` (UTC); satellites SGP4 cannot
    /// propagate to that time (decayed orbits) are left out.
    pub fn positions(&self, unix_s: f64) -> Vec<SatellitePosition> {
        let theta = gmst_rad(unix_s);
        let (s, c) = theta.sin_cos();
        self.satellites
            .iter()
            .enumerate()
            .filter_map(|(index, sat)| {
                let minutes = (unix_s - sat.epoch_unix_s) / 60.0;
                let p = sat.constants.propagate(sgp4::MinutesSinceEpoch(minutes)).ok()?.position;
                // TEME -> Earth-fixed: a rotation about z by the sidereal angle, km -> m.
                let r = Vector3::new(c * p[0] + s * p[1], -s * p[0] + c * p[1], p[2]) * 1000.0;
                Some(SatellitePosition { index, ecef: Ecef { x_m: r.x, y_m: r.y, z_m: r.z } })
            })
            .collect()
    }

    /// The newest element set's epoch, UNIX seconds (UTC): the default t = 0 of a run.
    pub fn newest_epoch_unix_s(&self) -> f64 {
        self.satellites.iter().map(|s| s.epoch_unix_s).fold(f64::NEG_INFINITY, f64::max)
    }

    /// The element set of satellite `index` (for tools that propagate it themselves).
    pub fn elements(&self, index: usize) -> &sgp4::Elements {
        &self.satellites[index].elements
    }
}

/// Greenwich mean sidereal time at `unix_s`, radians (IAU 1982, UT1 taken as UTC: 0.9 s at
/// most, 0.004 degree of Earth rotation).
fn gmst_rad(unix_s: f64) -> f64 {
    // Julian years since 2000-01-01 12:00 UTC (UNIX 946 728 000).
    let years = (unix_s - 946_728_000.0) / (365.25 * 86_400.0);
    sgp4::iau_epoch_to_sidereal_time(years)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// GPS SVN 43 (PRN 13), Galileo's first satellite and the ISS, in 3LE form as the
    /// public catalogue of 2020-12-01 has them.
    pub(crate) const SAMPLE: &str = "\
0 NAVSTAR 43 (USA 132)
1 24876U 97035A   20334.96836884 +.00000096 +00000-0 +00000-0 0  9990
2 24876 055.4606 177.6943 0046391 058.6753 301.8606 02.00562032171136
0 GALILEO-PFM
1 37846U 11060A   20335.54226950 -.00000073  00000-0  00000+0 0  9992
2 37846  56.7287  36.7266 0002118 302.7747  57.2653  1.70475407 56731
0 ISS (ZARYA)
1 25544U 98067A   20336.23881537  .00004902  00000-0  96666-4 0  9993
2 25544  51.6479 241.8901 0001933  98.6369   4.7960 15.49124337257915
";

    #[test]
    fn navigation_satellites_are_kept_by_name_and_the_rest_skipped() {
        let c = Constellation::from_tle(SAMPLE).expect("parses");
        let kept: Vec<(&str, System)> = c.satellites.iter().map(|s| (s.name.as_str(), s.system)).collect();
        assert_eq!(kept, [("NAVSTAR 43 (USA 132)", System::Gps), ("GALILEO-PFM", System::Galileo)]);
        assert_eq!(c.satellites[0].norad_id, 24876);
    }

    #[test]
    fn a_gps_orbit_is_26_560_km_from_the_earth_centre() {
        let c = Constellation::from_tle(SAMPLE).expect("parses");
        let t = c.satellites[0].epoch_unix_s + 3600.0;
        let p = c.positions(t)[0].ecef;
        let r_km = (p.x_m * p.x_m + p.y_m * p.y_m + p.z_m * p.z_m).sqrt() / 1000.0;
        // a = (mu / n^2)^(1/3) for 2.0056 rev/day: 26 560 km, eccentricity 0.004.
        assert!((26_400.0..26_700.0).contains(&r_km), "{r_km}");
        assert!(c.age_days(t) < 1.0);
        // The oldest element set (PRN 13's) is 10 days and the hour older.
        assert!((c.age_days(t + 10.0 * 86_400.0) - (10.0 + 1.0 / 24.0)).abs() < 1e-6);
    }

    #[test]
    fn broken_files_name_the_line() {
        let bad_checksum = SAMPLE.replacen("0  9990", "0  9991", 1);
        let e = Constellation::from_tle(&bad_checksum).unwrap_err().to_string();
        assert!(e.starts_with("line 2: ") && e.to_lowercase().contains("checksum"), "{e}");
        let cut = &SAMPLE[..SAMPLE.find("0 GALILEO-PFM").unwrap() + 40];
        let e = Constellation::from_tle(cut).unwrap_err().to_string();
        assert!(e.contains("line 4") && e.contains("ends early"), "{e}");
        let iss = &SAMPLE[SAMPLE.find("0 ISS").unwrap()..];
        let e = Constellation::from_tle(iss).unwrap_err();
        assert_eq!(e, OrbitError::NoNavigationSatellites { objects: 1 });
        let e = Constellation::from_tle("<html>\n<body>not found</body>\n</html>\n").unwrap_err();
        assert_eq!(e, OrbitError::UnknownFormat { first: "<html>".into() });
        // A TLE-looking file whose name line is followed by something else.
        let e = Constellation::from_tle(&format!("GPS X\nnot a line\n{SAMPLE}")).unwrap_err().to_string();
        assert!(e.starts_with("line 2: expected a TLE line 1"), "{e}");
    }

    #[test]
    fn a_checksum_that_is_not_a_digit_is_refused() {
        // Found by fuzz/fuzz_targets/orbits.rs: the sgp4 crate subtracts b'0' from the
        // checksum column, which overflowed (a panic in a debug build) on `!` or a letter.
        for bad in ['!', 'x', '+'] {
            let tle = SAMPLE.replacen("0  9990", &format!("0  999{bad}"), 1);
            let e = Constellation::from_tle(&tle).unwrap_err().to_string();
            assert_eq!(e, format!("line 2: column 69 is the checksum, a digit 0-9; found {bad:?}"));
        }
    }
}
