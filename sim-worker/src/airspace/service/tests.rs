//! The API over real HTTP: the service on 127.0.0.1 port 0, the blocking client of
//! [`super::client`], the Chicago case study's zone and fleet.

use std::collections::BTreeSet;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use sadesim_crds::run::SimulationRun;
use sadesim_crds::zones::Zone;
use serde_json::{Value, json};

use super::client::{HttpClient, HttpResponse};
use super::*;
use sadesim_engine::fixtures::plan_of;

const DPS: &str = "dps-token-local-only";
const NEWS: &str = "news-token-local-only";
const ZONE_PATH: &str = "/zones/museum-tfr/requests";

/// Every route the router serves, as (method, OpenAPI path). The OpenAPI test checks the
/// file documents exactly these, and `every_listed_route_is_served` that the router serves
/// them.
const ROUTES: &[(&str, &str)] = &[
    ("get", "/healthz"),
    ("get", "/zones"),
    ("get", "/zones/{id}"),
    ("post", "/zones/{id}/requests"),
    ("get", "/leases/{id}"),
    ("delete", "/leases/{id}"),
    ("post", "/leases/{id}/renew"),
    ("get", "/events"),
];

/// The Chicago case study (`examples/chicago-museum.yaml`), to be planned by the real
/// planner (drones `<group>-<k>` in fleet order).
fn chicago_run() -> SimulationRun {
    let text = include_str!("../../../../examples/chicago-museum.yaml");
    sadesim_crds::parse_run(text).expect("the Chicago example parses")
}

/// A zone next to the museum, from JSON (as a scenario would write it).
fn extra_zone(name: &str, extra: Value) -> Zone {
    let mut zone = json!({
        "name": name,
        "polygon": [
            {"latitudeDeg": 41.8700, "longitudeDeg": -87.6300},
            {"latitudeDeg": 41.8700, "longitudeDeg": -87.6280},
            {"latitudeDeg": 41.8720, "longitudeDeg": -87.6280},
        ],
        "ceiling": {"heightM": 120, "reference": "agl"},
        "policy": {"authorizedOperators": ["chicago-dps"]},
    });
    for (k, v) in extra.as_object().expect("an object") {
        zone[k] = v.clone();
    }
    serde_json::from_value(zone).expect("a valid zone")
}

/// The Chicago zone plus `later` (active from 300 s) and `single` (capacity 1), served on
/// a free port.
fn serve() -> (ServiceHandle, SharedAirspace) {
    let mut run = chicago_run();
    run.spec.zones.push(extra_zone("later", json!({"activeFrom": "5m"})));
    run.spec.zones.push(extra_zone(
        "single",
        json!({"policy": {"authorizedOperators": ["chicago-dps"], "capacity": 1, "leaseDuration": "2m"}}),
    ));
    let plan = plan_of(run);
    let state = Arc::new(Mutex::new(AirspaceState::new(&plan, &|_| None)));
    let handle = start(state.clone(), "127.0.0.1:0".parse().unwrap()).expect("the service starts");
    (handle, state)
}

fn client(addr: SocketAddr) -> HttpClient {
    HttpClient::connect(addr).expect("connect to the service")
}

fn entry(drone: &str, operator: &str, min_agl_m: f64, max_agl_m: f64) -> String {
    json!({"drone": drone, "operator": operator, "altitude": {"minAglM": min_agl_m, "maxAglM": max_agl_m}}).to_string()
}

fn body(response: &HttpResponse) -> Value {
    response.json().unwrap_or_else(|e| panic!("not JSON ({e}): {}", response.text()))
}

/// Asserts a JSON error answer: status, code, and that the message mentions each of `words`.
#[track_caller]
fn assert_error(response: &HttpResponse, status: u16, code: &str, words: &[&str]) {
    let b = body(response);
    assert_eq!(response.status, status, "{b}");
    assert_eq!(b["error"], code, "{b}");
    let message = b["message"].as_str().expect("a message");
    for w in words {
        assert!(message.contains(w), "message {message:?} does not mention {w:?}");
    }
    assert_eq!(response.header("content-type"), Some("application/json"));
}

#[test]
fn health_reports_the_sim_time_and_the_release() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    assert_eq!(body(&c.get("/healthz").unwrap()), json!({"status": "ok", "simTimeS": 0.0, "pilotsReleased": false}));
    state.lock().unwrap().time_s = 12.5;
    state.lock().unwrap().pilots_released = true;
    let health = body(&c.get("/healthz").unwrap());
    assert_eq!(health["simTimeS"], 12.5);
    assert_eq!(health["pilotsReleased"], true);
}

