//! The clap types of the `sadesim` command line: commands, flags and their parsers.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

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
    /// Print the CustomResourceDefinitions (SimulationRun, SimulationSweep) as one YAML
    /// stream, for `kubectl apply -f -`.
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
        /// Also run with the ranging GNSS receiver (urban GNSS: pseudoranges to the
        /// synthetic GPS + Galileo constellation among the city's buildings) and report its
        /// cost as a ratio of the statistical receiver's run.
        #[arg(long, conflicts_with_all = ["mavlink", "recording"])]
        urban_gnss: bool,
        /// Also run with the urban wind field off (`environment.wind.urban.model: none`, the
        /// plain log profile) and report what the field (on by default) costs: each
        /// variant's drone-steps/s and their ratio.
        #[arg(long, conflicts_with_all = ["mavlink", "recording", "urban_gnss", "airspace"])]
        urban_wind: bool,
        /// Also run with one downward camera per drone, WIDTHxHEIGHT pixels (e.g. 320x240) at
        /// 10 Hz, rendered on this machine's Vulkan device (Mesa's lavapipe without a GPU)
        /// and recorded at 1 Hz, and report what the cameras cost against the run without.
        #[arg(long, value_name = "WIDTHxHEIGHT", conflicts_with_all = ["mavlink", "recording", "urban_gnss", "urban_wind", "airspace"])]
        cameras: Option<crate::bench::CameraSize>,
        /// Also run with `spec.recording` off (no recording.mcap, no ULogs) and report the CPU
        /// cost of the recordings as a ratio of the run without: `all` (default) turns both on
        /// in the other runs, `mcap` or `ulog` one of them.
        #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "all", conflicts_with_all = ["mavlink", "airspace"])]
        recording: Option<crate::bench::RecordingSet>,
        /// Run the bare simulation only: no MAVLink and no recordings (recording.mcap holds at
        /// most 6 553 drones, so larger fleets are measured this way).
        #[arg(long, conflicts_with_all = ["mavlink", "recording", "urban_gnss", "urban_wind", "cameras", "airspace", "whole_stack"])]
        bare: bool,
        /// Also run the whole stack, with MAVLink endpoints and routers at PX4's default rates
        /// and recording.mcap with the ULogs, against the bare simulation (neither), and
        /// report what that I/O costs: each variant's drone-steps/s and their ratio.
        #[arg(long, conflicts_with_all = ["mavlink", "recording", "urban_gnss", "urban_wind", "cameras", "airspace"])]
        whole_stack: bool,
        /// Record the ground truth (pose, velocity, /tf in recording.mcap) at this rate in
        /// every run, Hz (`spec.recording.rates.groundTruthHz`; default that field's default,
        /// 100), to see what a lower rate saves.
        #[arg(long, value_name = "HZ", value_parser = clap::value_parser!(u32).range(1..=1000), conflicts_with_all = ["bare", "airspace"])]
        ground_truth_hz: Option<u32>,
        /// Compress recording.mcap's chunks with this codec in every run
        /// (`spec.recording.compression`: zstd, lz4 or none; default that field's default,
        /// zstd), to see what a lighter recording saves.
        #[arg(long, value_name = "CODEC", value_parser = ["zstd", "lz4", "none"], conflicts_with_all = ["bare", "airspace"])]
        compression: Option<String>,
        /// With --mavlink or --whole-stack: in the runs with MAVLink, a ground station on
        /// every router (UDP, as QGroundControl connects) reads all the telemetry, so the
        /// runs pay for its delivery (drones to routers to ground stations), not only for
        /// building and encoding it. Without one, routers do not register with the drones
        /// and only heartbeats leave them.
        #[arg(long)]
        ground_stations: bool,
        /// With a comparison (--mavlink, --recording, --urban-gnss, --urban-wind, --cameras, --whole-stack): run this many back-to-back pairs of the two
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
        /// Override `spec.pilot.connectTimeoutS`: simulated time holds at the release until
        /// the pilot's first MAVLink frame reaches a drone it flies, for at most this many
        /// seconds of wall time (1 to 3600; default 300); a pilot silent that long fails the
        /// run (`pilotNotConnected`).
        #[arg(long, value_name = "SECONDS", value_parser = clap::value_parser!(u32).range(1..=3600))]
        pilot_connect_timeout: Option<u32>,
        /// Serve no MAVLink endpoints (scripted missions only; groups without a `mission`
        /// are then refused).
        #[arg(long)]
        no_mavlink: bool,
        /// The asset cache to load the world's bundle from and store it in: an archive URL
        /// (file://, s3://, gs://, az://). Default: `$SADESIM_CACHE_DIR`, else
        /// `$XDG_CACHE_HOME/sadesim`, else `~/.cache/sadesim`.
        #[arg(long, value_name = "URL", conflicts_with = "no_asset_cache")]
        asset_cache: Option<String>,
        /// Build the world in memory and store no bundle (each `--processes` shard then
        /// builds it again).
        #[arg(long)]
        no_asset_cache: bool,
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
    /// its run folder, or a sweep's (sweep.html, sweep.json) from its runs' folders.
    Report {
        /// Run folder (`runs/<run>/<UTC time>/`, or one fetched with `archive get`), or a
        /// sweep's folder (`sweeps/<sweep>/`).
        run_dir: PathBuf,
    },
    /// Replay a recorded run in the browser: the live view's page on the run's
    /// recording.mcap, events.jsonl and world, with a timeline to play, pause and scrub.
    ///
    /// RUN is a local run folder (`runs/<run>/<UTC time>/`) or an archived one
    /// (`s3://bucket/prefix/<namespace>/<run>/<uid>`, ...; each file is checked against the
    /// run's manifest). Serves until Ctrl-C.
    View {
        /// Run folder or archive URL.
        run: String,
        /// Address to serve the page on.
        #[arg(long, default_value = "127.0.0.1:8490")]
        listen: std::net::SocketAddr,
        /// Frames per simulated second the timeline steps through (0 < rate <= 1000).
        #[arg(long, default_value_t = 20.0)]
        rate: f64,
    },
    /// The web console: plan a run on a map, launch it, watch it, browse the archive.
    ///
    /// Locally (default) it flies runs on this machine into --runs; with --cluster it
    /// creates SimulationRuns with the user's own Kubernetes identity. Serves until Ctrl-C.
    Console(super::console_cmd::ConsoleArgs),
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
        /// As an operator with its Kueue integration on (Helm `kueue.enabled`): a run with
        /// `spec.queue` starts as one Kueue Workload listing every pod of the run.
        #[arg(long)]
        kueue: bool,
    },
    /// A scenario's world assets: build them into the asset cache, or preview the world.
    ///
    /// The world (buildings, ground, open spaces) is built once per asset cache key (a
    /// hash of the world's parameters and its files' bytes) into
    /// `<cache>/assets/<key>/world/`: world.bin (what the roles load), world.glb (glTF 2.0),
    /// buildings.geojson, world.json and manifest.json. `sadesim run` and every shard then
    /// load it instead of building it again.
    Assets {
        #[command(subcommand)]
        command: AssetsCommand,
    },
    /// Read an OpenStreetMap extract (.osm.pbf) as SADE-SIM's world reads it: the buildings
    /// (footprints with courtyards, heights from `height`, `building:levels`, ... or a
    /// default) and open areas (parks, grass) within --extent-m of --origin, clipped to that
    /// square. Prints what was read, kept and skipped; --geojson writes the shapes (WGS84,
    /// with heights and OSM ids) for QGIS, geojson.io or a diff against another reader.
    ///
    /// Exits 2 naming the file and the byte or element when the extract cannot be read,
    /// does not cover the square, or holds no building there.
    Osm {
        /// The extract (`.osm.pbf`, e.g. from Geofabrik or BBBike).
        file: PathBuf,
        /// The world origin as `LAT,LON` in degrees (spec.origin).
        #[arg(long, value_parser = parse_lat_lon)]
        origin: (f64, f64),
        /// Half-width of the square world around the origin, metres (spec.world.extentM).
        #[arg(long, default_value_t = 2000.0)]
        extent_m: f64,
        /// Write the buildings and open areas as a GeoJSON FeatureCollection here.
        #[arg(long)]
        geojson: Option<PathBuf>,
        /// Write the world (buildings on flat ground) as glTF 2.0 binary (.glb) here, for
        /// Blender, three.js or any glTF viewer (x east, y up, z south, metres).
        #[arg(long)]
        glb: Option<PathBuf>,
        /// Print the statistics as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Read a digital elevation model (GeoTIFF in EPSG:4326 or WGS84 UTM, or an SRTM .hgt
    /// tile) as SADE-SIM's terrain reads it: check that it covers the square of --extent-m
    /// around --origin and print the ground there (lowest, highest, at the origin, largest
    /// slope); --at prints the elevation at given points.
    ///
    /// Exits 2 naming the file and the problem when the DEM cannot be read, is not
    /// georeferenced, uses another CRS, or does not cover the square.
    Dem {
        /// The DEM file (`.tif`, `.hgt`).
        file: PathBuf,
        /// The world origin as `LAT,LON` in degrees (spec.origin).
        #[arg(long, value_parser = parse_lat_lon)]
        origin: (f64, f64),
        /// Half-width of the square world around the origin, metres (spec.world.extentM).
        #[arg(long, default_value_t = 2000.0)]
        extent_m: f64,
        /// Also print the elevation at `LAT,LON` (repeatable).
        #[arg(long, value_parser = parse_lat_lon)]
        at: Vec<(f64, f64)>,
        /// Print as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// GNSS geometry from an orbit file.
    Gnss {
        #[command(subcommand)]
        command: GnssCommand,
    },
    /// Run the Kubernetes operator: reconcile SimulationRuns in the cluster of the current
    /// kubeconfig or service account.
    ///
    /// Logs JSON lines to stderr; stops cleanly on SIGTERM. The Lease for leader election is
    /// `sadesim-operator` in POD_NAMESPACE, held as POD_NAME.
    Operator(sadesim_operator::OperatorArgs),
    /// Run a SimulationSweep: its runs in parallel on this machine, each in its own folder
    /// under `<out>/<sweep>/`, then its report (sweep.html, sweep.json). Resumable: a rerun
    /// skips every run whose evidence is complete and verifies. Exits 0 when every run
    /// finished (whatever their verdicts), 1 when the sweep is invalid or a run could not
    /// be flown, 130 when interrupted.
    ///
    /// `sadesim sweep compare OLD NEW` compares two sweeps over the same space.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Sweep(SweepArgs),
}

/// `sadesim gnss ...`
#[derive(Debug, Subcommand)]
pub enum GnssCommand {
    /// The navigation satellites an orbit file puts over a place at a time: azimuth,
    /// elevation and range of each above the elevation mask, and their dilution of
    /// precision. Warns when the file's element sets are more than a week from the time.
    Sky {
        /// The orbit file: TLE or 3LE element sets, or OMM in KVN, XML, JSON or CSV (e.g.
        /// CelesTrak's gnss group); GPS, Galileo, GLONASS and BeiDou satellites are
        /// recognised by name.
        file: PathBuf,
        /// The receiver as `LAT,LON` or `LAT,LON,HEIGHT_M` (degrees, metres above the
        /// WGS84 ellipsoid).
        #[arg(long, value_parser = parse_lat_lon_height)]
        at: (f64, f64, f64),
        /// The time, RFC 3339 (`2026-05-01T14:30:00Z`).
        #[arg(long)]
        time: String,
        /// Elevation mask, degrees.
        #[arg(long, default_value_t = 10.0)]
        mask_deg: f64,
        /// Print as JSON.
        #[arg(long)]
        json: bool,
    },
    /// How each satellite of a scenario's constellation reaches antennas in its world: line
    /// of sight, a single facade reflection (with its extra path) or blocked, at the
    /// scenario's epoch plus `--at-s`. Prints JSON: the satellites (look angles from the
    /// origin), and for every point its verdict per satellite with the exact line of sight.
    Los {
        /// The scenario file (its `environment.gnss.constellation` and `world`).
        scenario: PathBuf,
        /// Antenna points: a JSON array of `[east, north, up]` in the run's ENU metres.
        #[arg(long)]
        points: PathBuf,
        /// Sim time after the scenario's epoch, seconds.
        #[arg(long, default_value_t = 0.0)]
        at_s: f64,
        /// Also write the world's buildings here as JSON prisms in ENU metres
        /// (`{"outer": [[e, n], ...], "holes": [...], "baseM": .., "roofM": ..}`), for
        /// independent checks.
        #[arg(long)]
        buildings: Option<PathBuf>,
    },
    /// The sky grid of a scenario: for every voxel of its world and every time slice of the
    /// run, the satellites in line of sight, those received only by a facade reflection, and
    /// the HDOP of those strong enough to use; written as a Zarr v2 group (read it with
    /// Python's `zarr` or xarray). For inspection: the receiver casts its rays live.
    Grid {
        /// The scenario file (its `environment.gnss.constellation` and `world`).
        scenario: PathBuf,
        /// The Zarr folder to write (e.g. `sky.zarr`).
        #[arg(long)]
        out: PathBuf,
        /// Voxel edge, metres.
        #[arg(long, default_value_t = 10.0)]
        spacing_m: f64,
        /// Sim seconds between time slices (the sky turns by a degree in 4 minutes).
        #[arg(long, default_value_t = 300.0)]
        slice_s: f64,
    },
}

/// `sadesim assets ...`
#[derive(Debug, Subcommand)]
pub enum AssetsCommand {
    /// Build the scenario's world into the asset cache, or say it is there already (a
    /// verified entry of the same key); a damaged or partial entry is rebuilt.
    Build {
        /// Scenario file with exactly one run.
        file: PathBuf,
        /// The asset cache: an archive URL (file://, s3://, gs://, az://). Default:
        /// `$SADESIM_CACHE_DIR`, else `$XDG_CACHE_HOME/sadesim`, else `~/.cache/sadesim`.
        #[arg(long, value_name = "URL")]
        asset_cache: Option<String>,
        /// No progress spinner.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Draw the scenario's world from above as a PNG: buildings coloured by height, open
    /// spaces, the ground's relief, the zones and every drone's home, before anyone flies.
    Show {
        /// Scenario file with exactly one run.
        file: PathBuf,
        /// Where to write the picture.
        #[arg(long, default_value = "world-preview.png")]
        png: PathBuf,
        /// Also write the picture as SVG here.
        #[arg(long)]
        svg: Option<PathBuf>,
        /// The asset cache to load the world from (and store it in), as for `build`.
        #[arg(long, value_name = "URL", conflicts_with = "no_asset_cache")]
        asset_cache: Option<String>,
        /// Build the world in memory and store nothing.
        #[arg(long)]
        no_asset_cache: bool,
        /// No progress spinner.
        #[arg(long, short)]
        quiet: bool,
        /// Also draw a horizontal slice of the run's urban wind field this many metres above
        /// the ground (the scenario's wind speed and direction; needs wind among buildings).
        #[arg(long, value_name = "METRES")]
        wind_slice_agl: Option<f64>,
        /// Where to write the wind slice.
        #[arg(long, default_value = "wind-slice.png", requires = "wind_slice_agl")]
        wind_png: PathBuf,
        /// The slice's area, metres east and north of the origin: EAST_MIN,NORTH_MIN,EAST_MAX,NORTH_MAX
        /// (default: the whole world).
        #[arg(long, value_name = "E0,N0,E1,N1", requires = "wind_slice_agl", value_parser = parse_area)]
        wind_area: Option<[f64; 4]>,
    },
}

/// `--wind-area`: four numbers, west < east and south < north.
fn parse_area(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|_| format!("{x:?} is not a number")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [e0, n0, e1, n1] if e0 < e1 && n0 < n1 && v.iter().all(|x| x.is_finite()) => Ok([e0, n0, e1, n1]),
        [_, _, _, _] => Err("expected EAST_MIN < EAST_MAX and NORTH_MIN < NORTH_MAX".into()),
        _ => Err(format!("expected four comma-separated numbers E0,N0,E1,N1, found {}", v.len())),
    }
}

/// `sadesim sweep FILE` or `sadesim sweep compare OLD NEW`.
#[derive(Debug, clap::Args)]
pub struct SweepArgs {
    #[command(subcommand)]
    pub command: Option<SweepCommand>,
    /// The SimulationSweep file (YAML or JSON).
    #[arg(required = true)]
    pub file: Option<PathBuf>,
    /// Folder to create the sweep's folder in.
    #[arg(long, default_value = "sweeps")]
    pub out: PathBuf,
    /// Runs in flight at once (default: the sweep's `parallelism`, at most this machine's
    /// cores).
    #[arg(long, short, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub jobs: Option<u32>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Override every run's clock: `realtime`, `asFastAsPossible` (or `afap`), or
    /// `scaled:FACTOR`.
    #[arg(long, value_parser = parse_clock)]
    pub clock: Option<sadesim_crds::run::Clock>,
    /// Print the sweep's runs as SimulationRun documents (a YAML stream) and run nothing:
    /// `sadesim run` on one of them flies that run alone, byte for byte as in the sweep.
    #[arg(long)]
    pub expand: bool,
    /// The asset cache URL (as for `sadesim run`).
    #[arg(long, value_name = "URL", conflicts_with = "no_asset_cache")]
    pub asset_cache: Option<String>,
    /// Build each run's world in memory and store no bundle.
    #[arg(long)]
    pub no_asset_cache: bool,
    /// Serve no MAVLink endpoints (sweeps of scripted missions only).
    #[arg(long)]
    pub no_mavlink: bool,
}

/// `sadesim sweep ...` subcommands.
#[derive(Debug, Subcommand)]
pub enum SweepCommand {
    /// Compare two sweeps over the same parameter space (e.g. two pilot versions): per
    /// cell, the pass rates and a one-sided Fisher exact test that NEW passes less often
    /// than OLD, then the same pooled over every cell. Exits 1 when NEW is significantly
    /// worse in a cell or pooled, so CI can gate a pilot on it.
    Compare {
        /// The old sweep's folder (or its sweep.json).
        old: PathBuf,
        /// The new sweep's folder (or its sweep.json).
        new: PathBuf,
        /// Significance level of the tests.
        #[arg(long, default_value_t = 0.05)]
        alpha: f64,
    },
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

/// `LAT,LON` in degrees, latitude within ±90 and longitude within ±180.
fn parse_lat_lon(text: &str) -> Result<(f64, f64), String> {
    let expected = "expected LAT,LON in degrees, e.g. 60.1699,24.9384";
    let (lat, lon) = text.split_once(',').ok_or_else(|| format!("{text:?}: {expected}"))?;
    let number = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    match (number(lat), number(lon)) {
        (Some(lat), Some(lon)) if lat.abs() <= 90.0 && lon.abs() <= 180.0 => Ok((lat, lon)),
        _ => Err(format!("{text:?}: {expected} (latitude within ±90, longitude within ±180)")),
    }
}

/// `LAT,LON` or `LAT,LON,HEIGHT_M`: degrees as [`parse_lat_lon`], the height in metres
/// (default 0).
fn parse_lat_lon_height(text: &str) -> Result<(f64, f64, f64), String> {
    let (lat_lon, height) = match text.rsplit_once(',') {
        Some((head, tail)) if head.contains(',') => (head, Some(tail)),
        _ => (text, None),
    };
    let (lat, lon) = parse_lat_lon(lat_lon)?;
    let height_m = match height {
        None => 0.0,
        Some(h) => h
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && v.abs() < 100_000.0)
            .ok_or_else(|| format!("{text:?}: the height {h:?} must be metres (|h| < 100 km)"))?,
    };
    Ok((lat, lon, height_m))
}
