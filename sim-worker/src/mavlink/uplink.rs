//! The shard's telemetry to its MAVLink routers, gathered across drones.
//!
//! A router registers with every drone endpoint of its segment (its HEARTBEAT, from
//! [`ROUTER_SYSTEM_ID`] / [`ROUTER_COMPONENT_ID`]), so each endpoint would send the router
//! a datagram of its own at every exchange: one `sendto` per drone every 20 ms, which at a
//! thousand drones cost the shard more than building and encoding the telemetry
//! (docs/performance.md, issue 20, fifth round). Instead the shard gathers, per router,
//! the datagrams of all its drones into shared datagrams of up to
//! [`MAX_DATAGRAM`](super::endpoint::MAX_DATAGRAM) bytes, and sends each from the endpoint
//! of the first of those drones (the router takes frames only from its segment's
//! endpoints, and routes by the frames' system ids, not by the sender's address).
//!
//! Only router peers are gathered. Any other client (a ground station or SDK talking to a
//! drone's port directly) keeps getting each drone's datagrams from that drone's own
//! address: SDKs such as MAVSDK learn where a system is from the address its frames come
//! from, and send its commands there.

use std::net::SocketAddr;

use super::endpoint::{Endpoint, MAX_DATAGRAM};

/// Frames for the routers, gathered over one exchange (see the module docs).
#[derive(Debug, Default)]
pub struct Uplink {
    routers: Vec<RouterBatch>,
}

#[derive(Debug)]
struct RouterBatch {
    router: SocketAddr,
    /// Index (in the shard's endpoints) of the endpoint the batch is sent from.
    sender: usize,
    /// Whole frames, each datagram at most MAX_DATAGRAM bytes (or one drone's datagram as
    /// it came).
    datagrams: Vec<Vec<u8>>,
}

impl Uplink {
    /// Adds one drone's datagram (whole frames) for `router`; `endpoint` is the drone's
    /// index among the shard's endpoints.
    pub fn add(&mut self, router: SocketAddr, endpoint: usize, datagram: &[u8]) {
        let batch = match self.routers.iter().position(|b| b.router == router) {
            Some(i) => &mut self.routers[i],
            None => {
                self.routers.push(RouterBatch { router, sender: endpoint, datagrams: Vec::new() });
                self.routers.last_mut().expect("just pushed")
            }
        };
        match batch.datagrams.last_mut() {
            Some(last) if last.len() + datagram.len() <= MAX_DATAGRAM => last.extend_from_slice(datagram),
            _ => batch.datagrams.push(datagram.to_vec()),
        }
    }

    /// Sends every gathered datagram from its batch's endpoint, and starts over.
    pub fn send(&mut self, endpoints: &mut [Endpoint]) {
        for batch in self.routers.drain(..) {
            if let Some(endpoint) = endpoints.get_mut(batch.sender) {
                for datagram in &batch.datagrams {
                    endpoint.send_datagram(datagram, batch.router);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn datagrams_for_one_router_share_datagrams_up_to_the_limit_and_routers_stay_apart() {
        let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.1:1".parse().unwrap(), "127.0.0.1:2".parse().unwrap());
        let mut uplink = Uplink::default();
        for drone in 0..10 {
            uplink.add(a, drone, &[drone as u8; 300]);
        }
        uplink.add(b, 7, &[70; 100]);
        // 4 x 300 bytes fit in 1 400: 10 drones in 3 datagrams for a, 1 for b.
        assert_eq!(uplink.routers[0].datagrams.iter().map(Vec::len).collect::<Vec<_>>(), [1200, 1200, 600]);
        assert_eq!((uplink.routers[0].sender, uplink.routers[1].sender), (0, 7));
        assert_eq!(uplink.routers[1].datagrams, [vec![70; 100]]);
        // In arrival order, never split.
        let bytes: Vec<u8> = uplink.routers[0].datagrams.concat();
        assert_eq!(bytes, (0..10u8).flat_map(|d| [d; 300]).collect::<Vec<_>>());
        uplink.add(a, 3, &[9; MAX_DATAGRAM + 10]);
        assert_eq!(uplink.routers[0].datagrams.last().unwrap().len(), MAX_DATAGRAM + 10, "a big one goes as it came");
    }
}
