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

use std::collections::{HashMap, HashSet};

use serde::{Deserialize, Serialize};

pub use sadesim_crds::outcome::compliance::{
    AltitudeBand, DenyReason, Lease, LeaseConstraints, RequestRecord, Verdict,
};

use sadesim_crds::fleet::Credential;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::validate::duration_s;
use sadesim_crds::zones::ZonePolicy;

use crate::events::{Event, EventKind};

/// Default lease length when the policy gives none (10 min).
pub const DEFAULT_LEASE_S: f64 = 600.0;

/// Highest altitude a request may name, metres AGL (the schema's limit for zone heights).
pub const MAX_BAND_AGL_M: f64 = 20_000.0;

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
        self.leases.iter().filter(|l| l.zone == zone && l.is_valid_at(time_s)).count()
    }

    /// The drone's lease for the zone valid at `time_s`.
    pub fn valid(&self, drone: u32, zone: &str, time_s: f64) -> Option<&Lease> {
        self.leases.iter().find(|l| l.drone == drone && l.zone == zone && l.is_valid_at(time_s))
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
    let deny = |reason, message: String| Decision::Deny { reason, message };
    let (drone, zone, policy) = (&requester.name, &rule.zone, &rule.policy);

    // 1. Who is asking: the group's credential, the drone's own operator, an authorized operator.
    let Some(credential) = &requester.credential else {
        return deny(
            DenyReason::InsufficientCredentials,
            format!(
                "drone {drone} (group {}) has no credential configured; it cannot be granted any zone",
                requester.group
            ),
        );
    };
    if token.is_empty() {
        return deny(
            DenyReason::InsufficientCredentials,
            format!("no bearer credential was presented for drone {drone}"),
        );
    }
    if !constant_time_eq(token.as_bytes(), credential.as_bytes()) {
        return deny(
            DenyReason::InsufficientCredentials,
            format!("the bearer credential is not valid for drone {drone} (group {})", requester.group),
        );
    }
    if request.operator != requester.operator {
        return deny(
            DenyReason::InsufficientCredentials,
            format!("drone {drone} is operated by {}, not by {}", requester.operator, request.operator),
        );
    }
    if !policy.authorized_operators.contains(&requester.operator) {
        let authorized = if policy.authorized_operators.is_empty() {
            "none".to_string()
        } else {
            policy.authorized_operators.join(", ")
        };
        return deny(
            DenyReason::InsufficientCredentials,
            format!("operator {} is not authorized for zone {zone} (authorized: {authorized})", requester.operator),
        );
    }

    // 2. When.
    if !(now_s >= rule.active_from_s && now_s < rule.active_until_s) {
        return deny(
            DenyReason::ZoneInactive,
            format!(
                "zone {zone} is not active at {now_s} s (active from {} s until {})",
                rule.active_from_s,
                if rule.active_until_s.is_finite() { format!("{} s", rule.active_until_s) } else { "the end".into() }
            ),
        );
    }

    // 3. Where: the whole band must respect the zone's altitude constraints.
    let band = request.altitude;
    if let Some(min) = policy.min_altitude_agl_m
        && band.min_agl_m < min
    {
        return deny(
            DenyReason::UnsafeAltitude,
            format!(
                "requested band {}-{} m AGL for drone {drone} goes below zone {zone}'s minimum of {min} m AGL",
                band.min_agl_m, band.max_agl_m
            ),
        );
    }
    if let Some(max) = policy.max_altitude_agl_m
        && band.max_agl_m > max
    {
        return deny(
            DenyReason::UnsafeAltitude,
            format!(
                "requested band {}-{} m AGL for drone {drone} goes above zone {zone}'s maximum of {max} m AGL",
                band.min_agl_m, band.max_agl_m
            ),
        );
    }

    // A lease the drone holds is handed back as it is (it does not take a second slot).
    if let Some(lease) = leases.valid(requester.drone, zone, now_s) {
        return Decision::Grant { expires_at_s: lease.expires_at_s, constraints: lease.constraints };
    }

    // 4. How many: leases of other drones valid now.
    if let Some(capacity) = policy.capacity {
        let others = leases
            .leases
            .iter()
            .filter(|l| l.zone == *zone && l.drone != requester.drone && l.is_valid_at(now_s))
            .count();
        if others >= capacity as usize {
            return deny(
                DenyReason::CapacityExhausted,
                format!(
                    "zone {zone} is full: {others} of {capacity} leases are held; drone {drone} may ask again later"
                ),
            );
        }
    }

    Decision::Grant {
        expires_at_s: now_s + rule.lease_s,
        constraints: LeaseConstraints {
            min_altitude_agl_m: policy.min_altitude_agl_m,
            max_altitude_agl_m: policy.max_altitude_agl_m,
        },
    }
}

