//! The local backend: runs flown by this process with the local runner (`sadesim run`'s
//! code, given as a [`Launcher`]), each into `<runs>/<run>/<UTC time>/` like `sadesim run`.
//!
//! Runs are followed through [`LiveRun`]: the runner calls [`LiveRun::started`] and
//! [`LiveRun::window`]; every change wakes the pages watching (at most a few times a
//! second per run, however fast the run goes).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

use serde_json::Value;

use sadesim_crds::SimulationRun;
use sadesim_crds::outcome::run_folder;
use sadesim_crds::outcome::summary::FleetCounts;

use crate::model::{CameraStream, Condition, RunDetail, RunView, camera_streams, criteria_states};
use crate::time::{rfc3339, utc_stamp};

/// Flies a run with the local runner. Implemented by the `sadesim` binary (its runner is
/// in the CLI crate).
pub trait Launcher: Send + Sync {
    /// Flies `run` into `run_dir` (the runner creates it; it must not exist), blocking until
    /// the run ends. `scenario` is the run's own document (`SADESIM_SCENARIO`); pilots
    /// start in `pilot_dir`. `live` is told of the start and every window; `stop` ends the
    /// run as Ctrl-C would.
    ///
    /// # Errors
    /// Why the run could not start or did not finish, as `sadesim run` prints it.
    fn fly(
        &self,
        run: &SimulationRun,
        scenario: &Path,
        pilot_dir: &Path,
        run_dir: &Path,
        live: Arc<LiveRun>,
        stop: Arc<AtomicBool>,
    ) -> Result<(), String>;
}

/// Wakes the watchers of the runs list and of the runs' pages.
pub type Changes = tokio::sync::watch::Sender<u64>;

fn notify(changes: &Changes) {
    changes.send_modify(|n| *n = n.wrapping_add(1));
}

/// How often a flying run wakes its watchers at most.
const NOTIFY_EVERY: Duration = Duration::from_millis(250);

/// A run started by this console.
#[derive(Debug)]
pub struct LiveRun {
    pub id: String,
    pub name: String,
    pub namespace: String,
    pub dir: PathBuf,
    pub drones: u64,
    pub duration_s: f64,
    started_at: SystemTime,
    criteria: Vec<Value>,
    stop: Arc<AtomicBool>,
    changes: Changes,
    state: Mutex<LiveState>,
}

#[derive(Debug)]
struct LiveState {
    phase: &'static str,
    sim_time_s: f64,
    flying_since: Option<Instant>,
    /// Wall seconds from start to end, once over.
    flown_s: Option<f64>,
    view_url: Option<String>,
    message: Option<String>,
    verdict: Option<Value>,
    counts: FleetCounts,
    last_notified: Option<Instant>,
    /// From the run's `plan.json`, once it started.
    drone_names: Vec<String>,
    /// The onboard cameras' streams, while the live view serves them.
    cameras: Vec<CameraStream>,
}

impl LiveRun {
    /// The run folder exists and the run starts.
    pub fn started(&self, view_url: Option<String>) {
        let plan: Option<Value> =
            std::fs::read(self.dir.join(run_folder::PLAN)).ok().and_then(|b| serde_json::from_slice(&b).ok());
        let names = plan.as_ref().map(crate::archive::drone_names).unwrap_or_default();
        let cameras = match (&plan, &view_url) {
            (Some(plan), Some(view)) => camera_streams(plan, view),
            _ => Vec::new(),
        };
        let mut s = self.state.lock().expect("state lock");
        s.phase = "Running";
        s.drone_names = names;
        s.cameras = cameras;
        s.view_url = view_url;
        s.flying_since = Some(Instant::now());
        drop(s);
        notify(&self.changes);
    }

    /// A window was recorded.
    pub fn window(&self, time_s: f64, counts: FleetCounts) {
        let mut s = self.state.lock().expect("state lock");
        s.sim_time_s = time_s;
        s.counts = counts;
        let due = s.last_notified.is_none_or(|t| t.elapsed() >= NOTIFY_EVERY);
        if due {
            s.last_notified = Some(Instant::now());
        }
        drop(s);
        if due {
            notify(&self.changes);
        }
    }

