//! The MAVLink router of one segment (DESIGN §3): one GCS-facing endpoint (UDP and TCP)
//! multiplexing every drone of the segment, like mavlink-router or MAVProxy but small.
//!
//! Why it exists: every simulated drone has its own endpoint port, but a ground station
//! (QGroundControl) connects to one address and tells vehicles apart by system id. The
//! planner gives the drones of a segment distinct system ids (1..=250), so one router per
//! segment can merge their streams without rewriting anything.
//!
//! # How it works
//! - **Drone side**: one UDP socket on an ephemeral port. A drone endpoint sends its
//!   telemetry to every peer that has sent it a datagram, so the router registers by
//!   sending its own HEARTBEAT to every endpoint once a second (which also re-registers
//!   after a drone's endpoint restarts). Datagrams from the endpoints go to every GCS client
//!   unchanged; only the router's own heartbeat (should a drone echo it) and bad frames are
//!   taken out.
//! - **GCS side**: UDP clients are whoever sent a valid frame to the GCS UDP port (the most
//!   recent [`MAX_UDP_GCS`], least recently heard evicted); TCP clients are connections on
//!   the GCS TCP port (at most [`MAX_TCP_GCS`]). Their frames go to the drone whose system id
//!   is the message's `target_system`, to every drone when the target is 0 or the message
//!   has none, and nowhere (counted) for a system id outside the segment. Each GCS also
//!   receives the other GCS clients' frames, so two ground stations see each other, as
//!   with mavlink-router.
//!
//! Frames are forwarded byte for byte, never re-encoded: sequence numbers, signatures and
//! extension fields survive, and a frame costs one checksum check and a copy.
//!
//! # Threads
//! Plain std threads with blocking sockets and short read timeouts ([`POLL`]), so
//! [`RouterHandle::stop`] returns within about 100 ms: one for the drone side, one for GCS
//! UDP, one accepting TCP, and per TCP client a reader and a writer. The writer drains a
//! bounded queue, so a stalled TCP client loses whole datagrams (counted) instead of
//! stalling telemetry for everyone else.
//!
//! # Caveats
//! - The router's heartbeat is `MAV_TYPE_ONBOARD_CONTROLLER`, not `MAV_TYPE_GCS`, so it
//!   cannot keep a drone's GCS-link-loss failsafe from triggering: only a real GCS's
//!   heartbeats (forwarded to every drone) count as a ground station.
//! - Within one GCS datagram, frames keep their order per drone; frames to different drones
//!   are sent as separate datagrams.

use std::borrow::Cow;
use std::collections::HashSet;
use std::io::{self, Read, Write};
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, Shutdown, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType};
use serde::Serialize;

use super::frame::{Decoded, Frame, FrameParser, encode, target_system};

/// The router's own system id: outside the drones' 1..=250 and below the 255 ground stations
/// use by default (254 is MAVProxy's and some companion computers'), so it clashes with
/// neither.
pub const ROUTER_SYSTEM_ID: u8 = 253;
/// MAV_COMP_ID_UDP_BRIDGE: what the router is.
pub const ROUTER_COMPONENT_ID: u8 = 240;
/// Drones per segment: the planner's limit, since system ids 1..=250 must be distinct.
pub const MAX_DRONES: usize = 250;
/// UDP ground stations served at once; the least recently heard is dropped for a new one.
pub const MAX_UDP_GCS: usize = 16;
/// TCP ground stations served at once; further connections are closed at once (counted).
pub const MAX_TCP_GCS: usize = 16;
/// Read timeout of every socket: how long a thread may take to notice [`RouterHandle::stop`].
pub const POLL: Duration = Duration::from_millis(25);
/// How often the router registers with the drone endpoints.
const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);
/// A TCP client that accepts no bytes for this long is disconnected (a write that timed out
/// may have sent half a frame, so the stream cannot continue anyway).
const TCP_WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// Datagrams queued per TCP client before new ones are dropped: about a second of a full
/// segment's telemetry.
const TCP_QUEUE: usize = 1024;
/// Largest UDP payload.
const MAX_DATAGRAM: usize = 65_536;

/// One drone of the segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RoutedDrone {
    /// MAVLink system id, 1..=250, unique in the segment.
    pub system_id: u8,
    /// The drone's MAVLink endpoint (UDP).
    pub endpoint: SocketAddr,
}

/// What one router serves.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RouterConfig {
    /// Segment index (for messages and logs).
    pub segment: u32,
    /// Where ground stations send UDP (port 0: any free port, see [`RouterHandle::gcs_udp`]).
    pub gcs_udp: SocketAddr,
    /// Where ground stations connect over TCP (port 0: any free port).
    pub gcs_tcp: SocketAddr,
    /// The segment's drones (at most [`MAX_DRONES`], distinct system ids).
    pub drones: Vec<RoutedDrone>,
}

