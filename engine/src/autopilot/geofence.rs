//! The built-in geofence (PX4's GF_ACTION, fed by the airspace): keeps a drone out of the
//! active zones it holds no lease for.
//!
//! Checked once per coordinator window on the estimated state. The drone "looks ahead"
//! along its velocity by the distance it needs to stop — v² / (2 a) at the horizontal
//! braking acceleration, plus a reaction margin — and when that segment would enter a
//! forbidden zone it takes the group's action: `hold` (stop where it is, PX4 AUTO.LOITER)
//! or `returnToLaunch`. A drone already inside a forbidden zone takes the action at once.
//!
//! After a hold, the drone is free again once it stands still (the look-ahead no longer
//! reaches the zone): a pilot that steers it towards the zone again is stopped again, one
//! `failsafe` event each time. During a geofence RTL nothing re-triggers.

use nalgebra::Vector3;
use sadesim_crds::fleet::GeofenceAction;
use sadesim_crds::geo::Enu;

use crate::airspace::volume::{Ground, ZoneVolume};
use crate::events::FlightMode;

/// Horizontal braking acceleration assumed for the look-ahead, m/s² (PX4 MPC_ACC_HOR
/// defaults to 3; 2.5 leaves room for wind and the controller's lag).
pub const BRAKING_MPS2: f64 = 2.5;
/// Reaction margin: distance flown in this time at the current speed is added, s. One
/// window is 10 ms; the controller needs a few hundred ms to pitch up.
pub const REACTION_S: f64 = 1.0;
/// Always look at least this far ahead, m (GNSS noise and overshoot).
pub const MIN_LOOKAHEAD_M: f64 = 5.0;

/// What the geofence wants the autopilot to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Breach {
    /// Index of the zone in `spec.zones`.
    pub zone: usize,
    pub action: GeofenceAction,
}

/// One drone's geofence state.
#[derive(Clone, Debug, PartialEq)]
pub struct Geofence {
    action: GeofenceAction,
    /// Zones (by index in `spec.zones`) the drone holds a valid lease for.
    permitted: Vec<bool>,
    /// The action was taken and the drone has not come clear yet.
    engaged: bool,
}

impl Geofence {
    pub fn new(action: GeofenceAction, zones: usize) -> Self {
        Self { action, permitted: vec![false; zones], engaged: false }
    }

    /// Replaces the set of zones the drone may enter (its valid leases).
    pub fn set_permitted(&mut self, zones: impl IntoIterator<Item = usize>) {
        self.permitted.iter_mut().for_each(|p| *p = false);
        for z in zones {
            if let Some(p) = self.permitted.get_mut(z) {
                *p = true;
            }
        }
    }

    /// Checks the look-ahead at `time_s` from `position`/`velocity` (ENU m, m/s) in `mode`.
    /// `Some` when the autopilot must act now.
    pub fn check(
        &mut self,
        time_s: f64,
        position: Vector3<f64>,
        velocity: Vector3<f64>,
        mode: FlightMode,
        zones: &[ZoneVolume],
        ground: &dyn Ground,
    ) -> Option<Breach> {
        let speed = velocity.norm();
        let reach = (speed * speed / (2.0 * BRAKING_MPS2) + speed * REACTION_S).max(MIN_LOOKAHEAD_M);
        let ahead = if speed > 1e-6 { position + velocity * (reach / speed) } else { position };
        let (a, b) = (enu(position), enu(ahead));
        let forbidden = zones.iter().enumerate().find(|(i, z)| {
            !self.permitted.get(*i).copied().unwrap_or(false)
                && z.is_active(time_s)
                && z.first_inside(a, b, ground).is_some()
        });
        let Some((zone, _)) = forbidden else {
            self.engaged = false;
            return None;
        };
        let in_action = match self.action {
            GeofenceAction::Hold => mode == FlightMode::Hold,
            GeofenceAction::ReturnToLaunch => matches!(mode, FlightMode::ReturnToLaunch | FlightMode::Land),
        };
        if self.engaged && in_action {
            return None;
        }
        self.engaged = true;
        Some(Breach { zone, action: self.action })
    }
}

fn enu(p: Vector3<f64>) -> Enu {
    Enu { east_m: p.x, north_m: p.y, up_m: p.z }
}

#[cfg(test)]
mod tests;
