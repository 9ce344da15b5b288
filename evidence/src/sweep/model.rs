//! The sweep report's data (`sweep.json`): per cell of the parameter space the runs that
//! finished and passed, the pass rate with its Wilson interval, the distributions of the
//! drones' metrics and the runs that failed; and the comparison of two sweeps of the same
//! space (an old and a new pilot), cell by cell, with Fisher's exact test.
//!
//! Pure: [`build`] and [`compare`] are functions of their arguments; no clock, no file, so
//! the same runs give the same `sweep.json` bytes.

use std::collections::BTreeMap;
use std::fmt;

use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::sweep::{Cell, SimulationSweep};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::stats::{fisher_one_sided_worse, wilson};

/// The confidence of the intervals when the sweep does not say (`spec.report.confidence`).
pub const DEFAULT_CONFIDENCE: f64 = 0.95;

/// One run of the sweep as the report reads it: which cell and repetition it flew, and its
/// `summary.json` when it finished.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct SweepRecord {
    /// The run's name (`<sweep>-c<cell>-r<repetition>`).
    pub name: String,
    pub cell: u32,
    pub repetition: u32,
    pub seed: u64,
    /// Where the run's evidence is, relative to the sweep report or a URL; the report
    /// links `{folder}/report.html`.
    pub folder: String,
    /// `None`: the run did not finish (no `summary.json`).
    pub summary: Option<RunSummary>,
    /// Why the run did not finish or could not be read, when known.
    pub error: Option<String>,
}

/// `sweep.json`: the whole report.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct SweepReport {
    /// The sweep's name.
    pub sweep: String,
    pub parameters: Vec<ParameterValues>,
    pub repetitions: u32,
    /// Two-sided confidence of every interval (0.95: 95 %).
    pub confidence: f64,
    /// The parameter the pass-rate plot has on its x axis.
    pub x: String,
    /// The two parameters of the heat map (rows, columns); empty with one parameter.
    pub heat_map: Vec<String>,
    pub cells: Vec<CellReport>,
    pub totals: Totals,
}

/// A parameter and its values, in the order the sweep flies them.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct ParameterValues {
    pub name: String,
    /// The run field it sets (`spec.environment.wind.speedMps`).
    pub field: String,
    pub values: Vec<Value>,
}

/// A pass rate and its interval.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Rate {
    pub finished: u32,
    pub passed: u32,
    /// passed / finished; `None` when no run finished.
    pub pass_rate: Option<f64>,
    /// Wilson score interval of the pass rate at the report's confidence; (0, 1) when no
    /// run finished.
    pub ci_low: f64,
    pub ci_high: f64,
}

impl Rate {
    /// The rate of `passed` out of `finished` runs at `confidence`.
    pub fn of(passed: u32, finished: u32, confidence: f64) -> Self {
        let (ci_low, ci_high) = wilson(passed, finished, confidence);
        let pass_rate = (finished > 0).then(|| f64::from(passed) / f64::from(finished));
        Self { finished, passed, pass_rate, ci_low, ci_high }
    }
}

/// One cell: the runs of one combination of parameter values.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct CellReport {
    pub index: u32,
    /// `wind=5, pilot=v2`: also how [`compare`] matches cells of two sweeps.
    pub label: String,
    /// (parameter name, value), in the parameters' order.
    pub values: Vec<(String, Value)>,
    /// Runs of the cell: the sweep's repetitions.
    pub expected: u32,
    #[serde(flatten)]
    pub rate: Rate,
    /// Drones of the finished runs, and how many of them crashed and landed.
    pub drones: u32,
    pub crashed: u32,
    pub landed: u32,
    /// Distributions of the metrics with data, in [`METRICS`] order.
    pub metrics: Vec<MetricStats>,
    /// Runs that did not pass (failed, not judged, or not finished), by repetition.
    pub failing: Vec<FailingRun>,
}

/// Totals over every cell.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Totals {
    pub cells: u32,
    pub expected: u32,
    #[serde(flatten)]
    pub rate: Rate,
}

/// A run that did not pass, and why.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct FailingRun {
    pub name: String,
    pub seed: u64,
    pub repetition: u32,
    pub folder: String,
    pub finished: bool,
    /// `criterion: summary` of each failed criterion, the run's error, or why it was not
    /// judged.
    pub reasons: Vec<String>,
}

/// The distribution of one metric in a cell: over every drone of every finished run
/// (over the runs for run metrics). Quantiles are nearest-rank, as in `summary.json`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct MetricStats {
    /// The metric's key in [`METRICS`].
    pub metric: String,
    pub n: u32,
    pub min: f64,
    pub median: f64,
    pub p95: f64,
    pub max: f64,
    pub mean: f64,
}

