//! One drone's MAVLink link: a UDP socket to the drone's endpoint (`udpout://host:port` in
//! the fleet file), our heartbeat once a second, the drone's telemetry folded into a
//! [`Telemetry`] snapshot, and commands, parameters and mission clearing with their
//! acknowledgements.
//!
//! The endpoint answers whoever spoke to it last, so we speak first (a HEARTBEAT as an
//! onboard controller) and keep doing so: a peer silent for 5 s is forgotten. Timeouts
//! here are wall-clock on purpose: they bound how long a socket waits for an answer, which
//! the simulator gives within one of its I/O periods whatever the clock's speed. Flight
//! timing is the drone's clock ([`Telemetry::time_s`]), in `flight`.

use std::collections::VecDeque;
use std::io::ErrorKind;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use mavlink::dialects::common::*;
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MavlinkVersion, Message};

/// Our MAVLink system id: 255, the ground-station id PX4 expects commands from.
pub const OUR_SYSTEM_ID: u8 = 255;
/// Our component: MAV_COMP_ID_ONBOARD_COMPUTER (the pilot is the drone's companion program).
pub const OUR_COMPONENT_ID: u8 = 191;
/// How often we heartbeat (wall clock): well inside the endpoint's 5 s peer timeout.
const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);
/// Longest wait for one datagram in [`Link::pump`].
const RECV_WAIT: Duration = Duration::from_millis(20);
/// Wait for a COMMAND_ACK, PARAM_VALUE or MISSION_ACK before sending again.
const ACK_WAIT: Duration = Duration::from_millis(1500);
/// Sends of one command before giving up.
const SENDS: u32 = 5;
/// How long a drone's host name may take to resolve. On Kubernetes the drones are reached
/// through the shards' DNS names, which cluster DNS serves a few seconds after the shard pod
/// has its address (and answers "no such name" until then, cached for seconds).
const RESOLVE_WAIT: Duration = Duration::from_secs(30);
const RESOLVE_RETRY: Duration = Duration::from_millis(500);
/// MAVLink 2 start marker; frame overhead: STX, 9 header bytes, 2 checksum bytes.
const STX_V2: u8 = 0xFD;
const OVERHEAD: usize = 12;
const SIGNATURE_LEN: usize = 13;

/// A global position estimate from GLOBAL_POSITION_INT.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    /// Height above home, metres (downtown is flat: about the height above ground).
    pub relative_alt_m: f64,
}

/// What the drone last told us.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// The drone's clock: sim seconds since the run started (`time_boot_ms`).
    pub time_s: Option<f64>,
    pub position: Option<Fix>,
    /// A HEARTBEAT arrived.
    pub heartbeat: bool,
    pub armed: bool,
    /// PX4 custom mode of the last HEARTBEAT (`main << 16 | sub << 24`).
    pub custom_mode: u32,
    pub landed_state: Option<MavLandedState>,
    /// Remaining battery charge, 0..1 (BATTERY_STATUS or SYS_STATUS).
    pub battery_remaining: Option<f64>,
    /// GPS_RAW_INT reports a 3D fix or better.
    pub gps_3d_fix: bool,
    /// HOME_POSITION arrived.
    pub home_set: bool,
}

