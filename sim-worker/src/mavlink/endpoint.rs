//! The sockets of one drone's MAVLink endpoint: thin, non-blocking, polled by the shard at
//! each sync window (so I/O never runs concurrently with the drone it feeds).
//!
//! Addressing follows PX4 SITL so SDK defaults work unchanged:
//! - the *API link*: telemetry is sent to `api_target` (127.0.0.1:14540+i locally), where
//!   `udpin://0.0.0.0:14540` clients (MAVSDK, pymavlink `udpin:`) listen; their replies come
//!   back to our socket;
//! - *connecting clients*: anyone who sends a datagram to our UDP port (`udpout://host:port`,
//!   the form that works across pods) becomes a peer and receives telemetry from then on;
//! - *TCP*: clients connecting to the same port number over TCP (`tcpout://host:port`).
//!
//! Several frames are packed into one datagram, as PX4 does, which keeps the syscall count
//! per drone at one per peer and window. Telemetry is lossy by nature: a TCP peer that
//! cannot keep up loses frames rather than stalling the simulation.

use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream, UdpSocket};

use ::mavlink::MavHeader;

use crate::mavlink::frame::{Frame, FrameParser, MAX_FRAME_LEN};
use crate::mavlink::session::{COMPONENT_ID, Outgoing};

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
/// The TCP listener is checked every this many polls (connections wait at most that long).
const ACCEPT_EVERY_POLLS: u64 = 5;
/// Datagrams read per poll: a flood cannot keep the shard from simulating (the kernel
/// drops what does not fit its buffer).
const MAX_DATAGRAMS_PER_POLL: usize = 256;
/// Bytes read per TCP peer per poll, for the same reason.
const MAX_TCP_BYTES_PER_POLL: usize = 64 * 1024;

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
}

#[derive(Debug)]
struct TcpPeer {
    stream: TcpStream,
    parser: FrameParser,
    closed: bool,
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
}

/// One drone's sockets.
#[derive(Debug)]
pub struct Endpoint {
    config: EndpointConfig,
    udp: UdpSocket,
    tcp: TcpListener,
    udp_peers: Vec<UdpPeer>,
    tcp_peers: Vec<TcpPeer>,
    parser: FrameParser,
    sequence: u8,
    polls: u64,
    /// Encoded datagrams waiting for the next flush.
    pending: Vec<Vec<u8>>,
    pub stats: EndpointStats,
}

impl Endpoint {
    /// Binds UDP and TCP on `config.bind_ip:config.port`.
    ///
    /// # Errors
    /// When a socket cannot be bound (the message names the system and address).
    pub fn open(config: EndpointConfig) -> Result<Self, EndpointError> {
        let address = SocketAddr::new(config.bind_ip, config.port);
        let err = |source: std::io::Error| {
            let hint = if source.kind() == ErrorKind::AddrInUse {
                " (is another run or PX4 SITL using this port? `sadesim run --no-mavlink` runs without endpoints)"
            } else {
                ""
            };
            EndpointError { system_id: config.system_id, address, source, hint }
        };
        let udp = UdpSocket::bind(address).map_err(err)?;
        udp.set_nonblocking(true).map_err(err)?;
        // Same number over TCP (also when port 0 let the OS pick the UDP one).
        let bound = udp.local_addr().map_err(err)?;
        let tcp = TcpListener::bind(bound).map_err(err)?;
        tcp.set_nonblocking(true).map_err(err)?;
        Ok(Self {
            config,
            udp,
            tcp,
            udp_peers: Vec::new(),
            tcp_peers: Vec::new(),
            parser: FrameParser::new(),
            sequence: 0,
            polls: 0,
            pending: Vec::new(),
            stats: EndpointStats::default(),
        })
    }

