//! `sadesim bench`: throughput of the full per-drone stack (environment, sensors, estimator,
//! navigator, controller, motors, rigid body, contacts, recording) in drone-steps per
//! wall-clock second, on a synthetic scenario: `drones` x500s over downtown Chicago flying
//! random waypoints as fast as possible.
//!
//! `sadesim bench --recording` alternates runs with `spec.recording` off (no
//! `recording.mcap`, no ULogs) and on, and reports what the recordings cost.
//!
//! `sadesim bench --whole-stack` alternates the bare simulation (no MAVLink, no
//! recordings) with the whole stack (MAVLink endpoints and routers at PX4's default rates,
//! `recording.mcap` and the ULogs); `--bare` runs the bare simulation alone.
//!
//! `sadesim bench --urban-wind` alternates runs with the urban wind field off
//! (`environment.wind.urban.model: none`, the plain log profile) and on (the default).
//!
//! `sadesim bench --cameras 320x240` alternates runs without cameras and with one
//! downward camera per drone at 10 Hz of that size (rendered on this machine's Vulkan
//! device, lavapipe without a GPU, and recorded at 1 Hz), and reports what they cost.
//!
//! `sadesim bench --airspace` measures the airspace authority's HTTP API instead: the
//! service with the Chicago case study's zone and fleet on 127.0.0.1, under an open-loop
//! load of entry requests, `GET /zones` and `GET /events` (see [`airspace_load`]).

pub mod airspace_load;
pub mod ground_station;
pub mod pairs;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim_crds::parse_run;

use crate::runner::{RunError, RunOptions, RunReport, run_local};

/// The benchmark scenario; `{drones}`, `{seconds}` and `{per_shard}` are filled in.
const SCENARIO: &str = r#"
apiVersion: sadesim.io/v1alpha1
kind: SimulationRun
metadata: {name: bench}
spec:
  origin: {latitudeDeg: 41.8796, longitudeDeg: -87.6237, altitudeMslM: 181}
  duration: {seconds}s
  clock: {mode: asFastAsPossible}
  seed: 1
  environment:
    wind: {speedMps: 5, directionFromDeg: 270, turbulence: light{urban}}
    gnss: {gnss}
  sharding: {dronesPerShard: {per_shard}}
  recording: {mcap: {mcap}, ulog: {ulog}{recording}}
  rendering: {enabled: {rendering}}
  world:
    openAreas:
      - {name: flight area, center: {latitudeDeg: 41.8796, longitudeDeg: -87.6237}, radiusM: 700}
  fleet:
    - name: bench
      count: {drones}
      airframe: x500
      operator: bench
      homes: {randomInArea: {center: {latitudeDeg: 41.8796, longitudeDeg: -87.6237}, radiusM: 400}}
      altitude: {maxAglM: 120}{cameras}
      mission:
        speedMps: 8
        items:
          - takeoff: {altitudeAglM: 20}
          - randomWaypoints:
              area: {center: {latitudeDeg: 41.8796, longitudeDeg: -87.6237}, radiusM: 500}
              count: 100
              minAltitudeAglM: 20
              maxAltitudeAglM: 60
"#;

/// Which recordings a benchmark run writes (`spec.recording.mcap`, `spec.recording.ulog`),
/// at the default rates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Recordings {
    pub mcap: bool,
    pub ulog: bool,
}

impl Recordings {
    /// Both, as a scenario without `spec.recording`.
    pub const ALL: Self = Self { mcap: true, ulog: true };
    /// Neither: the baseline of `--recording`.
    pub const NONE: Self = Self { mcap: false, ulog: false };

    /// For reports: `MCAP + ULog`, `MCAP`, `ULog` or `recordings off`.
    pub fn label(self) -> &'static str {
        match (self.mcap, self.ulog) {
            (true, true) => "MCAP + ULog",
            (true, false) => "MCAP",
            (false, true) => "ULog",
            (false, false) => "recordings off",
        }
    }
}

/// What `bench --recording` turns on in the runs it compares with recordings off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RecordingSet {
    /// `recording.mcap` and the ULogs (the defaults of `spec.recording`).
    All,
    /// `recording.mcap` only.
    Mcap,
    /// The ULogs only.
    Ulog,
}

impl RecordingSet {
    pub fn recordings(self) -> Recordings {
        match self {
            Self::All => Recordings::ALL,
            Self::Mcap => Recordings { mcap: true, ulog: false },
            Self::Ulog => Recordings { mcap: false, ulog: true },
        }
    }
}

