//! A small blocking HTTP/1.1 client for the airspace API: what the service's tests and the
//! load generator (`sadesim bench --airspace`, `cli/src/bench/airspace_load.rs`) talk to
//! the service with. Keep-alive, `Content-Length` bodies only (axum's answers have one).

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use serde_json::Value;

/// How long the client waits to connect, send or receive before giving up.
const IO_TIMEOUT: Duration = Duration::from_secs(10);
/// Largest response head (status line and headers) the client reads, bytes.
const MAX_HEAD_BYTES: usize = 64 * 1024;
/// Largest response body the client reads, bytes.
const MAX_BODY_BYTES: usize = 64 * 1024 * 1024;

/// One HTTP response.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HttpResponse {
    pub status: u16,
    /// Header names in lowercase, in the order received.
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl HttpResponse {
    /// The first header called `name` (any case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    /// The body as JSON.
    ///
    /// # Errors
    /// The body is not JSON.
    pub fn json(&self) -> Result<Value, serde_json::Error> {
        serde_json::from_slice(&self.body)
    }

    /// The body as text (invalid UTF-8 replaced), for messages.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// A blocking HTTP/1.1 client on one keep-alive TCP connection: requests carry a
/// `Content-Length`, responses must too (axum's JSON answers do). The connection is
/// re-opened for the next request after the server closed it (`Connection: close`) or
/// after an I/O error.
#[derive(Debug)]
pub struct HttpClient {
    addr: SocketAddr,
    conn: Option<BufReader<TcpStream>>,
}

impl HttpClient {
    /// Connects now (so that connecting is not part of the first request's time).
    ///
    /// # Errors
    /// The connection cannot be made.
    pub fn connect(addr: SocketAddr) -> io::Result<Self> {
        let mut client = Self { addr, conn: None };
        client.connection()?;
        Ok(client)
    }

    fn connection(&mut self) -> io::Result<&mut BufReader<TcpStream>> {
        if self.conn.is_none() {
            let stream = TcpStream::connect_timeout(&self.addr, IO_TIMEOUT)?;
            stream.set_nodelay(true)?;
            stream.set_read_timeout(Some(IO_TIMEOUT))?;
            stream.set_write_timeout(Some(IO_TIMEOUT))?;
            self.conn = Some(BufReader::new(stream));
        }
        Ok(self.conn.as_mut().expect("connected just above"))
    }

    /// `GET path`.
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn get(&mut self, path: &str) -> io::Result<HttpResponse> {
        self.request("GET", path, &[], b"")
    }

    /// `POST path` with a JSON body and, when given, `Authorization: Bearer <token>`.
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn post_json(&mut self, path: &str, token: Option<&str>, body: &str) -> io::Result<HttpResponse> {
        let auth = token.map(|t| format!("Bearer {t}"));
        let mut headers = vec![("Content-Type", "application/json")];
        headers.extend(auth.as_deref().map(|a| ("Authorization", a)));
        self.request("POST", path, &headers, body.as_bytes())
    }

    /// A request with a bearer token and no body (`POST /leases/{id}/renew`, `DELETE`).
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn with_token(&mut self, method: &str, path: &str, token: &str) -> io::Result<HttpResponse> {
        let auth = format!("Bearer {token}");
        self.request(method, path, &[("Authorization", &auth)], b"")
    }

    /// Any request; `Host` and `Content-Length` are added.
    ///
    /// # Errors
    /// As [`HttpClient::send_raw`].
    pub fn request(
        &mut self,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &[u8],
    ) -> io::Result<HttpResponse> {
        let mut head = format!("{method} {path} HTTP/1.1\r\nHost: {}\r\nContent-Length: {}\r\n", self.addr, body.len());
        for (name, value) in headers {
            head.push_str(&format!("{name}: {value}\r\n"));
        }
        head.push_str("\r\n");
        let mut bytes = head.into_bytes();
        bytes.extend_from_slice(body);
        self.send_raw(&bytes)
    }

    /// Sends `request` as it is (for malformed requests in tests) and reads one response.
    /// When writing fails (a server may answer and close before reading a huge body), the
    /// response is still read if there is one.
    ///
    /// # Errors
    /// Connection, timeout, or a response that is not HTTP/1.1 with a `Content-Length`.
    pub fn send_raw(&mut self, request: &[u8]) -> io::Result<HttpResponse> {
        let result = self.exchange(request);
        if result.as_ref().map_or(true, |r| r.header("connection").is_some_and(|c| c.eq_ignore_ascii_case("close"))) {
            self.conn = None;
        }
        result
    }

    fn exchange(&mut self, request: &[u8]) -> io::Result<HttpResponse> {
        let conn = self.connection()?;
        let written = conn.get_mut().write_all(request).and_then(|()| conn.get_mut().flush());
        match read_response(conn) {
            Ok(response) => Ok(response),
            Err(read_error) => Err(written.err().unwrap_or(read_error)),
        }
    }
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// Reads a status line, headers and a `Content-Length` body.
fn read_response(conn: &mut BufReader<TcpStream>) -> io::Result<HttpResponse> {
    let mut head_bytes = 0;
    let mut line = String::new();
    let mut read_line = |line: &mut String| -> io::Result<()> {
        line.clear();
        let n = conn.by_ref().take((MAX_HEAD_BYTES - head_bytes) as u64).read_line(line)?;
        head_bytes += n;
        if n == 0 {
            return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "the server closed the connection"));
        }
        if !line.ends_with('\n') {
            return Err(invalid(format!("response head longer than {MAX_HEAD_BYTES} bytes")));
        }
        Ok(())
    };
    read_line(&mut line)?;
    let status = line
        .strip_prefix("HTTP/1.1 ")
        .or_else(|| line.strip_prefix("HTTP/1.0 "))
        .and_then(|rest| rest.get(..3))
        .and_then(|code| code.parse::<u16>().ok())
        .ok_or_else(|| invalid(format!("not an HTTP/1.1 status line: {:?}", line.trim_end())))?;
    let mut headers = Vec::new();
    loop {
        read_line(&mut line)?;
        let text = line.trim_end_matches(['\r', '\n']);
        if text.is_empty() {
            break;
        }
        let (name, value) = text.split_once(':').ok_or_else(|| invalid(format!("malformed header line {text:?}")))?;
        headers.push((name.trim().to_ascii_lowercase(), value.trim().to_string()));
    }
    let mut response = HttpResponse { status, headers, body: Vec::new() };
    let length = match response.header("content-length") {
        Some(v) => v.parse::<usize>().map_err(|_| invalid(format!("bad Content-Length {v:?}")))?,
        None if status == 204 || status == 304 || status < 200 => 0,
        None => return Err(invalid(format!("response {status} without Content-Length (chunked is not supported)"))),
    };
    if length > MAX_BODY_BYTES {
        return Err(invalid(format!("response body of {length} bytes is over the client's limit")));
    }
    response.body = vec![0; length];
    conn.read_exact(&mut response.body)?;
    Ok(response)
}