/// Why a router could not start.
#[derive(Debug, thiserror::Error)]
pub enum RouterError {
    /// Another process holds the port: a second router, QGroundControl itself (it listens
    /// on UDP 14550) or a PX4 SITL instance.
    #[error(
        "failed to bind the {socket} socket {addr}: the address is already in use \
         (another router, QGroundControl or PX4 SITL listening there?)"
    )]
    AddressInUse { socket: &'static str, addr: SocketAddr },
    /// Any other bind failure (no such interface, permission for ports below 1024, ...).
    #[error("failed to bind the {socket} socket {addr}: {source}")]
    Bind { socket: &'static str, addr: SocketAddr, source: io::Error },
    /// Configuring a socket or starting a thread failed.
    #[error("failed to set up the router: {0}")]
    Io(#[from] io::Error),
    /// More drones than system ids.
    #[error("a router segment holds at most {MAX_DRONES} drones, got {0}")]
    TooManyDrones(usize),
    /// A system id the router cannot address (0 is broadcast, 251..=255 are for ground
    /// stations and the router).
    #[error("drone system id {0} is outside 1..={MAX_DRONES}")]
    InvalidSystemId(u8),
    /// Two drones with one system id: a GCS could not tell them apart.
    #[error("drone system id {0} appears twice in the segment")]
    DuplicateSystemId(u8),
    /// The drone side is one socket, which speaks one address family.
    #[error("drone endpoints mix IPv4 and IPv6 ({0} and {1}); use addresses of one family")]
    MixedAddressFamilies(SocketAddr, SocketAddr),
}

/// Counters since start, for logs and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct RouterStats {
    /// Frames delivered to drone endpoints (a broadcast to n drones counts n).
    pub frames_to_drones: u64,
    /// Datagrams (UDP) or queued chunks (TCP) sent to ground stations: drone telemetry and
    /// other ground stations' frames.
    pub datagrams_to_gcs: u64,
    /// GCS frames addressed to a system id that is not in the segment.
    pub dropped_unknown_target: u64,
    /// Datagrams on the drone socket from an address that is no drone endpoint.
    pub dropped_unknown_source: u64,
    /// Frames with a wrong checksum, from either side.
    pub bad_checksum: u64,
    /// Bytes that could not start a frame, from either side.
    pub garbage_bytes: u64,
    /// Chunks not queued for a TCP client that does not read fast enough.
    pub dropped_gcs_backlog: u64,
    /// TCP connections refused because [`MAX_TCP_GCS`] were open.
    pub refused_tcp_clients: u64,
    /// UDP ground stations currently served.
    pub gcs_udp_clients: usize,
    /// TCP ground stations currently connected.
    pub gcs_tcp_clients: usize,
}

/// A running router; dropping it stops it.
pub struct RouterHandle {
    /// `None` once stopped: dropping it closes the sockets, so the ports are free again.
    shared: Option<Arc<Shared>>,
    counters: Arc<Counters>,
    drones: usize,
    threads: Vec<JoinHandle<()>>,
    gcs_udp: SocketAddr,
    gcs_tcp: SocketAddr,
    drone_side: SocketAddr,
}

impl std::fmt::Debug for RouterHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RouterHandle")
            .field("gcs_udp", &self.gcs_udp)
            .field("gcs_tcp", &self.gcs_tcp)
            .field("drone_side", &self.drone_side)
            .field("drones", &self.drones)
            .field("running", &self.shared.is_some())
            .finish()
    }
}

/// Binds the GCS sockets and the drone-side socket and starts routing.
///
/// # Errors
/// A GCS address in use or not bindable, an invalid drone list (too many drones, system id
/// outside 1..=250 or repeated, mixed address families), or the OS refusing a socket option
/// or a thread.
pub fn start(config: RouterConfig) -> Result<RouterHandle, RouterError> {
    let drone_bind = check_drones(&config.drones)?;
    let gcs_udp = UdpSocket::bind(config.gcs_udp).map_err(|e| bind_error("GCS UDP", config.gcs_udp, e))?;
    let listener = TcpListener::bind(config.gcs_tcp).map_err(|e| bind_error("GCS TCP", config.gcs_tcp, e))?;
    let drone_socket = UdpSocket::bind(drone_bind).map_err(|e| bind_error("drone-side UDP", drone_bind, e))?;
    gcs_udp.set_read_timeout(Some(POLL))?;
    drone_socket.set_read_timeout(Some(POLL))?;
    // The accept loop polls: std offers no accept timeout.
    listener.set_nonblocking(true)?;

    let mut index_of = vec![None; 256];
    for (i, d) in config.drones.iter().enumerate() {
        index_of[usize::from(d.system_id)] = Some(i);
    }
    let shared = Arc::new(Shared {
        stop: AtomicBool::new(false),
        endpoints: config.drones.iter().map(|d| d.endpoint).collect(),
        drones: config.drones,
        index_of,
        drone_socket,
        gcs_udp,
        udp_peers: Mutex::new(PeerTable::default()),
        tcp_clients: Mutex::new(Vec::new()),
        tcp_threads: Mutex::new(Vec::new()),
        next_tcp_id: AtomicU64::new(0),
        counters: Arc::default(),
    });
    let mut handle = RouterHandle {
        gcs_udp: shared.gcs_udp.local_addr()?,
        gcs_tcp: listener.local_addr()?,
        drone_side: shared.drone_socket.local_addr()?,
        counters: shared.counters.clone(),
        drones: shared.drones.len(),
        shared: Some(shared.clone()),
        threads: Vec::new(),
    };
    // On an error below, dropping `handle` stops the threads already started.
    let segment = config.segment;
    let s = shared.clone();
    handle.threads.push(spawn(format!("router-{segment}-drones"), move || drone_side(&s))?);
    let s = shared.clone();
    handle.threads.push(spawn(format!("router-{segment}-gcs-udp"), move || gcs_udp_side(&s))?);
    let s = shared;
    handle.threads.push(spawn(format!("router-{segment}-gcs-tcp"), move || accept_tcp(&s, &listener))?);
    Ok(handle)
}

impl RouterHandle {
    /// The bound GCS UDP address (useful when the configured port was 0).
    pub fn gcs_udp(&self) -> SocketAddr {
        self.gcs_udp
    }

    /// The bound GCS TCP address.
    pub fn gcs_tcp(&self) -> SocketAddr {
        self.gcs_tcp
    }

    /// The drone-side socket, as the drone endpoints see the router.
    pub fn drone_side(&self) -> SocketAddr {
        self.drone_side
    }

