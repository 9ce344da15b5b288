//! The pilot under test as a child process of `sadesim run` (DESIGN §3, role "pilot"):
//! prepared before the run, started when the coordinator releases the pilots, watched
//! after every window, and stopped with the run.
//!
//! # Guarantees
//! - The pilot starts at most once, and only after the `pilotsReleased` event has been
//!   recorded in `events.jsonl`.
//! - When the run ends (duration, Ctrl-C, failure) a pilot still running gets SIGTERM, then
//!   SIGKILL after [`TERM_GRACE`]; both go to its whole process group, so programs it
//!   started itself stop too.
//! - Credential values are passed in the environment only: they never appear in
//!   `fleet.json`, `pilot.json` or `Debug` output.
//! - How the pilot ended is judged against `spec.pilot.expectedExit` ([`outcome`]): by
//!   default an exit it made itself with a code other than 0, or by a signal, fails the
//!   run, with its exit and the last lines of `pilot.log` in `summary.json`.
//!
//! # Caveats
//! The pilot runs in its own process group so that Ctrl-C in the terminal reaches `sadesim`
//! (which ends the run cleanly and then stops the pilot) and not the pilot directly. If
//! `sadesim` itself is killed with SIGKILL, the pilot is left running.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use sadesim_crds::fleet::Credential;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::{ExpectedExit, Pilot, PilotExit};

use sadesim_planner::credential_env_var;

use sadesim_crds::outcome::ending::EndReason;
pub use sadesim_crds::outcome::pilot::{PilotOutcome, PilotRecord};

/// The fleet file in the output folder (path in `SADESIM_FLEET`).
pub const FLEET_FILE: &str = sadesim_crds::outcome::run_folder::FLEET;
/// The pilot's stdout and stderr, interleaved, in the output folder.
pub const LOG_FILE: &str = sadesim_crds::outcome::run_folder::PILOT_LOG;
/// What happened to the pilot ([`PilotRecord`]), in the output folder.
pub const RECORD_FILE: &str = sadesim_crds::outcome::run_folder::PILOT_RECORD;
/// The variable that holds the base URL of the run's onboard camera frames.
pub use sadesim_planner::CAMERAS_URL_ENV;
/// Time between SIGTERM and SIGKILL when the run ends before the pilot.
pub const TERM_GRACE: Duration = Duration::from_secs(5);

/// Why the pilot could not be prepared or started.
#[derive(Debug, thiserror::Error)]
pub enum PilotError {
    /// `spec.pilot` names only an image: nothing to start on this machine.
    #[error(
        "spec.pilot.command: a local run starts the pilot from `command` (program and arguments) but the scenario gives only `image`; add `command`, or run with --no-pilot and start the pilot yourself"
    )]
    NoCommand,
    /// A credential that only Kubernetes can resolve.
    #[error(
        "spec.fleet[{group}].credential.secretKeyRef: not supported locally (Secret {secret:?} lives in Kubernetes); give the credential as `value` for local runs, or run with --no-pilot and set {env} yourself"
    )]
    SecretRef { group: usize, secret: String, env: String },
    /// A folder the pilot needs as an absolute path could not be resolved.
    #[error("failed to resolve the folder {path}: {source}")]
    Folder { path: String, source: std::io::Error },
    /// `pilot.log` could not be created.
    #[error("failed to create the pilot log {path}: {source}")]
    Log { path: String, source: std::io::Error },
    /// The program could not be started.
    #[error("spec.pilot.command[0]: failed to start {program:?} in {dir}: {reason}")]
    Start { program: String, dir: String, reason: String },
}