#[test]
fn zones_are_geojson_with_limits_window_policy_and_leases() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    let r = c.get("/zones").unwrap();
    assert_eq!(r.status, 200);
    let all = body(&r);
    assert_eq!(all["type"], "FeatureCollection");
    let names: Vec<&str> = all["features"].as_array().unwrap().iter().map(|f| f["id"].as_str().unwrap()).collect();
    assert_eq!(names, ["museum-tfr", "later", "single"]);

    let museum = body(&c.get("/zones/museum-tfr").unwrap());
    assert_eq!(museum, all["features"][0]);
    assert_eq!(museum["type"], "Feature");
    assert_eq!(museum["geometry"]["type"], "Polygon");
    let ring = museum["geometry"]["coordinates"][0].as_array().unwrap();
    // [lon, lat] (RFC 7946), closed: Michigan Ave & Monroe St first and last.
    assert_eq!(ring.len(), 5);
    assert_eq!(ring[0], json!([-87.6245, 41.8807]));
    assert_eq!(ring[4], ring[0]);
    let p = &museum["properties"];
    assert_eq!(p["name"], "museum-tfr");
    assert_eq!(p["floor"], json!({"heightM": 0.0, "reference": "agl"}));
    assert_eq!(p["ceiling"], json!({"heightM": 152.4, "reference": "agl"}));
    assert_eq!(p["activeFromS"], 0.0);
    assert_eq!(p["activeUntilS"], Value::Null);
    assert_eq!(p["active"], true);
    assert_eq!(
        p["policy"],
        json!({
            "authorizedOperators": ["chicago-dps"],
            "capacity": 10,
            "leaseDurationS": 600.0,
            "minAltitudeAglM": 106.68,
            "maxAltitudeAglM": null,
        })
    );
    assert_eq!(p["leasesHeld"], 0);

    // `active` and `leasesHeld` follow the sim time and the lease table.
    let later = body(&c.get("/zones/later").unwrap());
    assert_eq!(
        (later["properties"]["activeFromS"].as_f64(), later["properties"]["active"].as_bool()),
        (Some(300.0), Some(false))
    );
    assert_eq!(
        c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", 107.0, 121.0)).unwrap().status,
        200
    );
    state.lock().unwrap().time_s = 301.0;
    assert_eq!(body(&c.get("/zones/later").unwrap())["properties"]["active"], true);
    assert_eq!(body(&c.get("/zones/museum-tfr").unwrap())["properties"]["leasesHeld"], 1);

    assert_error(&c.get("/zones/nowhere").unwrap(), 404, "unknown_zone", &["nowhere"]);
}

