use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::{Credential, SecretKeyRef};

use super::*;
use crate::fixtures::plan_of;

const DPS_TOKEN: &str = "dps-secret-token";
const NEWS_TOKEN: &str = "news-secret-token";
const VAULT_TOKEN: &str = "vault-secret-token";
/// 350 ft.
const MIN_AGL_M: f64 = 106.68;
const MAX_AGL_M: f64 = 150.0;

/// The case study in small: drones 0-2 `dps` (chicago-dps, inline credential), 3 `news`
/// (wgn-news), 4 `unlisted` (chicago-dps but no credential), 5 `city-vault` (chicago-dps,
/// credential from a Secret). Zones: `museum-tfr` (chicago-dps only, capacity 2, 10 min
/// leases, 106.68-150 m AGL) and `later` (active 60-300 s, no limits, default lease).
fn plan() -> RunPlan {
    let run = RunBuilder::test()
        .with(|r| r.spec.fleet.clear())
        .with_group("dps", 3)
        .with_group("news", 1)
        .with_group("unlisted", 1)
        .with_group("city-vault", 1)
        .with_zone("museum-tfr")
        .with_zone("later")
        .with(|r| {
            let operators = ["chicago-dps", "wgn-news", "chicago-dps", "chicago-dps"];
            let credentials = [
                Some(Credential::Value(DPS_TOKEN.into())),
                Some(Credential::Value(NEWS_TOKEN.into())),
                None,
                Some(Credential::SecretKeyRef(SecretKeyRef { name: "vault".into(), key: "token".into() })),
            ];
            for ((g, op), cred) in r.spec.fleet.iter_mut().zip(operators).zip(credentials) {
                g.operator = op.into();
                g.credential = cred;
            }
            let museum = &mut r.spec.zones[0].policy;
            museum.authorized_operators = vec!["chicago-dps".into()];
            museum.capacity = Some(2);
            museum.lease_duration = Some(serde_yaml::from_str("10m").unwrap());
            museum.min_altitude_agl_m = Some(MIN_AGL_M);
            museum.max_altitude_agl_m = Some(MAX_AGL_M);
            let later = &mut r.spec.zones[1];
            later.policy.authorized_operators = vec!["chicago-dps".into()];
            later.active_from = Some(serde_yaml::from_str("1m").unwrap());
            later.active_until = Some(serde_yaml::from_str("5m").unwrap());
        })
        .build();
    plan_of(run)
}

/// The Secret's value is in the coordinator's environment.
fn env_with_vault(name: &str) -> Option<String> {
    (name == "SADESIM_CREDENTIAL_CITY_VAULT").then(|| VAULT_TOKEN.to_string())
}

fn authority() -> Authority {
    Authority::from_plan(&plan(), &env_with_vault)
}

fn band(min_agl_m: f64, max_agl_m: f64) -> AltitudeBand {
    AltitudeBand { min_agl_m, max_agl_m }
}

/// An entry request from `drone` (a name) as `operator`, for the museum's band.
fn entry(drone: &str, operator: &str) -> EntryRequest {
    EntryRequest { drone: drone.into(), operator: operator.into(), altitude: band(110.0, 130.0) }
}

fn museum_rule() -> ZoneRule {
    authority().rules[0].clone()
}

fn dps(drone: u32) -> Requester {
    Requester {
        drone,
        name: format!("dps-{drone}"),
        group: "dps".into(),
        operator: "chicago-dps".into(),
        credential: Some(DPS_TOKEN.into()),
    }
}

fn lease(id: u32, drone: u32, granted_at_s: f64, expires_at_s: f64) -> Lease {
    Lease {
        id: format!("lease-{id}"),
        zone: "museum-tfr".into(),
        drone,
        drone_name: format!("dps-{drone}"),
        operator: "chicago-dps".into(),
        granted_at_s,
        expires_at_s,
        released_at_s: None,
        constraints: LeaseConstraints::default(),
    }
}

fn denied(d: &Decision) -> Option<DenyReason> {
    match d {
        Decision::Deny { reason, .. } => Some(*reason),
        Decision::Grant { .. } => None,
    }
}

