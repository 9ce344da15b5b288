//! The airspace authority at run time (the decisions themselves are
//! `sadesim_engine::airspace`):
//!
//! - [`service`]: the authority's HTTP/JSON API (axum), part of the coordinator role.
//!   `docs/airspace-api.yaml` is its OpenAPI description.
//! - [`runtime`]: the authority, the monitor and the API together around a run: the
//!   coordinator's observer that merges their events into each window and writes
//!   `airspace.json` at the end.
//!
//! Time is simulated seconds since the start of the run everywhere in this module.

pub mod runtime;
pub mod service;

use std::sync::{Arc, Mutex};

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::zones::Zone;

use sadesim_engine::airspace::{authority, volume};
use sadesim_engine::events::Event;

/// What the HTTP service and the coordinator's observer share.
#[derive(Debug)]
pub struct AirspaceState {
    pub authority: authority::Authority,
    pub zones: Vec<volume::ZoneVolume>,
    /// The scenario's zones as written (`spec.zones`, same order as `zones`): the API
    /// serves their lat/lon outlines and policies.
    pub zone_specs: Vec<Zone>,
    pub frame: LocalFrame,
    /// Sim time of the latest window, seconds: requests between windows are decided and
    /// stamped at it.
    pub time_s: f64,
    /// The coordinator has released the pilots (every shard ready): `/healthz` says so, and
    /// a pilot pod's init container waits for it.
    pub pilots_released: bool,
    /// Every airspace event of the run so far (requests, verdicts, leases, entries,
    /// violations), served by `GET /events`; index + 1 is the event's sequence number.
    pub history: Vec<Event>,
    /// Events not yet handed to the recorder.
    unrecorded: Vec<Event>,
}

/// Shared between the HTTP service's tasks and the coordinator thread.
pub type SharedAirspace = Arc<Mutex<AirspaceState>>;

impl AirspaceState {
    /// The zones and authority of a run; `secret_env` resolves `secretKeyRef` credentials
    /// (see [`authority::Authority::from_plan`]).
    pub fn new(plan: &RunPlan, secret_env: &dyn Fn(&str) -> Option<String>) -> Self {
        let frame = LocalFrame::new(plan.spec.origin.geo());
        Self {
            authority: authority::Authority::from_plan(plan, secret_env),
            zones: plan.spec.zones.iter().map(|z| volume::ZoneVolume::new(z, &frame)).collect(),
            zone_specs: plan.spec.zones.clone(),
            frame,
            time_s: 0.0,
            pilots_released: false,
            history: Vec::new(),
            unrecorded: Vec::new(),
        }
    }

    /// Moves the authority's new events into the history (call after every change).
    pub fn collect_authority_events(&mut self) {
        let events = self.authority.take_events();
        self.publish(events);
    }

    /// Adds events (from the authority or the monitor) to the history and the recorder's
    /// queue.
    pub fn publish(&mut self, events: Vec<Event>) {
        self.history.extend(events.iter().cloned());
        self.unrecorded.extend(events);
    }

    /// Events for the recorder since the last call.
    pub fn take_unrecorded(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.unrecorded)
    }
}
