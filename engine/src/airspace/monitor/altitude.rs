//! The group altitude limits (`fleet[].altitude`) at the window samples: `maxAglM`
//! anywhere, `minAglM` while cruising.
//!
//! # When a drone is cruising (judged against `minAglM`)
//! Takeoff and landing necessarily pass below any minimum, so only the flight between them
//! is judged. A drone starts cruising at the first window sample where it is airborne
//! (neither on the ground nor crashed), in neither `land` nor `returnToLaunch` mode, and
//! at or above `minAglM`. It stops cruising at the first sample where it is on the ground,
//! crashed, or in `land` or `returnToLaunch` mode (PX4 AUTO.LAND, AUTO.RTL: the descent
//! home); an open `belowAltitudeMinimum` episode ends there. After that it must climb to
//! `minAglM` again before it is judged again.
//!
//! # Caveats
//! - A drone that never climbs to `minAglM` (a mission whose waypoints are all below it)
//!   is never judged: there is no cruise to tell apart from a long takeoff.
//! - A pilot flying home in `offboard` or `mission` mode, not `returnToLaunch`, is judged
//!   until it is on the ground or switches to `land`.

use super::{Monitor, NewViolation, Sample, ViolationKind};
use crate::events::FlightMode;

/// Whether `mode` is a descent to land (the end of a flight, not judged against `minAglM`).
fn is_descent(mode: FlightMode) -> bool {
    matches!(mode, FlightMode::Land | FlightMode::ReturnToLaunch)
}

impl Monitor {
    /// Both group altitude limits for drone `i` at the window sample `now`, flown in `mode`.
    pub(super) fn watch_altitude(&mut self, i: usize, now: &Sample, airborne: bool, mode: FlightMode) {
        let Self { drones, log, .. } = self;
        let d = &mut drones[i];
        let agl_m = now.height_agl_m;
        let limit_m = d.max_agl_m;
        let breach = (airborne && agl_m > limit_m).then_some(agl_m);
        log.track(&mut d.above_limit, breach, now, || NewViolation {
            kind: ViolationKind::AboveAltitudeLimit,
            drone: i as u32,
            drone_name: d.name.clone(),
            other: None,
            zone: None,
            limit_m: Some(limit_m),
            detail: format!("{agl_m:.1} m AGL, above the group's limit of {limit_m:.1} m AGL"),
        });

        let Some(min_m) = d.min_agl_m else { return };
        if !airborne || is_descent(mode) {
            d.cruising = false;
        } else if agl_m >= min_m {
            d.cruising = true;
        }
        let breach = (d.cruising && agl_m < min_m).then_some(agl_m);
        log.track(&mut d.below_minimum, breach, now, || NewViolation {
            kind: ViolationKind::BelowAltitudeMinimum,
            drone: i as u32,
            drone_name: d.name.clone(),
            other: None,
            zone: None,
            limit_m: Some(min_m),
            detail: format!("{agl_m:.1} m AGL, below the group's minimum of {min_m:.1} m AGL while cruising"),
        });
    }
}