/// Everything needed to start the pilot, resolved before the run starts.
#[derive(Clone)]
pub struct Launch {
    /// `spec.pilot.command`, as written.
    pub command: Vec<String>,
    /// The program to execute: `command[0]`, made absolute against `dir` when it is a
    /// relative path (`./pilot.sh`); a bare name (`python3`) is looked up in `PATH`.
    pub program: PathBuf,
    /// Working directory: the scenario file's folder (absolute).
    pub dir: PathBuf,
    /// Variables added to the inherited environment, in order.
    pub env: Vec<(String, String)>,
    /// The log file (stdout and stderr).
    pub log: PathBuf,
    pub on_exit: PilotExit,
    /// `spec.pilot.expectedExit` (default `success`).
    pub expected_exit: ExpectedExit,
}

impl std::fmt::Debug for Launch {
    /// Variable names only: values may be credentials.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Launch")
            .field("command", &self.command)
            .field("program", &self.program)
            .field("dir", &self.dir)
            .field("env", &self.env.iter().map(|(k, _)| k.as_str()).collect::<Vec<_>>())
            .field("log", &self.log)
            .field("on_exit", &self.on_exit)
            .field("expected_exit", &self.expected_exit)
            .finish()
    }
}

fn absolute(path: &Path) -> Result<PathBuf, PilotError> {
    std::path::absolute(path).map_err(|source| PilotError::Folder { path: path.display().to_string(), source })
}

impl Launch {
    /// Resolves `pilot` for a run of `plan` whose scenario file is `scenario` (`None`: read
    /// from stdin, the pilot starts in the current directory) and whose output folder is
    /// `out_dir` (which need not exist yet).
    ///
    /// The pilot's environment is `sadesim`'s, plus `spec.pilot.env`, plus `SADESIM_FLEET`
    /// (absolute path of `fleet.json`), `SADESIM_RUN` (run name), `SADESIM_OUT` (absolute
    /// output folder), `SADESIM_SCENARIO` (absolute path of the scenario file, when the run
    /// was read from one) and, for each group with a credential, `SADESIM_CREDENTIAL_<GROUP>`;
    /// a run with onboard cameras adds `SADESIM_CAMERAS_URL` ([`Self::set_cameras_url`]).
    ///
    /// # Errors
    /// [`PilotError::NoCommand`], [`PilotError::SecretRef`] (naming the field), or
    /// [`PilotError::Folder`].
    pub fn prepare(plan: &RunPlan, pilot: &Pilot, scenario: Option<&Path>, out_dir: &Path) -> Result<Self, PilotError> {
        let Some(first) = pilot.command.first() else { return Err(PilotError::NoCommand) };
        let mut env: Vec<(String, String)> = pilot.env.iter().map(|e| (e.name.clone(), e.value.clone())).collect();
        for (i, group) in plan.spec.fleet.iter().enumerate() {
            match &group.credential {
                None => {}
                Some(Credential::Value(v)) => env.push((credential_env_var(&group.name), v.clone())),
                Some(Credential::SecretKeyRef(r)) => {
                    return Err(PilotError::SecretRef {
                        group: i,
                        secret: r.name.clone(),
                        env: credential_env_var(&group.name),
                    });
                }
            }
        }
        let out_dir = absolute(out_dir)?;
        let fleet = out_dir.join(FLEET_FILE);
        env.push(("SADESIM_FLEET".into(), fleet.display().to_string()));
        env.push(("SADESIM_RUN".into(), plan.run.name.clone()));
        env.push(("SADESIM_OUT".into(), out_dir.display().to_string()));
        if let Some(file) = scenario {
            env.push(("SADESIM_SCENARIO".into(), absolute(file)?.display().to_string()));
        }
        let dir = match scenario.and_then(Path::parent) {
            Some(p) if !p.as_os_str().is_empty() => absolute(p)?,
            _ => absolute(Path::new("."))?,
        };
        // A program with a path is relative to the scenario's folder; std leaves relative
        // program paths combined with `current_dir` unspecified, so resolve it here.
        let program = Path::new(first);
        let program =
            if program.components().count() > 1 && program.is_relative() { dir.join(program) } else { program.into() };
        Ok(Self {
            command: pilot.command.clone(),
            program,
            dir,
            env,
            log: out_dir.join(LOG_FILE),
            on_exit: pilot.on_exit.unwrap_or_default(),
            expected_exit: pilot.expected_exit.unwrap_or_default(),
        })
    }

