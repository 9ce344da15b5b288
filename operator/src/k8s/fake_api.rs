//! The requests a fake API server (tower_test's mock service) receives in the controllers'
//! tests, read into [`Seen`] for the tests to answer and assert on.

use std::collections::BTreeMap;

use http::{Method, Request};
use kube::client::Body;
use serde_json::Value;

/// One request as the fake API server saw it.
#[derive(Clone, Debug)]
pub struct Seen {
    pub method: Method,
    pub path: String,
    /// The query's parameters, percent-decoded (`labelSelector`, `fieldManager`, ...).
    pub query: BTreeMap<String, String>,
    pub content_type: String,
    /// The body as JSON (`Null` when it is not JSON or empty).
    pub body: Value,
}

impl Seen {
    /// Reads `request` whole.
    pub async fn read(request: Request<Body>) -> Self {
        let (parts, body) = request.into_parts();
        let bytes = body.collect_bytes().await.expect("the client's body");
        let query = parts
            .uri
            .query()
            .unwrap_or_default()
            .split('&')
            .filter(|kv| !kv.is_empty())
            .map(|kv| {
                let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
                (k.to_string(), percent_decode(v))
            })
            .collect();
        let content_type = parts
            .headers
            .get(http::header::CONTENT_TYPE)
            .map(|v| v.to_str().expect("an ASCII content type").to_string())
            .unwrap_or_default();
        Self {
            method: parts.method,
            path: parts.uri.path().to_string(),
            query,
            content_type,
            body: serde_json::from_slice(&bytes).unwrap_or(Value::Null),
        }
    }

    /// Whether this is `method` on `path`.
    pub fn is(&self, method: Method, path: &str) -> bool {
        self.method == method && self.path == path
    }
}

/// `%2F` -> `/`, `+` -> space.
pub fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).expect("ASCII hex digits");
            out.push(u8::from_str_radix(hex, 16).expect("hex digits"));
            i += 3;
        } else {
            out.push(if bytes[i] == b'+' { b' ' } else { bytes[i] });
            i += 1;
        }
    }
    String::from_utf8(out).expect("UTF-8 query")
}
