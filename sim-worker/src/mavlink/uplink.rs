//! The shard's telemetry to its MAVLink routers, gathered across drones.
//!
//! A router registers with every drone endpoint of its segment (its HEARTBEAT, from
//! [`ROUTER_SYSTEM_ID`] / [`ROUTER_COMPONENT_ID`]), so each endpoint would send the router
//! a datagram of its own at every exchange: one `sendto` per drone every 20 ms, which at a
//! thousand drones cost the shard more than building and encoding the telemetry
//! (docs/performance.md, issue 20, fifth round). Instead the shard gathers, per router,
//! the datagrams of all its drones into shared datagrams, and sends each from the endpoint
//! of the first of those drones (the router takes frames only from its segment's
//! endpoints, and routes by the frames' system ids, not by the sender's address).
//!
//! How big a shared datagram may be depends on the path ([`datagram_limit`]): a router on
//! another host (a cluster's router pod) gets datagrams of at most
//! [`MAX_DATAGRAM`](super::endpoint::MAX_DATAGRAM) bytes, which no Ethernet MTU fragments;
//! a router on this host (loopback, whose MTU is 64 KiB: every local run) gets up to
//! [`LOOPBACK_DATAGRAM`], a tenth of the sends for the same frames. The router splits them
//! again, at frame boundaries, into datagrams a ground station can read.
//!
//! Only router peers are gathered. Any other client (a ground station or SDK talking to a
//! drone's port directly) keeps getting each drone's datagrams from that drone's own
//! address: SDKs such as MAVSDK learn where a system is from the address its frames come
//! from, and send its commands there.

use std::net::SocketAddr;

use super::endpoint::{Endpoint, MAX_DATAGRAM};

/// Largest shared datagram to a router on this host, bytes. Loopback carries up to 64 KiB
/// unfragmented; 16 KiB holds a 250-drone segment's exchange (about 50 kB, every 20 ms of
/// simulated time) in four sends, where a bigger limit would save little more and would
/// fill the router's receive buffer (212 992 bytes by default) in fewer datagrams.
pub const LOOPBACK_DATAGRAM: usize = 16 * 1024;

/// The largest shared datagram for `router` (see the module docs).
pub fn datagram_limit(router: SocketAddr) -> usize {
    if router.ip().is_loopback() { LOOPBACK_DATAGRAM } else { MAX_DATAGRAM }
}

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
    /// [`datagram_limit`] of `router`.
    limit: usize,
    /// Whole frames, each datagram at most `limit` bytes (or one drone's datagram as it
    /// came).
    datagrams: Vec<Vec<u8>>,
}

impl Uplink {
    /// Adds one drone's datagram (whole frames) for `router`; `endpoint` is the drone's
    /// index among the shard's endpoints.
    pub fn add(&mut self, router: SocketAddr, endpoint: usize, datagram: &[u8]) {
        let batch = match self.routers.iter().position(|b| b.router == router) {
            Some(i) => &mut self.routers[i],
            None => {
                let limit = datagram_limit(router);
                self.routers.push(RouterBatch { router, sender: endpoint, limit, datagrams: Vec::new() });
                self.routers.last_mut().expect("just pushed")
            }
        };
        match batch.datagrams.last_mut() {
            Some(last) if last.len() + datagram.len() <= batch.limit => last.extend_from_slice(datagram),
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
        // Routers on another host (a cluster's router pods).
        let (a, b): (SocketAddr, SocketAddr) = ("10.0.0.5:1".parse().unwrap(), "10.0.0.6:2".parse().unwrap());
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

    #[test]
    fn a_router_on_this_host_gets_loopback_sized_datagrams() {
        for local in ["127.0.0.1:14600", "[::1]:14600"] {
            let router: SocketAddr = local.parse().unwrap();
            assert_eq!(datagram_limit(router), LOOPBACK_DATAGRAM);
            let mut uplink = Uplink::default();
            // 250 drones' exchange of 200 bytes each: 50 000 bytes in 4 datagrams, not 36.
            for drone in 0..250 {
                uplink.add(router, drone, &[drone as u8; 200]);
            }
            let sizes: Vec<usize> = uplink.routers[0].datagrams.iter().map(Vec::len).collect();
            assert_eq!(sizes.len(), 4, "{sizes:?}");
            assert!(sizes.iter().all(|&n| n <= LOOPBACK_DATAGRAM && n % 200 == 0), "{sizes:?}");
        }
        assert_eq!(datagram_limit("10.42.0.7:14600".parse().unwrap()), MAX_DATAGRAM);
    }
}
