//! The sweep report built from fabricated run summaries: counts, rates and intervals,
//! metrics, the comparison of two sweeps, the page and the files.

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::outcome::summary::{DroneSummary, ErrorStats, GnssSummary, RunSummary};
use sadesim_crds::outcome::verdict::{CriterionResult, RunVerdict};
use sadesim_crds::sweep::expand::run_name;
use sadesim_crds::sweep::{Cell, Parameter, SimulationSweep, SimulationSweepSpec, SweepBase, SweepReportSpec, expand};
use serde_json::{Value, json};

use super::model::{METRICS, metric_values};
use super::stats::wilson;
use super::*;

/// A sweep of the fixture run over the origin's altitude (181, 200, 220 m) and the group's
/// name (alpha, beta): six cells, `repetitions` runs each.
fn sweep(repetitions: u32, report: Option<SweepReportSpec>) -> (SimulationSweep, Vec<Cell>) {
    let base = RunBuilder::test()
        .with(|r| r.spec.criteria = serde_json::from_value(json!([{"noCrashes": {}}])).expect("a criterion"))
        .build()
        .spec;
    let parameter = |name: &str, field: &str, values: Vec<Value>| Parameter {
        name: name.into(),
        field: field.into(),
        values: Some(values),
        range: None,
        random: None,
    };
    let spec = SimulationSweepSpec {
        base: SweepBase { spec: Some(Box::new(base.clone())), file: None },
        overrides: vec![],
        parameters: vec![
            parameter("altitude", "spec.origin.altitudeMslM", vec![json!(181), json!(200), json!(220)]),
            parameter("group", "spec.fleet[0].name", vec![json!("alpha"), json!("beta")]),
        ],
        repetitions: Some(repetitions),
        parallelism: None,
        seed: None,
        queue: None,
        report,
    };
    let sweep = SimulationSweep::new("lake", spec);
    let cells = expand(&sweep, &base).expect("the test sweep is valid").cells;
    (sweep, cells)
}

/// A finished run's summary: judged `passed` by one criterion, with one drone per
/// (estimate error median, battery remaining).
fn summary(passed: bool, drones: &[(f64, f64)]) -> RunSummary {
    let per_drone = drones
        .iter()
        .enumerate()
        .map(|(i, &(error_m, battery))| DroneSummary {
            index: i as u32,
            name: format!("d{i}"),
            landed: passed,
            crashed: !passed,
            final_battery_remaining: battery,
            gnss: Some(GnssSummary {
                estimate_error_m: Some(ErrorStats { median: error_m, p95: error_m, max: error_m }),
                ..Default::default()
            }),
            ..Default::default()
        })
        .collect();
    let criterion = CriterionResult {
        path: "spec.criteria[0]".into(),
        criterion: "allDronesLand".into(),
        passed,
        summary: if passed { "every drone landed".into() } else { "1 drone crashed".into() },
        failures: vec![],
    };
    RunSummary {
        run: "r".into(),
        sim_time_s: 120.0,
        per_drone,
        verdict: Some(RunVerdict { passed, criteria: vec![criterion] }),
        ..Default::default()
    }
}

fn record(cell: u32, repetition: u32, summary: Option<RunSummary>) -> SweepRecord {
    let name = run_name("lake", cell, repetition);
    SweepRecord {
        folder: format!("runs/{name}"),
        name,
        cell,
        repetition,
        seed: 7 + u64::from(repetition),
        summary,
        error: None,
    }
}

/// Every cell of a 10-repetition sweep with `passes[cell]` passing runs, the rest failing.
fn records_with(passes: &[u32]) -> Vec<SweepRecord> {
    passes
        .iter()
        .enumerate()
        .flat_map(|(cell, &p)| (0..10).map(move |r| record(cell as u32, r, Some(summary(r < p, &[(1.0, 0.5)])))))
        .collect()
}