#[test]
fn each_verdict_over_http() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    state.lock().unwrap().time_s = 42.0;

    let granted =
        body(&c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", 107.0, 121.0)).unwrap());
    assert_eq!(granted["verdict"], "granted", "{granted}");
    assert_eq!(granted["requestId"], 1);
    let lease = &granted["lease"];
    assert_eq!(lease["id"], "lease-1");
    assert_eq!(lease["zone"], "museum-tfr");
    assert_eq!(lease["droneName"], "public-safety-0");
    assert_eq!(lease["grantedAtS"], 42.0);
    assert_eq!(lease["expiresAtS"], 642.0);
    assert_eq!(lease["constraints"], json!({"minAltitudeAglM": 106.68}));

    let denied = |c: &mut HttpClient, zone: &str, token: &str, request: String, reason: &str| {
        let r = c.post_json(&format!("/zones/{zone}/requests"), Some(token), &request).unwrap();
        let b = body(&r);
        assert_eq!(r.status, 200, "a denial is a verdict: {b}");
        assert_eq!((b["verdict"].as_str(), b["reason"].as_str()), (Some("denied"), Some(reason)), "{b}");
        assert!(b["message"].as_str().is_some_and(|m| !m.is_empty()), "{b}");
        assert!(b.get("lease").is_none(), "{b}");
    };
    // Journalists are not an authorized operator.
    denied(&mut c, "museum-tfr", NEWS, entry("journalists-3", "wgn-news", 95.0, 110.0), "insufficient_credentials");
    // A DPS drone presenting another group's token, and a journalist presenting DPS's.
    denied(
        &mut c,
        "museum-tfr",
        NEWS,
        entry("public-safety-1", "chicago-dps", 107.0, 121.0),
        "insufficient_credentials",
    );
    denied(&mut c, "museum-tfr", DPS, entry("journalists-0", "chicago-dps", 107.0, 121.0), "insufficient_credentials");
    // Below the zone's 350 ft minimum.
    denied(&mut c, "museum-tfr", DPS, entry("public-safety-1", "chicago-dps", 30.0, 60.0), "unsafe_altitude");
    // Not active before 300 s.
    denied(&mut c, "later", DPS, entry("public-safety-1", "chicago-dps", 10.0, 60.0), "zone_inactive");
    // One lease at a time.
    let first = body(
        &c.post_json("/zones/single/requests", Some(DPS), &entry("public-safety-1", "chicago-dps", 10.0, 60.0))
            .unwrap(),
    );
    assert_eq!(first["verdict"], "granted", "{first}");
    denied(&mut c, "single", DPS, entry("public-safety-2", "chicago-dps", 10.0, 60.0), "capacity_exhausted");

    // Every request and verdict is in the authority's records and the event history.
    let s = state.lock().unwrap();
    assert_eq!(s.authority.requests.len(), 8);
    let kinds: Vec<&str> = s
        .history
        .iter()
        .map(|e| match &e.kind {
            sadesim_engine::events::EventKind::ZoneRequested { .. } => "requested",
            sadesim_engine::events::EventKind::ZoneGranted { .. } => "granted",
            sadesim_engine::events::EventKind::ZoneDenied { .. } => "denied",
            _ => "other",
        })
        .collect();
    assert_eq!(kinds.iter().filter(|k| **k == "requested").count(), 8);
    assert_eq!(kinds.iter().filter(|k| **k == "granted").count(), 2);
    assert_eq!(kinds.iter().filter(|k| **k == "denied").count(), 6);
}

/// Two runs of the same scenario on one cluster, each with its team's Secret: a token valid
/// in one run is worth nothing in the other, whichever pod presents it (the NetworkPolicy
/// keeps other runs' pods out; this is the check behind it): it is no credential there, so
/// 401 `invalid_token`, and nothing is decided or logged.
#[test]
fn another_run_s_credential_is_refused() {
    let serve_with = |dps_token: &str| {
        let token = dps_token.to_string();
        let mut run = chicago_run();
        let dps = run.spec.fleet.iter_mut().find(|g| g.operator == "chicago-dps").expect("the DPS group");
        dps.credential = Some(sadesim_crds::fleet::Credential::Value(token));
        let state = Arc::new(Mutex::new(AirspaceState::new(&plan_of(run), &|_| None)));
        (start(state.clone(), "127.0.0.1:0".parse().unwrap()).expect("the service starts"), state)
    };
    let ((team_a, state_a), (team_b, state_b)) = (serve_with("team-a-dps-token"), serve_with("team-b-dps-token"));
    let request = entry("public-safety-0", "chicago-dps", 107.0, 121.0);
    let post = |service: &ServiceHandle, token: &str| client(service.addr).post_json(ZONE_PATH, Some(token), &request);
    assert_error(&post(&team_a, "team-b-dps-token").unwrap(), 401, "invalid_token", &["not a credential of this run"]);
    assert_error(&post(&team_b, "team-a-dps-token").unwrap(), 401, "invalid_token", &["not a credential of this run"]);
    assert!(state_a.lock().unwrap().history.is_empty() && state_b.lock().unwrap().history.is_empty());
    assert_eq!(body(&post(&team_a, "team-a-dps-token").unwrap())["verdict"], "granted");
    assert_eq!(body(&post(&team_b, "team-b-dps-token").unwrap())["verdict"], "granted");
}

