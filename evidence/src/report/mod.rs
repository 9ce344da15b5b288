//! The run report: `report.html` (self-contained: inline CSS and SVG, opens offline) and
//! `report/{map,altitude,gnss-timeline,gnss-map}.{svg,png}` (the GNSS ones for runs with a
//! constellation), rebuilt from the files of a run folder. It shows
//! what the paper's case study shows (§4, Fig. 4A the flight paths of every drone by
//! group with the SADE Zone, Fig. 4G the altitude timeline against the zone's 350 ft
//! minimum) plus the evidence behind the verdict: each criterion, every zone request and
//! its verdict, leases, violations with time, drone, place and duration, and the run's
//! metadata.
//!
//! `sadesim run` writes it at the end of every local run (before `manifest.json`, so the
//! manifest lists it); `sadesim report RUN_DIR` rebuilds it. The output is a function of
//! the folder's files only (no clock, no absolute path), so a rebuild of an unchanged
//! folder writes the same bytes and the manifest's checksums still hold.

use std::path::{Path, PathBuf};

use sadesim_crds::plan::RunPlan;
use sadesim_world::World;

pub mod data;
pub mod html;
pub mod model;
pub mod png;
pub mod preview;
pub mod svg;

#[cfg(test)]
mod tests;

pub use data::{DataError, RunData};

/// The page, next to the run's other files.
pub const HTML_FILE: &str = sadesim_crds::outcome::run_folder::REPORT;
/// The folder of the plots.
pub const IMAGES_DIR: &str = "report";

/// What [`write_report`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportFiles {
    pub html: PathBuf,
    pub images: Vec<PathBuf>,
}

/// The report's contents, before they are written.
#[derive(Clone, Debug)]
pub struct Report {
    pub html: String,
    pub map_svg: String,
    pub altitude_svg: String,
    /// Runs with a GNSS constellation: the GNSS timeline and the error map.
    pub gnss_timeline_svg: Option<String>,
    pub gnss_map_svg: Option<String>,
}

/// Building footprints for the map, only when `world` is the world the run had
/// (`world.json`'s statistics match). Otherwise none: a map without buildings is right, one
/// with another city's would not be.
fn buildings(data: &RunData, world: Option<&World>) -> Vec<svg::Footprint> {
    match (&data.world, world) {
        (Some(recorded), Some(world)) if world.stats() == recorded => footprints(world),
        _ => Vec::new(),
    }
}

/// The world's building footprints as the maps draw them.
pub fn footprints(world: &World) -> Vec<svg::Footprint> {
    world
        .buildings()
        .iter()
        .map(|b| {
            // The procedural city's boxes are their bounding rectangles; mapped buildings
            // are drawn as their polygons.
            let f = b.footprint();
            let [east_min_m, north_min_m, east_max_m, north_max_m] = f.bounds();
            let rings = f.axis_rect().is_none().then(|| f.rings().map(<[_]>::to_vec).collect());
            svg::Footprint { east_min_m, north_min_m, east_max_m, north_max_m, rings }
        })
        .collect()
}

/// Builds the report of already-read run data in the run's `world` (pure; `None`: a map
/// without buildings).
pub fn build(data: &RunData, world: Option<&World>) -> Report {
    let styles = model::group_styles(&data.plan);
    let zones = model::zone_shapes(&data.plan);
    let buildings = buildings(data, world);
    let map_svg = svg::map(data, &styles, &zones, &buildings);
    let altitude_svg = svg::altitude(data, &styles, &zones);
    let gnss_timeline_svg = svg::gnss(data, &styles);
    let gnss_map_svg = svg::gnss_map(data, &buildings);
    let figures = html::Figures {
        map: &map_svg,
        altitude: &altitude_svg,
        gnss_timeline: gnss_timeline_svg.as_deref(),
        gnss_map: gnss_map_svg.as_deref(),
    };
    let html = html::page(data, &styles, &zones, &figures);
    Report { html, map_svg, altitude_svg, gnss_timeline_svg, gnss_map_svg }
}

