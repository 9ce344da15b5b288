//! A tiny HTTP/1.1 client on `std::net::TcpStream`: one request per connection
//! (`Connection: close`), JSON bodies, a bearer token. Enough for the airspace API and no
//! HTTP crate to pull in; [`parse_response`] is pure so the parsing is tested without a
//! server.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// Largest response body accepted, bytes (the zone list of a city fits in far less).
pub const MAX_RESPONSE_BYTES: usize = 4 << 20;

/// Where a service lives: `http://host:port/prefix`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BaseUrl {
    pub host: String,
    pub port: u16,
    /// Path prefix without a trailing slash (`""` for the root).
    pub prefix: String,
}

/// A response with its body (chunked transfer decoded).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Response {
    pub status: u16,
    /// Header names lower-cased, values trimmed, in order.
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Response {
    /// The first header of that (case-insensitive) name.
    pub fn header(&self, name: &str) -> Option<&str> {
        let name = name.to_ascii_lowercase();
        self.headers.iter().find(|(n, _)| *n == name).map(|(_, v)| v.as_str())
    }

    /// The body as text (lossy), for messages.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).trim().to_owned()
    }
}

/// Why a request got no HTTP response.
#[derive(Debug, thiserror::Error)]
pub enum HttpError {
    /// The base URL is not `http://host[:port][/prefix]`.
    #[error("invalid URL {url:?}: {problem}")]
    Url { url: String, problem: String },
    /// Name resolution or the TCP connection failed (service down, wrong port).
    #[error("failed to connect to {address}: {error}")]
    Connect { address: String, error: std::io::Error },
    /// The connection broke or timed out mid-exchange.
    #[error("failed to talk to {address}: {error}")]
    Io { address: String, error: std::io::Error },
    /// The bytes that came back are not an HTTP/1.x response.
    #[error("malformed HTTP response: {0}")]
    Malformed(String),
}

impl BaseUrl {
    /// Parses `http://host[:port][/prefix]` (port 80 by default).
    ///
    /// # Errors
    /// Another scheme, an empty host, a bad port.
    pub fn parse(url: &str) -> Result<Self, HttpError> {
        let bad = |problem: &str| HttpError::Url { url: url.to_owned(), problem: problem.to_owned() };
        let rest = url.strip_prefix("http://").ok_or_else(|| bad("expected http://host:port"))?;
        let (authority, prefix) = match rest.find('/') {
            Some(i) => (&rest[..i], rest[i..].trim_end_matches('/')),
            None => (rest, ""),
        };
        let (host, port) = match authority.rsplit_once(':') {
            Some((h, p)) => (h, p.parse::<u16>().map_err(|_| bad("the port is not a number in 1..65535"))?),
            None => (authority, 80),
        };
        if host.is_empty() {
            return Err(bad("the host is empty"));
        }
        Ok(Self { host: host.to_owned(), port, prefix: prefix.to_owned() })
    }

    /// `host:port`, for messages and the Host header.
    pub fn address(&self) -> String {
        format!("{}:{}", self.host, self.port)
    }
}

/// The request bytes: request line, Host, optional bearer token, JSON body with its length.
pub fn build_request(base: &BaseUrl, method: &str, path: &str, bearer: Option<&str>, json: Option<&str>) -> String {
    let mut out = format!("{method} {}{path} HTTP/1.1\r\nHost: {}\r\n", base.prefix, base.address());
    out.push_str("Accept: application/json\r\nConnection: close\r\n");
    if let Some(token) = bearer {
        out.push_str(&format!("Authorization: Bearer {token}\r\n"));
    }
    let body = json.unwrap_or("");
    if json.is_some() {
        out.push_str("Content-Type: application/json\r\n");
    }
    if json.is_some() || method != "GET" {
        out.push_str(&format!("Content-Length: {}\r\n", body.len()));
    }
    out.push_str("\r\n");
    out.push_str(body);
    out
}

