//! The GNSS timeline: each drone's estimate error (horizontal distance from the truth)
//! against sim time, one panel per group, from `gnss.csv` (runs with a constellation).

use std::fmt::Write;

use super::draw::{esc, open_svg, path_data, text};
use crate::report::data::RunData;
use crate::report::model::GroupStyle;

const WIDTH: f64 = 1600.0;
const LEFT: f64 = 95.0;
const PLOT_W: f64 = 1300.0;
const PANEL_H: f64 = 200.0;
const GAP: f64 = 80.0;
const TOP: f64 = 84.0;

/// The timeline; `None` without `gnss.csv`.
pub fn gnss(data: &RunData, styles: &[GroupStyle]) -> Option<String> {
    let samples = data.gnss.as_deref()?;
    let run = &data.plan.run.name;
    let end_s = samples.iter().map(|s| s.time_s).fold(1.0, f64::max);
    let height = TOP + styles.len().max(1) as f64 * (PANEL_H + GAP);
    let mut out = String::new();
    open_svg(&mut out, "gnss-timeline", WIDTH, height, &format!("GNSS timeline of {run}"));
    text(
        &mut out,
        WIDTH / 2.0,
        34.0,
        24.0,
        "middle",
        r#"font-weight="bold""#,
        &format!("Estimate error (horizontal distance from the truth) of run {run}, by group"),
    );
    for (g, style) in styles.iter().enumerate() {
        let top = TOP + g as f64 * (PANEL_H + GAP);
        let drones: Vec<u32> = data.plan.drones.iter().filter(|d| d.group == style.name).map(|d| d.index).collect();
        let of_group: Vec<_> = samples.iter().filter(|s| drones.contains(&s.drone)).collect();
        // A round ceiling over the group's largest error (at least 2 m).
        let worst = of_group.iter().filter_map(|s| s.estimate_error_m).fold(2.0, f64::max);
        let step = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0]
            .into_iter()
            .find(|s| worst / s <= 5.0)
            .unwrap_or(1000.0);
        let ceiling = (worst / step).ceil() * step;
        let x = |t: f64| LEFT + t / end_s * PLOT_W;
        let y = |m: f64| top + PANEL_H - m / ceiling * PANEL_H;
        let _ = write!(
            out,
            r##"<rect x="{LEFT}" y="{top:.1}" width="{PLOT_W}" height="{PANEL_H}" fill="none" stroke="#999999"/>"##
        );
        text(&mut out, LEFT, top - 10.0, 16.0, "start", r#"font-weight="bold""#, &format!("{} (m)", style.name));
        let mut tick = 0.0;
        while tick <= ceiling + 1e-9 {
            let _ = write!(
                out,
                r##"<line x1="{LEFT}" x2="{:.1}" y1="{1:.1}" y2="{1:.1}" stroke="#eeeeee"/>"##,
                LEFT + PLOT_W,
                y(tick)
            );
            text(&mut out, LEFT - 8.0, y(tick) + 5.0, 13.0, "end", "", &format!("{tick}"));
            tick += step;
        }
        for d in drones {
            let points = of_group
                .iter()
                .filter(|s| s.drone == d)
                .filter_map(|s| s.estimate_error_m.map(|e| (x(s.time_s), y(e.min(ceiling)))));
            let path = path_data(points, 0.5);
            if !path.is_empty() {
                let _ = write!(
                    out,
                    r#"<path d="{path}" fill="none" stroke="{}" stroke-width="1.5"><title>{}</title></path>"#,
                    style.colour,
                    esc(&data.plan.drones[d as usize].name)
                );
            }
        }
        text(&mut out, LEFT + PLOT_W, top + PANEL_H + 20.0, 13.0, "end", "", &format!("{end_s:.0} s"));
    }
    out.push_str("</svg>");
    Some(out)
}