/// A bearer token that is no group's credential is refused with 401 `invalid_token` on
/// every route that needs one, before the zone, lease or body is looked at, and leaves no
/// trace in the run's log; another group's credential is authenticated and decided (denied
/// for an entry request, 403 for someone else's lease).
#[test]
fn a_token_of_no_group_is_refused_on_every_authenticated_route() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    let granted = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", 107.0, 121.0)).unwrap();
    assert_eq!(body(&granted)["lease"]["id"], "lease-1");
    let logged = state.lock().unwrap().history.len();

    let good = entry("public-safety-1", "chicago-dps", 107.0, 121.0);
    for token in ["wrong", "dps-token-local-onl", "dps-token-local-onlyX", "DPS-TOKEN-LOCAL-ONLY"] {
        let auth = format!("Bearer {token}");
        let headers = [("Authorization", auth.as_str()), ("Content-Type", "application/json")];
        for (method, path, body) in [
            ("POST", ZONE_PATH, good.as_str()),
            ("POST", "/zones/nowhere/requests", good.as_str()),
            ("POST", ZONE_PATH, "not json"),
            ("POST", "/leases/lease-1/renew", ""),
            ("POST", "/leases/lease-9/renew", ""),
            ("DELETE", "/leases/lease-1", ""),
        ] {
            let r = c.request(method, path, &headers, body.as_bytes()).unwrap();
            assert_error(&r, 401, "invalid_token", &["not a credential of this run", "SADESIM_CREDENTIAL_"]);
            assert_eq!(r.header("www-authenticate"), Some("Bearer"), "{method} {path}");
        }
    }
    assert_eq!(state.lock().unwrap().history.len(), logged, "refused tokens leave no event");
    assert!(state.lock().unwrap().authority.leases.leases[0].released_at_s.is_none(), "lease-1 still held");

    // Another group's credential is a credential: decided, and refused for what it is.
    let denied = body(&c.post_json(ZONE_PATH, Some(NEWS), &good).unwrap());
    assert_eq!(
        (denied["verdict"].as_str(), denied["reason"].as_str()),
        (Some("denied"), Some("insufficient_credentials"))
    );
    assert_error(&c.with_token("POST", "/leases/lease-1/renew", NEWS).unwrap(), 403, "not_lease_holder", &["lease-1"]);
}

/// Unknown fields are refused at every depth of an entry request, `altitude` included,
/// with the field's path: a field is never accepted and ignored.
#[test]
fn unknown_fields_inside_the_altitude_band_are_refused_by_name() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    let with_extra = r#"{"drone": "public-safety-0", "operator": "chicago-dps",
        "altitude": {"minAglM": 107, "maxAglM": 121, "reference": "msl"}}"#;
    assert_error(
        &c.post_json(ZONE_PATH, Some(DPS), with_extra).unwrap(),
        400,
        "invalid_request",
        &["field `altitude.reference`", "unknown field `reference`", "minAglM", "maxAglM"],
    );
    assert!(state.lock().unwrap().authority.requests.is_empty(), "nothing was decided");
}

#[test]
fn leases_are_read_renewed_and_released_by_their_holder_only() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    let granted =
        body(&c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", 107.0, 121.0)).unwrap());
    assert_eq!(granted["lease"]["id"], "lease-1", "{granted}");
    assert_eq!(body(&c.get("/leases/lease-1").unwrap()), granted["lease"]);

    state.lock().unwrap().time_s = 100.0;
    let renewed = c.with_token("POST", "/leases/lease-1/renew", DPS).unwrap();
    assert_eq!(renewed.status, 200, "{}", renewed.text());
    assert_eq!(body(&renewed)["expiresAtS"], 700.0);

    assert_error(&c.with_token("POST", "/leases/lease-1/renew", NEWS).unwrap(), 403, "not_lease_holder", &["lease-1"]);
    assert_error(&c.with_token("DELETE", "/leases/lease-1", NEWS).unwrap(), 403, "not_lease_holder", &["lease-1"]);
    assert_error(&c.request("POST", "/leases/lease-1/renew", &[], b"").unwrap(), 401, "missing_token", &["Bearer"]);
    assert_error(&c.request("DELETE", "/leases/lease-1", &[], b"").unwrap(), 401, "missing_token", &["Bearer"]);
    assert_error(&c.with_token("POST", "/leases/lease-9/renew", DPS).unwrap(), 404, "unknown_lease", &["lease-9"]);
    assert_error(&c.get("/leases/lease-9").unwrap(), 404, "unknown_lease", &["lease-9"]);

    state.lock().unwrap().time_s = 150.0;
    let released = c.with_token("DELETE", "/leases/lease-1", DPS).unwrap();
    assert_eq!(released.status, 200, "{}", released.text());
    assert_eq!(body(&released)["releasedAtS"], 150.0);
    assert_eq!(body(&c.get("/leases/lease-1").unwrap())["releasedAtS"], 150.0);
    assert_eq!(body(&c.get("/zones/museum-tfr").unwrap())["properties"]["leasesHeld"], 0);
    assert_error(
        &c.with_token("POST", "/leases/lease-1/renew", DPS).unwrap(),
        409,
        "lease_ended",
        &["lease-1", "request the zone again"],
    );
    // Releasing again is harmless.
    assert_eq!(c.with_token("DELETE", "/leases/lease-1", DPS).unwrap().status, 200);

    let events = body(&c.get("/events").unwrap());
    let names: Vec<&str> = events["events"].as_array().unwrap().iter().map(|e| e["event"].as_str().unwrap()).collect();
    assert_eq!(names, ["zoneRequested", "zoneGranted", "leaseRenewed", "leaseReleased"]);
}

