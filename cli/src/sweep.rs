//! `sadesim sweep`: a `SimulationSweep` run on this machine. Its runs fly a few at a time
//! (each on its own MAVLink ports), each in its own folder under the sweep's folder, and
//! the sweep's report (`sweep.json`, `sweep.html`) is built from their `summary.json`
//! files. A rerun skips every run whose evidence is complete and verifies.
//!
//! The sweep's folder:
//!
//! ```text
//! <out>/<sweep>/
//!   sweep-definition.json   the sweep and its resolved base run: a rerun must match it
//!   scenarios/<run>.yaml    each run's own document (`sadesim run` on it flies that run alone)
//!   <run>/                  each run's folder, as `sadesim run` writes it (manifest.json last)
//!   sweep.json, sweep.html  the report
//! ```

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::outcome::run_folder::{MANIFEST, SUMMARY};
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::run::{Clock, SimulationRunSpec};
use sadesim_crds::sweep::{Expansion, SimulationSweep, expand, parse_sweep};
use sadesim_crds::{DocumentError, FieldError, ValidationErrors};
use sadesim_evidence::sweep::{SweepRecord, SweepReport};
use serde::{Deserialize, Serialize};

use crate::runner::{RunOptions, run_local};

/// The file in a sweep's folder that pins what it runs.
pub const DEFINITION: &str = "sweep-definition.json";
/// The folder of the runs' own documents.
pub const SCENARIOS: &str = "scenarios";

/// Why a sweep did not run.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("{path}: cannot read: {source}")]
    Read { path: String, source: std::io::Error },
    #[error("{path}: {source}")]
    Document { path: String, source: DocumentError },
    /// `spec.base.file` cannot be read as one SimulationRun.
    #[error("{path}: spec.base.file {file:?}: {message}")]
    BaseFile { path: String, file: String, message: String },
    /// Every problem of the sweep, each with its field path.
    #[error("{path}: {} problem(s)\n{errors}", errors.0.len())]
    Invalid { path: String, errors: ValidationErrors },
    /// The sweep's folder holds another sweep (or another version of this one).
    #[error(
        "{dir} holds the runs of a different sweep definition ({DEFINITION} differs): give another --out, or delete the folder to start over"
    )]
    Different { dir: String },
    #[error("{path}: {source}")]
    Write { path: String, source: std::io::Error },
    /// The runs cannot fly at once on this machine.
    #[error("{0}")]
    Ports(String),
    #[error("{dir}: {message}")]
    Definition { dir: String, message: String },
}

/// A sweep read from its file: the sweep, its base run and every run it holds.
#[derive(Debug)]
pub struct LoadedSweep {
    pub sweep: SimulationSweep,
    pub base: SimulationRunSpec,
    pub expansion: Expansion,
    /// The file the runs' pilots start beside: `spec.base.file` when the base is a file,
    /// else the sweep's file.
    pub pilot_folder_file: PathBuf,
}

/// What `sweep-definition.json` holds.
#[derive(Serialize, Deserialize, PartialEq)]
struct Definition {
    sweep: SimulationSweep,
    base: SimulationRunSpec,
}