/// Why a run folder's report could not be written; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file of the folder is missing (`plan.json`) or malformed (file, line or field).
    #[error(transparent)]
    Data(#[from] DataError),
    #[error("{path}: cannot create: {source}")]
    Create {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// A plot could not be rasterised (a bug of the report's SVG, not of the run).
    #[error("{path}: {message}")]
    Render { path: String, message: String },
    /// Not attempted: the run's recording stopped on a write error (the folder's
    /// `incomplete.json` says which file); the space left goes to the manifest.
    #[error(
        "not attempted: the recording is incomplete ({reason}); once there is room, `sadesim report <run folder>` writes it"
    )]
    RecordingIncomplete { reason: String },
}

/// Builds the report of the run folder `run_dir` into the same folder: `report.html`,
/// `report/map.svg`, `report/altitude.svg`, `report/map.png`, `report/altitude.png`, and
/// with `gnss.csv` `report/gnss-timeline.{svg,png}` and `report/gnss-map.{svg,png}`.
///
/// The map draws the buildings of the run's world, which `find_world` looks up from the
/// folder's plan (`sadesim report` passes `sadesim_sources::assets::find_world`: the local
/// asset cache, else the plan's files); it is called only when the folder records a world
/// (`world.json`), and its world is drawn only when it is the one the run had.
/// [`write_report_in`] takes the world from a caller that has it.
///
/// # Errors
/// A message naming the file (and line or field) when a file of the folder is malformed
/// or `plan.json` is missing, or the file that could not be written.
pub fn write_report(
    run_dir: &Path,
    find_world: impl FnOnce(&RunPlan) -> Option<World>,
) -> Result<ReportFiles, ReportError> {
    let data = RunData::read(run_dir)?;
    // Without `world.json` no world is drawn: nothing to look up.
    let world = if data.world.is_some() { find_world(&data.plan) } else { None };
    write_files(run_dir, &build(&data, world.as_ref()))
}

/// [`write_report`] with the run's world when the caller has it (the runner and the
/// coordinator flew in it); `None` draws the map without buildings.
///
/// # Errors
/// As [`write_report`].
pub fn write_report_in(run_dir: &Path, world: Option<&World>) -> Result<ReportFiles, ReportError> {
    let data = RunData::read(run_dir)?;
    write_files(run_dir, &build(&data, world))
}

/// Writes `report` into the run folder `run_dir`: the plots, then the page.
fn write_files(run_dir: &Path, report: &Report) -> Result<ReportFiles, ReportError> {
    let images_dir = run_dir.join(IMAGES_DIR);
    std::fs::create_dir_all(&images_dir)
        .map_err(|source| ReportError::Create { path: images_dir.display().to_string(), source })?;
    let write = |path: PathBuf, bytes: &[u8]| -> Result<PathBuf, ReportError> {
        std::fs::write(&path, bytes)
            .map_err(|source| ReportError::Write { path: path.display().to_string(), source })?;
        Ok(path)
    };
    let mut images = Vec::new();
    let gnss = [("gnss-timeline", &report.gnss_timeline_svg), ("gnss-map", &report.gnss_map_svg)];
    let plots = [("map", &report.map_svg), ("altitude", &report.altitude_svg)]
        .into_iter()
        .chain(gnss.into_iter().filter_map(|(name, svg)| svg.as_ref().map(|svg| (name, svg))));
    for (name, svg) in plots {
        images.push(write(images_dir.join(format!("{name}.svg")), svg.as_bytes())?);
        let path = images_dir.join(format!("{name}.png"));
        let png =
            png::render(svg).map_err(|message| ReportError::Render { path: path.display().to_string(), message })?;
        images.push(write(images_dir.join(format!("{name}.png")), &png)?);
    }
    // The page last: a folder with report.html has its plots too.
    let html = write(run_dir.join(HTML_FILE), report.html.as_bytes())?;
    Ok(ReportFiles { html, images })
}