    /// The run ended: its verdict from `summary.json`, or why it failed.
    fn finished(&self, outcome: Result<(), String>) {
        let summary: Option<Value> =
            std::fs::read(self.dir.join(run_folder::SUMMARY)).ok().and_then(|b| serde_json::from_slice(&b).ok());
        let mut s = self.state.lock().expect("state lock");
        s.view_url = None;
        s.cameras.clear();
        s.flown_s = s.flying_since.map(|t| t.elapsed().as_secs_f64());
        s.verdict = summary.as_ref().and_then(|v| v.get("verdict")).cloned();
        if let Some(t) = summary.as_ref().and_then(|v| v.get("simTimeS")).and_then(Value::as_f64) {
            s.sim_time_s = t;
        }
        let passed = s.verdict.as_ref().and_then(|v| v.get("passed")).and_then(Value::as_bool);
        let end = summary.as_ref().and_then(|v| v.get("endReason")).and_then(Value::as_str).map(String::from);
        (s.phase, s.message) = match (&outcome, passed) {
            (Err(e), _) => ("Failed", Some(e.clone())),
            (Ok(()), _) if end.as_deref() == Some("interrupted") => {
                ("Aborted", Some("stopped before its end; its evidence is in the archive".into()))
            }
            (Ok(()), Some(true)) => ("Succeeded", end.map(|e| format!("ended: {e}"))),
            (Ok(()), Some(false)) => ("Failed", Some("criteria failed".into())),
            (Ok(()), None) => ("Failed", Some("the run wrote no verdict".into())),
        };
        drop(s);
        notify(&self.changes);
    }

    /// Asks the run to stop (as Ctrl-C does: it ends `interrupted`, with its evidence).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::SeqCst);
        let mut s = self.state.lock().expect("state lock");
        if !is_over(s.phase) {
            s.message = Some("stopping: asked from the console".into());
        }
        drop(s);
        notify(&self.changes);
    }

    /// The runs list's row.
    pub fn view(&self) -> RunView {
        let s = self.state.lock().expect("state lock");
        let elapsed = s.flown_s.or_else(|| s.flying_since.map(|t| t.elapsed().as_secs_f64())).filter(|e| *e > 0.0);
        let over = is_over(s.phase);
        RunView {
            id: self.id.clone(),
            name: self.name.clone(),
            namespace: self.namespace.clone(),
            phase: s.phase.to_string(),
            progress: Some(if over { 1.0 } else { (s.sim_time_s / self.duration_s.max(1e-9)).clamp(0.0, 1.0) }),
            sim_time_s: s.sim_time_s,
            duration_s: self.duration_s,
            real_time_factor: elapsed.map(|e| s.sim_time_s / e),
            queue_position: None,
            verdict: s.verdict.as_ref().and_then(|v| v.get("passed")).and_then(Value::as_bool).map(verdict_word),
            message: s.message.clone(),
            started_at: rfc3339(self.started_at),
            drones: self.drones,
            archive_id: over.then(|| self.id.clone()),
        }
    }

    /// The run's page: its conditions, newest events, criteria and live view.
    pub fn detail(&self) -> RunDetail {
        let run = self.view();
        let s = self.state.lock().expect("state lock");
        let condition = |kind: &str, on: bool, reason: &str, message: String| Condition {
            kind: kind.into(),
            status: if on { "True" } else { "False" }.into(),
            reason: reason.into(),
            message,
        };
        let over = is_over(s.phase);
        let c = s.counts;
        let conditions = vec![
            condition("Valid", true, "Validated", "the scenario validated".into()),
            condition(
                "Running",
                s.phase == "Running",
                s.phase,
                format!(
                    "sim {:.1}/{:.0} s; airborne {}, on the ground {}, crashed {}",
                    s.sim_time_s, self.duration_s, c.airborne, c.on_ground, c.crashed
                ),
            ),
            condition("Complete", over, s.phase, s.message.clone().unwrap_or_default()),
        ];
        let criteria = criteria_states(&self.criteria, s.verdict.as_ref());
        let view_url = s.view_url.clone();
        let names = s.drone_names.clone();
        let cameras = s.cameras.clone();
        drop(s);
        let events = crate::archive::tail_events(&self.dir.join(run_folder::EVENTS), &names);
        RunDetail { run, conditions, events, criteria, view_url, cameras }
    }

    fn is_over(&self) -> bool {
        is_over(self.state.lock().expect("state lock").phase)
    }
}

/// Whether a run in `phase` has ended (the SimulationRun's final phases).
pub(crate) fn is_over(phase: &str) -> bool {
    matches!(phase, "Succeeded" | "Failed" | "Aborted")
}

pub(crate) fn verdict_word(passed: bool) -> String {
    if passed { "passed" } else { "failed" }.into()
}

/// The runs this console started, and how to start more.
pub struct LocalBackend {
    /// Where run folders go: also the archive the console browses.
    pub runs_root: PathBuf,
    /// Relative paths in scenarios (world files, pilots) are relative to this folder.
    pub scenario_dir: PathBuf,
    launcher: Arc<dyn Launcher>,
    runs: Mutex<Vec<Arc<LiveRun>>>,
    changes: Changes,
}

impl std::fmt::Debug for LocalBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LocalBackend").field("runs_root", &self.runs_root).finish_non_exhaustive()
    }
}