fn message(d: &Decision) -> &str {
    match d {
        Decision::Deny { message, .. } => message,
        Decision::Grant { .. } => panic!("granted: {d:?}"),
    }
}

fn granted_lease(v: &Verdict) -> &Lease {
    match v {
        Verdict::Granted { lease, .. } => lease,
        Verdict::Denied { message, .. } => panic!("denied: {message}"),
    }
}

fn kinds(events: &[Event]) -> Vec<&EventKind> {
    events.iter().map(|e| &e.kind).collect()
}

// ---- decide: one test per verdict ----

#[test]
fn an_authorized_operator_with_its_credential_is_granted_with_the_zone_constraints() {
    let d = decide(&museum_rule(), &LeaseTable::default(), &dps(0), DPS_TOKEN, &entry("dps-0", "chicago-dps"), 42.0);
    assert_eq!(
        d,
        Decision::Grant {
            expires_at_s: 42.0 + 600.0,
            constraints: LeaseConstraints { min_altitude_agl_m: Some(MIN_AGL_M), max_altitude_agl_m: Some(MAX_AGL_M) },
        }
    );
}

#[test]
fn an_operator_not_in_the_zone_policy_gets_insufficient_credentials() {
    let news = Requester {
        drone: 3,
        name: "news-0".into(),
        group: "news".into(),
        operator: "wgn-news".into(),
        credential: Some(NEWS_TOKEN.into()),
    };
    let d = decide(&museum_rule(), &LeaseTable::default(), &news, NEWS_TOKEN, &entry("news-0", "wgn-news"), 0.0);
    assert_eq!(denied(&d), Some(DenyReason::InsufficientCredentials));
    assert_eq!(message(&d), "operator wgn-news is not authorized for zone museum-tfr (authorized: chicago-dps)");
}

#[test]
fn a_wrong_missing_or_other_groups_token_gets_insufficient_credentials() {
    let (rule, leases, req) = (museum_rule(), LeaseTable::default(), entry("dps-0", "chicago-dps"));
    for token in [NEWS_TOKEN, "", "dps-secret-toke", "dps-secret-token ", "DPS-SECRET-TOKEN"] {
        let d = decide(&rule, &leases, &dps(0), token, &req, 0.0);
        assert_eq!(denied(&d), Some(DenyReason::InsufficientCredentials), "token {token:?}");
        assert!(message(&d).contains("dps-0"), "{}", message(&d));
    }
}

#[test]
fn a_drone_without_a_configured_credential_is_never_granted() {
    let mut unlisted = dps(4);
    unlisted.credential = None;
    for token in ["", DPS_TOKEN, "anything"] {
        let d = decide(&museum_rule(), &LeaseTable::default(), &unlisted, token, &entry("dps-4", "chicago-dps"), 0.0);
        assert_eq!(denied(&d), Some(DenyReason::InsufficientCredentials), "token {token:?}");
        assert!(message(&d).contains("no credential configured"), "{}", message(&d));
    }
}

#[test]
fn claiming_another_operator_gets_insufficient_credentials() {
    let d = decide(&museum_rule(), &LeaseTable::default(), &dps(0), DPS_TOKEN, &entry("dps-0", "wgn-news"), 0.0);
    assert_eq!(denied(&d), Some(DenyReason::InsufficientCredentials));
    assert_eq!(message(&d), "drone dps-0 is operated by chicago-dps, not by wgn-news");
}

#[test]
fn a_zone_outside_its_time_window_gets_zone_inactive() {
    let later = authority().rules[1].clone();
    assert_eq!((later.active_from_s, later.active_until_s), (60.0, 300.0));
    let req = EntryRequest { altitude: band(10.0, 500.0), ..entry("dps-0", "chicago-dps") };
    let at = |t: f64| decide(&later, &LeaseTable::default(), &dps(0), DPS_TOKEN, &req, t);
    for t in [0.0, 59.99, 300.0, 1000.0] {
        assert_eq!(denied(&at(t)), Some(DenyReason::ZoneInactive), "at {t} s");
    }
    assert_eq!(message(&at(10.0)), "zone later is not active at 10 s (active from 60 s until 300 s)");
    assert_eq!(denied(&at(60.0)), None);
    assert_eq!(denied(&at(299.99)), None);
}

