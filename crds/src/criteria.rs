//! Pass/fail criteria evaluated when a run ends. A run fails when any criterion fails;
//! `sadesim run` then exits non-zero so CI pipelines can gate on it.

use kube::core::Duration;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The verdict a zone request is expected to get: `granted` or `denied`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub enum Expectation {
    Granted,
    Denied,
}

/// One criterion. Each is an object keyed by its kind, e.g. `- noUnauthorizedEntries: {}`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", rename_all_fields = "camelCase", deny_unknown_fields)]
pub enum Criterion {
    /// No drone is inside an active zone without a valid lease.
    NoUnauthorizedEntries {},
    /// Drones inside a zone respect the zone's altitude constraints.
    ZoneConstraintsRespected {},
    /// Every drone stays within its group's altitude limits: at or below `maxAglM`
    /// anywhere, and at or above `minAglM` while cruising (from its first climb to
    /// `minAglM` until it lands or switches to `land` or `returnToLaunch`).
    AltitudeLimitsRespected {},
    /// No drone crashes (building or ground contact above landing speed).
    NoCrashes {},
    /// Airborne drones never come closer to each other than `distanceM`.
    MinSeparation {
        /// Minimum 3-D distance between any two airborne drones, metres (0.1..10000).
        #[schemars(range(min = 0.1, max = 10000.0))]
        distance_m: f64,
    },
    /// Every drone of `groups` is inside `zone` within `within` of sim time.
    ReachZone {
        /// Fleet group names.
        #[schemars(length(min = 1, max = 64), inner(length(max = 40)))]
        groups: Vec<String>,
        /// Zone name.
        #[schemars(length(min = 1, max = 63))]
        zone: String,
        /// Deadline in sim time from the start (Go duration).
        within: Duration,
    },
    /// Every drone of `groups` that asked for `zone` got the `expect`ed verdict, and at
    /// least one asked.
    ZoneVerdicts {
        /// Fleet group names.
        #[schemars(length(min = 1, max = 64), inner(length(max = 40)))]
        groups: Vec<String>,
        /// Zone name.
        #[schemars(length(min = 1, max = 63))]
        zone: String,
        /// `granted` or `denied`.
        expect: Expectation,
    },
    /// Airborne drones of `groups` (every drone when empty) keep their estimated position,
    /// what the autopilot flies on, within `maxHorizontalM` of the truth: a pilot gated in
    /// CI on a GNSS-degraded scenario (urban canyons, outages).
    EstimatedPositionError {
        /// Fleet group names; empty means every drone.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        #[schemars(length(max = 64), inner(length(max = 40)))]
        groups: Vec<String>,
        /// Largest allowed horizontal distance between the estimate and the truth, metres
        /// (0.1..1000).
        #[schemars(range(min = 0.1, max = 1000.0))]
        max_horizontal_m: f64,
    },
    /// Every drone of `groups` (every drone when empty) ends the run on the ground, not
    /// crashed, having last touched down within `withinM` (horizontally) of the centre of
    /// the world marker `marker`: a landing on a pad.
    LandedNear {
        /// Fleet group names; empty means every drone.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        #[schemars(length(max = 64), inner(length(max = 40)))]
        groups: Vec<String>,
        /// A marker of `spec.world.markers` (its `name`).
        #[schemars(length(min = 1, max = 63))]
        marker: String,
        /// Largest horizontal distance from the marker's centre to where the drone touched
        /// down, metres (0.01..1000).
        #[schemars(range(min = 0.01, max = 1000.0))]
        within_m: f64,
    },
}
