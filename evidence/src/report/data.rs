//! Reading a run folder for the report: `plan.json` (required), `trajectory.csv`,
//! `events.jsonl`, `airspace.json`, `summary.json`, `world.json` and `pilot.json`
//! (each optional: a missing one becomes a "not recorded" note in the report).
//!
//! # Errors
//! A file that exists but cannot be read as its writer wrote it fails the whole report,
//! with the file and the line (CSV, JSON lines) or the field path and line (JSON) named:
//! a report silently built from half a file would be wrong evidence.

use std::path::{Path, PathBuf};

use sadesim_crds::outcome::compliance::{ComplianceReport, Presence, ViolationRecord};
use sadesim_crds::outcome::compliance::{Lease, RequestRecord};
use sadesim_crds::outcome::events::{Event, Place};
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::plan::RunPlan;
use sadesim_world::WorldStats;
use serde::Deserialize;
use serde::de::DeserializeOwned;

use sadesim_crds::outcome::pilot::PilotRecord;

/// Why a run folder could not be read. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A required file is missing or unreadable.
    #[error("{path}: failed to read: {source}")]
    Read { path: String, source: std::io::Error },
    /// A JSON document does not have the expected shape (`field` is the path inside it).
    #[error("{path}: field `{field}`: {message}")]
    Json { path: String, field: String, message: String },
    /// A line of a line-oriented file (CSV, JSON lines) is malformed (1-based line).
    #[error("{path}: line {line}: {message}")]
    Line { path: String, line: usize, message: String },
}

/// One trajectory sample of one drone (a row of `trajectory.csv`). Positions are metres in
/// the run's local east-north-up frame (origin: `spec.origin`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub time_s: f64,
    pub east_m: f64,
    pub north_m: f64,
    pub up_m: f64,
    pub height_agl_m: f64,
    pub on_ground: bool,
    pub crashed: bool,
}

/// One row of `gnss.csv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssSample {
    pub time_s: f64,
    pub drone: u32,
    pub satellites: u32,
    /// Horizontal dilution of precision of the satellites in the fix (`None`: no fix).
    pub hdop: Option<f64>,
    /// Horizontal distance of the estimate from the truth, m (`None`: no estimate).
    pub estimate_error_m: Option<f64>,
    /// Horizontal distance of the 3D fix from the truth, m (`None`: no 3D fix).
    pub fix_error_m: Option<f64>,
}

/// All samples of one drone, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct Track {
    pub drone: u32,
    pub name: String,
    pub group: String,
    pub samples: Vec<Sample>,
}

/// `airspace.json` as the runner writes it (`AirspaceRecord`: requests, leases and the
/// compliance report's fields side by side).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AirspaceFile {
    pub requests: Vec<RequestRecord>,
    pub leases: Vec<Lease>,
    pub compliance: ComplianceReport,
}

/// The file's fields spelled out rather than `#[serde(flatten)]`: flattening buffers the
/// document, and errors would lose their field path and line.
#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct AirspaceFields {
    #[serde(default)]
    requests: Vec<RequestRecord>,
    #[serde(default)]
    leases: Vec<Lease>,
    #[serde(default)]
    violations: Vec<ViolationRecord>,
    #[serde(default)]
    presences: Vec<Presence>,
    #[serde(default)]
    crashes: Vec<(u32, f64)>,
    #[serde(default)]
    crash_places: Vec<Place>,
    #[serde(default)]
    closest_approach: Option<(f64, f64, u32, u32)>,
    #[serde(default)]
    worst_position_errors: Vec<Option<sadesim_crds::outcome::compliance::PositionError>>,
    #[serde(default)]
    touchdowns: Vec<Option<sadesim_crds::outcome::compliance::Touchdown>>,
}

impl<'de> Deserialize<'de> for AirspaceFile {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let f = AirspaceFields::deserialize(d)?;
        Ok(Self {
            requests: f.requests,
            leases: f.leases,
            compliance: ComplianceReport {
                violations: f.violations,
                presences: f.presences,
                crashes: f.crashes,
                crash_places: f.crash_places,
                closest_approach: f.closest_approach,
                worst_position_errors: f.worst_position_errors,
                touchdowns: f.touchdowns,
            },
        })
    }
}

