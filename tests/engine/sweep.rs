//! Sweeps end to end (`sadesim::sweep`): tests/engine/sweeps/headwind.yaml flown locally,
//! its report checked against the runs' own `summary.json` files, the pass rate against
//! the wind, a resumed sweep, a comparison of two versions, and a sweep's run against the
//! same run flown alone.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunOptions, run_local};
use sadesim::sweep::{LoadedSweep, SweepOptions, SweepOutcome, load, run_sweep};
use serde_json::Value;

fn headwind() -> LoadedSweep {
    load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("engine/sweeps/headwind.yaml")).unwrap()
}

fn out_root(name: &str) -> PathBuf {
    let root = std::env::temp_dir().join(format!("sadesim-sweep-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    root
}

fn options(root: &Path, jobs: u32, mavlink: bool) -> SweepOptions {
    SweepOptions {
        out_root: root.to_path_buf(),
        jobs: Some(jobs),
        progress: false,
        clock: None,
        asset_cache: None,
        mavlink,
    }
}

fn fly(loaded: &LoadedSweep, options: &SweepOptions) -> SweepOutcome {
    run_sweep(loaded, options, Arc::new(AtomicBool::new(false))).unwrap()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

/// Wilson score interval at 95 %, written out here independently of the report's code.
fn wilson95(passed: f64, n: f64) -> (f64, f64) {
    let z = 1.959_963_984_540_054_f64;
    let p = passed / n;
    let centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n);
    let half = z / (1.0 + z * z / n) * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    (centre - half, centre + half)
}

#[test]
fn the_report_is_what_the_runs_summaries_say_and_the_pass_rate_falls_with_the_wind() {
    let root = out_root("report");
    let loaded = headwind();
    let outcome = fly(&loaded, &options(&root, 2, false));
    assert_eq!((outcome.ran, outcome.skipped, outcome.errors.len()), (6, 0, 0), "{:?}", outcome.errors);
    let dir = root.join("headwind");
    let report = json(&dir.join("sweep.json"));
    assert_eq!(report, serde_json::to_value(&outcome.report).unwrap(), "sweep.json is the report returned");

    // Recompute every cell from the run folders alone: which runs belong to which cell
    // (labels in each run's document), and whether each passed (its summary's verdict).
    let mut rates = Vec::new();
    for cell in report["cells"].as_array().unwrap() {
        let index = cell["index"].as_u64().unwrap();
        let (mut finished, mut passed, mut flight_times) = (0u32, 0u32, Vec::new());
        for r in loaded.expansion.runs.iter().filter(|r| u64::from(r.cell) == index) {
            let document = std::fs::read_to_string(dir.join("scenarios").join(format!("{}.yaml", r.name()))).unwrap();
            assert!(document.contains(&format!("sadesim.io/sweep-cell: '{index}'")), "{document}");
            let summary = json(&dir.join(r.name()).join("summary.json"));
            finished += 1;
            passed += u32::from(summary["verdict"]["passed"] == Value::Bool(true));
            flight_times
                .extend(summary["perDrone"].as_array().unwrap().iter().filter_map(|d| d["flightTimeS"].as_f64()));
        }
        assert_eq!(cell["finished"], finished, "{cell}");
        assert_eq!(cell["passed"], passed, "{cell}");
        let (lo, hi) = wilson95(f64::from(passed), f64::from(finished));
        assert!((cell["ciLow"].as_f64().unwrap() - lo).abs() < 1e-9, "{cell} vs {lo}");
        assert!((cell["ciHigh"].as_f64().unwrap() - hi).abs() < 1e-9, "{cell} vs {hi}");
        flight_times.sort_by(f64::total_cmp);
        let median = flight_times[flight_times.len().div_ceil(2) - 1]; // nearest rank
        let stats = cell["metrics"].as_array().unwrap().iter().find(|m| m["metric"] == "flightTimeS").unwrap();
        assert_eq!(stats["n"], flight_times.len(), "{stats}");
        assert!((stats["median"].as_f64().unwrap() - median).abs() < 1e-9, "{stats} vs {median}");
        rates.push(f64::from(passed) / f64::from(finished));
    }
    // Calm air: every courier reaches the pad in time. A 14 m/s westerly (about 20 m/s at
    // their 30 m) is more than a 250 g drone can fly into at 8 m/s over the ground.
    assert_eq!(rates[0], 1.0, "{rates:?}");
    assert!(rates.windows(2).all(|w| w[1] <= w[0]), "the pass rate never rises with the wind: {rates:?}");
    assert_eq!(rates[2], 0.0, "{rates:?}");
    let failing = &report["cells"][2]["failing"][0];
    assert!(failing["reasons"][0].as_str().unwrap().starts_with("reachZone: 0 of 3 drones"), "{failing}");
    assert!(std::fs::read_to_string(dir.join("sweep.html")).unwrap().contains("headwind-c2-r0/report.html"));
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_rerun_keeps_complete_runs_and_flies_the_rest() {
    let root = out_root("resume");
    let loaded = headwind();
    let first = fly(&loaded, &options(&root, 2, false));
    assert_eq!(first.ran, 6);
    let dir = root.join("headwind");
    let events = |run: &str| std::fs::read_to_string(dir.join(run).join("events.jsonl")).unwrap();
    let before = events("headwind-c1-r1");
    // One run lost its manifest (stopped while its files were written), one a recording
    // (the evidence no longer verifies), one its whole folder.
    std::fs::remove_file(dir.join("headwind-c1-r1/manifest.json")).unwrap();
    std::fs::write(dir.join("headwind-c0-r0/trajectory.csv"), "truncated").unwrap();
    std::fs::remove_dir_all(dir.join("headwind-c2-r0")).unwrap();
    let again = fly(&loaded, &options(&root, 2, false));
    assert_eq!((again.ran, again.skipped), (3, 3));
    assert_eq!(events("headwind-c1-r1"), before, "the run flown again is the same run");
    assert_eq!(again.report, first.report, "the same report once every run is complete");

    // Ctrl-C before the sweep starts: nothing more is flown and the report says so.
    std::fs::remove_dir_all(dir.join("headwind-c2-r1")).unwrap();
    let stopped = run_sweep(&loaded, &options(&root, 2, false), Arc::new(AtomicBool::new(true))).unwrap();
    assert!(stopped.interrupted);
    assert_eq!(stopped.ran, 0);
    assert_eq!(stopped.report.totals.rate.finished, 5);

    // Another sweep definition in the same folder is refused, not mixed in.
    let mut other = headwind();
    other.sweep.spec.repetitions = Some(3);
    let e = run_sweep(&other, &options(&root, 2, false), Arc::new(AtomicBool::new(false))).unwrap_err();
    assert!(e.to_string().contains("holds the runs of a different sweep definition"), "{e}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn compare_flags_a_worse_version_and_passes_the_same_one() {
    use sadesim_evidence::sweep::compare;
    let root = out_root("compare");
    let old = fly(&headwind(), &options(&root.join("old"), 2, false)).report;
    let same = fly(&headwind(), &options(&root.join("same"), 2, false)).report;
    // Version 2 of the couriers' mission cruises at 5 m/s: it cannot make the pad in time
    // even in calm air.
    let mut slow = headwind();
    for r in &mut slow.expansion.runs {
        r.run.spec.fleet[0].mission.as_mut().unwrap().speed_mps = Some(5.0);
    }
    let worse = fly(&slow, &options(&root.join("worse"), 2, false)).report;
    let verdict = compare(&old, &worse, 0.05);
    assert!(verdict.significantly_worse(), "{verdict}");
    let text = verdict.to_string();
    assert!(text.contains("wind=0"), "{text}");
    let verdict = compare(&old, &same, 0.05);
    assert!(!verdict.significantly_worse(), "{verdict}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_sweeps_run_is_byte_identical_to_the_same_run_flown_alone_with_mavlink() {
    let _ports = sadesim_integration_tests::mavlink_ports();
    let root = out_root("identical");
    let loaded = headwind();
    // Two at a time, each on its own MAVLink ports.
    let outcome = fly(&loaded, &options(&root, 2, true));
    assert_eq!(outcome.ran, 6, "{:?}", outcome.errors);
    let dir = root.join("headwind");
    for name in ["headwind-c0-r0", "headwind-c1-r1"] {
        // The run's own document, as `sadesim run` would read it.
        let text = std::fs::read_to_string(dir.join("scenarios").join(format!("{name}.yaml"))).unwrap();
        let run = sadesim_crds::parse_run(&text).unwrap();
        let alone = root.join("alone").join(name);
        let options = RunOptions { run_dir: Some(alone.clone()), ..RunOptions::default() };
        run_local(&run, &options, Arc::new(AtomicBool::new(false))).unwrap();
        for file in ["events.jsonl", "trajectory.csv", "trajectory.geojson", "airspace.json"] {
            let (a, b) = (std::fs::read(dir.join(name).join(file)).unwrap(), std::fs::read(alone.join(file)).unwrap());
            assert!(a == b, "{name}/{file} differs between the sweep and the run alone");
        }
    }
    std::fs::remove_dir_all(&root).unwrap();
}
