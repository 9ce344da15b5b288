//! `sadesim bench --ground-stations`: one UDP ground station per MAVLink router, as
//! QGroundControl connects, so the benchmark pays for the telemetry's delivery too.
//!
//! Without a ground station a router does not register with the drones (a router nobody
//! listens to costs them nothing), so each drone's telemetry is built and encoded but only
//! its 1 Hz heartbeat leaves the shard. With one, every drone's telemetry goes to its router
//! and on to the ground station (in shared datagrams, docs/architecture.md), as in a run a
//! ground station or a pilot watches.
//!
//! Each station sends a GCS HEARTBEAT to its router's GCS UDP port once a second (which makes
//! it a client, and the router register with the drones) and reads everything that arrives,
//! counting datagrams, bytes and frames. It runs on a thread of this process, so its reads
//! are in the benchmark's CPU time (on a real deployment the ground station is elsewhere).

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sadesim_crds::plan::RunPlan;

/// The system id the ground stations use (QGroundControl's default).
const GCS_SYSTEM_ID: u8 = 255;
/// How long a read waits before the thread checks whether to stop or send a heartbeat.
const READ_TIMEOUT: Duration = Duration::from_millis(100);
/// Once a second, as QGroundControl does.
const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

/// What the ground stations received over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Received {
    pub datagrams: u64,
    pub bytes: u64,
    /// MAVLink 2 frames (counted by their start byte and length, not checksummed).
    pub frames: u64,
}

/// One ground station per router segment of a run, reading until [`GroundStations::stop`].
#[derive(Debug)]
pub struct GroundStations {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<std::io::Result<Received>>>,
}

impl GroundStations {
    /// Starts a station for each of `plan`'s router segments, at 127.0.0.1 on the segment's
    /// GCS UDP port. The routers need not be up yet: heartbeats go out once a second until
    /// the stop.
    ///
    /// # Errors
    /// A socket that cannot be opened.
    pub fn start(plan: &RunPlan) -> std::io::Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let mut threads = Vec::new();
        for segment in &plan.segments {
            let router = SocketAddr::from(([127, 0, 0, 1], segment.gcs_udp));
            let socket = UdpSocket::bind("127.0.0.1:0")?;
            socket.set_read_timeout(Some(READ_TIMEOUT))?;
            let stop = stop.clone();
            threads.push(std::thread::spawn(move || listen(&socket, router, &stop)));
        }
        Ok(Self { stop, threads })
    }

    /// Stops every station and adds up what they received.
    ///
    /// # Errors
    /// A station whose socket failed.
    pub fn stop(self) -> std::io::Result<Received> {
        self.stop.store(true, Ordering::Relaxed);
        let mut total = Received::default();
        for thread in self.threads {
            let r = thread.join().map_err(|_| std::io::Error::other("a ground station thread panicked"))??;
            total.datagrams += r.datagrams;
            total.bytes += r.bytes;
            total.frames += r.frames;
        }
        Ok(total)
    }
}

fn listen(socket: &UdpSocket, router: SocketAddr, stop: &AtomicBool) -> std::io::Result<Received> {
    let mut received = Received::default();
    let mut buf = vec![0u8; 65_536];
    let mut sequence = 0u8;
    let mut next_heartbeat = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        if Instant::now() >= next_heartbeat {
            // Refused while the router is not up yet: the next one goes a second later.
            let _ = socket.send_to(&gcs_heartbeat(sequence), router);
            sequence = sequence.wrapping_add(1);
            next_heartbeat += HEARTBEAT_PERIOD;
        }
        match socket.recv_from(&mut buf) {
            Ok((n, _)) => {
                received.datagrams += 1;
                received.bytes += n as u64;
                received.frames += count_frames(&buf[..n]);
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            // An ICMP "port unreachable" for a heartbeat sent before the router was up.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
            Err(e) => return Err(e),
        }
    }
    Ok(received)
}

/// MAVLink 2 frames in a datagram of whole frames: each is a 0xFD start byte, a header
/// whose second byte is the payload length, the payload and the 2-byte checksum (the
/// drones' frames are unsigned).
fn count_frames(datagram: &[u8]) -> u64 {
    let mut at = 0;
    let mut frames = 0;
    while at + 1 < datagram.len() && datagram[at] == 0xFD {
        let signed = datagram.get(at + 2).is_some_and(|flags| flags & 1 == 1);
        at += 12 + usize::from(datagram[at + 1]) + if signed { 13 } else { 0 };
        frames += 1;
    }
    frames
}

/// A MAVLink 2 HEARTBEAT from a ground station (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID), as
/// QGroundControl sends it.
fn gcs_heartbeat(sequence: u8) -> Vec<u8> {
    const HEARTBEAT_CRC_EXTRA: u8 = 50;
    // custom_mode u32, type (6: GCS), autopilot (8: invalid), base_mode, system_status,
    // mavlink_version (3); the last byte is not zero, so nothing is truncated.
    let payload = [0, 0, 0, 0, 6, 8, 0, 0, 3];
    let mut frame = vec![0xFD, payload.len() as u8, 0, 0, sequence, GCS_SYSTEM_ID, 190, 0, 0, 0];
    frame.extend_from_slice(&payload);
    let crc = sadesim_engine::mavlink::frame::checksum(&frame[1..], HEARTBEAT_CRC_EXTRA);
    frame.extend_from_slice(&crc.to_le_bytes());
    frame
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_heartbeat_is_a_frame_the_routers_parser_takes_from_a_ground_station() {
        let mut parser = sadesim_engine::mavlink::frame::FrameParser::new();
        let frames = parser.push(&gcs_heartbeat(7));
        assert_eq!(frames.len(), 1, "{frames:?}");
        let (h, id) = (frames[0].header, frames[0].message_id);
        assert_eq!((h.system_id, h.component_id, h.sequence, id), (255, 190, 7, 0));
        assert!(matches!(frames[0].message, sadesim_engine::mavlink::frame::Decoded::Message(_)), "decoded");
        assert_eq!(count_frames(&gcs_heartbeat(0)), 1);
    }

    #[test]
    fn frames_are_counted_by_their_lengths() {
        let two: Vec<u8> = [gcs_heartbeat(1), gcs_heartbeat(2)].concat();
        assert_eq!(count_frames(&two), 2);
        assert_eq!(count_frames(&[]), 0);
        assert_eq!(count_frames(&[0x55, 0xFD]), 0, "not a frame start");
    }
}
