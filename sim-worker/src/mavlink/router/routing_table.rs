//! The state every router thread shares: who the ground stations are, which drone a
//! system id is, and how a frame from either side is routed (byte for byte).

use std::borrow::Cow;
use std::collections::HashSet;
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Instant, SystemTime};

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType};

use super::config::{MAX_UDP_GCS, ROUTER_COMPONENT_ID, ROUTER_SYSTEM_ID, RoutedDrone, UDP_GCS_LIVENESS};
use super::gcs_signing::{GcsSigning, SETUP_SIGNING_ID};
use super::refusal_log::{Dropped, RefusalLog, describe_bad_bytes};
use sadesim_engine::mavlink::frame::{
    DatagramFrames, Decoded, Frame, FrameParser, FrameRef, ParseStats, encode, target_system,
};
use sadesim_engine::mavlink::signing::{Refusal, timestamp_at};

/// A poisoned lock only means another router thread panicked; the tables stay usable.
pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The UDP ground stations: at most [`MAX_UDP_GCS`], each keeping its place while it is
/// heard within [`UDP_GCS_LIVENESS`]. Time is passed in (tests choose it).
#[derive(Debug, Default)]
pub(super) struct PeerTable {
    /// (address, when last heard)
    pub(super) peers: Vec<(SocketAddr, Instant)>,
}

/// What [`PeerTable::heard`] did with a sender.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Heard {
    /// A client already: its place is renewed.
    Known,
    /// A new client, in a free place.
    Added,
    /// A new client, in the place of this one (silent for longer than [`UDP_GCS_LIVENESS`]).
    Replaced(SocketAddr),
    /// Not a client: every place is held by a live one.
    Refused,
}

impl PeerTable {
    /// A valid frame from `addr` at `now`.
    pub(super) fn heard(&mut self, addr: SocketAddr, now: Instant) -> Heard {
        if let Some(p) = self.peers.iter_mut().find(|p| p.0 == addr) {
            p.1 = now;
            return Heard::Known;
        }
        if self.peers.len() < MAX_UDP_GCS {
            self.peers.push((addr, now));
            return Heard::Added;
        }
        match self.peers.iter_mut().min_by_key(|p| p.1) {
            Some(oldest) if now.saturating_duration_since(oldest.1) > UDP_GCS_LIVENESS => {
                let gone = oldest.0;
                *oldest = (addr, now);
                Heard::Replaced(gone)
            }
            _ => Heard::Refused,
        }
    }
}

/// Who sent frames on the GCS side (they are not echoed back to it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GcsOrigin {
    Udp(SocketAddr),
    Tcp(u64),
}

/// A TCP ground station as the other threads see it.
#[derive(Debug)]
pub(super) struct TcpClient {
    pub(super) id: u64,
    pub(super) queue: SyncSender<Arc<[u8]>>,
    /// A handle for shutting the connection down from outside its threads.
    pub(super) stream: TcpStream,
    pub(super) closed: Arc<AtomicBool>,
}

impl TcpClient {
    pub(super) fn is_closed(&self) -> bool {
        self.closed.load(Ordering::Relaxed)
    }
}

#[derive(Debug, Default)]
pub(super) struct Counters {
    pub(super) frames_to_drones: AtomicU64,
    pub(super) datagrams_to_gcs: AtomicU64,
    pub(super) dropped_unknown_target: AtomicU64,
    pub(super) dropped_unknown_source: AtomicU64,
    pub(super) bad_checksum: AtomicU64,
    pub(super) garbage_bytes: AtomicU64,
    pub(super) dropped_gcs_backlog: AtomicU64,
    pub(super) refused_tcp_clients: AtomicU64,
    pub(super) refused_udp_gcs_frames: AtomicU64,
    pub(super) refused_unsigned: AtomicU64,
    pub(super) refused_bad_signature: AtomicU64,
    pub(super) refused_old_timestamp: AtomicU64,
}

pub(super) fn add(counter: &AtomicU64, n: u64) {
    if n > 0 {
        counter.fetch_add(n, Ordering::Relaxed);
    }
}