/// Everything the report shows, read from one run folder.
#[derive(Clone, Debug)]
pub struct RunData {
    pub dir: PathBuf,
    pub plan: RunPlan,
    /// One per drone of the plan that has at least one sample, by drone index.
    pub tracks: Option<Vec<Track>>,
    pub events: Option<Vec<Event>>,
    pub airspace: Option<AirspaceFile>,
    pub summary: Option<RunSummary>,
    pub world: Option<WorldStats>,
    /// `pilot.json`: what happened to the pilot process.
    pub pilot: Option<PilotRecord>,
    /// `gnss.csv` (runs with a GNSS constellation): each drone's receiver in flight once a
    /// second.
    pub gnss: Option<Vec<GnssSample>>,
    /// Files of the run folder the report would use but that are not there, e.g.
    /// "airspace.json: not recorded".
    pub notes: Vec<String>,
}

/// File names, as the recorder and the runner write them.
pub const PLAN_FILE: &str = sadesim_crds::outcome::run_folder::PLAN;
pub const TRAJECTORY_FILE: &str = "trajectory.csv";
pub const EVENTS_FILE: &str = sadesim_crds::outcome::run_folder::EVENTS;
pub const AIRSPACE_FILE: &str = sadesim_crds::outcome::run_folder::AIRSPACE;
pub const SUMMARY_FILE: &str = sadesim_crds::outcome::run_folder::SUMMARY;
pub const WORLD_FILE: &str = "world.json";
pub const PILOT_FILE: &str = sadesim_crds::outcome::run_folder::PILOT_RECORD;

impl RunData {
    /// Reads the run folder `dir`.
    ///
    /// # Errors
    /// `plan.json` missing or unreadable, or any present file malformed (see [`DataError`]).
    pub fn read(dir: &Path) -> Result<Self, DataError> {
        let plan: RunPlan = parse_json(&dir.join(PLAN_FILE), &read_required(&dir.join(PLAN_FILE))?)?;
        let mut notes = Vec::new();
        let mut optional = |name: &str, why: &str| -> Result<Option<(PathBuf, String)>, DataError> {
            let path = dir.join(name);
            match std::fs::read_to_string(&path) {
                Ok(text) => Ok(Some((path, text))),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    notes.push(format!("{name}: not recorded ({why})"));
                    Ok(None)
                }
                Err(source) => Err(DataError::Read { path: path.display().to_string(), source }),
            }
        };
        let tracks = optional(TRAJECTORY_FILE, "no map and no altitude timeline")?
            .map(|(p, t)| parse_trajectory(&p, &t))
            .transpose()?;
        let events = optional(EVENTS_FILE, "no event times")?.map(|(p, t)| parse_events(&p, &t)).transpose()?;
        let airspace = optional(AIRSPACE_FILE, "no zone requests, leases or violations")?
            .map(|(p, t)| parse_json::<AirspaceFile>(&p, &t))
            .transpose()?;
        let summary = optional(SUMMARY_FILE, "the run did not finish: no totals and no criteria verdict")?
            .map(|(p, t)| parse_json::<RunSummary>(&p, &t))
            .transpose()?;
        let world = optional(WORLD_FILE, "no world statistics and no buildings on the map")?
            .map(|(p, t)| parse_json::<WorldStats>(&p, &t))
            .transpose()?;
        let pilot = if plan.spec.pilot.is_some() {
            optional(PILOT_FILE, "no record of the pilot process")?
                .map(|(p, t)| parse_json::<PilotRecord>(&p, &t))
                .transpose()?
        } else {
            None
        };
        // Only runs with a constellation write it: its absence is no gap worth a note.
        let gnss_path = dir.join(sadesim_crds::outcome::run_folder::GNSS);
        let gnss = match std::fs::read_to_string(&gnss_path) {
            Ok(text) => Some(parse_gnss(&gnss_path, &text)?),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(source) => return Err(DataError::Read { path: gnss_path.display().to_string(), source }),
        };
        // Absolute, so that the page names the folder (`<run>/<UTC time>`) even when it
        // was given as `.`.
        let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
        Ok(Self { dir, plan, tracks, events, airspace, summary, world, pilot, gnss, notes })
    }

    /// The track of drone `index`, when recorded.
    pub fn track(&self, index: u32) -> Option<&Track> {
        self.tracks.as_deref().and_then(|t| t.iter().find(|t| t.drone == index))
    }
}