#[test]
fn a_band_reaching_outside_the_policy_altitudes_gets_unsafe_altitude() {
    let (rule, leases) = (museum_rule(), LeaseTable::default());
    let ask = |min: f64, max: f64| {
        let req = EntryRequest { altitude: band(min, max), ..entry("dps-0", "chicago-dps") };
        decide(&rule, &leases, &dps(0), DPS_TOKEN, &req, 0.0)
    };
    let low = ask(30.0, 120.0);
    assert_eq!(denied(&low), Some(DenyReason::UnsafeAltitude));
    assert_eq!(
        message(&low),
        "requested band 30-120 m AGL for drone dps-0 goes below zone museum-tfr's minimum of 106.68 m AGL"
    );
    let high = ask(110.0, 160.0);
    assert_eq!(denied(&high), Some(DenyReason::UnsafeAltitude));
    assert!(message(&high).contains("above zone museum-tfr's maximum of 150 m AGL"), "{}", message(&high));
    assert_eq!(denied(&ask(MIN_AGL_M, MAX_AGL_M)), None, "exactly the policy band is safe");
    // A zone without altitude constraints accepts any band.
    let mut open = rule.clone();
    (open.policy.min_altitude_agl_m, open.policy.max_altitude_agl_m) = (None, None);
    let req = EntryRequest { altitude: band(0.0, 20_000.0), ..entry("dps-0", "chicago-dps") };
    assert_eq!(denied(&decide(&open, &leases, &dps(0), DPS_TOKEN, &req, 0.0)), None);
}

#[test]
fn capacity_counts_only_valid_leases_of_other_drones() {
    let rule = museum_rule(); // capacity 2
    let req = entry("dps-2", "chicago-dps");
    let mut leases = LeaseTable { leases: vec![lease(1, 0, 0.0, 600.0), lease(2, 1, 10.0, 610.0)] };
    let d = decide(&rule, &leases, &dps(2), DPS_TOKEN, &req, 100.0);
    assert_eq!(denied(&d), Some(DenyReason::CapacityExhausted));
    assert_eq!(message(&d), "zone museum-tfr is full: 2 of 2 leases are held; drone dps-2 may ask again later");
    // Expired: drone 0's lease ends at 600 s.
    assert_eq!(denied(&decide(&rule, &leases, &dps(2), DPS_TOKEN, &req, 600.0)), None);
    // Released.
    leases.leases[1].released_at_s = Some(200.0);
    assert_eq!(denied(&decide(&rule, &leases, &dps(2), DPS_TOKEN, &req, 200.0)), None);
    assert_eq!(denied(&decide(&rule, &leases, &dps(2), DPS_TOKEN, &req, 199.0)), Some(DenyReason::CapacityExhausted));
    // Leases of another zone do not count.
    let mut other_zone = LeaseTable { leases: vec![lease(1, 0, 0.0, 600.0), lease(2, 1, 0.0, 600.0)] };
    other_zone.leases[1].zone = "later".into();
    assert_eq!(denied(&decide(&rule, &other_zone, &dps(2), DPS_TOKEN, &req, 100.0)), None);
}

#[test]
fn a_drone_holding_a_lease_gets_it_again_even_when_the_zone_is_full() {
    let rule = museum_rule();
    let mut held = lease(1, 0, 0.0, 600.0);
    held.constraints.min_altitude_agl_m = Some(MIN_AGL_M);
    let leases = LeaseTable { leases: vec![held, lease(2, 1, 0.0, 600.0)] };
    let d = decide(&rule, &leases, &dps(0), DPS_TOKEN, &entry("dps-0", "chicago-dps"), 300.0);
    assert_eq!(
        d,
        Decision::Grant {
            expires_at_s: 600.0,
            constraints: LeaseConstraints { min_altitude_agl_m: Some(MIN_AGL_M), max_altitude_agl_m: None },
        },
        "the held lease, same expiry"
    );
}

