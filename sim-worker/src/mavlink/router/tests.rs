//! The router against real sockets on loopback.

use std::collections::BTreeSet;
use std::thread;

use ::mavlink::dialects::common::{ATTITUDE_DATA, COMMAND_LONG_DATA, MavCmd, SETUP_SIGNING_DATA};

use super::config::{
    HEARTBEAT_PERIOD, MAX_DATAGRAM, MAX_UDP_GCS, ROUTER_SYSTEM_ID, RoutedDrone, RouterConfig, RouterError,
    UDP_GCS_LIVENESS,
};
use super::handle::{RouterHandle, start};
use super::routing_table::{Heard, PeerTable};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType};

use sadesim_engine::mavlink::frame::{Decoded, Frame, FrameParser, encode};
use sadesim_engine::mavlink::signing::{IFLAG_SIGNED, Refusal, SecretKey, Signer, Verifier, timestamp_at};

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
    fleet_signing(n, None)
}

/// `n` fake drones behind a router that signs on the GCS side when given a key.
fn fleet_signing(n: u8, signing: Option<SecretKey>) -> (Vec<FakeDrone>, RouterHandle) {
    let drones: Vec<FakeDrone> = (1..=n).map(FakeDrone::start).collect();
    let router = router_for(drones.iter().map(|d| d.addr), signing);
    (drones, router)
}

/// A router on free ports for drones at `endpoints`, system ids 1, 2, ... in that order.
fn router_for(endpoints: impl Iterator<Item = SocketAddr>, signing: Option<SecretKey>) -> RouterHandle {
    let config = RouterConfig {
        segment: 0,
        gcs_udp: "127.0.0.1:0".parse().unwrap(),
        gcs_tcp: "127.0.0.1:0".parse().unwrap(),
        drones: endpoints.enumerate().map(|(i, endpoint)| RoutedDrone { system_id: i as u8 + 1, endpoint }).collect(),
        signing,
    };
    start(config).unwrap()
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
    assert!(frames.iter().all(|f| f.bytes[2] & IFLAG_SIGNED == 0), "without a key nothing is signed");
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
    // The TCP GCS's single heartbeat reaches only the UDP ground stations registered by
    // then: wait for the UDP one (a loaded machine may read the TCP stream first).
    wait_for("the UDP client registered", || (router.stats().gcs_udp_clients == 1).then_some(()));
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
    // Logged once per address, naming the address and what was wrong; the rest is summed.
    let logged = router.shared.as_ref().unwrap().logged.lock().unwrap().clone();
    let udp_addr = udp.local_addr().unwrap().to_string();
    let about = |who: &str| logged.iter().filter(|l| l.contains(&format!("from {who}"))).cloned().collect::<Vec<_>>();
    let udp_lines = about(&udp_addr);
    assert_eq!(udp_lines.len(), 1, "{logged:?}");
    assert!(
        udp_lines[0].contains(&format!(
            "dropped 1 frame(s) from {udp_addr}: at byte 0 of a {}-byte datagram, a MAVLink 2 frame (message id 76, \
             {} bytes) whose checksum does not match; further refusals from {udp_addr} are summed up every 10 s",
            bad.len(),
            bad.len()
        )),
        "{udp_lines:?}"
    );
    let tcp_addr = tcp.local_addr().unwrap().to_string();
    let tcp_lines = about(&tcp_addr);
    assert_eq!(tcp_lines.len(), 1, "{logged:?}");
    assert!(tcp_lines[0].contains(&format!("from {tcp_addr}")) && tcp_lines[0].contains("TCP read"), "{tcp_lines:?}");
}

