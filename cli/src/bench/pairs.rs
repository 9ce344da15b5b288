//! The throughput `sadesim bench`: its runs (one, or back-to-back off/on pairs of MAVLink or
//! recordings), one line each, and the median cost of the "on" variant over the pairs.

use std::io::Write;

use super::{Recordings, Variant};

/// What the pairs of a benchmark compare (the "off" variant against the "on" one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Comparison {
    /// One run: MAVLink off, every recording.
    None,
    /// MAVLink off / on.
    Mavlink,
    /// Recordings off / the chosen set.
    Recording(super::RecordingSet),
    /// The statistical GNSS receiver / the ranging receiver among the buildings.
    UrbanGnss,
    /// The plain log wind profile (`urban: {model: none}`) / the urban wind field (the
    /// default).
    UrbanWind,
    /// No cameras / one downward camera of this size per drone at 10 Hz.
    Cameras(super::CameraSize),
    /// The bare simulation (no MAVLink, no recordings) / the whole stack with its I/O
    /// (MAVLink endpoints and routers, `recording.mcap` and the ULogs).
    WholeStack,
    /// One run of the bare simulation, no comparison.
    BareOnly,
}
use crate::cli::{CliError, Outcome, count};

/// Runs the throughput benchmark (`sadesim bench` without `--airspace`) and writes its
/// report to `out`: each run, then with a comparison the paired costs and each variant's
/// drone-steps/s.
///
/// # Errors
/// A run that could not start or finish ([`CliError::Run`]), or a failed write.
pub fn run_pairs(
    setup: crate::bench::Setup,
    comparison: Comparison,
    repeat: u32,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let recording = match comparison {
        Comparison::Recording(set) => Some(set),
        Comparison::WholeStack => Some(super::RecordingSet::All),
        _ => None,
    };
    use crate::bench::BenchResult;
    let root = std::env::temp_dir().join(format!("sadesim-bench-{}", std::process::id()));
    let variants = schedule(comparison, repeat);
    let mut results = Vec::new();
    for &variant in &variants {
        let result = crate::bench::run(&setup, root.clone(), variant)
            .map_err(|source| CliError::Run { path: "bench".into(), source })?;
        let (with_mavlink, recordings) = (variant.mavlink, variant.recordings);
        writeln!(
            out,
            "bench{}{}{}{}: {} in {} at 1000 Hz: {:.0} s simulated in {:.2} s wall{} = {:.0} drone-steps/s (real-time factor {:.1}, {} cores available)",
            if with_mavlink { " (MAVLink on)" } else { "" },
            if recording.is_some() { format!(" ({})", recordings.label()) } else { String::new() },
            if variant.urban_gnss { " (urban GNSS)" } else { "" },
            match (comparison, variant.urban_wind, variant.cameras) {
                (Comparison::UrbanWind, true, _) => " (urban wind field)".to_string(),
                (Comparison::UrbanWind, false, _) => " (urban wind off)".to_string(),
                (Comparison::Cameras(_), _, Some(c)) => format!(" (a {c} camera per drone at 10 Hz)"),
                (Comparison::Cameras(_), _, None) => " (no cameras)".to_string(),
                (Comparison::BareOnly, ..) => " (bare: no MAVLink, no recordings)".to_string(),
                _ => String::new(),
            },
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
        if let Some(us) = shard_cpu_per_drone_step_us(&result) {
            let shards = &result.report.summary.shard_cpu_s;
            writeln!(
                out,
                "  shards' threads: {:.3} s CPU stepping the drones (MAVLink I/O included) = {us:.3} µs per drone-step (shards {:.3}-{:.3} s)",
                shards.iter().sum::<f64>(),
                shards.iter().copied().fold(f64::INFINITY, f64::min),
                shards.iter().copied().fold(0.0, f64::max),
            )?;
        }
        if let Some(got) = result.delivered {
            let per = |n: u64| n as f64 / drone_seconds(&result);
            writeln!(
                out,
                "  ground stations: {} frames in {} datagrams ({:.1} MB) = {:.0} frames, {:.1} datagrams, {:.0} bytes per drone-second",
                got.frames,
                got.datagrams,
                got.bytes as f64 / 1e6,
                per(got.frames),
                per(got.datagrams),
                per(got.bytes),
            )?;
        }
        if let Some(tallies) = Some(&result.report.summary.cameras).filter(|t| !t.is_empty()) {
            let frames: u64 = tallies.iter().map(|t| t.frames).sum();
            writeln!(
                out,
                "  cameras: {frames} frames rendered, {:.1} frames per wall second",
                frames as f64 / result.wall_time_s.max(1e-9)
            )?;
        }
        results.push(result);
    }
    let _ = std::fs::remove_dir_all(&root);
    // What the pairs compare: the report's label, and which runs are the "on" variant.
    let label = match comparison {
        Comparison::Mavlink => Some("MAVLink cost".to_string()),
        Comparison::Recording(set) => Some(format!("Recording cost ({})", set.recordings().label())),
        Comparison::UrbanGnss => Some("Urban GNSS cost".to_string()),
        Comparison::UrbanWind => Some("Urban wind cost".to_string()),
        Comparison::Cameras(c) => Some(format!("Camera cost ({c} at 10 Hz per drone)")),
        Comparison::WholeStack => Some("MAVLink + recording cost".to_string()),
        Comparison::None | Comparison::BareOnly => None,
    };
    let is_on = |r: &BenchResult| match comparison {
        Comparison::Mavlink => r.mavlink,
        Comparison::UrbanGnss => r.urban_gnss,
        Comparison::UrbanWind => r.urban_wind,
        Comparison::Cameras(_) => r.cameras.is_some(),
        Comparison::WholeStack => r.mavlink && r.recordings != Recordings::NONE,
        _ => r.recordings != Recordings::NONE,
    };
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
            crate::bench::paired_cost_percent(&wall).map(|c| format!("{c:+.1} % wall time")).unwrap_or_default(),
            crate::bench::paired_cost_percent(&cpu).map(|c| format!(", {c:+.1} % CPU time")).unwrap_or_default()
        )?;
        // Throughput of each variant and their ratio, on / off, per pair (the figure a
        // throughput budget such as "at most 10 % slower" is checked against).
        let rates = pairs(&|r: &BenchResult| Some(r.drone_steps_per_s));
        if let Some(ratio) = crate::bench::median(rates.iter().map(|(off, on)| on / off.max(1e-9)).collect()) {
            let off = crate::bench::median(rates.iter().map(|p| p.0).collect()).unwrap_or_default();
            let on = crate::bench::median(rates.iter().map(|p| p.1).collect()).unwrap_or_default();
            writeln!(
                out,
                "{label}: {off:.0} drone-steps/s off, {on:.0} on (medians); on / off {ratio:.3} (median of the pairs' ratios)"
            )?;
        }
        // Within each run: the recorder's CPU time on the recordings against the
        // rest of the process's CPU time (the simulation), immune to the drift
        // between runs that the pairs above suffer from.
        let shares: Vec<f64> =
            results.iter().filter(|r| is_on(r)).filter_map(crate::bench::recorder_share_percent).collect();
        if recording.is_some()
            && let Some(c) = crate::bench::median(shares)
        {
            writeln!(
                out,
                "Recordings measured on the recorder's thread (median of {repeat}): {c:.1} % of the simulation's CPU time"
            )?;
        }
    }
    Ok(Outcome::Success)
}