/// Result of one benchmark run.
#[derive(Debug)]
pub struct BenchResult {
    pub drones: u32,
    pub shards: u32,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    /// CPU time of this process (all threads, user + system) during the run, s; `None`
    /// where `/proc/self/stat` is not available.
    pub cpu_time_s: Option<f64>,
    /// MAVLink endpoints and routers were on.
    pub mavlink: bool,
    /// The recordings written.
    pub recordings: Recordings,
    /// The ranging GNSS receiver was on.
    pub urban_gnss: bool,
    /// The urban wind field was on (the default; off: `urban: {model: none}`).
    pub urban_wind: bool,
    /// Every drone carried a camera of this size.
    pub cameras: Option<CameraSize>,
    /// Drone-steps (drones x physics steps) per wall second.
    pub drone_steps_per_s: f64,
    /// What the ground stations received (`Setup::ground_stations`, MAVLink runs).
    pub delivered: Option<ground_station::Received>,
    pub report: RunReport,
}

/// What one benchmark run turns on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Variant {
    /// MAVLink endpoints and routers.
    pub mavlink: bool,
    pub recordings: Recordings,
    /// The ranging GNSS receiver (urban GNSS) under the synthetic GPS + Galileo
    /// constellation, instead of the statistical receiver.
    pub urban_gnss: bool,
    /// The urban wind field over the city's buildings (the default, `urban: {model:
    /// diagnostic}`); `false` flies the plain log profile (`urban: {model: none}`).
    pub urban_wind: bool,
    /// One downward camera per drone of this size (width, height), 10 Hz, recorded at 1 Hz.
    pub cameras: Option<CameraSize>,
}

/// What every run of one `sadesim bench` invocation shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setup {
    pub drones: u32,
    /// Simulated seconds of each run.
    pub seconds: u32,
    pub drones_per_shard: u32,
    /// `spec.recording.rates.groundTruthHz`, Hz; `None`: the field's default.
    pub ground_truth_hz: Option<u32>,
    /// `spec.recording.compression`; `None`: the field's default.
    pub compression: Option<sadesim_crds::run::Compression>,
    /// In the runs with MAVLink, a ground station on every router reads all the telemetry
    /// ([`ground_station`]), so its delivery is paid for too.
    pub ground_stations: bool,
}

/// The image size of `bench --cameras`, `WIDTHxHEIGHT` on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CameraSize {
    pub width_px: u32,
    pub height_px: u32,
}

impl std::str::FromStr for CameraSize {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("{s:?}: expected WIDTHxHEIGHT in pixels, e.g. 320x240");
        let (w, h) = s.split_once('x').ok_or_else(bad)?;
        let (width_px, height_px) = (w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?);
        Ok(Self { width_px, height_px })
    }
}

impl std::fmt::Display for CameraSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.width_px, self.height_px)
    }
}

/// Runs the benchmark scenario.
///
/// # Errors
/// As [`run_local`].
pub fn run(setup: &Setup, out_root: std::path::PathBuf, variant: Variant) -> Result<BenchResult, RunError> {
    let Variant { mavlink, recordings, urban_gnss, urban_wind, cameras } = variant;
    let run = scenario(setup, variant);
    // No pilot: with MAVLink on, every drone builds and encodes PX4's default telemetry.
    // Unless ground stations listen (`--ground-stations`), the routers do not register with
    // the drones and the API links back off, so only heartbeats are sent.
    let options = RunOptions { out_root: Some(out_root), mavlink, start_pilot: false, ..RunOptions::default() };
    let stations = match mavlink && setup.ground_stations {
        true => {
            let plan = sadesim_planner::plan(&run)?;
            let stations = ground_station::GroundStations::start(&plan)
                .map_err(|e| RunError::Worker(format!("bench: ground station: {e}")))?;
            Some(stations)
        }
        false => None,
    };
    let cpu_before = process_cpu_time_s();
    let report = run_local(&run, &options, Arc::new(AtomicBool::new(false)));
    let cpu_time_s = cpu_before.zip(process_cpu_time_s()).map(|(a, b)| b - a);
    let delivered = stations
        .map(ground_station::GroundStations::stop)
        .transpose()
        .map_err(|e| RunError::Worker(format!("bench: ground station: {e}")))?;
    let report = report?;
    let s = &report.summary;
    let steps = f64::from(s.drones) * s.sim_time_s * 1000.0;
    Ok(BenchResult {
        drones: s.drones,
        shards: s.shards,
        sim_time_s: s.sim_time_s,
        wall_time_s: s.wall_time_s,
        drone_steps_per_s: steps / s.wall_time_s.max(1e-9),
        cpu_time_s,
        delivered,
        mavlink,
        recordings,
        urban_gnss,
        urban_wind,
        cameras,
        report,
    })
}

