//! The airspace authority's HTTP/JSON API (axum), served by the coordinator. See
//! `docs/airspace-api.yaml` (OpenAPI 3.1) for the contract.
//!
//! A thin shell around [`AirspaceState`]: every handler validates its input, locks the
//! state once, asks the [`Authority`](super::authority::Authority) (which decides, purely)
//! and answers. Decisions are stamped with the sim time of the latest coordinator window
//! (`state.time_s`), so a request between two windows is decided as of the earlier one.
//!
//! # Errors on the wire
//! A denial is a verdict and is answered 200. Requests the authority cannot decide get a
//! 4xx with `{"error": "<code>", "message": "<what is wrong and what is expected>"}`;
//! unknown routes and methods too (404, 405). Checks on `POST /zones/{id}/requests` run in
//! this order: bearer token present and a credential of this run (401), `Content-Type`
//! (415), body size (413), JSON (400, unknown fields at any depth included), zone (404),
//! drone (404), altitude band (422).
//!
//! # Guarantees
//! No request can stop the service: bodies are read up to [`MAX_BODY_BYTES`] and no further,
//! every parse error is an answer, and a handler that panicked (a bug) only loses its own
//! connection: the state lock's poison is ignored because the authority changes its state
//! whole, one request at a time.

pub mod client;

use std::net::SocketAddr;
use std::sync::{MutexGuard, PoisonError};
use std::time::Duration;

use axum::Router;
use axum::body::{Body, HttpBody};
use axum::extract::rejection::PathRejection;
use axum::extract::{FromRequest, FromRequestParts, Path, RawQuery, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::authority::{Authority, AuthorityError, constant_time_eq};
use super::{AirspaceState, SharedAirspace};
use sadesim_engine::events::Event;

/// Largest request body accepted, bytes (an entry request is about 100 bytes).
pub const MAX_BODY_BYTES: usize = 16 * 1024;
/// Events per `GET /events` page when `limit` is not given.
pub const DEFAULT_EVENTS_LIMIT: usize = 1000;
/// Largest `limit` of `GET /events`.
pub const MAX_EVENTS_LIMIT: usize = 10_000;
/// How long a stopping service waits for requests in flight before cutting connections.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(5);

/// What `POST /zones/{id}/requests` expects, for error messages.
const ENTRY_REQUEST_SHAPE: &str =
    r#"{"drone": "<drone name>", "operator": "<operator id>", "altitude": {"minAglM": <number>, "maxAglM": <number>}}"#;

/// A 4xx answer: `{"error": code, "message": message}`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiError {
    pub status: StatusCode,
    /// Stable, machine-readable (`missing_token`, `invalid_json`, `unknown_zone`, ...).
    pub code: &'static str,
    /// A sentence for people: what is wrong and what is expected.
    pub message: String,
}

impl ApiError {
    fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self { status, code, message: message.into() }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut response =
            (self.status, axum::Json(json!({"error": self.code, "message": self.message}))).into_response();
        let headers = response.headers_mut();
        if self.status == StatusCode::UNAUTHORIZED {
            headers.insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        if self.status == StatusCode::PAYLOAD_TOO_LARGE {
            // The rest of the body is not read: the connection cannot carry another request.
            headers.insert(header::CONNECTION, HeaderValue::from_static("close"));
        }
        response
    }
}

impl From<AuthorityError> for ApiError {
    fn from(e: AuthorityError) -> Self {
        let (status, code) = match &e {
            AuthorityError::UnknownZone(_) => (StatusCode::NOT_FOUND, "unknown_zone"),
            AuthorityError::UnknownDrone(_) => (StatusCode::NOT_FOUND, "unknown_drone"),
            AuthorityError::UnknownLease(_) => (StatusCode::NOT_FOUND, "unknown_lease"),
            AuthorityError::NotHolder(_) => (StatusCode::FORBIDDEN, "not_lease_holder"),
            AuthorityError::LeaseEnded(_) => (StatusCode::CONFLICT, "lease_ended"),
            AuthorityError::InvalidBand(_) => (StatusCode::UNPROCESSABLE_ENTITY, "invalid_altitude_band"),
        };
        Self::new(status, code, e.to_string())
    }
}

/// The `{id}` path segment, with axum's rejection (invalid percent-encoding) as a JSON 400.
fn path_id(path: Result<Path<String>, PathRejection>) -> Result<String, ApiError> {
    path.map(|Path(id)| id)
        .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, "invalid_path", format!("invalid path: {e}")))
}

