//! Which urban wind field a run needs: the grid, the sectors, the direction and the model,
//! decided from the scenario and the world. The asset role, the local runner and the
//! shards decide the same way because they call the same function.

use sadesim_crds::SimulationRunSpec;
use sadesim_crds::environment::UrbanWindModel;
use sadesim_world::World;

use crate::{DEFAULT_SECTORS, GridSpec};

/// How the field is made.
#[derive(Clone, Debug, PartialEq)]
pub enum FieldModel {
    /// The built-in model, every sector (cheap: seconds for a city).
    Diagnostic,
    /// OpenFOAM over the world's buildings, the sectors of the run's direction only
    /// (minutes per sector).
    OpenFoam,
    /// A case computed elsewhere, read from its folder by every role that needs it (not
    /// cached: reading it takes seconds, and its files are the user's).
    Imported(sadesim_crds::environment::OpenFoamCase),
}

impl FieldModel {
    /// The `model` attribute of the stored group.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Diagnostic => "diagnostic",
            Self::OpenFoam => "openfoam",
            Self::Imported(_) => "openfoam-imported",
        }
    }
}

/// What field a run needs: the grid, the sectors around the compass, the direction its
/// wind blows from (whose one or two sectors a run without a cache computes) and the model.
#[derive(Clone, Debug, PartialEq)]
pub struct WindRequest {
    pub grid: GridSpec,
    pub sectors: u32,
    pub direction_from_deg: f64,
    pub model: FieldModel,
}

impl WindRequest {
    /// The sectors the field holds once built: all of them for the diagnostic model, the
    /// run direction's for OpenFOAM (an imported case is its own single sector).
    pub fn sectors_built(&self) -> Vec<u32> {
        match self.model {
            FieldModel::Diagnostic => (0..self.sectors).collect(),
            _ => crate::field::SectorBlend::of(self.sectors, self.direction_from_deg)
                .into_iter()
                .map(|(k, _)| k)
                .collect(),
        }
    }
}

/// The field `spec` needs in `world`: `None` without wind, with `environment.wind.urban.
/// model: none`, or without buildings (unless a case is imported). The grid is
/// [`GridSpec::default_for`] the world unless `spacingM` is given.
pub fn wind_request(spec: &SimulationRunSpec, world: &World) -> Option<WindRequest> {
    let wind = spec.environment().wind?;
    let urban = wind.urban.as_ref();
    let model = match (urban.map_or(UrbanWindModel::Diagnostic, |u| u.model), urban.and_then(|u| u.case.clone())) {
        (UrbanWindModel::None, _) => return None,
        (UrbanWindModel::OpenFoam, Some(case)) => FieldModel::Imported(case),
        (UrbanWindModel::OpenFoam, None) => FieldModel::OpenFoam,
        (UrbanWindModel::Diagnostic, _) => FieldModel::Diagnostic,
    };
    if world.buildings().is_empty() && !matches!(model, FieldModel::Imported(_)) {
        return None;
    }
    let mut grid = GridSpec::default_for(world.extent_m());
    if let Some(spacing_m) = urban.and_then(|u| u.spacing_m) {
        grid.spacing_m = spacing_m;
    }
    let sectors = urban.and_then(|u| u.sectors).unwrap_or(DEFAULT_SECTORS);
    Some(WindRequest { grid, sectors, direction_from_deg: wind.direction_from_deg, model })
}
