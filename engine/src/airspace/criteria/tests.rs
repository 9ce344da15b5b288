use sadesim_crds::criteria::{Criterion, Expectation};
use sadesim_crds::plan::RunPlan;

use super::*;
use crate::airspace::authority::{AltitudeBand, DenyReason};
use crate::airspace::monitor::{Presence, ViolationKind, ViolationRecord};
use crate::fixtures::{plan_of, rect_zone, run_with_groups};

/// Two public-safety drones, three journalists, the zone `tfr`, and `criteria`.
fn plan(criteria: Vec<Criterion>) -> RunPlan {
    plan_of(
        run_with_groups(&[("public-safety", 2), ("journalists", 3)])
            .with(|r| r.spec.zones.push(rect_zone("tfr", (0.0, 100.0), (0.0, 100.0), 0.0, 150.0)))
            .with(|r| r.spec.criteria = criteria)
            // Long enough for the 300 s `reachZone` windows below (the planner refuses a
            // window longer than the run).
            .with(|r| r.spec.duration = "10m".parse().unwrap())
            .build(),
    )
}

/// Drone indices: public-safety-0, -1 are 0 and 1; journalists-0..2 are 2..4.
const PS0: u32 = 0;
const PS1: u32 = 1;
const J0: u32 = 2;
const J1: u32 = 3;

fn museum() -> Place {
    Place { latitude_deg: 41.88011, longitude_deg: -87.62301, height_agl_m: 104.2, ..Place::default() }
}

fn violation(kind: ViolationKind, drone: u32, name: &str, start_s: f64, end_s: Option<f64>) -> ViolationRecord {
    let zone_rule = matches!(
        kind,
        ViolationKind::UnauthorizedEntry | ViolationKind::BelowZoneMinimum | ViolationKind::AboveZoneMaximum
    );
    ViolationRecord {
        kind,
        drone,
        drone_name: name.into(),
        other: None,
        zone: zone_rule.then(|| "tfr".to_string()),
        start_s,
        end_s,
        at: museum(),
        limit_m: None,
        worst_m: 104.2,
    }
}

fn presence(drone: u32, entered_s: f64) -> Presence {
    Presence { drone, zone: "tfr".into(), entered_s, exited_s: None, authorized: true, min_agl_m: 110.0 }
}

fn request(id: u64, drone: u32, name: &str, granted: bool) -> RequestRecord {
    RequestRecord {
        id,
        time_s: 10.0 + id as f64,
        zone: "tfr".into(),
        drone,
        drone_name: name.into(),
        operator: "acme".into(),
        altitude: AltitudeBand { min_agl_m: 110.0, max_agl_m: 140.0 },
        verdict: if granted { "granted" } else { "denied" }.into(),
        reason: (!granted).then_some(DenyReason::InsufficientCredentials),
        lease: granted.then(|| format!("lease-{id}")),
    }
}

/// The one criterion of `plan` judged on `report` and `requests`.
fn judge(criterion: Criterion, report: &ComplianceReport, requests: &[RequestRecord]) -> CriterionResult {
    let verdict = evaluate(&plan(vec![criterion]), report, requests, 600.0);
    assert_eq!(verdict.criteria.len(), 1);
    assert_eq!(verdict.passed, verdict.criteria[0].passed);
    verdict.criteria.into_iter().next().unwrap()
}

#[test]
fn a_run_without_criteria_passes() {
    let verdict = evaluate(&plan(vec![]), &ComplianceReport::default(), &[], 60.0);
    assert!(verdict.passed && verdict.criteria.is_empty());
}