#[test]
fn checks_run_in_order_credentials_activity_altitude_capacity() {
    let mut rule = museum_rule();
    (rule.active_from_s, rule.active_until_s) = (60.0, 300.0);
    let full = LeaseTable { leases: vec![lease(1, 0, 0.0, 600.0), lease(2, 1, 0.0, 600.0)] };
    let unsafe_req = EntryRequest { altitude: band(10.0, 20.0), ..entry("dps-2", "chicago-dps") };
    let safe_req = entry("dps-2", "chicago-dps");
    let d = |token: &str, req: &EntryRequest, t: f64| denied(&decide(&rule, &full, &dps(2), token, req, t));
    assert_eq!(d(NEWS_TOKEN, &unsafe_req, 0.0), Some(DenyReason::InsufficientCredentials));
    assert_eq!(d(DPS_TOKEN, &unsafe_req, 0.0), Some(DenyReason::ZoneInactive));
    assert_eq!(d(DPS_TOKEN, &unsafe_req, 100.0), Some(DenyReason::UnsafeAltitude));
    assert_eq!(d(DPS_TOKEN, &safe_req, 100.0), Some(DenyReason::CapacityExhausted));
}

#[test]
fn token_comparison_is_exact() {
    assert!(constant_time_eq(b"abc", b"abc"));
    assert!(constant_time_eq(b"", b""));
    assert!(!constant_time_eq(b"abc", b"abd"));
    assert!(!constant_time_eq(b"abc", b"xbc"));
    assert!(!constant_time_eq(b"abc", b"abcd"), "a prefix is not equal");
    assert!(!constant_time_eq(b"abc\0", b"abc"), "trailing zero bytes are not padding");
    assert!(!constant_time_eq(b"", b"a"));
}

#[test]
fn lease_table_counts_and_finds_valid_leases() {
    let mut released = lease(3, 2, 0.0, 600.0);
    released.released_at_s = Some(50.0);
    let table = LeaseTable { leases: vec![lease(1, 0, 0.0, 100.0), lease(2, 1, 20.0, 620.0), released] };
    assert_eq!(table.held("museum-tfr", 10.0), 2, "drone 1's lease starts at 20 s");
    assert_eq!(table.held("museum-tfr", 30.0), 3);
    assert_eq!(table.held("museum-tfr", 60.0), 2, "released at 50 s");
    assert_eq!(table.held("museum-tfr", 100.0), 1, "drone 0's ended at 100 s");
    assert_eq!(table.held("later", 30.0), 0);
    assert_eq!(table.valid(0, "museum-tfr", 99.0).map(|l| l.id.as_str()), Some("lease-1"));
    assert_eq!(table.valid(0, "museum-tfr", 100.0), None);
    assert_eq!(table.valid(0, "later", 50.0), None);
    assert_eq!(table.valid(2, "museum-tfr", 50.0), None);
}

// ---- Authority: from the plan ----

#[test]
fn from_plan_resolves_zone_rules_and_every_drones_credential() {
    let a = authority();
    let museum = &a.rules[0];
    assert_eq!((museum.zone.as_str(), museum.lease_s), ("museum-tfr", 600.0));
    assert_eq!((museum.active_from_s, museum.active_until_s), (0.0, f64::INFINITY));
    assert_eq!(museum.policy.capacity, Some(2));
    let later = &a.rules[1];
    assert_eq!((later.lease_s, later.active_from_s, later.active_until_s), (DEFAULT_LEASE_S, 60.0, 300.0));

    let names: Vec<&str> = a.requesters.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(names, ["dps-0", "dps-1", "dps-2", "news-0", "unlisted-0", "city-vault-0"]);
    let creds: Vec<Option<&str>> = a.requesters.iter().map(|r| r.credential.as_deref()).collect();
    assert_eq!(creds, [Some(DPS_TOKEN), Some(DPS_TOKEN), Some(DPS_TOKEN), Some(NEWS_TOKEN), None, Some(VAULT_TOKEN)]);
    assert_eq!(a.requesters[3].operator, "wgn-news");
    assert_eq!(a.requesters[5].drone, 5);

    // Without the Secret in the environment, or with it empty, the vault group has none.
    let none = Authority::from_plan(&plan(), &|_| None);
    assert_eq!(none.requesters[5].credential, None);
    let empty = Authority::from_plan(&plan(), &|_| Some(String::new()));
    assert_eq!(empty.requesters[5].credential, None, "an empty credential would match an empty token");
    assert_eq!(credential_env_var("news-crews"), "SADESIM_CREDENTIAL_NEWS_CREWS");
}

