//! What a router serves (its segment's drones, its GCS addresses), its limits, its
//! errors and its counters.

use std::io;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::time::Duration;

use serde::Serialize;

use sadesim_engine::mavlink::signing::SecretKey;

/// The router's own system id: outside the drones' 1..=250 and below the 255 ground stations
/// use by default (254 is MAVProxy's and some companion computers'), so it clashes with
/// neither.
pub const ROUTER_SYSTEM_ID: u8 = sadesim_engine::shard::ROUTER_SYSTEM_ID;
/// MAV_COMP_ID_UDP_BRIDGE: what the router is.
pub const ROUTER_COMPONENT_ID: u8 = sadesim_engine::shard::ROUTER_COMPONENT_ID;
/// Drones per segment: the planner's limit, since system ids 1..=250 must be distinct.
pub const MAX_DRONES: usize = 250;
/// UDP ground stations served at once. A station keeps its place while it is live (heard
/// within [`UDP_GCS_LIVENESS`]); a newcomer while every place is live is refused (counted in
/// [`RouterStats::refused_udp_gcs_frames`], logged), and takes the place of the least
/// recently heard station once that one has been silent for longer than the period.
pub const MAX_UDP_GCS: usize = 16;
/// How long a UDP ground station keeps its place without a frame from it: ground stations
/// heartbeat at 1 Hz, so a live one is never silent this long, and a gone one frees its
/// place for a newcomer after it. (A silent station keeps receiving telemetry until a
/// newcomer needs the place.)
pub const UDP_GCS_LIVENESS: Duration = Duration::from_secs(5);
/// TCP ground stations served at once; further connections are closed at once (counted).
pub const MAX_TCP_GCS: usize = 16;
/// Read timeout of every socket: how long a thread may take to notice [`RouterHandle::stop`].
pub const POLL: Duration = Duration::from_millis(25);
/// How often the router registers with the drone endpoints.
pub(super) const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);
/// A TCP client that accepts no bytes for this long is disconnected (a write that timed out
/// may have sent half a frame, so the stream cannot continue anyway).
pub(super) const TCP_WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// Datagrams queued per TCP client before new ones are dropped: about a second of a full
/// segment's telemetry.
pub(super) const TCP_QUEUE: usize = 1024;
/// Largest UDP payload.
pub(super) const MAX_DATAGRAM: usize = 65_536;
/// The drone side gathers the frames of datagrams that arrive together (a shard sends all
/// its drones' telemetry at once, every 20 ms of simulated time) and sends them to the
/// ground stations in shared datagrams: a send for the router and a receive for each ground
/// station per gathered datagram instead of one per drone. It sends what it gathered when
/// no datagram came for this long...
pub(super) const GATHER_GAP: Duration = Duration::from_millis(1);
/// ...or when the first gathered frame has waited this long (a steady trickle of datagrams
/// could otherwise hold frames back)...
pub(super) const GATHER_MAX_WAIT: Duration = Duration::from_millis(5);
/// ...or when the next frames would not fit in this many bytes: below a 1 500-byte
/// Ethernet MTU's UDP payload and within MAVSDK's 2 kB receive buffer. A larger datagram
/// from a shard (up to 16 KiB from one on this host) is split at frame boundaries.
pub(super) const GCS_DATAGRAM: usize = 1400;

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
    /// MAVLink 2 signing on the GCS side: with a key, only frames signed with it are taken
    /// from ground stations, and everything sent to them is signed. `None`: neither (frames
    /// pass byte for byte).
    pub signing: Option<SecretKey>,
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
    /// Frames from UDP ground stations refused because [`MAX_UDP_GCS`] others were live
    /// (heard within [`UDP_GCS_LIVENESS`]): not forwarded, and their sender gets no telemetry.
    pub refused_udp_gcs_frames: u64,
    /// With signing: GCS frames dropped for carrying no signature (MAVLink 1 frames
    /// included, which cannot carry one).
    pub refused_unsigned: u64,
    /// With signing: GCS frames dropped for a signature that does not match the key.
    pub refused_bad_signature: u64,
    /// With signing: GCS frames dropped for a timestamp not after the last one of their
    /// stream (a replay), or a new stream starting over a minute in the past.
    pub refused_old_timestamp: u64,
    /// UDP ground stations currently served.
    pub gcs_udp_clients: usize,
    /// TCP ground stations currently connected.
    pub gcs_tcp_clients: usize,
}

/// Checks the drone list and picks the drone-side bind address: loopback when every
/// endpoint is local (nothing else can reach the socket), otherwise any interface.
pub(super) fn check_drones(drones: &[RoutedDrone]) -> Result<SocketAddr, RouterError> {
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

pub(super) fn bind_error(socket: &'static str, addr: SocketAddr, source: io::Error) -> RouterError {
    if source.kind() == io::ErrorKind::AddrInUse {
        RouterError::AddressInUse { socket, addr }
    } else {
        RouterError::Bind { socket, addr, source }
    }
}