/// The benchmark scenario for one run.
fn scenario(setup: &Setup, variant: Variant) -> sadesim_crds::run::SimulationRun {
    let Setup { drones, seconds, drones_per_shard, ground_truth_hz, compression, ground_stations: _ } = *setup;
    let Variant { mavlink: _, recordings, urban_gnss, urban_wind, cameras } = variant;
    let camera = cameras.map_or(String::new(), |c| {
        format!(
            "\n      cameras: [{{name: down, widthPx: {}, heightPx: {}, horizontalFovDeg: 90, rateHz: 10, mount: {{pitchDeg: 90}}}}]",
            c.width_px, c.height_px
        )
    });
    // Urban GNSS under the built-in nominal GPS + Galileo constellation (no file).
    let gnss = if urban_gnss { "{rateHz: 5, constellation: {}}" } else { "{rateHz: 5}" };
    // More fields of `spec.recording`, after `mcap` and `ulog`.
    let mut recording = ground_truth_hz.map_or(String::new(), |hz| format!(", rates: {{groundTruthHz: {hz}}}"));
    if let Some(c) = compression {
        let name = serde_json::to_value(c).expect("a plain enum");
        recording += &format!(", compression: {}", name.as_str().expect("named by a string"));
    }
    let text = SCENARIO
        .replace("{gnss}", gnss)
        .replace("{urban}", if urban_wind { "" } else { ", urban: {model: none}" })
        .replace("{rendering}", &cameras.is_some().to_string())
        .replace("{cameras}", &camera)
        .replace("{recording}", &recording)
        .replace("{mcap}", &recordings.mcap.to_string())
        .replace("{ulog}", &recordings.ulog.to_string())
        .replace("{drones}", &drones.to_string())
        .replace("{seconds}", &seconds.to_string())
        .replace("{per_shard}", &drones_per_shard.to_string());
    parse_run(&text).expect("the benchmark scenario is valid")
}

/// `--compression`'s codec by its name in the scenario (`zstd`, `lz4`, `none`).
///
/// # Errors
/// Any other name, quoted.
pub fn compression_named(name: &str) -> Result<sadesim_crds::run::Compression, crate::cli::CliError> {
    serde_json::from_value(serde_json::Value::String(name.into())).map_err(|_| {
        crate::cli::CliError::Failed(format!("bench: --compression \"{name}\": expected zstd, lz4 or none"))
    })
}

/// The middle value (the upper one of the two middle values for an even count); `None`
/// for no values.
pub fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

/// What the "on" variant costs, % of the "off" one: the median over `(off, on)` pairs of
/// `(on - off) / off`. Each pair ran back to back, so the machine's speed drift between
/// minutes (tens of percent here) mostly cancels within a pair.
pub fn paired_cost_percent(pairs: &[(f64, f64)]) -> Option<f64> {
    median(pairs.iter().filter(|(off, _)| *off > 0.0).map(|(off, on)| (on - off) / off * 100.0).collect())
}

/// The CPU time the recorder's thread spent on `recording.mcap` and the ULogs, % of the
/// rest of the process's CPU time in that run (the simulation and everything else); `None`
/// without a process CPU time.
pub fn recorder_share_percent(result: &BenchResult) -> Option<f64> {
    let c = result.report.summary.recording_cpu_s;
    let recording = c.mcap + c.ulog;
    result.cpu_time_s.map(|total| recording / (total - recording).max(1e-9) * 100.0)
}

/// User + system CPU time of this process so far, s (Linux `/proc/self/stat`, fields 14
/// and 15 in clock ticks of 1/100 s, the kernel's USER_HZ on every mainstream platform).
fn process_cpu_time_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may contain spaces; fields after it follow the last ')'.
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// The scenario whose zone, fleet and credentials the airspace benchmark serves.
const CHICAGO: &str = include_str!("../../examples/chicago-museum.yaml");

