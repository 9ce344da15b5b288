//! The sockets of one drone's MAVLink endpoint: thin, non-blocking, serviced by the shard at
//! its MAVLink exchanges (so I/O never runs concurrently with the drone it feeds).
//!
//! Addressing follows PX4 SITL so SDK defaults work unchanged:
//! - the *API link*: telemetry is sent to `api_target` (127.0.0.1:14540+i locally), where
//!   `udpin://0.0.0.0:14540` clients (MAVSDK, pymavlink `udpin:`) listen; their replies come
//!   back to our port;
//! - *connecting clients*: anyone who sends a datagram to our UDP port (`udpout://host:port`,
//!   the form that works across pods) becomes a peer and receives telemetry from then on;
//! - *TCP*: clients connecting to the same port number over TCP (`tcpout://host:port`).
//!
//! Several frames are packed into one datagram, as PX4 does, which keeps the syscall count
//! per drone at one per peer and exchange. A shard's drones share their datagrams to a
//! MAVLink router of the run ([`Endpoint::flush_gathering`], `mavlink::uplink`), which
//! brings the router's share to one per shared datagram. Telemetry is lossy by nature: a TCP peer that
//! cannot keep up loses frames rather than stalling the simulation.
//!
//! # What it costs, and how that is kept small (docs/performance.md, MAVLink)
//! - **Readiness**: a shard registers all its endpoints with one [`EndpointPoll`]; one
//!   zero-timeout wait per exchange tells which sockets have something, and only those are
//!   read (a `recvfrom` on each of 250 idle sockets every 20 ms was a tenth of the cost).
//!   An endpoint never registered (unit tests, tools) reads every socket at every call.
//! - **The API link backs off while nobody listens** (a departure from PX4, which sends
//!   blindly; docs/architecture.md, MAVLink). It has its own socket, connected to the
//!   target and bound to the endpoint's port (`SO_REUSEPORT`, so clients still see one
//!   address), which lets the kernel's ICMP "port unreachable" come back as
//!   `ECONNREFUSED`. After that only the 1 Hz HEARTBEAT is sent there; the full stream
//!   resumes after a heartbeat that is not refused (at the next exchange, 20 ms later) or
//!   as soon as anything arrives from the target. A client that starts listening on
//!   14540 sees a heartbeat within a second and the full stream 20 ms after it.
//! - Datagram buffers are reused from one exchange to the next.

use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, SocketAddr};

use ::mavlink::MavHeader;
use ::mavlink::Message;
use ::mavlink::dialects::common::MavMessage;
use mio::net::{TcpListener, TcpStream, UdpSocket};
use mio::{Events, Interest, Poll, Token};

use crate::mavlink::router::{ROUTER_COMPONENT_ID, ROUTER_SYSTEM_ID};
use crate::mavlink::uplink::Uplink;
use sadesim_engine::mavlink::frame::{Frame, FrameParser, MAX_FRAME_LEN, encode_command_ack, encode_into};
use sadesim_engine::mavlink::session::{COMPONENT_ID, Outgoing};

/// Datagrams are filled up to this many bytes (below the 1500-byte Ethernet MTU with IP
/// and UDP headers, so nothing fragments on a real network).
pub const MAX_DATAGRAM: usize = 1400;
/// Queued datagrams kept between flushes (a second of a busy drone's telemetry).
const MAX_PENDING_DATAGRAMS: usize = 64;
/// UDP peers remembered; the least recently heard is dropped for a new one.
pub const MAX_UDP_PEERS: usize = 8;
/// TCP connections accepted at once; more are closed at once.
pub const MAX_TCP_PEERS: usize = 8;
/// A peer that sent HEARTBEATs and then fell silent this long is forgotten (MAVLink's
/// heartbeat protocol: a component is lost after a few missed heartbeats). Peers that never
/// sent a heartbeat (a bare pymavlink `udpout` script) are kept until evicted.
pub const PEER_HEARTBEAT_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);
/// Without readiness events (an endpoint not registered with an [`EndpointPoll`]), the TCP
/// listener is checked every this many polls (connections wait at most that long).
const ACCEPT_EVERY_POLLS: u64 = 5;
/// Datagrams read per socket and poll: a flood cannot keep the shard from simulating (the
/// kernel drops what does not fit its buffer).
const MAX_DATAGRAMS_PER_POLL: usize = 256;
/// Bytes read per TCP peer per poll, for the same reason.
const MAX_TCP_BYTES_PER_POLL: usize = 64 * 1024;
/// Message id of HEARTBEAT, the only message the API link carries while nobody listens.
const HEARTBEAT_ID: u32 = 0;