#[test]
fn events_are_paged_by_sequence_number() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    for k in 0..3 {
        let r =
            c.post_json(ZONE_PATH, Some(NEWS), &entry(&format!("journalists-{k}"), "wgn-news", 95.0, 110.0)).unwrap();
        assert_eq!(r.status, 200);
    }
    // 3 requests, each requested + denied.
    assert_eq!(state.lock().unwrap().history.len(), 6);

    let all = body(&c.get("/events").unwrap());
    assert_eq!(all["next"], 6);
    let first = &all["events"][0];
    assert_eq!(first["seq"], 1);
    assert_eq!(first["event"], "zoneRequested");
    assert_eq!(first["drone"], 5, "journalists-0 is drone 5");
    assert_eq!(first["zone"], "museum-tfr");
    assert_eq!(all["events"][1]["event"], "zoneDenied");
    assert_eq!(all["events"][1]["reason"], "insufficient_credentials");

    let page = body(&c.get("/events?since=1&limit=2").unwrap());
    let seqs: Vec<u64> = page["events"].as_array().unwrap().iter().map(|e| e["seq"].as_u64().unwrap()).collect();
    assert_eq!((seqs, page["next"].as_u64()), (vec![2, 3], Some(3)));
    let rest = body(&c.get("/events?limit=10&since=3").unwrap());
    let seqs: Vec<u64> = rest["events"].as_array().unwrap().iter().map(|e| e["seq"].as_u64().unwrap()).collect();
    assert_eq!((seqs, rest["next"].as_u64()), (vec![4, 5, 6], Some(6)));
    // Caught up, or ahead of the history: nothing, and `next` is where the history ends.
    assert_eq!(body(&c.get("/events?since=6").unwrap()), json!({"events": [], "next": 6}));
    assert_eq!(body(&c.get("/events?since=99").unwrap()), json!({"events": [], "next": 6}));
    // Any whole number is a cursor, also beyond 64 bits (the spec sets no maximum).
    for since in ["18446744073709551615", "18446744073709551616", "99999999999999999999999999999999"] {
        assert_eq!(body(&c.get(&format!("/events?since={since}")).unwrap()), json!({"events": [], "next": 6}));
    }

    for (query, words) in [
        ("limit=0", &["limit", "between 1 and 10000", "0"][..]),
        ("limit=10001", &["limit", "between 1 and 10000"]),
        ("limit=18446744073709551616", &["limit", "between 1 and 10000", "18446744073709551616"]),
        ("since=%2B1", &["since", "whole number"]),
        ("since=1.0", &["since", "whole number"]),
        ("since=-1", &["since", "whole number", "-1"]),
        ("since=abc", &["since", "\"abc\""]),
        ("since=", &["since", "whole number"]),
        ("after=3", &["unknown query parameter `after`", "since", "limit"]),
        ("since=1&since=2", &["since", "twice"]),
    ] {
        assert_error(&c.get(&format!("/events?{query}")).unwrap(), 400, "invalid_query", words);
    }
}

