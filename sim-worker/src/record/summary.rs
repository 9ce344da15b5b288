//! `summary.json`: per drone and per run totals, built from the windows as they pass.

pub use sadesim_crds::outcome::summary::{DroneSummary, RunSummary};

use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::{DroneSnapshot, fleet_counts};

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
        let airborne = !s.on_ground && !s.crashed;
        if let (true, Some(w)) = (airborne, d.wind.as_mut()) {
            // A running mean: windows are counted, the sum is not kept.
            let speed = s.detail.wind_enu_mps[0].hypot(s.detail.wind_enu_mps[1]);
            w.windows += 1;
            w.mean_mps += (speed - w.mean_mps) / f64::from(w.windows);
            w.max_mps = w.max_mps.max(speed);
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_engine::fixtures::over;

    #[test]
    fn the_wind_met_is_tallied_while_airborne_only_and_only_in_runs_with_wind() {
        let mut summary = RunSummary {
            per_drone: vec![
                DroneSummary { index: 0, wind: Some(Default::default()), ..Default::default() },
                DroneSummary { index: 1, ..Default::default() },
            ],
            ..Default::default()
        };
        let mut last = vec![None; 2];
        let with_wind = |mut s: DroneSnapshot, w: [f64; 3], on_ground: bool| {
            s.detail.wind_enu_mps = w;
            s.on_ground = on_ground;
            s
        };
        for (w, on_ground) in [([3.0, 4.0, 9.0], false), ([6.0, 8.0, 0.0], false), ([30.0, 40.0, 0.0], true)] {
            let drones = [with_wind(over(0, [0.0, 0.0, 20.0], 0.0), w, on_ground), over(1, [9.0, 0.0, 20.0], 0.0)];
            observe_window(&mut summary, &drones, &[], &mut last);
        }
        // Horizontal speeds 5 and 10 m/s in flight; the 50 m/s on the ground is not counted.
        let w = summary.per_drone[0].wind.expect("tallied");
        assert_eq!((w.windows, w.mean_mps, w.max_mps), (2, 7.5, 10.0));
        assert_eq!(summary.per_drone[1].wind, None, "a run without wind tallies none");
    }
}