/// The credential of an `Authorization: Bearer <token>` header, known to be the credential
/// of one of the run's groups (which group is the authority's business: a drone presenting
/// another group's credential is a decided request, denied).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bearer(pub String);

impl FromRequestParts<SharedAirspace> for Bearer {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &SharedAirspace) -> Result<Self, ApiError> {
        let token = bearer(&parts.headers)?;
        authenticate(&lock(state).authority, &token)?;
        Ok(Bearer(token))
    }
}

/// 401 `invalid_token` unless `token` is the credential of one of the run's groups (RFC
/// 6750 §3.1). An unknown token is refused before anything is decided or logged, so a
/// client without a credential cannot write into the run's airspace log. Every credential
/// is compared in full, so the answer's timing does not tell how much of a token matched.
fn authenticate(authority: &Authority, token: &str) -> Result<(), ApiError> {
    let mut known = false;
    for credential in authority.requesters.iter().filter_map(|r| r.credential.as_deref()) {
        known |= constant_time_eq(token.as_bytes(), credential.as_bytes());
    }
    if known {
        Ok(())
    } else {
        Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "invalid_token",
            "the bearer token is not a credential of this run: send your drone group's credential \
             (`credential` in the scenario; `SADESIM_CREDENTIAL_<GROUP>` in a pilot's environment)",
        ))
    }
}

/// Reads the bearer token. Missing, empty or another scheme: 401 `missing_token` (a request
/// without a credential is refused, never decided as anonymous).
fn bearer(headers: &HeaderMap) -> Result<String, ApiError> {
    let unauthorized = |message: &str| ApiError::new(StatusCode::UNAUTHORIZED, "missing_token", message);
    let Some(value) = headers.get(header::AUTHORIZATION) else {
        return Err(unauthorized(
            "this endpoint needs the drone's credential in an `Authorization: Bearer <token>` header",
        ));
    };
    let value = value.to_str().map_err(|_| unauthorized("the Authorization header must be visible ASCII text"))?;
    // The scheme name is case-insensitive (RFC 9110 §11.1); `Bearer` alone (trailing
    // whitespace is not part of a header value) is an empty token.
    let (scheme, token) = value.split_once(' ').unwrap_or((value, ""));
    if !scheme.eq_ignore_ascii_case("bearer") {
        return Err(unauthorized(
            "the Authorization header must use the Bearer scheme: `Authorization: Bearer <token>`",
        ));
    }
    let token = token.trim();
    if token.is_empty() {
        return Err(unauthorized("the bearer token is empty: send `Authorization: Bearer <token>`"));
    }
    Ok(token.to_string())
}

/// A JSON body parsed with our own messages: 415 unless `Content-Type: application/json`,
/// 413 over [`MAX_BODY_BYTES`] (read no further), 400 naming the field, line and column.
#[derive(Debug, Clone, PartialEq)]
pub struct ApiJson<T>(pub T);

impl<S: Send + Sync, T: DeserializeOwned> FromRequest<S> for ApiJson<T> {
    type Rejection = ApiError;

    async fn from_request(req: Request, _state: &S) -> Result<Self, ApiError> {
        check_json_content_type(req.headers())?;
        let bytes = read_body(req.into_body()).await?;
        parse_json(&bytes).map(ApiJson)
    }
}

fn check_json_content_type(headers: &HeaderMap) -> Result<(), ApiError> {
    let unsupported = |got: &str| {
        ApiError::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "unsupported_media_type",
            format!("the body must be JSON sent with `Content-Type: application/json`, got {got}"),
        )
    };
    let Some(value) = headers.get(header::CONTENT_TYPE) else {
        return Err(unsupported("no Content-Type header"));
    };
    let text = value.to_str().unwrap_or("");
    // Parameters (`; charset=utf-8`) are allowed; JSON is always UTF-8 anyway.
    let essence = text.split(';').next().unwrap_or("").trim();
    if essence.eq_ignore_ascii_case("application/json") { Ok(()) } else { Err(unsupported(&format!("`{text}`"))) }
}

fn too_large() -> ApiError {
    ApiError::new(
        StatusCode::PAYLOAD_TOO_LARGE,
        "body_too_large",
        format!("the request body is larger than {MAX_BODY_BYTES} bytes; an entry request is a small JSON object"),
    )
}