#[test]
fn no_unauthorized_entries_lists_each_entry_with_drone_time_duration_and_place() {
    let ok = judge(Criterion::NoUnauthorizedEntries {}, &ComplianceReport::default(), &[]);
    assert!(ok.passed && ok.failures.is_empty());
    assert_eq!((ok.path.as_str(), ok.criterion.as_str()), ("spec.criteria[0]", "noUnauthorizedEntries"));
    let report = ComplianceReport {
        violations: vec![
            violation(ViolationKind::UnauthorizedEntry, J1, "journalists-1", 312.4, Some(330.6)),
            // Other rules are not this criterion's business.
            violation(ViolationKind::AboveAltitudeLimit, J0, "journalists-0", 1.0, Some(2.0)),
            violation(ViolationKind::UnauthorizedEntry, J0, "journalists-0", 590.0, None),
        ],
        ..Default::default()
    };
    let r = judge(Criterion::NoUnauthorizedEntries {}, &report, &[]);
    assert!(!r.passed);
    assert_eq!(r.summary, "2 unauthorized entries by 2 drones");
    assert_eq!(
        r.failures,
        [
            "journalists-1 inside tfr without a lease from 312.40 s for 18.20 s at 41.88011 N 87.62301 W, 104.2 m AGL",
            "journalists-0 inside tfr without a lease from 590.00 s for 10.00 s, until the end at 41.88011 N 87.62301 W, 104.2 m AGL",
        ]
    );
}

#[test]
fn zone_constraints_fail_on_breaches_below_or_above_a_lease_band() {
    let unrelated = ComplianceReport {
        violations: vec![violation(ViolationKind::UnauthorizedEntry, J0, "journalists-0", 1.0, Some(2.0))],
        ..Default::default()
    };
    assert!(judge(Criterion::ZoneConstraintsRespected {}, &unrelated, &[]).passed);
    let mut below = violation(ViolationKind::BelowZoneMinimum, PS0, "public-safety-0", 40.0, Some(41.5));
    (below.limit_m, below.worst_m) = (Some(106.7), 98.24);
    let mut above = violation(ViolationKind::AboveZoneMaximum, PS1, "public-safety-1", 50.0, Some(50.5));
    (above.limit_m, above.worst_m) = (Some(140.0), 141.0);
    let report = ComplianceReport { violations: vec![below, above], ..Default::default() };
    let r = judge(Criterion::ZoneConstraintsRespected {}, &report, &[]);
    assert!(!r.passed);
    assert_eq!(
        r.failures,
        [
            "public-safety-0 inside tfr below the lease's minimum of 106.7 m AGL from 40.00 s for 1.50 s at 41.88011 N 87.62301 W, 104.2 m AGL; lowest 98.2 m AGL",
            "public-safety-1 inside tfr above the lease's maximum of 140.0 m AGL from 50.00 s for 0.50 s at 41.88011 N 87.62301 W, 104.2 m AGL; highest 141.0 m AGL",
        ]
    );
}

/// With a group `altitude.minAglM`, `altitudeLimitsRespected` also fails on flying below it
/// while cruising, and says so in its summary.
#[test]
fn altitude_limits_fail_below_a_group_minimum_when_a_group_sets_one() {
    let plan = |min: Option<f64>| {
        plan_of(
            run_with_groups(&[("journalists", 3)])
                .with(|r| r.spec.fleet[0].altitude.min_agl_m = min)
                .with(|r| r.spec.criteria = vec![Criterion::AltitudeLimitsRespected {}])
                .build(),
        )
    };
    let mut v = violation(ViolationKind::BelowAltitudeMinimum, 1, "journalists-1", 7.0, Some(9.0));
    (v.limit_m, v.worst_m) = (Some(30.0), 21.5);
    let report = ComplianceReport { violations: vec![v], ..Default::default() };
    let verdict = evaluate(&plan(Some(30.0)), &report, &[], 600.0);
    let r = &verdict.criteria[0];
    assert!(!verdict.passed && !r.passed);
    assert_eq!(r.summary, "1 flights outside a group's altitude limits by 1 drones");
    assert_eq!(
        r.failures,
        [
            "journalists-1 below its group's minimum of 30.0 m AGL while cruising from 7.00 s for 2.00 s at 41.88011 N 87.62301 W, 104.2 m AGL; lowest 21.5 m AGL"
        ]
    );
    let clean = evaluate(&plan(Some(30.0)), &ComplianceReport::default(), &[], 600.0);
    assert!(clean.passed);
    assert!(clean.criteria[0].summary.contains("at or above minAglM while cruising"), "{:?}", clean.criteria[0]);
    // Without a minimum the summary is the one it always was.
    let none = evaluate(&plan(None), &ComplianceReport::default(), &[], 600.0);
    assert_eq!(none.criteria[0].summary, "every drone stayed at or below its group's altitude limit");
}