/// Byte-wise equality whose running time depends only on the lengths, not on where the
/// first difference is, so response times do not reveal a credential's prefix.
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    let mut diff = u8::from(a.len() != b.len());
    for i in 0..a.len().max(b.len()) {
        let (x, y) = (a.get(i).copied().unwrap_or(0), b.get(i).copied().unwrap_or(0));
        diff |= std::hint::black_box(x ^ y);
    }
    diff == 0
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
    /// Leases whose `leaseExpired` was emitted.
    expiry_reported: HashSet<String>,
}

impl Authority {
    /// Rules from `spec.zones`, requesters from the plan's drones. Credentials:
    /// `credential.value`, or for `secretKeyRef` the environment variable
    /// `SADESIM_CREDENTIAL_<GROUP>` given in `secret_env` (the coordinator pod gets the
    /// Secret there); a group without a resolvable credential is never granted.
    pub fn from_plan(plan: &RunPlan, secret_env: &dyn Fn(&str) -> Option<String>) -> Self {
        let rules = plan
            .spec
            .zones
            .iter()
            .map(|z| ZoneRule {
                zone: z.name.clone(),
                policy: z.policy.clone(),
                active_from_s: z.active_from.as_ref().map_or(0.0, duration_s),
                active_until_s: z.active_until.as_ref().map_or(f64::INFINITY, duration_s),
                lease_s: z.policy.lease_duration.as_ref().map_or(DEFAULT_LEASE_S, duration_s),
            })
            .collect();
        let credentials: HashMap<&str, Option<String>> = plan
            .spec
            .fleet
            .iter()
            .map(|g| {
                let credential = match &g.credential {
                    Some(Credential::Value(v)) => Some(v.clone()),
                    Some(Credential::SecretKeyRef(_)) => secret_env(&credential_env_var(&g.name)),
                    None => None,
                };
                // An empty credential would match an empty token: treat it as none.
                (g.name.as_str(), credential.filter(|c| !c.is_empty()))
            })
            .collect();
        let requesters = plan
            .drones
            .iter()
            .map(|d| Requester {
                drone: d.index,
                name: d.name.clone(),
                group: d.group.clone(),
                operator: d.operator.clone(),
                credential: credentials.get(d.group.as_str()).cloned().flatten(),
            })
            .collect();
        Self {
            rules,
            requesters,
            leases: LeaseTable::default(),
            requests: Vec::new(),
            pending: Vec::new(),
            expiry_reported: HashSet::new(),
        }
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
        check_band(request.altitude)?;
        let rule =
            self.rules.iter().find(|r| r.zone == zone).ok_or_else(|| AuthorityError::UnknownZone(zone.into()))?;
        let requester = self
            .requesters
            .iter()
            .find(|r| r.name == request.drone)
            .ok_or_else(|| AuthorityError::UnknownDrone(request.drone.clone()))?;
        let decision = decide(rule, &self.leases, requester, token, request, now_s);

        let request_id = self.requests.len() as u64 + 1;
        let drone = requester.drone;
        let band = request.altitude;
        let mut record = RequestRecord {
            id: request_id,
            time_s: now_s,
            zone: zone.into(),
            drone,
            drone_name: requester.name.clone(),
            operator: request.operator.clone(),
            altitude: band,
            verdict: String::new(),
            reason: None,
            lease: None,
        };
        let mut events = vec![EventKind::ZoneRequested {
            zone: zone.into(),
            request: request_id,
            operator: request.operator.clone(),
            min_agl_m: band.min_agl_m,
            max_agl_m: band.max_agl_m,
        }];
        let verdict = match decision {
            Decision::Grant { expires_at_s, constraints } => {
                let lease = match self.leases.valid(drone, zone, now_s) {
                    Some(held) => held.clone(),
                    None => {
                        let lease = Lease {
                            id: format!("lease-{}", self.leases.leases.len() + 1),
                            zone: zone.into(),
                            drone,
                            drone_name: requester.name.clone(),
                            operator: requester.operator.clone(),
                            granted_at_s: now_s,
                            expires_at_s,
                            released_at_s: None,
                            constraints,
                        };
                        self.leases.leases.push(lease.clone());
                        lease
                    }
                };
                record.verdict = "granted".into();
                record.lease = Some(lease.id.clone());
                events.push(EventKind::ZoneGranted {
                    zone: zone.into(),
                    request: request_id,
                    lease: lease.id.clone(),
                    expires_at_s: lease.expires_at_s,
                    min_altitude_agl_m: lease.constraints.min_altitude_agl_m,
                    max_altitude_agl_m: lease.constraints.max_altitude_agl_m,
                });
                Verdict::Granted { request_id, lease }
            }
            Decision::Deny { reason, message } => {
                record.verdict = "denied".into();
                record.reason = Some(reason);
                events.push(EventKind::ZoneDenied {
                    zone: zone.into(),
                    request: request_id,
                    reason: reason.as_str().into(),
                    message: message.clone(),
                });
                Verdict::Denied { request_id, reason, message }
            }
        };
        self.requests.push(record);
        self.pending.extend(events.into_iter().map(|kind| Event { time_s: now_s, drone: Some(drone), kind }));
        Ok(verdict)
    }