/// Reads the body frame by frame and stops at the first byte over the limit, so a huge body
/// costs at most [`MAX_BODY_BYTES`] of memory (a declared `Content-Length` over the limit
/// is refused before reading anything).
async fn read_body(mut body: Body) -> Result<Vec<u8>, ApiError> {
    if body.size_hint().lower() > MAX_BODY_BYTES as u64 {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    while let Some(frame) = std::future::poll_fn(|cx| std::pin::Pin::new(&mut body).poll_frame(cx)).await {
        let frame = frame.map_err(|e| {
            ApiError::new(StatusCode::BAD_REQUEST, "invalid_body", format!("failed to read the request body: {e}"))
        })?;
        if let Ok(data) = frame.into_data() {
            if bytes.len() + data.len() > MAX_BODY_BYTES {
                return Err(too_large());
            }
            bytes.extend_from_slice(&data);
        }
    }
    Ok(bytes)
}

/// `serde_json` with the path of the field that failed: 400 `invalid_json` when the text
/// is not JSON, `invalid_request` when it is JSON of the wrong shape.
fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "invalid_json",
            format!("the request body is empty; expected a JSON object {ENTRY_REQUEST_SHAPE}"),
        ));
    }
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        json_error(&inner, (path != ".").then_some(path))
    })?;
    de.end().map_err(|e| json_error(&e, None))?;
    Ok(value)
}

fn json_error(e: &serde_json::Error, path: Option<String>) -> ApiError {
    use serde_json::error::Category;
    match e.classify() {
        Category::Syntax | Category::Eof | Category::Io => ApiError::new(
            StatusCode::BAD_REQUEST,
            "invalid_json",
            format!("the request body is not valid JSON: {e}; expected {ENTRY_REQUEST_SHAPE}"),
        ),
        Category::Data => {
            let field = path.map(|p| format!("field `{p}`: ")).unwrap_or_default();
            ApiError::new(
                StatusCode::BAD_REQUEST,
                "invalid_request",
                format!("invalid request body: {field}{e}; expected {ENTRY_REQUEST_SHAPE}"),
            )
        }
    }
}

/// `POST /zones/{id}/requests`'s body as it travels: unknown fields are refused at every
/// depth (`altitude` included), so a field the service would ignore is a 400 naming it,
/// never silently dropped.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
struct EntryRequest {
    drone: String,
    operator: String,
    altitude: AltitudeBand,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
struct AltitudeBand {
    min_agl_m: f64,
    max_agl_m: f64,
}

impl From<EntryRequest> for super::authority::EntryRequest {
    fn from(r: EntryRequest) -> Self {
        let altitude = sadesim_crds::outcome::compliance::AltitudeBand {
            min_agl_m: r.altitude.min_agl_m,
            max_agl_m: r.altitude.max_agl_m,
        };
        Self { drone: r.drone, operator: r.operator, altitude }
    }
}

/// The state, even if a handler panicked while holding it (see the module's guarantees).
fn lock(state: &SharedAirspace) -> MutexGuard<'_, AirspaceState> {
    state.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The API's routes on `state`. Unknown routes answer 404 and known routes with another
/// method 405, both as JSON errors.
pub fn router(state: SharedAirspace) -> Router {
    Router::new()
        .route("/healthz", get(healthz))
        .route("/zones", get(list_zones))
        .route("/zones/{id}", get(get_zone))
        .route("/zones/{id}/requests", post(request_entry))
        .route("/leases/{id}", get(get_lease).delete(release_lease))
        .route("/leases/{id}/renew", post(renew_lease))
        .route("/events", get(list_events))
        .fallback(unknown_route)
        .method_not_allowed_fallback(method_not_allowed)
        .with_state(state)
}

async fn unknown_route(request: Request) -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        "unknown_route",
        format!(
            "no route {} {}; the API serves /healthz, /zones, /zones/{{id}}, /zones/{{id}}/requests, /leases/{{id}}, /leases/{{id}}/renew and /events (see docs/airspace-api.yaml)",
            request.method(),
            request.uri().path()
        ),
    )
}

async fn method_not_allowed(request: Request) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        format!("{} is not allowed on {} (see the Allow header)", request.method(), request.uri().path()),
    )
}