    /// Points `SADESIM_SCENARIO` at `document` (made absolute) instead of the scenario file
    /// the pilot starts beside.
    ///
    /// # Errors
    /// [`PilotError::Folder`]: the path cannot be made absolute.
    pub fn set_scenario_document(&mut self, document: &Path) -> Result<(), PilotError> {
        let path = absolute(document)?.display().to_string();
        self.env.retain(|(k, _)| k != "SADESIM_SCENARIO");
        self.env.push(("SADESIM_SCENARIO".into(), path));
        Ok(())
    }

    /// Tells the pilot where the run's onboard camera frames are: `SADESIM_CAMERAS_URL`,
    /// the frame server's `/cameras` (known once the server listens, after [`Self::prepare`]).
    pub fn set_cameras_url(&mut self, cameras_url: &str) {
        self.env.retain(|(k, _)| k != CAMERAS_URL_ENV);
        self.env.push((CAMERAS_URL_ENV.into(), cameras_url.into()));
    }

    /// Starts the program in its own process group, stdin from /dev/null, stdout and
    /// stderr into the log.
    fn spawn(&self) -> Result<Child, PilotError> {
        let log_err = |source| PilotError::Log { path: self.log.display().to_string(), source };
        let log = File::create(&self.log).map_err(log_err)?;
        let stderr = log.try_clone().map_err(log_err)?;
        let mut cmd = Command::new(&self.program);
        cmd.args(&self.command[1..])
            .current_dir(&self.dir)
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(stderr);
        #[cfg(unix)]
        std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
        cmd.spawn().map_err(|e| PilotError::Start {
            program: self.command[0].clone(),
            dir: self.dir.display().to_string(),
            reason: match e.kind() {
                std::io::ErrorKind::NotFound => {
                    "program not found (a bare name is looked up in PATH, a path is relative to the scenario's folder)"
                        .into()
                }
                std::io::ErrorKind::PermissionDenied => "permission denied (is it executable?)".into(),
                _ => e.to_string(),
            },
        })
    }
}

/// Where the pilot process is in its life.
#[derive(Debug)]
enum State {
    /// Waiting for the coordinator to release the pilots.
    Waiting,
    Running {
        child: Child,
        started_at_s: f64,
    },
    Exited {
        pid: u32,
        started_at_s: f64,
        exited_at_s: f64,
        /// Wall seconds from the start of the run.
        exited_at_wall_s: f64,
        status: Option<ExitStatus>,
        by_runner: bool,
    },
    /// Starting failed; the run fails.
    Failed,
}

/// Starts, watches and stops the pilot of one run.
#[derive(Debug)]
pub struct Supervisor {
    launch: Launch,
    state: State,
    /// Latest simulated time the runner reported, s.
    now_s: f64,
    /// When the run started (the supervisor is made just before it), for wall times.
    run_started: Instant,
}

/// The reason to end the run for the pilot, if any: it could not be started (`failed`), or
/// it exited and `onExit` is `endRun` (`exited`, [`Supervisor::poll`]).
pub fn end_reason(failed: bool, exited: bool) -> Option<EndReason> {
    if failed {
        Some(EndReason::PilotFailed)
    } else if exited {
        Some(EndReason::PilotExited)
    } else {
        None
    }
}

impl Supervisor {
    pub fn new(launch: Launch) -> Self {
        Self { launch, state: State::Waiting, now_s: 0.0, run_started: Instant::now() }
    }

    /// The onboard cameras' frames are served at `cameras_url` ([`Launch::set_cameras_url`]);
    /// known once the server listens, before the pilot starts.
    pub fn set_cameras_url(&mut self, cameras_url: &str) {
        self.launch.set_cameras_url(cameras_url);
    }

    /// Records that simulated time reached `sim_time_s` (it never goes back).
    pub fn advance(&mut self, sim_time_s: f64) {
        self.now_s = self.now_s.max(sim_time_s);
    }