#[test]
fn counts_rates_and_intervals_per_cell() {
    let (sweep, cells) = sweep(10, None);
    assert_eq!(cells.len(), 6);
    let mut records = Vec::new();
    // Cell 0: 8 of 10 pass. Cell 1: one run without a verdict, nine pass.
    for r in 0..10 {
        records.push(record(0, r, Some(summary(r < 8, &[(1.0, 0.5)]))));
        let mut s = summary(true, &[(1.0, 0.5)]);
        if r == 3 {
            s.verdict = None;
        }
        records.push(record(1, r, Some(s)));
    }
    // Cell 2: one run did not finish (an error), one has no record yet, eight pass.
    for r in 0..8 {
        records.push(record(2, r, Some(summary(true, &[(1.0, 0.5)]))));
    }
    records.push(SweepRecord { error: Some("pod evicted".into()), ..record(2, 8, None) });

    let report = build(&sweep, &cells, &records);
    assert_eq!(report.sweep, "lake");
    assert_eq!((report.x.as_str(), report.heat_map.clone()), ("altitude", vec!["altitude".into(), "group".into()]));
    assert_eq!(report.confidence, 0.95);
    assert_eq!(report.parameters[1].values, [json!("alpha"), json!("beta")]);
    let c0 = &report.cells[0];
    assert_eq!((c0.expected, c0.rate.finished, c0.rate.passed), (10, 10, 8));
    assert_eq!(c0.rate.pass_rate, Some(0.8));
    assert!((c0.rate.ci_low - 0.4902).abs() < 1e-4 && (c0.rate.ci_high - 0.9433).abs() < 1e-4);
    assert_eq!(c0.failing.iter().map(|f| f.repetition).collect::<Vec<_>>(), [8, 9]);
    assert_eq!(c0.failing[0].reasons, ["allDronesLand: 1 drone crashed"]);
    assert_eq!((c0.drones, c0.crashed, c0.landed), (10, 2, 8));

    let c1 = &report.cells[1];
    assert_eq!((c1.rate.finished, c1.rate.passed), (10, 9), "a run without a verdict counts as failed");
    assert!(c1.failing[0].finished && c1.failing[0].reasons[0].contains("not judged"), "{:?}", c1.failing);

    let c2 = &report.cells[2];
    assert_eq!((c2.expected, c2.rate.finished, c2.rate.passed), (10, 8, 8), "no summary: not finished");
    assert_eq!(c2.failing.len(), 1);
    assert!(!c2.failing[0].finished);
    assert_eq!(c2.failing[0].reasons, ["pod evicted"]);
    assert_eq!((c2.rate.ci_low, c2.rate.ci_high), wilson(8, 8, 0.95));

    let c3 = &report.cells[3];
    assert_eq!((c3.rate.finished, c3.rate.pass_rate, c3.rate.ci_low, c3.rate.ci_high), (0, None, 0.0, 1.0));
    assert_eq!(report.totals.cells, 6);
    assert_eq!(report.totals.expected, 60);
    assert_eq!((report.totals.rate.finished, report.totals.rate.passed), (28, 25));
}

#[test]
fn the_report_spec_sets_confidence_and_axes() {
    let spec = SweepReportSpec { x: Some("group".into()), heat_map: None, confidence: Some(0.9) };
    let (sweep, cells) = sweep(10, Some(spec));
    let report = build(&sweep, &cells, &records_with(&[8, 8, 8, 8, 8, 8]));
    assert_eq!(report.x, "group");
    assert_eq!(report.confidence, 0.9);
    assert_eq!((report.cells[0].rate.ci_low, report.cells[0].rate.ci_high), wilson(8, 10, 0.9));
}

