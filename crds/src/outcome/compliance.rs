//! The airspace records of a run: the authority's requests, verdicts and leases, and the
//! compliance monitor's violations and zone stays (`airspace.json`, the report, the
//! criteria). Altitudes are metres above ground (AGL), times simulated seconds.

use serde::{Deserialize, Serialize};

use super::events::Place;

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
    /// Below the group's `altitude.minAglM` while cruising (takeoff and landing excepted).
    BelowAltitudeMinimum,
}

impl ViolationKind {
    /// The rule's name in events and reports (the serde name).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::UnauthorizedEntry => "unauthorizedEntry",
            Self::BelowZoneMinimum => "belowZoneMinimum",
            Self::AboveZoneMaximum => "aboveZoneMaximum",
            Self::AboveAltitudeLimit => "aboveAltitudeLimit",
            Self::SeparationLoss => "separationLoss",
            Self::BelowAltitudeMinimum => "belowAltitudeMinimum",
        }
    }

    /// Whether the worst value of an episode is the highest one seen (altitude above a
    /// ceiling) rather than the lowest (altitude below a floor, distance, the lowest AGL
    /// altitude of an unauthorized stay).
    pub fn worst_is_highest(self) -> bool {
        matches!(self, Self::AboveZoneMaximum | Self::AboveAltitudeLimit)
    }
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
    /// `None` while it lasts; the monitor's `finish` closes every open one.
    pub end_s: Option<f64>,
    /// Where it started.
    pub at: Place,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit_m: Option<f64>,
    /// Furthest value reached (AGL metres, or distance metres for separation). For an
    /// unauthorized entry: the lowest AGL altitude inside.
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
    /// Lowest height above ground inside, metres (at the entry point and the window
    /// samples inside).
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
    /// Where each crash of `crashes` happened (same order): the wreck at the end of the
    /// crash's window.
    #[serde(default)]
    pub crash_places: Vec<Place>,
    /// Closest approach between two airborne drones: (distance m, time s, drone, drone),
    /// tracked when the scenario has a `minSeparation` criterion.
    ///
    /// # Guarantees
    /// Exact (over the window samples) whenever it is below the largest `minSeparation`
    /// distance: every pair closer than that is compared. Above it, it is the closest pair
    /// among those the grid compared (neighbouring cells), so the true closest approach
    /// may be smaller, but still at least that distance; `None` when no two airborne
    /// drones were ever in neighbouring cells.
    pub closest_approach: Option<(f64, f64, u32, u32)>,
    /// Per drone (index order), the largest horizontal distance between its estimated and
    /// its true position while airborne, tracked when the scenario has an
    /// `estimatedPositionError` criterion; `None` for a drone never airborne with an
    /// estimate.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub worst_position_errors: Vec<Option<PositionError>>,
    /// Per drone (index order), where it last touched down (a `landed` event; the drone at
    /// the end of that window), `None` once it takes off again or crashes and for a drone
    /// that never landed: tracked when the scenario has a `landedNear` criterion.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub touchdowns: Vec<Option<Touchdown>>,
}

/// Where and when a drone touched down.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Touchdown {
    pub time_s: f64,
    pub at: Place,
}

/// A drone's worst estimated-position error: how far, when, where (the truth).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct PositionError {
    pub horizontal_m: f64,
    pub time_s: f64,
    pub at: Place,
}