async fn healthz(State(state): State<SharedAirspace>) -> Response {
    let (time_s, released) = {
        let state = lock(&state);
        (state.time_s, state.pilots_released)
    };
    axum::Json(json!({"status": "ok", "simTimeS": time_s, "pilotsReleased": released})).into_response()
}

async fn list_zones(State(state): State<SharedAirspace>) -> Response {
    let state = lock(&state);
    let features: Vec<Value> = (0..state.zone_specs.len()).map(|i| zone_feature(&state, i)).collect();
    axum::Json(json!({"type": "FeatureCollection", "features": features})).into_response()
}

async fn get_zone(State(state): State<SharedAirspace>, path: Result<Path<String>, PathRejection>) -> Response {
    let id = match path_id(path) {
        Ok(id) => id,
        Err(e) => return e.into_response(),
    };
    let state = lock(&state);
    match state.zone_specs.iter().position(|z| z.name == id) {
        Some(i) => axum::Json(zone_feature(&state, i)).into_response(),
        None => ApiError::from(AuthorityError::UnknownZone(id)).into_response(),
    }
}

/// Zone `i` as a GeoJSON Feature (RFC 7946): the outline as a closed ring of `[lon, lat]`,
/// and as properties its limits, time window (sim seconds), policy and, as of now
/// (`state.time_s`), whether it is active and how many leases are held.
fn zone_feature(state: &AirspaceState, i: usize) -> Value {
    let spec = &state.zone_specs[i];
    let volume = &state.zones[i];
    let now_s = state.time_s;
    let lease_duration_s = state.authority.rules.iter().find(|r| r.zone == spec.name).map(|r| r.lease_s);
    let mut ring: Vec<Value> = spec.polygon.iter().map(|v| json!([v.longitude_deg, v.latitude_deg])).collect();
    if let Some(first) = ring.first().cloned() {
        ring.push(first);
    }
    let policy = &spec.policy;
    json!({
        "type": "Feature",
        "id": spec.name,
        "geometry": {"type": "Polygon", "coordinates": [ring]},
        "properties": {
            "name": spec.name,
            "floor": spec.floor(),
            "ceiling": spec.ceiling,
            "activeFromS": volume.active_from_s,
            // JSON has no infinity: null means until the end of the run.
            "activeUntilS": volume.active_until_s.is_finite().then_some(volume.active_until_s),
            "active": volume.is_active(now_s),
            "policy": {
                "authorizedOperators": policy.authorized_operators,
                "capacity": policy.capacity,
                "leaseDurationS": lease_duration_s,
                "minAltitudeAglM": policy.min_altitude_agl_m,
                "maxAltitudeAglM": policy.max_altitude_agl_m,
            },
            "leasesHeld": state.authority.leases.held(&spec.name, now_s),
        },
    })
}

async fn request_entry(
    State(state): State<SharedAirspace>,
    path: Result<Path<String>, PathRejection>,
    token: Bearer,
    ApiJson(request): ApiJson<EntryRequest>,
) -> Result<Response, ApiError> {
    let zone = path_id(path)?;
    let mut state = lock(&state);
    // Checked here so that an unknown zone is a 404 whatever else is wrong with the request.
    if !state.authority.rules.iter().any(|r| r.zone == zone) {
        return Err(AuthorityError::UnknownZone(zone).into());
    }
    let request = super::authority::EntryRequest::from(request);
    decide(&mut state, |authority, now_s| authority.request(&zone, &token.0, &request, now_s))
}

/// Asks the authority (`ask`, at the airspace's current time), collects the events it raised
/// and answers with its decision: the answer of every request that may change the leases.
fn decide<T: Serialize>(
    state: &mut AirspaceState,
    ask: impl FnOnce(&mut Authority, f64) -> Result<T, AuthorityError>,
) -> Result<Response, ApiError> {
    let now_s = state.time_s;
    let decision = ask(&mut state.authority, now_s);
    state.collect_authority_events();
    Ok(axum::Json(decision?).into_response())
}