impl Telemetry {
    /// Folds one message in.
    pub fn update(&mut self, msg: &MavMessage) {
        let mut clock = |ms: u32| {
            let t = f64::from(ms) / 1000.0;
            self.time_s = Some(self.time_s.map_or(t, |old| old.max(t)));
        };
        match msg {
            MavMessage::GLOBAL_POSITION_INT(p) => {
                clock(p.time_boot_ms);
                self.position = Some(Fix {
                    latitude_deg: f64::from(p.lat) * 1e-7,
                    longitude_deg: f64::from(p.lon) * 1e-7,
                    relative_alt_m: f64::from(p.relative_alt) / 1000.0,
                });
            }
            MavMessage::SYSTEM_TIME(t) => clock(t.time_boot_ms),
            MavMessage::ATTITUDE(a) => clock(a.time_boot_ms),
            MavMessage::HEARTBEAT(h) => {
                self.heartbeat = true;
                self.armed = h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                self.custom_mode = h.custom_mode;
            }
            MavMessage::EXTENDED_SYS_STATE(s) => self.landed_state = Some(s.landed_state),
            MavMessage::BATTERY_STATUS(b) if b.battery_remaining >= 0 => {
                self.battery_remaining = Some(f64::from(b.battery_remaining) / 100.0);
            }
            MavMessage::SYS_STATUS(s) if s.battery_remaining >= 0 => {
                self.battery_remaining = Some(f64::from(s.battery_remaining) / 100.0);
            }
            MavMessage::GPS_RAW_INT(g) => {
                self.gps_3d_fix = matches!(
                    g.fix_type,
                    GpsFixType::GPS_FIX_TYPE_3D_FIX
                        | GpsFixType::GPS_FIX_TYPE_DGPS
                        | GpsFixType::GPS_FIX_TYPE_RTK_FLOAT
                        | GpsFixType::GPS_FIX_TYPE_RTK_FIXED
                );
            }
            MavMessage::HOME_POSITION(_) => self.home_set = true,
            _ => {}
        }
    }

    /// On the ground and disarmed.
    pub fn landed_and_disarmed(&self) -> bool {
        !self.armed && self.landed_state == Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND)
    }
}

/// A link operation that failed.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("bad MAVLink URL {url:?}: {problem}")]
    Url { url: String, problem: String },
    #[error("MAVLink socket: {0}")]
    Io(#[from] std::io::Error),
    /// The drone never acknowledged (it is gone, or the run ended).
    #[error("no {what} from the drone after {sends} sends")]
    NoAnswer { what: String, sends: u32 },
    /// A PARAM_SET answered with another value (out of range, read-only).
    #[error("parameter {name} was not set: the drone keeps {kept}")]
    ParamRefused { name: String, kept: f32 },
    #[error("mission clear refused: {0:?}")]
    MissionRefused(MavMissionResult),
}

/// The link to one drone.
#[derive(Debug)]
pub struct Link {
    socket: UdpSocket,
    /// The drone's system and component id.
    target: (u8, u8),
    sequence: u8,
    next_heartbeat: Instant,
    last_heard: Instant,
    pub telemetry: Telemetry,
    acks: VecDeque<COMMAND_ACK_DATA>,
    params: VecDeque<(String, f32)>,
    mission_acks: VecDeque<MavMissionResult>,
    /// STATUSTEXT lines (severity, text) not yet taken by the caller.
    pub status_texts: VecDeque<(MavSeverity, String)>,
}

/// `host:port` of a `udpout://host:port` (or `udp://`) URL.
///
/// # Errors
/// Another scheme or no port.
pub fn udp_address(url: &str) -> Result<String, LinkError> {
    let bad = |problem: &str| LinkError::Url { url: url.to_owned(), problem: problem.to_owned() };
    let rest = url
        .strip_prefix("udpout://")
        .or_else(|| url.strip_prefix("udp://"))
        .ok_or_else(|| bad("expected udpout://host:port (the fleet file's mavlink.udp)"))?;
    match rest.rsplit_once(':') {
        Some((host, port)) if !host.is_empty() && port.parse::<u16>().is_ok() => Ok(rest.to_owned()),
        _ => Err(bad("expected host:port after the scheme")),
    }
}

/// The first address of `host:port`, asking again until it resolves or `wait` has passed.
///
/// # Errors
/// The last resolver error (or "no address") after `wait`.
pub fn resolve(address: &str, wait: Duration) -> std::io::Result<SocketAddr> {
    retry_lookup(|| address.to_socket_addrs().map(|mut a| a.next()), wait, RESOLVE_RETRY)
        .map_err(|e| std::io::Error::other(format!("{address} did not resolve within {} s: {e}", wait.as_secs())))
}