/// Errors of the airspace benchmark.
#[derive(Debug, thiserror::Error)]
pub enum AirspaceBenchError {
    /// The embedded Chicago example does not plan (a bug in this build).
    #[error("failed to plan the Chicago example: {0}")]
    Plan(String),
    /// The service could not listen on 127.0.0.1.
    #[error("failed to start the airspace service: {0}")]
    Start(#[from] std::io::Error),
}

/// Serves the airspace API with the Chicago example's zones and credentials on a free
/// port of 127.0.0.1 and loads it with `rate_per_s` requests per second for `seconds`
/// over `connections` keep-alive connections. The sim clock stays at 0 (no flight), so
/// leases never expire and verdicts are the same all along.
///
/// # Errors
/// The example does not plan, or the service cannot start.
pub fn run_airspace(
    rate_per_s: f64,
    seconds: f64,
    connections: usize,
) -> Result<airspace_load::LoadReport, AirspaceBenchError> {
    run_airspace_with(rate_per_s, seconds, connections).map(|(report, _)| report)
}

/// [`run_airspace`], also returning the service's state afterwards (what the authority
/// recorded).
fn run_airspace_with(
    rate_per_s: f64,
    seconds: f64,
    connections: usize,
) -> Result<(airspace_load::LoadReport, sim_worker::airspace::SharedAirspace), AirspaceBenchError> {
    use sim_worker::airspace::{AirspaceState, service};
    let run = parse_run(CHICAGO).map_err(|e| AirspaceBenchError::Plan(e.to_string()))?;
    let plan = sadesim_planner::plan(&run).map_err(|e| AirspaceBenchError::Plan(e.to_string()))?;
    let state = AirspaceState::new(&plan, &|name| std::env::var(name).ok());
    let state = std::sync::Arc::new(std::sync::Mutex::new(state));
    let service = service::start(state.clone(), std::net::SocketAddr::from(([127, 0, 0, 1], 0)))?;
    let report = airspace_load::run(service.addr, rate_per_s, seconds, connections);
    service.stop();
    Ok((report, state))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_airspace_load_gets_every_request_answered_as_expected() {
        let (report, state) = run_airspace_with(200.0, 1.0, 4).unwrap();
        assert_eq!(report.requests, 200, "{report}");
        assert_eq!(report.answered, 200, "{report}");
        assert_eq!(report.errors, 0, "{report}");
        // The mix: 3 grants, 5 denials, GET /zones and GET /events in every 10 requests.
        assert_eq!((report.granted, report.denied), (60, 100), "{report}");
        assert_eq!(state.lock().unwrap().authority.requests.len(), 160);
        assert!(report.p50_ms <= report.p99_ms && report.p99_ms <= report.max_ms, "{report}");
    }

    #[test]
    fn the_ground_truth_rate_goes_into_the_scenario_and_its_default_stays_otherwise() {
        let v =
            Variant { mavlink: false, recordings: Recordings::ALL, urban_gnss: false, urban_wind: true, cameras: None };
        let rates = |ground_truth_hz| {
            let setup = Setup {
                drones: 4,
                seconds: 5,
                drones_per_shard: 2,
                ground_truth_hz,
                compression: None,
                ground_stations: false,
            };
            scenario(&setup, v).spec.recording.expect("recorded").rates
        };
        assert_eq!(rates(Some(25)).ground_truth_hz, 25.0);
        assert_eq!(rates(None), sadesim_crds::run::RecordingRates::default());
    }

    #[test]
    fn the_compression_goes_into_the_scenario_and_its_default_stays_otherwise() {
        use sadesim_crds::run::Compression;
        let v =
            Variant { mavlink: false, recordings: Recordings::ALL, urban_gnss: false, urban_wind: true, cameras: None };
        let compression = |compression, ground_truth_hz| {
            let setup = Setup {
                drones: 4,
                seconds: 5,
                drones_per_shard: 2,
                ground_truth_hz,
                compression,
                ground_stations: false,
            };
            let recording = scenario(&setup, v).spec.recording.expect("recorded");
            (recording.compression, recording.rates.ground_truth_hz)
        };
        assert_eq!(compression(Some(Compression::Lz4), None), (Compression::Lz4, 100.0));
        assert_eq!(compression(Some(Compression::None), Some(50)), (Compression::None, 50.0));
        assert_eq!(compression(None, None).0, Compression::default());
        for name in ["zstd", "lz4", "none"] {
            let c = compression_named(name).unwrap();
            assert_eq!(compression(Some(c), None).0, c, "{name}");
        }
        assert!(compression_named("gzip").unwrap_err().to_string().contains("gzip"));
    }

    #[test]
    fn paired_costs_take_the_median_ratio_of_back_to_back_runs() {
        // The machine slows down between pairs: 2.0 -> 3.0 s baseline. Each pair costs
        // 10 %, except an outlier; the ratio of the medians would say +32 %.
        let pairs = [(2.0, 2.2), (3.0, 3.3), (2.5, 2.75), (2.0, 3.5), (3.0, 3.3)];
        let cost = paired_cost_percent(&pairs).unwrap();
        assert!((cost - 10.0).abs() < 1e-9, "{cost}");
        assert_eq!(paired_cost_percent(&[]), None);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
    }
}