#[test]
fn altitude_limits_fail_on_any_flight_above_a_group_limit() {
    assert!(judge(Criterion::AltitudeLimitsRespected {}, &ComplianceReport::default(), &[]).passed);
    let mut v = violation(ViolationKind::AboveAltitudeLimit, J0, "journalists-0", 7.0, Some(9.0));
    (v.limit_m, v.worst_m) = (Some(120.0), 133.3);
    let report = ComplianceReport { violations: vec![v], ..Default::default() };
    let r = judge(Criterion::AltitudeLimitsRespected {}, &report, &[]);
    assert!(!r.passed);
    assert_eq!(r.summary, "1 flights above a group's altitude limit by 1 drones");
    assert_eq!(
        r.failures,
        [
            "journalists-0 above its group's limit of 120.0 m AGL from 7.00 s for 2.00 s at 41.88011 N 87.62301 W, 104.2 m AGL; highest 133.3 m AGL"
        ]
    );
}

#[test]
fn no_crashes_names_each_crash_with_time_and_place() {
    assert!(judge(Criterion::NoCrashes {}, &ComplianceReport::default(), &[]).passed);
    let report = ComplianceReport { crashes: vec![(J1, 12.346)], crash_places: vec![museum()], ..Default::default() };
    let r = judge(Criterion::NoCrashes {}, &report, &[]);
    assert!(!r.passed);
    assert_eq!(r.summary, "1 of 5 drones crashed");
    assert_eq!(r.failures, ["journalists-1 crashed at 12.35 s at 41.88011 N 87.62301 W, 104.2 m AGL"]);
}

#[test]
fn min_separation_passes_on_a_closest_approach_at_or_above_the_distance() {
    let report = ComplianceReport { closest_approach: Some((10.0, 5.0, PS0, J0)), ..Default::default() };
    let r = judge(Criterion::MinSeparation { distance_m: 10.0 }, &report, &[]);
    assert!(r.passed, "{r:?}");
    assert_eq!(r.summary, "no two airborne drones came closer than 10.0 m");
    assert!(judge(Criterion::MinSeparation { distance_m: 10.0 }, &ComplianceReport::default(), &[]).passed);
}

#[test]
fn min_separation_lists_each_loss_and_a_larger_distance_fails_on_the_closest_approach() {
    let mut loss = violation(ViolationKind::SeparationLoss, PS0, "public-safety-0", 20.0, Some(21.0));
    (loss.other, loss.limit_m, loss.worst_m) = (Some(J0), Some(5.0), 3.257);
    let report = ComplianceReport {
        violations: vec![loss],
        closest_approach: Some((3.257, 20.5, PS0, J0)),
        ..Default::default()
    };
    let r = judge(Criterion::MinSeparation { distance_m: 5.0 }, &report, &[]);
    assert!(!r.passed);
    assert_eq!(
        r.summary,
        "closest approach 3.26 m between public-safety-0 and journalists-0 at 20.50 s, below 5.0 m; 1 losses of separation"
    );
    assert_eq!(
        r.failures,
        [
            "public-safety-0 and journalists-0 closer than 5.0 m from 20.00 s for 1.00 s at 41.88011 N 87.62301 W, 104.2 m AGL; closest 3.26 m"
        ]
    );
    // With a 5 m and a 20 m criterion the monitor records losses below 5 m only; a
    // closest approach of 12 m still fails the 20 m one.
    let report = ComplianceReport { closest_approach: Some((12.0, 30.0, PS1, J1)), ..Default::default() };
    let r = judge(Criterion::MinSeparation { distance_m: 20.0 }, &report, &[]);
    assert!(!r.passed);
    assert_eq!(r.failures, ["public-safety-1 and journalists-1 came 12.00 m apart at 30.00 s"]);
}

fn reach(within: &str) -> Criterion {
    Criterion::ReachZone { groups: vec!["public-safety".into()], zone: "tfr".into(), within: within.parse().unwrap() }
}

