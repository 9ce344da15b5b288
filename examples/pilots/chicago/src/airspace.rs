//! Client of the airspace authority's HTTP API (base URL: the fleet file's `airspaceUrl`):
//! the zone list, entry requests, lease renewal and release. The JSON types mirror the API
//! and ignore fields they do not know, so the pilot keeps working when the API grows.

use std::time::Duration;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::http::{self, BaseUrl, HttpError, Response};

/// Per read/write timeout of one API call (wall clock: it bounds a socket, not a flight).
const CALL_TIMEOUT: Duration = Duration::from_secs(5);
/// Connection attempts before the authority counts as unreachable.
const CONNECT_ATTEMPTS: u32 = 5;

/// The altitude band a drone intends to fly in inside a zone, metres above ground.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct AltitudeBand {
    pub min_agl_m: f64,
    pub max_agl_m: f64,
}

/// `POST /zones/{zone}/requests` body.
#[derive(Serialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct EntryRequest {
    /// Drone name from the fleet file (`public-safety-0`).
    pub drone: String,
    pub operator: String,
    pub altitude: AltitudeBand,
}

/// What a lease holder must respect inside the zone (metres above ground).
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct LeaseConstraints {
    #[serde(default)]
    pub min_altitude_agl_m: Option<f64>,
    #[serde(default)]
    pub max_altitude_agl_m: Option<f64>,
}

/// Permission for one drone to be inside one zone until `expires_at_s` (run sim time).
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Lease {
    pub id: String,
    #[serde(default)]
    pub zone: String,
    #[serde(default)]
    pub granted_at_s: Option<f64>,
    pub expires_at_s: f64,
    #[serde(default)]
    pub constraints: LeaseConstraints,
}

/// The authority's answer to an entry request.
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "verdict", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Verdict {
    Granted {
        request_id: u64,
        lease: Lease,
    },
    Denied {
        request_id: u64,
        /// `insufficient_credentials`, `capacity_exhausted`, `unsafe_altitude`,
        /// `zone_inactive` (kept as text: new reasons must not break the pilot).
        reason: String,
        #[serde(default)]
        message: String,
    },
}

/// A call that produced no usable answer.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// No HTTP exchange (authority down, wrong URL, timeout).
    #[error("airspace authority: {0}")]
    Http(HttpError),
    /// The authority refused the call (4xx/5xx) with this message.
    #[error("{call}: HTTP {status}: {message}")]
    Status { call: String, status: u16, message: String },
    /// A 2xx answer whose JSON is not what the API promises.
    #[error("{call}: unexpected answer ({problem}): {body}")]
    Body { call: String, problem: String, body: String },
}

impl From<HttpError> for ApiError {
    fn from(e: HttpError) -> Self {
        Self::Http(e)
    }
}

/// The authority at one base URL.
#[derive(Clone, Debug)]
pub struct Client {
    base: BaseUrl,
}

impl Client {
    /// # Errors
    /// The URL is not `http://host:port`.
    pub fn new(url: &str) -> Result<Self, HttpError> {
        Ok(Self { base: BaseUrl::parse(url)? })
    }

    /// `GET /zones`: the zones as a GeoJSON FeatureCollection.
    ///
    /// # Errors
    /// See [`ApiError`].
    pub fn zones(&self) -> Result<Value, ApiError> {
        self.call("GET", "/zones", None, None)
    }

    /// `POST /zones/{zone}/requests` with the drone's bearer token.
    ///
    /// # Errors
    /// See [`ApiError`]; a denial is a [`Verdict`], not an error.
    pub fn request_entry(&self, zone: &str, token: Option<&str>, request: &EntryRequest) -> Result<Verdict, ApiError> {
        let body = serde_json::to_string(request).expect("plain data serialises");
        self.call("POST", &format!("/zones/{}/requests", path_segment(zone)), token, Some(&body))
    }

    /// `POST /leases/{id}/renew`: the lease with its new expiry.
    ///
    /// # Errors
    /// See [`ApiError`].
    pub fn renew(&self, lease_id: &str, token: Option<&str>) -> Result<Lease, ApiError> {
        let v: Value = self.call("POST", &format!("/leases/{}/renew", path_segment(lease_id)), token, None)?;
        lease_of(&format!("POST /leases/{lease_id}/renew"), v)
    }

    /// `DELETE /leases/{id}`: the lease, now released.
    ///
    /// # Errors
    /// See [`ApiError`].
    pub fn release(&self, lease_id: &str, token: Option<&str>) -> Result<Lease, ApiError> {
        let v: Value = self.call("DELETE", &format!("/leases/{}", path_segment(lease_id)), token, None)?;
        lease_of(&format!("DELETE /leases/{lease_id}"), v)
    }

    /// One call; connection failures are retried a few times (a service that is just
    /// starting, a busy accept queue), anything after the connection is not.
    fn call<T: DeserializeOwned>(
        &self,
        method: &str,
        path: &str,
        token: Option<&str>,
        body: Option<&str>,
    ) -> Result<T, ApiError> {
        let mut attempt = 1;
        loop {
            match http::request(&self.base, method, path, token, body, CALL_TIMEOUT) {
                Ok(r) => return parse_answer(&format!("{method} {path}"), &r),
                Err(HttpError::Connect { .. }) if attempt < CONNECT_ATTEMPTS => {
                    std::thread::sleep(Duration::from_millis(200 * u64::from(attempt)));
                    attempt += 1;
                }
                Err(e) => return Err(e.into()),
            }
        }
    }
}