/// Where one drone's endpoint listens and sends.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EndpointConfig {
    pub system_id: u8,
    /// Address to bind UDP and TCP on (127.0.0.1 locally, 0.0.0.0 in a pod).
    pub bind_ip: IpAddr,
    /// UDP and TCP port (the plan's `ports.endpoint`).
    pub port: u16,
    /// The API link target (PX4 SITL's 14540+i), if any.
    pub api_target: Option<SocketAddr>,
    /// Silence after which a heartbeating UDP peer is forgotten ([`PEER_HEARTBEAT_TIMEOUT`]).
    pub peer_timeout: std::time::Duration,
}

/// Why an endpoint could not open.
#[derive(Debug, thiserror::Error)]
#[error("MAVLink endpoint of system {system_id} on {address}: {source}{hint}")]
pub struct EndpointError {
    pub system_id: u8,
    pub address: SocketAddr,
    pub source: std::io::Error,
    hint: &'static str,
}

#[derive(Debug)]
struct UdpPeer {
    address: SocketAddr,
    /// Poll counter when last heard from.
    heard: u64,
    /// Wall time of the last HEARTBEAT from this peer (liveness is a wall-clock matter).
    heartbeat_at: Option<std::time::Instant>,
    /// A MAVLink router of the run (its HEARTBEAT came from the routers' system and
    /// component ids): the shard may gather its telemetry with other drones' ([`Uplink`]).
    router: bool,
}

#[derive(Debug)]
struct TcpPeer {
    stream: TcpStream,
    parser: FrameParser,
    closed: bool,
}

/// The API link's own socket and what we believe about its target.
#[derive(Debug)]
struct ApiLink {
    /// Bound to the endpoint's address (shared with [`Endpoint::udp`] through
    /// `SO_REUSEPORT`) and connected to the target: the kernel hands it the target's
    /// datagrams and reports ICMP port-unreachable for it as `ECONNREFUSED`.
    socket: UdpSocket,
    /// Someone is believed to listen: send everything. Otherwise heartbeats only.
    listening: bool,
    /// A heartbeat went out while not listening; the next flush checks whether it was
    /// refused.
    probe_sent: bool,
    /// The HEARTBEAT frame queued since the last flush (the probe while not listening).
    heartbeat: Vec<u8>,
}

/// Counters for logs and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EndpointStats {
    pub datagrams_in: u64,
    pub datagrams_out: u64,
    pub frames_in: u64,
    pub bad_checksum: u64,
    pub tcp_accepted: u64,
    pub tcp_refused: u64,
    pub send_errors: u64,
    /// Queued datagrams dropped because nothing flushed them.
    pub dropped_datagrams: u64,
    /// Times the API link found nobody listening and fell back to heartbeats.
    pub api_refused: u64,
}

/// Which socket of an endpoint a readiness event is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SocketKind {
    /// The endpoint's UDP port (connecting clients, the router).
    Udp,
    /// The TCP listener.
    TcpListener,
    /// The API link's socket.
    Api,
}

impl SocketKind {
    const ALL: [SocketKind; 3] = [SocketKind::Udp, SocketKind::TcpListener, SocketKind::Api];

    fn token(self, index: usize) -> Token {
        Token(index * Self::ALL.len() + self as usize)
    }

