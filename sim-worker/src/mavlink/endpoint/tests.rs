use std::net::{Ipv4Addr, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavMessage};

use super::*;
use sadesim_engine::mavlink::frame::{Decoded, encode};

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

fn heartbeat_out() -> Outgoing {
    Outgoing::Message(MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))
}

fn attitude_out() -> Outgoing {
    Outgoing::Message(MavMessage::ATTITUDE(::mavlink::dialects::common::ATTITUDE_DATA {
        time_boot_ms: 1,
        roll: 0.1,
        pitch: 0.2,
        yaw: 0.3,
        rollspeed: 0.4,
        pitchspeed: 0.5,
        yawspeed: 0.6,
    }))
}

/// A loopback port nobody listens on (bound once by the OS's choice, then released).
fn free_port() -> SocketAddr {
    UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap()
}

/// Message ids of every frame that reached `socket` so far.
fn drain(socket: &UdpSocket) -> Vec<Vec<u32>> {
    socket.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    let mut buf = [0u8; 2048];
    let mut datagrams = Vec::new();
    while let Ok(n) = socket.recv(&mut buf) {
        datagrams.push(FrameParser::new().push(&buf[..n]).iter().map(|f| f.message_id).collect());
    }
    datagrams
}

#[test]
fn the_api_link_sends_only_heartbeats_while_nobody_listens_and_resumes_when_someone_does() {
    let target = free_port();
    let mut e = open(Some(target));
    // Nobody on the target: the first rounds are refused, then the link goes quiet.
    for _ in 0..3 {
        e.receive();
        e.send(&[heartbeat_out(), attitude_out()]);
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!e.api_link_live(), "{:?}", e.stats);
    assert!(e.stats.api_refused >= 1);
    // A client starts listening: the next heartbeat reaches it alone, ...
    let listener = UdpSocket::bind(target).unwrap();
    e.receive();
    e.send(&[attitude_out()]);
    e.receive();
    e.send(&[heartbeat_out(), attitude_out()]);
    assert_eq!(drain(&listener), vec![vec![0]], "only the heartbeat while quiet");
    // ... and, that heartbeat not being refused, everything from the next exchange on.
    std::thread::sleep(Duration::from_millis(5));
    e.receive();
    e.send(&[attitude_out()]);
    assert!(e.api_link_live());
    assert_eq!(drain(&listener), vec![vec![30]]);
    // The listener leaves: quiet again after the refusal comes back.
    drop(listener);
    for _ in 0..3 {
        e.receive();
        e.send(&[attitude_out()]);
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!e.api_link_live());
}

#[test]
fn a_datagram_from_the_api_target_revives_the_link_at_once() {
    let target = free_port();
    let mut e = open(Some(target));
    for _ in 0..3 {
        e.receive();
        e.send(&[attitude_out()]);
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!e.api_link_live());
    // A MAVSDK-like client: binds the API port and greets the drone it heard of.
    let client = UdpSocket::bind(target).unwrap();
    client.send_to(&heartbeat(245), e.local_addr().unwrap()).unwrap();
    let frames = receive_until(&mut e, 1);
    assert_eq!(frames.len(), 1, "the client's frame is handed to the session");
    assert!(e.api_link_live());
    e.send(&[attitude_out()]);
    assert_eq!(drain(&client), vec![vec![30]]);
}

#[test]
fn a_second_endpoint_on_a_taken_port_fails_also_with_an_api_link() {
    let e = open(Some(free_port()));
    let port = e.local_addr().unwrap().port();
    let err = Endpoint::open(EndpointConfig {
        system_id: 4,
        bind_ip: IpAddr::V4(Ipv4Addr::LOCALHOST),
        port,
        api_target: Some(free_port()),
        peer_timeout: PEER_HEARTBEAT_TIMEOUT,
    })
    .unwrap_err();
    assert_eq!(err.source.kind(), ErrorKind::AddrInUse, "{err}");
}

#[test]
fn a_registered_endpoint_reads_what_the_readiness_wait_reports() {
    let mut poll = EndpointPoll::new().unwrap();
    let mut quiet = open(None);
    let mut busy = open(None);
    poll.register(&mut quiet, 0).unwrap();
    poll.register(&mut busy, 1).unwrap();
    // Registration reads everything once (nothing there yet).
    assert!(quiet.receive().is_empty() && busy.receive().is_empty());
    let client = UdpSocket::bind("127.0.0.1:0").unwrap();
    client.send_to(&heartbeat(255), busy.local_addr().unwrap()).unwrap();
    let tcp = TcpStream::connect(busy.local_addr().unwrap()).unwrap();
    std::thread::sleep(Duration::from_millis(20));
    // Not marked yet: a registered endpoint does not look.
    assert!(busy.receive().is_empty());
    let mut marked = Vec::new();
    poll.dispatch(|index, socket| marked.push((index, socket)));
    marked.sort_by_key(|&(i, s)| (i, s as usize));
    assert_eq!(marked, vec![(1, SocketKind::Udp), (1, SocketKind::TcpListener)]);
    for (_, socket) in marked {
        busy.mark_ready(socket);
    }
    assert_eq!(busy.receive().len(), 1);
    assert_eq!(busy.stats.tcp_accepted, 1);
    // Nothing new: nothing marked.
    let mut again = 0;
    poll.dispatch(|_, _| again += 1);
    assert_eq!(again, 0);
    drop(tcp);
}

#[test]
fn unflushed_datagrams_drop_oldest_first_and_buffers_are_reused() {
    let mut e = open(None);
    let client = UdpSocket::bind("127.0.0.1:0").unwrap();
    client.send_to(&heartbeat(255), e.local_addr().unwrap()).unwrap();
    receive_until(&mut e, 1);
    // A datagram takes frames while it has room for the largest one. Queue 70 datagrams'
    // worth without flushing.
    let frame_len = attitude_out().encode(MavHeader::default()).len();
    let per_datagram = (MAX_DATAGRAM - MAX_FRAME_LEN) / frame_len + 1;
    let total = per_datagram * 70;
    for _ in 0..total {
        e.queue(&[attitude_out()]);
    }
    assert_eq!(e.stats.dropped_datagrams, 70 - 64);
    e.flush();
    client.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let mut buf = [0u8; 2048];
    let mut sequences = Vec::new();
    while let Ok(n) = client.recv(&mut buf) {
        sequences.extend(FrameParser::new().push(&buf[..n]).iter().map(|f| f.header.sequence));
    }
    assert_eq!(sequences.len(), per_datagram * 64, "64 datagrams, full ones");
    assert_eq!(*sequences.last().unwrap(), (total - 1) as u8, "the newest frame survives");
    // Buffers are reused: a later round sends what it queued, nothing stale.
    e.send(&[heartbeat_out()]);
    let n = client.recv(&mut buf).unwrap();
    assert_eq!(FrameParser::new().push(&buf[..n]).len(), 1);
}
