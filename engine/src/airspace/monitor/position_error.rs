//! The `estimatedPositionError` criterion's measurement: per drone, the largest horizontal
//! distance between the estimated position (what the autopilot flies on) and the truth
//! while airborne, at the window samples.
//!
//! # Caveats
//! Sampled at window boundaries (every 10–50 ms of sim time): an estimate jump shorter than
//! a window between two samples is not seen, which a position estimate (a filter) does not
//! do.

use super::{Monitor, Sample};
use crate::protocol::DroneSnapshot;
use sadesim_crds::outcome::compliance::PositionError;

impl Monitor {
    /// Drone `i`'s estimate against its truth `now` (tracked only when the plan has the
    /// criterion: the report's list is then one slot per drone).
    pub(super) fn watch_position_error(&mut self, i: usize, now: &Sample, snap: &DroneSnapshot, airborne: bool) {
        let Some(estimate) = snap.detail.estimate.as_ref().filter(|_| airborne) else { return };
        let Self { log, .. } = self;
        if log.report.worst_position_errors.is_empty() {
            return;
        }
        let [e, n, _] = estimate.position_enu_m;
        let horizontal_m = (e - now.p.east_m).hypot(n - now.p.north_m);
        let worst = log.report.worst_position_errors[i].as_ref().map_or(f64::NEG_INFINITY, |w| w.horizontal_m);
        if horizontal_m > worst {
            let at = log.place(now);
            log.report.worst_position_errors[i] = Some(PositionError { horizontal_m, time_s: now.time_s, at });
        }
    }
}