/// Sends one request and reads the whole response (the server closes the connection).
///
/// # Errors
/// No connection, a broken or timed-out exchange (`timeout` per read/write), or a
/// malformed response. An HTTP error status is a response, not an error.
pub fn request(
    base: &BaseUrl,
    method: &str,
    path: &str,
    bearer: Option<&str>,
    json: Option<&str>,
    timeout: Duration,
) -> Result<Response, HttpError> {
    let address = base.address();
    let connect_err = |error| HttpError::Connect { address: address.clone(), error };
    let addrs: Vec<_> = (base.host.as_str(), base.port).to_socket_addrs().map_err(connect_err)?.collect();
    let mut last = std::io::Error::new(std::io::ErrorKind::NotFound, "the host name resolves to no address");
    let mut stream = None;
    for a in addrs {
        match TcpStream::connect_timeout(&a, timeout) {
            Ok(s) => {
                stream = Some(s);
                break;
            }
            Err(e) => last = e,
        }
    }
    let mut stream = stream.ok_or_else(|| connect_err(last))?;
    let io_err = |error| HttpError::Io { address: address.clone(), error };
    stream.set_read_timeout(Some(timeout)).map_err(io_err)?;
    stream.set_write_timeout(Some(timeout)).map_err(io_err)?;
    stream.write_all(build_request(base, method, path, bearer, json).as_bytes()).map_err(io_err)?;
    let mut raw = Vec::new();
    stream.take(MAX_RESPONSE_BYTES as u64 + 1).read_to_end(&mut raw).map_err(io_err)?;
    if raw.len() > MAX_RESPONSE_BYTES {
        return Err(HttpError::Malformed(format!("response larger than {MAX_RESPONSE_BYTES} bytes")));
    }
    parse_response(&raw)
}

/// Parses a complete HTTP/1.x response: status line, headers, then a body delimited by
/// `Content-Length`, by chunked transfer coding, or by the end of the bytes.
///
/// # Errors
/// No blank line after the headers, a bad status line or header, a body shorter than its
/// `Content-Length`, broken chunks.
pub fn parse_response(raw: &[u8]) -> Result<Response, HttpError> {
    let malformed = |m: &str| HttpError::Malformed(m.to_owned());
    let end = raw.windows(4).position(|w| w == b"\r\n\r\n").ok_or_else(|| malformed("no end of headers"))?;
    let head = std::str::from_utf8(&raw[..end]).map_err(|_| malformed("headers are not UTF-8"))?;
    let mut lines = head.split("\r\n");
    let status_line = lines.next().unwrap_or_default();
    let mut parts = status_line.splitn(3, ' ');
    let version = parts.next().unwrap_or_default();
    if !version.starts_with("HTTP/1.") {
        return Err(HttpError::Malformed(format!("not an HTTP/1.x status line: {status_line:?}")));
    }
    let status = parts
        .next()
        .and_then(|s| s.parse::<u16>().ok())
        .filter(|s| (100..=999).contains(s))
        .ok_or_else(|| HttpError::Malformed(format!("bad status code in {status_line:?}")))?;
    let mut headers = Vec::new();
    for line in lines {
        let (name, value) =
            line.split_once(':').ok_or_else(|| HttpError::Malformed(format!("bad header line {line:?}")))?;
        headers.push((name.trim().to_ascii_lowercase(), value.trim().to_owned()));
    }
    let mut response = Response { status, headers, body: Vec::new() };
    let rest = &raw[end + 4..];
    let chunked = response.header("transfer-encoding").is_some_and(|v| v.to_ascii_lowercase().contains("chunked"));
    response.body = if chunked {
        decode_chunked(rest)?
    } else if let Some(length) = response.header("content-length") {
        let length: usize = length.parse().map_err(|_| malformed("Content-Length is not a number"))?;
        if rest.len() < length {
            return Err(HttpError::Malformed(format!(
                "body has {} of its {length} bytes (Content-Length)",
                rest.len()
            )));
        }
        rest[..length].to_vec()
    } else {
        rest.to_vec()
    };
    Ok(response)
}

