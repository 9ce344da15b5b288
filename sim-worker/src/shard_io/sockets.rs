//! The sockets of a shard's drones: one MAVLink [`Endpoint`] per drone and one readiness
//! wait ([`EndpointPoll`]) for them all, carrying the shard core's MAVLink queues to the
//! network ([`MavlinkIo`]). Used by the `sim-worker shard` role and by in-process shard
//! threads alike.

use sadesim_crds::plan::RunPlan;

use sadesim_engine::shard::{MavlinkIo, MavlinkQueues, Shard, ShardError};

use crate::mavlink::endpoint::{Endpoint, EndpointConfig, EndpointError, EndpointPoll, PEER_HEARTBEAT_TIMEOUT};
use crate::mavlink::uplink::Uplink;

/// How a shard's drones expose MAVLink.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MavlinkOptions {
    /// Address the endpoints bind (127.0.0.1 locally; 0.0.0.0 in a pod).
    pub bind_ip: std::net::IpAddr,
    /// Host that receives each drone's API link on port 14540+i (PX4 SITL style); `None`
    /// sends no API link (in a cluster, clients connect to the endpoints instead).
    pub api_host: Option<std::net::IpAddr>,
    /// Wall-clock UNIX time at sim time 0, µs (SYSTEM_TIME).
    pub unix_epoch_at_start_us: u64,
}

impl MavlinkOptions {
    /// Endpoints on 127.0.0.1, API links to 127.0.0.1: `sadesim run`.
    pub fn local() -> Self {
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
        let localhost = std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST);
        Self { bind_ip: localhost, api_host: Some(localhost), unix_epoch_at_start_us: now.as_micros() as u64 }
    }
}