/// Reads, resolves and expands the sweep in `file`.
///
/// # Errors
/// The file or its base file cannot be read or parsed, or the sweep is invalid (every
/// problem, with its field path).
pub fn load(file: &Path) -> Result<LoadedSweep, SweepError> {
    let path = file.display().to_string();
    let text = read(file)?;
    let sweep = parse_sweep(&text).map_err(|source| SweepError::Document { path: path.clone(), source })?;
    let (base, pilot_folder_file) = match (&sweep.spec.base.spec, &sweep.spec.base.file) {
        (Some(spec), None) => ((**spec).clone(), file.to_path_buf()),
        (None, Some(name)) => {
            let base_file = file.parent().unwrap_or(Path::new(".")).join(name);
            let fail = |message: String| SweepError::BaseFile { path: path.clone(), file: name.clone(), message };
            let text =
                std::fs::read_to_string(&base_file).map_err(|e| fail(format!("{}: {e}", base_file.display())))?;
            let run = sadesim_crds::parse_run(&text).map_err(|e| fail(e.to_string()))?;
            (run.spec, base_file)
        }
        (spec, file) => {
            let given = usize::from(spec.is_some()) + usize::from(file.is_some());
            let message = format!("give exactly one of spec (the run inline) and file (a scenario file); got {given}");
            let errors = ValidationErrors(vec![FieldError { path: "spec.base".into(), message }]);
            return Err(SweepError::Invalid { path, errors });
        }
    };
    let expansion = expand(&sweep, &base).map_err(|errors| SweepError::Invalid { path, errors })?;
    Ok(LoadedSweep { sweep, base, expansion, pilot_folder_file })
}

fn read(file: &Path) -> Result<String, SweepError> {
    std::fs::read_to_string(file).map_err(|source| SweepError::Read { path: file.display().to_string(), source })
}

/// How to run a sweep locally.
#[derive(Clone, Debug)]
pub struct SweepOptions {
    /// The sweep's folder is `<out_root>/<sweep>/`.
    pub out_root: PathBuf,
    /// Runs in flight at once (default: the sweep's `parallelism`, at most this machine's
    /// cores).
    pub jobs: Option<u32>,
    /// Draw the sweep's progress bar.
    pub progress: bool,
    /// Overrides every run's clock (`--clock`).
    pub clock: Option<Clock>,
    /// The asset cache (see [`RunOptions::asset_cache`]).
    pub asset_cache: Option<String>,
    /// Serve MAVLink endpoints in every run (see [`RunOptions::mavlink`]; off for sweeps of
    /// scripted missions, which need no ports).
    pub mavlink: bool,
}

/// What a sweep did.
#[derive(Debug)]
pub struct SweepOutcome {
    pub dir: PathBuf,
    pub report: SweepReport,
    /// Runs flown now.
    pub ran: usize,
    /// Runs whose complete evidence was found and kept.
    pub skipped: usize,
    /// Runs that could not be flown: `(run, why)`.
    pub errors: Vec<(String, String)>,
    /// Ctrl-C stopped the sweep before every run was flown.
    pub interrupted: bool,
}

/// The finished, verified evidence of the run in `dir`: its summary, when the run ended
/// (not interrupted) and every file matches its manifest.
pub fn complete_run(dir: &Path) -> Option<RunSummary> {
    let summary = read_summary(dir)?;
    if summary.end_reason == EndReason::Interrupted || !dir.join(MANIFEST).exists() {
        return None;
    }
    let verified = sadesim_evidence::archive::verify(&dir.display().to_string()).ok()?;
    verified.passed().then_some(summary)
}

fn read_summary(dir: &Path) -> Option<RunSummary> {
    serde_json::from_str(&std::fs::read_to_string(dir.join(SUMMARY)).ok()?).ok()
}

