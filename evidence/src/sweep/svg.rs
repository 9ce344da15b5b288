//! The sweep report's plots as SVG text: the pass rate against the x parameter with its
//! confidence interval as error bars (one line per combination of the other parameters),
//! the heat map of the pass rate over two parameters, and a box plot per metric (one row
//! per cell).
//!
//! Pure functions of the report: the same report gives the same bytes. Parameters whose
//! values are not all numbers are drawn as categories, evenly spaced in sweep order.

use std::fmt::Write;

use serde_json::Value;

use super::model::{CellReport, METRICS, MetricStats, SweepReport, metric_label};
use crate::markup::{FONT, esc};
use sadesim_crds::sweep::space::show;

/// At most this many lines in the pass-rate plot; the others are in the table.
pub const MAX_LINES: usize = 8;
/// Line colours (colour-blind friendly, Okabe–Ito), one per line.
const COLOURS: [&str; MAX_LINES] =
    ["#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#000000", "#999999"];

fn open_svg(out: &mut String, id: &str, width: f64, height: f64, title: &str) {
    let _ = write!(
        out,
        r##"<svg xmlns="http://www.w3.org/2000/svg" id="{id}" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="{FONT}" fill="#222222"><title>{}</title><rect width="100%" height="100%" fill="#ffffff"/>"##,
        esc(title)
    );
}

fn text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, extra: &str, content: &str) {
    let _ = write!(
        out,
        r#"<text x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="{anchor}" {extra}>{}</text>"#,
        esc(content)
    );
}

