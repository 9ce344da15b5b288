//! The airspace authority: decides zone entry requests and keeps the lease table.
//!
//! [`decide`] is a pure function of (zone rule, lease table, requester, request, sim time)
//! and is where every verdict comes from. [`Authority`] holds the state the HTTP service
//! and the compliance monitor share: the rules of every zone, who the drones are (operator
//! and credential, from the plan), the leases, and the log of requests and verdicts.
//!
//! A request is never granted by default: the presented bearer token must equal the
//! credential configured for the drone's group, and the drone's operator must be one of the
//! zone's `authorizedOperators`; otherwise the verdict is `insufficient_credentials`.

use serde::{Deserialize, Serialize};

use sadesim_crds::plan::RunPlan;
use sadesim_crds::zones::ZonePolicy;

use crate::events::Event;

/// Default lease length when the policy gives none (10 min).
pub const DEFAULT_LEASE_S: f64 = 600.0;

/// Why a request was denied. Serialised as in the API: `insufficient_credentials`, ...
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[serde(rename_all = "snake_case")]
pub enum DenyReason {
    /// Wrong or missing credential for the drone, or its operator is not authorized.
    InsufficientCredentials,
    /// The zone's `capacity` leases are all held.
    CapacityExhausted,
    /// The requested altitude band is not within the zone's altitude constraints.
    UnsafeAltitude,
    /// The zone is not active at the time of the request.
    ZoneInactive,
}

impl DenyReason {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::InsufficientCredentials => "insufficient_credentials",
            Self::CapacityExhausted => "capacity_exhausted",
            Self::UnsafeAltitude => "unsafe_altitude",
            Self::ZoneInactive => "zone_inactive",
        }
    }
}

/// The altitude band a drone intends to fly in inside the zone, metres AGL.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct AltitudeBand {
    pub min_agl_m: f64,
    pub max_agl_m: f64,
}

/// Constraints a lease holder must respect inside the zone (AGL metres).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct LeaseConstraints {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_altitude_agl_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_altitude_agl_m: Option<f64>,
}

/// Permission for one drone to be inside one zone until `expires_at_s`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Lease {
    /// `lease-<n>`, unique in the run.
    pub id: String,
    pub zone: String,
    /// Global drone index.
    pub drone: u32,
    /// Drone name (`<group>-<k>`).
    pub drone_name: String,
    pub operator: String,
    pub granted_at_s: f64,
    pub expires_at_s: f64,
    /// Set when released before expiry.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub released_at_s: Option<f64>,
    pub constraints: LeaseConstraints,
}

impl Lease {
    /// Whether the lease allows presence at `time_s`.
    pub fn is_valid_at(&self, time_s: f64) -> bool {
        time_s >= self.granted_at_s && time_s < self.expires_at_s && self.released_at_s.is_none_or(|r| time_s < r)
    }
}

/// One zone's rules, resolved from the scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct ZoneRule {
    pub zone: String,
    pub policy: ZonePolicy,
    pub active_from_s: f64,
    /// `f64::INFINITY` when active until the end.
    pub active_until_s: f64,
    pub lease_s: f64,
}

/// Who a drone is to the authority.
#[derive(Clone, Debug, PartialEq)]
pub struct Requester {
    pub drone: u32,
    pub name: String,
    pub group: String,
    pub operator: String,
    /// The group's credential; `None`: the drone can never be granted anything.
    pub credential: Option<String>,
}

/// An entry request as the pilot sends it (the token comes from the Authorization header).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct EntryRequest {
    /// Drone name from the fleet file (`public-safety-0`).
    pub drone: String,
    /// Operator id; must be the drone's operator.
    pub operator: String,
    /// Intended altitude band inside the zone.
    pub altitude: AltitudeBand,
}

/// The outcome of [`decide`].
#[derive(Clone, Debug, PartialEq)]
pub enum Decision {
    Grant { expires_at_s: f64, constraints: LeaseConstraints },
    Deny { reason: DenyReason, message: String },
}

/// The leases ever granted in a run (kept after expiry: they are evidence).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LeaseTable {
    pub leases: Vec<Lease>,
}

impl LeaseTable {
    /// Leases of `zone` valid at `time_s`.
    pub fn held(&self, zone: &str, time_s: f64) -> usize {
        let _ = (zone, time_s);
        unimplemented!("airspace::authority")
    }

    /// The drone's lease for the zone valid at `time_s`.
    pub fn valid(&self, drone: u32, zone: &str, time_s: f64) -> Option<&Lease> {
        let _ = (drone, zone, time_s);
        unimplemented!("airspace::authority")
    }
}

