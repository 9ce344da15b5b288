//! The router's threads: the drone-side socket, GCS UDP, the TCP accept loop, and a
//! reader and a writer per TCP ground station.

use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::Instant;

use super::config::{
    GATHER_GAP, GATHER_MAX_WAIT, GCS_DATAGRAM, HEARTBEAT_PERIOD, MAX_DATAGRAM, MAX_TCP_GCS, POLL, TCP_QUEUE,
    TCP_WRITE_TIMEOUT,
};
use super::handle::spawn;
use super::routing_table::{GcsOrigin, Shared, TcpClient, add, lock};
use sadesim_engine::mavlink::frame::{FrameParser, whole_frame_len};

pub(super) fn is_timeout(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted)
}

/// The drone-side thread: registration heartbeats and telemetry to the ground stations,
/// gathered into shared datagrams ([`Gathered`]).
pub(super) fn drone_side(shared: &Shared) {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut sequence: u8 = 0;
    let mut next_heartbeat = Instant::now();
    let mut gathered = Gathered::default();
    // The drone socket's read timeout as last set.
    let mut read_timeout = POLL;
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
            Ok((n, from)) => {
                if let Some(frames) = shared.drone_frames(&buf[..n], from) {
                    gathered.add(shared, &frames);
                }
                if gathered.is_due() {
                    gathered.send(shared);
                }
            }
            Err(e) if is_timeout(&e) => gathered.send(shared),
            // E.g. an ICMP port-unreachable reported on a later call (Windows): keep
            // serving, without spinning should the error persist.
            Err(_) => {
                gathered.send(shared);
                std::thread::sleep(POLL);
            }
        }
        // While frames wait, the next read waits only GATHER_GAP for more.
        let timeout = if gathered.is_empty() { POLL } else { GATHER_GAP };
        if read_timeout != timeout && shared.drone_socket.set_read_timeout(Some(timeout)).is_ok() {
            read_timeout = timeout;
        }
        // A socket whose timeout cannot be shortened would hold frames for POLL: send now.
        if read_timeout != GATHER_GAP {
            gathered.send(shared);
        }
    }
    gathered.send(shared);
}

/// Frames for the ground stations from datagrams that arrived together (see
/// [`GATHER_GAP`]), in arrival order; whole frames only, so a ground station's parser sees
/// the same frames as if each datagram had come on its own.
#[derive(Default)]
struct Gathered {
    bytes: Vec<u8>,
    /// When the oldest frame waiting arrived.
    since: Option<Instant>,
}

impl Gathered {
    fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Adds one datagram's frames (whole frames), sending what waits whenever the next
    /// frame would not fit in GCS_DATAGRAM bytes. A shard on this host sends datagrams of
    /// up to 16 KiB (`mavlink::uplink`); they are split here, at frame boundaries.
    fn add(&mut self, shared: &Shared, frames: &[u8]) {
        let mut rest = frames;
        while !rest.is_empty() {
            // Not a frame (cannot happen for checked frames): the rest goes as it came.
            let len = whole_frame_len(rest).unwrap_or(rest.len());
            if !self.bytes.is_empty() && self.bytes.len() + len > GCS_DATAGRAM {
                self.send(shared);
            }
            self.bytes.extend_from_slice(&rest[..len]);
            self.since.get_or_insert_with(Instant::now);
            rest = &rest[len..];
        }
    }

    /// Full, or the oldest frame has waited GATHER_MAX_WAIT.
    fn is_due(&self) -> bool {
        self.bytes.len() >= GCS_DATAGRAM || self.since.is_some_and(|t| t.elapsed() >= GATHER_MAX_WAIT)
    }

    fn send(&mut self, shared: &Shared) {
        if !self.bytes.is_empty() {
            shared.to_gcs(&self.bytes, None);
            self.bytes.clear();
        }
        self.since = None;
    }
}

/// The GCS UDP thread: learns ground stations and routes their frames.
pub(super) fn gcs_udp_side(shared: &Shared) {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut parser = FrameParser::new();
    while !shared.stopping() {
        // Every POLL at the latest: the sums of refused frames appear on time even when
        // the refusals have stopped.
        shared.report_refusals();
        match shared.gcs_udp.recv_from(&mut buf) {
            Ok((n, from)) => {
                parser.reset();
                let frames = shared.parse_gcs(&mut parser, &buf[..n], from, "datagram");
                // Only a sender of at least one valid frame (with signing: validly signed)
                // becomes a client, so a port scan or stray traffic does not subscribe to
                // the telemetry.
                // A newcomer while every place is held by a live client is refused.
                if !frames.is_empty() && shared.udp_gcs_heard(from, frames.len(), Instant::now()) {
                    shared.route_gcs_frames(&frames, GcsOrigin::Udp(from));
                }
            }
            Err(e) if is_timeout(&e) => {}
            Err(_) => std::thread::sleep(POLL),
        }
    }
}

/// The TCP accept thread.
pub(super) fn accept_tcp(shared: &Arc<Shared>, listener: &TcpListener) {
    while !shared.stopping() {
        match listener.accept() {
            // A client that cannot be set up is simply not served.
            Ok((stream, peer)) => {
                let _ = add_tcp_client(shared, stream, peer);
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

pub(super) fn add_tcp_client(shared: &Arc<Shared>, stream: TcpStream, peer: SocketAddr) -> io::Result<()> {
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
    let reader = spawn(format!("router-tcp-{id}-in"), move || tcp_reader(&s, stream, peer, id, &c));
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

/// Reads one TCP ground station's stream (from `peer`) and routes its frames.
pub(super) fn tcp_reader(shared: &Shared, mut stream: TcpStream, peer: SocketAddr, id: u64, closed: &AtomicBool) {
    let mut parser = FrameParser::new();
    let mut buf = vec![0u8; 16 * 1024];
    while !shared.stopping() && !closed.load(Ordering::Relaxed) {
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                let frames = shared.parse_gcs(&mut parser, &buf[..n], peer, "TCP read");
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
pub(super) fn tcp_writer(shared: &Shared, mut stream: TcpStream, outgoing: &Receiver<Arc<[u8]>>, closed: &AtomicBool) {
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