    fn from_token(token: Token) -> (usize, SocketKind) {
        let n = Self::ALL.len();
        (token.0 / n, Self::ALL[token.0 % n])
    }
}

/// One readiness wait for many endpoints (a shard's): endpoints are registered under an
/// index (the drone's position in the shard), and [`EndpointPoll::dispatch`] names the
/// sockets that became readable since the last call, without waiting.
///
/// Readiness is edge-triggered: an endpoint keeps a socket marked until a read finds it
/// empty, so a socket left with data (the per-poll read limit) is read again next time.
#[derive(Debug)]
pub struct EndpointPoll {
    poll: Poll,
    events: Events,
    /// One more than the largest registered index.
    endpoints: usize,
}

/// Readiness events fetched per wait; more are fetched by further waits in the same call.
const EVENTS_PER_WAIT: usize = 1024;

impl EndpointPoll {
    /// # Errors
    /// When the OS refuses a readiness queue (epoll instance).
    pub fn new() -> std::io::Result<Self> {
        Ok(Self { poll: Poll::new()?, events: Events::with_capacity(EVENTS_PER_WAIT), endpoints: 0 })
    }

    /// Registers the sockets of `endpoint` under `index`; from now on it reads a socket
    /// only when [`Endpoint::mark_ready`] said so.
    ///
    /// # Errors
    /// When a socket cannot be registered (the endpoint then stays unregistered and keeps
    /// reading every socket).
    pub fn register(&mut self, endpoint: &mut Endpoint, index: usize) -> std::io::Result<()> {
        let registry = self.poll.registry();
        registry.register(&mut endpoint.udp, SocketKind::Udp.token(index), Interest::READABLE)?;
        registry.register(&mut endpoint.tcp, SocketKind::TcpListener.token(index), Interest::READABLE)?;
        if let Some(api) = &mut endpoint.api {
            registry.register(&mut api.socket, SocketKind::Api.token(index), Interest::READABLE)?;
        }
        endpoint.registered = true;
        // Whatever arrived before registration: read everything once.
        endpoint.ready = [true; 3];
        self.endpoints = self.endpoints.max(index + 1);
        Ok(())
    }

    /// Calls `mark(index, socket)` for every socket that became readable (or got an error)
    /// since the last call; never waits. If the wait itself fails, every registered socket
    /// is marked, so nothing is missed.
    pub fn dispatch(&mut self, mut mark: impl FnMut(usize, SocketKind)) {
        // A full batch may mean more are pending: bounded, since each wait drains events.
        for _ in 0..=(self.endpoints * SocketKind::ALL.len()) / EVENTS_PER_WAIT {
            if self.poll.poll(&mut self.events, Some(std::time::Duration::ZERO)).is_err() {
                for index in 0..self.endpoints {
                    for kind in SocketKind::ALL {
                        mark(index, kind);
                    }
                }
                return;
            }
            let mut n = 0;
            for event in &self.events {
                let (index, kind) = SocketKind::from_token(event.token());
                mark(index, kind);
                n += 1;
            }
            if n < EVENTS_PER_WAIT {
                return;
            }
        }
    }
}

/// How many ports [`Endpoint::open`] tries when asked for any port (port 0).
const ANY_PORT_ATTEMPTS: u32 = 16;

/// One drone's sockets.
#[derive(Debug)]
pub struct Endpoint {
    config: EndpointConfig,
    udp: UdpSocket,
    tcp: TcpListener,
    api: Option<ApiLink>,
    udp_peers: Vec<UdpPeer>,
    tcp_peers: Vec<TcpPeer>,
    parser: FrameParser,
    sequence: u8,
    polls: u64,
    /// Registered with an [`EndpointPoll`]: sockets are read only when marked ready.
    registered: bool,
    /// Per [`SocketKind`]: readable (or not read to the end yet) since the last poll.
    ready: [bool; 3],
    /// Datagram buffers; the first `filled` hold frames waiting for the next flush, the
    /// rest are empty and kept for reuse.
    datagrams: Vec<Vec<u8>>,
    filled: usize,
    pub stats: EndpointStats,
}

