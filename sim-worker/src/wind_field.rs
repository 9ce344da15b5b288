//! The urban wind field computed at the edge, where files and processes are: the built-in
//! model over every sector, OpenFOAM run in case folders (`openfoam_run`), or an imported
//! OpenFOAM case read from its folder. Used by the asset role and the local runner.

pub mod openfoam_run;

use std::path::Path;

use sadesim_wind::UrbanWindField;
use sadesim_wind::foam_import::ImportSpec;
use sadesim_wind::request::{FieldModel, WindRequest};
use sadesim_world::World;

use openfoam_run::{OpenFoamRunError, compute_sector, import_case_dir};

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