#[test]
fn reach_zone_passes_when_every_drone_of_the_groups_entered_in_time() {
    let report = ComplianceReport {
        // The first stay counts; journalists are not part of the criterion.
        presences: vec![presence(PS0, 200.0), presence(PS1, 280.0), presence(PS0, 400.0)],
        ..Default::default()
    };
    let r = judge(reach("5m"), &report, &[]);
    assert!(r.passed, "{r:?}");
    assert_eq!(r.summary, "2 of 2 drones of public-safety entered tfr within 300.00 s");
}

#[test]
fn reach_zone_fails_for_a_late_or_missing_drone() {
    let late = ComplianceReport { presences: vec![presence(PS0, 200.0), presence(PS1, 301.0)], ..Default::default() };
    let r = judge(reach("5m"), &late, &[]);
    assert!(!r.passed);
    assert_eq!(r.failures, ["public-safety-1 entered tfr only at 301.00 s, after the deadline of 300.00 s"]);
    let missing = ComplianceReport {
        presences: vec![presence(PS0, 200.0), Presence { zone: "other".into(), ..presence(PS1, 10.0) }],
        ..Default::default()
    };
    let r = judge(reach("5m"), &missing, &[]);
    assert!(!r.passed);
    assert_eq!(r.summary, "1 of 2 drones of public-safety entered tfr within 300.00 s");
    assert_eq!(r.failures, ["public-safety-1 never entered tfr"]);
}

fn verdicts(groups: &[&str], expect: Expectation) -> Criterion {
    Criterion::ZoneVerdicts { groups: groups.iter().map(|g| g.to_string()).collect(), zone: "tfr".into(), expect }
}

#[test]
fn zone_verdicts_pass_when_every_request_got_the_expected_verdict() {
    let requests = [
        request(1, PS0, "public-safety-0", true),
        request(2, PS1, "public-safety-1", true),
        request(3, J0, "journalists-0", false),
        request(4, J0, "journalists-0", false),
    ];
    let r = judge(verdicts(&["public-safety"], Expectation::Granted), &ComplianceReport::default(), &requests);
    assert!(r.passed, "{r:?}");
    assert_eq!(r.summary, "2 of 2 drones of public-safety asked for tfr; all granted");
    let r = judge(verdicts(&["journalists"], Expectation::Denied), &ComplianceReport::default(), &requests);
    assert!(r.passed, "{r:?}");
    assert_eq!(
        r.summary,
        "1 of 3 drones of journalists asked for tfr; all denied; never asked: journalists-1, journalists-2"
    );
}

#[test]
fn zone_verdicts_fail_on_the_other_verdict_or_when_nobody_asked() {
    let requests = [
        request(1, PS0, "public-safety-0", true),
        request(2, PS1, "public-safety-1", false),
        request(3, J0, "journalists-0", true),
    ];
    let r = judge(verdicts(&["public-safety"], Expectation::Granted), &ComplianceReport::default(), &requests);
    assert!(!r.passed);
    assert_eq!(r.summary, "2 of 2 drones of public-safety asked for tfr; 1 of 2 requests denied");
    assert_eq!(
        r.failures,
        ["public-safety-1 was denied tfr at 12.00 s (insufficient_credentials), request 2; expected granted"]
    );
    let r = judge(verdicts(&["journalists"], Expectation::Denied), &ComplianceReport::default(), &requests);
    assert!(!r.passed);
    assert_eq!(r.failures, ["journalists-0 was granted tfr at 13.00 s (lease-3), request 3; expected denied"]);
    let r = judge(verdicts(&["journalists"], Expectation::Denied), &ComplianceReport::default(), &[]);
    assert!(!r.passed);
    assert_eq!(r.failures, ["no drone of journalists asked for tfr"]);
}