impl LocalBackend {
    pub fn new(runs_root: PathBuf, scenario_dir: PathBuf, launcher: Arc<dyn Launcher>) -> Self {
        Self { runs_root, scenario_dir, launcher, runs: Mutex::new(Vec::new()), changes: Changes::new(0) }
    }

    /// Subscribes to changes of any run.
    pub fn changes(&self) -> tokio::sync::watch::Receiver<u64> {
        self.changes.subscribe()
    }

    /// Every run started by this console, newest first.
    pub fn list(&self) -> Vec<RunView> {
        self.runs.lock().expect("runs lock").iter().rev().map(|r| r.view()).collect()
    }

    pub fn get(&self, id: &str) -> Option<Arc<LiveRun>> {
        self.runs.lock().expect("runs lock").iter().find(|r| r.id == id).cloned()
    }

    /// Starts `run` (valid) on a thread of its own; `document` is its text as exported.
    ///
    /// # Errors
    /// The scenario file cannot be written.
    pub fn launch(&self, mut run: SimulationRun, document: &str) -> Result<Arc<LiveRun>, String> {
        sadesim_sources::world::resolve_paths(&mut run, &self.scenario_dir);
        let name = run.metadata.name.clone().unwrap_or_else(|| "run".into());
        let namespace = run.metadata.namespace.clone().unwrap_or_else(|| "default".into());
        let now = SystemTime::now();
        let mut runs = self.runs.lock().expect("runs lock");
        let stamp = utc_stamp(now);
        let base = self.runs_root.join(&name);
        let (dir, stamp) = (1..)
            .map(|n| if n == 1 { stamp.clone() } else { format!("{stamp}-{n}") })
            .map(|s| (base.join(&s), s))
            .find(|(d, s)| !d.exists() && !runs.iter().any(|r| r.id == format!("{name}.{s}")))
            .expect("some suffix is free");
        // The run's own document, for its pilot (`SADESIM_SCENARIO`); the run folder keeps
        // the whole spec in plan.json.
        let scenarios = std::env::temp_dir().join(format!("sadesim-console-{}", std::process::id()));
        std::fs::create_dir_all(&scenarios).map_err(|e| format!("{}: {e}", scenarios.display()))?;
        let id = format!("{name}.{stamp}");
        let scenario = scenarios.join(format!("{id}.yaml"));
        std::fs::write(&scenario, document).map_err(|e| format!("{}: {e}", scenario.display()))?;
        let stop = Arc::new(AtomicBool::new(false));
        let live = Arc::new(LiveRun {
            id,
            name,
            namespace,
            dir: dir.clone(),
            drones: run.spec.total_drones(),
            duration_s: run.spec.duration_s(),
            started_at: now,
            criteria: serde_json::to_value(&run.spec.criteria)
                .ok()
                .and_then(|v| v.as_array().cloned())
                .unwrap_or_default(),
            stop: stop.clone(),
            changes: self.changes.clone(),
            state: Mutex::new(LiveState {
                phase: "GeneratingAssets",
                sim_time_s: 0.0,
                flying_since: None,
                flown_s: None,
                view_url: None,
                message: None,
                verdict: None,
                counts: FleetCounts::default(),
                last_notified: None,
                drone_names: Vec::new(),
                cameras: Vec::new(),
            }),
        });
        runs.push(live.clone());
        drop(runs);
        notify(&self.changes);
        let (launcher, thread_live, pilot_dir) = (self.launcher.clone(), live.clone(), self.scenario_dir.clone());
        std::thread::Builder::new()
            .name(format!("console-run-{}", live.name))
            .spawn(move || {
                let outcome = launcher.fly(&run, &scenario, &pilot_dir, &dir, thread_live.clone(), stop);
                let _ = std::fs::remove_file(&scenario);
                thread_live.finished(outcome);
            })
            .map_err(|e| format!("cannot start the run's thread: {e}"))?;
        Ok(live)
    }