/// A ground station that sends nothing but garbage, as fast as it can: every byte is
/// counted, one line names it, and a well-behaved ground station beside it is served.
#[test]
fn a_gcs_spewing_garbage_is_logged_once_and_the_others_are_served() {
    let (drones, router) = fleet(2);
    let hostile = UdpSocket::bind("127.0.0.1:0").unwrap();
    let noise: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8 | 1).filter(|b| *b != 0xFD && *b != 0xFE).collect();
    let mut sent = 2000;
    for _ in 0..sent {
        hostile.send_to(&noise, router.gcs_udp()).unwrap();
    }
    wait_for("the garbage counted", || (router.stats().garbage_bytes > 0).then_some(()));
    // The good ground station among more garbage (it resends, as UDP may lose a datagram
    // when the socket's buffer is full of garbage: the kernel's drop, not the router's).
    let gcs = udp_gcs(&router);
    wait_for("the good command", || {
        for _ in 0..50 {
            hostile.send_to(&noise, router.gcs_udp()).unwrap();
        }
        sent += 50;
        gcs.send_to(&frame(GCS_SYSID, &heartbeat(MavType::MAV_TYPE_GCS)), router.gcs_udp()).unwrap();
        gcs.send_to(&frame(GCS_SYSID, &command(1, 5.0)), router.gcs_udp()).unwrap();
        thread::sleep(Duration::from_millis(20));
        (!drones[0].commands().is_empty()).then_some(())
    });
    assert!(drones[0].commands().iter().all(|&c| c == 5.0));
    udp_until(&gcs, "telemetry of both drones", |f| sysids(f).is_superset(&BTreeSet::from([1, 2])));
    let stats = router.stats();
    assert!(stats.garbage_bytes > 0 && stats.garbage_bytes <= sent * noise.len() as u64, "{stats:?}");
    assert_eq!(stats.gcs_udp_clients, 1, "garbage makes no client: {stats:?}");
    let logged = router.shared.as_ref().unwrap().logged.lock().unwrap().clone();
    let from = hostile.local_addr().unwrap().to_string();
    assert_eq!(logged.len(), 1, "{logged:?}");
    assert!(
        logged[0].contains(&format!(
            "dropped {} byte(s) from {from} that are not MAVLink: at byte 0 of a {}-byte datagram, byte 0x{:02x} is no \
             MAVLink start marker",
            noise.len(),
            noise.len(),
            noise[0]
        )),
        "{logged:?}"
    );
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
        signing: None,
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
        signing: None,
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
        signing: None,
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