/// Runs a sweep: every run without complete evidence in the sweep's folder, `jobs` at a
/// time, then the report. Ctrl-C (`stop`) interrupts the runs in flight and starts no
/// more; the report then covers the runs that finished.
///
/// # Errors
/// The sweep's folder cannot be written or holds another sweep, or the runs cannot fly
/// at once on this machine's ports. A run that fails is not an error of the sweep: it is
/// listed in [`SweepOutcome::errors`] and counted as not finished.
pub fn run_sweep(
    loaded: &LoadedSweep,
    options: &SweepOptions,
    stop: Arc<AtomicBool>,
) -> Result<SweepOutcome, SweepError> {
    let name = loaded.sweep.metadata.name.clone().unwrap_or_default();
    let dir = options.out_root.join(&name);
    let write_err = |path: &Path| {
        let path = path.display().to_string();
        move |source| SweepError::Write { path, source }
    };
    std::fs::create_dir_all(dir.join(SCENARIOS)).map_err(write_err(&dir))?;
    pin_definition(&dir, loaded)?;

    let runs = &loaded.expansion.runs;
    let mut pending = VecDeque::new();
    let mut skipped = 0;
    for (i, r) in runs.iter().enumerate() {
        let document = dir.join(SCENARIOS).join(format!("{}.yaml", r.name()));
        let yaml = run_yaml(&r.run);
        std::fs::write(&document, yaml).map_err(write_err(&document))?;
        let run_dir = dir.join(r.name());
        if complete_run(&run_dir).is_some() {
            skipped += 1;
            continue;
        }
        if run_dir.exists() {
            std::fs::remove_dir_all(&run_dir).map_err(write_err(&run_dir))?;
        }
        pending.push_back(i);
    }

    let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    let jobs = options
        .jobs
        .unwrap_or_else(|| loaded.sweep.spec.parallelism.unwrap_or(cores).min(cores))
        .clamp(1, pending.len().max(1) as u32);
    let drones = runs.iter().map(|r| r.run.spec.fleet.iter().map(|g| g.count).sum::<u32>()).max().unwrap_or(1);
    let offsets = match options.mavlink {
        true => sadesim_planner::concurrent_offsets(drones, jobs).map_err(SweepError::Ports)?,
        false => vec![0; jobs as usize],
    };

    let bar = if options.progress { ProgressBar::new(runs.len() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{bar:30.cyan/blue} {pos}/{len} runs {msg} [{elapsed_precise}<{eta_precise}]")
            .expect("a valid template"),
    );
    bar.set_position(skipped as u64);
    bar.enable_steady_tick(Duration::from_millis(500));

    let queue = Mutex::new(pending);
    let errors = Mutex::new(Vec::new());
    let ran = std::sync::atomic::AtomicUsize::new(0);
    let tally = Mutex::new(Tally::default());
    std::thread::scope(|scope| {
        for offset in &offsets {
            let (queue, errors, ran, tally, bar, stop, dir) = (&queue, &errors, &ran, &tally, &bar, &stop, &dir);
            scope.spawn(move || {
                loop {
                    if stop.load(Ordering::Relaxed) {
                        return;
                    }
                    let Some(i) = queue.lock().expect("not poisoned").pop_front() else { return };
                    let r = &runs[i];
                    let mut run = r.run.clone();
                    if options.clock.is_some() {
                        run.spec.clock = options.clock.clone();
                    }
                    let run_options = RunOptions {
                        run_dir: Some(dir.join(r.name())),
                        port_offset: *offset,
                        scenario: Some(loaded.pilot_folder_file.clone()),
                        scenario_document: Some(dir.join(SCENARIOS).join(format!("{}.yaml", r.name()))),
                        asset_cache: options.asset_cache.clone(),
                        mavlink: options.mavlink,
                        ..RunOptions::default()
                    };
                    match run_local(&run, &run_options, stop.clone()) {
                        Ok(report) => {
                            ran.fetch_add(1, Ordering::Relaxed);
                            tally.lock().expect("not poisoned").add(&report.summary);
                        }
                        Err(e) => {
                            bar.println(format!("run {} failed: {e}", r.name()));
                            errors.lock().expect("not poisoned").push((r.name().to_string(), e.to_string()));
                        }
                    }
                    bar.inc(1);
                    bar.set_message(tally.lock().expect("not poisoned").to_string());
                }
            });
        }
    });
    bar.finish_and_clear();

    let report = write_report(&dir, &loaded.sweep, &loaded.expansion)?;
    let errors = errors.into_inner().expect("not poisoned");
    let interrupted = stop.load(Ordering::Relaxed);
    Ok(SweepOutcome { dir, report, ran: ran.into_inner(), skipped, errors, interrupted })
}

/// Passed and failed runs so far, for the progress bar.
#[derive(Default)]
struct Tally {
    passed: u32,
    failed: u32,
}

impl Tally {
    fn add(&mut self, s: &RunSummary) {
        match &s.verdict {
            Some(v) if v.passed && !v.criteria.is_empty() => self.passed += 1,
            _ if s.end_reason == EndReason::Interrupted => {}
            _ => self.failed += 1,
        }
    }
}

impl std::fmt::Display for Tally {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "(this session: {} passed, {} failed)", self.passed, self.failed)
    }
}

