//! `summary.json`: per drone and per run totals, built from the windows as they pass.

use super::RecordingCost;
use serde::{Deserialize, Serialize};

use crate::airspace::criteria::RunVerdict;
use crate::events::{Event, EventKind};
use crate::protocol::{DroneSnapshot, FleetCounts};

/// Per-drone outcome.
#[derive(Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct DroneSummary {
    pub index: u32,
    pub name: String,
    pub group: String,
    pub took_off: bool,
    pub landed: bool,
    pub crashed: bool,
    pub max_height_agl_m: f64,
    /// Horizontal distance flown, m.
    pub distance_m: f64,
    pub waypoints_reached: u32,
    pub failsafes: u32,
    pub final_battery_remaining: f64,
}

/// The whole run.
#[derive(Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RunSummary {
    pub run: String,
    pub end_reason: String,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    /// Simulated seconds per wall second over the whole run.
    pub real_time_factor: f64,
    pub drones: u32,
    pub shards: u32,
    pub airborne: u32,
    pub crashed: u32,
    pub events: u64,
    pub pilots_released_at_s: Option<f64>,
    pub per_drone: Vec<DroneSummary>,
    /// The scenario's criteria judged at the end (absent when the run did not get that far).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verdict: Option<RunVerdict>,
    /// CPU seconds the recorder spent writing each kind of file (measured on its thread).
    #[serde(default)]
    pub recording_cpu_s: RecordingCost,
}

impl RunSummary {
    /// Folds one window into the totals.
    pub fn observe(&mut self, drones: &[DroneSnapshot], events: &[Event], last_positions: &mut [Option<[f64; 2]>]) {
        self.events += events.len() as u64;
        for e in events {
            let Some(i) = e.drone else { continue };
            let Some(d) = self.per_drone.get_mut(i as usize) else { continue };
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
            let Some(d) = self.per_drone.get_mut(s.index as usize) else { continue };
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
        let counts = FleetCounts::of(drones);
        self.airborne = counts.airborne;
        self.crashed = counts.crashed;
    }
}
