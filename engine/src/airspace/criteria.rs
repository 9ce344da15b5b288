//! The run's verdict: each of the scenario's `criteria` judged on the compliance report
//! and the authority's request log when the run ends. A run passes when every criterion
//! does; `sadesim run` then exits 0, else 1 (so CI pipelines can gate on it).
//!
//! What each criterion checks:
//! - `noUnauthorizedEntries`: no `unauthorizedEntry` violation.
//! - `zoneConstraintsRespected`: no `belowZoneMinimum` or `aboveZoneMaximum` violation.
//! - `altitudeLimitsRespected`: no `aboveAltitudeLimit` violation, nor
//!   `belowAltitudeMinimum` (groups with `altitude.minAglM`: below it while cruising).
//! - `noCrashes`: no crash.
//! - `minSeparation {distanceM}`: the closest approach between airborne drones is at least
//!   `distanceM` (each loss of separation is a failure line).
//! - `reachZone {groups, zone, within}`: every drone of the groups entered the zone at or
//!   before `within` (sim time from the start).
//! - `zoneVerdicts {groups, zone, expect}`: at least one drone of the groups asked for the
//!   zone, and no request of theirs for it got the other verdict. Drones that never asked
//!   are named in the summary but do not fail it (a drone may never need the zone).
//!
//! - `estimatedPositionError {groups, maxHorizontalM}`: while airborne, no drone of the
//!   groups (every drone when empty) had its estimated position farther than
//!   `maxHorizontalM` from the truth (one failure line per drone, at its worst moment).
//!
//! - `landedNear {groups, marker, withinM}`: every drone of the groups (every drone when
//!   empty) ended the run on the ground and not crashed, its last touchdown within
//!   `withinM` of the marker's centre (one failure line per drone that did not).
//!
//! Failure lines name the drone, the sim time (seconds, 2 decimals), the duration, the
//! place (latitude and longitude to 5 decimals, about 1 m; height above ground) and the
//! zone, so a reader can find the moment in the events log and on a map.

use std::collections::BTreeSet;

use sadesim_crds::criteria::{Criterion, Expectation};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::validate::duration_s;

pub use sadesim_crds::outcome::verdict::{CriterionResult, RunVerdict};

use super::authority::RequestRecord;
use super::monitor::{ComplianceReport, ViolationKind, ViolationRecord};
use crate::events::Place;
use sadesim_crds::outcome::compliance::PositionError;

/// Most drone names a summary lists (the rest are counted).
pub const MAX_NAMES_IN_SUMMARY: usize = 20;

/// Judges `plan.spec.criteria`. `end_s` is the sim time the run ended: violations still
/// open (the monitor was not finished) last until then.
pub fn evaluate(plan: &RunPlan, report: &ComplianceReport, requests: &[RequestRecord], end_s: f64) -> RunVerdict {
    let judge = Judge { plan, report, requests, end_s };
    let criteria: Vec<CriterionResult> =
        plan.spec.criteria.iter().enumerate().map(|(i, c)| judge.criterion(i, c)).collect();
    RunVerdict { passed: criteria.iter().all(|c| c.passed), criteria }
}

/// The criterion's kind as written in the scenario.
pub fn criterion_name(c: &Criterion) -> &'static str {
    match c {
        Criterion::NoUnauthorizedEntries {} => "noUnauthorizedEntries",
        Criterion::ZoneConstraintsRespected {} => "zoneConstraintsRespected",
        Criterion::AltitudeLimitsRespected {} => "altitudeLimitsRespected",
        Criterion::NoCrashes {} => "noCrashes",
        Criterion::MinSeparation { .. } => "minSeparation",
        Criterion::ReachZone { .. } => "reachZone",
        Criterion::ZoneVerdicts { .. } => "zoneVerdicts",
        Criterion::EstimatedPositionError { .. } => "estimatedPositionError",
        Criterion::LandedNear { .. } => "landedNear",
    }
}