/// Decodes a 2xx JSON answer into `T`; any other status becomes [`ApiError::Status`] with
/// the service's message (its JSON `message` or `error` field, else the body text).
///
/// # Errors
/// See [`ApiError`].
pub fn parse_answer<T: DeserializeOwned>(call: &str, r: &Response) -> Result<T, ApiError> {
    if !(200..300).contains(&r.status) {
        let json: Option<Value> = serde_json::from_slice(&r.body).ok();
        let field = |k: &str| json.as_ref().and_then(|j| j.get(k)).and_then(Value::as_str).map(str::to_owned);
        let message = field("message").or_else(|| field("error")).unwrap_or_else(|| r.text());
        return Err(ApiError::Status { call: call.to_owned(), status: r.status, message });
    }
    serde_json::from_slice(&r.body).map_err(|e| ApiError::Body {
        call: call.to_owned(),
        problem: e.to_string(),
        body: r.text().chars().take(300).collect(),
    })
}

/// A lease answered either bare or as `{"lease": {...}}`.
fn lease_of(call: &str, v: Value) -> Result<Lease, ApiError> {
    let inner = v.get("lease").cloned().unwrap_or(v);
    let text = inner.to_string();
    serde_json::from_value(inner).map_err(|e| ApiError::Body {
        call: call.to_owned(),
        problem: e.to_string(),
        body: text.chars().take(300).collect(),
    })
}

/// Percent-encodes everything but RFC 3986 unreserved characters (zone names are DNS labels
/// and lease ids `lease-<n>`, so this is a safety net).
fn path_segment(s: &str) -> String {
    s.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' => (b as char).to_string(),
            _ => format!("%{b:02X}"),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn response(status: u16, body: &str) -> Response {
        Response { status, headers: Vec::new(), body: body.as_bytes().to_vec() }
    }

    #[test]
    fn a_grant_carries_the_lease_and_its_minimum_altitude() {
        let body = r#"{"verdict":"granted","requestId":1,"lease":{"id":"lease-1","zone":"museum-tfr","drone":0,
            "droneName":"public-safety-0","operator":"chicago-dps","grantedAtS":210.5,"expiresAtS":810.5,
            "constraints":{"minAltitudeAglM":106.68}}}"#;
        let v: Verdict = parse_answer("POST /zones/museum-tfr/requests", &response(200, body)).unwrap();
        let Verdict::Granted { request_id, lease } = v else { panic!("{v:?}") };
        assert_eq!(request_id, 1);
        assert_eq!(lease.id, "lease-1");
        assert_eq!(lease.granted_at_s, Some(210.5));
        assert_eq!(lease.expires_at_s, 810.5);
        assert_eq!(lease.constraints.min_altitude_agl_m, Some(106.68));
        assert_eq!(lease.constraints.max_altitude_agl_m, None);
    }

    #[test]
    fn a_denial_carries_its_reason() {
        let body = r#"{"verdict":"denied","requestId":2,"reason":"insufficient_credentials","message":"wgn-news is not authorized"}"#;
        let v: Verdict = parse_answer("POST", &response(200, body)).unwrap();
        assert_eq!(
            v,
            Verdict::Denied {
                request_id: 2,
                reason: "insufficient_credentials".into(),
                message: "wgn-news is not authorized".into()
            }
        );
    }

    #[test]
    fn error_statuses_keep_the_services_message() {
        let e = parse_answer::<Verdict>(
            "POST /zones/nope/requests",
            &response(404, r#"{"error":"unknown zone \"nope\""}"#),
        )
        .unwrap_err();
        assert_eq!(e.to_string(), "POST /zones/nope/requests: HTTP 404: unknown zone \"nope\"");
        let e = parse_answer::<Verdict>("POST", &response(401, "missing bearer token")).unwrap_err();
        assert!(matches!(e, ApiError::Status { status: 401, ref message, .. } if message == "missing bearer token"));
    }

    #[test]
    fn an_answer_of_the_wrong_shape_is_an_error() {
        let e = parse_answer::<Verdict>("POST", &response(200, r#"{"verdict":"maybe"}"#)).unwrap_err();
        assert!(matches!(e, ApiError::Body { .. }), "{e}");
        let e = parse_answer::<Verdict>("POST", &response(200, "<html>")).unwrap_err();
        assert!(e.to_string().contains("<html>"), "{e}");
    }

    #[test]
    fn leases_are_read_bare_or_wrapped() {
        let bare = serde_json::json!({"id": "lease-4", "expiresAtS": 900.0});
        assert_eq!(lease_of("renew", bare.clone()).unwrap().id, "lease-4");
        assert_eq!(lease_of("renew", serde_json::json!({"lease": bare})).unwrap().expires_at_s, 900.0);
        assert!(lease_of("renew", serde_json::json!({"id": 4})).is_err());
    }

    #[test]
    fn requests_serialise_as_the_api_expects() {
        let r = EntryRequest {
            drone: "public-safety-0".into(),
            operator: "chicago-dps".into(),
            altitude: AltitudeBand { min_agl_m: 110.0, max_agl_m: 121.0 },
        };
        assert_eq!(
            serde_json::to_value(&r).unwrap(),
            serde_json::json!({"drone":"public-safety-0","operator":"chicago-dps","altitude":{"minAglM":110.0,"maxAglM":121.0}})
        );
        assert_eq!(path_segment("museum-tfr"), "museum-tfr");
        assert_eq!(path_segment("a b/c"), "a%20b%2Fc");
    }
}
