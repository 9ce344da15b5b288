//! An axum server on a thread of its own: one current-thread tokio runtime on a named OS
//! thread, so the roles that serve HTTP (the airspace API, the live view) keep their own
//! loops synchronous and the simulation keeps the cores.

use std::net::SocketAddr;
use std::time::Duration;

/// A running server. Stops when dropped or on [`HttpThread::stop`]: requests in flight get
/// the server's grace period, then the runtime is dropped (which cuts any connection still
/// open), and the thread is joined.
#[derive(Debug)]
pub struct HttpThread {
    /// Where it listens (the actual port when bound to port 0).
    pub addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl HttpThread {
    /// `http://host:port/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Stops the server and waits for its thread.
    pub fn stop(mut self) {
        self.shut_down();
    }

    fn shut_down(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for HttpThread {
    fn drop(&mut self) {
        self.shut_down();
    }
}

/// `serve(bind)`, or when that port is taken (another run on this machine) `serve` on a
/// free port of the same address: local runs print or write the address they got, so a
/// second run beside the first still works.
///
/// # Errors
/// `serve`'s error other than a taken port, or the free port's.
pub fn or_free_port<T>(
    bind: SocketAddr,
    mut serve: impl FnMut(SocketAddr) -> std::io::Result<T>,
) -> std::io::Result<T> {
    match serve(bind) {
        Err(e) if e.kind() == std::io::ErrorKind::AddrInUse && bind.port() != 0 => serve(SocketAddr::new(bind.ip(), 0)),
        other => other,
    }
}

/// Serves `app` on `bind` from the thread `name`. The socket is bound before this returns:
/// port 0 picks a free port, reported in [`HttpThread::addr`]. On stop, requests in flight
/// get at most `grace` to finish (zero: none, for endless streams).
///
/// # Errors
/// The address cannot be bound, or the runtime or thread cannot be created.
pub fn start(bind: SocketAddr, app: axum::Router, name: &str, grace: Duration) -> std::io::Result<HttpThread> {
    let listener = std::net::TcpListener::bind(bind)?;
    listener.set_nonblocking(true)?;
    let addr = listener.local_addr()?;
    let runtime = tokio::runtime::Builder::new_current_thread().enable_io().enable_time().build()?;
    let listener = {
        let _context = runtime.enter();
        tokio::net::TcpListener::from_std(listener)?
    };
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::Builder::new().name(name.into()).spawn(move || {
        runtime.block_on(async move {
            let (graceful_tx, graceful_rx) = tokio::sync::oneshot::channel::<()>();
            let server = axum::serve(listener, app).with_graceful_shutdown(async move {
                let _ = graceful_rx.await;
            });
            let server = tokio::spawn(async move { server.await });
            // `stop()` sends; a dropped handle closes the channel: either way, stop.
            let _ = stop_rx.await;
            let _ = graceful_tx.send(());
            let _ = tokio::time::timeout(grace, server).await;
        });
        // Dropping the runtime here cuts any connection still open after the grace period.
    })?;
    Ok(HttpThread { addr, stop: Some(stop_tx), thread: Some(thread) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_taken_port_falls_back_to_a_free_one_on_the_same_address() {
        let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let bind = taken.local_addr().unwrap();
        let got = or_free_port(bind, |a| std::net::TcpListener::bind(a).and_then(|l| l.local_addr())).unwrap();
        assert_eq!(got.ip(), bind.ip());
        assert_ne!(got.port(), bind.port());
        // Any other error is returned as it is.
        let refused =
            or_free_port(bind, |_| -> std::io::Result<()> { Err(std::io::ErrorKind::PermissionDenied.into()) });
        assert_eq!(refused.unwrap_err().kind(), std::io::ErrorKind::PermissionDenied);
    }
}