/// The runs of a benchmark in order: with a comparison, `repeat` (at least 1) back-to-back
/// (off, on) pairs, every other one "on" first; otherwise one run with MAVLink off and
/// every recording.
fn schedule(comparison: Comparison, repeat: u32) -> Vec<Variant> {
    let base =
        Variant { mavlink: false, recordings: Recordings::ALL, urban_gnss: false, urban_wind: true, cameras: None };
    // No MAVLink (already off in `base`), no recordings.
    let bare = Variant { recordings: Recordings::NONE, ..base };
    // The (off, on) variants a comparison alternates; `None` for a single run.
    let compared: Option<[Variant; 2]> = match comparison {
        Comparison::Mavlink => Some([base, Variant { mavlink: true, ..base }]),
        Comparison::Recording(set) => Some([bare, Variant { recordings: set.recordings(), ..base }]),
        Comparison::UrbanGnss => Some([base, Variant { urban_gnss: true, ..base }]),
        Comparison::UrbanWind => Some([Variant { urban_wind: false, ..base }, base]),
        Comparison::Cameras(size) => Some([base, Variant { cameras: Some(size), ..base }]),
        Comparison::WholeStack => Some([bare, Variant { mavlink: true, ..base }]),
        Comparison::None | Comparison::BareOnly => None,
    };
    match compared {
        // Every other pair runs "on" first, so what one position in a pair gains
        // (caches warmed, the previous run's files being written back) cancels out.
        Some([off, on]) => (0..repeat.max(1)).flat_map(|i| if i % 2 == 0 { [off, on] } else { [on, off] }).collect(),
        None if comparison == Comparison::BareOnly => vec![bare],
        None => vec![base],
    }
}

