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
    let [nx, ny, nz] = grid.dims;
    let slices = grid.spec.slices;
    std::fs::create_dir_all(dir)?;
    let mut written = 0u64;
    let mut put = |path: &Path, bytes: &[u8]| -> std::io::Result<()> {
        std::fs::write(path, bytes)?;
        written += bytes.len() as u64;
        Ok(())
    };
    put(&dir.join(".zgroup"), json!({"zarr_format": 2}).to_string().as_bytes())?;
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
    put(&dir.join(".zattrs"), attrs.to_string().as_bytes())?;
    let dims4 = json!(["slice", "up", "north", "east"]);
    let mut array = |name: &str,
                     dtype: &str,
                     fill: serde_json::Value,
                     shape: Vec<usize>,
                     dims: &serde_json::Value,
                     chunks: Vec<Vec<u8>>|
     -> std::io::Result<()> {
        let folder = dir.join(name);
        std::fs::create_dir_all(&folder)?;
        let mut chunk_shape = shape.clone();
        chunk_shape[0] = if shape.len() == 4 { 1 } else { shape[0] };
        let meta = json!({"zarr_format": 2, "shape": shape, "chunks": chunk_shape, "dtype": dtype,
                          "compressor": null, "fill_value": fill, "filters": null, "order": "C"});
        put(&folder.join(".zarray"), meta.to_string().as_bytes())?;
        put(&folder.join(".zattrs"), json!({"_ARRAY_DIMENSIONS": dims}).to_string().as_bytes())?;
        let zeros = if shape.len() == 4 { ".0.0.0" } else { ".0.0" };
        for (s, chunk) in chunks.iter().enumerate() {
            put(&folder.join(format!("{s}{zeros}")), chunk)?;
        }
        Ok(())
    };
    let per_slice = nx * ny * nz;
    let u8_slices = |v: &[u8]| v.chunks(per_slice).map(<[u8]>::to_vec).collect::<Vec<_>>();
    let shape = vec![slices, nz, ny, nx];
    array("line_of_sight", "|u1", json!(0), shape.clone(), &dims4, u8_slices(&grid.line_of_sight))?;
    array("reflected", "|u1", json!(0), shape.clone(), &dims4, u8_slices(&grid.reflected))?;
    let hdop: Vec<Vec<u8>> =
        grid.hdop.chunks(per_slice).map(|c| c.iter().flat_map(|h| h.to_le_bytes()).collect()).collect();
    array("hdop", "<f4", json!("NaN"), shape, &dims4, hdop)?;
    array("solid", "|u1", json!(0), vec![nz, ny, nx], &json!(["up", "north", "east"]), vec![grid.solid.clone()])?;
    Ok(written)
}
