//! `sim-worker shard`: builds one shard from the plan, connects to the coordinator and
//! serves the protocol until told to stop.
//!
//! Across hosts the coordinator may come up after the shard (another pod, DNS not yet
//! resolving), so connecting is retried, each attempt bounded, until `connect_timeout`.
//! Losing the coordinator before it said `Stop` is an error (exit 2 with the address):
//! the run is over and this shard's part of it was not recorded to the end.
//!
//! The role owns the drones' MAVLink sockets ([`shard_io::ShardSockets`]), on a thread of
//! their own ([`MavlinkThread`]), both opened by [`shard_io::start`]; the shard core only
//! sees their queues.

use std::io::{BufReader, BufWriter};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use sadesim_crds::plan::RunPlan;

use super::RoleError;
use crate::shard_io::{self, MavlinkOptions, MavlinkThread};
use crate::transport;
use sadesim_engine::coordinator::LinkError;
use sadesim_engine::protocol::ToShard;
use sadesim_engine::shard::Shard;

/// Default of `--connect-timeout`: how long a shard keeps trying to reach a coordinator
/// that is not up yet (its pod scheduled later, its Service name not yet resolving).
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(60);

/// Longest single connection attempt. Without a bound, a SYN to an address nobody answers
/// (a host that is down, a firewall dropping packets) waits out the kernel's retries,
/// about two minutes, whatever `connect_timeout` says.
const ATTEMPT_TIMEOUT: Duration = Duration::from_secs(5);

/// Pause between attempts (a refused connection fails at once).
const RETRY_PAUSE: Duration = Duration::from_millis(200);

/// Runs shard `index` of `plan` in `surroundings` (see [`Shard::new`]) against the coordinator at `coordinator`
/// (host:port), trying to reach it for up to `connect_timeout`.
///
/// # Errors
/// When the shard cannot be built, the coordinator cannot be reached in time, or the
/// connection to it is lost before it says `Stop`.
pub fn run(
    plan: &RunPlan,
    surroundings: &sadesim_engine::shard::Surroundings,
    index: u32,
    coordinator: &str,
    mavlink: Option<&MavlinkOptions>,
    connect_timeout: Duration,
) -> Result<(), RoleError> {
    let (shard, sockets) = shard_io::start(plan, index, surroundings, mavlink)?;
    let stream = connect(coordinator, connect_timeout)?;
    // On stderr (the role's log), so a run across hosts says who was where.
    let local = stream.local_addr().map_or_else(|_| "?".into(), |a| a.to_string());
    eprintln!(
        "shard {index}: {} drones; connected to the coordinator at {coordinator} from {local}",
        shard.drones().len()
    );
    let drones = shard.drones().len();
    let busy_s = serve(shard, sockets, stream, coordinator)?;
    // The shard's own cost (what `summary.json` `shardCpuS` holds for in-process shards).
    eprintln!("shard {index}: stepped {drones} drones in {busy_s:.3} s of CPU (waits for the coordinator excluded)");
    Ok(())
}

/// Connects to `coordinator`, resolving and retrying until `timeout` has passed.
///
/// # Errors
/// [`RoleError::Protocol`] naming the address, the time waited and the last error.
pub fn connect(coordinator: &str, timeout: Duration) -> Result<TcpStream, RoleError> {
    let deadline = Instant::now() + timeout;
    let mut attempts = 0u32;
    loop {
        attempts += 1;
        let last_error = match coordinator.to_socket_addrs() {
            Ok(addresses) => {
                let mut last = "the name resolves to no address".to_string();
                for address in addresses {
                    let left = deadline.saturating_duration_since(Instant::now());
                    // A zero timeout is refused by the OS call: give a last attempt 1 ms.
                    match TcpStream::connect_timeout(&address, left.clamp(Duration::from_millis(1), ATTEMPT_TIMEOUT)) {
                        Ok(stream) => return Ok(stream),
                        Err(e) => last = format!("{address}: {e}"),
                    }
                }
                last
            }
            Err(e) => format!("cannot resolve it: {e}"),
        };
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(RoleError::Protocol(format!(
                "cannot reach the coordinator at {coordinator} within {} s ({attempts} attempts; last: {last_error}); \
                 check --coordinator and that the coordinator is listening there",
                timeout.as_secs_f64()
            )));
        }
        std::thread::sleep(left.min(RETRY_PAUSE));
    }
}

/// Serves the shard protocol over `stream` until the coordinator says `Stop`; returns the
/// CPU seconds spent handling its messages (see [`transport::serve`]).
fn serve(shard: Shard, sockets: Option<MavlinkThread>, stream: TcpStream, coordinator: &str) -> Result<f64, RoleError> {
    stream.set_nodelay(true)?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut writer = BufWriter::new(stream);
    let (mut incoming, mut outgoing) = (Vec::new(), Vec::new());
    let lost = |what: String| {
        RoleError::Protocol(format!(
            "lost the coordinator at {coordinator}: {what} before it ended the run (it exited or failed; see its output)"
        ))
    };
    transport::serve(
        shard,
        sockets,
        || match transport::read_message::<ToShard>(&mut reader, &mut incoming) {
            Ok(Some(msg)) => Ok(msg),
            Ok(None) | Err(LinkError::Closed) => Err(lost("the connection closed".into())),
            Err(LinkError::Io(e)) => Err(lost(e.to_string())),
            Err(LinkError::Decode(e)) => Err(lost(format!("unreadable message: {e}"))),
        },
        |reply| transport::write_message(&mut writer, &reply, &mut outgoing).map_err(|e| lost(e.to_string())),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_address_nobody_listens_on_fails_within_the_timeout_naming_it() {
        // Bind then drop: the port is free, so every attempt is refused.
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let address = format!("127.0.0.1:{port}");
        let err = connect(&address, Duration::from_millis(500)).unwrap_err().to_string();
        assert!(err.contains(&format!("cannot reach the coordinator at {address} within 0.5 s")), "{err}");
        assert!(err.contains("attempts; last: 127.0.0.1:"), "{err}");
    }

    #[test]
    fn a_name_that_does_not_resolve_is_reported_as_such() {
        let err = connect("no-such-host.invalid:7400", Duration::from_millis(300)).unwrap_err().to_string();
        assert!(err.contains("no-such-host.invalid:7400") && err.contains("cannot resolve it"), "{err}");
    }

    #[test]
    fn a_listening_coordinator_is_reached() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let address = listener.local_addr().unwrap().to_string();
        let stream = connect(&address, Duration::from_secs(5)).unwrap();
        assert_eq!(stream.peer_addr().unwrap().to_string(), address);
    }
}