#[test]
fn metrics_are_distributions_over_every_drone_of_the_cell() {
    let (sweep, cells) = sweep(2, None);
    let records = vec![
        record(0, 0, Some(summary(true, &[(1.0, 0.9), (4.0, 0.6)]))),
        record(0, 1, Some(summary(false, &[(2.0, 0.8)]))),
    ];
    let report = build(&sweep, &cells, &records);
    let metric = |key: &str| report.cells[0].metrics.iter().find(|m| m.metric == key).cloned();
    let error = metric("estimateErrorM").expect("estimate errors recorded");
    assert_eq!((error.n, error.min, error.median, error.max), (3, 1.0, 2.0, 4.0));
    assert!((error.mean - 7.0 / 3.0).abs() < 1e-12);
    let used = metric("batteryUsed").expect("batteries recorded");
    assert!((used.median - 0.2).abs() < 1e-12 && (used.max - 0.4).abs() < 1e-12, "{used:?}");
    assert_eq!(metric("simTimeS").map(|m| m.n), Some(2), "one value per run");
    assert_eq!(metric("flightTimeS"), None, "summaries without the metric give no distribution");
    assert!(report.cells[1].metrics.is_empty(), "a cell without finished runs has no metrics");
}

#[test]
fn per_drone_metrics_are_read_from_the_summary_json() {
    let summary = json!({
        "simTimeS": 300.0,
        "perDrone": [
            {"flightTimeS": 100.0, "landingErrorM": 0.5, "energyWh": 12.0, "finalBatteryRemaining": 0.25},
            {"flightTimeS": 140.0, "closestZoneM": 30.0, "finalBatteryRemaining": 0.5},
            {"landingErrorM": 1.5}
        ]
    });
    let values = |key: &str| metric_values(METRICS.iter().find(|m| m.key == key).unwrap(), &summary);
    assert_eq!(values("flightTimeS"), [100.0, 140.0]);
    assert_eq!(values("landingErrorM"), [0.5, 1.5]);
    assert_eq!(values("closestZoneM"), [30.0]);
    assert_eq!(values("energyWh"), [12.0]);
    assert_eq!(values("batteryUsed"), [0.75, 0.5]);
    assert_eq!(values("simTimeS"), [300.0]);
    assert!(values("estimateErrorM").is_empty());
}

#[test]
fn the_same_runs_in_any_order_give_the_same_bytes() {
    let (sweep, cells) = sweep(10, None);
    let mut records = records_with(&[8, 10, 3, 0, 10, 5]);
    let first = serde_json::to_string_pretty(&build(&sweep, &cells, &records)).unwrap();
    records.reverse();
    let second = serde_json::to_string_pretty(&build(&sweep, &cells, &records)).unwrap();
    assert_eq!(first, second);
    assert!(!first.contains("wallTime"), "no wall time in the report");
}

#[test]
fn compare_flags_a_cell_that_got_worse_and_not_one_that_held() {
    let (sweep, cells) = sweep(10, None);
    let old = build(&sweep, &cells, &records_with(&[10, 5, 10, 10, 10, 10]));
    let new = build(&sweep, &cells, &records_with(&[2, 5, 10, 10, 10, 10]));
    let c = compare(&old, &new, 0.05);
    assert!(c.cells[0].worse && c.cells[0].p_worse < 0.001, "{:?}", c.cells[0]);
    assert_eq!(c.cells[0].difference, Some(-0.8));
    assert!(!c.cells[1].worse, "5/10 -> 5/10 is not worse");
    assert!(c.significantly_worse());
    let text = c.to_string();
    assert!(text.contains("altitude=181, group=alpha: 10/10 -> 2/10 (-80.0 pp)"), "{text}");
    assert!(text.contains("verdict: significantly worse"), "{text}");
    assert_eq!(text.lines().count(), 1 + 6 + 1 + 1, "header, cells, pooled, verdict:\n{text}");

    let same = compare(&old, &old, 0.05);
    assert!(!same.significantly_worse());
    assert!(same.to_string().contains("verdict: not significantly worse"));
}

#[test]
fn the_pooled_test_sees_a_drop_no_single_cell_shows() {
    let (sweep, cells) = sweep(10, None);
    let old = build(&sweep, &cells, &records_with(&[10, 10, 10, 10, 10, 10]));
    let new = build(&sweep, &cells, &records_with(&[8, 8, 8, 8, 8, 8]));
    let c = compare(&old, &new, 0.05);
    assert!(c.cells.iter().all(|cell| !cell.worse), "10/10 -> 8/10 alone is not significant");
    assert_eq!((c.pooled.old_passed, c.pooled.new_passed, c.pooled.new_finished), (60, 48, 60));
    assert!(c.pooled.worse && c.significantly_worse());
    assert!(c.to_string().contains("(the pooled runs)"));
}