/// A number as a label: integers plain, others with up to three decimals.
pub fn number(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e12 {
        format!("{v:.0}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Positions of a parameter's values along an axis `width` pixels wide: proportional when
/// every value is a number, else evenly spaced categories.
fn positions(values: &[Value], width: f64) -> Vec<f64> {
    let numbers: Option<Vec<f64>> = values.iter().map(Value::as_f64).collect();
    match numbers {
        Some(xs) if xs.len() > 1 => {
            let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
            let span = if hi > lo { hi - lo } else { 1.0 };
            xs.iter().map(|x| width * (0.05 + 0.9 * (x - lo) / span)).collect()
        }
        _ => (0..values.len()).map(|i| width * (i as f64 + 0.5) / values.len() as f64).collect(),
    }
}

/// The label of a cell without the parameter `x`: the combination its line stands for.
fn others_label(cell: &CellReport, x: &str) -> String {
    let parts: Vec<String> =
        cell.values.iter().filter(|(name, _)| name != x).map(|(name, v)| format!("{name}={}", show(v))).collect();
    if parts.is_empty() { "all runs".into() } else { parts.join(", ") }
}

/// The pass rate of every cell against the x parameter, with the Wilson interval as error
/// bars; `None` without cells or when `report.x` is not a parameter.
pub fn pass_rate(report: &SweepReport) -> Option<String> {
    const WIDTH: f64 = 1100.0;
    const LEFT: f64 = 80.0;
    const PLOT_W: f64 = 700.0;
    const TOP: f64 = 60.0;
    const PLOT_H: f64 = 360.0;
    let x = report.parameters.iter().find(|p| p.name == report.x)?;
    if report.cells.is_empty() {
        return None;
    }
    // Lines in order of first appearance.
    let mut lines: Vec<(String, Vec<&CellReport>)> = Vec::new();
    for cell in &report.cells {
        let label = others_label(cell, &x.name);
        match lines.iter_mut().find(|(l, _)| *l == label) {
            Some((_, cells)) => cells.push(cell),
            None => lines.push((label, vec![cell])),
        }
    }
    let hidden = lines.len().saturating_sub(MAX_LINES);
    lines.truncate(MAX_LINES);
    let xs = positions(&x.values, PLOT_W);
    let y = |rate: f64| TOP + PLOT_H * (1.0 - rate);
    let height = TOP + PLOT_H + 80.0;
    let mut out = String::new();
    let title = format!("Pass rate of sweep {} against {}", report.sweep, x.name);
    open_svg(&mut out, "pass-rate", WIDTH, height, &title);
    text(&mut out, LEFT + PLOT_W / 2.0, 30.0, 20.0, "middle", r#"font-weight="bold""#, &title);
    // Frame, horizontal grid every 25 %, x ticks at each value.
    let _ = write!(
        out,
        r##"<rect x="{LEFT}" y="{TOP}" width="{PLOT_W}" height="{PLOT_H}" fill="none" stroke="#888888"/>"##
    );
    for k in 0..=4 {
        let rate = f64::from(k) / 4.0;
        let _ = write!(
            out,
            r##"<line x1="{LEFT}" x2="{:.1}" y1="{:.1}" y2="{:.1}" stroke="#e0e0e0"/>"##,
            LEFT + PLOT_W,
            y(rate),
            y(rate)
        );
        text(&mut out, LEFT - 8.0, y(rate) + 5.0, 14.0, "end", "", &format!("{:.0} %", rate * 100.0));
    }
    for (value, px) in x.values.iter().zip(&xs) {
        let _ = write!(
            out,
            r##"<line x1="{0:.1}" x2="{0:.1}" y1="{1:.1}" y2="{2:.1}" stroke="#888888"/>"##,
            LEFT + px,
            TOP + PLOT_H,
            TOP + PLOT_H + 6.0
        );
        text(&mut out, LEFT + px, TOP + PLOT_H + 24.0, 14.0, "middle", "", &show(value));
    }
    text(&mut out, LEFT + PLOT_W / 2.0, TOP + PLOT_H + 54.0, 16.0, "middle", "", &x.name);
    // Lines: small horizontal offsets keep their error bars apart.
    let count = lines.len() as f64;
    for (k, (label, cells)) in lines.iter().enumerate() {
        let colour = COLOURS[k];
        let offset = (k as f64 - (count - 1.0) / 2.0) * 5.0;
        let points: Vec<(f64, &CellReport)> = cells
            .iter()
            .filter_map(|c| {
                let value = c.values.iter().find(|(n, _)| *n == x.name).map(|(_, v)| v)?;
                let i = x.values.iter().position(|v| v == value)?;
                Some((LEFT + xs[i] + offset, *c))
            })
            .collect();
        let mut d = String::new();
        for (px, c) in points.iter().filter(|(_, c)| c.rate.pass_rate.is_some()) {
            let _ =
                write!(d, "{}{px:.1} {:.1}", if d.is_empty() { "M" } else { "L" }, y(c.rate.pass_rate.unwrap_or(0.0)));
        }
        let _ = write!(
            out,
            r#"<g data-series="{}"><path d="{d}" fill="none" stroke="{colour}" stroke-width="2"/>"#,
            esc(label)
        );
        for (px, c) in &points {
            let (lo, hi) = (y(c.rate.ci_low), y(c.rate.ci_high));
            let _ = write!(
                out,
                r#"<path class="ci" d="M{0:.1} {lo:.1}V{hi:.1}M{1:.1} {lo:.1}H{2:.1}M{1:.1} {hi:.1}H{2:.1}" stroke="{colour}" stroke-width="1.2" fill="none"/>"#,
                px,
                px - 4.0,
                px + 4.0
            );
            if let Some(rate) = c.rate.pass_rate {
                let _ = write!(
                    out,
                    r#"<circle cx="{px:.1}" cy="{:.1}" r="4.5" fill="{colour}"><title>{}: {}/{} passed, {:.0} % CI {:.0}–{:.0} %</title></circle>"#,
                    y(rate),
                    esc(&c.label),
                    c.rate.passed,
                    c.rate.finished,
                    report.confidence * 100.0,
                    c.rate.ci_low * 100.0,
                    c.rate.ci_high * 100.0
                );
            }
        }
        out.push_str("</g>");
        // Legend entry.
        let ly = TOP + 10.0 + k as f64 * 24.0;
        let lx = LEFT + PLOT_W + 24.0;
        let _ = write!(
            out,
            r#"<line x1="{lx:.1}" x2="{:.1}" y1="{ly:.1}" y2="{ly:.1}" stroke="{colour}" stroke-width="3"/>"#,
            lx + 24.0
        );
        text(&mut out, lx + 32.0, ly + 5.0, 14.0, "start", "", label);
    }
    if hidden > 0 {
        let ly = TOP + 10.0 + count * 24.0 + 6.0;
        text(&mut out, LEFT + PLOT_W + 24.0, ly, 13.0, "start", "", &format!("{hidden} more not drawn: see the table"));
    }
    out.push_str("</svg>");
    Some(out)
}

/// The fill of a pass rate: red at 0, amber at 0.5, green at 1.
pub fn rate_colour(rate: f64) -> String {
    let (red, amber, green) = ([192.0, 38.0, 45.0], [240.0, 190.0, 60.0], [42.0, 138.0, 58.0]);
    let (a, b, t) = if rate < 0.5 { (red, amber, rate * 2.0) } else { (amber, green, rate * 2.0 - 1.0) };
    let c: Vec<u8> = (0..3).map(|i| (a[i] + (b[i] - a[i]) * t.clamp(0.0, 1.0)).round() as u8).collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// The pass rate over the two heat-map parameters (rows: the first, columns: the second),
/// the runs of cells that differ in other parameters pooled; `None` unless there are two.
pub fn heat_map(report: &SweepReport) -> Option<String> {
    const LEFT: f64 = 170.0;
    const TOP: f64 = 90.0;
    const CELL_W: f64 = 96.0;
    const CELL_H: f64 = 56.0;
    let [rows, columns] = report.heat_map.as_slice() else { return None };
    let rows = report.parameters.iter().find(|p| p.name == *rows)?;
    let columns = report.parameters.iter().find(|p| p.name == *columns)?;
    let width = LEFT + CELL_W * columns.values.len() as f64 + 40.0;
    let height = TOP + CELL_H * rows.values.len() as f64 + 40.0;
    let mut out = String::new();
    let title = format!("Pass rate of sweep {} by {} and {}", report.sweep, rows.name, columns.name);
    open_svg(&mut out, "heat-map", width.max(520.0), height, &title);
    text(&mut out, 20.0, 30.0, 20.0, "start", r#"font-weight="bold""#, &title);
    text(&mut out, LEFT, TOP - 36.0, 15.0, "start", r#"font-weight="bold""#, &format!("{} →", columns.name));
    text(&mut out, 20.0, TOP - 12.0, 15.0, "start", r#"font-weight="bold""#, &format!("{} ↓", rows.name));
    for (j, column) in columns.values.iter().enumerate() {
        text(&mut out, LEFT + (j as f64 + 0.5) * CELL_W, TOP - 12.0, 14.0, "middle", "", &show(column));
    }
    for (i, row) in rows.values.iter().enumerate() {
        let top = TOP + i as f64 * CELL_H;
        text(&mut out, LEFT - 10.0, top + CELL_H / 2.0 + 5.0, 14.0, "end", "", &show(row));
        for (j, column) in columns.values.iter().enumerate() {
            let left = LEFT + j as f64 * CELL_W;
            let (passed, finished) = report
                .cells
                .iter()
                .filter(|c| {
                    c.values.iter().any(|(n, v)| *n == rows.name && v == row)
                        && c.values.iter().any(|(n, v)| *n == columns.name && v == column)
                })
                .fold((0, 0), |(p, f), c| (p + c.rate.passed, f + c.rate.finished));
            let (fill, big) = if finished == 0 {
                ("#dddddd".to_string(), "no runs".to_string())
            } else {
                let rate = f64::from(passed) / f64::from(finished);
                (rate_colour(rate), format!("{:.0} %", rate * 100.0))
            };
            let _ = write!(
                out,
                r##"<rect class="heat" x="{left:.1}" y="{top:.1}" width="{CELL_W}" height="{CELL_H}" fill="{fill}" stroke="#ffffff" stroke-width="2"/>"##
            );
            let halo = r##"stroke="#ffffff" stroke-width="3" paint-order="stroke""##;
            text(
                &mut out,
                left + CELL_W / 2.0,
                top + 25.0,
                16.0,
                "middle",
                &format!(r#"font-weight="bold" {halo}"#),
                &big,
            );
            text(&mut out, left + CELL_W / 2.0, top + 44.0, 12.0, "middle", halo, &format!("{passed}/{finished}"));
        }
    }
    out.push_str("</svg>");
    Some(out)
}

/// One box plot per metric with data: a row per cell that has the metric, a line from
/// min to max, a box from the median to the 95th percentile and a tick at the median.
/// Returns (metric key, SVG) in [`METRICS`] order.
pub fn box_plots(report: &SweepReport) -> Vec<(&'static str, String)> {
    const LEFT: f64 = 300.0;
    const PLOT_W: f64 = 560.0;
    const TOP: f64 = 50.0;
    const ROW_H: f64 = 22.0;
    let mut plots = Vec::new();
    for metric in &METRICS {
        let rows: Vec<(&CellReport, &MetricStats)> = report
            .cells
            .iter()
            .filter_map(|c| c.metrics.iter().find(|m| m.metric == metric.key).map(|m| (c, m)))
            .collect();
        if rows.is_empty() {
            continue;
        }
        let lo = rows.iter().map(|(_, m)| m.min).fold(f64::INFINITY, f64::min);
        let hi = rows.iter().map(|(_, m)| m.max).fold(f64::NEG_INFINITY, f64::max);
        let span = if hi > lo { hi - lo } else { 1.0 };
        let x = |v: f64| LEFT + PLOT_W * (v - lo) / span;
        let height = TOP + ROW_H * rows.len() as f64 + 40.0;
        let mut out = String::new();
        open_svg(&mut out, &format!("box-{}", metric.key), LEFT + PLOT_W + 40.0, height, metric_label(metric.key));
        text(&mut out, 20.0, 26.0, 16.0, "start", r#"font-weight="bold""#, metric_label(metric.key));
        for (k, (cell, m)) in rows.iter().enumerate() {
            let mid = TOP + (k as f64 + 0.5) * ROW_H;
            let label: String = cell.label.chars().take(42).collect();
            text(&mut out, LEFT - 10.0, mid + 4.0, 12.0, "end", "", &label);
            let (min, max, median, p95) = (x(m.min), x(m.max), x(m.median), x(m.p95));
            let box_w = (p95 - median).max(1.0);
            let (box_top, tick_top, tick_bottom) = (mid - 6.0, mid - 8.0, mid + 8.0);
            let _ = write!(
                out,
                r##"<g><title>{}: n {}, min {}, median {}, p95 {}, max {}</title><line x1="{min:.1}" x2="{max:.1}" y1="{mid:.1}" y2="{mid:.1}" stroke="#555555"/><rect x="{median:.1}" y="{box_top:.1}" width="{box_w:.1}" height="12" fill="#9ecae1" stroke="#3182bd"/><line x1="{median:.1}" x2="{median:.1}" y1="{tick_top:.1}" y2="{tick_bottom:.1}" stroke="#08306b" stroke-width="2.5"/></g>"##,
                esc(&cell.label),
                m.n,
                number(m.min),
                number(m.median),
                number(m.p95),
                number(m.max),
            );
        }
        let axis = TOP + ROW_H * rows.len() as f64 + 6.0;
        let _ = write!(
            out,
            r##"<line x1="{LEFT}" x2="{:.1}" y1="{axis:.1}" y2="{axis:.1}" stroke="#888888"/>"##,
            LEFT + PLOT_W
        );
        for k in 0..=4 {
            let v = lo + span * f64::from(k) / 4.0;
            text(&mut out, x(v), axis + 18.0, 12.0, "middle", "", &number(v));
        }
        out.push_str("</svg>");
        plots.push((metric.key, out));
    }
    plots
}