    /// Stops every run still flying (the console is shutting down) and waits for them to
    /// write their evidence, at most `grace`.
    pub fn stop_all(&self, grace: Duration) {
        let runs: Vec<_> = self.runs.lock().expect("runs lock").clone();
        runs.iter().for_each(|r| r.stop.store(true, Ordering::SeqCst));
        let deadline = Instant::now() + grace;
        while runs.iter().any(|r| !r.is_over()) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flies nothing: follows `script` and writes the summary a real run would.
    struct Scripted {
        passed: Option<bool>,
        until_stopped: bool,
        fail: Option<&'static str>,
    }

    impl Launcher for Scripted {
        fn fly(
            &self,
            _run: &SimulationRun,
            scenario: &Path,
            _pilot_dir: &Path,
            run_dir: &Path,
            live: Arc<LiveRun>,
            stop: Arc<AtomicBool>,
        ) -> Result<(), String> {
            assert!(scenario.is_file(), "the run's own document is written for its pilot");
            std::fs::create_dir_all(run_dir).unwrap();
            live.started(Some("http://127.0.0.1:8490/".into()));
            let mut t = 0.0;
            while self.until_stopped && !stop.load(Ordering::SeqCst) {
                t += 0.5;
                live.window(t, FleetCounts { airborne: 1, on_ground: 0, crashed: 0 });
                std::thread::sleep(Duration::from_millis(5));
            }
            if let Some(e) = self.fail {
                return Err(e.into());
            }
            let end = if self.until_stopped { "interrupted" } else { "duration" };
            let verdict = self.passed.map(|p| serde_json::json!({"passed": p, "criteria": []}));
            let summary = serde_json::json!({"simTimeS": 40.0, "endReason": end, "verdict": verdict});
            std::fs::write(run_dir.join(run_folder::SUMMARY), summary.to_string()).unwrap();
            Ok(())
        }
    }

    fn backend(launcher: Scripted) -> (LocalBackend, PathBuf) {
        let root = std::env::temp_dir().join(format!("console-local-{}-{}", std::process::id(), rand_suffix()));
        (LocalBackend::new(root.clone(), root.clone(), Arc::new(launcher)), root)
    }

    fn rand_suffix() -> u64 {
        use std::sync::atomic::AtomicU64;
        static N: AtomicU64 = AtomicU64::new(0);
        N.fetch_add(1, Ordering::SeqCst)
    }

    fn wait_over(run: &LiveRun) -> RunView {
        for _ in 0..500 {
            if run.is_over() {
                return run.view();
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("the run never ended: {:?}", run.view());
    }

    fn quickstart() -> SimulationRun {
        sadesim_crds::fixtures::RunBuilder::test().build()
    }

    #[test]
    fn a_run_goes_from_assets_to_its_verdict() {
        let (b, root) = backend(Scripted { passed: Some(true), until_stopped: false, fail: None });
        let mut changes = b.changes();
        let live = b.launch(quickstart(), "kind: SimulationRun\n").unwrap();
        assert!(live.dir.starts_with(&root));
        let v = wait_over(&live);
        assert_eq!((v.phase.as_str(), v.verdict.as_deref(), v.sim_time_s), ("Succeeded", Some("passed"), 40.0));
        assert_eq!(v.archive_id.as_deref(), Some(v.id.as_str()));
        assert!(changes.has_changed().unwrap(), "watchers were woken");
        assert_eq!(b.list().len(), 1);
        assert!(b.get(&v.id).is_some() && b.get("other.20260101T000000Z").is_none());
        let _ = changes.borrow_and_update();
        std::fs::remove_dir_all(root).ok();
    }

    #[test]
    fn failed_criteria_a_runner_error_and_no_verdict_fail_the_run() {
        for (launcher, message) in [
            (Scripted { passed: Some(false), until_stopped: false, fail: None }, "criteria failed"),
            (Scripted { passed: None, until_stopped: false, fail: Some("shard 0 failed") }, "shard 0 failed"),
            (Scripted { passed: None, until_stopped: false, fail: None }, "the run wrote no verdict"),
        ] {
            let (b, root) = backend(launcher);
            let v = wait_over(&b.launch(quickstart(), "").unwrap());
            assert_eq!(v.phase, "Failed");
            assert_eq!(v.message.as_deref(), Some(message));
            std::fs::remove_dir_all(root).ok();
        }
    }

    #[test]
    fn a_stopped_run_ends_aborted_and_its_live_view_goes() {
        let (b, root) = backend(Scripted { passed: Some(true), until_stopped: true, fail: None });
        let live = b.launch(quickstart(), "").unwrap();
        while live.view().sim_time_s < 1.0 {
            std::thread::sleep(Duration::from_millis(5));
        }
        let flying = live.detail();
        assert_eq!(flying.run.phase, "Running");
        assert_eq!(flying.view_url.as_deref(), Some("http://127.0.0.1:8490/"));
        assert!(flying.run.progress.unwrap() > 0.0);
        live.stop();
        let v = wait_over(&live);
        assert_eq!(v.phase, "Aborted");
        assert_eq!(live.detail().view_url, None);
        std::fs::remove_dir_all(root).ok();
    }

    #[test]
    fn two_runs_of_one_scenario_in_one_second_get_their_own_folders() {
        let (b, root) = backend(Scripted { passed: Some(true), until_stopped: false, fail: None });
        let a = b.launch(quickstart(), "").unwrap();
        let c = b.launch(quickstart(), "").unwrap();
        assert_ne!(a.id, c.id);
        assert_ne!(a.dir, c.dir);
        wait_over(&a);
        wait_over(&c);
        std::fs::remove_dir_all(root).ok();
    }
}