/// State every router thread reads.
#[derive(Debug)]
pub(super) struct Shared {
    pub(super) stop: AtomicBool,
    pub(super) drones: Vec<RoutedDrone>,
    /// Drone endpoints, to accept drone-side datagrams only from them.
    pub(super) endpoints: HashSet<SocketAddr>,
    /// System id -> index into `drones`.
    pub(super) index_of: Vec<Option<usize>>,
    pub(super) drone_socket: UdpSocket,
    pub(super) gcs_udp: UdpSocket,
    pub(super) udp_peers: Mutex<PeerTable>,
    pub(super) tcp_clients: Mutex<Vec<TcpClient>>,
    pub(super) tcp_threads: Mutex<Vec<JoinHandle<()>>>,
    pub(super) next_tcp_id: AtomicU64,
    pub(super) counters: Arc<Counters>,
    /// MAVLink 2 signing on the GCS side, when configured.
    pub(super) signing: Option<GcsSigning>,
    /// What was dropped from ground stations, for the log (signing refusals, garbage).
    pub(super) refusals: Mutex<RefusalLog>,
    /// The lines logged (tests read them; the router writes them to stderr).
    #[cfg(test)]
    pub(super) logged: Mutex<Vec<String>>,
}

impl Shared {
    pub(super) fn stopping(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Parses one datagram (or one TCP read) and counts what the parser threw away; returns
    /// the frames and what was thrown away.
    pub(super) fn parse(&self, parser: &mut FrameParser, bytes: &[u8]) -> (Vec<Frame>, ParseStats) {
        let before = parser.stats;
        let frames = parser.push(bytes);
        let skipped = ParseStats {
            bad_checksum: parser.stats.bad_checksum - before.bad_checksum,
            skipped_bytes: parser.stats.skipped_bytes - before.skipped_bytes,
            ..ParseStats::default()
        };
        self.count_skipped(&skipped);
        (frames, skipped)
    }

    /// Writes a line to the router's log (stderr).
    fn log(&self, line: String) {
        eprintln!("{line}");
        #[cfg(test)]
        lock(&self.logged).push(line);
    }

    /// Counts what a parse threw away: frames with a bad checksum, bytes of garbage.
    fn count_skipped(&self, stats: &ParseStats) {
        add(&self.counters.bad_checksum, stats.bad_checksum);
        add(&self.counters.garbage_bytes, stats.skipped_bytes);
    }

    /// Parses bytes from the ground station at `source` (`what`: "datagram" or "TCP read",
    /// for the log). Bytes that are not MAVLink and frames with a bad checksum are counted
    /// and logged (the first from an address at once, naming the offending byte). With
    /// signing, only the frames that pass the signature and replay checks are returned; the
    /// others (and MAVLink 1 frames) are counted and logged.
    pub(super) fn parse_gcs(
        &self,
        parser: &mut FrameParser,
        bytes: &[u8],
        source: SocketAddr,
        what: &str,
    ) -> Vec<Frame> {
        let mavlink1_before = parser.stats.mavlink1_frames;
        let (mut frames, skipped) = self.parse(parser, bytes);
        if skipped.skipped_bytes > 0 || skipped.bad_checksum > 0 {
            let now = Instant::now();
            let mut log = lock(&self.refusals);
            // A bad checksum first: the bytes of a corrupted frame also count as garbage.
            let garbage = [(Dropped::BadChecksum, skipped.bad_checksum), (Dropped::NotMavlink, skipped.skipped_bytes)];
            for (why, n) in garbage.into_iter().filter(|(_, n)| *n > 0) {
                if let Some(line) = log.refused(source, why, n, now, || describe_bad_bytes(bytes, what)) {
                    self.log(line);
                }
            }
        }
        let Some(signing) = &self.signing else { return frames };
        let mut refused: Vec<Refusal> =
            (mavlink1_before..parser.stats.mavlink1_frames).map(|_| Refusal::Mavlink1).collect();
        if !frames.is_empty() {
            let now = timestamp_at(SystemTime::now());
            let mut verifier = lock(&signing.verifier);
            frames.retain(|f| verifier.check(&f.bytes, now).map_err(|why| refused.push(why)).is_ok());
            // SETUP_SIGNING (QGroundControl's "send to vehicle") carries the secret key in
            // plain text: passed on, it would reach every ground station, including TCP
            // clients without the key. The run's key is the scenario's; nothing to set up.
            frames.retain(|f| f.message_id != SETUP_SIGNING_ID);
        }
        if refused.is_empty() {
            return frames;
        }
        let now = Instant::now();
        let mut log = lock(&self.refusals);
        for why in refused {
            let counter = match why {
                Refusal::Unsigned | Refusal::Mavlink1 => &self.counters.refused_unsigned,
                Refusal::BadSignature => &self.counters.refused_bad_signature,
                Refusal::OldTimestamp => &self.counters.refused_old_timestamp,
            };
            add(counter, 1);
            if let Some(line) = log.refused(source, Dropped::Signing(why), 1, now, String::new) {
                self.log(line);
            }
        }
        frames
    }

    /// `frames` valid frames (at least one) from the UDP ground station `from` at `now`:
    /// whether it is a client (its frames are routed). A newcomer while every place is live
    /// is refused: counted and logged (the first from an address at once, then summed).
    pub(super) fn udp_gcs_heard(&self, from: SocketAddr, frames: usize, now: Instant) -> bool {
        let heard = lock(&self.udp_peers).heard(from, now);
        match heard {
            Heard::Known | Heard::Added => true,
            Heard::Replaced(gone) => {
                let segment = lock(&self.refusals).segment();
                let silent = UDP_GCS_LIVENESS.as_secs();
                self.log(format!(
                    "MAVLink router, segment {segment}: UDP ground station {gone} silent for over {silent} s: its \
                     place goes to {from}"
                ));
                true
            }
            Heard::Refused => {
                let n = frames as u64;
                add(&self.counters.refused_udp_gcs_frames, n);
                if let Some(line) = lock(&self.refusals).refused(from, Dropped::NoPlace, n, now, String::new) {
                    self.log(line);
                }
                false
            }
        }
    }

    /// Logs the sums of refusals that are due (called often by the GCS UDP thread).
    pub(super) fn report_refusals(&self) {
        let lines = lock(&self.refusals).due(Instant::now());
        for line in lines {
            self.log(line);
        }
    }

    /// Whether any ground station would receive telemetry.
    pub(super) fn has_ground_stations(&self) -> bool {
        !lock(&self.udp_peers).peers.is_empty() || !lock(&self.tcp_clients).is_empty()
    }

    /// Sends the router's HEARTBEAT to every drone endpoint, which makes the endpoint send
    /// its telemetry here.
    pub(super) fn register_with_drones(&self, sequence: u8) {
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

    /// A datagram on the drone socket: what goes to every ground station, the datagram
    /// unchanged when it is clean (without signing), each frame signed (with signing);
    /// `None` for a datagram from a stranger or when no ground station listens.
    ///
    /// The frames are checked where they lie ([`DatagramFrames`]): a shard's datagram holds
    /// the frames of hundreds of drones, and copying each into a buffer of its own cost the
    /// router an allocation per frame.
    pub(super) fn drone_frames<'a>(&self, datagram: &'a [u8], from: SocketAddr) -> Option<Cow<'a, [u8]>> {
        if !self.endpoints.contains(&from) {
            add(&self.counters.dropped_unknown_source, 1);
            return None;
        }
        if !self.has_ground_stations() {
            return None; // nobody to forward to: not worth checking
        }
        let own = |f: &FrameRef<'_>| {
            f.header.system_id == u32::from(ROUTER_SYSTEM_ID) && f.header.component_id == ROUTER_COMPONENT_ID
        };
        let mut frames = DatagramFrames::new(datagram);
        let out: Cow<'_, [u8]> = if let Some(signing) = &self.signing {
            let now = timestamp_at(SystemTime::now());
            let mut signed = Vec::with_capacity(datagram.len() * 2);
            for f in frames.by_ref().filter(|f| !own(f)) {
                signing.signer.sign_into(&mut signed, f.bytes, now);
            }
            Cow::Owned(signed)
        } else {
            // Clean: nothing but good frames, none of them the router's own.
            let (mut covered, mut any_own) = (0, false);
            for f in frames.by_ref() {
                covered += f.bytes.len();
                any_own |= own(&f);
            }
            if covered == datagram.len() && !any_own {
                Cow::Borrowed(datagram)
            } else {
                let mut kept = Vec::with_capacity(covered);
                for f in DatagramFrames::new(datagram).filter(|f| !own(f)) {
                    kept.extend_from_slice(f.bytes);
                }
                Cow::Owned(kept)
            }
        };
        self.count_skipped(&frames.stats);
        (!out.is_empty()).then_some(out)
    }

    /// Sends `bytes` (whole frames) to every ground station except `origin`.
    pub(super) fn to_gcs(&self, bytes: &[u8], origin: Option<GcsOrigin>) {
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
    pub(super) fn route_gcs_frames(&self, frames: &[Frame], origin: GcsOrigin) {
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
pub(super) fn destination(frame: &Frame) -> Option<u8> {
    match &frame.message {
        Decoded::Message(m) => target_system(m),
        Decoded::UnknownCommand { target_system, .. } => Some(*target_system),
        Decoded::Undecodable(_) => None,
    }
}