/// A metric of the report: its key (`sweep.json`), its label with unit, and where it is
/// read from.
#[derive(Clone, Copy, Debug)]
pub struct Metric {
    pub key: &'static str,
    pub label: &'static str,
    source: Source,
}

/// Where a metric's values come from.
#[derive(Clone, Copy, Debug)]
enum Source {
    /// A number at this JSON pointer of each `perDrone` entry of `summary.json`.
    Drone(&'static str),
    /// 1 − `finalBatteryRemaining` of each drone.
    BatteryUsed,
    /// The run's simulated time.
    SimTime,
}

/// The metrics of every cell. The per-drone ones are read from the summary's JSON, so a
/// summary without a metric (older runs) simply has no value for it.
pub const METRICS: [Metric; 7] = [
    Metric { key: "flightTimeS", label: "flight time (s)", source: Source::Drone("/flightTimeS") },
    Metric { key: "landingErrorM", label: "landing error (m)", source: Source::Drone("/landingErrorM") },
    Metric { key: "closestZoneM", label: "closest approach to a zone (m)", source: Source::Drone("/closestZoneM") },
    Metric {
        key: "estimateErrorM",
        label: "median position estimate error (m)",
        source: Source::Drone("/gnss/estimateErrorM/median"),
    },
    Metric { key: "energyWh", label: "energy used (Wh)", source: Source::Drone("/energyWh") },
    Metric { key: "batteryUsed", label: "battery used (fraction)", source: Source::BatteryUsed },
    Metric { key: "simTimeS", label: "simulated time of the run (s)", source: Source::SimTime },
];

/// The label of the metric `key` (the key itself when unknown).
pub fn metric_label(key: &str) -> &str {
    METRICS.iter().find(|m| m.key == key).map_or(key, |m| m.label)
}

/// The values of `metric` in one run's summary, read from its JSON (`summary` serialized):
/// one per drone that has it, one for run metrics. Non-finite numbers are left out.
pub fn metric_values(metric: &Metric, summary: &Value) -> Vec<f64> {
    let drones = summary.get("perDrone").and_then(Value::as_array).map_or(&[][..], Vec::as_slice);
    let values: Vec<f64> = match metric.source {
        Source::Drone(pointer) => drones.iter().filter_map(|d| d.pointer(pointer).and_then(Value::as_f64)).collect(),
        Source::BatteryUsed => drones
            .iter()
            .filter_map(|d| d.get("finalBatteryRemaining").and_then(Value::as_f64))
            .map(|remaining| 1.0 - remaining)
            .collect(),
        Source::SimTime => summary.get("simTimeS").and_then(Value::as_f64).into_iter().collect(),
    };
    values.into_iter().filter(|v| v.is_finite()).collect()
}

/// The distribution of `values`; `None` when empty.
pub fn distribution(metric: &str, mut values: Vec<f64>) -> Option<MetricStats> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    let rank = |q: f64| values[((q * n as f64).ceil() as usize).clamp(1, n) - 1];
    Some(MetricStats {
        metric: metric.to_string(),
        n: n as u32,
        min: values[0],
        median: rank(0.5),
        p95: rank(0.95),
        max: values[n - 1],
        mean: values.iter().sum::<f64>() / n as f64,
    })
}

/// Whether a finished run passed, and if not why: it passes when its verdict judged at
/// least one criterion and passed.
fn judge(summary: &RunSummary) -> Result<(), Vec<String>> {
    match &summary.verdict {
        None => Err(vec!["not judged: the run has no verdict (no criteria)".into()]),
        Some(v) if v.criteria.is_empty() => Err(vec!["not judged: the verdict has no criteria".into()]),
        Some(v) if v.passed => Ok(()),
        Some(v) => {
            let failed: Vec<String> =
                v.criteria.iter().filter(|c| !c.passed).map(|c| format!("{}: {}", c.criterion, c.summary)).collect();
            Err(if failed.is_empty() { vec!["the verdict failed".into()] } else { failed })
        }
    }
}

/// The parameters with their values in the order the cells use them (first appearance).
fn parameters(sweep: &SimulationSweep, cells: &[Cell]) -> Vec<ParameterValues> {
    sweep
        .spec
        .parameters
        .iter()
        .map(|p| {
            let mut values: Vec<Value> = Vec::new();
            for v in cells.iter().filter_map(|c| c.value(&p.name)) {
                if !values.contains(v) {
                    values.push(v.clone());
                }
            }
            ParameterValues { name: p.name.clone(), field: p.field.clone(), values }
        })
        .collect()
}

