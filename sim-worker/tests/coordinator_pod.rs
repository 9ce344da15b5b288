//! The coordinator pod's program, run for real: `sim-worker coordinator --finish-run` and
//! one `sim-worker shard` process a shard, as the Kubernetes Pods run them (no shell, no
//! `sadesim` after it), with a `file://` archive standing in for object storage. The run
//! folder must arrive in the archive with the files a local run has (plan, report with its
//! plots, manifest last and verifiable), also when the Pod is deleted mid-run (SIGTERM),
//! and a failed upload must be told apart from a failed run by the exit status.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, ExitStatus, Stdio};

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::outcome::coordinator::{Report, UPLOAD_FAILED_EXIT};
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::outcome::run_folder;
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::{Clock, ClockMode};
use sadesim_evidence::archive::{Manifest, verify};

const SIM_WORKER: &str = env!("CARGO_BIN_EXE_sim-worker");
const UID: &str = "6f1c2a9e-0d4b-4e57-9a1b-3c8d2e7f5a10";

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-coordinator-pod-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The plan of a one-drone fixture run with a uid (as the operator's runs have), written
/// where the Pod's config volume would hold it.
fn write_plan(dir: &Path, clock: ClockMode) -> (PathBuf, RunPlan) {
    let run = RunBuilder::test()
        .with(|r| {
            r.metadata.uid = Some(UID.into());
            r.spec.clock = Some(Clock { mode: clock, factor: None });
        })
        .build();
    let plan = sadesim_planner::plan(&run).expect("the fixture plans");
    let path = dir.join("config").join(run_folder::PLAN);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(&path, serde_json::to_vec_pretty(&plan).unwrap()).unwrap();
    (path, plan)
}

/// A coordinator Pod and its shard processes.
struct Pod {
    coordinator: Child,
    stdout: BufReader<ChildStdout>,
    shards: Vec<Child>,
}

impl Pod {
    /// Starts the coordinator as the operator's Pod spec does (`--finish-run`, the archive
    /// from `SADESIM_ARCHIVE_URL`), then every shard once it listens.
    fn start(plan_file: &Path, plan: &RunPlan, out: &Path, archive_url: &str) -> Self {
        let mut coordinator = Command::new(SIM_WORKER)
            .args(["coordinator", "--plan"])
            .arg(plan_file)
            .args(["--listen", "127.0.0.1:0", "--airspace-bind", "127.0.0.1:0", "--out"])
            .arg(out)
            .arg("--finish-run")
            .env("SADESIM_ARCHIVE_URL", archive_url)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .spawn()
            .expect("sim-worker starts");
        let mut stdout = BufReader::new(coordinator.stdout.take().unwrap());
        let Report::Listening { address, .. } = next_report(&mut stdout) else { panic!("expected listening first") };
        let shards = (0..plan.shards.len())
            .map(|i| {
                Command::new(SIM_WORKER)
                    .args(["shard", "--plan"])
                    .arg(plan_file)
                    .args(["--shard", &i.to_string(), "--coordinator", &address, "--no-mavlink"])
                    .stdin(Stdio::null())
                    .stdout(Stdio::null())
                    .spawn()
                    .expect("sim-worker shard starts")
            })
            .collect();
        Pod { coordinator, stdout, shards }
    }

    /// Waits for every process; the coordinator's exit status. Its stdout is drained so a
    /// full pipe cannot stall it.
    fn wait(mut self) -> ExitStatus {
        while !matches!(read_report(&mut self.stdout), None | Some(Report::Finished { .. } | Report::Failed { .. })) {}
        std::io::copy(&mut self.stdout, &mut std::io::sink()).unwrap();
        let status = self.coordinator.wait().unwrap();
        for mut shard in self.shards {
            assert!(shard.wait().unwrap().success(), "a shard failed");
        }
        status
    }
}

fn read_report(stdout: &mut BufReader<ChildStdout>) -> Option<Report> {
    let mut line = String::new();
    (stdout.read_line(&mut line).unwrap() > 0)
        .then(|| serde_json::from_str(&line).unwrap_or_else(|e| panic!("not a report line {line:?}: {e}")))
}

fn next_report(stdout: &mut BufReader<ChildStdout>) -> Report {
    read_report(stdout).expect("the coordinator ended its stdout early")
}

/// The archived run folder `<archive>/default/test-run/<uid>/`: its manifest verifies, and
/// it lists what a local run folder has.
fn check_archived(archive: &Path, out: &Path) -> RunSummary {
    let folder = archive.join("default/test-run").join(UID);
    let url = format!("file://{}", folder.display());
    let report = verify(&url).unwrap();
    assert!(report.passed(), "{report:?}");
    let manifest: Manifest =
        serde_json::from_slice(&std::fs::read(folder.join(run_folder::MANIFEST)).unwrap()).unwrap();
    let listed: Vec<&str> = manifest.files.iter().map(|f| f.path.as_str()).collect();
    for name in [run_folder::PLAN, run_folder::SUMMARY, run_folder::EVENTS, run_folder::REPORT, "report/map.png"] {
        assert!(listed.contains(&name), "{name} is not archived: {listed:?}");
    }
    assert!(!listed.contains(&run_folder::REPORT_ERROR), "the report failed: {listed:?}");
    // The same files as the Pod's own folder (which has its manifest too).
    let local: Manifest = serde_json::from_slice(&std::fs::read(out.join(run_folder::MANIFEST)).unwrap()).unwrap();
    assert_eq!(local.files, manifest.files);
    let html = std::fs::read_to_string(folder.join(run_folder::REPORT)).unwrap();
    assert!(html.contains("test-run"), "the report names the run");
    serde_json::from_slice(&std::fs::read(folder.join(run_folder::SUMMARY)).unwrap()).unwrap()
}

#[test]
fn the_coordinator_pod_reports_and_archives_its_run_folder() {
    let dir = temp("archive");
    let (plan_file, plan) = write_plan(&dir, ClockMode::AsFastAsPossible);
    let (out, archive) = (dir.join("out"), dir.join("archive"));
    let status = Pod::start(&plan_file, &plan, &out, &format!("file://{}", archive.display())).wait();
    assert!(status.success(), "{status}");
    let summary = check_archived(&archive, &out);
    assert_eq!(summary.end_reason, EndReason::Duration);
    // The plan is the one the Pod was given, byte for byte.
    assert_eq!(std::fs::read(out.join(run_folder::PLAN)).unwrap(), std::fs::read(&plan_file).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A real-time run's Pod one simulated second in (the run under way), archiving to a
/// `file://` folder: `(dir, out, archive, pod)`.
fn one_second_into_a_realtime_run(name: &str) -> (PathBuf, PathBuf, PathBuf, Pod) {
    let dir = temp(name);
    let (plan_file, plan) = write_plan(&dir, ClockMode::Realtime);
    let (out, archive) = (dir.join("out"), dir.join("archive"));
    let mut pod = Pod::start(&plan_file, &plan, &out, &format!("file://{}", archive.display()));
    while !matches!(next_report(&mut pod.stdout), Report::Progress { sim_time_s, .. } if sim_time_s >= 1.0) {}
    (dir, out, archive, pod)
}

/// What deleting a Pod does to its process.
fn sigterm(pid: u32) {
    let killed = Command::new("kill").args(["-TERM", &pid.to_string()]).status().unwrap();
    assert!(killed.success());
}

/// Deleting the Pod sends SIGTERM to the coordinator (PID 1, no shell to pass it on): the
/// run ends there, and its files are still written, reported and archived.
#[test]
fn sigterm_ends_the_run_and_the_folder_is_still_archived() {
    let (dir, out, archive, pod) = one_second_into_a_realtime_run("sigterm");
    sigterm(pod.coordinator.id());
    let status = pod.wait();
    assert!(status.success(), "{status}");
    let summary = check_archived(&archive, &out);
    assert_eq!(summary.end_reason, EndReason::Interrupted);
    assert!(summary.sim_time_s < 60.0, "the run went on after SIGTERM: {}", summary.sim_time_s);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Deleting a shard's Pod sends SIGTERM to the shard (PID 1 of its container, where the
/// kernel ignores a signal the program does not handle): the shard ends at once with status
/// 143, the coordinator fails the run naming the shard, and still archives its folder.
#[test]
fn sigterm_ends_a_shard_at_once_and_the_coordinator_fails_the_run_naming_it() {
    let (dir, out, archive, mut pod) = one_second_into_a_realtime_run("shard-sigterm");
    let mut shard = pod.shards.remove(0);
    sigterm(shard.id());
    // Exit status 143 (our handler), not death by the signal's default action.
    assert_eq!(shard.wait().unwrap().code(), Some(143));
    let (failed_shard, reason) = loop {
        match read_report(&mut pod.stdout) {
            Some(Report::Failed { shard, reason, .. }) => break (shard, reason),
            Some(_) => {}
            None => panic!("the coordinator ended without reporting the shard's failure"),
        }
    };
    assert_eq!(failed_shard, Some(0), "{reason}");
    let status = pod.coordinator.wait().unwrap();
    assert!(!status.success(), "{status}");
    let summary = check_archived(&archive, &out);
    assert!(matches!(summary.end_reason, EndReason::ShardFailed(_)), "{:?}", summary.end_reason);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An archive that cannot take the upload: the run itself succeeded, so the exit status
/// is UPLOAD_FAILED_EXIT (not a failed run), and the Pod's folder keeps every file.
#[test]
fn a_failed_upload_has_its_own_exit_status() {
    let dir = temp("upload-failed");
    let (plan_file, plan) = write_plan(&dir, ClockMode::AsFastAsPossible);
    let out = dir.join("out");
    // A regular file where the archive's folders would go.
    let blocked = dir.join("not-a-folder");
    std::fs::write(&blocked, "").unwrap();
    let status = Pod::start(&plan_file, &plan, &out, &format!("file://{}/runs", blocked.display())).wait();
    assert_eq!(status.code(), Some(i32::from(UPLOAD_FAILED_EXIT)), "{status}");
    assert!(verify(out.to_str().unwrap()).unwrap().passed());
    assert!(out.join(run_folder::REPORT).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Local runs start the coordinator on the plan's airspace port, which another run on the
/// machine may hold (`sadesim run --processes` beside others, as parallel tests are): the
/// API moves to a free port, and the `listening` line says where it answers.
#[test]
fn a_taken_airspace_port_gives_way_to_a_free_one_that_is_reported() {
    use std::io::{Read, Write};
    let dir = temp("port-taken");
    let (plan_file, _) = write_plan(&dir, ClockMode::AsFastAsPossible);
    let held = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let taken = held.local_addr().unwrap();
    let mut coordinator = Command::new(SIM_WORKER)
        .args(["coordinator", "--plan"])
        .arg(&plan_file)
        .args(["--listen", "127.0.0.1:0", "--airspace-bind", &taken.to_string(), "--out"])
        .arg(dir.join("out"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("sim-worker starts");
    let mut stdout = BufReader::new(coordinator.stdout.take().unwrap());
    let first = read_report(&mut stdout);
    let Some(Report::Listening { airspace, .. }) = first else {
        let _ = coordinator.kill();
        panic!("expected listening first, got {first:?}");
    };
    let airspace: std::net::SocketAddr = airspace.parse().unwrap();
    assert_eq!(airspace.ip(), taken.ip());
    assert_ne!(airspace.port(), taken.port(), "reported the port another program holds");
    // The reported address is the airspace API.
    let mut http = std::net::TcpStream::connect(airspace).unwrap();
    http.write_all(b"GET /healthz HTTP/1.0\r\nHost: localhost\r\n\r\n").unwrap();
    let mut answer = String::new();
    http.read_to_string(&mut answer).unwrap();
    coordinator.kill().unwrap();
    coordinator.wait().unwrap();
    assert!(answer.starts_with("HTTP/1.0 200") || answer.starts_with("HTTP/1.1 200"), "{answer}");
    drop(held);
    std::fs::remove_dir_all(&dir).unwrap();
}