// ---- Authority: requests, records, events ----

#[test]
fn a_granted_request_creates_a_lease_a_record_and_two_events() {
    let mut a = authority();
    let v = a.request("museum-tfr", DPS_TOKEN, &entry("dps-1", "chicago-dps"), 12.5).unwrap();
    let lease = granted_lease(&v).clone();
    assert_eq!(v, Verdict::Granted { request_id: 1, lease: lease.clone() });
    assert_eq!(
        lease,
        Lease {
            id: "lease-1".into(),
            zone: "museum-tfr".into(),
            drone: 1,
            drone_name: "dps-1".into(),
            operator: "chicago-dps".into(),
            granted_at_s: 12.5,
            expires_at_s: 612.5,
            released_at_s: None,
            constraints: LeaseConstraints { min_altitude_agl_m: Some(MIN_AGL_M), max_altitude_agl_m: Some(MAX_AGL_M) },
        }
    );
    assert_eq!(a.leases.leases, vec![lease.clone()]);
    assert_eq!(a.valid_lease(1, "museum-tfr", 600.0), Some(&lease));
    assert_eq!(
        a.requests,
        vec![RequestRecord {
            id: 1,
            time_s: 12.5,
            zone: "museum-tfr".into(),
            drone: 1,
            drone_name: "dps-1".into(),
            operator: "chicago-dps".into(),
            altitude: band(110.0, 130.0),
            verdict: "granted".into(),
            reason: None,
            lease: Some("lease-1".into()),
        }]
    );
    let events = a.take_events();
    assert!(events.iter().all(|e| e.time_s == 12.5 && e.drone == Some(1)), "{events:?}");
    assert_eq!(
        kinds(&events),
        [
            &EventKind::ZoneRequested {
                zone: "museum-tfr".into(),
                request: 1,
                operator: "chicago-dps".into(),
                min_agl_m: 110.0,
                max_agl_m: 130.0,
            },
            &EventKind::ZoneGranted {
                zone: "museum-tfr".into(),
                request: 1,
                lease: "lease-1".into(),
                expires_at_s: 612.5,
                min_altitude_agl_m: Some(MIN_AGL_M),
                max_altitude_agl_m: Some(MAX_AGL_M),
            },
        ]
    );
    assert!(a.take_events().is_empty(), "events are taken once");
}

#[test]
fn a_denied_request_is_recorded_with_its_reason_and_message() {
    let mut a = authority();
    let v = a.request("museum-tfr", NEWS_TOKEN, &entry("news-0", "wgn-news"), 5.0).unwrap();
    let message = "operator wgn-news is not authorized for zone museum-tfr (authorized: chicago-dps)".to_string();
    assert_eq!(
        v,
        Verdict::Denied { request_id: 1, reason: DenyReason::InsufficientCredentials, message: message.clone() }
    );
    assert!(a.leases.leases.is_empty());
    assert_eq!(a.requests.len(), 1);
    assert_eq!(
        (a.requests[0].verdict.as_str(), a.requests[0].reason, &a.requests[0].lease),
        ("denied", Some(DenyReason::InsufficientCredentials), &None)
    );
    let events = a.take_events();
    assert!(events.iter().all(|e| e.time_s == 5.0 && e.drone == Some(3)));
    assert!(matches!(events[0].kind, EventKind::ZoneRequested { request: 1, .. }));
    assert_eq!(
        events[1].kind,
        EventKind::ZoneDenied {
            zone: "museum-tfr".into(),
            request: 1,
            reason: "insufficient_credentials".into(),
            message
        }
    );
    assert_eq!(events.len(), 2);
}