/// Writes `sweep-definition.json`, or checks the one there is the same sweep.
fn pin_definition(dir: &Path, loaded: &LoadedSweep) -> Result<(), SweepError> {
    let path = dir.join(DEFINITION);
    let definition = Definition { sweep: loaded.sweep.clone(), base: loaded.base.clone() };
    if let Ok(text) = std::fs::read_to_string(&path) {
        let same = serde_json::from_str::<Definition>(&text).is_ok_and(|d| d == definition);
        return if same { Ok(()) } else { Err(SweepError::Different { dir: dir.display().to_string() }) };
    }
    let mut bytes = serde_json::to_vec_pretty(&definition).expect("a definition always serializes");
    bytes.push(b'\n');
    std::fs::write(&path, bytes).map_err(|source| SweepError::Write { path: path.display().to_string(), source })
}

/// The sweep's records: each run's `summary.json` as its folder holds it (`None` for a run
/// that did not finish).
pub fn records(dir: &Path, expansion: &Expansion) -> Vec<SweepRecord> {
    expansion
        .runs
        .iter()
        .map(|r| {
            let summary = read_summary(&dir.join(r.name())).filter(|s| s.end_reason != EndReason::Interrupted);
            SweepRecord {
                name: r.name().to_string(),
                cell: r.cell,
                repetition: r.repetition,
                seed: r.seed(),
                folder: r.name().to_string(),
                error: summary.is_none().then(|| "did not finish (no summary.json, or interrupted)".to_string()),
                summary,
            }
        })
        .collect()
}

/// Builds and writes the sweep's report from the run folders in `dir`.
///
/// # Errors
/// The report cannot be written.
pub fn write_report(dir: &Path, sweep: &SimulationSweep, expansion: &Expansion) -> Result<SweepReport, SweepError> {
    let report = sadesim_evidence::sweep::build(sweep, &expansion.cells, &records(dir, expansion));
    sadesim_evidence::sweep::write(dir, &report)
        .map_err(|source| SweepError::Write { path: dir.display().to_string(), source })?;
    Ok(report)
}

/// Rebuilds the report of the sweep folder `dir` (`sadesim report`), from its definition
/// and its run folders.
///
/// # Errors
/// `dir` holds no readable definition, or the report cannot be written.
pub fn rebuild_report(dir: &Path) -> Result<SweepReport, SweepError> {
    let fail = |message: String| SweepError::Definition { dir: dir.display().to_string(), message };
    let text = std::fs::read_to_string(dir.join(DEFINITION)).map_err(|e| fail(format!("{DEFINITION}: {e}")))?;
    let d: Definition = serde_json::from_str(&text).map_err(|e| fail(format!("{DEFINITION}: {e}")))?;
    let expansion = expand(&d.sweep, &d.base).map_err(|e| fail(format!("{DEFINITION}: {e}")))?;
    write_report(dir, &d.sweep, &expansion)
}

/// Whether `dir` is a sweep's folder.
pub fn is_sweep_folder(dir: &Path) -> bool {
    dir.join(DEFINITION).is_file()
}

/// A run as a YAML document `sadesim run` reads back (through JSON: serde_yaml would write
/// enum variants as YAML tags, which scenario files do not use).
pub fn run_yaml(run: &sadesim_crds::SimulationRun) -> String {
    let value = serde_json::to_value(run).expect("a run always serializes");
    serde_yaml::to_string(&value).expect("JSON values always serialize")
}
