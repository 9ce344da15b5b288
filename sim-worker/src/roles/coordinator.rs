//! `sim-worker coordinator`: accepts one TCP connection per shard, runs the lockstep loop
//! with the recorder, and reports progress as JSON lines on stdout. A [`StopRequest`] ends
//! the run early: a stdin line from `sadesim run --processes` when the pilot exits, or the
//! Pod annotation the operator sets on Kubernetes (`super::control`).
//!
//! A shard that dies mid-run (its process exits, its host or network goes away, it
//! stops answering for `shard_timeout`) fails the run: the surviving shards are told to
//! stop, the run's files are finished up to the last complete window (`events.jsonl`
//! ends with `runEnded`, `summary.json` has `endReason: "shardFailed: ..."`), a
//! [`Report::Failed`] line goes to stdout and the process exits non-zero.

use std::io::Write;
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sadesim_crds::outcome::run_folder;
use sadesim_crds::plan::RunPlan;
use sadesim_evidence::finish::{Finished, RunAddress, finish_run};
use sadesim_world::World;

pub use sadesim_crds::outcome::coordinator::{FailedRole, Report};

use super::RoleError;
use super::control::StopRequest;
use crate::airspace::runtime::Airspace;
use crate::conduct::{ConductError, Watchers, conduct};
use crate::record::RunSummary;
use crate::transport::TcpLink;
use sadesim_engine::coordinator::{
    CoordinatorError, LinkError, ObserverError, PilotHold, RunFailure, RunObserver, ShardLink,
};
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::{DroneSnapshot, FromShard, PROTOCOL_VERSION};

/// Default of `--shard-timeout`: the longest wait for a shard's answer to a window. A shard
/// whose process dies is noticed at once (its connection closes); this bounds the wait
/// for one whose host went down or whose network was cut, where no FIN ever arrives. A
/// window takes milliseconds, so this only needs to cover a stalled machine.
pub const SHARD_TIMEOUT: Duration = Duration::from_secs(120);

/// Writes a report line to stdout (ignored when nobody reads it).
pub fn report(r: &Report) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, r);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// Reports progress and the pilots' release on stdout, and passes on requests to end the
/// run (the conductor records every window before it).
struct Reporting {
    next_report_s: f64,
    /// Where a request to end the run early arrives.
    stop_request: StopRequest,
}

impl RunObserver for Reporting {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), ObserverError> {
        if time_s >= self.next_report_s {
            self.next_report_s = time_s.floor() + 1.0;
            report(&Report::Progress { sim_time_s: time_s, counts: sadesim_engine::protocol::fleet_counts(drones) });
        }
        if let Some(e) = events.iter().find(|e| matches!(e.kind, EventKind::PilotsReleased)) {
            report(&Report::PilotsReleased { sim_time_s: e.time_s });
        }
        Ok(())
    }

    fn stop_reason(&mut self) -> Option<sadesim_engine::events::EndReason> {
        self.stop_request.take()
    }
}

/// How long the coordinator waits for what.
#[derive(Debug, Clone, Copy, Default)]
pub struct Timeouts {
    /// Longest wait for every shard to connect (`None`: wait forever; pods may wait for an
    /// image pull or a node).
    pub connect: Option<Duration>,
    /// Longest wait for a shard's answer to a window during the run (`None`: forever).
    pub shard: Option<Duration>,
}

/// What ends the run or the wait for shards: Ctrl-C/SIGTERM (`stop`), the timeouts, and
/// stop requests (the Pod's annotation, stdin).
#[derive(Debug)]
pub struct Ends<'a> {
    pub stop: &'a AtomicBool,
    pub timeouts: Timeouts,
    pub requests: StopRequest,
    /// A pilot is started on the release: hold for it ([`PilotHold::for_plan`]), which ends
    /// the run `pilotNotConnected` when it stays silent.
    pub hold_for_pilot: bool,
}

