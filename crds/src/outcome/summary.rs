//! `summary.json`: the outcome of a run, per drone and in total, as the coordinator writes
//! it at the end and the report, the CLI and the Kubernetes status read it.

use serde::{Deserialize, Serialize};

use super::ending::EndReason;
use super::verdict::RunVerdict;

/// Per-drone outcome.
#[derive(Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct DroneSummary {
    pub index: u32,
    pub name: String,
    pub group: String,
    pub took_off: bool,
    pub landed: bool,
    pub crashed: bool,
    pub max_height_agl_m: f64,
    /// Horizontal distance flown, m.
    pub distance_m: f64,
    pub waypoints_reached: u32,
    pub failsafes: u32,
    pub final_battery_remaining: f64,
    /// How the drone's GNSS receiver did in flight (absent when it never flew with one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss: Option<GnssSummary>,
    /// The wind the drone met in flight (absent in runs without wind, or when it never
    /// flew).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<WindSummary>,
    /// Simulated seconds airborne: the sum of the sync windows at whose end the drone was
    /// neither on the ground nor crashed (absent when it never was).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flight_time_s: Option<f64>,
    /// Horizontal distance, m (local ENU), from where the drone last landed (a `landed`
    /// event, not a crash; its position at the end of that window) to its home (absent
    /// when it never landed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub landing_error_m: Option<f64>,
    /// The closest horizontal approach, m, of the drone while airborne to a zone it held
    /// no valid lease for, counting a zone only while it was active and the drone was
    /// between its floor and ceiling; 0 when it was inside one (the compliance monitor's
    /// `unauthorizedEntry`). Absent in runs without zones, and for a drone that never
    /// came within such a zone's altitude band while airborne.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub closest_zone_m: Option<f64>,
    /// Battery energy drawn over the run, Wh: the charge drawn in each sync window times
    /// the terminal voltage at its end, summed from the second window on (absent when
    /// the drone was seen in fewer than two windows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy_wh: Option<f64>,
}

/// The horizontal wind at a drone (mean wind, urban field and gusts: what its airframe
/// felt) over the sync windows it was airborne, m/s.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct WindSummary {
    /// Sync windows airborne.
    pub windows: u32,
    pub mean_mps: f64,
    pub max_mps: f64,
}

/// A drone's GNSS in flight (the receiver's epochs while airborne): what its receiver saw
/// and how far its fixes and its estimate were from the truth.
#[derive(Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct GnssSummary {
    /// Receiver epochs while airborne (fixes or not).
    pub epochs: u32,
    /// Epochs without a 3D fix (2D or none), outages included.
    pub epochs_without_3d_fix: u32,
    /// Mean satellites used over the epochs with a fix.
    pub mean_satellites: f64,
    /// Median HDOP over the epochs with a fix (absent without one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_hdop: Option<f64>,
    /// Horizontal distance of the receiver's 3D fixes from the true position, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fix_error_m: Option<ErrorStats>,
    /// Horizontal distance of the estimate (what the autopilot flies on) from the true
    /// position at the receiver's epochs, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_error_m: Option<ErrorStats>,
    /// Of the satellites above the elevation mask, the share received only by a facade
    /// reflection (ranging receiver; absent for the statistical one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reflected_share: Option<f64>,
}

/// Order statistics of an error, metres.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct ErrorStats {
    pub median: f64,
    pub p95: f64,
    pub max: f64,
}

