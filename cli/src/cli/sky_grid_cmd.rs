//! `sadesim gnss grid SCENARIO --out DIR`: the sky grid of a scenario (crate `sadesim-gnss`,
//! module `grid`) written as a Zarr v2 group that Python's `zarr` (and xarray) reads:
//!
//! ```text
//! DIR/.zgroup, DIR/.zattrs          group; attributes say where the voxels are and when
//! DIR/line_of_sight/                uint8  [slice, up, north, east]
//! DIR/reflected/                    uint8  [slice, up, north, east]
//! DIR/hdop/                         float32 [slice, up, north, east], NaN: unusable
//! DIR/solid/                        uint8  [up, north, east], 1 inside a building or the ground
//! ```
//!
//! One uncompressed chunk per slice (the whole 3-D grid), little-endian, C order; every
//! array's `.zattrs` names its dimensions (`_ARRAY_DIMENSIONS`, xarray's convention).

use std::io::{IsTerminal, Write};
use std::path::Path;

use indicatif::ProgressBar;
use sadesim_gnss::grid::{GridSpec, SkyGrid};
use serde_json::json;

use super::{CliError, Outcome};

pub(super) fn grid(
    scenario: &Path,
    out_dir: &Path,
    spacing_m: f64,
    slice_s: f64,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let Some(run) = super::gnss_cmd::valid_scenario(scenario, out)? else { return Ok(Outcome::Problems) };
    if !(spacing_m.is_finite() && (1.0..=500.0).contains(&spacing_m)) {
        return Err(CliError::Failed(format!("--spacing-m {spacing_m}: expected 1..500 metres")));
    }
    if !(slice_s.is_finite() && slice_s >= 1.0) {
        return Err(CliError::Failed(format!("--slice-s {slice_s}: expected at least 1 second")));
    }
    let (sky, world) = super::gnss_cmd::sky_and_world(&run, scenario)?;
    let stats = world.stats();
    // Above the tallest roof (and the highest ground) every voxel of a layer sees the same
    // sky: one layer more is enough to show it.
    let top_m = stats.max_height_m.max(0.0) + (stats.ground_max_up_m - stats.ground_min_up_m) + spacing_m;
    let slices = (run.spec.duration_s() / slice_s).floor() as usize + 1;
    let spec = GridSpec { spacing_m, slice_s, slices, top_m };
    let bar = if std::io::stderr().is_terminal() { ProgressBar::new(0) } else { ProgressBar::hidden() };
    let started = std::time::Instant::now();
    let grid = sadesim_gnss::grid::compute(&world, &sky, spec, |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let bytes = write_zarr(out_dir, &grid, &run, sky.epoch_unix_s(), sky.mask_deg())
        .map_err(|e| CliError::Failed(format!("--out {}: {e}", out_dir.display())))?;
    let [nx, ny, nz] = grid.dims;
    writeln!(
        out,
        "{}: {nx} x {ny} x {nz} voxels of {spacing_m} m, {slices} slice(s) every {slice_s} s, computed in {seconds:.1} s, {bytes} bytes",
        out_dir.display()
    )?;
    Ok(Outcome::Success)
}

/// Writes the group; returns the bytes written.
fn write_zarr(
    dir: &Path,
    grid: &SkyGrid,
    run: &sadesim_crds::SimulationRun,
    epoch_unix_s: f64,
    mask_deg: f64,
) -> std::io::Result<u64> {
    use sadesim_sources::zarr::{ArrayOut, Compression, group_files, write_group};
    let [nx, ny, nz] = grid.dims;
    let slices = grid.spec.slices;
    let o = &run.spec.origin;
    let attrs = json!({
        "description": "SADE-SIM sky grid: per voxel and time slice, the GNSS satellites above the mask in line of sight and received only by a facade reflection, and the HDOP of those strong enough to use",
        "run": run.metadata.name,
        "origin": {"latitudeDeg": o.latitude_deg, "longitudeDeg": o.longitude_deg, "altitudeMslM": o.altitude_msl_m},
        "frame": "run ENU: metres east, north, up from the origin",
        "voxelCornerEnuM": grid.origin_m,
        "spacingM": grid.spec.spacing_m,
        "sliceS": grid.spec.slice_s,
        "epochUnixS": epoch_unix_s,
        "elevationMaskDeg": mask_deg,
    });
    let dims4 = ["slice", "up", "north", "east"];
    let shape = vec![slices, nz, ny, nx];
    let arrays = [
        ArrayOut::u8("line_of_sight", &dims4, shape.clone(), grid.line_of_sight.clone()).per_slice(),
        ArrayOut::u8("reflected", &dims4, shape.clone(), grid.reflected.clone()).per_slice(),
        ArrayOut::f32("hdop", &dims4, shape, &grid.hdop).per_slice(),
        ArrayOut::u8("solid", &["up", "north", "east"], vec![nz, ny, nx], grid.solid.clone()),
    ];
    std::fs::create_dir_all(dir)?;
    write_group(dir, &group_files(&attrs, &arrays, Compression::Raw))
}
