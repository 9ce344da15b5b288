//! The airspace at run time: the authority's HTTP service, the compliance monitor and the
//! verdict, wired into the coordinator's window loop.
//!
//! [`Airspace::on_window`] runs once per coordinator window, before the recorder: it moves
//! the sim clock the API decides at, expires leases, runs the monitor on the window's ground
//! truth and returns the airspace events of the window (requests, verdicts, lease changes,
//! entries, violations) to be recorded with the shards' events. [`WithAirspace`] does this
//! for any [`RunObserver`], so the local runner and the `sim-worker coordinator` role share it.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};

use sadesim_crds::plan::RunPlan;
use serde::Serialize;

use super::authority::{Lease, RequestRecord};
use super::service::{self, ServiceHandle};
use super::{AirspaceState, SharedAirspace};
use sadesim_engine::airspace::criteria::{self, RunVerdict};
use sadesim_engine::airspace::monitor::{ComplianceReport, Monitor};
use sadesim_engine::coordinator::{ObserverError, RunObserver};
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::DroneSnapshot;

/// The file the airspace records of a run go to, next to `summary.json`.
pub const AIRSPACE_FILE: &str = sadesim_crds::outcome::run_folder::AIRSPACE;

/// Everything airspace-related of one run.
#[derive(Debug)]
pub struct Airspace {
    shared: SharedAirspace,
    monitor: Monitor,
    service: Option<ServiceHandle>,
    finished: bool,
    /// Some group has a built-in geofence: the shards need the valid leases.
    fenced: bool,
    /// The valid leases last sent to the shards, sorted `[drone, zone]`.
    sent_leases: Vec<[u32; 2]>,
}

/// `airspace.json`: the authority's and the monitor's records, for reports and audits.
#[derive(Serialize, Debug, Clone)]
#[serde(rename_all = "camelCase")]
pub struct AirspaceRecord {
    pub requests: Vec<RequestRecord>,
    pub leases: Vec<Lease>,
    #[serde(flatten)]
    pub compliance: ComplianceReport,
}

impl Airspace {
    /// The authority and monitor of `plan`, without an HTTP service (tests, or runs whose
    /// pilots never ask).
    pub fn new(plan: &RunPlan, secret_env: &dyn Fn(&str) -> Option<String>) -> Self {
        let state = AirspaceState::new(plan, secret_env);
        let monitor = Monitor::new(plan, state.zones.clone());
        let fenced = plan.spec.fleet.iter().any(|g| g.geofence.is_some()) && !plan.spec.zones.is_empty();
        Self {
            shared: Arc::new(Mutex::new(state)),
            monitor,
            service: None,
            finished: false,
            fenced,
            sent_leases: Vec::new(),
        }
    }

    /// Also serves the HTTP API on `bind`.
    ///
    /// # Errors
    /// When the address cannot be bound.
    pub fn serve(&mut self, bind: SocketAddr) -> std::io::Result<SocketAddr> {
        let handle = service::start(self.shared.clone(), bind)?;
        let addr = handle.addr;
        self.service = Some(handle);
        Ok(addr)
    }

    /// The address the API listens on, when served.
    pub fn address(&self) -> Option<SocketAddr> {
        self.service.as_ref().map(|s| s.addr)
    }

    pub fn shared(&self) -> SharedAirspace {
        self.shared.clone()
    }

