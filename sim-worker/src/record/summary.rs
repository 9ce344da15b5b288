//! `summary.json`: per drone and per run totals, built from the windows as they pass.

pub use sadesim_crds::outcome::summary::{DroneSummary, RunSummary};

use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::{DroneSnapshot, fleet_counts};

/// What the summary carries from one window to the next for one drone.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DroneTrack {
    /// Home, local ENU (east, north), m: the plan's `home.local`.
    pub home_en_m: [f64; 2],
    /// Where the drone was at the previous window, ENU (east, north), m.
    pub last_position: Option<[f64; 2]>,
    /// The battery charge drawn by the previous window, mAh.
    pub last_consumed_mah: Option<f64>,
    /// A `landed` event came since the drone's last snapshot: its next snapshot is where it
    /// touched down.
    pub touched_down: bool,
}

impl DroneTrack {
    /// A drone whose home is at local ENU (east, north) `home_en_m`, not seen yet.
    pub fn new(home_en_m: [f64; 2]) -> Self {
        Self { home_en_m, ..Self::default() }
    }
}

/// Folds one window, `window_s` simulated seconds long, into the totals.
pub fn observe_window(
    summary: &mut RunSummary,
    window_s: f64,
    drones: &[DroneSnapshot],
    events: &[Event],
    tracks: &mut [DroneTrack],
) {
    summary.events += events.len() as u64;
    for e in events {
        let Some(i) = e.drone else { continue };
        let Some(d) = summary.per_drone.get_mut(i as usize) else { continue };
        match &e.kind {
            EventKind::Takeoff => d.took_off = true,
            EventKind::Landed => {
                d.landed = true;
                if let Some(track) = tracks.get_mut(i as usize) {
                    track.touched_down = true;
                }
            }
            EventKind::Crashed { .. } => d.crashed = true,
            EventKind::WaypointReached { .. } => d.waypoints_reached += 1,
            EventKind::Failsafe { .. } => d.failsafes += 1,
            _ => {}
        }
    }
    for s in drones {
        let (Some(d), Some(track)) = (summary.per_drone.get_mut(s.index as usize), tracks.get_mut(s.index as usize))
        else {
            continue;
        };
        d.max_height_agl_m = d.max_height_agl_m.max(s.height_agl_m);
        let airborne = !s.on_ground && !s.crashed;
        if airborne {
            d.flight_time_s = Some(d.flight_time_s.unwrap_or(0.0) + window_s);
        }
        if let (true, Some(w)) = (airborne, d.wind.as_mut()) {
            // A running mean: windows are counted, the sum is not kept.
            let speed = s.detail.wind_enu_mps[0].hypot(s.detail.wind_enu_mps[1]);
            w.windows += 1;
            w.mean_mps += (speed - w.mean_mps) / f64::from(w.windows);
            w.max_mps = w.max_mps.max(speed);
        }
        d.final_battery_remaining = s.battery_remaining;
        // Charge (mAh) times terminal voltage (V) is energy in mWh.
        let consumed_mah = s.detail.battery_consumed_mah;
        if let Some(before_mah) = track.last_consumed_mah {
            let window_wh = (consumed_mah - before_mah) * s.detail.battery_voltage_v / 1000.0;
            d.energy_wh = Some(d.energy_wh.unwrap_or(0.0) + window_wh);
        }
        track.last_consumed_mah = Some(consumed_mah);
        let here = [s.position_enu_m[0], s.position_enu_m[1]];
        if let Some(prev) = track.last_position {
            d.distance_m += (here[0] - prev[0]).hypot(here[1] - prev[1]);
        }
        track.last_position = Some(here);
        if std::mem::take(&mut track.touched_down) && !s.crashed {
            d.landing_error_m = Some((here[0] - track.home_en_m[0]).hypot(here[1] - track.home_en_m[1]));
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
        let mut tracks = vec![DroneTrack::default(); 2];
        let with_wind = |mut s: DroneSnapshot, w: [f64; 3], on_ground: bool| {
            s.detail.wind_enu_mps = w;
            s.on_ground = on_ground;
            s
        };
        for (w, on_ground) in [([3.0, 4.0, 9.0], false), ([6.0, 8.0, 0.0], false), ([30.0, 40.0, 0.0], true)] {
            let drones = [with_wind(over(0, [0.0, 0.0, 20.0], 0.0), w, on_ground), over(1, [9.0, 0.0, 20.0], 0.0)];
            observe_window(&mut summary, 0.01, &drones, &[], &mut tracks);
        }
        // Horizontal speeds 5 and 10 m/s in flight; the 50 m/s on the ground is not counted.
        let w = summary.per_drone[0].wind.expect("tallied");
        assert_eq!((w.windows, w.mean_mps, w.max_mps), (2, 7.5, 10.0));
        assert_eq!(summary.per_drone[1].wind, None, "a run without wind tallies none");
    }

    #[test]
    fn flight_time_landing_error_and_energy_are_tallied_per_drone() {
        let mut summary =
            RunSummary { per_drone: vec![DroneSummary::default(), DroneSummary::default()], ..Default::default() };
        let mut tracks = vec![DroneTrack::new([10.0, 20.0]), DroneTrack::new([0.0, 0.0])];
        // Drone 0: on the ground, 2 windows airborne (0.5 s each), lands 3 m east and 4 m
        // north of home. Drone 1 stays on the ground. Both draw 100 mAh a window at 15 V.
        let snap = |index: u32, p: [f64; 3], on_ground: bool, k: u32| {
            let mut s = sadesim_engine::fixtures::over(index, p, 0.0);
            s.on_ground = on_ground;
            s.detail.battery_consumed_mah = 100.0 * f64::from(k);
            s.detail.battery_voltage_v = 15.0;
            s
        };
        let landed = Event { time_s: 2.0, drone: Some(0), kind: EventKind::Landed };
        let windows = [
            ([10.0, 20.0, 0.0], true, vec![]),
            ([10.0, 20.0, 5.0], false, vec![]),
            ([13.0, 24.0, 5.0], false, vec![]),
            ([13.0, 24.0, 0.0], true, vec![landed]),
        ];
        for (k, (p, on_ground, events)) in windows.into_iter().enumerate() {
            let k = k as u32;
            let drones = [snap(0, p, on_ground, k), snap(1, [0.0; 3], true, k)];
            observe_window(&mut summary, 0.5, &drones, &events, &mut tracks);
        }
        let [d0, d1] = &summary.per_drone[..] else { unreachable!() };
        assert_eq!((d0.flight_time_s, d0.landing_error_m), (Some(1.0), Some(5.0)));
        assert!(d0.landed);
        assert_eq!((d1.flight_time_s, d1.landing_error_m), (None, None), "never flew");
        // 3 windows after the first, 0.1 Ah each at 15 V.
        for d in [d0, d1] {
            assert!((d.energy_wh.unwrap() - 4.5).abs() < 1e-9, "{:?}", d.energy_wh);
        }
    }
}