#[test]
fn bad_entry_requests_get_a_4xx_naming_the_problem() {
    let (service, state) = serve();
    let mut c = client(service.addr);
    let good = entry("public-safety-0", "chicago-dps", 107.0, 121.0);
    let json_ct = ("Content-Type", "application/json");

    // No credential is never a grant: 401 before anything else is looked at.
    let r = c.request("POST", ZONE_PATH, &[json_ct], good.as_bytes()).unwrap();
    assert_error(&r, 401, "missing_token", &["Authorization: Bearer <token>"]);
    assert_eq!(r.header("www-authenticate"), Some("Bearer"));
    let basic = c.request("POST", ZONE_PATH, &[json_ct, ("Authorization", "Basic ZHBzOnRva2Vu")], good.as_bytes());
    assert_error(&basic.unwrap(), 401, "missing_token", &["Bearer scheme"]);
    let empty = c.request("POST", ZONE_PATH, &[json_ct, ("Authorization", "Bearer ")], good.as_bytes());
    assert_error(&empty.unwrap(), 401, "missing_token", &["empty"]);

    let auth = ("Authorization", "Bearer dps-token-local-only");
    let form =
        c.request("POST", ZONE_PATH, &[auth, ("Content-Type", "application/x-www-form-urlencoded")], good.as_bytes());
    assert_error(
        &form.unwrap(),
        415,
        "unsupported_media_type",
        &["Content-Type: application/json", "x-www-form-urlencoded"],
    );
    assert_error(
        &c.request("POST", ZONE_PATH, &[auth], good.as_bytes()).unwrap(),
        415,
        "unsupported_media_type",
        &["no Content-Type"],
    );
    // Parameters are fine.
    let utf8 =
        c.request("POST", ZONE_PATH, &[auth, ("Content-Type", "application/json; charset=utf-8")], good.as_bytes());
    assert_eq!(body(&utf8.unwrap())["verdict"], "granted");

    let post = |c: &mut HttpClient, text: &str| c.post_json(ZONE_PATH, Some(DPS), text).unwrap();
    assert_error(&post(&mut c, ""), 400, "invalid_json", &["empty", "minAglM"]);
    assert_error(&post(&mut c, r#"{"drone": "public-safety-0",}"#), 400, "invalid_json", &["line 1 column 29"]);
    assert_error(&post(&mut c, "{\"drone\": \"public-safety-0\""), 400, "invalid_json", &["EOF", "line 1"]);
    assert_error(&post(&mut c, &format!("{good} trailing")), 400, "invalid_json", &["trailing characters"]);
    let wrong_type = r#"{"drone": "public-safety-0", "operator": "chicago-dps",
        "altitude": {"minAglM": "high", "maxAglM": 121}}"#;
    assert_error(
        &post(&mut c, wrong_type),
        400,
        "invalid_request",
        &["field `altitude.minAglM`", "expected f64", "line 2"],
    );
    let unknown = r#"{"drone": "public-safety-0", "operator": "chicago-dps", "altitude": {"minAglM": 107, "maxAglM": 121}, "speed": 3}"#;
    assert_error(
        &post(&mut c, unknown),
        400,
        "invalid_request",
        &["unknown field `speed`", "drone", "operator", "altitude"],
    );
    let missing = r#"{"drone": "public-safety-0", "altitude": {"minAglM": 107, "maxAglM": 121}}"#;
    assert_error(&post(&mut c, missing), 400, "invalid_request", &["missing field `operator`"]);
    assert_error(&post(&mut c, "42"), 400, "invalid_request", &["expected struct EntryRequest"]);

    let r = c.post_json("/zones/nowhere/requests", Some(DPS), &good).unwrap();
    assert_error(&r, 404, "unknown_zone", &["nowhere"]);
    let r = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-9", "chicago-dps", 107.0, 121.0)).unwrap();
    assert_error(&r, 404, "unknown_drone", &["public-safety-9", "fleet file"]);
    let r = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", 121.0, 107.0)).unwrap();
    assert_error(&r, 422, "invalid_altitude_band", &["minAglM", "below", "maxAglM"]);
    let r = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", -5.0, 107.0)).unwrap();
    assert_error(&r, 422, "invalid_altitude_band", &["minAglM", ">= 0"]);

    // Only the two well-formed requests with a known drone and band were decided.
    assert_eq!(state.lock().unwrap().authority.requests.len(), 1);
}

#[test]
fn huge_bodies_are_refused_without_being_read() {
    let (service, _state) = serve();
    let huge = format!(r#"{{"drone": "{}"}}"#, "x".repeat(1024 * 1024));
    let mut c = client(service.addr);
    let r = c.post_json(ZONE_PATH, Some(DPS), &huge).unwrap();
    assert_error(&r, 413, "body_too_large", &["16384 bytes"]);
    assert_eq!(r.header("connection"), Some("close"));

    // Without a Content-Length (chunked), the limit holds while reading.
    let chunk = "x".repeat(8000);
    let mut raw = format!(
        "POST {ZONE_PATH} HTTP/1.1\r\nHost: test\r\nAuthorization: Bearer {DPS}\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n"
    );
    for _ in 0..4 {
        raw.push_str(&format!("{:x}\r\n{chunk}\r\n", chunk.len()));
    }
    raw.push_str("0\r\n\r\n");
    assert_error(&client(service.addr).send_raw(raw.as_bytes()).unwrap(), 413, "body_too_large", &["16384"]);

    // Just under the limit is read and parsed (and is not an entry request).
    let padded = format!(r#"{{"drone": "{}"}}"#, "x".repeat(MAX_BODY_BYTES - 20));
    assert_error(&c.post_json(ZONE_PATH, Some(DPS), &padded).unwrap(), 400, "invalid_request", &["missing field"]);
}

#[test]
fn unknown_routes_and_methods_are_json_errors() {
    let (service, _state) = serve();
    let mut c = client(service.addr);
    assert_error(&c.get("/nothing/here").unwrap(), 404, "unknown_route", &["GET /nothing/here", "/zones"]);
    assert_error(&c.get("/zones/museum-tfr/requests").unwrap(), 405, "method_not_allowed", &["GET"]);
    let r = c.request("DELETE", "/zones", &[], b"").unwrap();
    assert_error(&r, 405, "method_not_allowed", &["DELETE", "/zones"]);
    assert_eq!(r.header("allow"), Some("GET,HEAD"));
}

#[test]
fn every_listed_route_is_served() {
    let (service, _state) = serve();
    let mut c = client(service.addr);
    for (method, path) in ROUTES {
        let concrete = path.replace("{id}", "x");
        let r = c.request(&method.to_ascii_uppercase(), &concrete, &[], b"").unwrap();
        let code = r.json().ok().and_then(|b| b["error"].as_str().map(str::to_string));
        assert!(
            !matches!(code.as_deref(), Some("unknown_route" | "method_not_allowed")),
            "{method} {path}: {} {}",
            r.status,
            r.text()
        );
    }
}

/// Sends `bytes` on a fresh connection, closes the sending side and reads whatever comes
/// back (for at most 2 s): the answer does not matter, only that the service survives.
fn send_and_hang_up(addr: SocketAddr, bytes: &[u8]) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(addr).expect("connect");
    stream.set_read_timeout(Some(std::time::Duration::from_secs(2))).unwrap();
    let _ = stream.write_all(bytes);
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let _ = stream.read_to_end(&mut Vec::new());
}

#[test]
fn the_service_keeps_serving_after_a_burst_of_bad_requests() {
    let (service, _state) = serve();
    let huge_body = "y".repeat(200_000);
    let garbage: Vec<Vec<u8>> = vec![
        b"NOT HTTP AT ALL\r\n\r\n".to_vec(),
        b"\x00\xff\xfe\r\n\r\n".to_vec(),
        b"POST /zones/museum-tfr/requests HTTP/1.1\r\nContent-Length: nope\r\n\r\n".to_vec(),
        format!("POST {ZONE_PATH} HTTP/1.1\r\nHost: t\r\nContent-Length: {}\r\n\r\n{huge_body}", huge_body.len())
            .into_bytes(),
        // Announces more than it sends, then the connection closes.
        format!("POST {ZONE_PATH} HTTP/1.1\r\nHost: t\r\nAuthorization: Bearer {DPS}\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{{\"dro").into_bytes(),
    ];
    for round in 0..20 {
        for raw in &garbage {
            send_and_hang_up(service.addr, raw);
        }
        let mut c = client(service.addr);
        let r = c.post_json(ZONE_PATH, Some(DPS), &format!("{{\"drone\": {round}}}")).unwrap();
        assert_eq!(r.status, 400);
        assert_eq!(c.request("POST", ZONE_PATH, &[], b"{}").unwrap().status, 401);
        assert_eq!(c.get("/nope").unwrap().status, 404);
    }
    let mut c = client(service.addr);
    let r = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-4", "chicago-dps", 107.0, 121.0)).unwrap();
    assert_eq!(body(&r)["verdict"], "granted");
    assert_eq!(c.get("/healthz").unwrap().status, 200);
}

#[test]
fn stopping_closes_the_port_even_with_idle_connections_open() {
    let (service, _state) = serve();
    let addr = service.addr;
    let mut idle = client(addr);
    assert_eq!(idle.get("/healthz").unwrap().status, 200);
    service.stop();
    assert!(std::net::TcpStream::connect(addr).is_err(), "the port is closed after stop()");
    assert!(idle.get("/healthz").is_err(), "the idle keep-alive connection was closed");
}

#[test]
fn binding_a_taken_port_is_an_error() {
    let (service, state) = serve();
    let e = start(state, service.addr).expect_err("the port is taken");
    assert_eq!(e.kind(), std::io::ErrorKind::AddrInUse);
}

/// `docs/airspace-api.yaml` documents exactly the routes of [`ROUTES`], and its references
/// resolve.
#[test]
fn the_openapi_file_documents_every_route() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/airspace-api.yaml");
    let text = std::fs::read_to_string(path).expect("docs/airspace-api.yaml exists");
    let doc: serde_yaml::Value = serde_yaml::from_str(&text).expect("the OpenAPI file is YAML");
    assert!(doc["openapi"].as_str().is_some_and(|v| v.starts_with("3.1.")), "OpenAPI 3.1");

    let methods = ["get", "put", "post", "delete", "patch", "head", "options"];
    let mut documented = BTreeSet::new();
    for (p, item) in doc["paths"].as_mapping().expect("paths") {
        for (m, op) in item.as_mapping().expect("a path item") {
            let m = m.as_str().unwrap();
            if methods.contains(&m) {
                assert!(op["responses"].as_mapping().is_some_and(|r| !r.is_empty()), "{m} {p:?} has responses");
                assert!(op["operationId"].as_str().is_some(), "{m} {p:?} has an operationId");
                documented.insert((m.to_string(), p.as_str().unwrap().to_string()));
            }
        }
    }
    let served: BTreeSet<(String, String)> = ROUTES.iter().map(|(m, p)| (m.to_string(), p.to_string())).collect();
    assert_eq!(documented, served, "documented routes vs served routes");

    // Every `$ref` points at something that exists.
    fn refs(v: &serde_yaml::Value, out: &mut Vec<String>) {
        match v {
            serde_yaml::Value::Mapping(m) => {
                for (k, v) in m {
                    if k.as_str() == Some("$ref") {
                        out.push(v.as_str().expect("a $ref is a string").to_string());
                    }
                    refs(v, out);
                }
            }
            serde_yaml::Value::Sequence(s) => s.iter().for_each(|v| refs(v, out)),
            _ => {}
        }
    }
    let mut all = Vec::new();
    refs(&doc, &mut all);
    assert!(!all.is_empty());
    for r in all {
        let target = r.strip_prefix("#/").unwrap_or_else(|| panic!("{r} is a local reference"));
        let node = target.split('/').fold(&doc, |node, key| &node[key]);
        assert!(!node.is_null(), "{r} resolves");
    }
}

/// The spec states every limit the authority puts on an altitude band, as JSON Schema
/// where JSON Schema can (each bound alone: `0 <= minAglM < 20000`, `0 < maxAglM <= 20000`)
/// and in words where it cannot (`minAglM < maxAglM`, answered 422): a schema-valid band is
/// refused only for the relation between its two bounds.
#[test]
fn the_spec_states_the_altitude_band_limits_the_authority_enforces() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/airspace-api.yaml");
    let doc: serde_yaml::Value = serde_yaml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let band = &doc["components"]["schemas"]["AltitudeBand"];
    let limit = |field: &str, key: &str| band["properties"][field][key].as_f64();
    let max = sadesim_engine::airspace::authority::MAX_BAND_AGL_M;
    assert_eq!(band["additionalProperties"].as_bool(), Some(false));
    assert_eq!((limit("minAglM", "minimum"), limit("minAglM", "exclusiveMaximum")), (Some(0.0), Some(max)));
    assert_eq!((limit("maxAglM", "exclusiveMinimum"), limit("maxAglM", "maximum")), (Some(0.0), Some(max)));
    let relation = "`minAglM < maxAglM`";
    assert!(band["description"].as_str().is_some_and(|d| d.contains(relation)), "{:?}", band["description"]);
    let op = &doc["paths"]["/zones/{id}/requests"]["post"];
    assert!(op["responses"]["422"]["description"].as_str().is_some_and(|d| d.contains("minAglM == maxAglM")));

    // And the service answers exactly so at the edges.
    let (service, _state) = serve();
    let mut c = client(service.addr);
    for (lo, hi, status) in [(0.0, 0.0, 422), (110.0, 110.0, 422), (121.0, 107.0, 422), (107.0, 121.0, 200)] {
        let r = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", lo, hi)).unwrap();
        assert_eq!(r.status, status, "band {lo}-{hi}: {}", r.text());
    }
    let r = c.post_json(ZONE_PATH, Some(DPS), &entry("public-safety-0", "chicago-dps", 0.0, max)).unwrap();
    assert_eq!(body(&r)["verdict"], "denied", "a band up to the limit is decided: {}", r.text());
}