/// The end of the coordinator pod (`--finish-run`), after [`run`] whatever its outcome:
/// `plan.json` (the bytes of `plan_file`) into `out_dir` so the folder has the files of a
/// local run, then [`finish_run`]: report, manifest, and the upload to
/// `<upload_to>/<namespace>/<run>/<uid>/` (the plan's run; the folder name as uid for a run
/// without one). Problems go to stderr and into the returned [`Finished`].
pub fn finish(plan_file: &Path, plan: &RunPlan, world: &World, out_dir: &Path, upload_to: Option<&str>) -> Finished {
    let copy = out_dir.join(run_folder::PLAN);
    let same = |a: &Path, b: &Path| matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b);
    if !same(plan_file, &copy)
        && let Err(e) = std::fs::copy(plan_file, &copy)
    {
        // The report then names the missing plan.json; the other files are still archived.
        eprintln!("warning: cannot copy the plan {} to {}: {e}", plan_file.display(), copy.display());
    }
    let folder_name = out_dir.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let uid = plan.run.uid.as_deref().unwrap_or(folder_name);
    let address = RunAddress { namespace: &plan.run.namespace, run: &plan.run.name, uid };
    let finished = finish_run(out_dir, address, upload_to, false, Some(world));
    if let Some(e) = &finished.report_error {
        eprintln!("warning: the run's report was not written (the run's other files are kept): {e}");
    }
    match &finished.archived {
        Ok(Some(uploaded)) => eprintln!("archived the run folder to {}", uploaded.url),
        Ok(None) => eprintln!("no archive URL: the run folder is not uploaded"),
        Err(e) => eprintln!("error: the run folder was not archived: {e}"),
    }
    finished
}

