//! `sweep.html`: one self-contained page (inline CSS and SVG, no script, no external URL
//! other than the links to the runs' own reports): the totals, the pass rate against the
//! x parameter, the heat map, a table per cell, the metrics' box plots and the runs that
//! did not pass, each linked to its `report.html`.

use std::fmt::Write;

use sadesim_crds::sweep::space::show;

use super::model::{CellReport, METRICS, Rate, SweepReport, metric_label};
use super::svg::{self, number};
use crate::markup::{cell, esc, header, num};

const CSS: &str = r#"
body { font-family: "DejaVu Sans", "Helvetica Neue", Arial, sans-serif; margin: 0 auto; max-width: 1640px; padding: 0 20px 40px; color: #222; }
h1 { font-size: 26px; margin: 22px 0 6px; }
h2 { font-size: 20px; margin: 30px 0 8px; border-bottom: 2px solid #ddd; padding-bottom: 4px; }
p.sub { margin: 0 0 12px; color: #555; }
table { border-collapse: collapse; margin: 8px 0 14px; font-size: 14px; }
th, td { border: 1px solid #ccc; padding: 4px 8px; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.bad td { background: #fdecea; } tr.good td { background: #f1f8f1; }
figure { margin: 10px 0 20px; } figure svg { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { color: #444; font-size: 14px; margin-top: 4px; max-width: 1200px; }
ul.reasons { margin: 0 0 0 18px; padding: 0; }
"#;

/// The inline form of a plot (no `xmlns`: implied inside HTML, and the page stays free of
/// URLs).
fn inline_svg(svg: &str) -> String {
    svg.replacen(r#" xmlns="http://www.w3.org/2000/svg""#, "", 1)
}

/// "8/10 (80 %)" or "0/0".
fn rate_text(rate: &Rate) -> String {
    match rate.pass_rate {
        Some(r) => format!("{}/{} ({:.0} %)", rate.passed, rate.finished, r * 100.0),
        None => format!("{}/{}", rate.passed, rate.finished),
    }
}

/// "49–94 %".
fn ci_text(rate: &Rate) -> String {
    format!("{:.0}–{:.0} %", rate.ci_low * 100.0, rate.ci_high * 100.0)
}

/// The page.
pub fn page(report: &SweepReport) -> String {
    let mut out = String::new();
    let _ = write!(
        out,
        r#"<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1"><title>Sweep report: {}</title><style>{CSS}</style></head><body>"#,
        esc(&report.sweep)
    );
    let t = &report.totals;
    let parameters: Vec<String> = report
        .parameters
        .iter()
        .map(|p| {
            let values: Vec<String> = p.values.iter().map(show).collect();
            format!("{} ({}) = {}", p.name, p.field, values.join(", "))
        })
        .collect();
    let _ = write!(
        out,
        r#"<h1>Sweep report: {}</h1><p class="sub" id="totals">{} cells × {} repetitions = {} runs: {} finished, {} passed; pass rate {}, {:.0} % confidence interval {}.</p><p class="sub">Parameters: {}.</p>"#,
        esc(&report.sweep),
        t.cells,
        report.repetitions,
        t.expected,
        t.rate.finished,
        t.rate.passed,
        t.rate.pass_rate.map_or("n/a".into(), |r| format!("{:.1} %", r * 100.0)),
        report.confidence * 100.0,
        ci_text(&t.rate),
        esc(&parameters.join("; "))
    );
    if let Some(plot) = svg::pass_rate(report) {
        let _ = write!(
            out,
            r#"<h2 id="pass-rate-plot">Pass rate against {}</h2><figure>{}<figcaption>Share of finished runs whose verdict passed, per cell, against {}; error bars: the Wilson score interval at {:.0} % confidence. One line per combination of the other parameters (at most {}).</figcaption></figure>"#,
            esc(&report.x),
            inline_svg(&plot),
            esc(&report.x),
            report.confidence * 100.0,
            svg::MAX_LINES
        );
    }
    if let Some(map) = svg::heat_map(report) {
        let _ = write!(
            out,
            r#"<h2 id="heat-map-plot">Pass rate by {}</h2><figure>{}<figcaption>Pass rate and passed/finished runs per pair of values (cells that differ only in other parameters pooled); red 0 %, amber 50 %, green 100 %, grey: no finished run.</figcaption></figure>"#,
            esc(&report.heat_map.join(" and ")),
            inline_svg(&map)
        );
    }
    cells_table(&mut out, report);
    metrics(&mut out, report);
    failing(&mut out, report);
    out.push_str("</body></html>\n");
    out
}

/// A row per cell: values, runs, rate with interval, and the median and p95 of each metric.
fn cells_table(out: &mut String, report: &SweepReport) {
    out.push_str(r#"<h2 id="cells">Cells</h2><table id="cells-table">"#);
    let mut names: Vec<String> = report.parameters.iter().map(|p| p.name.clone()).collect();
    names.extend(["passed/finished".into(), "expected".into(), "confidence interval".into()]);
    names.extend(["drones".into(), "crashed".into(), "landed".into()]);
    let with_data: Vec<&str> =
        METRICS.iter().map(|m| m.key).filter(|k| report.cells.iter().any(|c| metric(c, k).is_some())).collect();
    names.extend(with_data.iter().map(|k| format!("{}: median / p95", metric_label(k))));
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    header(out, &refs);
    for c in &report.cells {
        let class = if c.rate.finished > 0 && c.rate.passed == c.rate.finished { "good" } else { "bad" };
        let _ = write!(out, r#"<tr class="{class}" id="cell-{}">"#, c.index);
        for p in &report.parameters {
            cell(out, &c.values.iter().find(|(n, _)| *n == p.name).map_or(String::new(), |(_, v)| show(v)));
        }
        num(out, &rate_text(&c.rate));
        num(out, &c.expected.to_string());
        num(out, &ci_text(&c.rate));
        num(out, &c.drones.to_string());
        num(out, &c.crashed.to_string());
        num(out, &c.landed.to_string());
        for k in &with_data {
            num(out, &metric(c, k).map_or("–".into(), |m| format!("{} / {}", number(m.median), number(m.p95))));
        }
        out.push_str("</tr>");
    }
    out.push_str("</table>");
}

fn metric<'a>(c: &'a CellReport, key: &str) -> Option<&'a super::model::MetricStats> {
    c.metrics.iter().find(|m| m.metric == key)
}

/// The box plots of the metrics with data.
fn metrics(out: &mut String, report: &SweepReport) {
    let plots = svg::box_plots(report);
    if plots.is_empty() {
        return;
    }
    out.push_str(r#"<h2 id="metrics">Metrics</h2><p class="sub">Per cell, over every drone of its finished runs (the simulated time: over the runs): line from min to max, box from the median to the 95th percentile, dark tick at the median.</p>"#);
    for (key, plot) in plots {
        let _ = write!(out, r#"<figure data-metric="{}">{}</figure>"#, esc(key), inline_svg(&plot));
    }
}

/// Every run that did not pass, with its seed and a link to its report.
fn failing(out: &mut String, report: &SweepReport) {
    let runs: Vec<_> = report.cells.iter().flat_map(|c| c.failing.iter().map(move |r| (c, r))).collect();
    let _ = write!(out, r#"<h2 id="failing">Runs that did not pass ({})</h2>"#, runs.len());
    if runs.is_empty() {
        out.push_str(r#"<p class="sub">Every finished run passed.</p>"#);
        return;
    }
    out.push_str("<table>");
    header(out, &["cell", "run", "repetition", "seed", "finished", "why"]);
    for (c, r) in runs {
        out.push_str(r#"<tr class="bad">"#);
        cell(out, &c.label);
        let _ = write!(out, r#"<td><a href="{}/report.html">{}</a></td>"#, esc(&r.folder), esc(&r.name));
        num(out, &r.repetition.to_string());
        num(out, &r.seed.to_string());
        cell(out, if r.finished { "yes" } else { "no" });
        out.push_str(r#"<td><ul class="reasons">"#);
        for reason in &r.reasons {
            let _ = write!(out, "<li>{}</li>", esc(reason));
        }
        out.push_str("</ul></td></tr>");
    }
    out.push_str("</table>");
}
