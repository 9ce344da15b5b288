//! `sim-worker coordinator`: accepts one TCP connection per shard, runs the lockstep loop
//! with the recorder, and reports progress as JSON lines on stdout. When stdin is not a
//! terminal it reads [`Control`] lines from it (`sadesim run --processes` ends the run
//! this way when the pilot exits).

use std::io::{BufRead, IsTerminal, Write};
use std::net::{SocketAddr, TcpListener, ToSocketAddrs};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use sadesim_crds::plan::RunPlan;
use serde::{Deserialize, Serialize};

use super::RoleError;
use crate::airspace::runtime::{AIRSPACE_FILE, Airspace, WithAirspace};
use crate::coordinator::{self, RunObserver, ShardLink};
use crate::events::{Event, EventKind};
use crate::protocol::{DroneSnapshot, FleetCounts, FromShard, PROTOCOL_VERSION};
use crate::record::{Recorder, RecorderOptions, RunSummary};
use crate::transport::TcpLink;

/// One line of the coordinator's stdout.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Report {
    /// Bound and waiting for shards; the airspace API listens at `airspace`.
    Listening { address: String, airspace: String },
    /// Progress, about once per simulated second.
    Progress {
        sim_time_s: f64,
        /// Flattened: the line reads `{"type":"progress","simTimeS":..,"airborne":..,...}`.
        #[serde(flatten)]
        counts: FleetCounts,
    },
    /// The pilots were released at `sim_time_s` (the `pilotsReleased` event, already in
    /// `events.jsonl`): time to start the pilot process.
    PilotsReleased { sim_time_s: f64 },
    /// The run is over and its files are written.
    Finished { summary: RunSummary },
}

/// One line of the coordinator's stdin.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Control {
    /// End the run after the current window with this reason (e.g. `pilotExited`).
    Stop { reason: String },
}

/// Writes a report line to stdout (ignored when nobody reads it).
pub fn report(r: &Report) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, r);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// Forwards windows to the recorder and reports progress.
struct Reporting<'a> {
    recorder: &'a mut Recorder,
    next_report_s: f64,
    /// The reason of a [`Control::Stop`] read from stdin.
    stop_request: Arc<Mutex<Option<String>>>,
}

impl RunObserver for Reporting<'_> {
    fn on_window(&mut self, time_s: f64, drones: &[DroneSnapshot], events: &[Event]) -> Result<(), String> {
        self.recorder.on_window(time_s, drones, events)?;
        if time_s >= self.next_report_s {
            self.next_report_s = time_s.floor() + 1.0;
            report(&Report::Progress { sim_time_s: time_s, counts: FleetCounts::of(drones) });
        }
        if let Some(e) = events.iter().find(|e| matches!(e.kind, EventKind::PilotsReleased)) {
            report(&Report::PilotsReleased { sim_time_s: e.time_s });
        }
        Ok(())
    }

    fn stop_reason(&mut self) -> Option<String> {
        self.stop_request.lock().ok()?.take()
    }
}

/// Reads [`Control`] lines from stdin on a thread, unless stdin is a terminal (a
/// coordinator started by hand in the background must not read it).
fn read_control() -> Arc<Mutex<Option<String>>> {
    let slot = Arc::new(Mutex::new(None));
    if !std::io::stdin().is_terminal() {
        let requests = slot.clone();
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                if let Ok(Control::Stop { reason }) = serde_json::from_str(&line)
                    && let Ok(mut r) = requests.lock()
                {
                    *r = Some(reason);
                }
            }
        });
    }
    slot
}