async fn get_lease(
    State(state): State<SharedAirspace>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Response, ApiError> {
    let id = path_id(path)?;
    let state = lock(&state);
    let lease = state.authority.leases.leases.iter().find(|l| l.id == id).ok_or(AuthorityError::UnknownLease(id))?;
    Ok(axum::Json(lease).into_response())
}

async fn renew_lease(
    State(state): State<SharedAirspace>,
    path: Result<Path<String>, PathRejection>,
    token: Bearer,
) -> Result<Response, ApiError> {
    let id = path_id(path)?;
    decide(&mut lock(&state), |authority, now_s| authority.renew(&id, &token.0, now_s))
}

async fn release_lease(
    State(state): State<SharedAirspace>,
    path: Result<Path<String>, PathRejection>,
    token: Bearer,
) -> Result<Response, ApiError> {
    let id = path_id(path)?;
    decide(&mut lock(&state), |authority, now_s| authority.release(&id, &token.0, now_s))
}

/// `GET /events` query: `since` (exclusive sequence number, default 0) and `limit`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EventsQuery {
    pub since: u64,
    pub limit: usize,
}

impl EventsQuery {
    /// Parses `since=N&limit=M` (both optional). Anything else is a 400 naming the
    /// parameter. A whole number too large for 64 bits is read as the largest one: `since`
    /// beyond the end of the log is an empty page whatever its size, and `limit` is then
    /// outside its range like any other large number.
    ///
    /// # Errors
    /// Unknown or repeated parameter, a value that is not a whole number, `limit` outside
    /// `1..=MAX_EVENTS_LIMIT`.
    pub fn parse(query: Option<&str>) -> Result<Self, ApiError> {
        let bad = |message: String| ApiError::new(StatusCode::BAD_REQUEST, "invalid_query", message);
        let (mut since, mut limit) = (None, None);
        for pair in query.unwrap_or("").split('&').filter(|p| !p.is_empty()) {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            let slot = match key {
                "since" => &mut since,
                "limit" => &mut limit,
                _ => return Err(bad(format!("unknown query parameter `{key}`; expected `since` and/or `limit`"))),
            };
            if slot.is_some() {
                return Err(bad(format!("query parameter `{key}` is given twice")));
            }
            let whole = !value.is_empty() && value.bytes().all(|b| b.is_ascii_digit());
            if !whole {
                return Err(bad(format!("query parameter `{key}` must be a whole number >= 0, got {value:?}")));
            }
            *slot = Some((value.parse::<u64>().unwrap_or(u64::MAX), value));
        }
        let (limit, text) = limit.unwrap_or((DEFAULT_EVENTS_LIMIT as u64, ""));
        if limit == 0 || limit > MAX_EVENTS_LIMIT as u64 {
            return Err(bad(format!("query parameter `limit` must be between 1 and {MAX_EVENTS_LIMIT}, got {text}")));
        }
        Ok(Self { since: since.map_or(0, |(n, _)| n), limit: limit as usize })
    }
}

/// An event with its sequence number (1-based position in the run's airspace history).
#[derive(Serialize)]
struct NumberedEvent<'a> {
    seq: u64,
    #[serde(flatten)]
    event: &'a Event,
}

/// Events with sequence number > `since`, oldest first, at most `limit`; `next` is the
/// `since` to ask with next (the last sequence number returned, or where the history ends
/// when nothing is returned, so a cursor from the future does not wait forever).
async fn list_events(State(state): State<SharedAirspace>, RawQuery(query): RawQuery) -> Result<Response, ApiError> {
    let query = EventsQuery::parse(query.as_deref())?;
    let state = lock(&state);
    let start = usize::try_from(query.since).unwrap_or(usize::MAX).min(state.history.len());
    let events: Vec<NumberedEvent> = state.history[start..]
        .iter()
        .take(query.limit)
        .enumerate()
        .map(|(k, event)| NumberedEvent { seq: (start + k + 1) as u64, event })
        .collect();
    let next = (start + events.len()) as u64;
    Ok(axum::Json(json!({"events": events, "next": next})).into_response())
}

/// A running service. Stops (gracefully: requests in flight are answered, for at most 5 s)
/// when dropped or on [`ServiceHandle::stop`], and joins its thread.
pub type ServiceHandle = crate::http_thread::HttpThread;

/// Serves [`router`] on `bind` from a current-thread tokio runtime on its own OS thread
/// (`airspace-http`), so the coordinator's window loop stays synchronous. The socket is
/// bound before this returns: port 0 picks a free port, reported in
/// [`ServiceHandle::addr`].
///
/// # Errors
/// The address cannot be bound, or the runtime or thread cannot be created.
pub fn start(state: SharedAirspace, bind: SocketAddr) -> std::io::Result<ServiceHandle> {
    crate::http_thread::start(bind, router(state), "airspace-http", SHUTDOWN_GRACE)
}

#[cfg(test)]
mod tests;