    /// Counters since start (client counts are 0 once stopped).
    pub fn stats(&self) -> RouterStats {
        let c = &self.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        RouterStats {
            frames_to_drones: get(&c.frames_to_drones),
            datagrams_to_gcs: get(&c.datagrams_to_gcs),
            dropped_unknown_target: get(&c.dropped_unknown_target),
            dropped_unknown_source: get(&c.dropped_unknown_source),
            bad_checksum: get(&c.bad_checksum),
            garbage_bytes: get(&c.garbage_bytes),
            dropped_gcs_backlog: get(&c.dropped_gcs_backlog),
            refused_tcp_clients: get(&c.refused_tcp_clients),
            gcs_udp_clients: self.shared.as_ref().map_or(0, |s| lock(&s.udp_peers).peers.len()),
            gcs_tcp_clients: self
                .shared
                .as_ref()
                .map_or(0, |s| lock(&s.tcp_clients).iter().filter(|c| !c.is_closed()).count()),
        }
    }

    /// Stops every thread and closes every socket, so the ports can be bound again; returns
    /// within about 100 ms. Idempotent.
    pub fn stop(&mut self) {
        let Some(shared) = self.shared.take() else { return };
        shared.stop.store(true, Ordering::Relaxed);
        // Unblocks TCP writers stuck on a client that does not read.
        for c in lock(&shared.tcp_clients).iter() {
            let _ = c.stream.shutdown(Shutdown::Both);
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        // The accept thread is gone, so no new client threads appear.
        let client_threads = std::mem::take(&mut *lock(&shared.tcp_threads));
        for t in client_threads {
            let _ = t.join();
        }
        // Every thread has ended, so this was the last reference: the sockets close here.
        drop(shared);
    }
}

impl Drop for RouterHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Checks the drone list and picks the drone-side bind address: loopback when every
/// endpoint is local (nothing else can reach the socket), otherwise any interface.
fn check_drones(drones: &[RoutedDrone]) -> Result<SocketAddr, RouterError> {
    if drones.len() > MAX_DRONES {
        return Err(RouterError::TooManyDrones(drones.len()));
    }
    let mut seen = [false; 256];
    for d in drones {
        if d.system_id == 0 || usize::from(d.system_id) > MAX_DRONES {
            return Err(RouterError::InvalidSystemId(d.system_id));
        }
        if std::mem::replace(&mut seen[usize::from(d.system_id)], true) {
            return Err(RouterError::DuplicateSystemId(d.system_id));
        }
    }
    let Some(first) = drones.first() else {
        return Ok(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0));
    };
    if let Some(other) = drones.iter().find(|d| d.endpoint.is_ipv4() != first.endpoint.is_ipv4()) {
        return Err(RouterError::MixedAddressFamilies(first.endpoint, other.endpoint));
    }
    let local = drones.iter().all(|d| d.endpoint.ip().is_loopback());
    let ip = match (first.endpoint.is_ipv4(), local) {
        (true, true) => IpAddr::V4(Ipv4Addr::LOCALHOST),
        (true, false) => IpAddr::V4(Ipv4Addr::UNSPECIFIED),
        (false, true) => IpAddr::V6(Ipv6Addr::LOCALHOST),
        (false, false) => IpAddr::V6(Ipv6Addr::UNSPECIFIED),
    };
    Ok(SocketAddr::new(ip, 0))
}

fn bind_error(socket: &'static str, addr: SocketAddr, source: io::Error) -> RouterError {
    if source.kind() == io::ErrorKind::AddrInUse {
        RouterError::AddressInUse { socket, addr }
    } else {
        RouterError::Bind { socket, addr, source }
    }
}

fn spawn(name: String, f: impl FnOnce() + Send + 'static) -> io::Result<JoinHandle<()>> {
    std::thread::Builder::new().name(name).spawn(f)
}

/// A poisoned lock only means another router thread panicked; the tables stay usable.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn is_timeout(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted)
}

/// The UDP ground stations, most recently heard kept. Time is a counter of datagrams, so
/// the eviction order does not depend on the clock.
#[derive(Debug, Default)]
struct PeerTable {
    /// (address, tick last heard)
    peers: Vec<(SocketAddr, u64)>,
    tick: u64,
}

impl PeerTable {
    fn heard(&mut self, addr: SocketAddr) {
        self.tick += 1;
        let tick = self.tick;
        if let Some(p) = self.peers.iter_mut().find(|p| p.0 == addr) {
            p.1 = tick;
        } else if self.peers.len() < MAX_UDP_GCS {
            self.peers.push((addr, tick));
        } else if let Some(oldest) = self.peers.iter_mut().min_by_key(|p| p.1) {
            *oldest = (addr, tick);
        }
    }
}

/// Who sent frames on the GCS side (they are not echoed back to it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GcsOrigin {
    Udp(SocketAddr),
    Tcp(u64),
}

/// A TCP ground station as the other threads see it.
#[derive(Debug)]
struct TcpClient {
    id: u64,
    queue: SyncSender<Arc<[u8]>>,
    /// A handle for shutting the connection down from outside its threads.
    stream: TcpStream,
    closed: Arc<AtomicBool>,
}

impl TcpClient {
    fn is_closed(&self) -> bool {
        self.closed.load(Ordering::Relaxed)
    }
}

#[derive(Debug, Default)]
struct Counters {
    frames_to_drones: AtomicU64,
    datagrams_to_gcs: AtomicU64,
    dropped_unknown_target: AtomicU64,
    dropped_unknown_source: AtomicU64,
    bad_checksum: AtomicU64,
    garbage_bytes: AtomicU64,
    dropped_gcs_backlog: AtomicU64,
    refused_tcp_clients: AtomicU64,
}

fn add(counter: &AtomicU64, n: u64) {
    if n > 0 {
        counter.fetch_add(n, Ordering::Relaxed);
    }
}