    /// Extends a valid lease by the zone's lease duration from `now_s`.
    ///
    /// # Errors
    /// Unknown lease, wrong token, lease ended.
    pub fn renew(&mut self, lease_id: &str, token: &str, now_s: f64) -> Result<Lease, AuthorityError> {
        let index = self.holder_lease(lease_id, token)?;
        let lease = &self.leases.leases[index];
        if !lease.is_valid_at(now_s) {
            return Err(AuthorityError::LeaseEnded(lease_id.into()));
        }
        let lease_s = self.rules.iter().find(|r| r.zone == lease.zone).map_or(DEFAULT_LEASE_S, |r| r.lease_s);
        let lease = &mut self.leases.leases[index];
        lease.expires_at_s = now_s + lease_s;
        let lease = lease.clone();
        self.pending.push(Event {
            time_s: now_s,
            drone: Some(lease.drone),
            kind: EventKind::LeaseRenewed {
                zone: lease.zone.clone(),
                lease: lease.id.clone(),
                expires_at_s: lease.expires_at_s,
            },
        });
        Ok(lease)
    }

    /// Ends a lease now (idempotent for an already released lease). Releasing a lease that
    /// already expired changes nothing and emits nothing.
    ///
    /// # Errors
    /// Unknown lease, wrong token.
    pub fn release(&mut self, lease_id: &str, token: &str, now_s: f64) -> Result<Lease, AuthorityError> {
        let index = self.holder_lease(lease_id, token)?;
        let lease = &mut self.leases.leases[index];
        if lease.released_at_s.is_none() && now_s < lease.expires_at_s {
            lease.released_at_s = Some(now_s);
            self.pending.push(Event {
                time_s: now_s,
                drone: Some(lease.drone),
                kind: EventKind::LeaseReleased { zone: lease.zone.clone(), lease: lease.id.clone() },
            });
        }
        Ok(self.leases.leases[index].clone())
    }

    /// Emits `leaseExpired` for leases that expired by `now_s` (once each; released leases
    /// never expire). The events are stamped `now_s`, so the log stays in time order; the
    /// exact expiry is the lease's `expires_at_s`.
    pub fn expire(&mut self, now_s: f64) {
        for lease in &self.leases.leases {
            if lease.released_at_s.is_none()
                && now_s >= lease.expires_at_s
                && self.expiry_reported.insert(lease.id.clone())
            {
                self.pending.push(Event {
                    time_s: now_s,
                    drone: Some(lease.drone),
                    kind: EventKind::LeaseExpired { zone: lease.zone.clone(), lease: lease.id.clone() },
                });
            }
        }
    }

    /// Index of lease `lease_id` when `token` is its holder's credential.
    fn holder_lease(&self, lease_id: &str, token: &str) -> Result<usize, AuthorityError> {
        let index = self
            .leases
            .leases
            .iter()
            .position(|l| l.id == lease_id)
            .ok_or_else(|| AuthorityError::UnknownLease(lease_id.into()))?;
        let drone = self.leases.leases[index].drone;
        let credential = self.requesters.iter().find(|r| r.drone == drone).and_then(|r| r.credential.as_deref());
        match credential {
            Some(c) if constant_time_eq(token.as_bytes(), c.as_bytes()) => Ok(index),
            _ => Err(AuthorityError::NotHolder(lease_id.into())),
        }
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

/// The environment variable holding a `secretKeyRef` credential for `group`:
/// `SADESIM_CREDENTIAL_<GROUP>`, upper case with `-` as `_` (`news-crews` ->
/// `SADESIM_CREDENTIAL_NEWS_CREWS`).
pub fn credential_env_var(group: &str) -> String {
    format!("SADESIM_CREDENTIAL_{}", group.to_ascii_uppercase().replace('-', "_"))
}

/// A band the authority can decide on: finite, `0 <= min < max <= MAX_BAND_AGL_M`.
fn check_band(band: AltitudeBand) -> Result<(), AuthorityError> {
    let (min, max) = (band.min_agl_m, band.max_agl_m);
    let problem = if !min.is_finite() || !max.is_finite() {
        Some("altitude.minAglM and altitude.maxAglM must be finite numbers".to_string())
    } else if min < 0.0 {
        Some(format!("altitude.minAglM must be >= 0 m AGL, got {min}"))
    } else if max > MAX_BAND_AGL_M {
        Some(format!("altitude.maxAglM must be <= {MAX_BAND_AGL_M} m AGL, got {max}"))
    } else if min >= max {
        Some(format!("altitude.minAglM ({min}) must be below altitude.maxAglM ({max})"))
    } else {
        None
    };
    problem.map_or(Ok(()), |p| Err(AuthorityError::InvalidBand(p)))
}

#[cfg(test)]
mod tests;
