//! Starting and stopping a router: binds the sockets, starts the threads, and hands back
//! a [`RouterHandle`] that reads the counters and stops it.

use std::io;
use std::net::{Shutdown, SocketAddr, TcpListener, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use super::config::{POLL, RouterConfig, RouterError, RouterStats, bind_error, check_drones};
use super::gcs_signing::GcsSigning;
use super::refusal_log::RefusalLog;
use super::routing_table::{Counters, PeerTable, Shared, lock};
use super::sockets::{accept_tcp, drone_side, gcs_udp_side};

/// A running router; dropping it stops it.
pub struct RouterHandle {
    /// `None` once stopped: dropping it closes the sockets, so the ports are free again.
    pub(super) shared: Option<Arc<Shared>>,
    pub(super) counters: Arc<Counters>,
    pub(super) drones: usize,
    pub(super) threads: Vec<JoinHandle<()>>,
    pub(super) gcs_udp: SocketAddr,
    pub(super) gcs_tcp: SocketAddr,
    pub(super) drone_side: SocketAddr,
}

impl std::fmt::Debug for RouterHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RouterHandle")
            .field("gcs_udp", &self.gcs_udp)
            .field("gcs_tcp", &self.gcs_tcp)
            .field("drone_side", &self.drone_side)
            .field("drones", &self.drones)
            .field("running", &self.shared.is_some())
            .finish()
    }
}

/// Binds the GCS sockets and the drone-side socket and starts routing.
///
/// # Errors
/// A GCS address in use or not bindable, an invalid drone list (too many drones, system id
/// outside 1..=250 or repeated, mixed address families), or the OS refusing a socket option
/// or a thread.
pub fn start(config: RouterConfig) -> Result<RouterHandle, RouterError> {
    let drone_bind = check_drones(&config.drones)?;
    let gcs_udp = UdpSocket::bind(config.gcs_udp).map_err(|e| bind_error("GCS UDP", config.gcs_udp, e))?;
    let listener = TcpListener::bind(config.gcs_tcp).map_err(|e| bind_error("GCS TCP", config.gcs_tcp, e))?;
    let drone_socket = UdpSocket::bind(drone_bind).map_err(|e| bind_error("drone-side UDP", drone_bind, e))?;
    gcs_udp.set_read_timeout(Some(POLL))?;
    drone_socket.set_read_timeout(Some(POLL))?;
    // The accept loop polls: std offers no accept timeout.
    listener.set_nonblocking(true)?;

    let mut index_of = vec![None; 256];
    for (i, d) in config.drones.iter().enumerate() {
        index_of[usize::from(d.system_id)] = Some(i);
    }
    let shared = Arc::new(Shared {
        stop: AtomicBool::new(false),
        endpoints: config.drones.iter().map(|d| d.endpoint).collect(),
        drones: config.drones,
        index_of,
        drone_socket,
        gcs_udp,
        udp_peers: Mutex::new(PeerTable::default()),
        tcp_clients: Mutex::new(Vec::new()),
        tcp_threads: Mutex::new(Vec::new()),
        next_tcp_id: AtomicU64::new(0),
        counters: Arc::default(),
        signing: config.signing.map(GcsSigning::new),
        refusals: Mutex::new(RefusalLog::new(config.segment)),
        #[cfg(test)]
        logged: Mutex::default(),
    });
    let mut handle = RouterHandle {
        gcs_udp: shared.gcs_udp.local_addr()?,
        gcs_tcp: listener.local_addr()?,
        drone_side: shared.drone_socket.local_addr()?,
        counters: shared.counters.clone(),
        drones: shared.drones.len(),
        shared: Some(shared.clone()),
        threads: Vec::new(),
    };
    // On an error below, dropping `handle` stops the threads already started.
    let segment = config.segment;
    let s = shared.clone();
    handle.threads.push(spawn(format!("router-{segment}-drones"), move || drone_side(&s))?);
    let s = shared.clone();
    handle.threads.push(spawn(format!("router-{segment}-gcs-udp"), move || gcs_udp_side(&s))?);
    let s = shared;
    handle.threads.push(spawn(format!("router-{segment}-gcs-tcp"), move || accept_tcp(&s, &listener))?);
    Ok(handle)
}

impl RouterHandle {
    /// The bound GCS UDP address (useful when the configured port was 0).
    pub fn gcs_udp(&self) -> SocketAddr {
        self.gcs_udp
    }

    /// The bound GCS TCP address.
    pub fn gcs_tcp(&self) -> SocketAddr {
        self.gcs_tcp
    }

    /// The drone-side socket, as the drone endpoints see the router.
    pub fn drone_side(&self) -> SocketAddr {
        self.drone_side
    }

    /// Counters since start (client counts are 0 once stopped).
    pub fn stats(&self) -> RouterStats {
        let c = &self.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        RouterStats {
            frames_to_drones: get(&c.frames_to_drones),
            datagrams_to_gcs: get(&c.datagrams_to_gcs),
            dropped_unknown_target: get(&c.dropped_unknown_target),
            dropped_unknown_source: get(&c.dropped_unknown_source),
            bad_checksum: get(&c.bad_checksum),
            garbage_bytes: get(&c.garbage_bytes),
            dropped_gcs_backlog: get(&c.dropped_gcs_backlog),
            refused_tcp_clients: get(&c.refused_tcp_clients),
            refused_udp_gcs_frames: get(&c.refused_udp_gcs_frames),
            refused_unsigned: get(&c.refused_unsigned),
            refused_bad_signature: get(&c.refused_bad_signature),
            refused_old_timestamp: get(&c.refused_old_timestamp),
            gcs_udp_clients: self.shared.as_ref().map_or(0, |s| lock(&s.udp_peers).peers.len()),
            gcs_tcp_clients: self
                .shared
                .as_ref()
                .map_or(0, |s| lock(&s.tcp_clients).iter().filter(|c| !c.is_closed()).count()),
        }
    }

    /// Stops every thread and closes every socket, so the ports can be bound again; returns
    /// within about 100 ms. Idempotent.
    pub fn stop(&mut self) {
        let Some(shared) = self.shared.take() else { return };
        shared.stop.store(true, Ordering::Relaxed);
        // Unblocks TCP writers stuck on a client that does not read.
        for c in lock(&shared.tcp_clients).iter() {
            let _ = c.stream.shutdown(Shutdown::Both);
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        // The accept thread is gone, so no new client threads appear.
        let client_threads = std::mem::take(&mut *lock(&shared.tcp_threads));
        for t in client_threads {
            let _ = t.join();
        }
        // Every thread has ended, so this was the last reference: the sockets close here.
        drop(shared);
    }
}

impl Drop for RouterHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

pub(super) fn spawn(name: String, f: impl FnOnce() + Send + 'static) -> io::Result<JoinHandle<()>> {
    std::thread::Builder::new().name(name).spawn(f)
}