/// State every router thread reads.
#[derive(Debug)]
struct Shared {
    stop: AtomicBool,
    drones: Vec<RoutedDrone>,
    /// Drone endpoints, to accept drone-side datagrams only from them.
    endpoints: HashSet<SocketAddr>,
    /// System id -> index into `drones`.
    index_of: Vec<Option<usize>>,
    drone_socket: UdpSocket,
    gcs_udp: UdpSocket,
    udp_peers: Mutex<PeerTable>,
    tcp_clients: Mutex<Vec<TcpClient>>,
    tcp_threads: Mutex<Vec<JoinHandle<()>>>,
    next_tcp_id: AtomicU64,
    counters: Arc<Counters>,
}

impl Shared {
    fn stopping(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Parses one datagram (or one TCP read) and counts what the parser threw away.
    fn parse(&self, parser: &mut FrameParser, bytes: &[u8]) -> Vec<Frame> {
        let before = parser.stats;
        let frames = parser.push(bytes);
        add(&self.counters.bad_checksum, parser.stats.bad_checksum - before.bad_checksum);
        add(&self.counters.garbage_bytes, parser.stats.skipped_bytes - before.skipped_bytes);
        frames
    }

    /// Sends the router's HEARTBEAT to every drone endpoint, which makes the endpoint send
    /// its telemetry here.
    fn has_ground_stations(&self) -> bool {
        !lock(&self.udp_peers).peers.is_empty() || !lock(&self.tcp_clients).is_empty()
    }

    fn register_with_drones(&self, sequence: u8) {
        let header = MavHeader { system_id: u32::from(ROUTER_SYSTEM_ID), component_id: ROUTER_COMPONENT_ID, sequence };
        let heartbeat = encode(
            header,
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }),
        );
        for d in &self.drones {
            // A drone not up yet is registered by a later heartbeat.
            let _ = self.drone_socket.send_to(&heartbeat, d.endpoint);
        }
    }

    /// A datagram on the drone socket: to every ground station, unchanged when it is clean.
    fn forward_drone_datagram(&self, datagram: &[u8], from: SocketAddr, parser: &mut FrameParser) {
        if !self.endpoints.contains(&from) {
            add(&self.counters.dropped_unknown_source, 1);
            return;
        }
        if !self.has_ground_stations() {
            return; // nobody to forward to: not worth checking
        }
        parser.reset();
        let frames = self.parse(parser, datagram);
        let own = |f: &Frame| {
            f.header.system_id == u32::from(ROUTER_SYSTEM_ID) && f.header.component_id == ROUTER_COMPONENT_ID
        };
        let clean = frames.iter().map(|f| f.bytes.len()).sum::<usize>() == datagram.len() && !frames.iter().any(own);
        let out: Cow<'_, [u8]> = if clean {
            Cow::Borrowed(datagram)
        } else {
            Cow::Owned(frames.iter().filter(|f| !own(f)).flat_map(|f| f.bytes.iter().copied()).collect())
        };
        if !out.is_empty() {
            self.to_gcs(&out, None);
        }
    }

    /// Sends `bytes` (whole frames) to every ground station except `origin`.
    fn to_gcs(&self, bytes: &[u8], origin: Option<GcsOrigin>) {
        let mut sent = 0;
        {
            let peers = lock(&self.udp_peers);
            for &(addr, _) in &peers.peers {
                if origin != Some(GcsOrigin::Udp(addr)) && self.gcs_udp.send_to(bytes, addr).is_ok() {
                    sent += 1;
                }
            }
        }
        let mut clients = lock(&self.tcp_clients);
        clients.retain(|c| !c.is_closed());
        let mut shared: Option<Arc<[u8]>> = None;
        for c in clients.iter() {
            if origin == Some(GcsOrigin::Tcp(c.id)) {
                continue;
            }
            let chunk = shared.get_or_insert_with(|| Arc::from(bytes)).clone();
            match c.queue.try_send(chunk) {
                Ok(()) => sent += 1,
                Err(TrySendError::Full(_)) => add(&self.counters.dropped_gcs_backlog, 1),
                Err(TrySendError::Disconnected(_)) => c.closed.store(true, Ordering::Relaxed),
            }
        }
        add(&self.counters.datagrams_to_gcs, sent);
    }

    /// Frames from a ground station: to the other ground stations, and to their drones.
    fn route_gcs_frames(&self, frames: &[Frame], origin: GcsOrigin) {
        if frames.is_empty() {
            return;
        }
        let all: Vec<u8> = frames.iter().flat_map(|f| f.bytes.iter().copied()).collect();
        self.to_gcs(&all, Some(origin));

        // (drone index or None for every drone, frame)
        let mut routed: Vec<(Option<usize>, &Frame)> = Vec::with_capacity(frames.len());
        for f in frames {
            match destination(f) {
                None | Some(0) => routed.push((None, f)),
                Some(id) => match self.index_of[usize::from(id)] {
                    Some(i) => routed.push((Some(i), f)),
                    None => add(&self.counters.dropped_unknown_target, 1),
                },
            }
        }
        if routed.is_empty() {
            return;
        }
        // What a drone gets when every frame is for it (the common case: one frame, or
        // broadcasts only), built once.
        let every: Cow<'_, [u8]> = if routed.len() == frames.len() {
            Cow::Borrowed(&all)
        } else {
            Cow::Owned(routed.iter().flat_map(|(_, f)| f.bytes.iter().copied()).collect())
        };
        let mut delivered = 0;
        for (i, drone) in self.drones.iter().enumerate() {
            let reaches = |to: &Option<usize>| to.is_none_or(|t| t == i);
            let count = routed.iter().filter(|(to, _)| reaches(to)).count();
            if count == 0 {
                continue;
            }
            let result = if count == routed.len() {
                self.drone_socket.send_to(&every, drone.endpoint)
            } else {
                let mine: Vec<u8> =
                    routed.iter().filter(|(to, _)| reaches(to)).flat_map(|(_, f)| f.bytes.iter().copied()).collect();
                self.drone_socket.send_to(&mine, drone.endpoint)
            };
            if result.is_ok() {
                delivered += count as u64;
            }
        }
        add(&self.counters.frames_to_drones, delivered);
    }
}