/// Accepts the plan's shards on `listen`, runs the run, records into `out_dir` (the city
/// drawn in the recording is `world`). Shards that have not connected after
/// `ends.timeouts.connect`, or `ends.stop` while waiting for them, end the role before the
/// run starts; a shard that sends nothing for `ends.timeouts.shard` during the run fails
/// it. A request in `ends.requests` ends the run after the current window with its reason.
/// With `spec.rendering.enabled` the live stream (`/live`, and the page itself) is served on
/// `view_bind` (default 127.0.0.1 at the plan's renderer port) for the renderer to follow.
/// The airspace API is served on `airspace_bind`. When either port is taken, a free port is
/// used instead; the [`Report::Listening`] line says where each one answers.
///
/// # Errors
/// Network, protocol, shard and recording failures; each is also reported as a
/// [`Report::Failed`] line.
pub fn run(
    plan: &RunPlan,
    world: &World,
    listen: impl ToSocketAddrs,
    airspace_bind: SocketAddr,
    out_dir: &Path,
    ends: Ends<'_>,
    view_bind: Option<SocketAddr>,
) -> Result<RunSummary, RoleError> {
    let Ends { stop, timeouts, requests, hold_for_pilot } = ends;
    let result = (|| {
        // The onboard cameras render in the conductor's observer, and their frames are
        // served with the live stream (`/cameras`), which is up before the shards connect:
        // the renderer follows it from the start.
        let view_bind = view_bind.unwrap_or_else(|| SocketAddr::from(([127, 0, 0, 1], plan.services.renderer_http)));
        let mut watchers = Watchers::start(plan, world, view_bind).map_err(RoleError::Protocol)?;
        // The airspace API is up before any shard connects, so it answers as soon as pilots
        // are released. Credentials from Secrets arrive as SADESIM_CREDENTIAL_<GROUP>.
        // A port another program holds (a local run beside other runs; never in a pod, which
        // has its own network namespace) gives way to a free one, as the live view's does:
        // the `listening` line reports where it answers, and `sadesim run --processes`
        // writes that address into the fleet file.
        let mut airspace = Airspace::new(plan, &|key| std::env::var(key).ok());
        let airspace_addr = crate::http_thread::or_free_port(airspace_bind, |addr| airspace.serve(addr))
            .map_err(|e| RoleError::Protocol(format!("airspace API: cannot listen on {airspace_bind}: {e}")))?;
        let listener = TcpListener::bind(listen)?;
        report(&Report::Listening {
            address: listener.local_addr()?.to_string(),
            airspace: airspace_addr.to_string(),
            view: watchers.live.as_ref().map(|l| l.server.addr.to_string()),
        });
        let mut links: Vec<Option<Box<dyn ShardLink>>> = (0..plan.shards.len()).map(|_| None).collect();
        let deadline = timeouts.connect.map(|t| Instant::now() + t);
        for _ in 0..plan.shards.len() {
            let (stream, peer) = accept(&listener, stop, deadline, &links, timeouts.connect)?;
            let mut link = Greeted::new(stream, peer, timeouts.shard)?;
            // The Hello tells which shard connected; `Greeted` replays it to the loop.
            let hello =
                link.link.recv().map_err(|e| RoleError::Protocol(format!("shard greeting from {peer}: {e}")))?;
            let FromShard::Hello { shard, version, drones } = hello.clone() else {
                return Err(RoleError::Protocol(format!("expected a Hello from {peer}, got {hello:?}")));
            };
            if version != PROTOCOL_VERSION {
                return Err(RoleError::Protocol(format!(
                    "shard {shard} ({peer}) speaks protocol {version}, expected {PROTOCOL_VERSION}"
                )));
            }
            let slot = links
                .get_mut(shard as usize)
                .ok_or_else(|| RoleError::Protocol(format!("shard {shard} ({peer}) is not in the plan")))?;
            if slot.is_some() {
                return Err(RoleError::Protocol(format!("shard {shard} connected twice (again from {peer})")));
            }
            // On stderr (the role's log), so a run across hosts says who was where.
            eprintln!("shard {shard} connected from {peer} ({drones} drones)");
            link.hello = Some(FromShard::Hello { shard, version, drones });
            *slot = Some(Box::new(link));
        }
        let links: Vec<Box<dyn ShardLink>> = links.into_iter().flatten().collect();
        let mut reporting = Reporting { next_report_s: 0.0, stop_request: requests };
        // The shards are processes elsewhere: their CPU time is not known here.
        let hold = hold_for_pilot.then(|| PilotHold::for_plan(plan)).flatten();
        if let Some(h) = &hold {
            eprintln!(
                "holding simulated time at the release until the pilot's MAVLink reaches one of its {} drones (at most {} s)",
                h.drones.len(),
                h.limit.as_secs()
            );
        }
        let conducted = conduct(
            plan,
            world,
            links,
            &mut airspace,
            &mut watchers,
            out_dir,
            stop,
            &mut reporting,
            hold.as_ref(),
            || None,
        );
        match conducted {
            Ok(summary) => {
                report(&Report::Finished { summary: summary.clone() });
                Ok(summary)
            }
            Err(ConductError::RunFailed { failure, closed }) => Err(failed(failure, closed, out_dir)),
            Err(ConductError::Record(source)) => Err(RoleError::Record { path: out_dir.display().to_string(), source }),
            Err(ConductError::Coordinator(e)) => Err(e.into()),
        }
    })();
    match &result {
        // Reported with the shard's details and the summary by `failed`.
        Err(RoleError::Coordinator(CoordinatorError::RunFailed(_))) | Ok(_) => {}
        Err(e) => report(&Report::Failed {
            role: FailedRole::Coordinator,
            shard: None,
            address: None,
            reason: e.to_string(),
            summary: None,
        }),
    }
    result
}

