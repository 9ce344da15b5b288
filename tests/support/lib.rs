//! Helpers shared by the integration tests.

use std::sync::Arc;

use sadesim_crds::SimulationRun;
use sadesim_crds::plan::RunPlan;
use sim_worker::world::{World, WorldInputs};

/// Plans a run that must be valid.
pub fn plan(run: &SimulationRun) -> RunPlan {
    sadesim::planner::plan(run).expect("a valid run")
}

/// The world a plan's shards share.
pub fn world(plan: &RunPlan) -> Arc<World> {
    Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])))
}