/// What every criterion is judged on.
struct Judge<'a> {
    plan: &'a RunPlan,
    report: &'a ComplianceReport,
    requests: &'a [RequestRecord],
    end_s: f64,
}

/// A criterion's outcome before it gets its path and name.
struct Outcome {
    passed: bool,
    summary: String,
    failures: Vec<String>,
}

impl Judge<'_> {
    fn criterion(&self, i: usize, c: &Criterion) -> CriterionResult {
        let outcome = match c {
            Criterion::NoUnauthorizedEntries {} => self.no_violations(
                &[ViolationKind::UnauthorizedEntry],
                "no drone was inside an active zone without a valid lease",
                "unauthorized entries",
            ),
            Criterion::ZoneConstraintsRespected {} => self.no_violations(
                &[ViolationKind::BelowZoneMinimum, ViolationKind::AboveZoneMaximum],
                "drones inside zones kept to their leases' altitude constraints",
                "breaches of a lease's altitude constraints",
            ),
            Criterion::AltitudeLimitsRespected {} if self.any_altitude_minimum() => self.no_violations(
                &[ViolationKind::AboveAltitudeLimit, ViolationKind::BelowAltitudeMinimum],
                "every drone stayed within its group's altitude limits (at or below maxAglM, at or above minAglM while cruising)",
                "flights outside a group's altitude limits",
            ),
            Criterion::AltitudeLimitsRespected {} => self.no_violations(
                &[ViolationKind::AboveAltitudeLimit],
                "every drone stayed at or below its group's altitude limit",
                "flights above a group's altitude limit",
            ),
            Criterion::NoCrashes {} => self.no_crashes(),
            Criterion::MinSeparation { distance_m } => self.min_separation(*distance_m),
            Criterion::ReachZone { groups, zone, within } => self.reach_zone(groups, zone, duration_s(within)),
            Criterion::ZoneVerdicts { groups, zone, expect } => self.zone_verdicts(groups, zone, *expect),
            Criterion::EstimatedPositionError { groups, max_horizontal_m } => {
                self.position_error(groups, *max_horizontal_m)
            }
            Criterion::LandedNear { groups, marker, within_m } => self.landed_near(groups, marker, *within_m),
        };
        CriterionResult {
            path: format!("spec.criteria[{i}]"),
            criterion: criterion_name(c).to_string(),
            passed: outcome.passed,
            summary: outcome.summary,
            failures: outcome.failures,
        }
    }

    /// Whether some group sets `altitude.minAglM` (judged by `altitudeLimitsRespected`).
    fn any_altitude_minimum(&self) -> bool {
        self.plan.spec.fleet.iter().any(|g| g.altitude.min_agl_m.is_some())
    }

    fn name(&self, drone: u32) -> String {
        self.plan.drones.get(drone as usize).map_or_else(|| format!("drone {drone}"), |d| d.name.clone())
    }

    /// Passes when the report has no violation of `kinds`.
    fn no_violations(&self, kinds: &[ViolationKind], passed: &str, what: &str) -> Outcome {
        let found: Vec<&ViolationRecord> = self.report.violations.iter().filter(|v| kinds.contains(&v.kind)).collect();
        let drones: BTreeSet<u32> = found.iter().map(|v| v.drone).collect();
        Outcome {
            passed: found.is_empty(),
            summary: if found.is_empty() {
                passed.to_string()
            } else {
                format!("{} {what} by {} drones", found.len(), drones.len())
            },
            failures: found.iter().map(|v| self.violation_line(v)).collect(),
        }
    }

    /// One violation as a human line.
    fn violation_line(&self, v: &ViolationRecord) -> String {
        let who = &v.drone_name;
        let zone = v.zone.as_deref().unwrap_or("?");
        let limit_m = v.limit_m.unwrap_or(f64::NAN);
        let worst_m = v.worst_m;
        let duration_s = v.end_s.unwrap_or(self.end_s) - v.start_s;
        let until_end = if v.end_s.is_none() { ", until the end" } else { "" };
        let when = format!("from {:.2} s for {duration_s:.2} s{until_end}", v.start_s);
        let at = place(&v.at);
        match v.kind {
            ViolationKind::UnauthorizedEntry => format!("{who} inside {zone} without a lease {when} at {at}"),
            ViolationKind::BelowZoneMinimum => format!(
                "{who} inside {zone} below the lease's minimum of {limit_m:.1} m AGL {when} at {at}; lowest {worst_m:.1} m AGL"
            ),
            ViolationKind::AboveZoneMaximum => format!(
                "{who} inside {zone} above the lease's maximum of {limit_m:.1} m AGL {when} at {at}; highest {worst_m:.1} m AGL"
            ),
            ViolationKind::AboveAltitudeLimit => format!(
                "{who} above its group's limit of {limit_m:.1} m AGL {when} at {at}; highest {worst_m:.1} m AGL"
            ),
            ViolationKind::BelowAltitudeMinimum => format!(
                "{who} below its group's minimum of {limit_m:.1} m AGL while cruising {when} at {at}; lowest {worst_m:.1} m AGL"
            ),
            ViolationKind::SeparationLoss => {
                let other = v.other.map_or_else(|| "?".to_string(), |o| self.name(o));
                format!("{who} and {other} closer than {limit_m:.1} m {when} at {at}; closest {worst_m:.2} m")
            }
        }
    }

    fn no_crashes(&self) -> Outcome {
        let crashes = &self.report.crashes;
        let failures = crashes
            .iter()
            .enumerate()
            .map(|(k, &(drone, time_s))| match self.report.crash_places.get(k) {
                Some(at) => format!("{} crashed at {time_s:.2} s at {}", self.name(drone), place(at)),
                None => format!("{} crashed at {time_s:.2} s", self.name(drone)),
            })
            .collect();
        Outcome {
            passed: crashes.is_empty(),
            summary: if crashes.is_empty() {
                "no drone crashed".to_string()
            } else {
                format!("{} of {} drones crashed", crashes.len(), self.plan.drones.len())
            },
            failures,
        }
    }

    /// Each drone of `groups` (all when empty) against its worst estimated-position error.
    fn position_error(&self, groups: &[String], max_m: f64) -> Outcome {
        let judged: Vec<(u32, Option<&PositionError>)> = self
            .plan
            .drones
            .iter()
            .filter(|d| groups.is_empty() || groups.contains(&d.group))
            .map(|d| (d.index, self.report.worst_position_errors.get(d.index as usize).and_then(Option::as_ref)))
            .collect();
        let worst = judged
            .iter()
            .filter_map(|(d, e)| e.map(|e| (*d, e)))
            .max_by(|a, b| a.1.horizontal_m.total_cmp(&b.1.horizontal_m));
        let failures: Vec<String> = judged
            .iter()
            .filter_map(|(d, e)| e.filter(|e| e.horizontal_m > max_m).map(|e| (*d, e)))
            .map(|(d, e)| {
                format!(
                    "{}: estimate {:.1} m from the truth at {:.2} s at {} (limit {max_m} m)",
                    self.name(d),
                    e.horizontal_m,
                    e.time_s,
                    place(&e.at)
                )
            })
            .collect();
        let summary = match worst {
            None => "no drone of the groups was airborne with a position estimate".to_string(),
            Some((d, e)) if failures.is_empty() => format!(
                "every estimate stayed within {max_m} m of the truth (worst {:.1} m, {})",
                e.horizontal_m,
                self.name(d)
            ),
            Some(_) => format!("{} of {} drones' estimates strayed over {max_m} m", failures.len(), judged.len()),
        };
        Outcome { passed: failures.is_empty(), summary, failures }
    }

    /// Each drone of `groups` (all when empty) against where it last touched down.
    fn landed_near(&self, groups: &[String], marker: &str, within_m: f64) -> Outcome {
        let world = self.plan.spec.world();
        let Some(pad) = world.markers.iter().find(|m| m.name == marker) else {
            let failures = vec![format!("no marker {marker:?} in spec.world.markers")];
            return Outcome { passed: false, summary: failures[0].clone(), failures };
        };
        let frame = sadesim_crds::geo::LocalFrame::new(self.plan.spec.origin.geo());
        let (east, north) = frame.to_plane(pad.position.latitude_deg, pad.position.longitude_deg);
        let judged: Vec<u32> = self
            .plan
            .drones
            .iter()
            .filter(|d| groups.is_empty() || groups.contains(&d.group))
            .map(|d| d.index)
            .collect();
        let crashed = |d: u32| self.report.crashes.iter().any(|c| c.0 == d);
        let mut closest: Option<f64> = None;
        let mut failures = Vec::new();
        for &d in &judged {
            let touchdown = self.report.touchdowns.get(d as usize).and_then(Option::as_ref);
            match touchdown {
                _ if crashed(d) => failures.push(format!("{} crashed", self.name(d))),
                None => failures.push(format!(
                    "{} did not end the run landed (it never touched down, or took off again)",
                    self.name(d)
                )),
                Some(t) => {
                    let off = (t.at.east_m - east).hypot(t.at.north_m - north);
                    closest = Some(closest.map_or(off, |c: f64| c.max(off)));
                    if off > within_m {
                        failures.push(format!(
                            "{} touched down {off:.2} m from {marker} at {:.2} s at {} (limit {within_m} m)",
                            self.name(d),
                            t.time_s,
                            place(&t.at)
                        ));
                    }
                }
            }
        }
        if judged.is_empty() {
            failures.push(format!("no drone belongs to {}", groups.join(", ")));
        }
        let summary = match closest {
            Some(worst) if failures.is_empty() => {
                format!("{} drones landed within {within_m} m of {marker} (farthest {worst:.2} m)", judged.len())
            }
            _ => format!(
                "{} of {} drones landed within {within_m} m of {marker}",
                judged.len().saturating_sub(failures.len()),
                judged.len()
            ),
        };
        Outcome { passed: failures.is_empty(), summary, failures }
    }

    /// The monitor records losses below the smallest `minSeparation` distance; a larger
    /// distance also fails on a closest approach between the two.
    fn min_separation(&self, distance_m: f64) -> Outcome {
        let losses: Vec<&ViolationRecord> = self
            .report
            .violations
            .iter()
            .filter(|v| v.kind == ViolationKind::SeparationLoss && v.worst_m < distance_m)
            .collect();
        let mut failures: Vec<String> = losses.iter().map(|v| self.violation_line(v)).collect();
        let closest = self.report.closest_approach.filter(|c| c.0 < distance_m);
        if let (Some((d, t, a, b)), true) = (closest, failures.is_empty()) {
            failures.push(format!("{} and {} came {d:.2} m apart at {t:.2} s", self.name(a), self.name(b)));
        }
        let summary = match closest {
            None => format!("no two airborne drones came closer than {distance_m:.1} m"),
            Some((d, t, a, b)) => format!(
                "closest approach {d:.2} m between {} and {} at {t:.2} s, below {distance_m:.1} m; {} losses of separation",
                self.name(a),
                self.name(b),
                losses.len()
            ),
        };
        Outcome { passed: failures.is_empty(), summary, failures }
    }

    /// Indices of the drones of `groups`.
    fn drones_of(&self, groups: &[String]) -> Vec<u32> {
        self.plan.drones.iter().filter(|d| groups.contains(&d.group)).map(|d| d.index).collect()
    }

    fn reach_zone(&self, groups: &[String], zone: &str, within_s: f64) -> Outcome {
        let drones = self.drones_of(groups);
        let who = groups.join(", ");
        let mut failures = Vec::new();
        for &d in &drones {
            let first = self
                .report
                .presences
                .iter()
                .filter(|p| p.drone == d && p.zone == zone)
                .map(|p| p.entered_s)
                .min_by(f64::total_cmp);
            match first {
                Some(t) if t <= within_s => {}
                Some(t) => failures.push(format!(
                    "{} entered {zone} only at {t:.2} s, after the deadline of {within_s:.2} s",
                    self.name(d)
                )),
                None => failures.push(format!("{} never entered {zone}", self.name(d))),
            }
        }
        if drones.is_empty() {
            failures.push(format!("no drone belongs to {who}"));
        }
        let reached = drones.len().saturating_sub(failures.len());
        Outcome {
            passed: failures.is_empty(),
            summary: format!("{reached} of {} drones of {who} entered {zone} within {within_s:.2} s", drones.len()),
            failures,
        }
    }

    fn zone_verdicts(&self, groups: &[String], zone: &str, expect: Expectation) -> Outcome {
        let (expected, other) = match expect {
            Expectation::Granted => ("granted", "denied"),
            Expectation::Denied => ("denied", "granted"),
        };
        let drones = self.drones_of(groups);
        let members: BTreeSet<u32> = drones.iter().copied().collect();
        let who = groups.join(", ");
        let theirs: Vec<&RequestRecord> =
            self.requests.iter().filter(|r| r.zone == zone && members.contains(&r.drone)).collect();
        let asked: BTreeSet<u32> = theirs.iter().map(|r| r.drone).collect();
        let mut failures: Vec<String> = theirs
            .iter()
            .filter(|r| r.verdict != expected)
            .map(|r| {
                let why = match (&r.reason, &r.lease) {
                    (Some(reason), _) => format!(" ({})", reason.as_str()),
                    (None, Some(lease)) => format!(" ({lease})"),
                    (None, None) => String::new(),
                };
                format!(
                    "{} was {} {zone} at {:.2} s{why}, request {}; expected {expected}",
                    r.drone_name, r.verdict, r.time_s, r.id
                )
            })
            .collect();
        let wrong = failures.len();
        if asked.is_empty() {
            failures.push(format!("no drone of {who} asked for {zone}"));
        }
        let mut summary = format!("{} of {} drones of {who} asked for {zone}", asked.len(), drones.len());
        if wrong == 0 {
            summary.push_str(&format!("; all {expected}"));
        } else {
            summary.push_str(&format!("; {wrong} of {} requests {other}", theirs.len()));
        }
        let silent: Vec<String> = drones.iter().filter(|d| !asked.contains(d)).map(|&d| self.name(d)).collect();
        if !silent.is_empty() {
            summary.push_str(&format!("; never asked: {}", names_list(&silent)));
        }
        Outcome { passed: failures.is_empty(), summary, failures }
    }
}

/// "a, b, c", or the first [`MAX_NAMES_IN_SUMMARY`] and "and N more".
fn names_list(names: &[String]) -> String {
    if names.len() <= MAX_NAMES_IN_SUMMARY {
        names.join(", ")
    } else {
        format!("{} and {} more", names[..MAX_NAMES_IN_SUMMARY].join(", "), names.len() - MAX_NAMES_IN_SUMMARY)
    }
}

/// "41.88011 N 87.62301 W, 104.2 m AGL".
fn place(p: &Place) -> String {
    let ns = if p.latitude_deg >= 0.0 { 'N' } else { 'S' };
    let ew = if p.longitude_deg >= 0.0 { 'E' } else { 'W' };
    format!("{:.5} {ns} {:.5} {ew}, {:.1} m AGL", p.latitude_deg.abs(), p.longitude_deg.abs(), p.height_agl_m)
}

#[cfg(test)]
mod tests;