/// The shards' own cost: the CPU their threads spent stepping the drones (waits for the
/// coordinator excluded, `summary.json` `shardCpuS`) per drone-step, µs; `None` when the
/// run has no such figure.
pub fn shard_cpu_per_drone_step_us(result: &crate::bench::BenchResult) -> Option<f64> {
    let shards = &result.report.summary.shard_cpu_s;
    (!shards.is_empty()).then(|| shards.iter().sum::<f64>() / (drone_seconds(result) * 1000.0) * 1e6)
}

/// Drones x simulated seconds of a benchmark run.
fn drone_seconds(result: &crate::bench::BenchResult) -> f64 {
    (f64::from(result.drones) * result.sim_time_s).max(1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::RecordingSet;

    const BASE: Variant =
        Variant { mavlink: false, recordings: Recordings::ALL, urban_gnss: false, urban_wind: true, cameras: None };

    #[test]
    fn mavlink_pairs_alternate_which_variant_runs_first() {
        let (off, on) = (BASE, Variant { mavlink: true, ..BASE });
        assert_eq!(schedule(Comparison::Mavlink, 3), vec![off, on, on, off, off, on]);
    }

    #[test]
    fn recording_pairs_compare_the_chosen_set_against_recordings_off() {
        let off = Variant { recordings: Recordings::NONE, ..BASE };
        let on = Variant { recordings: Recordings { mcap: true, ulog: false }, ..BASE };
        assert_eq!(schedule(Comparison::Recording(RecordingSet::Mcap), 2), vec![off, on, on, off]);
    }

    #[test]
    fn urban_gnss_pairs_change_only_the_receiver() {
        let on = Variant { urban_gnss: true, ..BASE };
        assert_eq!(schedule(Comparison::UrbanGnss, 2), vec![BASE, on, on, BASE]);
    }

    #[test]
    fn urban_wind_pairs_change_only_the_field() {
        // The benchmark flies in the field by default: "off" is the plain profile.
        let off = Variant { urban_wind: false, ..BASE };
        assert_eq!(schedule(Comparison::UrbanWind, 3), vec![off, BASE, BASE, off, off, BASE]);
    }

    #[test]
    fn camera_pairs_add_one_camera_per_drone() {
        let size: crate::bench::CameraSize = "160x120".parse().unwrap();
        assert_eq!((size.width_px, size.height_px), (160, 120));
        let on = Variant { cameras: Some(size), ..BASE };
        assert_eq!(schedule(Comparison::Cameras(size), 2), vec![BASE, on, on, BASE]);
        let bad = "160".parse::<crate::bench::CameraSize>().unwrap_err();
        assert!(bad.contains("expected WIDTHxHEIGHT"), "{bad}");
    }

    #[test]
    fn whole_stack_pairs_turn_mavlink_and_every_recording_on_together() {
        let bare = Variant { recordings: Recordings::NONE, ..BASE };
        let whole = Variant { mavlink: true, ..BASE };
        assert_eq!(whole.recordings, Recordings::ALL);
        assert_eq!(schedule(Comparison::WholeStack, 2), vec![bare, whole, whole, bare]);
        assert_eq!(schedule(Comparison::BareOnly, 3), vec![bare], "one run, nothing compared");
    }

    #[test]
    fn zero_repeats_still_run_one_pair() {
        assert_eq!(schedule(Comparison::Mavlink, 0), vec![BASE, Variant { mavlink: true, ..BASE }]);
    }

    #[test]
    fn without_a_comparison_one_run_with_every_recording() {
        assert_eq!(schedule(Comparison::None, 5), vec![BASE]);
    }
}