/// Calls `lookup` every `every` until it gives an address or `wait` has passed.
fn retry_lookup(
    mut lookup: impl FnMut() -> std::io::Result<Option<SocketAddr>>,
    wait: Duration,
    every: Duration,
) -> std::io::Result<SocketAddr> {
    let deadline = Instant::now() + wait;
    loop {
        let error = match lookup() {
            Ok(Some(peer)) => return Ok(peer),
            Ok(None) => std::io::Error::other("the host resolves to no address"),
            Err(e) => e,
        };
        if Instant::now() >= deadline {
            return Err(error);
        }
        std::thread::sleep(every);
    }
}

impl Link {
    /// Opens a socket to the drone at `url` (system `system_id`, component `component_id`)
    /// and says hello.
    ///
    /// # Errors
    /// Bad URL, a host that does not resolve within [`RESOLVE_WAIT`], socket errors.
    pub fn open(url: &str, system_id: u8, component_id: u8) -> Result<Self, LinkError> {
        let peer = resolve(&udp_address(url)?, RESOLVE_WAIT)
            .map_err(|e| LinkError::Url { url: url.to_owned(), problem: e.to_string() })?;
        let local = if peer.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" };
        let socket = UdpSocket::bind(local)?;
        socket.connect(peer)?;
        socket.set_read_timeout(Some(RECV_WAIT))?;
        let now = Instant::now();
        let mut link = Self {
            socket,
            target: (system_id, component_id),
            sequence: 0,
            next_heartbeat: now,
            last_heard: now,
            telemetry: Telemetry::default(),
            acks: VecDeque::new(),
            params: VecDeque::new(),
            mission_acks: VecDeque::new(),
            status_texts: VecDeque::new(),
        };
        link.heartbeat_if_due()?;
        Ok(link)
    }

    /// Wall time since the drone last sent anything.
    pub fn silent_for(&self) -> Duration {
        self.last_heard.elapsed()
    }