    /// Starts the pilot: the coordinator released the pilots. Later calls do nothing.
    ///
    /// # Errors
    /// The log cannot be created or the program cannot be started; the pilot is then never
    /// started (its record has no `startedAtS`).
    pub fn start(&mut self) -> Result<(), PilotError> {
        if !matches!(self.state, State::Waiting) {
            return Ok(());
        }
        match self.launch.spawn() {
            Ok(child) => {
                self.state = State::Running { child, started_at_s: self.now_s };
                Ok(())
            }
            Err(e) => {
                self.state = State::Failed;
                Err(e)
            }
        }
    }

    /// Notices an exit of the pilot. True when the run should end now: the pilot has
    /// exited and `onExit` is `endRun`.
    pub fn poll(&mut self) -> bool {
        if let State::Running { child, started_at_s } = &mut self.state
            && let Ok(Some(status)) = child.try_wait()
        {
            self.state = State::Exited {
                pid: child.id(),
                started_at_s: *started_at_s,
                exited_at_s: self.now_s,
                exited_at_wall_s: self.run_started.elapsed().as_secs_f64(),
                status: Some(status),
                by_runner: false,
            };
        }
        matches!(self.state, State::Exited { .. }) && self.launch.on_exit == PilotExit::EndRun
    }

    /// The run is over: stops a pilot that is still running (SIGTERM to its process
    /// group, SIGKILL after [`TERM_GRACE`]) and tells what happened. Blocks at most about
    /// [`TERM_GRACE`].
    pub fn finish(&mut self) -> PilotRecord {
        self.poll();
        if let State::Running { child, started_at_s } = &mut self.state {
            let status = stop(child);
            self.state = State::Exited {
                pid: child.id(),
                started_at_s: *started_at_s,
                exited_at_s: self.now_s,
                exited_at_wall_s: self.run_started.elapsed().as_secs_f64(),
                status,
                by_runner: true,
            };
        }
        let l = &self.launch;
        let mut record = PilotRecord {
            command: l.command.clone(),
            working_dir: l.dir.display().to_string(),
            on_exit: l.on_exit,
            expected_exit: l.expected_exit,
            log: LOG_FILE.into(),
            pid: None,
            started_at_s: None,
            exited_at_s: None,
            exited_at_wall_s: None,
            exit_code: None,
            signal: None,
            stopped_by_runner: false,
        };
        if let State::Exited { pid, started_at_s, exited_at_s, exited_at_wall_s, status, by_runner } = &self.state {
            record.pid = Some(*pid);
            record.started_at_s = Some(*started_at_s);
            record.exited_at_s = Some(*exited_at_s);
            record.exited_at_wall_s = Some(*exited_at_wall_s);
            record.exit_code = status.and_then(|s| s.code());
            record.signal = status.and_then(signal_of);
            record.stopped_by_runner = *by_runner;
        }
        record
    }
}

/// Bytes read from the end of `pilot.log` for its tail.
const TAIL_BYTES: u64 = 64 * 1024;

/// The `pilot` section of `summary.json` for `record`: its end judged against
/// `spec.pilot.expectedExit`, with the last lines of the log in `out_dir` (none when it
/// cannot be read).
pub fn outcome(record: &PilotRecord, out_dir: &Path) -> PilotOutcome {
    record.outcome(
        read_tail(&out_dir.join(&record.log)).map(|t| sadesim_crds::outcome::pilot::log_tail(&t)).unwrap_or_default(),
    )
}

/// The last [`TAIL_BYTES`] of `path` as text (invalid UTF-8 replaced), from the first
/// whole line.
fn read_tail(path: &Path) -> std::io::Result<String> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = File::open(path)?;
    let len = file.metadata()?.len();
    let from = len.saturating_sub(TAIL_BYTES);
    file.seek(SeekFrom::Start(from))?;
    let mut bytes = Vec::new();
    file.take(TAIL_BYTES).read_to_end(&mut bytes)?;
    let text = String::from_utf8_lossy(&bytes).into_owned();
    Ok(match (from, text.split_once('\n')) {
        (1.., Some((_, rest))) => rest.to_string(),
        _ => text,
    })
}