fn read_required(path: &Path) -> Result<String, DataError> {
    std::fs::read_to_string(path).map_err(|source| DataError::Read { path: path.display().to_string(), source })
}

/// Parses a JSON document, naming the field path and the line of the first mismatch.
pub fn parse_json<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T, DataError> {
    let mut de = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let field = e.path().to_string();
        DataError::Json { path: path.display().to_string(), field, message: e.into_inner().to_string() }
    })
}

/// Parses `events.jsonl`: one [`Event`] per non-empty line.
pub fn parse_events(path: &Path, text: &str) -> Result<Vec<Event>, DataError> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l).map_err(|e| DataError::Line {
                path: path.display().to_string(),
                line: i + 1,
                message: format!("not an event: {e}"),
            })
        })
        .collect()
}

/// Columns of `trajectory.csv` the report needs, found by name in the header so that
/// added columns do not break it.
struct Columns {
    time_s: usize,
    drone: usize,
    name: usize,
    group: usize,
    east_m: usize,
    north_m: usize,
    up_m: usize,
    height_agl_m: usize,
    on_ground: Option<usize>,
    crashed: Option<usize>,
}

impl Columns {
    fn from_header(path: &Path, header: &str) -> Result<Self, DataError> {
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let find = |name: &str| names.iter().position(|n| *n == name);
        let need = |name: &str| {
            find(name).ok_or_else(|| DataError::Line {
                path: path.display().to_string(),
                line: 1,
                message: format!("header has no `{name}` column (expected the recorder's header: {header:?})"),
            })
        };
        Ok(Self {
            time_s: need("time_s")?,
            drone: need("drone")?,
            name: need("name")?,
            group: need("group")?,
            east_m: need("east_m")?,
            north_m: need("north_m")?,
            up_m: need("up_m")?,
            height_agl_m: need("height_agl_m")?,
            on_ground: find("on_ground"),
            crashed: find("crashed"),
        })
    }
}

/// Parses `gnss.csv` (its header, then `time_s,drone,fix_type,satellites,hdop,fix_error_m,
/// estimate_error_m` rows; empty optional cells).
pub fn parse_gnss(path: &Path, text: &str) -> Result<Vec<GnssSample>, DataError> {
    const HEADER: &str = "time_s,drone,fix_type,satellites,hdop,fix_error_m,estimate_error_m";
    let mut lines = text.lines().enumerate();
    let bad = |line: usize, message: String| DataError::Line { path: path.display().to_string(), line, message };
    if lines.next().map(|(_, h)| h.trim()) != Some(HEADER) {
        return Err(bad(1, format!("expected the header {HEADER}")));
    }
    let mut out = Vec::new();
    for (i, line) in lines.filter(|(_, l)| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 7 {
            return Err(bad(i + 1, format!("{} fields, expected 7", f.len())));
        }
        let number = |k: usize| -> Result<Option<f64>, DataError> {
            match f[k] {
                "" => Ok(None),
                raw => raw
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .map(Some)
                    .ok_or_else(|| bad(i + 1, format!("column {}: expected a finite number, got {raw:?}", k + 1))),
            }
        };
        let int = |k: usize| -> Result<u32, DataError> {
            f[k].parse().map_err(|_| bad(i + 1, format!("column {}: expected a count, got {:?}", k + 1, f[k])))
        };
        out.push(GnssSample {
            time_s: number(0)?.ok_or_else(|| bad(i + 1, "column 1: time_s is empty".into()))?,
            drone: int(1)?,
            satellites: int(3)?,
            hdop: number(4)?,
            fix_error_m: number(5)?,
            estimate_error_m: number(6)?,
        });
    }
    Ok(out)
}

