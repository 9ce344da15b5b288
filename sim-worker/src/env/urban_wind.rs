//! Which urban wind field a run flies in: a pure decision on the spec and the world, and
//! the field's computation (the sectors the run's wind direction blends).

use sadesim_crds::SimulationRunSpec;
use sadesim_crds::environment::UrbanWindModel;
use sadesim_wind::{DEFAULT_SECTORS, GridSpec, UrbanWindField};
use sadesim_world::World;

/// Whether the run has wind among buildings under the diagnostic model (the default): then
/// its shards need the field.
pub fn wants_urban_wind(spec: &SimulationRunSpec, world: &World) -> bool {
    let Some(wind) = spec.environment().wind else { return false };
    // `openfoam` is refused by validation before any run.
    let model = wind.urban.as_ref().map_or(UrbanWindModel::Diagnostic, |u| u.model);
    model == UrbanWindModel::Diagnostic && !world.buildings().is_empty()
}

/// The run's field with the sectors of its wind direction computed; `None` when the run
/// does not want one ([`wants_urban_wind`]). Seconds for a city (docs/performance.md).
pub fn urban_wind_field(spec: &SimulationRunSpec, world: &World) -> Option<UrbanWindField> {
    if !wants_urban_wind(spec, world) {
        return None;
    }
    let wind = spec.environment().wind?;
    let urban = wind.urban.as_ref();
    let mut grid = GridSpec::default_for(world.extent_m());
    if let Some(spacing_m) = urban.and_then(|u| u.spacing_m) {
        grid.spacing_m = spacing_m;
    }
    let sectors = urban.and_then(|u| u.sectors).unwrap_or(DEFAULT_SECTORS);
    let mut field = UrbanWindField::new(world, grid, sectors);
    for (k, _) in field.sectors_for(wind.direction_from_deg) {
        field.ensure_sector(world, k);
    }
    Some(field)
}

/// One line for logs: the field's grid, its sectors, their mass-conservation residual and
/// how long it took.
pub fn describe_urban_wind(field: &UrbanWindField, seconds: f64) -> String {
    let [nx, ny, nz] = field.grid.dims;
    let sectors: Vec<String> = field.sectors.iter().map(|(_, s)| format!("{:.0}°", s.direction_from_deg)).collect();
    let residual = field.sectors.iter().map(|(_, s)| s.residual).fold(0.0, f64::max);
    format!(
        "urban wind: {nx}x{ny}x{nz} cells of {} m, sectors {} (mass residual {residual:.1e}) in {seconds:.1} s",
        field.grid.spacing_m,
        sectors.join(", ")
    )
}