/// The report of a sweep from its `cells` (from `sadesim_crds::sweep::expand`) and the
/// `records` of its runs.
///
/// # Assumptions
/// At most one record per (cell, repetition); records of cells not in `cells` are left
/// out. A missing record counts as a run that did not finish (`expected` − `finished`).
///
/// # Guarantees
/// Deterministic: the same arguments, in any record order, give the same report.
pub fn build(sweep: &SimulationSweep, cells: &[Cell], records: &[SweepRecord]) -> SweepReport {
    let spec = &sweep.spec;
    let report_spec = spec.report.clone().unwrap_or_default();
    let confidence = report_spec.confidence.unwrap_or(DEFAULT_CONFIDENCE);
    let names: Vec<String> = spec.parameters.iter().map(|p| p.name.clone()).collect();
    let x = report_spec.x.clone().or_else(|| names.first().cloned()).unwrap_or_default();
    let heat_map = match report_spec.heat_map {
        Some(axes) => axes,
        None if names.len() >= 2 => names[..2].to_vec(),
        None => Vec::new(),
    };
    let repetitions = spec.repetitions();
    let mut by_cell: BTreeMap<u32, Vec<&SweepRecord>> = BTreeMap::new();
    for r in records {
        by_cell.entry(r.cell).or_default().push(r);
    }
    let cell_reports: Vec<CellReport> = cells
        .iter()
        .map(|cell| {
            let mut runs = by_cell.remove(&cell.index).unwrap_or_default();
            runs.sort_by(|a, b| (a.repetition, &a.name).cmp(&(b.repetition, &b.name)));
            cell_report(cell, &runs, repetitions, confidence)
        })
        .collect();
    let passed = cell_reports.iter().map(|c| c.rate.passed).sum();
    let finished = cell_reports.iter().map(|c| c.rate.finished).sum();
    let totals = Totals {
        cells: cell_reports.len() as u32,
        expected: cell_reports.iter().map(|c| c.expected).sum(),
        rate: Rate::of(passed, finished, confidence),
    };
    SweepReport {
        sweep: sweep.metadata.name.clone().unwrap_or_default(),
        parameters: parameters(sweep, cells),
        repetitions,
        confidence,
        x,
        heat_map,
        cells: cell_reports,
        totals,
    }
}

/// One cell's report from its runs (sorted by repetition).
fn cell_report(cell: &Cell, runs: &[&SweepRecord], expected: u32, confidence: f64) -> CellReport {
    let (mut finished, mut passed, mut drones, mut crashed, mut landed) = (0, 0, 0, 0, 0);
    let mut failing = Vec::new();
    let mut samples: Vec<Vec<f64>> = vec![Vec::new(); METRICS.len()];
    for run in runs {
        let fail = |finished: bool, reasons: Vec<String>| FailingRun {
            name: run.name.clone(),
            seed: run.seed,
            repetition: run.repetition,
            folder: run.folder.clone(),
            finished,
            reasons,
        };
        let Some(summary) = &run.summary else {
            let reason = run.error.clone().unwrap_or_else(|| "did not finish: no summary.json".into());
            failing.push(fail(false, vec![reason]));
            continue;
        };
        finished += 1;
        drones += summary.per_drone.len() as u32;
        crashed += summary.per_drone.iter().filter(|d| d.crashed).count() as u32;
        landed += summary.per_drone.iter().filter(|d| d.landed).count() as u32;
        let json = serde_json::to_value(summary).expect("a summary always serializes");
        for (metric, values) in METRICS.iter().zip(&mut samples) {
            values.extend(metric_values(metric, &json));
        }
        match judge(summary) {
            Ok(()) => passed += 1,
            Err(reasons) => failing.push(fail(true, reasons)),
        }
    }
    let metrics = METRICS.iter().zip(samples).filter_map(|(m, values)| distribution(m.key, values)).collect();
    CellReport {
        index: cell.index,
        label: cell.label(),
        values: cell.values.clone(),
        expected,
        rate: Rate::of(passed, finished, confidence),
        drones,
        crashed,
        landed,
        metrics,
        failing,
    }
}

/// One cell of two sweeps, compared.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct CellComparison {
    /// The cell's label (`pooled` for the pooled test).
    pub label: String,
    pub old_passed: u32,
    pub old_finished: u32,
    pub new_passed: u32,
    pub new_finished: u32,
    /// New pass rate minus old; `None` when a side has no finished run.
    pub difference: Option<f64>,
    /// One-sided Fisher's exact p that the new runs pass less often.
    pub p_worse: f64,
    /// `p_worse < alpha`.
    pub worse: bool,
}