impl Drop for Supervisor {
    /// Never leaves a pilot behind, also when the runner unwinds.
    fn drop(&mut self) {
        if let State::Running { child, .. } = &mut self.state {
            let _ = stop(child);
        }
    }
}

#[cfg(unix)]
fn signal_of(status: ExitStatus) -> Option<i32> {
    std::os::unix::process::ExitStatusExt::signal(&status)
}

#[cfg(not(unix))]
fn signal_of(_: ExitStatus) -> Option<i32> {
    None
}

/// Sends `signal` to the process group led by `child` (through `kill`: no unsafe code).
fn signal_group(child: &Child, signal: &str) {
    let _ = Command::new("kill")
        .arg(format!("-{signal}"))
        .arg("--")
        .arg(format!("-{}", child.id()))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
}

/// SIGTERM, up to [`TERM_GRACE`] to exit, then SIGKILL; returns the exit status.
fn stop(child: &mut Child) -> Option<ExitStatus> {
    signal_group(child, "TERM");
    let deadline = Instant::now() + TERM_GRACE;
    while Instant::now() < deadline {
        match child.try_wait() {
            Ok(Some(status)) => return Some(status),
            Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            Err(_) => break,
        }
    }
    signal_group(child, "KILL");
    let _ = child.kill(); // in case `kill` is missing: the leader at least
    child.wait().ok()
}

#[cfg(test)]
mod tests {
    use sadesim_crds::fixtures::RunBuilder;
    use sadesim_crds::fleet::SecretKeyRef;
    use sadesim_crds::run::EnvVar;

    use super::*;

    fn plan_with(f: impl FnOnce(&mut sadesim_crds::SimulationRun)) -> RunPlan {
        sadesim_planner::plan(&RunBuilder::test().with_group("beta-team", 1).with(f).build()).unwrap()
    }

    fn pilot(command: &[&str]) -> Pilot {
        Pilot {
            image: None,
            command: command.iter().map(|s| s.to_string()).collect(),
            container_command: None,
            env: vec![EnvVar { name: "MY_VAR".into(), value: "1".into() }],
            ..Pilot::default()
        }
    }

    #[test]
    fn environment_has_the_scenario_env_run_variables_and_credentials() {
        let plan = plan_with(|r| r.spec.fleet[1].credential = Some(Credential::Value("s3cret".into())));
        let launch =
            Launch::prepare(&plan, &pilot(&["python3", "p.py"]), Some(Path::new("/s/scen.yaml")), Path::new("/o/r/t"))
                .unwrap();
        let names: Vec<&str> = launch.env.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(
            names,
            [
                "MY_VAR",
                "SADESIM_CREDENTIAL_BETA_TEAM",
                "SADESIM_FLEET",
                "SADESIM_RUN",
                "SADESIM_OUT",
                "SADESIM_SCENARIO"
            ]
        );
        assert_eq!(launch.env[5].1, "/s/scen.yaml");
        assert_eq!(launch.env[1].1, "s3cret");
        assert_eq!(launch.env[2].1, "/o/r/t/fleet.json");
        assert_eq!(launch.env[3].1, "test-run");
        assert_eq!((launch.dir.as_path(), launch.program.as_path()), (Path::new("/s"), Path::new("python3")));
        assert_eq!(launch.on_exit, PilotExit::EndRun);
        assert!(!format!("{launch:?}").contains("s3cret"), "credential values stay out of Debug output");
    }