    /// The bound UDP address (the port is known once bound, also when 0 was asked for).
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.udp.local_addr()
    }

    /// Everything that arrived since the last call, as checksummed frames.
    pub fn receive(&mut self) -> Vec<Frame> {
        self.polls += 1;
        let mut frames = Vec::new();
        let mut buf = [0u8; 2048];
        for _ in 0..MAX_DATAGRAMS_PER_POLL {
            match self.udp.recv_from(&mut buf) {
                Ok((n, from)) => {
                    self.stats.datagrams_in += 1;
                    // Each datagram stands alone: a frame never spans two.
                    self.parser.reset();
                    let got = self.parser.push(&buf[..n]);
                    let heartbeat = got.iter().any(|f| f.message_id == 0);
                    self.remember(from, heartbeat);
                    frames.extend(got);
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                // ICMP errors from an earlier send (e.g. nobody on the API port) surface
                // here on some systems; they concern that send, not this socket.
                Err(_) => continue,
            }
        }
        let now = std::time::Instant::now();
        self.udp_peers.retain(|p| p.heartbeat_at.is_none_or(|t| now.duration_since(t) < self.config.peer_timeout));
        if self.polls % ACCEPT_EVERY_POLLS == 1 {
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

    fn remember(&mut self, from: SocketAddr, heartbeat: bool) {
        if Some(from) == self.config.api_target {
            return; // the API link already receives everything
        }
        let heartbeat_at = heartbeat.then(std::time::Instant::now);
        if let Some(p) = self.udp_peers.iter_mut().find(|p| p.address == from) {
            p.heard = self.polls;
            p.heartbeat_at = heartbeat_at.or(p.heartbeat_at);
            return;
        }
        if self.udp_peers.len() >= MAX_UDP_PEERS
            && let Some(oldest) = self.udp_peers.iter().enumerate().min_by_key(|(_, p)| p.heard).map(|(i, _)| i)
        {
            self.udp_peers.swap_remove(oldest);
        }
        self.udp_peers.push(UdpPeer { address: from, heard: self.polls, heartbeat_at });
    }

    fn accept_tcp(&mut self) {
        while let Ok((stream, _)) = self.tcp.accept() {
            if self.tcp_peers.len() >= MAX_TCP_PEERS || stream.set_nonblocking(true).is_err() {
                self.stats.tcp_refused += 1;
                continue; // dropped: closes the connection
            }
            let _ = stream.set_nodelay(true);
            self.stats.tcp_accepted += 1;
            self.tcp_peers.push(TcpPeer { stream, parser: FrameParser::new(), closed: false });
        }
    }

    /// Encodes `messages` with this link's sequence numbers into the outgoing datagrams,
    /// sent at the next [`Endpoint::flush`]. Messages are built when due (their rates and
    /// timestamps stay right); only the sending is batched.
    pub fn queue(&mut self, messages: &[Outgoing]) {
        for m in messages {
            let header = MavHeader {
                system_id: u32::from(self.config.system_id),
                component_id: COMPONENT_ID,
                sequence: self.sequence,
            };
            self.sequence = self.sequence.wrapping_add(1);
            // A frame is at most MAX_FRAME_LEN bytes: start a new datagram when it may not fit.
            let fits = self.pending.last().is_some_and(|d| d.len() + MAX_FRAME_LEN <= MAX_DATAGRAM);
            if !fits {
                if self.pending.len() >= MAX_PENDING_DATAGRAMS {
                    self.pending.remove(0); // nobody flushed for long: oldest first out
                    self.stats.dropped_datagrams += 1;
                }
                self.pending.push(Vec::with_capacity(MAX_DATAGRAM));
            }
            let datagram = self.pending.last_mut().expect("pushed above");
            m.encode_into(datagram, header);
        }
    }

    /// Sends the queued datagrams to every peer.
    pub fn flush(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        let datagrams = std::mem::take(&mut self.pending);
        let targets = self.config.api_target.into_iter().chain(self.udp_peers.iter().map(|p| p.address));
        for target in targets {
            for d in &datagrams {
                match self.udp.send_to(d, target) {
                    Ok(_) => self.stats.datagrams_out += 1,
                    Err(_) => self.stats.send_errors += 1,
                }
            }
        }
        self.tcp_peers.retain_mut(|peer| {
            for d in &datagrams {
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
    }

    /// [`Endpoint::queue`] then [`Endpoint::flush`].
    pub fn send(&mut self, messages: &[Outgoing]) {
        self.queue(messages);
        self.flush();
    }
}

#[cfg(test)]
mod tests {
    use std::net::Ipv4Addr;
    use std::time::{Duration, Instant};

    use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavMessage};

    use super::*;
    use crate::mavlink::frame::{Decoded, encode};

    fn open(api_target: Option<SocketAddr>) -> Endpoint {
        Endpoint::open(EndpointConfig {
            system_id: 9,
            bind_ip: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: 0,
            api_target,
            peer_timeout: Duration::from_millis(300),
        })
        .expect("binds an ephemeral port")
    }

    fn heartbeat(sys: u32) -> Vec<u8> {
        encode(
            MavHeader { system_id: sys, component_id: 190, sequence: 0 },
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        )
    }

    fn receive_until(e: &mut Endpoint, n: usize) -> Vec<Frame> {
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut frames = Vec::new();
        while frames.len() < n && Instant::now() < deadline {
            frames.extend(e.receive());
            std::thread::sleep(Duration::from_millis(2));
        }
        frames
    }

    #[test]
    fn a_udp_client_that_speaks_first_receives_telemetry() {
        let mut e = open(None);
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        client.send_to(&heartbeat(255), e.local_addr().unwrap()).unwrap();
        let frames = receive_until(&mut e, 1);
        assert!(matches!(frames[0].message, Decoded::Message(MavMessage::HEARTBEAT(_))));
        e.send(&vec![Outgoing::Message(MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())); 3]);
        client.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut buf = [0u8; 2048];
        let n = client.recv(&mut buf).unwrap();
        let got = FrameParser::new().push(&buf[..n]);
        assert_eq!(got.len(), 3, "three frames packed in one datagram");
        assert_eq!(got.iter().map(|f| f.header.sequence).collect::<Vec<_>>(), vec![0, 1, 2]);
        assert_eq!(got[0].header.system_id, 9);
    }

    /// Sends one heartbeat from `client`, then counts datagrams reaching it.
    fn datagrams_after(e: &mut Endpoint, client: &UdpSocket, wait: Duration) -> usize {
        std::thread::sleep(wait);
        let mut buf = [0u8; 2048];
        client.set_nonblocking(true).unwrap();
        while client.recv(&mut buf).is_ok() {} // what earlier sends left behind
        client.set_nonblocking(false).unwrap();
        e.receive();
        e.send(&[Outgoing::Message(MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))]);
        client.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
        usize::from(client.recv(&mut buf).is_ok())
    }

    #[test]
    fn a_peer_whose_heartbeats_stop_is_forgotten_but_a_silent_one_is_kept() {
        let mut e = open(None);
        let heartbeating = UdpSocket::bind("127.0.0.1:0").unwrap();
        let silent = UdpSocket::bind("127.0.0.1:0").unwrap();
        heartbeating.send_to(&heartbeat(255), e.local_addr().unwrap()).unwrap();
        // A frame that is not a heartbeat (garbage works too: any datagram registers).
        silent.send_to(b"hello", e.local_addr().unwrap()).unwrap();
        receive_until(&mut e, 1);
        assert_eq!(datagrams_after(&mut e, &heartbeating, Duration::ZERO), 1);
        assert_eq!(datagrams_after(&mut e, &silent, Duration::ZERO), 1);
        // 300 ms without a heartbeat: the heartbeating peer is gone, the silent one stays.
        assert_eq!(datagrams_after(&mut e, &heartbeating, Duration::from_millis(400)), 0);
        assert_eq!(datagrams_after(&mut e, &silent, Duration::ZERO), 1);
    }

    #[test]
    fn the_api_link_gets_telemetry_without_asking() {
        let listener = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut e = open(Some(listener.local_addr().unwrap()));
        e.send(&[Outgoing::Message(MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))]);
        listener.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut buf = [0u8; 2048];
        let (n, from) = listener.recv_from(&mut buf).unwrap();
        assert_eq!(from, e.local_addr().unwrap(), "replies go back to the endpoint");
        assert_eq!(FrameParser::new().push(&buf[..n]).len(), 1);
    }

    #[test]
    fn tcp_clients_send_and_receive_and_garbage_is_dropped() {
        let mut e = open(None);
        let mut client = TcpStream::connect(e.local_addr().unwrap()).unwrap();
        let mut garbage: Vec<u8> = (0..5000u32).map(|i| (i.wrapping_mul(2_654_435_761u32) >> 24) as u8).collect();
        // A false start marker in the garbage may claim up to 280 bytes: the parser then
        // waits for them, so real frames right after it are found once that many arrived.
        for _ in 0..20 {
            garbage.extend(heartbeat(200));
        }
        client.write_all(&garbage).unwrap();
        let frames = receive_until(&mut e, 5);
        assert!(frames.len() >= 5, "{} frames", frames.len());
        assert!(frames.iter().all(|f| f.header.system_id == 200));
        e.send(&[Outgoing::Message(MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))]);
        client.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut buf = [0u8; 512];
        let n = client.read(&mut buf).unwrap();
        assert_eq!(FrameParser::new().push(&buf[..n]).len(), 1);
    }

    #[test]
    fn a_port_in_use_is_named_in_the_error() {
        let e = open(None);
        let port = e.local_addr().unwrap().port();
        let err = Endpoint::open(EndpointConfig {
            system_id: 3,
            bind_ip: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port,
            api_target: None,
            peer_timeout: PEER_HEARTBEAT_TIMEOUT,
        })
        .unwrap_err()
        .to_string();
        assert!(err.contains(&format!("127.0.0.1:{port}")) && err.contains("system 3"), "{err}");
    }
}
