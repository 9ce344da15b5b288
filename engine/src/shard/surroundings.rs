//! What a shard flies in besides its plan: the world and what the run derives from it.

use std::sync::Arc;

use sadesim_crds::plan::RunPlan;
use sadesim_gnss::RunSky;
use sadesim_wind::UrbanWindField;
use sadesim_world::World;

use crate::env::urban_wind_field;

/// The world, the GNSS sky of a run with a constellation and the urban wind field of a run
/// with wind among buildings. Made once per process and shared by its shards.
#[derive(Clone, Debug)]
pub struct Surroundings {
    pub world: Arc<World>,
    /// `sim_worker::roles::sky`: read from the run's orbit file (I/O, so the caller loads it).
    pub sky: Option<Arc<RunSky>>,
    /// Computed here from the world and the spec (`env::urban_wind_field`): seconds for a
    /// city, so built once per process, not per shard.
    pub wind: Option<Arc<UrbanWindField>>,
}

impl Surroundings {
    /// The surroundings of `plan` in `world` under `sky`; computes the urban wind field
    /// (the sectors of the run's direction only: a run with an asset cache loads every
    /// sector from it instead, `sim_worker::roles::surroundings`).
    pub fn new(plan: &RunPlan, world: Arc<World>, sky: Option<Arc<RunSky>>) -> Self {
        let wind = urban_wind_field(&plan.spec, &world).map(Arc::new);
        Self { world, sky, wind }
    }
}