impl Endpoint {
    /// Binds UDP and TCP on `config.bind_ip:config.port`, and the API link's socket.
    ///
    /// Port 0 asks for any free port: the kernel picks a free UDP port, and the same number
    /// may be taken over TCP (by another program's connection); then another pick is
    /// tried, up to [`ANY_PORT_ATTEMPTS`] times.
    ///
    /// # Errors
    /// When a socket cannot be bound (the message names the system and address).
    pub fn open(config: EndpointConfig) -> Result<Self, EndpointError> {
        let mut attempt = 1;
        loop {
            match Self::open_once(config.clone()) {
                Err(e)
                    if config.port == 0 && e.source.kind() == ErrorKind::AddrInUse && attempt < ANY_PORT_ATTEMPTS =>
                {
                    attempt += 1;
                }
                result => return result,
            }
        }
    }

    fn open_once(config: EndpointConfig) -> Result<Self, EndpointError> {
        let mut address = SocketAddr::new(config.bind_ip, config.port);
        let err = |address: SocketAddr| {
            move |source: std::io::Error| {
                let hint = if source.kind() == ErrorKind::AddrInUse {
                    " (is another run or PX4 SITL using this port? `sadesim run --no-mavlink` runs without endpoints)"
                } else {
                    ""
                };
                EndpointError { system_id: config.system_id, address, source, hint }
            }
        };
        // A plain bind first: it fails when anyone holds the port (also a group of
        // SO_REUSEPORT sockets, such as another run's endpoint), and picks the port when 0
        // was asked for.
        let plain = std::net::UdpSocket::bind(address).map_err(err(address))?;
        address = plain.local_addr().map_err(err(address))?;
        let (udp, api) = match config.api_target {
            None => (plain, None),
            Some(target) => {
                drop(plain);
                let udp = reuse_port_socket(address).map_err(err(address))?;
                let api = reuse_port_socket(address).map_err(err(address))?;
                api.connect(target).map_err(err(address))?;
                (udp, Some(api))
            }
        };
        udp.set_nonblocking(true).map_err(err(address))?;
        // Same number over TCP.
        let tcp = std::net::TcpListener::bind(address).map_err(err(address))?;
        tcp.set_nonblocking(true).map_err(err(address))?;
        let api = match api {
            Some(socket) => {
                socket.set_nonblocking(true).map_err(err(address))?;
                Some(ApiLink {
                    socket: UdpSocket::from_std(socket),
                    // As PX4: stream from the start; the first refusal quiets the link.
                    listening: true,
                    probe_sent: false,
                    heartbeat: Vec::new(),
                })
            }
            None => None,
        };
        Ok(Self {
            config,
            udp: UdpSocket::from_std(udp),
            tcp: TcpListener::from_std(tcp),
            api,
            udp_peers: Vec::new(),
            tcp_peers: Vec::new(),
            parser: FrameParser::new(),
            sequence: 0,
            polls: 0,
            registered: false,
            ready: [true; 3],
            datagrams: Vec::new(),
            filled: 0,
            stats: EndpointStats::default(),
        })
    }

