//! Which urban wind field a run flies in (the decision is `sadesim_wind::request::
//! wind_request`, shared with the asset role) and the built-in field of the run's direction
//! (seconds for a city); the roles build OpenFOAM's and imported fields
//! (`sim_worker::wind_field`).

use sadesim_crds::SimulationRunSpec;
use sadesim_wind::UrbanWindField;
use sadesim_wind::request::{FieldModel, wind_request};
use sadesim_world::World;

/// Whether the run has wind among buildings under any urban model (built-in, OpenFOAM or
/// an imported case): then its shards need the field.
pub fn wants_urban_wind(spec: &SimulationRunSpec, world: &World) -> bool {
    wind_request(spec, world).is_some()
}

/// The run's built-in field with only the sectors of its wind direction computed (what a
/// run without an asset cache needs); `None` when the run does not want one, or wants
/// OpenFOAM's (`sim_worker::wind_field::build_field`: minutes and files, so the roles make
/// it). Seconds for a city (docs/performance.md).
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