/// Decides one request. Pure. Checks, in order: credential and operator
/// (`insufficient_credentials`), zone active (`zone_inactive`), altitude band within the
/// policy's min/max AGL (`unsafe_altitude`), capacity counting valid leases of other drones
/// (`capacity_exhausted`). A drone that already holds a valid lease for the zone gets it
/// again (same expiry) rather than a second one.
pub fn decide(
    rule: &ZoneRule,
    leases: &LeaseTable,
    requester: &Requester,
    token: &str,
    request: &EntryRequest,
    now_s: f64,
) -> Decision {
    let _ = (rule, leases, requester, token, request, now_s);
    unimplemented!("airspace::authority")
}

/// One request and its verdict, kept for the report and the criteria.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RequestRecord {
    /// 1-based sequence number in the run.
    pub id: u64,
    pub time_s: f64,
    pub zone: String,
    pub drone: u32,
    pub drone_name: String,
    pub operator: String,
    pub altitude: AltitudeBand,
    /// `granted` or `denied`.
    pub verdict: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<DenyReason>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lease: Option<String>,
}

/// What the API answers a request with.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "verdict", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Verdict {
    Granted { request_id: u64, lease: Lease },
    Denied { request_id: u64, reason: DenyReason, message: String },
}

/// A request the authority cannot decide: the API answers 4xx with the message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AuthorityError {
    #[error("unknown zone {0:?}")]
    UnknownZone(String),
    #[error("unknown drone {0:?}: use a drone name from the fleet file")]
    UnknownDrone(String),
    #[error("unknown lease {0:?}")]
    UnknownLease(String),
    /// Renew or release with a token that is not the lease holder's credential.
    #[error("the credential does not belong to the holder of lease {0:?}")]
    NotHolder(String),
    /// Renewing a lease that expired or was released.
    #[error("lease {0:?} is no longer valid; request the zone again")]
    LeaseEnded(String),
    #[error("invalid altitude band: {0}")]
    InvalidBand(String),
}

/// The authority's state for one run.
#[derive(Clone, Debug)]
pub struct Authority {
    pub rules: Vec<ZoneRule>,
    pub requesters: Vec<Requester>,
    pub leases: LeaseTable,
    pub requests: Vec<RequestRecord>,
    /// Events not yet taken by [`Authority::take_events`] (zoneRequested, zoneGranted,
    /// zoneDenied, leaseRenewed, leaseReleased, leaseExpired).
    pending: Vec<Event>,
}

impl Authority {
    /// Rules from `spec.zones`, requesters from the plan's drones. Credentials:
    /// `credential.value`, or for `secretKeyRef` the environment variable
    /// `SADESIM_CREDENTIAL_<GROUP>` given in `secret_env` (the coordinator pod gets the
    /// Secret there); a group without a resolvable credential is never granted.
    pub fn from_plan(plan: &RunPlan, secret_env: &dyn Fn(&str) -> Option<String>) -> Self {
        let _ = (plan, secret_env);
        unimplemented!("airspace::authority")
    }

    /// Decides a request for `zone` at `now_s`, records it and its events.
    ///
    /// # Errors
    /// Unknown zone or drone, invalid band (min >= max, negative, not finite).
    pub fn request(
        &mut self,
        zone: &str,
        token: &str,
        request: &EntryRequest,
        now_s: f64,
    ) -> Result<Verdict, AuthorityError> {
        let _ = (zone, token, request, now_s);
        unimplemented!("airspace::authority")
    }

    /// Extends a valid lease by the zone's lease duration from `now_s`.
    ///
    /// # Errors
    /// Unknown lease, wrong token, lease ended.
    pub fn renew(&mut self, lease_id: &str, token: &str, now_s: f64) -> Result<Lease, AuthorityError> {
        let _ = (lease_id, token, now_s);
        unimplemented!("airspace::authority")
    }

    /// Ends a lease now (idempotent for an already released lease).
    ///
    /// # Errors
    /// Unknown lease, wrong token.
    pub fn release(&mut self, lease_id: &str, token: &str, now_s: f64) -> Result<Lease, AuthorityError> {
        let _ = (lease_id, token, now_s);
        unimplemented!("airspace::authority")
    }

    /// Emits `leaseExpired` for leases that expired by `now_s` (once each).
    pub fn expire(&mut self, now_s: f64) {
        let _ = now_s;
        unimplemented!("airspace::authority")
    }

    /// The drone's valid lease for the zone at `time_s`.
    pub fn valid_lease(&self, drone: u32, zone: &str, time_s: f64) -> Option<&Lease> {
        self.leases.valid(drone, zone, time_s)
    }

    /// Events since the last call, in order.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.pending)
    }
}
