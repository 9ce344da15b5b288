//! `sadesim bench`: throughput of the full per-drone stack (environment, sensors, estimator,
//! navigator, controller, motors, rigid body, contacts, recording) in drone-steps per
//! wall-clock second, on a synthetic scenario: `drones` x500s over downtown Chicago flying
//! random waypoints as fast as possible.

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
    wind: {speedMps: 5, directionFromDeg: 270, turbulence: light}
    gnss: {rateHz: 5}
  sharding: {dronesPerShard: {per_shard}}
  world:
    openAreas:
      - {name: flight area, center: {latitudeDeg: 41.8796, longitudeDeg: -87.6237}, radiusM: 700}
  fleet:
    - name: bench
      count: {drones}
      airframe: x500
      operator: bench
      homes: {randomInArea: {center: {latitudeDeg: 41.8796, longitudeDeg: -87.6237}, radiusM: 400}}
      altitude: {maxAglM: 120}
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
    /// Drone-steps (drones x physics steps) per wall second.
    pub drone_steps_per_s: f64,
    pub report: RunReport,
}

/// Runs the benchmark scenario.
///
/// # Errors
/// As [`run_local`].
pub fn run(
    drones: u32,
    seconds: u32,
    drones_per_shard: u32,
    out_root: std::path::PathBuf,
    mavlink: bool,
) -> Result<BenchResult, RunError> {
    let text = SCENARIO
        .replace("{drones}", &drones.to_string())
        .replace("{seconds}", &seconds.to_string())
        .replace("{per_shard}", &drones_per_shard.to_string());
    let run = parse_run(&text).expect("the benchmark scenario is valid");
    // No pilot: with MAVLink on, every drone streams PX4's default telemetry to its API
    // port and to the router, which is the cost `--mavlink` measures.
    let options = RunOptions { out_root: Some(out_root), mavlink, start_pilot: false, ..RunOptions::default() };
    let cpu_before = process_cpu_time_s();
    let report = run_local(&run, &options, Arc::new(AtomicBool::new(false)))?;
    let cpu_time_s = cpu_before.zip(process_cpu_time_s()).map(|(a, b)| b - a);
    let s = &report.summary;
    let steps = f64::from(s.drones) * s.sim_time_s * 1000.0;
    Ok(BenchResult {
        drones: s.drones,
        shards: s.shards,
        sim_time_s: s.sim_time_s,
        wall_time_s: s.wall_time_s,
        drone_steps_per_s: steps / s.wall_time_s.max(1e-9),
        cpu_time_s,
        mavlink,
        report,
    })
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