#[test]
fn the_run_fails_when_any_criterion_fails() {
    let plan = plan(vec![Criterion::NoCrashes {}, Criterion::NoUnauthorizedEntries {}]);
    let report = ComplianceReport {
        violations: vec![violation(ViolationKind::UnauthorizedEntry, J0, "journalists-0", 1.0, Some(2.0))],
        ..Default::default()
    };
    let verdict = evaluate(&plan, &report, &[], 60.0);
    assert!(!verdict.passed);
    let passed: Vec<(&str, bool)> = verdict.criteria.iter().map(|c| (c.path.as_str(), c.passed)).collect();
    assert_eq!(passed, [("spec.criteria[0]", true), ("spec.criteria[1]", false)]);
}

#[test]
fn long_lists_of_names_are_cut_in_summaries() {
    let names: Vec<String> = (0..25).map(|i| format!("d-{i}")).collect();
    let list = names_list(&names);
    assert!(list.starts_with("d-0, d-1, ") && list.ends_with("d-19 and 5 more"), "{list}");
}

#[test]
fn the_monitor_s_records_make_the_failure_lines() {
    use crate::airspace::monitor::Monitor;
    use crate::fixtures::{over, volumes};
    use crate::protocol::DroneSnapshot;

    let plan = plan(vec![Criterion::NoUnauthorizedEntries {}, Criterion::AltitudeLimitsRespected {}]);
    let mut monitor = Monitor::new(&plan, volumes(&plan));
    let snap = |e: f64, time_s: f64| {
        let s = DroneSnapshot { velocity_enu_mps: [10.0, 0.0, 0.0], ..over(J0, [e, 50.0, 40.0], 0.0) };
        (time_s, s)
    };
    for (t, s) in [snap(-5.0, 10.0), snap(5.0, 11.0), snap(50.0, 15.0)] {
        monitor.observe(t, &[s], &[], &|_, _, _| None);
    }
    monitor.finish(20.0);
    let verdict = evaluate(&plan, monitor.report(), &[], 20.0);
    assert!(!verdict.passed);
    assert!(verdict.criteria[1].passed);
    let line = &verdict.criteria[0].failures[0];
    // Entered through the west edge (east 0) at 10.5 s, 50 m north of the origin at the
    // Art Institute of Chicago (41.8796 N, 87.6237 W): 41.88005 N.
    assert_eq!(
        line,
        "journalists-0 inside tfr without a lease from 10.50 s for 9.50 s at 41.88005 N 87.62370 W, 40.0 m AGL"
    );
}

#[test]
fn estimated_position_error_fails_each_drone_of_the_groups_over_the_bound_at_its_worst_moment() {
    let worst = |m: f64, t: f64| Some(PositionError { horizontal_m: m, time_s: t, at: museum() });
    let report = ComplianceReport {
        // public-safety-0 strayed 12.5 m, -1 never flew; journalists 3 m, 30 m, 1 m.
        worst_position_errors: vec![worst(12.5, 40.0), None, worst(3.0, 10.0), worst(30.0, 75.5), worst(1.0, 5.0)],
        ..ComplianceReport::default()
    };
    let all = |m: f64| Criterion::EstimatedPositionError { groups: vec![], max_horizontal_m: m };
    let r = judge(all(10.0), &report, &[]);
    assert!(!r.passed);
    assert_eq!(r.criterion, "estimatedPositionError");
    assert_eq!(r.summary, "2 of 5 drones' estimates strayed over 10 m");
    assert_eq!(r.failures.len(), 2);
    assert!(
        r.failures[0]
            .starts_with("public-safety-0: estimate 12.5 m from the truth at 40.00 s at 41.88011 N 87.62301 W"),
        "{}",
        r.failures[0]
    );
    assert!(r.failures[1].starts_with("journalists-1: estimate 30.0 m"), "{}", r.failures[1]);
    let passed = judge(all(50.0), &report, &[]);
    assert!(passed.passed && passed.summary.contains("worst 30.0 m, journalists-1"), "{}", passed.summary);
    // Only the named group is judged.
    let ps = Criterion::EstimatedPositionError { groups: vec!["public-safety".into()], max_horizontal_m: 20.0 };
    assert!(judge(ps, &report, &[]).passed);
    let none = judge(all(1.0), &ComplianceReport::default(), &[]);
    assert!(none.passed && none.summary.contains("no drone"), "{}", none.summary);
}