    /// The bound UDP address (the port is known once bound, also when 0 was asked for).
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.udp.local_addr()
    }

    /// The API link currently carries the full telemetry (someone is believed to listen).
    pub fn api_link_live(&self) -> bool {
        self.api.as_ref().is_some_and(|a| a.listening)
    }

    /// [`EndpointPoll::dispatch`] found `socket` readable.
    pub fn mark_ready(&mut self, socket: SocketKind) {
        self.ready[socket as usize] = true;
    }

    fn should_read(&self, socket: SocketKind) -> bool {
        !self.registered || self.ready[socket as usize]
    }

    /// Everything that arrived since the last call, as checksummed frames.
    pub fn receive(&mut self) -> Vec<Frame> {
        self.polls += 1;
        let mut frames = Vec::new();
        let mut buf = [0u8; 2048];
        if self.should_read(SocketKind::Udp) {
            self.receive_udp(&mut frames, &mut buf);
        }
        if self.api.is_some() && self.should_read(SocketKind::Api) {
            self.receive_api(&mut frames, &mut buf);
        }
        if !self.udp_peers.is_empty() {
            let now = std::time::Instant::now();
            self.udp_peers.retain(|p| p.heartbeat_at.is_none_or(|t| now.duration_since(t) < self.config.peer_timeout));
        }
        let accept = if self.registered {
            self.ready[SocketKind::TcpListener as usize]
        } else {
            self.polls % ACCEPT_EVERY_POLLS == 1
        };
        if accept {
            self.accept_tcp();
        }
        for peer in &mut self.tcp_peers {
            let mut read = 0;
            while read < MAX_TCP_BYTES_PER_POLL {
                match peer.stream.read(&mut buf) {
                    Ok(0) => {
                        peer.closed = true;
                        break;
                    }
                    Ok(n) => {
                        read += n;
                        frames.extend(peer.parser.push(&buf[..n]));
                    }
                    Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                    Err(_) => {
                        peer.closed = true;
                        break;
                    }
                }
            }
        }
        self.tcp_peers.retain(|p| !p.closed);
        self.stats.frames_in += frames.len() as u64;
        self.stats.bad_checksum =
            self.parser.stats.bad_checksum + self.tcp_peers.iter().map(|p| p.parser.stats.bad_checksum).sum::<u64>();
        frames
    }

    fn receive_udp(&mut self, frames: &mut Vec<Frame>, buf: &mut [u8]) {
        for _ in 0..MAX_DATAGRAMS_PER_POLL {
            match self.udp.recv_from(buf) {
                Ok((n, from)) => {
                    self.stats.datagrams_in += 1;
                    // Each datagram stands alone: a frame never spans two.
                    self.parser.reset();
                    let got = self.parser.push(&buf[..n]);
                    let heartbeat = got.iter().any(|f| f.message_id == HEARTBEAT_ID);
                    let router = got.iter().any(|f| {
                        f.message_id == HEARTBEAT_ID
                            && f.header.system_id == u32::from(ROUTER_SYSTEM_ID)
                            && f.header.component_id == ROUTER_COMPONENT_ID
                    });
                    self.remember(from, heartbeat, router);
                    frames.extend(got);
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    self.ready[SocketKind::Udp as usize] = false;
                    return;
                }
                // ICMP errors from an earlier send surface here on some systems; they
                // concern that send, not this socket.
                Err(_) => {}
            }
        }
    }

    /// Datagrams from the API link's target (its replies: commands, its heartbeats).
    fn receive_api(&mut self, frames: &mut Vec<Frame>, buf: &mut [u8]) {
        let Some(api) = &mut self.api else { return };
        for _ in 0..MAX_DATAGRAMS_PER_POLL {
            match api.socket.recv(buf) {
                Ok(n) => {
                    // Someone is there: the full stream again.
                    api.listening = true;
                    self.stats.datagrams_in += 1;
                    self.parser.reset();
                    frames.extend(self.parser.push(&buf[..n]));
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    self.ready[SocketKind::Api as usize] = false;
                    return;
                }
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {
                    // An earlier datagram found nobody (reading the error clears it).
                    if api.listening {
                        self.stats.api_refused += 1;
                    }
                    api.listening = false;
                    api.probe_sent = false;
                }
                Err(_) => {}
            }
        }
    }

    fn remember(&mut self, from: SocketAddr, heartbeat: bool, router: bool) {
        if Some(from) == self.config.api_target {
            return; // the API link already receives everything
        }
        let heartbeat_at = heartbeat.then(std::time::Instant::now);
        if let Some(p) = self.udp_peers.iter_mut().find(|p| p.address == from) {
            p.heard = self.polls;
            p.heartbeat_at = heartbeat_at.or(p.heartbeat_at);
            p.router |= router;
            return;
        }
        if self.udp_peers.len() >= MAX_UDP_PEERS
            && let Some(oldest) = self.udp_peers.iter().enumerate().min_by_key(|(_, p)| p.heard).map(|(i, _)| i)
        {
            self.udp_peers.swap_remove(oldest);
        }
        self.udp_peers.push(UdpPeer { address: from, heard: self.polls, heartbeat_at, router });
    }

    fn accept_tcp(&mut self) {
        loop {
            match self.tcp.accept() {
                Ok((stream, _)) => {
                    if self.tcp_peers.len() >= MAX_TCP_PEERS {
                        self.stats.tcp_refused += 1;
                        continue; // dropped: closes the connection
                    }
                    let _ = stream.set_nodelay(true);
                    self.stats.tcp_accepted += 1;
                    self.tcp_peers.push(TcpPeer { stream, parser: FrameParser::new(), closed: false });
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    self.ready[SocketKind::TcpListener as usize] = false;
                    return;
                }
                // A connection reset before we took it: try the next one. Anything else
                // (out of descriptors) waits for the next poll.
                Err(e) if e.kind() == ErrorKind::ConnectionAborted => {}
                Err(_) => return,
            }
        }
    }

    /// Encodes `messages` with this link's sequence numbers into the outgoing datagrams,
    /// sent at the next [`Endpoint::flush`]. Messages are built when due (their rates and
    /// timestamps stay right); only the sending is batched.
    ///
    /// Deferred telemetry ([`Outgoing::Telemetry`]) is built here, one message at a time.
    pub fn queue(&mut self, messages: &[Outgoing]) {
        for m in messages {
            match m {
                Outgoing::Message(message) => self.queue_message(message),
                Outgoing::Telemetry(due) => due.messages().for_each(|message| self.queue_message(&message)),
                Outgoing::UnknownCommandAck { command, result, target } => {
                    let (header, datagram) = self.next_frame();
                    datagram.extend(encode_command_ack(header, *command, *result, *target));
                }
            }
        }
    }

    /// Encodes one message; a HEARTBEAT is also kept for the API link (module docs).
    fn queue_message(&mut self, message: &MavMessage) {
        let (header, datagram) = self.next_frame();
        let at = datagram.len();
        encode_into(datagram, header, message);
        if message.message_id() == HEARTBEAT_ID
            && let Some(api) = &mut self.api
        {
            api.heartbeat.clear();
            api.heartbeat.extend_from_slice(&self.datagrams[self.filled - 1][at..]);
        }
    }

    /// The next frame's header (taking this link's next sequence number) and the datagram
    /// it goes in: a new one when a frame of the largest size might not fit the last.
    fn next_frame(&mut self) -> (MavHeader, &mut Vec<u8>) {
        let header = MavHeader {
            system_id: u32::from(self.config.system_id),
            component_id: COMPONENT_ID,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let fits = self.filled > 0 && self.datagrams[self.filled - 1].len() + MAX_FRAME_LEN <= MAX_DATAGRAM;
        if !fits {
            self.start_datagram();
        }
        (header, &mut self.datagrams[self.filled - 1])
    }

    /// Makes an empty datagram the last filled one, reusing a buffer when there is one.
    fn start_datagram(&mut self) {
        if self.filled == MAX_PENDING_DATAGRAMS {
            // Nobody flushed for long: the oldest goes first (its buffer is reused).
            self.datagrams[..self.filled].rotate_left(1);
            self.filled -= 1;
            self.stats.dropped_datagrams += 1;
        }
        if self.filled == self.datagrams.len() {
            self.datagrams.push(Vec::with_capacity(MAX_DATAGRAM));
        }
        self.datagrams[self.filled].clear();
        self.filled += 1;
    }

    /// Sends the queued datagrams to every peer (the API link: see the module docs).
    pub fn flush(&mut self) {
        self.flush_to(None);
    }

    /// [`Endpoint::flush`], except that what goes to a router peer is added to `uplink`
    /// (this endpoint is the shard's `index`-th), which the shard sends after every
    /// endpoint has flushed.
    pub fn flush_gathering(&mut self, index: usize, uplink: &mut Uplink) {
        self.flush_to(Some((index, uplink)));
    }

    fn flush_to(&mut self, mut uplink: Option<(usize, &mut Uplink)>) {
        let datagrams = &self.datagrams[..self.filled];
        if let Some(api) = &mut self.api {
            send_api(api, datagrams, &mut self.stats);
        }
        for peer in &self.udp_peers {
            for d in datagrams {
                if let (true, Some((index, uplink))) = (peer.router, uplink.as_mut()) {
                    uplink.add(peer.address, *index, d);
                    continue;
                }
                send_udp(&self.udp, &mut self.stats, d, peer.address);
            }
        }
        self.tcp_peers.retain_mut(|peer| {
            for d in datagrams {
                match peer.stream.write(d) {
                    Ok(n) if n == d.len() => {}
                    // A slow reader: drop the rest of this round's telemetry for it. A
                    // partial write would leave half a frame, which the peer's parser skips.
                    Ok(_) => return true,
                    Err(e) if e.kind() == ErrorKind::WouldBlock => return true,
                    Err(_) => return false,
                }
            }
            true
        });
        for d in &mut self.datagrams[..self.filled] {
            d.clear();
        }
        self.filled = 0;
    }

    /// Sends `datagram` (whole frames) to `to` from this endpoint's UDP port: an
    /// [`Uplink`]'s shared datagram for a router.
    pub fn send_datagram(&mut self, datagram: &[u8], to: SocketAddr) {
        send_udp(&self.udp, &mut self.stats, datagram, to);
    }

    /// [`Endpoint::queue`] then [`Endpoint::flush`].
    pub fn send(&mut self, messages: &[Outgoing]) {
        self.queue(messages);
        self.flush();
    }
}

