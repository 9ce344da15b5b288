//! The `sadesim` command line: flags and glue only; the work is in the planner and the
//! contracts crate.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};
use sadesim_crds::document::{DocumentError, MAX_DOCUMENT_BYTES};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::{SimulationRun, parse_runs, validate};

use sadesim_planner::{self as planner, Addressing};

/// SADE-SIM: city-scale multi-drone simulation for validating software pilots.
///
/// A SimulationRun document declares a run: origin, world, environment, fleet, airspace
/// zones, pilot, criteria and archive. The same document runs locally (`sadesim run`) and on
/// Kubernetes (`kubectl apply -f`). Scenario files may hold several runs (YAML `---`
/// documents, a `kind: List`, or a JSON array).
#[derive(Debug, Parser)]
#[command(name = "sadesim", version, propagate_version = true, max_term_width = 100)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Check scenario files and list every problem with its field path.
    ///
    /// Exits 0 when every run in every file is valid, 1 otherwise. Use `-` for stdin.
    Validate {
        /// Scenario files (YAML or JSON).
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Show how a run will be laid out: groups, shards, router segments, ports, resources.
    Plan {
        /// Scenario file with exactly one run (use `-` for stdin).
        file: PathBuf,
        /// Print the full RunPlan as JSON instead of the summary.
        #[arg(long)]
        json: bool,
        /// Print the fleet file a local pilot would get (`SADESIM_FLEET`) as JSON.
        #[arg(long, conflicts_with = "json")]
        fleet: bool,
        /// Namespace to plan for (default: the document's, else `default`).
        #[arg(long)]
        namespace: Option<String>,
    },
    /// Print the SimulationRun CustomResourceDefinition (YAML), for `kubectl apply -f -`.
    Crd,
    /// Measure simulation throughput (drone-steps per second) on a synthetic scenario:
    /// x500s flying random waypoints over Chicago at 1 kHz with wind, GNSS noise and
    /// recording, as fast as possible. With --airspace, measure the airspace authority's
    /// HTTP API instead. Results go in docs/performance.md.
    Bench {
        /// Drones in the fleet.
        #[arg(long, default_value_t = 32)]
        drones: u32,
        /// Simulated seconds (default 60); with --airspace, seconds of load (default 10).
        #[arg(long)]
        seconds: Option<u32>,
        /// Drones per shard (one thread per shard).
        #[arg(long, default_value_t = 100)]
        drones_per_shard: u32,
        /// Also run with MAVLink endpoints and routers on (PX4 default telemetry rates) and
        /// report the CPU cost of MAVLink as a ratio of the run without.
        #[arg(long)]
        mavlink: bool,
        /// Also run with `spec.recording` off (no recording.mcap, no ULogs) and report the CPU
        /// cost of the recordings as a ratio of the run without: `all` (default) turns both on
        /// in the other runs, `mcap` or `ulog` one of them.
        #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "all", conflicts_with_all = ["mavlink", "airspace"])]
        recording: Option<crate::bench::RecordingSet>,
        /// With --mavlink or --recording: run this many back-to-back pairs of the two
        /// variants (every other pair "on" first) and report the median ratio of the pairs
        /// (this machine's speed drifts by tens of percent between minutes).
        #[arg(long, default_value_t = 3)]
        repeat: u32,
        /// Load the airspace authority's HTTP API (Chicago example's zone and fleet, on
        /// 127.0.0.1) with entry requests, GET /zones and GET /events, open-loop, and report
        /// latency percentiles. Exits 1 when any request failed.
        #[arg(long, conflicts_with = "mavlink")]
        airspace: bool,
        /// With --airspace: requests per second (default 1000).
        #[arg(long, requires = "airspace")]
        rate: Option<u32>,
        /// With --airspace: keep-alive connections, one client thread each (default 8).
        #[arg(long, requires = "airspace")]
        connections: Option<usize>,
    },
    /// Run a scenario locally: world, shards, coordinator and recorder in this process,
    /// and `spec.pilot` as a child process.
    ///
    /// Writes plan.json, fleet.json, world.json, events.jsonl, trajectory.csv,
    /// trajectory.geojson and summary.json (and pilot.json, pilot.log with a pilot) into
    /// `<out>/<run>/<UTC time>/` (out: the archive folder of a file:// archive URL, else
    /// ./runs). Ctrl-C ends the run cleanly and keeps everything written.
    Run {
        /// Scenario file with exactly one run (use `-` for stdin).
        file: PathBuf,
        /// Folder to create the run folder in.
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
        /// Run the coordinator and each shard as separate `sim-worker` processes over TCP
        /// (as on Kubernetes) instead of threads.
        #[arg(long)]
        processes: bool,
        /// Override the scenario's clock: `realtime`, `asFastAsPossible` (or `afap`), or
        /// `scaled:FACTOR` (e.g. `scaled:4`).
        #[arg(long, value_parser = parse_clock)]
        clock: Option<sadesim_crds::run::Clock>,
        /// Do not start `spec.pilot`: attach a pilot, SDK script or ground station yourself
        /// (the fleet file is `fleet.json` in the run folder, or `sadesim plan --fleet`).
        /// The run lasts until `duration` or Ctrl-C.
        #[arg(long)]
        no_pilot: bool,
        /// Serve no MAVLink endpoints (scripted missions only; groups without a `mission`
        /// are then refused).
        #[arg(long)]
        no_mavlink: bool,
    },
    /// Run archives: list, verify, download and upload run folders with their
    /// manifest.json (sizes and SHA-256 of every file).
    ///
    /// An archive is a URL: file:///abs/folder, file://relative/folder, s3://bucket/prefix,
    /// gs://bucket/prefix, az://container/prefix, or a plain folder path. A run in it is
    /// `<archive>/<namespace>/<run>/<uid>/`; a local run folder (`runs/<run>/<UTC time>/`)
    /// is one too. Object-store credentials come from the usual environment variables
    /// (AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_REGION, AWS_ENDPOINT_URL,
    /// AWS_ALLOW_HTTP; GOOGLE_*; AZURE_*).
    Archive {
        #[command(subcommand)]
        command: ArchiveCommand,
    },
    /// Rebuild a run's report (report.html, report/*.svg, report/*.png) from the files in
    /// its run folder.
    Report {
        /// Run folder (`runs/<run>/<UTC time>/`, or one fetched with `archive get`).
        run_dir: PathBuf,
    },
    /// Print the Kubernetes objects the operator would create for each run in FILE (YAML,
    /// one document per object), for review in GitOps pull requests.
    Manifests {
        /// Scenario files (use `-` for stdin); the objects of all runs are printed as one
        /// YAML stream.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Namespace of the run (default: the document's, else `default`).
        #[arg(long)]
        namespace: Option<String>,
    },
    /// Build a run's world assets (city footprints as GeoJSON, world statistics) into the
    /// archive's asset cache `<archive>/assets/<cache key>/world/`, unless a verified entry
    /// is there. The operator runs this as the `<run>-assets` Job.
    Assets {
        /// RunPlan JSON (`sadesim plan FILE --json`).
        #[arg(long)]
        plan: PathBuf,
        /// Archive URL holding the cache (s3://, gs://, az:// or file://).
        #[arg(long)]
        archive: String,
    },
    /// Run the Kubernetes operator: reconcile SimulationRuns in the cluster of the current
    /// kubeconfig or service account.
    ///
    /// Logs JSON lines to stderr; stops cleanly on SIGTERM. The Lease for leader election is
    /// `sadesim-operator` in POD_NAMESPACE, held as POD_NAME.
    Operator(sadesim_operator::OperatorArgs),
}

