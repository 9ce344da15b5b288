//! The parameters a planned drone starts with: one function for the MAVLink session (built
//! by the shard) and the drone's ULog (written by the recorder), so both carry the same
//! values.

use sadesim_crds::fleet::FleetGroup;
use sadesim_crds::plan::{PlannedDrone, RunPlan};

use super::ParamTable;
use crate::autopilot::navigator::NavigatorConfig;
use crate::preset::Preset;

/// The navigator tunables a drone of `group` starts with: PX4's defaults, returning at 80 %
/// of the group's ceiling, at most 60 m (PX4's 60 m default is above many groups' limits).
pub fn navigator_config(group: &FleetGroup) -> NavigatorConfig {
    NavigatorConfig { rtl_altitude_m: (group.altitude.max_agl_m * 0.8).min(60.0), ..NavigatorConfig::default() }
}

/// The parameter table of `drone` at the start of the run: its preset, its system id and
/// its group's navigator tunables. `None` when the drone's airframe or group is unknown
/// (the validator refuses such plans).
pub fn drone_table(plan: &RunPlan, drone: &PlannedDrone) -> Option<ParamTable> {
    let preset = Preset::named(&drone.airframe)?;
    let group = plan.spec.fleet.get(drone.group_index as usize)?;
    Some(ParamTable::px4(drone.system_id, &preset, &navigator_config(group)))
}