/// Why a shard could not start with its sockets.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The engine could not build the shard or its drones' MAVLink sessions.
    #[error(transparent)]
    Shard(#[from] ShardError),
    /// A MAVLink endpoint could not open its sockets.
    #[error(transparent)]
    Mavlink(#[from] EndpointError),
}

/// A shard's MAVLink endpoints (index = the drone's position in the shard).
#[derive(Debug)]
pub struct ShardSockets {
    endpoints: Vec<Endpoint>,
    /// What goes to the routers at a flush, gathered across the shard's drones.
    uplink: Uplink,
    /// `None` when the OS refused a readiness queue: every socket is read at every
    /// exchange then, slower but not wrong.
    poll: Option<EndpointPoll>,
}

impl ShardSockets {
    /// Gives `shard`'s drones their MAVLink sessions ([`Shard::enable_mavlink`]) and opens
    /// an endpoint for each, as `options` say.
    ///
    /// # Errors
    /// The first endpoint that cannot bind (its port is named); none stay open then.
    pub fn open(shard: &mut Shard, plan: &RunPlan, options: &MavlinkOptions) -> Result<Self, StartError> {
        let mut poll = EndpointPoll::new().ok();
        let mut endpoints = Vec::with_capacity(shard.drones().len());
        for (index, drone) in shard.drones().iter().enumerate() {
            let d = &drone.plan;
            let mut endpoint = Endpoint::open(EndpointConfig {
                system_id: d.system_id,
                bind_ip: options.bind_ip,
                port: d.ports.endpoint,
                api_target: options.api_host.map(|h| std::net::SocketAddr::new(h, d.ports.api_udp)),
                peer_timeout: PEER_HEARTBEAT_TIMEOUT,
            })?;
            if let Some(p) = &mut poll {
                // Unregistered, the endpoint reads all its sockets: still correct.
                let _ = p.register(&mut endpoint, index);
            }
            endpoints.push(endpoint);
        }
        shard.enable_mavlink(plan, options.unix_epoch_at_start_us)?;
        Ok(Self { endpoints, uplink: Uplink::default(), poll })
    }

    /// The endpoints, in the shard's drone order.
    pub fn endpoints(&self) -> &[Endpoint] {
        &self.endpoints
    }
}

impl MavlinkIo for ShardSockets {
    /// One readiness wait for the whole shard, then only sockets with something to read
    /// are read.
    fn receive(&mut self, queues: &mut [MavlinkQueues]) {
        if let Some(poll) = &mut self.poll {
            let endpoints = &mut self.endpoints;
            poll.dispatch(|index, socket| {
                if let Some(endpoint) = endpoints.get_mut(index) {
                    endpoint.mark_ready(socket);
                }
            });
        }
        for (endpoint, queue) in self.endpoints.iter_mut().zip(queues) {
            queue.inbound.extend(endpoint.receive());
        }
    }

    /// Encodes every drone's outbound messages into its datagrams (with the endpoint's
    /// sequence numbers); on `flush` sends them to every peer, what goes to the routers
    /// gathered across drones ([`Uplink`]).
    fn send(&mut self, queues: &mut [MavlinkQueues], flush: bool) {
        for (index, (endpoint, queue)) in self.endpoints.iter_mut().zip(queues).enumerate() {
            endpoint.queue(&queue.outbound);
            queue.outbound.clear();
            if flush {
                endpoint.flush_gathering(index, &mut self.uplink);
            }
        }
        if flush {
            self.uplink.send(&mut self.endpoints);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    use ::mavlink::MavHeader;
    use ::mavlink::dialects::common::{MavMessage, PARAM_REQUEST_READ_DATA};
    use ::mavlink::types::CharArray;
    use sadesim_world::{World, WorldInputs};

    use super::*;
    use sadesim_engine::fixtures::{plan_of, run_with_groups};
    use sadesim_engine::mavlink::frame::{Decoded, FrameParser, encode};

    /// One shard of `drones` drones with their sockets on 127.0.0.1, each on a free port.
    fn shard_with_sockets(drones: u32) -> (RunPlan, Shard, ShardSockets) {
        let mut plan = plan_of(run_with_groups(&[("a", drones)]).build());
        for d in &mut plan.drones {
            d.ports.endpoint = 0; // any free port
        }
        let world = Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])));
        let mut shard = Shard::new(&plan, 0, &sadesim_engine::shard::Surroundings::new(&plan, world, None)).unwrap();
        let localhost = std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST);
        let options = MavlinkOptions { bind_ip: localhost, api_host: None, unix_epoch_at_start_us: 0 };
        let sockets = ShardSockets::open(&mut shard, &plan, &options).unwrap();
        (plan, shard, sockets)
    }

    #[test]
    fn a_udp_client_gets_its_parameter_through_the_shards_sockets() {
        let (_, mut shard, mut sockets) = shard_with_sockets(1);
        let endpoint = sockets.endpoints()[0].local_addr().unwrap();

        let client = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        client.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
        let request = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: CharArray::from("SYS_AUTOSTART"),
        });
        client
            .send_to(&encode(MavHeader { system_id: 255, component_id: 190, sequence: 0 }, &request), endpoint)
            .unwrap();

        let deadline = Instant::now() + Duration::from_secs(5);
        let mut buf = [0u8; 2048];
        let mut step = 0;
        while Instant::now() < deadline {
            step += 10;
            shard.advance_with(step, &mut sockets);
            let Ok(n) = client.recv(&mut buf) else { continue };
            for frame in FrameParser::new().push(&buf[..n]) {
                if let Decoded::Message(MavMessage::PARAM_VALUE(v)) = frame.message {
                    // An INT32 parameter travels as its bytes in the float (PX4).
                    assert_eq!((v.param_id.to_str().unwrap(), v.param_value.to_bits()), ("SYS_AUTOSTART", 4001));
                    assert!(shard.mavlink_queues()[0].outbound.is_empty(), "the sockets took the queue");
                    return;
                }
            }
        }
        panic!("no PARAM_VALUE within 5 s");
    }

    /// A router's telemetry is gathered across the shard's drones and sent from one
    /// endpoint; a client talking to drones directly still gets each drone's frames from
    /// that drone's own address.
    #[test]
    fn a_router_gets_the_shards_telemetry_gathered_and_a_direct_client_per_drone() {
        use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavType};

        use crate::mavlink::router::{ROUTER_COMPONENT_ID, ROUTER_SYSTEM_ID};

        let (plan, mut shard, mut sockets) = shard_with_sockets(3);
        let endpoints: Vec<std::net::SocketAddr> =
            sockets.endpoints().iter().map(|e| e.local_addr().unwrap()).collect();
        let sysids: Vec<u32> = plan.drones.iter().map(|d| u32::from(d.system_id)).collect();

        let heartbeat = |system_id, component_id, mavtype| {
            let message = MavMessage::HEARTBEAT(HEARTBEAT_DATA { mavtype, ..Default::default() });
            encode(MavHeader { system_id, component_id, sequence: 0 }, &message)
        };
        let peer = || {
            let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
            socket.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
            socket
        };
        // The router registers with every drone; the client talks to drones 0 and 1 itself.
        let router = peer();
        let client = peer();
        let router_hb =
            heartbeat(u32::from(ROUTER_SYSTEM_ID), ROUTER_COMPONENT_ID, MavType::MAV_TYPE_ONBOARD_CONTROLLER);
        for e in &endpoints {
            router.send_to(&router_hb, e).unwrap();
        }
        let client_hb = heartbeat(255, 190, MavType::MAV_TYPE_GCS);
        for e in &endpoints[..2] {
            client.send_to(&client_hb, e).unwrap();
        }

        // About a second of simulated time: 50 exchanges.
        for step in (10..=1000).step_by(10) {
            shard.advance_with(step, &mut sockets);
        }
        let read = |socket: &std::net::UdpSocket| {
            let mut got = Vec::new();
            let mut buf = [0u8; 2048];
            while let Ok((n, from)) = socket.recv_from(&mut buf) {
                let frames = FrameParser::new().push(&buf[..n]);
                assert_eq!(frames.iter().map(|f| f.bytes.len()).sum::<usize>(), n, "whole frames");
                got.push((from, frames.iter().map(|f| f.header.system_id).collect::<Vec<_>>()));
            }
            got
        };
        let to_router = read(&router);
        let to_client = read(&client);

        let ids = |got: &[(std::net::SocketAddr, Vec<u32>)]| {
            got.iter().flat_map(|(_, s)| s.iter().copied()).collect::<std::collections::BTreeSet<u32>>()
        };
        assert_eq!(ids(&to_router), sysids.iter().copied().collect(), "every drone's telemetry reaches the router");
        assert!(to_router.iter().all(|(from, _)| *from == endpoints[0]), "sent from the first drone's endpoint");
        // A 20 ms exchange of 3 drones' telemetry fits one datagram: about one per exchange
        // (50), not one per drone and exchange (150).
        assert!(to_router.len() <= 55, "{} datagrams to the router: not gathered", to_router.len());
        // The direct client: drones 0 and 1 only, each from its own address.
        assert_eq!(ids(&to_client), sysids[..2].iter().copied().collect());
        for (from, ids) in &to_client {
            let drone = endpoints.iter().position(|e| e == from).expect("from a drone's endpoint");
            assert!(ids.iter().all(|&id| id == sysids[drone]), "{from}: frames of {ids:?}");
        }
    }

    /// What one client of drone 0 receives in a simulated second: it registers with a
    /// HEARTBEAT and asks for a parameter, then reads everything (after `finish`).
    fn client_session<Io: MavlinkIo>(
        shard: &mut Shard,
        mut io: Io,
        endpoint: std::net::SocketAddr,
        finish: impl FnOnce(Io),
    ) -> Vec<u8> {
        use ::mavlink::dialects::common::HEARTBEAT_DATA;
        let client = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        client.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        client.send_to(&encode(header, &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())), endpoint).unwrap();
        let request = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: CharArray::from("MPC_XY_CRUISE"),
        });
        client.send_to(&encode(header, &request), endpoint).unwrap();
        // Both datagrams are in the socket's buffer before the first exchange reads it.
        std::thread::sleep(Duration::from_millis(20));
        for step in (10..=1000).step_by(10) {
            shard.advance_with(step, &mut io);
        }
        finish(io);
        let mut got = Vec::new();
        let mut buf = [0u8; 65536];
        while let Ok(n) = client.recv(&mut buf) {
            got.extend_from_slice(&buf[..n]);
        }
        got
    }

    /// The I/O thread changes when frames leave, not what leaves: the same shard run twice,
    /// once with its sockets on its own thread and once behind a [`MavlinkThread`], sends
    /// a client byte for byte the same frames (telemetry built on the I/O thread, and the
    /// reply to a request that went in through it).
    #[test]
    fn the_io_thread_sends_the_same_frames_as_the_shards_own_thread() {
        use crate::shard_io::MavlinkThread;

        let (_, mut shard, sockets) = shard_with_sockets(2);
        let endpoint = sockets.endpoints()[0].local_addr().unwrap();
        let direct = client_session(&mut shard, sockets, endpoint, drop);

        let (_, mut shard, sockets) = shard_with_sockets(2);
        let endpoint = sockets.endpoints()[0].local_addr().unwrap();
        let thread = MavlinkThread::spawn(sockets, "test-mavlink".into());
        // Finishing waits until the last window's frames are sent; the thread's CPU time
        // is the shard's to count.
        let threaded = client_session(&mut shard, thread, endpoint, |mut io| {
            let cpu_s = io.finish();
            assert!(cpu_s > 0.0 && cpu_s < 10.0, "the I/O thread's CPU: {cpu_s} s");
            assert_eq!(io.finish(), 0.0, "finished once");
        });

        let messages: Vec<u32> = FrameParser::new()
            .push(&threaded)
            .iter()
            .filter_map(|f| match &f.message {
                Decoded::Message(m) => Some(::mavlink::Message::message_id(m)),
                _ => None,
            })
            .collect();
        for (id, name) in [(22, "PARAM_VALUE"), (30, "ATTITUDE"), (33, "GLOBAL_POSITION_INT"), (0, "HEARTBEAT")] {
            assert!(messages.contains(&id), "no {name} among {} messages", messages.len());
        }
        // About 265 messages a second at PX4's onboard rates.
        assert!(messages.len() > 200, "{} messages", messages.len());
        assert_eq!(threaded.len(), direct.len(), "bytes received, threaded vs direct");
        assert!(threaded == direct, "the same bytes in the same order");
    }
}