/// The system a GCS frame is for: `None` or `Some(0)` mean every drone. A message the
/// dialect cannot decode goes to every drone, which drop what is not theirs, as on any
/// shared MAVLink link.
fn destination(frame: &Frame) -> Option<u8> {
    match &frame.message {
        Decoded::Message(m) => target_system(m),
        Decoded::UnknownCommand { target_system, .. } => Some(*target_system),
        Decoded::Undecodable(_) | Decoded::NotDecoded => None,
    }
}

/// The drone-side thread: registration heartbeats and telemetry to the ground stations.
fn drone_side(shared: &Shared) {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut parser = FrameParser::checksum_only();
    let mut sequence: u8 = 0;
    let mut next_heartbeat = Instant::now();
    while !shared.stopping() {
        let now = Instant::now();
        if now >= next_heartbeat {
            // Only while someone listens: drones forget a peer whose heartbeats stop, so a
            // router without ground stations costs the drones nothing.
            if shared.has_ground_stations() {
                shared.register_with_drones(sequence);
            }
            sequence = sequence.wrapping_add(1);
            next_heartbeat = now + HEARTBEAT_PERIOD;
        }
        match shared.drone_socket.recv_from(&mut buf) {
            Ok((n, from)) => shared.forward_drone_datagram(&buf[..n], from, &mut parser),
            Err(e) if is_timeout(&e) => {}
            // E.g. an ICMP port-unreachable reported on a later call (Windows): keep
            // serving, without spinning should the error persist.
            Err(_) => std::thread::sleep(POLL),
        }
    }
}

/// The GCS UDP thread: learns ground stations and routes their frames.
fn gcs_udp_side(shared: &Shared) {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut parser = FrameParser::new();
    while !shared.stopping() {
        match shared.gcs_udp.recv_from(&mut buf) {
            Ok((n, from)) => {
                parser.reset();
                let frames = shared.parse(&mut parser, &buf[..n]);
                // Only a sender of at least one valid frame becomes a client, so a port
                // scan or stray traffic does not subscribe to the telemetry.
                if !frames.is_empty() {
                    lock(&shared.udp_peers).heard(from);
                }
                shared.route_gcs_frames(&frames, GcsOrigin::Udp(from));
            }
            Err(e) if is_timeout(&e) => {}
            Err(_) => std::thread::sleep(POLL),
        }
    }
}

/// The TCP accept thread.
fn accept_tcp(shared: &Arc<Shared>, listener: &TcpListener) {
    while !shared.stopping() {
        match listener.accept() {
            // A client that cannot be set up is simply not served.
            Ok((stream, _)) => {
                let _ = add_tcp_client(shared, stream);
            }
            Err(_) => std::thread::sleep(POLL),
        }
        // Reap the threads of clients that left.
        let mut threads = lock(&shared.tcp_threads);
        let (done, running): (Vec<_>, Vec<_>) = threads.drain(..).partition(|t| t.is_finished());
        *threads = running;
        drop(threads);
        for t in done {
            let _ = t.join();
        }
    }
}

fn add_tcp_client(shared: &Arc<Shared>, stream: TcpStream) -> io::Result<()> {
    // Accepted sockets may inherit the listener's non-blocking mode on some platforms.
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(POLL))?;
    stream.set_write_timeout(Some(TCP_WRITE_TIMEOUT))?;
    let mut clients = lock(&shared.tcp_clients);
    clients.retain(|c| !c.is_closed());
    if clients.len() >= MAX_TCP_GCS {
        add(&shared.counters.refused_tcp_clients, 1);
        let _ = stream.shutdown(Shutdown::Both);
        return Ok(());
    }
    let id = shared.next_tcp_id.fetch_add(1, Ordering::Relaxed);
    let (queue, outgoing) = mpsc::sync_channel(TCP_QUEUE);
    let closed = Arc::new(AtomicBool::new(false));
    let writer_stream = stream.try_clone()?;
    clients.push(TcpClient { id, queue, stream: stream.try_clone()?, closed: closed.clone() });
    drop(clients);

    let mut threads = lock(&shared.tcp_threads);
    let (s, c) = (shared.clone(), closed.clone());
    let reader = spawn(format!("router-tcp-{id}-in"), move || tcp_reader(&s, stream, id, &c));
    let (s, c) = (shared.clone(), closed.clone());
    let writer = spawn(format!("router-tcp-{id}-out"), move || tcp_writer(&s, writer_stream, &outgoing, &c));
    for t in [reader, writer] {
        match t {
            Ok(t) => threads.push(t),
            // The other thread sees `closed` and ends; the client is removed on next use.
            Err(e) => {
                closed.store(true, Ordering::Relaxed);
                return Err(e);
            }
        }
    }
    Ok(())
}

/// Reads one TCP ground station's stream and routes its frames.
fn tcp_reader(shared: &Shared, mut stream: TcpStream, id: u64, closed: &AtomicBool) {
    let mut parser = FrameParser::new();
    let mut buf = vec![0u8; 16 * 1024];
    while !shared.stopping() && !closed.load(Ordering::Relaxed) {
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                let frames = shared.parse(&mut parser, &buf[..n]);
                shared.route_gcs_frames(&frames, GcsOrigin::Tcp(id));
            }
            Err(e) if is_timeout(&e) => {}
            Err(_) => break,
        }
    }
    closed.store(true, Ordering::Relaxed);
    let _ = stream.shutdown(Shutdown::Both);
}

