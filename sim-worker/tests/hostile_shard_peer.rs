//! A shard peer that breaks the shard protocol mid-run: `sim-worker coordinator` with a
//! fake shard on the other end of its TCP connection, which greets it properly, then cuts
//! a window frame short and hangs up. The coordinator must end the run with an error that
//! names the peer and what it was reading, and still write the run's evidence (events,
//! summary, manifest), instead of hanging or panicking.

use std::io::{BufRead, BufReader, BufWriter, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{ChildStdout, Command, Stdio};

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::outcome::coordinator::Report;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::outcome::run_folder;
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::run::{Clock, ClockMode};
use sadesim_engine::protocol::{FromShard, PROTOCOL_VERSION, ToShard};
use sadesim_evidence::archive::verify;
use sim_worker::transport::{read_message, write_message};

const SIM_WORKER: &str = env!("CARGO_BIN_EXE_sim-worker");

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-hostile-shard-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read_report(stdout: &mut BufReader<ChildStdout>) -> Option<Report> {
    let mut line = String::new();
    (stdout.read_line(&mut line).unwrap() > 0)
        .then(|| serde_json::from_str(&line).unwrap_or_else(|e| panic!("not a report line {line:?}: {e}")))
}

/// The plan of a one-drone, one-shard fixture run, written to `dir`.
fn write_plan(dir: &Path) -> PathBuf {
    let run = RunBuilder::test()
        .with(|r| r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None }))
        .build();
    let plan = sadesim_planner::plan(&run).expect("the fixture plans");
    assert_eq!(plan.shards.len(), 1);
    let path = dir.join(run_folder::PLAN);
    std::fs::write(&path, serde_json::to_vec_pretty(&plan).unwrap()).unwrap();
    path
}

#[test]
fn a_shard_peer_that_cuts_a_frame_short_fails_the_run_naming_it_and_the_evidence_is_written() {
    let dir = temp("truncated");
    let plan = write_plan(&dir);
    let out = dir.join("out");
    let mut coordinator = Command::new(SIM_WORKER)
        .args(["coordinator", "--plan"])
        .arg(&plan)
        .args(["--listen", "127.0.0.1:0", "--airspace-bind", "127.0.0.1:0", "--shard-timeout", "20", "--out"])
        .arg(&out)
        // The coordinator pod's end: report and manifest (no archive to upload to).
        .arg("--finish-run")
        .env_remove("SADESIM_ARCHIVE_URL")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sim-worker starts");
    let mut stdout = BufReader::new(coordinator.stdout.take().unwrap());
    let Some(Report::Listening { address, .. }) = read_report(&mut stdout) else { panic!("expected listening first") };

    // The fake shard: a proper greeting, then half of a window frame, then it hangs up.
    let stream = TcpStream::connect(&address).unwrap();
    let peer = stream.local_addr().unwrap().to_string();
    let (mut reader, mut writer) = (BufReader::new(stream.try_clone().unwrap()), BufWriter::new(stream));
    let mut buf = Vec::new();
    write_message(&mut writer, &FromShard::Hello { version: PROTOCOL_VERSION, shard: 0, drones: 1 }, &mut buf).unwrap();
    let first = read_message::<ToShard>(&mut reader, &mut buf).unwrap();
    assert!(matches!(first, Some(ToShard::Advance { .. })), "{first:?}");
    writer.write_all(&1000u32.to_le_bytes()).unwrap();
    writer.write_all(b"W\x00\x00\x00\x00\x00\x00\x00\x00\x00").unwrap();
    writer.flush().unwrap();
    writer.get_ref().shutdown(std::net::Shutdown::Both).unwrap();
    drop((reader, writer));

    let (shard, address, reason, summary) = loop {
        match read_report(&mut stdout) {
            Some(Report::Failed { shard, address, reason, summary, .. }) => break (shard, address, reason, summary),
            Some(_) => {}
            None => panic!("the coordinator ended without reporting the shard's failure"),
        }
    };
    let status = coordinator.wait().unwrap();
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut coordinator.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(!status.success(), "{status}\n{stderr}");
    assert_eq!(shard, Some(0), "{reason}");
    assert_eq!(address.as_deref(), Some(peer.as_str()), "{reason}");
    // The peer, and what was expected of it.
    let expected = "the stream ended inside a frame of 1000 bytes (10 of them received, a window (`W`) frame)";
    assert!(reason.contains(&peer) && reason.contains(expected), "{reason}");
    assert!(summary.is_some(), "no summary in the failure report");

    // The evidence: a summary saying why, the events ending with it, a manifest that holds.
    let folder = out.clone();
    let summary: RunSummary =
        serde_json::from_slice(&std::fs::read(folder.join(run_folder::SUMMARY)).unwrap()).unwrap();
    let EndReason::ShardFailed(why) = &summary.end_reason else { panic!("{:?}", summary.end_reason) };
    assert!(why.contains(&peer) && why.contains(expected), "{why}");
    let events = std::fs::read_to_string(folder.join(run_folder::EVENTS)).unwrap();
    let last = events.lines().last().expect("events were written");
    assert!(last.contains("\"runEnded\"") && last.contains(expected), "{last}");
    let report = verify(folder.to_str().unwrap()).unwrap();
    assert!(report.passed(), "{report:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