impl CellComparison {
    fn of(label: String, old: Rate, new: Rate, alpha: f64) -> Self {
        let p_worse = fisher_one_sided_worse(old.passed, old.finished, new.passed, new.finished);
        let difference = old.pass_rate.zip(new.pass_rate).map(|(o, n)| n - o);
        Self {
            label,
            old_passed: old.passed,
            old_finished: old.finished,
            new_passed: new.passed,
            new_finished: new.finished,
            difference,
            p_worse,
            worse: p_worse < alpha,
        }
    }
}

/// Two sweeps of the same space compared: is the new one worse?
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Comparison {
    pub old: String,
    pub new: String,
    /// Significance level of every test.
    pub alpha: f64,
    /// The cells of both, in the new sweep's order.
    pub cells: Vec<CellComparison>,
    /// Labels of cells only the old or only the new sweep has: not compared.
    pub only_old: Vec<String>,
    pub only_new: Vec<String>,
    /// The matched cells' counts summed, tested once.
    pub pooled: CellComparison,
}

impl Comparison {
    /// True when any matched cell, or the pooled counts, is significantly worse.
    ///
    /// # Caveats
    /// One test per cell at the same alpha: with many cells some flag by chance
    /// (no multiple-comparison correction); a flagged cell is a lead to rerun, the pooled
    /// test the overall answer.
    pub fn significantly_worse(&self) -> bool {
        self.pooled.worse || self.cells.iter().any(|c| c.worse)
    }
}

/// Compares the `new` sweep's cells with the `old` one's, matched by label (the parameter
/// values), each with a one-sided Fisher's exact test at `alpha` (0.05).
pub fn compare(old: &SweepReport, new: &SweepReport, alpha: f64) -> Comparison {
    let old_cells: BTreeMap<&str, &CellReport> = old.cells.iter().map(|c| (c.label.as_str(), c)).collect();
    let mut cells = Vec::new();
    let (mut old_sum, mut new_sum) = ((0, 0), (0, 0));
    let mut only_new = Vec::new();
    for n in &new.cells {
        let Some(o) = old_cells.get(n.label.as_str()) else {
            only_new.push(n.label.clone());
            continue;
        };
        old_sum = (old_sum.0 + o.rate.passed, old_sum.1 + o.rate.finished);
        new_sum = (new_sum.0 + n.rate.passed, new_sum.1 + n.rate.finished);
        cells.push(CellComparison::of(n.label.clone(), o.rate, n.rate, alpha));
    }
    let only_old =
        old.cells.iter().filter(|o| !new.cells.iter().any(|n| n.label == o.label)).map(|o| o.label.clone()).collect();
    let pooled = CellComparison::of(
        "pooled".into(),
        Rate::of(old_sum.0, old_sum.1, new.confidence),
        Rate::of(new_sum.0, new_sum.1, new.confidence),
        alpha,
    );
    Comparison { old: old.sweep.clone(), new: new.sweep.clone(), alpha, cells, only_old, only_new, pooled }
}

impl fmt::Display for CellComparison {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let difference = self.difference.map_or("n/a".into(), |d| format!("{:+.1} pp", 100.0 * d));
        write!(
            f,
            "{}: {}/{} -> {}/{} ({difference}), p = {:.4}{}",
            self.label,
            self.old_passed,
            self.old_finished,
            self.new_passed,
            self.new_finished,
            self.p_worse,
            if self.worse { "  WORSE" } else { "" }
        )
    }
}

/// The text `sadesim sweep compare` prints: a line per cell, the cells not compared, the
/// pooled test, then the verdict.
impl fmt::Display for Comparison {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{} (old) -> {} (new), one-sided Fisher's exact test at alpha {}", self.old, self.new, self.alpha)?;
        for c in &self.cells {
            writeln!(f, "  {c}")?;
        }
        for label in &self.only_old {
            writeln!(f, "  {label}: only in the old sweep, not compared")?;
        }
        for label in &self.only_new {
            writeln!(f, "  {label}: only in the new sweep, not compared")?;
        }
        writeln!(f, "  {}", self.pooled)?;
        let worse: Vec<&str> = self.cells.iter().filter(|c| c.worse).map(|c| c.label.as_str()).collect();
        if self.significantly_worse() {
            let which = if worse.is_empty() { "the pooled runs".to_string() } else { worse.join("; ") };
            writeln!(f, "verdict: significantly worse at alpha {} ({which})", self.alpha)
        } else {
            writeln!(f, "verdict: not significantly worse at alpha {}", self.alpha)
        }
    }
}