/// Writes queued chunks to one TCP ground station.
fn tcp_writer(shared: &Shared, mut stream: TcpStream, outgoing: &Receiver<Arc<[u8]>>, closed: &AtomicBool) {
    while !shared.stopping() && !closed.load(Ordering::Relaxed) {
        match outgoing.recv_timeout(POLL) {
            Ok(chunk) => {
                if stream.write_all(&chunk).is_err() {
                    break;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    closed.store(true, Ordering::Relaxed);
    let _ = stream.shutdown(Shutdown::Both);
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;
    use std::thread;

    use ::mavlink::dialects::common::{ATTITUDE_DATA, COMMAND_LONG_DATA, MavCmd};

    use super::*;

    const DEADLINE: Duration = Duration::from_secs(5);
    const GCS_SYSID: u32 = 255;

    fn heartbeat(mavtype: MavType) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_STANDBY,
            mavlink_version: 3,
        })
    }

    fn frame(system_id: u32, message: &MavMessage) -> Vec<u8> {
        encode(MavHeader { system_id, component_id: 1, sequence: 0 }, message)
    }

    fn command(target_system: u8, param1: f32) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system,
            target_component: 1,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            param1,
            ..Default::default()
        })
    }

    /// Polls `f` until it returns `Some` or the deadline passes.
    fn wait_for<T>(what: &str, mut f: impl FnMut() -> Option<T>) -> T {
        let end = Instant::now() + DEADLINE;
        loop {
            if let Some(v) = f() {
                return v;
            }
            assert!(Instant::now() < end, "timed out waiting for {what}");
            thread::sleep(Duration::from_millis(5));
        }
    }

    /// A drone endpoint stand-in: sends HEARTBEAT + ATTITUDE in one datagram every 20 ms to
    /// whoever registered with a heartbeat, and records every other frame it receives.
    struct FakeDrone {
        addr: SocketAddr,
        received: Arc<Mutex<Vec<Frame>>>,
        registrations: Arc<AtomicU64>,
        stop: Arc<AtomicBool>,
        thread: Option<JoinHandle<()>>,
    }

    impl FakeDrone {
        fn start(system_id: u8) -> Self {
            let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
            socket.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
            let addr = socket.local_addr().unwrap();
            let received = Arc::new(Mutex::new(Vec::new()));
            let registrations = Arc::new(AtomicU64::new(0));
            let stop = Arc::new(AtomicBool::new(false));
            let (rec, regs, halt) = (received.clone(), registrations.clone(), stop.clone());
            let thread = thread::spawn(move || {
                let sysid = u32::from(system_id);
                let mut telemetry = frame(sysid, &heartbeat(MavType::MAV_TYPE_QUADROTOR));
                telemetry.extend(frame(sysid, &MavMessage::ATTITUDE(ATTITUDE_DATA::default())));
                let mut peer = None;
                let mut parser = FrameParser::new();
                let mut buf = [0u8; 4096];
                let mut next_send = Instant::now();
                while !halt.load(Ordering::Relaxed) {
                    if let Ok((n, from)) = socket.recv_from(&mut buf) {
                        parser.reset();
                        for f in parser.push(&buf[..n]) {
                            if f.header.system_id == u32::from(ROUTER_SYSTEM_ID) {
                                peer = Some(from);
                                regs.fetch_add(1, Ordering::Relaxed);
                            } else {
                                rec.lock().unwrap().push(f);
                            }
                        }
                    }
                    if let Some(p) = peer
                        && Instant::now() >= next_send
                    {
                        let _ = socket.send_to(&telemetry, p);
                        next_send = Instant::now() + Duration::from_millis(20);
                    }
                }
            });
            Self { addr, received, registrations, stop, thread: Some(thread) }
        }

        /// COMMAND_LONG param1 values received.
        fn commands(&self) -> Vec<f32> {
            let frames = self.received.lock().unwrap();
            frames
                .iter()
                .filter_map(|f| match &f.message {
                    Decoded::Message(MavMessage::COMMAND_LONG(c)) => Some(c.param1),
                    _ => None,
                })
                .collect()
        }
    }

    impl Drop for FakeDrone {
        fn drop(&mut self) {
            self.stop.store(true, Ordering::Relaxed);
            if let Some(t) = self.thread.take() {
                let _ = t.join();
            }
        }
    }

    fn fleet(n: u8) -> (Vec<FakeDrone>, RouterHandle) {
        let drones: Vec<FakeDrone> = (1..=n).map(FakeDrone::start).collect();
        let config = RouterConfig {
            segment: 0,
            gcs_udp: "127.0.0.1:0".parse().unwrap(),
            gcs_tcp: "127.0.0.1:0".parse().unwrap(),
            drones: drones
                .iter()
                .enumerate()
                .map(|(i, d)| RoutedDrone { system_id: i as u8 + 1, endpoint: d.addr })
                .collect(),
        };
        let router = start(config).unwrap();
        (drones, router)
    }

    /// A UDP ground station that announced itself with a GCS heartbeat.
    fn udp_gcs(router: &RouterHandle) -> UdpSocket {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
        socket.send_to(&frame(GCS_SYSID, &heartbeat(MavType::MAV_TYPE_GCS)), router.gcs_udp()).unwrap();
        socket
    }

    /// Reads from a GCS socket until `want` holds for the frames seen so far.
    fn udp_until(socket: &UdpSocket, what: &str, mut want: impl FnMut(&[Frame]) -> bool) -> Vec<Frame> {
        let mut seen = Vec::new();
        let mut parser = FrameParser::new();
        let mut buf = vec![0u8; MAX_DATAGRAM];
        wait_for(what, || {
            while let Ok(n) = socket.recv(&mut buf) {
                parser.reset();
                seen.extend(parser.push(&buf[..n]));
            }
            want(&seen).then_some(())
        });
        seen
    }

    fn sysids(frames: &[Frame]) -> BTreeSet<u32> {
        frames.iter().map(|f| f.header.system_id).collect()
    }

    #[test]
    fn a_gcs_sees_every_drone_of_the_segment_but_not_the_router() {
        let (drones, router) = fleet(32);
        // No ground station yet: the drones are left alone (their telemetry would go nowhere).
        thread::sleep(HEARTBEAT_PERIOD + Duration::from_millis(200));
        assert!(drones.iter().all(|d| d.registrations.load(Ordering::Relaxed) == 0));
        let gcs = udp_gcs(&router);
        wait_for("every drone registered", || {
            drones.iter().all(|d| d.registrations.load(Ordering::Relaxed) > 0).then_some(())
        });
        let frames = udp_until(&gcs, "32 system ids", |f| sysids(f).len() >= 32);
        assert_eq!(sysids(&frames), (1..=32).collect());
        assert!(router.stats().datagrams_to_gcs > 0);
        assert_eq!(router.stats().gcs_udp_clients, 1);
    }

    #[test]
    fn a_command_reaches_its_target_only_and_a_broadcast_reaches_all() {
        let (drones, router) = fleet(32);
        let gcs = udp_gcs(&router);
        gcs.send_to(&frame(GCS_SYSID, &command(7, 1.0)), router.gcs_udp()).unwrap();
        wait_for("drone 7 to get its command", || (drones[6].commands() == [1.0]).then_some(()));
        // The router sends in order on one socket, so once the broadcast sent after the
        // command has arrived everywhere, a misrouted copy would have arrived too.
        gcs.send_to(&frame(GCS_SYSID, &command(0, 2.0)), router.gcs_udp()).unwrap();
        wait_for("the broadcast everywhere", || drones.iter().all(|d| d.commands().contains(&2.0)).then_some(()));
        for (i, d) in drones.iter().enumerate() {
            let expected: &[f32] = if i == 6 { &[1.0, 2.0] } else { &[2.0] };
            assert_eq!(d.commands(), expected, "drone {}", i + 1);
        }
        // The GCS heartbeat (no target) reached every drone as well.
        for d in &drones {
            let frames = d.received.lock().unwrap();
            assert!(frames.iter().any(|f| f.header.system_id == GCS_SYSID && f.message_id == 0));
        }
        // A target outside the segment goes nowhere.
        gcs.send_to(&frame(GCS_SYSID, &command(99, 3.0)), router.gcs_udp()).unwrap();
        wait_for("the unknown target counted", || (router.stats().dropped_unknown_target == 1).then_some(()));
        assert_eq!(router.stats().frames_to_drones, 1 + 32 + 32);
    }

    #[test]
    fn udp_and_tcp_ground_stations_both_get_telemetry_and_see_each_other() {
        let (_drones, router) = fleet(4);
        let udp = udp_gcs(&router);
        let mut tcp = TcpStream::connect(router.gcs_tcp()).unwrap();
        tcp.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
        wait_for("the TCP client registered", || (router.stats().gcs_tcp_clients == 1).then_some(()));
        tcp.write_all(&frame(254, &heartbeat(MavType::MAV_TYPE_GCS))).unwrap();
        udp.send_to(&frame(GCS_SYSID, &heartbeat(MavType::MAV_TYPE_GCS)), router.gcs_udp()).unwrap();

        let mut parser = FrameParser::new();
        let mut seen = BTreeSet::new();
        let mut buf = [0u8; 4096];
        wait_for("telemetry over TCP", || {
            if let Ok(n) = tcp.read(&mut buf) {
                seen.extend(parser.push(&buf[..n]).iter().map(|f| f.header.system_id));
            }
            ((1..=4).all(|s| seen.contains(&s)) && seen.contains(&GCS_SYSID)).then_some(())
        });
        let frames = udp_until(&udp, "telemetry and the TCP GCS over UDP", |f| {
            let s = sysids(f);
            (1..=4).all(|id| s.contains(&id)) && s.contains(&254)
        });
        assert!(!sysids(&frames).contains(&GCS_SYSID), "a GCS's own frames are not echoed back");
    }

    #[test]
    fn garbage_and_bad_checksums_from_a_gcs_are_dropped_and_routing_goes_on() {
        let (drones, router) = fleet(3);
        let udp = udp_gcs(&router);
        let mut bad = frame(GCS_SYSID, &command(2, 9.0));
        let last = bad.len() - 1;
        bad[last] ^= 0xFF;
        let mut noise: Vec<u8> = (0..=255u8).collect();
        noise.extend([0xFD, 200, 0, 0]); // a start marker with a long, never-completed frame
        udp.send_to(&bad, router.gcs_udp()).unwrap();
        udp.send_to(&noise, router.gcs_udp()).unwrap();
        let mut tcp = TcpStream::connect(router.gcs_tcp()).unwrap();
        tcp.write_all(&bad).unwrap();
        tcp.write_all(&(0..100u8).collect::<Vec<_>>()).unwrap();
        // A good frame after garbage on the same stream still gets through.
        tcp.write_all(&frame(254, &command(2, 1.0))).unwrap();
        udp.send_to(&frame(GCS_SYSID, &command(2, 2.0)), router.gcs_udp()).unwrap();
        wait_for("both good commands", || {
            let mut c = drones[1].commands();
            c.sort_by(f32::total_cmp);
            (c == [1.0, 2.0]).then_some(())
        });
        let stats = router.stats();
        assert!(stats.bad_checksum >= 2, "{stats:?}");
        assert!(stats.garbage_bytes > 0, "{stats:?}");
        assert!(drones[0].commands().is_empty() && drones[2].commands().is_empty());
    }

    #[test]
    fn the_router_heartbeat_and_strangers_never_reach_a_gcs() {
        let (drones, router) = fleet(1);
        let gcs = udp_gcs(&router);
        wait_for("drone telemetry", || (router.stats().datagrams_to_gcs > 0).then_some(()));
        // A stranger writes to the drone-side socket: dropped.
        let stranger = UdpSocket::bind("127.0.0.1:0").unwrap();
        stranger.send_to(&frame(42, &heartbeat(MavType::MAV_TYPE_QUADROTOR)), router.drone_side()).unwrap();
        wait_for("the stranger counted", || (router.stats().dropped_unknown_source == 1).then_some(()));
        let frames = udp_until(&gcs, "a few datagrams", |f| f.len() >= 10);
        assert!(frames.iter().all(|f| f.header.system_id == 1), "{:?}", sysids(&frames));
        drop(drones);
    }

    #[test]
    fn an_echoed_router_heartbeat_is_taken_out_of_a_drone_datagram() {
        // A drone endpoint played by hand: it echoes the router's heartbeat with its own.
        let drone = UdpSocket::bind("127.0.0.1:0").unwrap();
        drone.set_read_timeout(Some(DEADLINE)).unwrap();
        let router = start(RouterConfig {
            segment: 1,
            gcs_udp: "127.0.0.1:0".parse().unwrap(),
            gcs_tcp: "127.0.0.1:0".parse().unwrap(),
            drones: vec![RoutedDrone { system_id: 5, endpoint: drone.local_addr().unwrap() }],
        })
        .unwrap();
        let gcs = udp_gcs(&router);
        let mut buf = [0u8; 512];
        // The GCS's heartbeat, forwarded to every drone, may come first.
        let (mut datagram, router_addr) = loop {
            let (n, from) = drone.recv_from(&mut buf).unwrap();
            let frames = FrameParser::new().push(&buf[..n]);
            if frames.iter().any(|f| f.header.system_id == u32::from(ROUTER_SYSTEM_ID)) {
                break (buf[..n].to_vec(), from);
            }
        };
        wait_for("the GCS registered", || (router.stats().gcs_udp_clients == 1).then_some(()));
        datagram.extend(frame(5, &heartbeat(MavType::MAV_TYPE_QUADROTOR)));
        drone.send_to(&datagram, router_addr).unwrap();
        let frames = udp_until(&gcs, "the drone's heartbeat", |f| !f.is_empty());
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].header.system_id, 5);
    }

    #[test]
    fn a_port_in_use_is_named_in_the_error() {
        let taken = UdpSocket::bind("127.0.0.1:0").unwrap();
        let addr = taken.local_addr().unwrap();
        let err = start(RouterConfig {
            segment: 0,
            gcs_udp: addr,
            gcs_tcp: "127.0.0.1:0".parse().unwrap(),
            drones: Vec::new(),
        })
        .unwrap_err();
        let message = err.to_string();
        assert!(message.contains(&addr.to_string()) && message.contains("in use"), "{message}");
    }

    #[test]
    fn invalid_drone_lists_are_refused() {
        let d = |system_id| RoutedDrone { system_id, endpoint: "127.0.0.1:9".parse().unwrap() };
        let config = |drones| RouterConfig {
            segment: 0,
            gcs_udp: "127.0.0.1:0".parse().unwrap(),
            gcs_tcp: "127.0.0.1:0".parse().unwrap(),
            drones,
        };
        assert!(matches!(start(config(vec![d(3), d(3)])), Err(RouterError::DuplicateSystemId(3))));
        assert!(matches!(start(config(vec![d(0)])), Err(RouterError::InvalidSystemId(0))));
        assert!(matches!(start(config(vec![d(251)])), Err(RouterError::InvalidSystemId(251))));
        assert!(matches!(start(config(vec![d(1); 251])), Err(RouterError::TooManyDrones(251))));
        let v6 = RoutedDrone { system_id: 2, endpoint: "[::1]:9".parse().unwrap() };
        assert!(matches!(start(config(vec![d(1), v6])), Err(RouterError::MixedAddressFamilies(..))));
    }

    #[test]
    fn stop_is_prompt_and_releases_the_ports() {
        let (_drones, mut router) = fleet(2);
        let gcs = udp_gcs(&router);
        let _tcp = TcpStream::connect(router.gcs_tcp()).unwrap();
        wait_for("both clients", || {
            let s = router.stats();
            (s.gcs_tcp_clients == 1 && s.gcs_udp_clients == 1).then_some(())
        });
        let (udp_addr, tcp_addr) = (router.gcs_udp(), router.gcs_tcp());
        let started = Instant::now();
        router.stop();
        // ~100 ms by design; the bound is loose so a loaded CI machine does not fail it.
        assert!(started.elapsed() < Duration::from_secs(1), "stop took {:?}", started.elapsed());
        drop(gcs);
        UdpSocket::bind(udp_addr).unwrap();
        TcpListener::bind(tcp_addr).unwrap();
        router.stop(); // idempotent
    }

    #[test]
    fn the_least_recently_heard_udp_gcs_is_evicted() {
        let mut table = PeerTable::default();
        let addr = |p: u16| SocketAddr::from(([127, 0, 0, 1], p));
        for p in 0..MAX_UDP_GCS as u16 {
            table.heard(addr(p));
        }
        table.heard(addr(0)); // 0 is now the most recent; 1 the least
        table.heard(addr(100));
        let peers: BTreeSet<u16> = table.peers.iter().map(|p| p.0.port()).collect();
        assert_eq!(peers.len(), MAX_UDP_GCS);
        assert!(peers.contains(&0) && peers.contains(&100) && !peers.contains(&1));
    }
}