#[test]
fn cells_missing_on_one_side_are_listed_not_compared() {
    let (sweep, cells) = sweep(10, None);
    let old = build(&sweep, &cells, &records_with(&[10; 6]));
    let mut new = build(&sweep, &cells, &records_with(&[0; 6]));
    new.cells.truncate(5);
    new.cells[4].label = "altitude=250, group=alpha".into();
    let c = compare(&old, &new, 0.05);
    assert_eq!(c.cells.len(), 4);
    assert_eq!(c.only_new, ["altitude=250, group=alpha"]);
    assert_eq!(c.only_old, ["altitude=220, group=alpha", "altitude=220, group=beta"]);
    assert_eq!(c.pooled.old_finished, 40);
}

#[test]
fn the_page_has_the_plots_the_links_and_escapes_text() {
    let (sweep, cells) = sweep(10, None);
    let mut report = build(&sweep, &cells, &records_with(&[8, 10, 3, 0, 10, 5]));
    report.cells[0].label = "<script>alert(1)</script>".into();
    let page = html::page(&report);
    assert!(page.contains(r#"id="pass-rate""#) && page.contains(r#"id="heat-map""#));
    assert_eq!(page.matches(r#"class="heat""#).count(), 6, "a square per pair of values");
    assert_eq!(page.matches("<g data-series=").count(), 2, "a line per group");
    assert_eq!(page.matches(r#"class="ci""#).count(), 6, "an error bar per cell");
    assert!(page.contains(r#"<a href="runs/lake-c0-r8/report.html">lake-c0-r8</a>"#));
    assert!(page.contains("30 %") && page.contains("3/10"), "the heat map's numbers");
    assert!(page.contains(r#"data-metric="estimateErrorM""#) && page.contains(r#"data-metric="batteryUsed""#));
    assert!(!page.contains("<script>"), "labels are escaped");
    assert!(page.contains("&lt;script&gt;alert(1)&lt;/script&gt;"));
}

#[test]
fn string_values_plot_as_categories_and_one_parameter_has_no_heat_map() {
    let spec = SweepReportSpec { x: Some("group".into()), heat_map: None, confidence: None };
    let (sweep, cells) = sweep(10, Some(spec));
    let report = build(&sweep, &cells, &records_with(&[8, 10, 3, 0, 10, 5]));
    let plot = svg::pass_rate(&report).expect("a plot");
    assert!(plot.contains(">alpha</text>") && plot.contains(">beta</text>"));
    assert_eq!(plot.matches("<g data-series=").count(), 3, "a line per altitude");

    let mut single = report.clone();
    single.heat_map.clear();
    assert!(svg::heat_map(&single).is_none());
    assert!(!html::page(&single).contains(r#"id="heat-map""#));
}

#[test]
fn write_then_read_round_trips_and_errors_name_the_field() {
    let dir = std::env::temp_dir().join(format!("sadesim-sweep-report-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (sweep, cells) = sweep(10, None);
    let report = build(&sweep, &cells, &records_with(&[8, 10, 3, 0, 10, 5]));
    write(&dir, &report).unwrap();
    assert_eq!(read(&dir).unwrap(), report);
    let json = std::fs::read_to_string(dir.join(SWEEP_JSON)).unwrap();
    assert!(json.ends_with("}\n"));
    assert!(std::fs::read_to_string(dir.join(SWEEP_HTML)).unwrap().starts_with("<!DOCTYPE html>"));

    let mut broken: Value = serde_json::from_str(&json).unwrap();
    broken["cells"][2]["expected"] = json!("ten");
    std::fs::write(dir.join(SWEEP_JSON), broken.to_string()).unwrap();
    let e = read(&dir).unwrap_err().to_string();
    assert!(e.contains("sweep.json") && e.contains("cells[2].expected"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(read(&dir).unwrap_err().to_string().contains("failed to read"));
}