    fn state(&self) -> MutexGuard<'_, AirspaceState> {
        // A panicking request handler must not take the run down with it: the state is
        // only ever changed whole (one request at a time), so it is still consistent.
        self.shared.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// One coordinator window ending at `time_s`. Returns the airspace events to record,
    /// in time order. On the final window (the one carrying `runEnded`) the monitor closes
    /// every open stay and violation.
    pub fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Vec<Event> {
        let final_window = events.iter().any(|e| matches!(e.kind, EventKind::RunEnded { .. }));
        let shared = self.shared.clone();
        let mut state = shared.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        state.time_s = time_s;
        state.pilots_released |= events.iter().any(|e| matches!(e.kind, EventKind::PilotsReleased));
        state.authority.expire(time_s);
        state.collect_authority_events();
        let authority = &state.authority;
        let lease = |drone: u32, zone: &str, t: f64| authority.valid_lease(drone, zone, t).map(|l| l.constraints);
        let mut raised = if self.finished {
            Vec::new()
        } else if final_window {
            self.finished = true;
            let mut raised = self.monitor.observe(time_s, drones, events, &lease);
            raised.extend(self.monitor.finish(time_s));
            raised
        } else {
            self.monitor.observe(time_s, drones, events, &lease)
        };
        state.publish(std::mem::take(&mut raised));
        let mut out = state.take_unrecorded();
        out.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.drone.cmp(&b.drone)));
        out
    }

    /// The valid leases as `[drone, zone index]` when they changed since the last call
    /// (only for runs with a geofenced group).
    pub fn leases_changed(&mut self) -> Option<Vec<[u32; 2]>> {
        if !self.fenced {
            return None;
        }
        let current = {
            let state = self.state();
            let now = state.time_s;
            let mut current: Vec<[u32; 2]> = state
                .authority
                .leases
                .leases
                .iter()
                .filter(|l| l.is_valid_at(now))
                .filter_map(|l| state.zones.iter().position(|z| z.name == l.zone).map(|z| [l.drone, z as u32]))
                .collect();
            current.sort_unstable();
            current.dedup();
            current
        };
        (current != self.sent_leases).then(|| {
            self.sent_leases.clone_from(&current);
            current
        })
    }

    /// The run's verdict on `plan.spec.criteria`, at the end of the run.
    pub fn verdict(&self, plan: &RunPlan, end_s: f64) -> RunVerdict {
        let state = self.state();
        criteria::evaluate(plan, self.monitor.report(), &state.authority.requests, end_s)
    }

    /// Per drone, the closest horizontal approach to a zone it held no lease for, metres
    /// (the monitor's [`Monitor::closest_zones_m`]), for `summary.json`.
    pub fn closest_zones_m(&self) -> Vec<Option<f64>> {
        self.monitor.closest_zones_m()
    }

    /// The records for `airspace.json`.
    pub fn record(&self) -> AirspaceRecord {
        let state = self.state();
        AirspaceRecord {
            requests: state.authority.requests.clone(),
            leases: state.authority.leases.leases.clone(),
            compliance: self.monitor.report().clone(),
        }
    }
}

/// Runs the airspace before another observer and hands it the merged events.
pub struct WithAirspace<'a> {
    pub airspace: &'a mut Airspace,
    pub inner: &'a mut dyn RunObserver,
    merged: Vec<Event>,
}

impl std::fmt::Debug for WithAirspace<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WithAirspace").field("airspace", &self.airspace).finish_non_exhaustive()
    }
}

impl<'a> WithAirspace<'a> {
    pub fn new(airspace: &'a mut Airspace, inner: &'a mut dyn RunObserver) -> Self {
        Self { airspace, inner, merged: Vec::new() }
    }
}

impl RunObserver for WithAirspace<'_> {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        let raised = self.airspace.on_window(time_s, drones, events);
        if raised.is_empty() {
            return self.inner.on_window(time_s, drones, events);
        }
        self.merged.clear();
        self.merged.extend_from_slice(events);
        // `runEnded` stays last: the airspace's closing events come before it.
        let end = self.merged.iter().position(|e| matches!(e.kind, EventKind::RunEnded { .. }));
        let tail: Vec<Event> = end.map(|i| self.merged.split_off(i)).unwrap_or_default();
        self.merged.extend(raised);
        self.merged.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.drone.cmp(&b.drone)));
        self.merged.extend(tail);
        self.inner.on_window(time_s, drones, &self.merged)
    }

    fn leases_changed(&mut self) -> Option<Vec<[u32; 2]>> {
        self.airspace.leases_changed()
    }

    fn stop_reason(&mut self) -> Option<sadesim_engine::events::EndReason> {
        self.inner.stop_reason()
    }

    fn on_clock_started(&mut self, started: std::time::Instant) {
        self.inner.on_clock_started(started);
    }

    /// Forwarded: the runner looks at its pilot process while the run holds for it.
    fn on_hold(&mut self, waited: std::time::Duration) {
        self.inner.on_hold(waited);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_engine::fixtures::plan_of;

    /// `/healthz` says `pilotsReleased` from the window that carries the event on, and
    /// keeps saying it: the pilot pod's init container polls it.
    #[test]
    fn the_release_is_remembered_from_its_window_on() {
        let run = sadesim_crds::parse_run(include_str!("../../../examples/chicago-museum.yaml")).unwrap();
        let plan = plan_of(run);
        let mut airspace = Airspace::new(&plan, &|_| None);
        airspace.on_window(0.1, &[], &[]);
        assert!(!airspace.shared().lock().unwrap().pilots_released);
        let release = Event { time_s: 0.2, drone: None, kind: EventKind::PilotsReleased };
        airspace.on_window(0.2, &[], &[release]);
        assert!(airspace.shared().lock().unwrap().pilots_released);
        airspace.on_window(0.3, &[], &[]);
        assert!(airspace.shared().lock().unwrap().pilots_released, "still released a window later");
    }
}