    #[test]
    fn a_run_with_cameras_tells_the_pilot_where_the_frames_are() {
        let plan = plan_with(|_| {});
        let mut launch =
            Launch::prepare(&plan, &pilot(&["python3", "p.py"]), Some(Path::new("/s/scen.yaml")), Path::new("/o/r/t"))
                .unwrap();
        assert!(launch.env.iter().all(|(k, _)| k != CAMERAS_URL_ENV), "no frame server, no variable");
        launch.set_cameras_url("http://127.0.0.1:8091/cameras");
        launch.set_cameras_url("http://127.0.0.1:8092/cameras");
        let urls: Vec<&str> =
            launch.env.iter().filter(|(k, _)| k == CAMERAS_URL_ENV).map(|(_, v)| v.as_str()).collect();
        assert_eq!(urls, ["http://127.0.0.1:8092/cameras"]);
    }

    #[test]
    fn relative_paths_are_made_absolute_from_the_scenario_folder() {
        let plan = plan_with(|_| {});
        let launch =
            Launch::prepare(&plan, &pilot(&["./bin/pilot", "x"]), Some(Path::new("scen.yaml")), Path::new("runs/a"))
                .unwrap();
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(launch.dir, cwd);
        assert_eq!(launch.program, cwd.join("./bin/pilot"));
        assert_eq!(
            launch.env.iter().find(|(k, _)| k == "SADESIM_OUT").unwrap().1,
            cwd.join("runs/a").display().to_string()
        );
    }

    #[test]
    fn a_secret_credential_is_refused_locally_naming_the_field() {
        let plan = plan_with(|r| {
            r.spec.fleet[1].credential =
                Some(Credential::SecretKeyRef(SecretKeyRef { name: "dps".into(), key: "token".into() }))
        });
        let err = Launch::prepare(&plan, &pilot(&["p"]), None, Path::new("/o")).unwrap_err().to_string();
        assert!(err.starts_with("spec.fleet[1].credential.secretKeyRef: not supported locally"), "{err}");
        assert!(err.contains("SADESIM_CREDENTIAL_BETA_TEAM"), "{err}");
    }

    #[test]
    fn an_image_only_pilot_needs_a_command_locally() {
        let plan = plan_with(|_| {});
        let err = Launch::prepare(&plan, &pilot(&[]), None, Path::new("/o")).unwrap_err().to_string();
        assert!(err.starts_with("spec.pilot.command: a local run starts the pilot from `command`"), "{err}");
    }

    #[test]
    fn the_log_tail_is_read_from_the_end_of_a_long_log_in_whole_lines() {
        let dir = std::env::temp_dir().join(format!("sadesim-pilot-tail-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // 100 000 lines of 8 bytes: far more than the bytes read.
        let text: String = (0..100_000).map(|i| format!("l{i:06}\n")).collect();
        std::fs::write(dir.join(LOG_FILE), text).unwrap();
        let tail = read_tail(&dir.join(LOG_FILE)).unwrap();
        assert!(tail.len() as u64 <= TAIL_BYTES && tail.starts_with('l') && tail.ends_with("l099999\n"));
        let lines = sadesim_crds::outcome::pilot::log_tail(&tail);
        assert_eq!((lines.len(), lines[0].as_str()), (20, "l099980"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn records_describe_what_happened() {
        let mut r = PilotRecord {
            command: vec!["p".into()],
            working_dir: "/s".into(),
            on_exit: PilotExit::EndRun,
            expected_exit: ExpectedExit::Success,
            log: LOG_FILE.into(),
            pid: Some(1),
            started_at_s: Some(0.02),
            exited_at_s: Some(3.5),
            exited_at_wall_s: None,
            exit_code: Some(3),
            signal: None,
            stopped_by_runner: false,
        };
        assert_eq!(r.describe(), "started at 0.02 s, exited with code 3 at 3.50 s");
        (r.exit_code, r.signal, r.stopped_by_runner) = (None, Some(15), true);
        assert_eq!(r.describe(), "started at 0.02 s, still running at the end of the run, stopped (SIGTERM)");
        r.started_at_s = None;
        assert!(r.describe().starts_with("not started"));
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains(r#""onExit":"endRun""#) && json.contains(r#""stoppedByRunner":true"#), "{json}");
    }
}