#[test]
fn every_deny_reason_reaches_the_record_and_the_event() {
    let mut a = authority();
    let cases = [
        ("museum-tfr", "dps-0", DPS_TOKEN, band(110.0, 130.0), 0.0, None),
        ("museum-tfr", "dps-1", DPS_TOKEN, band(110.0, 130.0), 0.0, None),
        ("museum-tfr", "dps-2", DPS_TOKEN, band(110.0, 130.0), 1.0, Some(DenyReason::CapacityExhausted)),
        ("museum-tfr", "dps-2", DPS_TOKEN, band(50.0, 130.0), 1.0, Some(DenyReason::UnsafeAltitude)),
        ("later", "dps-2", DPS_TOKEN, band(50.0, 130.0), 1.0, Some(DenyReason::ZoneInactive)),
        ("later", "dps-2", DPS_TOKEN, band(50.0, 130.0), 61.0, None),
        ("later", "unlisted-0", "", band(50.0, 130.0), 61.0, Some(DenyReason::InsufficientCredentials)),
    ];
    for (i, (zone, drone, token, altitude, t, want)) in cases.into_iter().enumerate() {
        let req = EntryRequest { drone: drone.into(), operator: "chicago-dps".into(), altitude };
        let v = a.request(zone, token, &req, t).unwrap();
        let got = match &v {
            Verdict::Granted { .. } => None,
            Verdict::Denied { reason, .. } => Some(*reason),
        };
        assert_eq!(got, want, "case {i}: {v:?}");
        assert_eq!(a.requests[i].id, i as u64 + 1);
        assert_eq!(a.requests[i].reason, want);
        let events = a.take_events();
        match (want, &events[1].kind) {
            (Some(r), EventKind::ZoneDenied { reason, .. }) => assert_eq!(reason, r.as_str()),
            (None, EventKind::ZoneGranted { .. }) => {}
            other => panic!("case {i}: {other:?}"),
        }
    }
    let lease_ids: Vec<&str> = a.leases.leases.iter().map(|l| l.id.as_str()).collect();
    assert_eq!(lease_ids, ["lease-1", "lease-2", "lease-3"]);
}

#[test]
fn asking_again_while_holding_a_lease_returns_the_same_lease() {
    let mut a = authority();
    let first =
        granted_lease(&a.request("museum-tfr", DPS_TOKEN, &entry("dps-0", "chicago-dps"), 0.0).unwrap()).clone();
    let again = a.request("museum-tfr", DPS_TOKEN, &entry("dps-0", "chicago-dps"), 100.0).unwrap();
    assert_eq!(again, Verdict::Granted { request_id: 2, lease: first.clone() });
    assert_eq!(a.leases.leases.len(), 1, "no second lease");
    assert_eq!(a.leases.held("museum-tfr", 100.0), 1);
    assert_eq!((a.requests[1].verdict.as_str(), a.requests[1].lease.as_deref()), ("granted", Some("lease-1")));
    let events = a.take_events();
    assert!(
        matches!(&events[3].kind, EventKind::ZoneGranted { request: 2, lease, expires_at_s, .. }
            if lease == "lease-1" && *expires_at_s == 600.0),
        "{events:?}"
    );
}

#[test]
fn expiry_and_release_free_capacity() {
    let mut a = authority();
    for (drone, t) in [("dps-0", 0.0), ("dps-1", 100.0)] {
        granted_lease(&a.request("museum-tfr", DPS_TOKEN, &entry(drone, "chicago-dps"), t).unwrap());
    }
    let third =
        |a: &mut Authority, t: f64| a.request("museum-tfr", DPS_TOKEN, &entry("dps-2", "chicago-dps"), t).unwrap();
    assert!(matches!(third(&mut a, 599.0), Verdict::Denied { reason: DenyReason::CapacityExhausted, .. }));
    // dps-0's lease expires at 600 s.
    let lease = granted_lease(&third(&mut a, 600.0)).clone();
    assert_eq!(lease.id, "lease-3");
    // Full again; dps-1 releases early and the vault drone gets in.
    let vault = entry("city-vault-0", "chicago-dps");
    assert!(matches!(
        a.request("museum-tfr", VAULT_TOKEN, &vault, 601.0).unwrap(),
        Verdict::Denied { reason: DenyReason::CapacityExhausted, .. }
    ));
    a.release("lease-2", DPS_TOKEN, 602.0).unwrap();
    assert_eq!(granted_lease(&a.request("museum-tfr", VAULT_TOKEN, &vault, 603.0).unwrap()).id, "lease-4");
}

