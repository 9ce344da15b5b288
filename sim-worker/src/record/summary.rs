//! `summary.json`: per drone and per run totals, built from the windows as they pass.

pub use sadesim_crds::outcome::summary::{DroneSummary, RunSummary};

use crate::events::{Event, EventKind};
use crate::protocol::{DroneSnapshot, fleet_counts};

/// Folds one window into the totals.
pub fn observe_window(
    summary: &mut RunSummary,
    drones: &[DroneSnapshot],
    events: &[Event],
    last_positions: &mut [Option<[f64; 2]>],
) {
    summary.events += events.len() as u64;
    for e in events {
        let Some(i) = e.drone else { continue };
        let Some(d) = summary.per_drone.get_mut(i as usize) else { continue };
        match &e.kind {
            EventKind::Takeoff => d.took_off = true,
            EventKind::Landed => d.landed = true,
            EventKind::Crashed { .. } => d.crashed = true,
            EventKind::WaypointReached { .. } => d.waypoints_reached += 1,
            EventKind::Failsafe { .. } => d.failsafes += 1,
            _ => {}
        }
    }
    for s in drones {
        let Some(d) = summary.per_drone.get_mut(s.index as usize) else { continue };
        d.max_height_agl_m = d.max_height_agl_m.max(s.height_agl_m);
        d.final_battery_remaining = s.battery_remaining;
        let here = [s.position_enu_m[0], s.position_enu_m[1]];
        if let Some(Some(prev)) = last_positions.get(s.index as usize) {
            d.distance_m += (here[0] - prev[0]).hypot(here[1] - prev[1]);
        }
        if let Some(slot) = last_positions.get_mut(s.index as usize) {
            *slot = Some(here);
        }
    }
    let counts = fleet_counts(drones);
    summary.airborne = counts.airborne;
    summary.crashed = counts.crashed;
}