/// Decodes a chunked body: hex size line, data, CRLF, ..., a zero-size chunk.
fn decode_chunked(mut rest: &[u8]) -> Result<Vec<u8>, HttpError> {
    let malformed = |m: &str| HttpError::Malformed(format!("chunked body: {m}"));
    let mut body = Vec::new();
    loop {
        let line_end = rest.windows(2).position(|w| w == b"\r\n").ok_or_else(|| malformed("no chunk size line"))?;
        let line = std::str::from_utf8(&rest[..line_end]).map_err(|_| malformed("size line is not text"))?;
        let hex = line.split(';').next().unwrap_or_default().trim();
        let size = usize::from_str_radix(hex, 16).map_err(|_| malformed("chunk size is not hexadecimal"))?;
        rest = &rest[line_end + 2..];
        if size == 0 {
            return Ok(body);
        }
        if rest.len() < size + 2 {
            return Err(malformed("a chunk is cut short"));
        }
        body.extend_from_slice(&rest[..size]);
        rest = &rest[size + 2..];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_urls_parse_host_port_and_prefix() {
        let u = BaseUrl::parse("http://127.0.0.1:8480").unwrap();
        assert_eq!(u, BaseUrl { host: "127.0.0.1".into(), port: 8480, prefix: String::new() });
        let u = BaseUrl::parse("http://airspace.sim.svc/api/").unwrap();
        assert_eq!((u.port, u.prefix.as_str()), (80, "/api"));
        for bad in ["https://x:1", "127.0.0.1:8480", "http://:80", "http://h:99999"] {
            assert!(matches!(BaseUrl::parse(bad), Err(HttpError::Url { .. })), "{bad}");
        }
    }

    #[test]
    fn requests_carry_the_token_and_the_body_length() {
        let base = BaseUrl::parse("http://127.0.0.1:8480").unwrap();
        let r = build_request(&base, "POST", "/zones/museum-tfr/requests", Some("tok"), Some("{\"a\":1}"));
        assert!(r.starts_with("POST /zones/museum-tfr/requests HTTP/1.1\r\nHost: 127.0.0.1:8480\r\n"), "{r}");
        assert!(r.contains("Authorization: Bearer tok\r\n"));
        assert!(r.contains("Content-Type: application/json\r\nContent-Length: 7\r\n\r\n{\"a\":1}"), "{r}");
        let g = build_request(&base, "GET", "/zones", None, None);
        assert!(!g.contains("Authorization") && !g.contains("Content-Length"), "{g}");
        let d = build_request(&base, "DELETE", "/leases/lease-1", Some("t"), None);
        assert!(d.contains("Content-Length: 0\r\n\r\n"), "{d}");
    }

    #[test]
    fn a_content_length_body_is_cut_at_its_length() {
        let raw = b"HTTP/1.1 200 OK\r\ncontent-type: application/json\r\nContent-Length: 2\r\n\r\n{}garbage";
        let r = parse_response(raw).unwrap();
        assert_eq!(r.status, 200);
        assert_eq!(r.header("Content-Type"), Some("application/json"));
        assert_eq!(r.body, b"{}");
    }

    #[test]
    fn chunked_bodies_are_reassembled() {
        let raw = b"HTTP/1.1 404 Not Found\r\nTransfer-Encoding: chunked\r\n\r\n4\r\n{\"er\r\n9;ext\r\nror\":\"x\"}\r\n0\r\n\r\n";
        let r = parse_response(raw).unwrap();
        assert_eq!(r.status, 404);
        assert_eq!(r.text(), "{\"error\":\"x\"}");
    }

    #[test]
    fn a_body_without_length_runs_to_the_end() {
        let r = parse_response(b"HTTP/1.0 400 Bad Request\r\n\r\nmissing token").unwrap();
        assert_eq!((r.status, r.text().as_str()), (400, "missing token"));
    }

    #[test]
    fn broken_responses_are_errors_not_panics() {
        for raw in [
            &b"HTTP/1.1 200 OK\r\nContent-Length: 10\r\n\r\n{}"[..],
            b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n",
            b"SSH-2.0-OpenSSH\r\n\r\n",
            b"HTTP/1.1 abc OK\r\n\r\n",
            b"HTTP/1.1 200 OK\r\nno colon here\r\n\r\n",
            b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n",
            b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n10\r\nshort\r\n",
            b"",
        ] {
            assert!(matches!(parse_response(raw), Err(HttpError::Malformed(_))), "{:?}", String::from_utf8_lossy(raw));
        }
    }

    #[test]
    fn a_closed_port_is_a_connect_error() {
        // Bind then drop: the port is very likely closed for the next moment.
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let base = BaseUrl { host: "127.0.0.1".into(), port, prefix: String::new() };
        let e = request(&base, "GET", "/zones", None, None, Duration::from_secs(1)).unwrap_err();
        assert!(matches!(e, HttpError::Connect { .. }), "{e}");
        assert!(e.to_string().contains(&format!("127.0.0.1:{port}")), "{e}");
    }

    #[test]
    fn a_request_round_trips_through_a_real_socket() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut buf = [0u8; 1024];
            let n = s.read(&mut buf).unwrap();
            let got = String::from_utf8_lossy(&buf[..n]).into_owned();
            s.write_all(b"HTTP/1.1 200 OK\r\nContent-Length: 11\r\n\r\n{\"ok\":true}").unwrap();
            got
        });
        let base = BaseUrl { host: "127.0.0.1".into(), port, prefix: String::new() };
        let r = request(&base, "DELETE", "/leases/lease-3", Some("t0k"), None, Duration::from_secs(5)).unwrap();
        assert_eq!((r.status, r.text().as_str()), (200, "{\"ok\":true}"));
        let sent = server.join().unwrap();
        assert!(sent.starts_with("DELETE /leases/lease-3 HTTP/1.1\r\n") && sent.contains("Bearer t0k"), "{sent}");
    }
}
