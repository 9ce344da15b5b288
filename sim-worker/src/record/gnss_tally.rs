//! The GNSS part of `summary.json`: per drone, the receiver's epochs in flight (airborne:
//! neither on the ground nor crashed) and the errors of its fixes and of the estimate
//! against the truth, folded from the windows as they pass.

use sadesim_crds::outcome::summary::{ErrorStats, GnssSummary};

use sadesim_engine::protocol::DroneSnapshot;

/// One row of `gnss.csv`: a drone's receiver epoch in flight, at most one per second.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssRow {
    pub time_s: f64,
    pub fix_type: u8,
    pub satellites: u8,
    pub hdop: Option<f64>,
    /// Horizontal distance of the 3D fix from the truth, m.
    pub fix_error_m: Option<f64>,
    /// Horizontal distance of the estimate from the truth, m.
    pub estimate_error_m: Option<f64>,
}

/// Seconds between two rows of one drone in `gnss.csv`.
pub const ROW_PERIOD_S: f64 = 1.0;

/// One drone's samples so far.
#[derive(Clone, Debug, Default)]
pub struct GnssTally {
    last_epoch_s: Option<f64>,
    last_row_s: Option<f64>,
    epochs: u32,
    without_3d_fix: u32,
    satellites: u64,
    hdop: Vec<f64>,
    fix_error_m: Vec<f64>,
    estimate_error_m: Vec<f64>,
    above_mask: u64,
    reflected: u64,
    ranging: bool,
}

impl GnssTally {
    /// Takes drone `s`'s receiver output when it is a new epoch (sampled at `window_s`);
    /// returns the epoch as a `gnss.csv` row when one is due (in flight, [`ROW_PERIOD_S`]
    /// after the last).
    pub fn observe(&mut self, window_s: f64, s: &DroneSnapshot) -> Option<GnssRow> {
        let g = s.detail.gnss.as_ref()?;
        if self.last_epoch_s == Some(g.time_s) {
            return None;
        }
        self.last_epoch_s = Some(g.time_s);
        // On the ground a drone is waiting or done: the statistics are of its flight.
        if s.on_ground || s.crashed {
            return None;
        }
        self.epochs += 1;
        let truth = s.position_back_at(g.time_s, window_s);
        if let Some(sky) = g.sky {
            self.ranging = true;
            self.above_mask += u64::from(sky.above_mask);
            self.reflected += u64::from(sky.reflected);
        }
        let fix_error_m = (g.fix_type >= 3).then(|| {
            let [e, n, _] = g.position_enu_m;
            (e - truth[0]).hypot(n - truth[1])
        });
        match fix_error_m {
            Some(error) => {
                self.satellites += u64::from(g.satellites);
                self.hdop.extend(g.hdop);
                self.fix_error_m.push(error);
            }
            None => self.without_3d_fix += 1,
        }
        let estimate_error_m = s.detail.estimate.as_ref().map(|est| {
            let [e, n, _] = est.position_enu_m;
            (e - truth[0]).hypot(n - truth[1])
        });
        self.estimate_error_m.extend(estimate_error_m);
        if self.last_row_s.is_some_and(|t| g.time_s < t + ROW_PERIOD_S - 1e-9) {
            return None;
        }
        self.last_row_s = Some(g.time_s);
        Some(GnssRow {
            time_s: g.time_s,
            fix_type: g.fix_type,
            satellites: g.satellites,
            hdop: g.hdop,
            fix_error_m,
            estimate_error_m,
        })
    }

    /// The summary (`None` before the first epoch).
    pub fn summary(&mut self) -> Option<GnssSummary> {
        if self.epochs == 0 {
            return None;
        }
        let fixes = self.epochs - self.without_3d_fix;
        Some(GnssSummary {
            epochs: self.epochs,
            epochs_without_3d_fix: self.without_3d_fix,
            mean_satellites: if fixes == 0 { 0.0 } else { self.satellites as f64 / f64::from(fixes) },
            median_hdop: ErrorStats::of(&mut self.hdop).map(|s| s.median),
            fix_error_m: ErrorStats::of(&mut self.fix_error_m),
            estimate_error_m: ErrorStats::of(&mut self.estimate_error_m),
            reflected_share: (self.ranging && self.above_mask > 0)
                .then(|| self.reflected as f64 / self.above_mask as f64),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_engine::protocol::{GnssDetail, SkyDetail};

    fn snap(t: f64, fix: Option<[f64; 3]>) -> DroneSnapshot {
        let mut s = DroneSnapshot::climbing(0, 0.0, t);
        s.position_enu_m = [0.0, 0.0, 20.0];
        s.velocity_enu_mps = [0.0; 3];
        s.detail.gnss = Some(GnssDetail {
            time_s: t,
            position_enu_m: fix.unwrap_or([0.0; 3]),
            fix_type: if fix.is_some() { 3 } else { 1 },
            satellites: 8,
            hdop: fix.map(|_| 1.5),
            sky: Some(SkyDetail { above_mask: 10, line_of_sight: 8, reflected: 2 }),
            ..Default::default()
        });
        s
    }

    #[test]
    fn epochs_are_counted_once_and_errors_measured_against_the_truth() {
        let mut tally = GnssTally::default();
        for k in 0..20 {
            let t = f64::from(k) * 0.2;
            let fix = if k < 15 { Some([f64::from(k % 5), 0.0, 20.0]) } else { None };
            tally.observe(t, &snap(t, fix));
            tally.observe(t + 0.01, &snap(t, fix)); // the same epoch in the next window
        }
        let mut rows = GnssTally::default();
        let written: Vec<f64> = (0..20)
            .filter_map(|k| {
                let t = f64::from(k) * 0.2;
                rows.observe(t, &snap(t, Some([1.0, 0.0, 20.0])))
            })
            .map(|r| r.time_s)
            .collect();
        assert_eq!(written.len(), 4, "a row a second: {written:?}");
        assert!((written[1] - 1.0).abs() < 1e-9);
        let mut grounded = snap(10.0, Some([50.0, 0.0, 0.0]));
        grounded.on_ground = true;
        tally.observe(10.0, &grounded);
        let s = tally.summary().unwrap();
        assert_eq!((s.epochs, s.epochs_without_3d_fix), (20, 5));
        assert_eq!(s.mean_satellites, 8.0);
        assert_eq!(s.median_hdop, Some(1.5));
        let fix = s.fix_error_m.unwrap();
        assert_eq!((fix.median, fix.max), (2.0, 4.0), "errors 0..4 m, three times each");
        assert_eq!(s.reflected_share, Some(0.2));
        assert_eq!(GnssTally::default().summary(), None);
    }
}
