//! Which urban wind field a run flies in (the decision is `sadesim_sources::wind::
//! wind_request`, shared with the asset role), and the field's computation: the built-in
//! model, OpenFOAM, or an imported OpenFOAM case.

use std::path::Path;

use sadesim_crds::SimulationRunSpec;
use sadesim_sources::wind::{FieldModel, WindRequest, wind_request};
use sadesim_wind::UrbanWindField;
use sadesim_wind::foam_import::ImportSpec;
use sadesim_world::World;

use super::openfoam_run::{OpenFoamRunError, compute_sector, import_case_dir};

/// Builds the field of `request` over `world`: the sectors of
/// [`WindRequest::sectors_built`] (every sector for the built-in model, the run direction's
/// for OpenFOAM, run in case folders under `scratch`); an imported case becomes the one
/// sector of its direction (degrees, rounded) in a 360-sector field. `progress(done,
/// total)` after each sector.
///
/// # Errors
/// OpenFOAM is not installed or fails (naming the program and its log), or a case does not
/// read or does not cover the grid (naming the file).
pub fn build_field(
    world: &World,
    request: &WindRequest,
    scratch: &Path,
    mut progress: impl FnMut(u32, u32),
) -> Result<UrbanWindField, OpenFoamRunError> {
    let mut field = UrbanWindField::new(world, request.grid, request.sectors);
    match &request.model {
        FieldModel::Diagnostic => field.ensure_all(world, progress),
        FieldModel::OpenFoam => {
            let sectors = request.sectors_built();
            for (done, &k) in sectors.iter().enumerate() {
                let direction = f64::from(k) * field.sector_step_deg();
                let case_dir = scratch.join(format!("openfoam-sector-{k}"));
                let _ = std::fs::remove_dir_all(&case_dir);
                let sector = compute_sector(world, &field.grid, direction, &case_dir, |_| {})?;
                field.sectors.push((k, sector));
                progress(done as u32 + 1, sectors.len() as u32);
            }
        }
        FieldModel::Imported(case) => {
            field.sector_count = 360;
            let k = (case.direction_from_deg.round() as u32) % 360;
            let spec = ImportSpec { direction_from_deg: f64::from(k), reference_speed_ms: case.reference_speed_mps };
            let sector = import_case_dir(&field.grid, Path::new(&case.dir), spec)?;
            field.sectors.push((k, sector));
            progress(1, 1);
        }
    }
    Ok(field)
}

/// Whether the run has wind among buildings under any urban model (built-in, OpenFOAM or
/// an imported case): then its shards need the field.
pub fn wants_urban_wind(spec: &SimulationRunSpec, world: &World) -> bool {
    wind_request(spec, world).is_some()
}

/// The run's built-in field with only the sectors of its wind direction computed (what a
/// run without an asset cache needs); `None` when the run does not want one, or wants
/// OpenFOAM's ([`build_field`]: minutes and files, so the roles make it). Seconds for a city
/// (docs/performance.md).
pub fn urban_wind_field(spec: &SimulationRunSpec, world: &World) -> Option<UrbanWindField> {
    let request = wind_request(spec, world).filter(|r| r.model == FieldModel::Diagnostic)?;
    let mut field = UrbanWindField::new(world, request.grid, request.sectors);
    for (k, _) in field.sectors_for(request.direction_from_deg) {
        field.ensure_sector(world, k);
    }
    Some(field)
}

/// One line for logs: the field's grid, its sectors, their mass-conservation residual and
/// solver iterations, and how long it took.
pub fn describe_urban_wind(field: &UrbanWindField, seconds: f64) -> String {
    let [nx, ny, nz] = field.grid.dims;
    let sectors: Vec<String> = field.sectors.iter().map(|(_, s)| format!("{:.0}°", s.direction_from_deg)).collect();
    let residual = field.sectors.iter().map(|(_, s)| s.residual).fold(0.0, f64::max);
    let iterations = field.sectors.iter().map(|(_, s)| s.iterations);
    let (fewest, most) = (iterations.clone().min().unwrap_or(0), iterations.max().unwrap_or(0));
    let iterations = if fewest == most { format!("{most}") } else { format!("{fewest}-{most}") };
    format!(
        "urban wind: {nx}x{ny}x{nz} cells of {} m ({} cells), sectors {} (mass residual {residual:.1e}, {iterations} CG iterations) in {seconds:.1} s",
        field.grid.spacing_m,
        field.grid.cells(),
        sectors.join(", ")
    )
}