/// One datagram from the endpoint's UDP port to `to`, counted in `stats`.
fn send_udp(udp: &UdpSocket, stats: &mut EndpointStats, datagram: &[u8], to: SocketAddr) {
    match udp.send_to(datagram, to) {
        Ok(_) => stats.datagrams_out += 1,
        Err(_) => stats.send_errors += 1,
    }
}

/// A UDP socket with `SO_REUSEPORT` bound to `address`: the endpoint's port and its API
/// link share the port (the kernel gives the connected one its peer's datagrams).
fn reuse_port_socket(address: SocketAddr) -> std::io::Result<std::net::UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(Domain::for_address(address), Type::DGRAM, Some(Protocol::UDP))?;
    socket.set_reuse_port(true)?;
    socket.bind(&address.into())?;
    Ok(socket.into())
}

/// The API link's share of a flush: everything while someone listens, otherwise only the
/// heartbeat, whose fate decides at the next flush whether the link comes back.
fn send_api(api: &mut ApiLink, datagrams: &[Vec<u8>], stats: &mut EndpointStats) {
    if !api.listening && std::mem::take(&mut api.probe_sent) {
        // On loopback the ICMP answer to the last probe is back long before now; on a
        // real network a late one quiets the link again at the next send.
        if matches!(api.socket.take_error(), Ok(None)) {
            api.listening = true;
        }
    }
    if api.listening {
        for d in datagrams {
            match api.socket.send(d) {
                Ok(_) => stats.datagrams_out += 1,
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {
                    // An earlier datagram was refused (this one was not sent).
                    stats.api_refused += 1;
                    api.listening = false;
                    break;
                }
                Err(_) => stats.send_errors += 1,
            }
        }
    }
    if !api.listening && !api.heartbeat.is_empty() {
        match api.socket.send(&api.heartbeat) {
            Ok(_) => {
                stats.datagrams_out += 1;
                api.probe_sent = true;
            }
            // A refusal left over (consumed now): the next heartbeat probes again.
            Err(e) if e.kind() == ErrorKind::ConnectionRefused => {}
            Err(_) => stats.send_errors += 1,
        }
    }
    api.heartbeat.clear();
}

#[cfg(test)]
mod tests;