    /// Heartbeats when due, then reads what has arrived (waiting up to 20 ms for the first
    /// datagram) and folds it into the telemetry and the answer queues.
    ///
    /// # Errors
    /// Socket errors other than timeouts and ICMP refusals (a drone not up yet).
    pub fn pump(&mut self) -> Result<(), LinkError> {
        self.heartbeat_if_due()?;
        let mut buf = [0u8; 65_536];
        let started = Instant::now();
        while started.elapsed() < Duration::from_millis(50) {
            match self.socket.recv(&mut buf) {
                Ok(n) => {
                    for (header, msg) in decode_datagram(&buf[..n]) {
                        if header.system_id == u32::from(self.target.0) {
                            self.last_heard = Instant::now();
                            self.take(msg);
                        }
                    }
                }
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => break,
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => break,
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }

    fn take(&mut self, msg: MavMessage) {
        self.telemetry.update(&msg);
        match msg {
            MavMessage::COMMAND_ACK(a) => push_bounded(&mut self.acks, a),
            MavMessage::PARAM_VALUE(p) => {
                let name = p.param_id.to_str().unwrap_or_default().trim_end_matches('\0').to_owned();
                push_bounded(&mut self.params, (name, p.param_value));
            }
            MavMessage::MISSION_ACK(a) => push_bounded(&mut self.mission_acks, a.mavtype),
            MavMessage::STATUSTEXT(t) => {
                let text = String::from_utf8_lossy(&t.text[..]).trim_end_matches('\0').to_owned();
                push_bounded(&mut self.status_texts, (t.severity, text));
            }
            _ => {}
        }
    }

    fn heartbeat_if_due(&mut self) -> Result<(), LinkError> {
        if Instant::now() < self.next_heartbeat {
            return Ok(());
        }
        self.next_heartbeat = Instant::now() + HEARTBEAT_PERIOD;
        self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }))
    }

    /// Sends one message from us.
    ///
    /// # Errors
    /// Socket errors (a refused datagram is not one: the drone may not be listening yet).
    pub fn send(&mut self, msg: &MavMessage) -> Result<(), LinkError> {
        let header =
            MavHeader { system_id: u32::from(OUR_SYSTEM_ID), component_id: OUR_COMPONENT_ID, sequence: self.sequence };
        self.sequence = self.sequence.wrapping_add(1);
        match self.socket.send(&encode(header, msg)) {
            Ok(_) => Ok(()),
            Err(e) if e.kind() == ErrorKind::ConnectionRefused => Ok(()),
            Err(e) => Err(e.into()),
        }
    }

    /// COMMAND_LONG, sent until acknowledged; the ack's result.
    ///
    /// # Errors
    /// No acknowledgement after [`SENDS`] sends, socket errors.
    pub fn command_long(&mut self, command: MavCmd, params: [f32; 7]) -> Result<MavResult, LinkError> {
        let (target_system, target_component) = self.target;
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: params[0],
            param2: params[1],
            param3: params[2],
            param4: params[3],
            param5: params[4],
            param6: params[5],
            param7: params[6],
            command,
            target_system,
            target_component,
            confirmation: 0,
        });
        self.until_acked(command, &msg)
    }

    /// COMMAND_INT with a position (`x`, `y` in 1e-7 degrees, `z` in `frame`'s metres),
    /// sent until acknowledged; the ack's result.
    ///
    /// # Errors
    /// As [`Link::command_long`].
    pub fn command_int(
        &mut self,
        command: MavCmd,
        frame: MavFrame,
        params: [f32; 4],
        position: (i32, i32, f32),
    ) -> Result<MavResult, LinkError> {
        let (target_system, target_component) = self.target;
        let msg = MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            param1: params[0],
            param2: params[1],
            param3: params[2],
            param4: params[3],
            x: position.0,
            y: position.1,
            z: position.2,
            command,
            target_system,
            target_component,
            frame,
            current: 0,
            autocontinue: 0,
        });
        self.until_acked(command, &msg)
    }

    fn until_acked(&mut self, command: MavCmd, msg: &MavMessage) -> Result<MavResult, LinkError> {
        self.acks.clear();
        for _ in 0..SENDS {
            self.send(msg)?;
            let deadline = Instant::now() + ACK_WAIT;
            while Instant::now() < deadline {
                self.pump()?;
                if let Some(i) = self.acks.iter().position(|a| a.command == command) {
                    let ack = self.acks.remove(i).expect("index from position");
                    if ack.result != MavResult::MAV_RESULT_IN_PROGRESS {
                        return Ok(ack.result);
                    }
                }
            }
        }
        Err(LinkError::NoAnswer { what: format!("COMMAND_ACK for {command:?}"), sends: SENDS })
    }

    /// PARAM_SET of a REAL32 parameter, sent until the drone echoes the value.
    ///
    /// # Errors
    /// No PARAM_VALUE, or the drone kept another value.
    pub fn set_param(&mut self, name: &str, value: f32) -> Result<(), LinkError> {
        let (target_system, target_component) = self.target;
        let msg = MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system,
            target_component,
            param_id: name.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        });
        self.params.clear();
        for _ in 0..SENDS {
            self.send(&msg)?;
            let deadline = Instant::now() + ACK_WAIT;
            while Instant::now() < deadline {
                self.pump()?;
                if let Some(&(_, kept)) = self.params.iter().find(|(n, _)| n == name) {
                    if (kept - value).abs() <= 1e-4 * value.abs().max(1.0) {
                        return Ok(());
                    }
                    return Err(LinkError::ParamRefused { name: name.to_owned(), kept });
                }
            }
        }
        Err(LinkError::NoAnswer { what: format!("PARAM_VALUE for {name}"), sends: SENDS })
    }

    /// MISSION_CLEAR_ALL, sent until the drone answers MISSION_ACK. (PX4 then flies
    /// go-tos at MPC_XY_CRUISE.)
    ///
    /// # Errors
    /// No answer, or a refusal.
    pub fn clear_mission(&mut self) -> Result<(), LinkError> {
        let (target_system, target_component) = self.target;
        let msg = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system,
            target_component,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        });
        self.mission_acks.clear();
        for _ in 0..SENDS {
            self.send(&msg)?;
            let deadline = Instant::now() + ACK_WAIT;
            while Instant::now() < deadline {
                self.pump()?;
                if let Some(result) = self.mission_acks.pop_front() {
                    return match result {
                        MavMissionResult::MAV_MISSION_ACCEPTED => Ok(()),
                        other => Err(LinkError::MissionRefused(other)),
                    };
                }
            }
        }
        Err(LinkError::NoAnswer { what: "MISSION_ACK".into(), sends: SENDS })
    }
}