impl ErrorStats {
    /// The statistics of `values` (sorted in place; NaNs last); `None` when empty.
    /// Percentiles are nearest-rank.
    pub fn of(values: &mut [f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        values.sort_by(f64::total_cmp);
        let rank = |q: f64| values[((q * values.len() as f64).ceil() as usize).clamp(1, values.len()) - 1];
        Some(Self { median: rank(0.5), p95: rank(0.95), max: values[values.len() - 1] })
    }
}

/// The whole run.
#[derive(Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RunSummary {
    pub run: String,
    pub end_reason: EndReason,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    /// Simulated seconds per wall second over the whole run.
    pub real_time_factor: f64,
    pub drones: u32,
    pub shards: u32,
    pub airborne: u32,
    pub crashed: u32,
    pub events: u64,
    pub pilots_released_at_s: Option<f64>,
    /// Wall-clock seconds simulated time held at the release until the pilot's first
    /// MAVLink frame reached a drone it flies. Absent when the run did not hold (no pilot
    /// started, no MAVLink, no drone without a mission) or ended while holding (the pilot
    /// exited, Ctrl-C, or `endReason` `pilotNotConnected`: silent for
    /// `spec.pilot.connectTimeoutS`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pilot_connect_wait_s: Option<f64>,
    pub per_drone: Vec<DroneSummary>,
    /// The scenario's criteria judged at the end (absent when the run did not get that far).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verdict: Option<RunVerdict>,
    /// CPU seconds the recorder spent writing each kind of file (measured on its thread).
    #[serde(default)]
    pub recording_cpu_s: RecordingCost,
    /// CPU seconds each shard spent stepping its drones, its waits for the coordinator
    /// excluded, plus its MAVLink I/O thread (building, encoding and sending the
    /// telemetry), by shard index: the simulation's own cost, apart from the coordinator's
    /// and the recorder's. Runs whose shards are threads of this process (`sadesim run`);
    /// empty when they are processes of their own (`sim-worker shard`, each of which prints
    /// its figure in its log).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shard_cpu_s: Vec<f64>,
    /// Each onboard camera's frames, and how many were late (runs with cameras).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cameras: Vec<CameraTally>,
    /// How the pilot process `sadesim run` started ended, and whether that is what
    /// `spec.pilot.expectedExit` asks (absent without one: no `spec.pilot`, `--no-pilot`,
    /// or a Kubernetes run, whose status says how the pilot's Job ended).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pilot: Option<super::pilot::PilotOutcome>,
}

/// One camera on one drone over a run.
#[derive(Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct CameraTally {
    pub drone: String,
    pub camera: String,
    /// Frames rendered (and served), one per period of its `rateHz`.
    pub frames: u64,
    /// Frames of a paced run (realtime, scaled) handed to pilots more than one camera
    /// period (on the wall clock: `1 / rateHz / factor`) after their simulated time was due
    /// on the wall clock: a real camera would already have taken the next one. Always 0 in `asFastAsPossible` runs, which wait
    /// for every frame.
    pub late: u64,
    /// The latest a frame came after its due time, wall seconds (0 when none was behind).
    pub max_late_s: f64,
}

/// CPU seconds the recorder's threads spent on each kind of file over a run.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct RecordingCost {
    /// `recording.mcap`.
    pub mcap: f64,
    /// `ulog/*.ulg`.
    pub ulog: f64,
    /// `events.jsonl`, `trajectory.csv`, `trajectory.geojson` and the summary's totals.
    pub other: f64,
}

impl RecordingCost {
    /// Everything the recorder spent.
    pub fn total(&self) -> f64 {
        self.mcap + self.ulog + self.other
    }
}

/// How many drones are in the air, on the ground, crashed: what progress displays show.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[serde(rename_all = "camelCase")]
pub struct FleetCounts {
    pub airborne: u32,
    pub on_ground: u32,
    pub crashed: u32,
}

impl FleetCounts {
    /// Counts drones from their `(on_ground, crashed)` flags: a crashed drone counts as
    /// crashed only, a drone neither on the ground nor crashed as airborne.
    pub fn from_flags(flags: impl IntoIterator<Item = (bool, bool)>) -> Self {
        let mut c = Self::default();
        for (on_ground, crashed) in flags {
            if crashed {
                c.crashed += 1;
            } else if on_ground {
                c.on_ground += 1;
            } else {
                c.airborne += 1;
            }
        }
        c
    }
}