fn local(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// A table full of live ground stations keeps them all, whoever was heard least recently:
/// a newcomer is refused.
#[test]
fn a_live_udp_gcs_keeps_its_place_and_a_newcomer_is_refused() {
    let mut table = PeerTable::default();
    let t0 = Instant::now();
    for p in 0..MAX_UDP_GCS as u16 {
        assert_eq!(table.heard(local(p), t0), Heard::Added);
    }
    let t1 = t0 + Duration::from_secs(1);
    assert_eq!(table.heard(local(0), t1), Heard::Known); // 0 is now the most recent; 1 the least
    assert_eq!(table.heard(local(100), t1), Heard::Refused);
    // Still refused up to the period after the least recently heard station was heard.
    assert_eq!(table.heard(local(100), t0 + UDP_GCS_LIVENESS), Heard::Refused);
    let peers: BTreeSet<u16> = table.peers.iter().map(|p| p.0.port()).collect();
    assert_eq!(peers, (0..MAX_UDP_GCS as u16).collect());
}

/// A ground station silent for longer than the liveness period gives its place to a newcomer;
/// the live ones keep theirs.
#[test]
fn a_silent_udp_gcs_gives_its_place_to_a_newcomer_after_the_liveness_period() {
    let mut table = PeerTable::default();
    let t0 = Instant::now();
    for p in 0..MAX_UDP_GCS as u16 {
        table.heard(local(p), t0);
    }
    // Every station but 3 heartbeats at 1 Hz; 3 falls silent after t0.
    let mut t = t0;
    while t < t0 + UDP_GCS_LIVENESS {
        t += Duration::from_secs(1);
        for p in (0..MAX_UDP_GCS as u16).filter(|&p| p != 3) {
            table.heard(local(p), t);
        }
    }
    // Exactly the period: still live.
    assert_eq!(table.heard(local(100), t0 + UDP_GCS_LIVENESS), Heard::Refused);
    let after = t0 + UDP_GCS_LIVENESS + Duration::from_millis(1);
    assert_eq!(table.heard(local(100), after), Heard::Replaced(local(3)));
    assert_eq!(table.heard(local(101), after), Heard::Refused, "the others are live");
    let peers: BTreeSet<u16> = table.peers.iter().map(|p| p.0.port()).collect();
    let mut want: BTreeSet<u16> = (0..MAX_UDP_GCS as u16).filter(|&p| p != 3).collect();
    want.insert(100);
    assert_eq!(peers, want);
}

/// 16 live UDP ground stations keep their telemetry while a 17th is refused: its frames
/// reach no drone, it receives nothing, and it is counted and logged once.
#[test]
fn sixteen_live_udp_gcs_keep_telemetry_while_a_17th_is_refused() {
    let (drones, router) = fleet(2);
    let served: Vec<UdpSocket> = (0..MAX_UDP_GCS).map(|_| udp_gcs(&router)).collect();
    wait_for("16 ground stations", || (router.stats().gcs_udp_clients == MAX_UDP_GCS).then_some(()));
    let newcomer = UdpSocket::bind("127.0.0.1:0").unwrap();
    newcomer.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
    for _ in 0..3 {
        newcomer.send_to(&frame(GCS_SYSID, &heartbeat(MavType::MAV_TYPE_GCS)), router.gcs_udp()).unwrap();
    }
    newcomer.send_to(&frame(GCS_SYSID, &command(1, 7.0)), router.gcs_udp()).unwrap();
    // A served station's command after it: once it has arrived, the newcomer's would have.
    served[5].send_to(&frame(GCS_SYSID, &command(1, 8.0)), router.gcs_udp()).unwrap();
    wait_for("the served station's command", || (drones[0].commands() == [8.0]).then_some(()));
    let stats = router.stats();
    assert_eq!(stats.refused_udp_gcs_frames, 4, "{stats:?}");
    assert_eq!(stats.gcs_udp_clients, MAX_UDP_GCS);
    // Every served station keeps receiving both drones' telemetry...
    for gcs in &served {
        udp_until(gcs, "telemetry of both drones", |f| sysids(f).is_superset(&BTreeSet::from([1, 2])));
    }
    // ...sent to each at once: had the newcomer been served, it would have had some by now.
    let mut buf = vec![0u8; MAX_DATAGRAM];
    assert!(newcomer.recv(&mut buf).is_err(), "the refused ground station received a datagram");
    let logged = router.shared.as_ref().unwrap().logged.lock().unwrap().clone();
    let from = newcomer.local_addr().unwrap().to_string();
    assert_eq!(logged.len(), 1, "once per address: {logged:?}");
    assert!(
        logged[0].contains(&format!(
            "refused 1 frame(s) from the new UDP ground station {from}: all 16 places are held by ground stations \
             heard within the last 5 s"
        )),
        "{logged:?}"
    );
}

/// A ground station's signer: link id 1, timestamps from the wall clock.
fn signed(signer: &Signer, frame: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    signer.sign_into(&mut out, frame, timestamp_at(std::time::SystemTime::now()));
    out
}

#[test]
fn with_signing_only_signed_gcs_frames_pass_and_the_gcs_gets_signed_frames() {
    let key = SecretKey::from_passphrase("router test passphrase");
    let (drones, router) = fleet_signing(2, Some(key.clone()));
    let gcs_signer = Signer::new(key.clone(), 1);
    let stranger = Signer::new(SecretKey::from_passphrase("another passphrase"), 1);

    // Without the key: unsigned frames, MAVLink 1 and another key's signature go nowhere,
    // and their sender does not become a client.
    let unsigned = UdpSocket::bind("127.0.0.1:0").unwrap();
    unsigned.send_to(&frame(GCS_SYSID, &heartbeat(MavType::MAV_TYPE_GCS)), router.gcs_udp()).unwrap();
    unsigned.send_to(&frame(GCS_SYSID, &command(1, 1.0)), router.gcs_udp()).unwrap();
    let mut v1 = vec![0xFE, 9, 0, 255, 190, 0, 0, 0, 0, 0, 6, 8, 0, 4, 3];
    let crc = sadesim_engine::mavlink::frame::checksum(&v1[1..], 50); // HEARTBEAT's CRC_EXTRA
    v1.extend(crc.to_le_bytes());
    unsigned.send_to(&v1, router.gcs_udp()).unwrap();
    unsigned.send_to(&signed(&stranger, &frame(GCS_SYSID, &command(1, 2.0))), router.gcs_udp()).unwrap();
    wait_for("the refusals counted", || {
        let s = router.stats();
        (s.refused_unsigned == 3 && s.refused_bad_signature == 1).then_some(())
    });
    assert_eq!(router.stats().gcs_udp_clients, 0);

    // With the key: the heartbeat registers the GCS, the command reaches its drone.
    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    gcs.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
    gcs.send_to(&signed(&gcs_signer, &frame(GCS_SYSID, &heartbeat(MavType::MAV_TYPE_GCS))), router.gcs_udp()).unwrap();
    let command_datagram = signed(&gcs_signer, &frame(GCS_SYSID, &command(1, 3.0)));
    gcs.send_to(&command_datagram, router.gcs_udp()).unwrap();
    wait_for("drone 1 to get the signed command", || (drones[0].commands() == [3.0]).then_some(()));
    assert_eq!(router.stats().gcs_udp_clients, 1);
    // The drone side is unsigned: drones get the GCS's frames as they came.
    assert!(drones[0].received.lock().unwrap().iter().all(|f| f.bytes[2] & IFLAG_SIGNED != 0));

    // SETUP_SIGNING carries the key in plain text: not passed on, even signed. (The router
    // sends to a drone in order, so the command after it shows it would have arrived.)
    let setup =
        MavMessage::SETUP_SIGNING(SETUP_SIGNING_DATA { target_system: 1, target_component: 1, ..Default::default() });
    gcs.send_to(&signed(&gcs_signer, &frame(GCS_SYSID, &setup)), router.gcs_udp()).unwrap();
    gcs.send_to(&signed(&gcs_signer, &frame(GCS_SYSID, &command(1, 6.0))), router.gcs_udp()).unwrap();
    wait_for("the command after SETUP_SIGNING", || (drones[0].commands() == [3.0, 6.0]).then_some(()));
    assert!(!drones[0].received.lock().unwrap().iter().any(|f| f.message_id == 256), "SETUP_SIGNING forwarded");

    // The same datagram again is a replay.
    gcs.send_to(&command_datagram, router.gcs_udp()).unwrap();
    wait_for("the replay counted", || (router.stats().refused_old_timestamp == 1).then_some(()));

    // Telemetry arrives signed with the key, every frame, and passes a receiver's checks
    // (strictly increasing timestamps per drone stream).
    let frames = udp_until(&gcs, "signed telemetry from both drones", |f| sysids(f).len() == 2 && f.len() >= 20);
    let mut receiver = Verifier::new(key.clone());
    let now = timestamp_at(std::time::SystemTime::now());
    for f in &frames {
        assert_ne!(f.bytes[2] & IFLAG_SIGNED, 0, "frame from {} unsigned", f.header.system_id);
        assert_eq!(f.bytes[f.bytes.len() - 13], super::ROUTER_LINK_ID);
        assert_eq!(receiver.check(&f.bytes, now), Ok(()), "frame from {}", f.header.system_id);
    }
    assert_eq!(Verifier::new(SecretKey::from_passphrase("x")).check(&frames[0].bytes, now), Err(Refusal::BadSignature));

    // TCP: the same rules.
    let mut tcp = TcpStream::connect(router.gcs_tcp()).unwrap();
    tcp.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
    tcp.write_all(&frame(254, &command(2, 4.0))).unwrap();
    wait_for("the unsigned TCP frame refused", || (router.stats().refused_unsigned == 4).then_some(()));
    tcp.write_all(&signed(&Signer::new(key.clone(), 2), &frame(254, &command(2, 5.0)))).unwrap();
    wait_for("drone 2 to get the signed TCP command", || (drones[1].commands() == [5.0]).then_some(()));
    let mut parser = FrameParser::new();
    let mut buf = [0u8; 4096];
    let mut over_tcp = Vec::new();
    wait_for("signed telemetry over TCP", || {
        if let Ok(n) = tcp.read(&mut buf) {
            over_tcp.extend(parser.push(&buf[..n]));
        }
        (over_tcp.len() >= 4).then_some(())
    });
    assert!(over_tcp.iter().all(|f| receiver.check(&f.bytes, now).is_ok()));
    assert!(drones[0].commands() == [3.0, 6.0] && drones[1].commands() == [5.0], "nothing refused got through");
    let stats = router.stats();
    assert_eq!((stats.refused_unsigned, stats.refused_bad_signature, stats.refused_old_timestamp), (4, 1, 1));
}

/// `n` drone sockets, a router for them with a UDP ground station, and the address the
/// router registered with the drones from (where drone datagrams go).
fn segment_with_gcs(n: u8) -> (Vec<UdpSocket>, RouterHandle, UdpSocket, SocketAddr) {
    let sockets: Vec<UdpSocket> = (0..n).map(|_| UdpSocket::bind("127.0.0.1:0").unwrap()).collect();
    let router = router_for(sockets.iter().map(|s| s.local_addr().unwrap()), None);
    let gcs = udp_gcs(&router);
    // The router registers with the drones once it has a ground station.
    let mut buf = vec![0u8; MAX_DATAGRAM];
    sockets[0].set_read_timeout(Some(DEADLINE)).unwrap();
    let (_, router_addr) = sockets[0].recv_from(&mut buf).expect("the router registers with the drones");
    (sockets, router, gcs, router_addr)
}

/// Reads what has arrived at `gcs` into `frames`, checking that each datagram is at most
/// 1 400 bytes of whole frames; returns how many datagrams it read.
fn read_gcs_datagrams(gcs: &UdpSocket, frames: &mut Vec<Frame>) -> usize {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut datagrams = 0;
    while let Ok(n) = gcs.recv(&mut buf) {
        assert!(n <= 1400, "a {n}-byte datagram to the ground station");
        let got = FrameParser::new().push(&buf[..n]);
        assert_eq!(got.iter().map(|f| f.bytes.len()).sum::<usize>(), n, "whole frames only");
        datagrams += 1;
        frames.extend(got);
    }
    datagrams
}

/// Datagrams from many drones at once (a shard's flush) reach a ground station in fewer,
/// fuller datagrams: every frame intact, each drone's in its order, none over 1 400 bytes.
#[test]
fn a_burst_of_drone_datagrams_reaches_a_gcs_in_shared_datagrams() {
    const DRONES: u8 = 16;
    let (sockets, router, gcs, router_addr) = segment_with_gcs(DRONES);
    // One datagram per drone, back to back: a heartbeat, then an ATTITUDE whose
    // time_boot_ms is the drone's number, so order and integrity can be checked.
    for (i, socket) in sockets.iter().enumerate() {
        let sysid = i as u32 + 1;
        let mut datagram = frame(sysid, &heartbeat(MavType::MAV_TYPE_QUADROTOR));
        datagram
            .extend(frame(sysid, &MavMessage::ATTITUDE(ATTITUDE_DATA { time_boot_ms: sysid, ..Default::default() })));
        socket.send_to(&datagram, router_addr).unwrap();
    }
    let mut frames = Vec::new();
    let mut datagrams = 0;
    wait_for("every drone's ATTITUDE at the ground station", || {
        datagrams += read_gcs_datagrams(&gcs, &mut frames);
        (sysids(&frames).len() == usize::from(DRONES)).then_some(())
    });
    assert_eq!(frames.len(), 2 * usize::from(DRONES), "{frames:?}");
    for sysid in 1..=u32::from(DRONES) {
        let mine: Vec<&Frame> = frames.iter().filter(|f| f.header.system_id == sysid).collect();
        assert!(matches!(mine[0].message, Decoded::Message(MavMessage::HEARTBEAT(_))), "{sysid}: {mine:?}");
        assert!(
            matches!(&mine[1].message, Decoded::Message(MavMessage::ATTITUDE(a)) if a.time_boot_ms == sysid),
            "{sysid}: {mine:?}"
        );
    }
    // 16 datagrams of 57 bytes fit in one; allow for the sender being preempted between sends.
    assert!(datagrams < usize::from(DRONES) / 2, "{datagrams} datagrams for {DRONES} drones");
    assert_eq!(router.stats().datagrams_to_gcs, datagrams as u64);
}

/// A shard on this host gathers its drones' frames into datagrams of up to 16 KiB
/// (`mavlink::uplink`), sent from one endpoint of the segment; the router splits them at
/// frame boundaries into datagrams a ground station reads (at most 1 400 bytes), every frame
/// whole and in order.
#[test]
fn a_shards_large_datagram_reaches_a_gcs_split_at_frame_boundaries() {
    const DRONES: u8 = 240;
    let (sockets, _router, gcs, router_addr) = segment_with_gcs(DRONES);
    // Every drone's heartbeat and ATTITUDE in one datagram from the first drone's endpoint.
    let mut datagram = Vec::new();
    for sysid in 1..=u32::from(DRONES) {
        datagram.extend(frame(sysid, &heartbeat(MavType::MAV_TYPE_QUADROTOR)));
        let attitude = ATTITUDE_DATA {
            time_boot_ms: sysid,
            roll: 0.1,
            pitch: -0.2,
            yaw: 1.5,
            rollspeed: 0.01,
            pitchspeed: 0.02,
            yawspeed: -0.03,
        };
        datagram.extend(frame(sysid, &MavMessage::ATTITUDE(attitude)));
    }
    assert!(datagram.len() > 8 * 1400 && datagram.len() <= 16 * 1024, "{} bytes", datagram.len());
    sockets[0].send_to(&datagram, router_addr).unwrap();
    let mut frames = Vec::new();
    let mut datagrams = 0;
    wait_for("the whole datagram at the ground station", || {
        datagrams += read_gcs_datagrams(&gcs, &mut frames);
        (frames.iter().map(|f| f.bytes.len()).sum::<usize>() >= datagram.len()).then_some(())
    });
    let received: Vec<u8> = frames.iter().flat_map(|f| f.bytes.iter().copied()).collect();
    assert_eq!(received, datagram, "every frame, byte for byte and in order");
    // Full datagrams: about as few as 1 400-byte ones can carry.
    assert!(datagrams <= datagram.len() / 1400 + 2, "{datagrams} datagrams for {} bytes", datagram.len());
}