/// `sadesim archive ...`
#[derive(Debug, Subcommand)]
pub enum ArchiveCommand {
    /// List the runs in an archive: path, files, size, complete (manifest.json written) or
    /// incomplete (an upload that did not finish).
    Ls {
        /// Archive URL or folder.
        url: String,
    },
    /// Re-read every file of a run and check its size and SHA-256 against manifest.json.
    ///
    /// Exits 0 when everything matches, 1 when a file differs, is missing, is not in the
    /// manifest, or the manifest is missing (incomplete run), naming each file.
    Verify {
        /// The run folder: URL/NAMESPACE/RUN/UID (e.g. s3://bucket/runs/default/quickstart/20261122T010058Z)
        /// or a local run folder (runs/quickstart/20261122T010058Z).
        location: String,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Download a run into a folder, checking every file against manifest.json (exit 1 on
    /// any mismatch, as `verify`).
    Get {
        /// The run folder, as for `verify`.
        location: String,
        /// Folder to download into (created if needed; files there are overwritten).
        dir: PathBuf,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Upload a local run folder to URL/NAMESPACE/RUN/UID/, manifest.json last.
    Put {
        /// The local run folder (e.g. runs/quickstart/20261122T010058Z).
        dir: PathBuf,
        /// Archive URL or folder.
        url: String,
        /// Namespace segment of the layout.
        #[arg(long, default_value = "default")]
        namespace: String,
        /// Run name (default: the name of DIR's parent folder, as in runs/<run>/<UTC time>).
        #[arg(long)]
        run: Option<String>,
        /// Uid of this execution (default: DIR's name).
        #[arg(long)]
        uid: Option<String>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
}

/// What a command reports back to `main`.
#[derive(Debug, PartialEq, Eq)]
pub enum Outcome {
    Success,
    /// The command ran but found problems (exit code 1).
    Problems,
    /// Ctrl-C ended a run early; its output was kept (exit code 130).
    Interrupted,
}

/// Errors that stop a command (exit code 2 from `main`).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// A file could not be read.
    #[error("failed to read {path}: {source}")]
    Read { path: String, source: std::io::Error },
    /// A file is too large to be a scenario.
    #[error("{path}: larger than {limit} bytes: not a scenario file")]
    TooLarge { path: String, limit: usize },
    /// The input was unreadable as a whole.
    #[error("{path}: {source}")]
    Document { path: String, source: DocumentError },
    /// `plan` and `run` need exactly one run.
    #[error("{path}: holds {count} runs; this command takes a file with exactly one")]
    NotOneRun { path: String, count: usize },
    /// A run could not start or finish.
    #[error("{path}: {source}")]
    Run { path: String, source: crate::runner::RunError },
    /// The airspace benchmark could not start.
    #[error("bench --airspace: {0}")]
    AirspaceBench(#[from] crate::bench::AirspaceBenchError),
    /// An archive command could not be carried out.
    #[error(transparent)]
    Archive(#[from] sadesim_evidence::archive::ArchiveError),
    /// `archive put` without `--run`/`--uid` on a folder whose names cannot supply them.
    #[error("{dir}: cannot take --{flag} from the folder's name; give --{flag}")]
    ArchiveName { dir: String, flag: &'static str },
    /// Writing the output failed.
    #[error("failed to write output: {0}")]
    Write(#[from] std::io::Error),
    /// A report, manifests or operator command failed (the message names what and why).
    #[error("{0}")]
    Failed(String),
}

/// Runs a parsed command, writing its report to `out`.
///
/// # Errors
/// Only for failures to read input or write output; invalid scenarios are reported on
/// `out` and give [`Outcome::Problems`].
pub fn execute(cli: Cli, out: &mut dyn Write) -> Result<Outcome, CliError> {
    match cli.command {
        Command::Validate { files } => validate_files(&files, out),
        Command::Plan { file, json, fleet, namespace } => plan_file(&file, json, fleet, namespace, out),
        Command::Run { file, out: out_root, quiet, processes, clock, no_pilot, no_mavlink } => {
            let options = crate::runner::RunOptions {
                out_root,
                progress: !quiet,
                processes,
                worker: None,
                scenario: (file.as_os_str() != "-").then(|| file.clone()),
                start_pilot: !no_pilot,
                mavlink: !no_mavlink,
            };
            run_file(&file, options, clock, out)
        }
        Command::Bench { airspace: true, seconds, rate, connections, .. } => {
            let report = crate::bench::run_airspace(
                f64::from(rate.unwrap_or(1000)),
                f64::from(seconds.unwrap_or(10)),
                connections.unwrap_or(8),
            )?;
            writeln!(out, "{report}")?;
            writeln!(out, "  ({} cores available, shared by the service and the client)", cores_available())?;
            let clean = report.errors == 0 && report.answered == report.requests;
            Ok(if clean { Outcome::Success } else { Outcome::Problems })
        }
        Command::Bench { drones, seconds, drones_per_shard, mavlink, recording, repeat, .. } => {
            use crate::bench::{BenchResult, Recordings};
            let seconds = seconds.unwrap_or(60);
            let root = std::env::temp_dir().join(format!("sadesim-bench-{}", std::process::id()));
            // (MAVLink on, recordings written) per run; the "off" variant of each pair first.
            // The (off, on) variants a comparison alternates: MAVLink off/on, or recordings
            // off/on; `None` for a single run.
            let compared: Option<[(bool, Recordings); 2]> = match (mavlink, recording) {
                (true, _) => Some([(false, Recordings::ALL), (true, Recordings::ALL)]),
                (false, Some(set)) => Some([(false, Recordings::NONE), (false, set.recordings())]),
                (false, None) => None,
            };
            let variants: Vec<(bool, Recordings)> = match compared {
                // Every other pair runs "on" first, so what one position in a pair gains
                // (caches warmed, the previous run's files being written back) cancels out.
                Some([off, on]) => {
                    (0..repeat.max(1)).flat_map(|i| if i % 2 == 0 { [off, on] } else { [on, off] }).collect()
                }
                None => vec![(false, Recordings::ALL)],
            };
            let mut results = Vec::new();
            for &(with_mavlink, recordings) in &variants {
                let result =
                    crate::bench::run(drones, seconds, drones_per_shard, root.clone(), with_mavlink, recordings)
                        .map_err(|source| CliError::Run { path: "bench".into(), source })?;
                writeln!(
                    out,
                    "bench{}{}: {} in {} at 1000 Hz: {:.0} s simulated in {:.2} s wall{} = {:.0} drone-steps/s (real-time factor {:.1}, {} cores available)",
                    if with_mavlink { " (MAVLink on)" } else { "" },
                    if recording.is_some() { format!(" ({})", recordings.label()) } else { String::new() },
                    count(result.drones as usize, "drone"),
                    count(result.shards as usize, "shard"),
                    result.sim_time_s,
                    result.wall_time_s,
                    result.cpu_time_s.map(|c| format!(", {c:.2} s CPU")).unwrap_or_default(),
                    result.drone_steps_per_s,
                    result.sim_time_s / result.wall_time_s,
                    std::thread::available_parallelism().map_or(1, usize::from)
                )?;
                let cost = result.report.summary.recording_cpu_s;
                if result.recordings != Recordings::NONE {
                    writeln!(
                        out,
                        "  recorder's thread: {:.3} s CPU on recording.mcap, {:.3} s on the ULogs ({:.0} + {:.0} µs per drone-second)",
                        cost.mcap,
                        cost.ulog,
                        cost.mcap / drone_seconds(&result) * 1e6,
                        cost.ulog / drone_seconds(&result) * 1e6,
                    )?;
                }
                results.push(result);
            }
            let _ = std::fs::remove_dir_all(&root);
            // What the pairs compare: the report's label, and which runs are the "on" variant.
            let label = match recording {
                _ if mavlink => Some("MAVLink cost".to_string()),
                Some(set) => Some(format!("Recording cost ({})", set.recordings().label())),
                None => None,
            };
            let is_on = |r: &BenchResult| if mavlink { r.mavlink } else { r.recordings != Recordings::NONE };
            if let Some(label) = label {
                // Each pair (one run off, one on) ran back to back.
                let pairs = |f: &dyn Fn(&BenchResult) -> Option<f64>| -> Vec<(f64, f64)> {
                    results
                        .chunks_exact(2)
                        .filter_map(|p| {
                            let (off, on) = if is_on(&p[1]) { (&p[0], &p[1]) } else { (&p[1], &p[0]) };
                            (!is_on(off) && is_on(on)).then_some(())?;
                            f(off).zip(f(on))
                        })
                        .collect()
                };
                let wall = pairs(&|r: &BenchResult| Some(r.wall_time_s));
                let cpu = pairs(&|r: &BenchResult| r.cpu_time_s);
                writeln!(
                    out,
                    "{label} (median of {repeat} back-to-back pairs): {}{}",
                    crate::bench::paired_cost_percent(&wall)
                        .map(|c| format!("{c:+.1} % wall time"))
                        .unwrap_or_default(),
                    crate::bench::paired_cost_percent(&cpu)
                        .map(|c| format!(", {c:+.1} % CPU time"))
                        .unwrap_or_default()
                )?;
                // Within each run: the recorder's CPU time on the recordings against the
                // rest of the process's CPU time (the simulation), immune to the drift
                // between runs that the pairs above suffer from.
                let shares: Vec<f64> =
                    results.iter().filter(|r| is_on(r)).filter_map(crate::bench::recorder_share_percent).collect();
                if !mavlink && let Some(c) = crate::bench::median(shares) {
                    writeln!(
                        out,
                        "{label} measured on the recorder's thread (median of {repeat}): {c:.1} % of the simulation's CPU time"
                    )?;
                }
            }
            Ok(Outcome::Success)
        }
        Command::Crd => {
            out.write_all(sadesim_crds::crd::crd_yaml().as_bytes())?;
            Ok(Outcome::Success)
        }
        Command::Archive { command } => archive_command(command, out),
        Command::Report { run_dir } => {
            let files = sadesim_evidence::report::write_report(&run_dir).map_err(CliError::Failed)?;
            writeln!(out, "report: {}", files.html.display())?;
            Ok(Outcome::Success)
        }
        Command::Manifests { files, namespace } => {
            let settings = sadesim_operator::k8s::children::ClusterSettings::default();
            for (i, file) in files.iter().enumerate() {
                let text = read_scenario(file)?;
                if i > 0 {
                    // One YAML stream: a document separator between files.
                    writeln!(out, "---")?;
                }
                sadesim_operator::k8s::manifests::write_manifests(&text, namespace.as_deref(), &settings, out)
                    .map_err(|e| CliError::Failed(format!("{}: {e}", file.display())))?;
            }
            Ok(Outcome::Success)
        }
        Command::Assets { plan, archive } => {
            let bytes =
                std::fs::read(&plan).map_err(|source| CliError::Read { path: plan.display().to_string(), source })?;
            let plan: sadesim_crds::plan::RunPlan = serde_json::from_slice(&bytes)
                .map_err(|e| CliError::Failed(format!("{}: not a RunPlan: {e}", plan.display())))?;
            let scratch = std::env::temp_dir().join(format!("sadesim-assets-{}", std::process::id()));
            let outcome = sadesim_evidence::assets::build_assets(&plan, &archive, &scratch);
            let _ = std::fs::remove_dir_all(&scratch);
            match outcome.map_err(|e| CliError::Failed(e.to_string()))? {
                sadesim_evidence::assets::AssetsOutcome::CacheHit { url } => writeln!(out, "asset cache hit: {url}")?,
                sadesim_evidence::assets::AssetsOutcome::Built { url, buildings } => {
                    writeln!(out, "assets built: {buildings} buildings -> {url}")?;
                }
            }
            Ok(Outcome::Success)
        }
        Command::Operator(args) => {
            sadesim_operator::k8s::controller::run(args.options()).map_err(CliError::Failed)?;
            Ok(Outcome::Success)
        }
    }
}

/// `sadesim archive ...`: exit 1 (`Problems`) when a run does not match its manifest.
fn archive_command(command: ArchiveCommand, out: &mut dyn Write) -> Result<Outcome, CliError> {
    use indicatif::HumanBytes;
    use sadesim_evidence::archive::Archive;

    match command {
        ArchiveCommand::Ls { url } => {
            let archive = Archive::open(&url)?;
            let runs = archive.list()?;
            if runs.is_empty() {
                writeln!(out, "no runs in {}", archive.url())?;
                return Ok(Outcome::Success);
            }
            let width = runs.iter().map(|r| r.path.len()).max().unwrap_or(0).max(3);
            writeln!(out, "{:<width$}  {:>6}  {:>10}  status", "run", "files", "size")?;
            for r in &runs {
                let status = if r.complete { "complete" } else { "incomplete (no manifest.json)" };
                writeln!(out, "{:<width$}  {:>6}  {:>10}  {status}", r.path, r.files, HumanBytes(r.bytes).to_string())?;
            }
            writeln!(out, "{} in {}", count(runs.len(), "run"), archive.url())?;
            Ok(Outcome::Success)
        }
        ArchiveCommand::Verify { location, quiet } => {
            let mut archive = Archive::open(&location)?;
            archive.set_progress(!quiet);
            let report = archive.verify("")?;
            report_check(out, &report, "verified")
        }
        ArchiveCommand::Get { location, dir, quiet } => {
            let mut archive = Archive::open(&location)?;
            archive.set_progress(!quiet);
            let report = archive.get("", &dir)?;
            let outcome = report_check(out, &report, "downloaded")?;
            writeln!(out, "  into {}", dir.display())?;
            Ok(outcome)
        }
        ArchiveCommand::Put { dir, url, namespace, run, uid, quiet } => {
            let name_of = |p: Option<&Path>, flag| {
                p.and_then(|p| p.file_name())
                    .and_then(|n| n.to_str())
                    .map(String::from)
                    .ok_or_else(|| CliError::ArchiveName { dir: dir.display().to_string(), flag })
            };
            let absolute = std::path::absolute(&dir).unwrap_or_else(|_| dir.clone());
            let uid = match uid {
                Some(u) => u,
                None => name_of(Some(&absolute), "uid")?,
            };
            let run = match run {
                Some(r) => r,
                None => name_of(absolute.parent(), "run")?,
            };
            let mut archive = Archive::open(&url)?;
            archive.set_progress(!quiet);
            let uploaded = archive.upload_run(&dir, &namespace, &run, &uid)?;
            let m = &uploaded.manifest;
            writeln!(
                out,
                "uploaded {} ({}) to {}/ ({} written last)",
                count(m.file_count, "file"),
                HumanBytes(m.total_bytes),
                uploaded.url,
                sadesim_evidence::archive::MANIFEST_FILE
            )?;
            Ok(Outcome::Success)
        }
    }
}

/// Prints a verify/get report: one line per problem, then the verdict.
fn report_check(
    out: &mut dyn Write,
    report: &sadesim_evidence::archive::VerifyReport,
    verb: &str,
) -> Result<Outcome, CliError> {
    use indicatif::HumanBytes;
    if report.passed() {
        writeln!(
            out,
            "ok: {}: {} {} ({}) match {}",
            report.url,
            verb,
            count(report.files_checked, "file"),
            HumanBytes(report.bytes_checked),
            sadesim_evidence::archive::MANIFEST_FILE
        )?;
        return Ok(Outcome::Success);
    }
    writeln!(out, "error: {}: {}", report.url, count(report.problems.len(), "problem"))?;
    for p in &report.problems {
        writeln!(out, "  {p}")?;
    }
    Ok(Outcome::Problems)
}

/// Reads a scenario file (or stdin for `-`) without ever holding more than the size limit.
pub fn read_scenario(path: &Path) -> Result<String, CliError> {
    let name = path.display().to_string();
    let read_err = |source| CliError::Read { path: name.clone(), source };
    let mut reader: Box<dyn Read> =
        if name == "-" { Box::new(std::io::stdin()) } else { Box::new(std::fs::File::open(path).map_err(read_err)?) };
    let mut buf = Vec::new();
    reader.by_ref().take(MAX_DOCUMENT_BYTES as u64 + 1).read_to_end(&mut buf).map_err(read_err)?;
    if buf.len() > MAX_DOCUMENT_BYTES {
        return Err(CliError::TooLarge { path: name, limit: MAX_DOCUMENT_BYTES });
    }
    String::from_utf8(buf).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        read_err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (invalid byte at offset {at})"),
        ))
    })
}

/// Drones x simulated seconds of a benchmark run.
fn drone_seconds(result: &crate::bench::BenchResult) -> f64 {
    (f64::from(result.drones) * result.sim_time_s).max(1e-9)
}

/// CPU cores this process may use.
fn cores_available() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

/// "1 problem", "3 problems".
fn count(n: usize, noun: &str) -> String {
    if n == 1 { format!("1 {noun}") } else { format!("{n} {noun}s") }
}

fn run_label(run: &SimulationRun) -> String {
    run.metadata.name.clone().unwrap_or_else(|| "(unnamed)".into())
}

fn validate_files(files: &[PathBuf], out: &mut dyn Write) -> Result<Outcome, CliError> {
    let mut problems = 0usize;
    for file in files {
        let path = file.display().to_string();
        let text = match read_scenario(file) {
            Ok(t) => t,
            Err(e) => {
                writeln!(out, "error: {e}")?;
                problems += 1;
                continue;
            }
        };
        let docs = match parse_runs(&text) {
            Ok(docs) => docs,
            Err(e) => {
                writeln!(out, "error: {path}: {e}")?;
                problems += 1;
                continue;
            }
        };
        for (i, doc) in docs.into_iter().enumerate() {
            let run = match doc {
                Ok(run) => run,
                Err(e) => {
                    writeln!(out, "error: {path}: {e}")?;
                    problems += 1;
                    continue;
                }
            };
            match validate(&run) {
                Ok(()) => writeln!(
                    out,
                    "ok: {path}: {} ({} in {}, {})",
                    run_label(&run),
                    count(run.spec.total_drones() as usize, "drone"),
                    count(run.spec.fleet.len(), "group"),
                    count(run.spec.zones.len(), "zone")
                )?,
                Err(errors) => {
                    let n = count(errors.0.len(), "problem");
                    writeln!(out, "error: {path}: document {} ({}): {n}", i + 1, run_label(&run))?;
                    for e in &errors.0 {
                        writeln!(out, "  {e}")?;
                    }
                    problems += 1;
                }
            }
        }
    }
    Ok(if problems == 0 { Outcome::Success } else { Outcome::Problems })
}

/// Reads a file holding exactly one run; parse problems are reported on `out` (`None`).
fn load_one(file: &Path, out: &mut dyn Write) -> Result<Option<SimulationRun>, CliError> {
    let path = file.display().to_string();
    let text = read_scenario(file)?;
    let mut docs = parse_runs(&text).map_err(|source| CliError::Document { path: path.clone(), source })?;
    if docs.len() != 1 {
        return Err(CliError::NotOneRun { path, count: docs.len() });
    }
    match docs.remove(0) {
        Ok(run) => Ok(Some(run)),
        Err(e) => {
            writeln!(out, "error: {path}: {e}")?;
            Ok(None)
        }
    }
}

fn report_problems(out: &mut dyn Write, path: &str, errors: &sadesim_crds::ValidationErrors) -> std::io::Result<()> {
    writeln!(out, "error: {path}: {}", count(errors.0.len(), "problem"))?;
    for e in &errors.0 {
        writeln!(out, "  {e}")?;
    }
    Ok(())
}

/// `--clock` values.
fn parse_clock(s: &str) -> Result<sadesim_crds::run::Clock, String> {
    use sadesim_crds::run::{Clock, ClockMode};
    match s {
        "realtime" => Ok(Clock { mode: ClockMode::Realtime, factor: None }),
        "asFastAsPossible" | "afap" => Ok(Clock { mode: ClockMode::AsFastAsPossible, factor: None }),
        _ => match s.strip_prefix("scaled:").map(str::parse::<f64>) {
            Some(Ok(f)) if f.is_finite() && f > 0.0 => Ok(Clock { mode: ClockMode::Scaled, factor: Some(f) }),
            _ => Err(format!("expected realtime, asFastAsPossible or scaled:FACTOR (e.g. scaled:4), got {s:?}")),
        },
    }
}

fn run_file(
    file: &Path,
    mut options: crate::runner::RunOptions,
    clock: Option<sadesim_crds::run::Clock>,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    use std::io::IsTerminal;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    use crate::runner::{RunError, run_local};

    let path = file.display().to_string();
    let Some(mut run) = load_one(file, out)? else { return Ok(Outcome::Problems) };
    if clock.is_some() {
        run.spec.clock = clock;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    // Ctrl-C asks the coordinator to stop after the current window; the recorder then
    // closes its files. (Fails only if a handler is already installed: keep that one.)
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    options.progress &= std::io::stderr().is_terminal();
    match run_local(&run, &options, stop) {
        Ok(report) => {
            let s = &report.summary;
            let took_off = s.per_drone.iter().filter(|d| d.took_off).count();
            let landed = s.per_drone.iter().filter(|d| d.landed).count();
            writeln!(
                out,
                "run {} ended ({}) at {:.1} s simulated in {:.1} s wall (real-time factor {:.1})",
                s.run, s.end_reason, s.sim_time_s, s.wall_time_s, s.real_time_factor
            )?;
            writeln!(
                out,
                "  {} in {}: {took_off} took off, {landed} landed, {} airborne at the end, {} crashed; {} events",
                count(s.drones as usize, "drone"),
                count(s.shards as usize, "shard"),
                s.airborne,
                s.crashed,
                s.events
            )?;
            if let Some(p) = &report.pilot {
                let log = report.out_dir.join(&p.log);
                writeln!(out, "  pilot: {}; log: {}", p.describe(), log.display())?;
            }
            writeln!(out, "  output: {}", report.out_dir.display())?;
            match &report.report_error {
                None => writeln!(out, "  report: {}", report.out_dir.join("report.html").display())?,
                Some(e) => writeln!(out, "  report: not written: {e}")?,
            }
            if let Some(url) = &report.archive {
                writeln!(out, "  archived: {url}/")?;
            }
            let failed = match &s.verdict {
                Some(v) if !v.criteria.is_empty() => {
                    report_verdict(out, v)?;
                    !v.passed
                }
                _ => false,
            };
            if s.end_reason == "interrupted" {
                return Ok(Outcome::Interrupted);
            }
            Ok(if failed { Outcome::Problems } else { Outcome::Success })
        }
        Err(RunError::Plan(planner::PlanError::Invalid(errors))) => {
            report_problems(out, &path, &errors)?;
            Ok(Outcome::Problems)
        }
        Err(RunError::Plan(e @ planner::PlanError::NoHome { .. })) => {
            writeln!(out, "error: {path}: {e}")?;
            Ok(Outcome::Problems)
        }
        Err(source) => Err(CliError::Run { path, source }),
    }
}

/// Prints the criteria verdict: one line per criterion, then each failure.
fn report_verdict(out: &mut dyn Write, v: &sim_worker::airspace::criteria::RunVerdict) -> std::io::Result<()> {
    let passed = v.criteria.iter().filter(|c| c.passed).count();
    let word = if v.passed { "PASSED" } else { "FAILED" };
    writeln!(out, "  criteria {word}: {passed} of {} passed", v.criteria.len())?;
    for c in &v.criteria {
        let mark = if c.passed { "pass" } else { "FAIL" };
        writeln!(out, "    {mark} {} {}: {}", c.path, c.criterion, c.summary)?;
        for f in c.failures.iter().take(20) {
            writeln!(out, "         - {f}")?;
        }
        if c.failures.len() > 20 {
            writeln!(out, "         ... and {} more (see summary.json)", c.failures.len() - 20)?;
        }
    }
    Ok(())
}

fn plan_file(
    file: &Path,
    json: bool,
    fleet: bool,
    namespace: Option<String>,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let path = file.display().to_string();
    let Some(mut run) = load_one(file, out)? else { return Ok(Outcome::Problems) };
    if namespace.is_some() {
        run.metadata.namespace = namespace;
    }
    let plan = match planner::plan(&run) {
        Ok(plan) => plan,
        Err(planner::PlanError::Invalid(errors)) => {
            report_problems(out, &path, &errors)?;
            return Ok(Outcome::Problems);
        }
        Err(e @ planner::PlanError::NoHome { .. }) => {
            writeln!(out, "error: {path}: {e}")?;
            return Ok(Outcome::Problems);
        }
    };
    if json {
        serde_json::to_writer_pretty(&mut *out, &plan).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else if fleet {
        let file = planner::fleet_file(&plan, &Addressing::Local { host: "127.0.0.1".into() });
        serde_json::to_writer_pretty(&mut *out, &file).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        out.write_all(summary(&plan).as_bytes())?;
    }
    Ok(Outcome::Success)
}

/// Human-readable plan summary.
pub fn summary(plan: &RunPlan) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let spec = &plan.spec;
    let clock = spec.clock();
    let clock = match clock.factor {
        Some(f) => format!("{:?} x{f}", clock.mode),
        None => format!("{:?}", clock.mode),
    };
    let o = &spec.origin;
    let _ = writeln!(s, "Run {}/{}", plan.run.namespace, plan.run.name);
    let _ = writeln!(
        s,
        "  origin {:.6}, {:.6} at {} m MSL; duration {} s at {} Hz; clock {clock}; seed {}",
        o.latitude_deg, o.longitude_deg, o.altitude_msl_m, plan.duration_s, plan.physics_rate_hz, plan.seed
    );
    let world = spec.world();
    let _ = writeln!(
        s,
        "  world {:?}, {} m around the origin; asset cache key {}",
        world.source,
        world.extent_m,
        &plan.asset_cache_key[..16]
    );
    let _ = writeln!(s, "\nGroups ({} drones)", plan.drones.len());
    let _ = writeln!(
        s,
        "  {:<20} {:>6}  {:<13} {:<9} {:<20} flown by",
        "group", "drones", "indices", "airframe", "operator"
    );
    for (gi, g) in spec.fleet.iter().enumerate() {
        let idx: Vec<u32> = plan.drones.iter().filter(|d| d.group_index == gi as u32).map(|d| d.index).collect();
        let range = format!("{}-{}", idx.first().unwrap_or(&0), idx.last().unwrap_or(&0));
        let by = if g.mission.is_some() { "scripted mission" } else { "pilot over MAVLink" };
        let _ = writeln!(s, "  {:<20} {:>6}  {:<13} {:<9} {:<20} {by}", g.name, g.count, range, g.airframe, g.operator);
    }
    let _ = writeln!(
        s,
        "\nShards ({} drones per shard, sync every {} steps)",
        spec.sharding().drones_per_shard,
        plan.sync_window_steps
    );
    let _ = writeln!(s, "  {:<6} {:>6}  {:<13} {:>8} {:>9}", "shard", "drones", "indices", "cpu (m)", "mem (MiB)");
    for (sh, r) in plan.shards.iter().zip(&plan.resources.shards).take(20) {
        let range = format!("{}-{}", sh.first_drone, sh.first_drone + sh.drone_count - 1);
        let _ = writeln!(
            s,
            "  {:<6} {:>6}  {:<13} {:>8} {:>9}",
            sh.index, sh.drone_count, range, r.cpu_millis, r.memory_mib
        );
    }
    if plan.shards.len() > 20 {
        let _ = writeln!(s, "  ... {} more shards", plan.shards.len() - 20);
    }
    let _ = writeln!(s, "\nMAVLink router segments (system ids 1..250 each)");
    let _ = writeln!(s, "  {:<8} {:>6}  {:<13} {:>8} {:>8}", "segment", "drones", "indices", "GCS udp", "GCS tcp");
    for seg in &plan.segments {
        let range = format!("{}-{}", seg.first_drone, seg.first_drone + seg.drone_count - 1);
        let _ = writeln!(
            s,
            "  {:<8} {:>6}  {:<13} {:>8} {:>8}",
            seg.index, seg.drone_count, range, seg.gcs_udp, seg.gcs_tcp
        );
    }
    let _ = writeln!(s, "\nDrones (API link: the drone sends to this UDP port; endpoint: connect here, UDP or TCP)");
    let _ = writeln!(
        s,
        "  {:<6} {:<24} {:>5} {:>4} {:>5} {:>9} {:>9}  home (lat, lon)",
        "index", "name", "sysid", "seg", "shard", "api udp", "endpoint"
    );
    for d in plan.drones.iter().take(12) {
        let _ = writeln!(
            s,
            "  {:<6} {:<24} {:>5} {:>4} {:>5} {:>9} {:>9}  {:.6}, {:.6}",
            d.index,
            d.name,
            d.system_id,
            d.segment,
            d.shard,
            d.ports.api_udp,
            d.ports.endpoint,
            d.home.global.latitude_deg,
            d.home.global.longitude_deg
        );
    }
    if plan.drones.len() > 12 {
        let _ = writeln!(s, "  ... {} more drones (`sadesim plan --json` lists all)", plan.drones.len() - 12);
    }
    let sv = plan.services;
    let _ = writeln!(
        s,
        "\nServices: coordinator tcp {}, airspace http {}, renderer http {}, metrics {}",
        sv.coordinator, sv.airspace_http, sv.renderer_http, sv.metrics
    );
    let total = plan.resources.total(plan.segments.len());
    let _ = writeln!(
        s,
        "Resources for the whole run: {} millicores, {} MiB (assets job: {} m, {} MiB)",
        total.cpu_millis, total.memory_mib, plan.resources.assets.cpu_millis, plan.resources.assets.memory_mib
    );
    s
}