/// Keeps at most 64 unanswered items (answers nobody waits for must not pile up).
fn push_bounded<T>(queue: &mut VecDeque<T>, item: T) {
    if queue.len() >= 64 {
        queue.pop_front();
    }
    queue.push_back(item);
}

/// One MAVLink 2 frame of `msg` from `header` (unsigned).
pub fn encode(header: MavHeader, msg: &MavMessage) -> Vec<u8> {
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(header, msg);
    raw.raw_bytes().to_vec()
}

/// Every MAVLink 2 frame with a good checksum in one datagram, decoded. Bytes that do not
/// start a frame, frames with a bad checksum and messages outside the common dialect are
/// skipped; MAVLink 1 frames too (the drones speak MAVLink 2).
pub fn decode_datagram(bytes: &[u8]) -> Vec<(MavHeader, MavMessage)> {
    let mut out = Vec::new();
    let mut at = 0;
    while at + OVERHEAD <= bytes.len() {
        if bytes[at] != STX_V2 {
            at += 1;
            continue;
        }
        let len = usize::from(bytes[at + 1]);
        let signed = bytes[at + 2] & 0x01 != 0;
        let total = OVERHEAD + len + if signed { SIGNATURE_LEN } else { 0 };
        if at + total > bytes.len() {
            at += 1;
            continue;
        }
        let frame = &bytes[at..at + total];
        let id = u32::from(frame[7]) | u32::from(frame[8]) << 8 | u32::from(frame[9]) << 16;
        let crc_at = 10 + len;
        let crc = u16::from_le_bytes([frame[crc_at], frame[crc_at + 1]]);
        if mavlink::calculate_crc(&frame[1..crc_at], MavMessage::extra_crc(id)) != crc {
            at += 1; // not a frame after all: resynchronise on the next byte
            continue;
        }
        if let Ok(msg) = MavMessage::parse(MavlinkVersion::V2, id, &frame[10..crc_at]) {
            let header = MavHeader { sequence: frame[4], system_id: u32::from(frame[5]), component_id: frame[6] };
            out.push((header, msg));
        }
        at += total;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(system_id: u32) -> MavHeader {
        MavHeader { system_id, component_id: 1, sequence: 7 }
    }

    fn position(time_boot_ms: u32, relative_alt_mm: i32) -> MavMessage {
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms,
            lat: 418_796_000,
            lon: -876_237_000,
            alt: 295_300,
            relative_alt: relative_alt_mm,
            vx: 0,
            vy: 0,
            vz: 0,
            hdg: 0,
        })
    }

    #[test]
    fn frames_round_trip_and_several_share_a_datagram() {
        let mut datagram = encode(header(3), &position(12_345, 114_300));
        datagram.extend(b"junk");
        datagram.extend(encode(
            header(3),
            &MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA { time_unix_usec: 1, time_boot_ms: 12_400 }),
        ));
        let frames = decode_datagram(&datagram);
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].0.system_id, 3);
        assert_eq!(frames[0].1, position(12_345, 114_300));
        let mut t = Telemetry::default();
        for (_, m) in &frames {
            t.update(m);
        }
        assert_eq!(t.time_s, Some(12.4));
        let fix = t.position.unwrap();
        assert!((fix.relative_alt_m - 114.3).abs() < 1e-9 && (fix.latitude_deg - 41.8796).abs() < 1e-9);
    }

    #[test]
    fn corrupted_or_cut_frames_are_skipped() {
        let good = encode(header(1), &position(1000, 0));
        let mut bad = good.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0xFF; // checksum
        assert!(decode_datagram(&bad).is_empty());
        assert!(decode_datagram(&good[..good.len() - 3]).is_empty());
        let mut both = bad;
        both.extend(&good);
        assert_eq!(decode_datagram(&both).len(), 1, "resynchronises after a bad frame");
    }

    #[test]
    fn telemetry_tracks_arming_landing_battery_and_the_clock_only_forward() {
        let mut t = Telemetry::default();
        t.update(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 4 << 16 | 3 << 24,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }));
        t.update(&MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
            landed_state: MavLandedState::MAV_LANDED_STATE_ON_GROUND,
        }));
        assert!(t.armed && !t.landed_and_disarmed(), "armed on the ground is not done");
        let battery = BATTERY_STATUS_DATA { battery_remaining: 42, ..BATTERY_STATUS_DATA::default() };
        t.update(&MavMessage::BATTERY_STATUS(battery));
        assert_eq!(t.battery_remaining, Some(0.42));
        t.update(&position(5000, 0));
        t.update(&position(4000, 0)); // a late datagram must not turn the clock back
        assert_eq!(t.time_s, Some(5.0));
    }

    #[test]
    fn udp_urls_need_the_udpout_scheme_and_a_port() {
        assert_eq!(udp_address("udpout://127.0.0.1:24600").unwrap(), "127.0.0.1:24600");
        assert!(udp_address("udpin://0.0.0.0:14540").is_err());
        assert!(udp_address("udpout://127.0.0.1").is_err());
    }

    #[test]
    fn a_name_that_resolves_late_is_asked_again_until_the_wait_ends() {
        // Cluster DNS answers "no such name" until the shard pod has its address.
        let peer: SocketAddr = "10.244.0.7:24600".parse().unwrap();
        let mut asked = 0;
        let late = retry_lookup(
            || {
                asked += 1;
                if asked < 3 {
                    Err(std::io::Error::other("Temporary failure in name resolution"))
                } else {
                    Ok(Some(peer))
                }
            },
            Duration::from_secs(10),
            Duration::from_millis(1),
        );
        assert_eq!(late.unwrap(), peer);
        assert_eq!(asked, 3);
        // Never: the last error, once the wait is over.
        let never = retry_lookup(|| Ok(None), Duration::ZERO, Duration::from_millis(1)).unwrap_err();
        assert!(never.to_string().contains("no address"), "{never}");
        let named = resolve("127.0.0.1:24600", Duration::ZERO).unwrap();
        assert_eq!(named, "127.0.0.1:24600".parse().unwrap());
    }

    #[test]
    fn commands_are_resent_until_acknowledged() {
        // A fake drone that ignores the first COMMAND_LONG and acknowledges the second.
        let drone = UdpSocket::bind("127.0.0.1:0").unwrap();
        let url = format!("udpout://{}", drone.local_addr().unwrap());
        let fake = std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            let mut commands = 0;
            loop {
                let (n, from) = drone.recv_from(&mut buf).unwrap();
                for (_, m) in decode_datagram(&buf[..n]) {
                    if let MavMessage::COMMAND_LONG(c) = m {
                        commands += 1;
                        if commands == 2 {
                            let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                                command: c.command,
                                result: MavResult::MAV_RESULT_ACCEPTED,
                                ..COMMAND_ACK_DATA::default()
                            });
                            drone.send_to(&encode(header(9), &ack), from).unwrap();
                            return commands;
                        }
                    }
                }
            }
        });
        let mut link = Link::open(&url, 9, 1).unwrap();
        let result = link.command_long(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]).unwrap();
        assert_eq!(result, MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(fake.join().unwrap(), 2);
    }
}
