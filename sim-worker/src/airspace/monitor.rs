//! The compliance monitor: checks every drone's ground truth against the zones, the leases
//! and the group altitude limits at every coordinator window (>= 50 Hz; 100 Hz with the
//! default 10 ms windows), and between windows along the straight segment a drone flew,
//! so a fast drone clipping a zone's corner is still caught.
//!
//! It emits `zoneEntered`/`zoneExited` and `violationStarted`/`violationEnded` events and
//! keeps the records the criteria are judged on.

use serde::{Deserialize, Serialize};

use sadesim_crds::plan::RunPlan;

use super::authority::LeaseConstraints;
use super::volume::ZoneVolume;
use crate::events::{Event, Place};
use crate::protocol::DroneSnapshot;

/// The rules the monitor checks. Serialised as in events (`rule`): `unauthorizedEntry`, ...
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[serde(rename_all = "camelCase")]
pub enum ViolationKind {
    /// Inside an active zone without a valid lease.
    UnauthorizedEntry,
    /// Inside a zone below the lease's minimum altitude AGL.
    BelowZoneMinimum,
    /// Inside a zone above the lease's maximum altitude AGL.
    AboveZoneMaximum,
    /// Above the group's `altitude.maxAglM`, anywhere.
    AboveAltitudeLimit,
    /// Two airborne drones closer than a `minSeparation` criterion's distance.
    SeparationLoss,
}

/// One violation, from start to end.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct ViolationRecord {
    pub kind: ViolationKind,
    pub drone: u32,
    pub drone_name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub other: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zone: Option<String>,
    pub start_s: f64,
    /// `None` while it lasts; [`Monitor::finish`] closes every open one.
    pub end_s: Option<f64>,
    /// Where it started.
    pub at: Place,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit_m: Option<f64>,
    /// Furthest value reached (AGL metres, or distance metres for separation).
    pub worst_m: f64,
}

/// A stay inside a zone.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Presence {
    pub drone: u32,
    pub zone: String,
    pub entered_s: f64,
    pub exited_s: Option<f64>,
    /// Held a valid lease on entry.
    pub authorized: bool,
    /// Lowest height above ground inside, metres.
    pub min_agl_m: f64,
}

/// Everything the criteria need.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct ComplianceReport {
    pub violations: Vec<ViolationRecord>,
    pub presences: Vec<Presence>,
    /// Crashed drones with the sim time of the crash.
    pub crashes: Vec<(u32, f64)>,
    /// Closest approach between two airborne drones: (distance m, time s, drone, drone).
    pub closest_approach: Option<(f64, f64, u32, u32)>,
}

/// The monitor's state for one run.
#[derive(Debug)]
pub struct Monitor {
    report: ComplianceReport,
}

impl Monitor {
    /// Drones, groups (altitude limits) and separation distance (the smallest
    /// `minSeparation` criterion, if any) from the plan.
    pub fn new(plan: &RunPlan, zones: Vec<ZoneVolume>) -> Self {
        let _ = (plan, zones);
        unimplemented!("airspace::monitor")
    }

    /// One window ending at `time_s`: `drones` is every drone's ground truth, `events` the
    /// window's events (crashes are taken from them), `lease(drone, zone, time_s)` the
    /// drone's valid lease constraints. Returns the events the monitor raised, in time
    /// order.
    pub fn observe(
        &mut self,
        time_s: f64,
        drones: &[DroneSnapshot],
        events: &[Event],
        lease: &dyn Fn(u32, &str, f64) -> Option<LeaseConstraints>,
    ) -> Vec<Event> {
        let _ = (time_s, drones, events, lease);
        unimplemented!("airspace::monitor")
    }

    /// Ends the run at `time_s`: closes open stays and violations (with their events).
    pub fn finish(&mut self, time_s: f64) -> Vec<Event> {
        let _ = time_s;
        unimplemented!("airspace::monitor")
    }

    pub fn report(&self) -> &ComplianceReport {
        &self.report
    }
}