#[test]
fn bad_requests_are_errors_and_leave_no_trace() {
    let mut a = authority();
    let ok = entry("dps-0", "chicago-dps");
    assert_eq!(a.request("nowhere", DPS_TOKEN, &ok, 0.0), Err(AuthorityError::UnknownZone("nowhere".into())));
    let ghost = entry("ghost-7", "chicago-dps");
    assert_eq!(a.request("museum-tfr", DPS_TOKEN, &ghost, 0.0), Err(AuthorityError::UnknownDrone("ghost-7".into())));
    for (min, max, says) in [
        (f64::NAN, 130.0, "finite"),
        (110.0, f64::INFINITY, "finite"),
        (-1.0, 130.0, "altitude.minAglM must be >= 0"),
        (130.0, 110.0, "must be below altitude.maxAglM"),
        (120.0, 120.0, "must be below altitude.maxAglM"),
        (110.0, 20_001.0, "altitude.maxAglM must be <= 20000"),
    ] {
        let req = EntryRequest { altitude: band(min, max), ..ok.clone() };
        match a.request("museum-tfr", DPS_TOKEN, &req, 0.0) {
            Err(AuthorityError::InvalidBand(m)) => assert!(m.contains(says), "{min}-{max}: {m}"),
            other => panic!("{min}-{max}: {other:?}"),
        }
    }
    assert!(a.requests.is_empty() && a.leases.leases.is_empty() && a.take_events().is_empty());
}

// ---- Authority: renew, release, expire ----

/// An authority where dps-0 holds lease-1 (granted at 0 s, expires at 600 s), events taken.
fn with_lease() -> Authority {
    let mut a = authority();
    granted_lease(&a.request("museum-tfr", DPS_TOKEN, &entry("dps-0", "chicago-dps"), 0.0).unwrap());
    a.take_events();
    a
}

#[test]
fn renew_extends_a_valid_lease_from_now_for_its_holder_only() {
    let mut a = with_lease();
    assert_eq!(a.renew("lease-1", NEWS_TOKEN, 500.0), Err(AuthorityError::NotHolder("lease-1".into())));
    assert_eq!(a.renew("lease-1", "", 500.0), Err(AuthorityError::NotHolder("lease-1".into())));
    assert_eq!(a.renew("lease-9", DPS_TOKEN, 500.0), Err(AuthorityError::UnknownLease("lease-9".into())));
    assert!(a.take_events().is_empty());
    let renewed = a.renew("lease-1", DPS_TOKEN, 500.0).unwrap();
    assert_eq!((renewed.granted_at_s, renewed.expires_at_s), (0.0, 1100.0));
    assert_eq!(a.leases.leases[0], renewed);
    assert_eq!(
        a.take_events(),
        [Event {
            time_s: 500.0,
            drone: Some(0),
            kind: EventKind::LeaseRenewed { zone: "museum-tfr".into(), lease: "lease-1".into(), expires_at_s: 1100.0 },
        }]
    );
    // Not expired at the old expiry, so no leaseExpired then.
    a.expire(600.0);
    assert!(a.take_events().is_empty());
    assert!(a.valid_lease(0, "museum-tfr", 1099.0).is_some());
}

#[test]
fn an_ended_lease_cannot_be_renewed() {
    let mut a = with_lease();
    assert_eq!(a.renew("lease-1", DPS_TOKEN, 600.0), Err(AuthorityError::LeaseEnded("lease-1".into())));
    let mut b = with_lease();
    b.release("lease-1", DPS_TOKEN, 100.0).unwrap();
    b.take_events();
    assert_eq!(b.renew("lease-1", DPS_TOKEN, 200.0), Err(AuthorityError::LeaseEnded("lease-1".into())));
    assert!(a.take_events().is_empty() && b.take_events().is_empty());
}