/// Accepts the plan's shards on `listen`, runs the run, records into `out_dir`.
///
/// # Errors
/// Network, protocol, shard and recording failures.
pub fn run(
    plan: &RunPlan,
    listen: impl ToSocketAddrs,
    airspace_bind: SocketAddr,
    out_dir: &Path,
    stop: &AtomicBool,
) -> Result<RunSummary, RoleError> {
    // The airspace API is up before any shard connects, so it answers as soon as pilots
    // are released. Credentials from Secrets arrive as SADESIM_CREDENTIAL_<GROUP>.
    let mut airspace = Airspace::new(plan, &|key| std::env::var(key).ok());
    let airspace_addr = airspace
        .serve(airspace_bind)
        .map_err(|e| RoleError::Protocol(format!("airspace API: cannot listen on {airspace_bind}: {e}")))?;
    let listener = TcpListener::bind(listen)?;
    report(&Report::Listening { address: listener.local_addr()?.to_string(), airspace: airspace_addr.to_string() });
    let mut links: Vec<Option<Box<dyn ShardLink>>> = (0..plan.shards.len()).map(|_| None).collect();
    for _ in 0..plan.shards.len() {
        let (stream, _) = listener.accept()?;
        let mut link = TcpLink::new(stream)?;
        // The Hello tells which shard connected; the coordinator reads it again below, so
        // keep it for the loop by re-queueing through a small wrapper.
        let hello = link.recv().map_err(|e| RoleError::Protocol(format!("shard greeting: {e}")))?;
        let FromShard::Hello { shard, version, drones } = hello.clone() else {
            return Err(RoleError::Protocol(format!("expected a Hello, got {hello:?}")));
        };
        if version != PROTOCOL_VERSION {
            return Err(RoleError::Protocol(format!(
                "shard {shard} speaks protocol {version}, expected {PROTOCOL_VERSION}"
            )));
        }
        let slot = links
            .get_mut(shard as usize)
            .ok_or_else(|| RoleError::Protocol(format!("shard {shard} is not in the plan")))?;
        if slot.is_some() {
            return Err(RoleError::Protocol(format!("shard {shard} connected twice")));
        }
        *slot = Some(Box::new(Greeted { hello: Some(FromShard::Hello { shard, version, drones }), link }));
    }
    let mut links: Vec<Box<dyn ShardLink>> = links.into_iter().flatten().collect();
    let record_err = |source| RoleError::Record { path: out_dir.display().to_string(), source };
    let mut recorder = Recorder::create(out_dir, plan, RecorderOptions::default()).map_err(record_err)?;
    let mut observer = Reporting { recorder: &mut recorder, next_report_s: 0.0, stop_request: read_control() };
    let outcome = coordinator::run(plan, &mut links, &mut WithAirspace::new(&mut airspace, &mut observer), stop)?;
    let json = serde_json::to_vec_pretty(&airspace.record()).map_err(std::io::Error::other).map_err(record_err)?;
    std::fs::write(out_dir.join(AIRSPACE_FILE), json).map_err(record_err)?;
    recorder.set_verdict(airspace.verdict(plan, outcome.sim_time_s));
    let summary = recorder.finish(&outcome).map_err(record_err)?;
    report(&Report::Finished { summary: summary.clone() });
    Ok(summary)
}

/// A link whose first message (the Hello, already read to identify the shard) is replayed.
struct Greeted {
    hello: Option<FromShard>,
    link: TcpLink,
}

impl ShardLink for Greeted {
    fn send(&mut self, msg: &crate::protocol::ToShard) -> Result<(), coordinator::LinkError> {
        self.link.send(msg)
    }
    fn recv(&mut self) -> Result<FromShard, coordinator::LinkError> {
        match self.hello.take() {
            Some(h) => Ok(h),
            None => self.link.recv(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_lines_keep_their_flat_shape() {
        let line = serde_json::to_string(&Report::Progress {
            sim_time_s: 1.0,
            counts: FleetCounts { airborne: 4, on_ground: 0, crashed: 0 },
        })
        .unwrap();
        assert_eq!(line, r#"{"type":"progress","simTimeS":1.0,"airborne":4,"onGround":0,"crashed":0}"#);
        assert!(matches!(serde_json::from_str::<Report>(&line).unwrap(), Report::Progress { .. }));
    }

    #[test]
    fn pilot_lines_have_their_documented_shape() {
        let released = serde_json::to_string(&Report::PilotsReleased { sim_time_s: 0.01 }).unwrap();
        assert_eq!(released, r#"{"type":"pilotsReleased","simTimeS":0.01}"#);
        let stop: Control = serde_json::from_str(r#"{"type":"stop","reason":"pilotExited"}"#).unwrap();
        assert_eq!(stop, Control::Stop { reason: "pilotExited".into() });
    }
}