/// Parses `trajectory.csv` (header line, then one row per drone per sample) into one
/// track per drone, sorted by drone index.
pub fn parse_trajectory(path: &Path, text: &str) -> Result<Vec<Track>, DataError> {
    let mut lines = text.lines().enumerate();
    let Some((_, header)) = lines.next() else {
        return Err(DataError::Line {
            path: path.display().to_string(),
            line: 1,
            message: "empty file: no header".into(),
        });
    };
    let cols = Columns::from_header(path, header)?;
    let width = header.split(',').count();
    let mut tracks: Vec<Track> = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |message: String| DataError::Line { path: path.display().to_string(), line: i + 1, message };
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != width {
            return Err(bad(format!("{} fields, the header has {width}", fields.len())));
        }
        let number = |col: usize, name: &str| -> Result<f64, DataError> {
            let raw = fields[col].trim();
            raw.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("column `{name}`: expected a finite number, got {raw:?}")))
        };
        let flag = |col: Option<usize>, name: &str| -> Result<bool, DataError> {
            match col.map(|c| fields[c].trim()) {
                None => Ok(false),
                Some("true") => Ok(true),
                Some("false") => Ok(false),
                Some(raw) => Err(bad(format!("column `{name}`: expected true or false, got {raw:?}"))),
            }
        };
        let raw_drone = fields[cols.drone].trim();
        let drone: u32 = raw_drone
            .parse()
            .map_err(|_| bad(format!("column `drone`: expected a drone index (0, 1, ...), got {raw_drone:?}")))?;
        let sample = Sample {
            time_s: number(cols.time_s, "time_s")?,
            east_m: number(cols.east_m, "east_m")?,
            north_m: number(cols.north_m, "north_m")?,
            up_m: number(cols.up_m, "up_m")?,
            height_agl_m: number(cols.height_agl_m, "height_agl_m")?,
            on_ground: flag(cols.on_ground, "on_ground")?,
            crashed: flag(cols.crashed, "crashed")?,
        };
        let track = match tracks.iter().position(|t| t.drone == drone) {
            Some(k) => &mut tracks[k],
            None => {
                tracks.push(Track {
                    drone,
                    name: fields[cols.name].trim().to_string(),
                    group: fields[cols.group].trim().to_string(),
                    samples: Vec::new(),
                });
                tracks.last_mut().expect("just pushed")
            }
        };
        if track.samples.last().is_some_and(|s| s.time_s > sample.time_s) {
            return Err(bad(format!("time_s {} is before drone {drone}'s previous sample", sample.time_s)));
        }
        track.samples.push(sample);
    }
    tracks.sort_by_key(|t| t.drone);
    Ok(tracks)
}

#[cfg(test)]
mod gnss_tests {
    use super::*;

    #[test]
    fn gnss_rows_parse_with_empty_cells_and_bad_ones_name_the_line() {
        let path = Path::new("gnss.csv");
        let text = "time_s,drone,fix_type,satellites,hdop,fix_error_m,estimate_error_m\n\
                    1.000,0,3,12,0.80,1.25,0.90\n2.000,0,1,2,,,1.40\n";
        let rows = parse_gnss(path, text).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!((rows[0].drone, rows[0].satellites, rows[0].fix_error_m), (0, 12, Some(1.25)));
        assert_eq!((rows[1].fix_error_m, rows[1].estimate_error_m), (None, Some(1.4)));
        assert_eq!((rows[0].hdop, rows[1].hdop), (Some(0.8), None));
        let e = parse_gnss(path, &text.replace("1.40", "x")).unwrap_err().to_string();
        assert!(e.contains("gnss.csv") && e.contains('3') && e.contains("\"x\""), "{e}");
        assert!(parse_gnss(path, "a,b\n").is_err());
    }
}