#[test]
fn release_ends_the_lease_once_and_is_idempotent() {
    let mut a = with_lease();
    assert_eq!(a.release("lease-1", NEWS_TOKEN, 100.0), Err(AuthorityError::NotHolder("lease-1".into())));
    assert_eq!(a.release("nope", DPS_TOKEN, 100.0), Err(AuthorityError::UnknownLease("nope".into())));
    let released = a.release("lease-1", DPS_TOKEN, 100.0).unwrap();
    assert_eq!(released.released_at_s, Some(100.0));
    assert!(a.valid_lease(0, "museum-tfr", 99.0).is_some());
    assert!(a.valid_lease(0, "museum-tfr", 100.0).is_none());
    assert_eq!(
        a.take_events(),
        [Event {
            time_s: 100.0,
            drone: Some(0),
            kind: EventKind::LeaseReleased { zone: "museum-tfr".into(), lease: "lease-1".into() },
        }]
    );
    let again = a.release("lease-1", DPS_TOKEN, 150.0).unwrap();
    assert_eq!(again.released_at_s, Some(100.0), "the first release stands");
    assert!(a.take_events().is_empty());
    // A released lease never expires.
    a.expire(1000.0);
    assert!(a.take_events().is_empty());
}

#[test]
fn releasing_an_expired_lease_changes_nothing() {
    let mut a = with_lease();
    let lease = a.release("lease-1", DPS_TOKEN, 700.0).unwrap();
    assert_eq!(lease.released_at_s, None);
    assert!(a.take_events().is_empty());
    a.expire(700.0);
    assert_eq!(a.take_events().len(), 1, "it expired; that is reported");
}

#[test]
fn expire_reports_each_expired_lease_once() {
    let mut a = with_lease();
    granted_lease(&a.request("later", DPS_TOKEN, &entry("dps-1", "chicago-dps"), 100.0).unwrap()); // until 700 s
    a.take_events();
    a.expire(599.99);
    assert!(a.take_events().is_empty(), "nothing expired yet");
    a.expire(600.0);
    assert_eq!(
        a.take_events(),
        [Event {
            time_s: 600.0,
            drone: Some(0),
            kind: EventKind::LeaseExpired { zone: "museum-tfr".into(), lease: "lease-1".into() },
        }]
    );
    a.expire(650.0);
    assert!(a.take_events().is_empty(), "once");
    a.expire(800.0);
    let events = a.take_events();
    assert_eq!(kinds(&events), [&EventKind::LeaseExpired { zone: "later".into(), lease: "lease-2".into() }]);
    assert_eq!((events[0].time_s, events[0].drone), (800.0, Some(1)));
}

// ---- Wire format the service relies on ----

#[test]
fn verdicts_serialise_as_the_api_documents() {
    let denied = Verdict::Denied {
        request_id: 3,
        reason: DenyReason::CapacityExhausted,
        message: "zone museum-tfr is full".into(),
    };
    assert_eq!(
        serde_json::to_value(&denied).unwrap(),
        serde_json::json!({
            "verdict": "denied", "requestId": 3, "reason": "capacity_exhausted", "message": "zone museum-tfr is full"
        })
    );
    let granted = Verdict::Granted { request_id: 1, lease: lease(1, 0, 0.0, 600.0) };
    let json = serde_json::to_value(&granted).unwrap();
    assert_eq!(json["verdict"], "granted");
    assert_eq!(json["lease"]["id"], "lease-1");
    assert_eq!(json["lease"]["expiresAtS"], 600.0);
    for r in [
        DenyReason::InsufficientCredentials,
        DenyReason::CapacityExhausted,
        DenyReason::UnsafeAltitude,
        DenyReason::ZoneInactive,
    ] {
        assert_eq!(serde_json::to_value(r).unwrap(), r.as_str());
    }
    let req: EntryRequest = serde_json::from_str(
        r#"{"drone": "dps-0", "operator": "chicago-dps", "altitude": {"minAglM": 110, "maxAglM": 130}}"#,
    )
    .unwrap();
    assert_eq!(req, entry("dps-0", "chicago-dps"));
}
