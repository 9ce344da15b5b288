//! The GNSS timeline: per group, three stacked plots against sim time from `gnss.csv`
//! (runs with a constellation): the satellites in each drone's fix, its HDOP and the
//! estimate error (horizontal distance of the position the autopilot flew on from the
//! truth). A street canyon shows as fewer satellites, a higher HDOP and a larger error at
//! the same moments.

use std::fmt::Write;

use super::draw::{esc, open_svg, path_data, text, title};
use crate::report::data::{GnssSample, RunData};
use crate::report::model::GroupStyle;

const WIDTH: f64 = 1600.0;
const LEFT: f64 = 95.0;
const PLOT_W: f64 = 1300.0;
/// One series' plot height and the gap under it (its time label).
const SERIES_H: f64 = 120.0;
const SERIES_GAP: f64 = 34.0;
/// Space above a group's first plot (its name) and after its last.
const GROUP_HEAD: f64 = 34.0;
const GROUP_GAP: f64 = 30.0;
const TOP: f64 = 70.0;
/// HDOP above this is drawn at the top of its plot (a 2D or marginal fix can reach 50+,
/// which would flatten every other value).
const HDOP_CAP: f64 = 10.0;

/// One plotted quantity of a `gnss.csv` row.
struct Series {
    /// `data-series` of its paths.
    id: &'static str,
    label: &'static str,
    value: fn(&GnssSample) -> Option<f64>,
    /// The plot's ceiling never goes below this nor above `cap`.
    floor: f64,
    cap: f64,
}

const SERIES: [Series; 3] = [
    Series {
        id: "satellites",
        label: "satellites used",
        value: |s| Some(f64::from(s.satellites)),
        floor: 5.0,
        cap: 200.0,
    },
    Series { id: "hdop", label: "HDOP", value: |s| s.hdop, floor: 2.0, cap: HDOP_CAP },
    Series {
        id: "estimate_error",
        label: "estimate error (m)",
        value: |s| s.estimate_error_m,
        floor: 2.0,
        cap: f64::INFINITY,
    },
];

/// The timeline; `None` without `gnss.csv`.
pub fn gnss(data: &RunData, styles: &[GroupStyle]) -> Option<String> {
    let samples = data.gnss.as_deref()?;
    let run = &data.plan.run.name;
    let end_s = samples.iter().map(|s| s.time_s).fold(1.0, f64::max);
    let group_h = GROUP_HEAD + SERIES.len() as f64 * (SERIES_H + SERIES_GAP) + GROUP_GAP;
    let height = TOP + styles.len().max(1) as f64 * group_h;
    let mut out = String::new();
    open_svg(&mut out, "gnss-timeline", WIDTH, height, &format!("GNSS timeline of {run}"));
    title(&mut out, WIDTH, &format!("GNSS of run {run} by group: satellites used, HDOP and estimate error"));
    for (g, style) in styles.iter().enumerate() {
        let group_top = TOP + g as f64 * group_h;
        text(&mut out, LEFT, group_top + 20.0, 18.0, "start", r#"font-weight="bold""#, &style.name);
        let drones: Vec<u32> = data.plan.drones.iter().filter(|d| d.group == style.name).map(|d| d.index).collect();
        let of_group: Vec<&GnssSample> = samples.iter().filter(|s| drones.contains(&s.drone)).collect();
        for (k, series) in SERIES.iter().enumerate() {
            let top = group_top + GROUP_HEAD + k as f64 * (SERIES_H + SERIES_GAP);
            let plot = Plot { top, end_s, ceiling: ceiling(&of_group, series) };
            plot.frame(&mut out, series.label);
            for &d in &drones {
                let points = of_group
                    .iter()
                    .filter(|s| s.drone == d)
                    .filter_map(|s| (series.value)(s).map(|v| (plot.x(s.time_s), plot.y(v))));
                let path = path_data(points, 0.5);
                if !path.is_empty() {
                    let _ = write!(
                        out,
                        r#"<path data-series="{}" d="{path}" fill="none" stroke="{}" stroke-width="1.5"><title>{}</title></path>"#,
                        series.id,
                        style.colour,
                        esc(&data.plan.drones[d as usize].name)
                    );
                }
            }
            text(&mut out, LEFT + PLOT_W, top + SERIES_H + 18.0, 13.0, "end", "", &format!("{end_s:.0} s"));
        }
    }
    out.push_str("</svg>");
    Some(out)
}

/// A round ceiling over the group's largest value of `series`, within its floor and cap.
fn ceiling(samples: &[&GnssSample], series: &Series) -> (f64, f64) {
    let worst = samples.iter().filter_map(|s| (series.value)(s)).fold(series.floor, f64::max).min(series.cap);
    let step =
        [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0].into_iter().find(|s| worst / s <= 5.0).unwrap_or(1000.0);
    ((worst / step).ceil() * step, step)
}

/// One series' plot: time across, its value up to `ceiling` (values above it at the top).
struct Plot {
    top: f64,
    end_s: f64,
    /// The top value and the grid step.
    ceiling: (f64, f64),
}

impl Plot {
    fn x(&self, t: f64) -> f64 {
        LEFT + t / self.end_s * PLOT_W
    }

    fn y(&self, v: f64) -> f64 {
        self.top + SERIES_H - v.min(self.ceiling.0) / self.ceiling.0 * SERIES_H
    }

    fn frame(&self, out: &mut String, label: &str) {
        let (ceiling, step) = self.ceiling;
        let _ = write!(
            out,
            r##"<rect x="{LEFT}" y="{:.1}" width="{PLOT_W}" height="{SERIES_H}" fill="none" stroke="#999999"/>"##,
            self.top
        );
        let mut tick = 0.0;
        while tick <= ceiling + 1e-9 {
            let _ = write!(
                out,
                r##"<line x1="{LEFT}" x2="{:.1}" y1="{1:.1}" y2="{1:.1}" stroke="#eeeeee"/>"##,
                LEFT + PLOT_W,
                self.y(tick)
            );
            text(out, LEFT - 8.0, self.y(tick) + 5.0, 13.0, "end", "", &format!("{tick}"));
            tick += step;
        }
        text(out, LEFT + PLOT_W + 10.0, self.top + 16.0, 13.0, "start", "", label);
    }
}