/// The next shard connection on `listener`. Polls every 50 ms so that `stop` (Ctrl-C) and
/// `deadline` are seen while no shard comes; `connected` names the missing shards.
fn accept<T>(
    listener: &TcpListener,
    stop: &AtomicBool,
    deadline: Option<Instant>,
    connected: &[Option<T>],
    connect_timeout: Option<Duration>,
) -> Result<(TcpStream, SocketAddr), RoleError> {
    let missing = || {
        let missing: Vec<String> =
            connected.iter().enumerate().filter(|(_, c)| c.is_none()).map(|(i, _)| i.to_string()).collect();
        format!("shard{} {} of {}", if missing.len() == 1 { "" } else { "s" }, missing.join(", "), connected.len())
    };
    listener.set_nonblocking(true)?;
    loop {
        match listener.accept() {
            Ok((stream, peer)) => {
                // The shard link does blocking reads with its own timeouts.
                stream.set_nonblocking(false)?;
                return Ok((stream, peer));
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.into()),
        }
        if stop.load(Ordering::Relaxed) {
            return Err(RoleError::NotConnected(format!("interrupted while waiting for {} to connect", missing())));
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            let waited = connect_timeout.unwrap_or_default().as_secs_f64();
            return Err(RoleError::NotConnected(format!(
                "{} did not connect within {waited} s (--connect-timeout); check that the shard pods or processes started and can reach this address",
                missing()
            )));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A shard failed and the conductor closed the run's files (`closed`: their summary, or why
/// that failed too): reports it on stdout and stderr, and returns the error to exit with.
fn failed(failure: Box<RunFailure>, closed: Result<Box<RunSummary>, String>, out_dir: &Path) -> RoleError {
    report(&Report::Failed {
        role: FailedRole::Shard,
        shard: Some(failure.shard),
        address: failure.peer.clone(),
        reason: failure.to_string(),
        summary: closed.as_ref().ok().map(|s| s.as_ref().clone()),
    });
    match closed {
        Ok(_) => eprintln!("the run's files up to the failure are in {}", out_dir.display()),
        Err(e) => eprintln!("writing the run's files into {} after the failure failed too: {e}", out_dir.display()),
    }
    RoleError::Coordinator(CoordinatorError::RunFailed(failure))
}

/// A shard's TCP connection whose first message (the Hello, already read to identify the
/// shard) is replayed, and which knows the shard's address.
struct Greeted {
    hello: Option<FromShard>,
    link: TcpLink,
    peer: SocketAddr,
    timeout: Option<Duration>,
}

impl Greeted {
    fn new(stream: TcpStream, peer: SocketAddr, timeout: Option<Duration>) -> std::io::Result<Self> {
        // On the socket, so the clones inside `TcpLink` share them. A write blocks only
        // when the shard stopped reading and the socket buffers are full.
        stream.set_read_timeout(timeout)?;
        stream.set_write_timeout(timeout)?;
        Ok(Self { hello: None, link: TcpLink::new(stream)?, peer, timeout })
    }

    /// Names socket errors for what they mean here: a timeout is a shard that stopped
    /// answering; a reset, like an end of stream, a shard that is gone (which of the two
    /// a dead process leaves depends on whether we were writing or reading).
    fn explain(&self, e: LinkError) -> LinkError {
        use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset, UnexpectedEof};
        match (e, self.timeout) {
            (LinkError::Io(io), _)
                if matches!(io.kind(), ConnectionReset | BrokenPipe | ConnectionAborted | UnexpectedEof) =>
            {
                LinkError::Closed
            }
            (LinkError::Io(io), Some(t))
                if matches!(io.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
            {
                LinkError::Io(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    format!(
                        "no answer for {} s (--shard-timeout); its host may be down or the network cut",
                        t.as_secs_f64()
                    ),
                ))
            }
            (e, _) => e,
        }
    }
}

impl ShardLink for Greeted {
    fn send(&mut self, msg: &sadesim_engine::protocol::ToShard) -> Result<(), LinkError> {
        self.link.send(msg).map_err(|e| self.explain(e))
    }
    fn recv(&mut self) -> Result<FromShard, LinkError> {
        match self.hello.take() {
            Some(h) => Ok(h),
            None => self.link.recv().map_err(|e| self.explain(e)),
        }
    }
    fn peer(&self) -> Option<String> {
        Some(self.peer.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    use crate::record::test_dir::TempDir;
    use sadesim_engine::fixtures::{plan_of, run_with_groups, world_of};

    /// The coordinator of a 4-drone plan in 2 shards on free ports of 127.0.0.1.
    fn wait_for_shards(name: &str, stop: &AtomicBool, connect: Option<Duration>) -> (RoleError, Duration) {
        let dir = TempDir::new(name);
        let plan = plan_of(run_with_groups(&[("a", 4)]).with_drones_per_shard(2).build());
        assert_eq!(plan.shards.len(), 2);
        let world = world_of(&plan);
        let started = Instant::now();
        let timeouts = Timeouts { connect, shard: None };
        let any = SocketAddr::from(([127, 0, 0, 1], 0));
        let error = run(
            &plan,
            &world,
            "127.0.0.1:0",
            any,
            &dir.0,
            Ends { stop, timeouts, requests: StopRequest::new(), hold_for_pilot: false },
            None,
        )
        .expect_err("no shard connects");
        (error, started.elapsed())
    }

    #[test]
    fn shards_that_do_not_connect_in_time_are_named() {
        let (error, waited) =
            wait_for_shards("connect-timeout", &AtomicBool::new(false), Some(Duration::from_millis(300)));
        assert!(matches!(error, RoleError::NotConnected(_)), "{error:?}");
        let message = error.to_string();
        assert!(message.starts_with("shards 0, 1 of 2 did not connect within 0.3 s (--connect-timeout)"), "{message}");
        assert!(waited >= Duration::from_millis(300), "gave up after {waited:?}");
    }

    #[test]
    fn ctrl_c_while_waiting_for_shards_ends_the_role() {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let press = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(200));
            flag.store(true, Ordering::Relaxed);
            Instant::now()
        });
        // No connect timeout: only the stop flag ends the wait (so it ends after the press,
        // however long planning and building the world took before it).
        let (error, _) = wait_for_shards("connect-interrupted", &stop, None);
        let ended = Instant::now();
        let pressed = press.join().unwrap();
        assert_eq!(error.to_string(), "interrupted while waiting for shards 0, 1 of 2 to connect");
        assert!(ended >= pressed, "the wait ended {:?} before the press", pressed - ended);
    }

    #[test]
    fn progress_lines_keep_their_flat_shape() {
        let line = serde_json::to_string(&Report::Progress {
            sim_time_s: 1.0,
            counts: sadesim_engine::protocol::FleetCounts { airborne: 4, on_ground: 0, crashed: 0 },
        })
        .unwrap();
        assert_eq!(line, r#"{"type":"progress","simTimeS":1.0,"airborne":4,"onGround":0,"crashed":0}"#);
        assert!(matches!(serde_json::from_str::<Report>(&line).unwrap(), Report::Progress { .. }));
    }

    #[test]
    fn pilot_lines_have_their_documented_shape() {
        let released = serde_json::to_string(&Report::PilotsReleased { sim_time_s: 0.01 }).unwrap();
        assert_eq!(released, r#"{"type":"pilotsReleased","simTimeS":0.01}"#);
        let stop: super::super::control::Control =
            serde_json::from_str(r#"{"type":"stop","reason":"pilotExited"}"#).unwrap();
        assert_eq!(stop, super::super::control::Control::Stop { reason: "pilotExited".into() });
    }

    #[test]
    fn failure_lines_name_the_role_and_the_shard() {
        let shard = Report::Failed {
            role: FailedRole::Shard,
            shard: Some(1),
            address: Some("10.77.0.3:40122".into()),
            reason: "shard 1 (10.77.0.3:40122) failed: connection closed".into(),
            summary: None,
        };
        let line = serde_json::to_string(&shard).unwrap();
        assert_eq!(
            line,
            r#"{"type":"failed","role":"shard","shard":1,"address":"10.77.0.3:40122","reason":"shard 1 (10.77.0.3:40122) failed: connection closed"}"#
        );
        assert_eq!(serde_json::from_str::<Report>(&line).unwrap(), shard);
        let own = serde_json::to_string(&Report::Failed {
            role: FailedRole::Coordinator,
            shard: None,
            address: None,
            reason: "network: address in use".into(),
            summary: None,
        })
        .unwrap();
        assert_eq!(own, r#"{"type":"failed","role":"coordinator","reason":"network: address in use"}"#);
    }
}
