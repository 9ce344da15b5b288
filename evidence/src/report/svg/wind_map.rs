//! A horizontal slice of the urban wind field (`sadesim assets show --wind-slice-agl H`):
//! at `H` metres above the local ground, every grid column coloured by the wind speed
//! there relative to the open-ground profile at that height (blue: sheltered, white: as
//! in the open, red: channelled or sped up over and around the blocks), arrows for the
//! direction, buildings in grey. Metres east and north of the run's origin, north up.

use std::fmt::Write;

use nalgebra::Vector3;
use sadesim_wind::UrbanWindField;

use super::draw::{open_svg, text, title};
use super::map::{Footprint, MapView, close_panel, draw_buildings, open_panel};

const WIDTH: f64 = 1400.0;
const TOP: f64 = 110.0;
const PANEL: f64 = 1100.0;
/// Arrows across the panel, about.
const ARROWS_ACROSS: f64 = 28.0;

/// Speed classes as a ratio to the open-ground profile at the slice's height: `[from, to)`
/// and the fill (a diverging palette, distinct in grey scale).
const CLASSES: [(f64, f64, &str); 7] = [
    (0.0, 0.25, "#2166ac"),
    (0.25, 0.5, "#67a9cf"),
    (0.5, 0.75, "#d1e5f0"),
    (0.75, 1.1, "#f7f7f7"),
    (1.1, 1.25, "#fddbc7"),
    (1.25, 1.5, "#ef8a62"),
    (1.5, f64::INFINITY, "#b2182b"),
];

fn class_of(ratio: f64) -> usize {
    CLASSES.iter().position(|(from, to, _)| ratio >= *from && ratio < *to).unwrap_or(CLASSES.len() - 1)
}

/// What to draw.
#[derive(Clone, Debug)]
pub struct WindSlice<'a> {
    /// With the sectors of `direction_from_deg` computed.
    pub field: &'a UrbanWindField,
    /// The scenario's wind: from where (degrees clockwise from north) and how strong at
    /// the field's reference height over open ground (m/s).
    pub direction_from_deg: f64,
    pub speed_mps: f64,
    /// Height of the slice above the ground of each column, metres.
    pub height_agl_m: f64,
    /// `[east_min, north_min, east_max, north_max]`, metres.
    pub area: [f64; 4],
    /// Run name, for the title.
    pub run: String,
}

/// Per class, the columns of the slice in it (what the picture shows, for a caption or a
/// test).
pub type ClassCounts = [usize; CLASSES.len()];

/// The slice as SVG, and how many columns fell in each class.
///
/// # Panics
/// When a sector the direction needs was not computed (the caller's to ensure).
pub fn wind_map(s: &WindSlice, buildings: &[Footprint]) -> (String, ClassCounts) {
    let g = &s.field.grid;
    let [nx, ny, _] = g.dims;
    let h = g.spacing_m;
    let open = s.field.profile.factor(s.height_agl_m) * s.speed_mps;
    let height = TOP + PANEL + 170.0;
    let mut out = String::new();
    open_svg(&mut out, "wind-slice", WIDTH, height, &format!("Urban wind of {} at {} m AGL", s.run, s.height_agl_m));
    title(
        &mut out,
        WIDTH,
        &format!(
            "Wind {:.0} m above the ground: {:.1} m/s from {:.0}° ({:.1} m/s there in the open)",
            s.height_agl_m, s.speed_mps, s.direction_from_deg, open
        ),
    );
    let v = MapView::fit([(WIDTH - PANEL) / 2.0, TOP, PANEL, PANEL], s.area, 0.0);
    let panel_title = format!("Run {}: speed relative to the open ground at this height; arrows: direction", s.run);
    let ticks = open_panel(&mut out, "wind", &panel_title, &v);
    // The slice's value at a column: `None` inside a building or outside the area.
    let at = |i: usize, j: usize| -> Option<Vector3<f64>> {
        let [e, n, _] = g.centre(i, j, 0);
        let inside = e >= s.area[0] && e <= s.area[2] && n >= s.area[1] && n <= s.area[3];
        let up = g.ground_up_m[j * nx + i] + s.height_agl_m;
        let k = ((up - g.corner_m[2]) / h).floor();
        let solid = k >= 0.0 && (k as usize) < g.dims[2] && g.solid[g.index(i, j, k as usize)];
        if !inside || solid {
            return None;
        }
        let factor = s.field.factor_at(&Vector3::new(e, n, up), s.direction_from_deg, s.height_agl_m);
        Some(factor.expect("the direction's sectors are computed") * s.speed_mps)
    };
    let mut counts = [0; CLASSES.len()];
    let _ = write!(out, r#"<g shape-rendering="crispEdges">"#);
    for j in 0..ny {
        // Runs of one class along a row become one rectangle.
        let mut run: Option<(usize, usize)> = None;
        let flush = |out: &mut String, run: Option<(usize, usize)>, end: usize| {
            if let Some((start, class)) = run {
                let (x0, y0) = v.px(g.corner_m[0] + start as f64 * h, g.corner_m[1] + (j + 1) as f64 * h);
                let (x1, y1) = v.px(g.corner_m[0] + end as f64 * h, g.corner_m[1] + j as f64 * h);
                let _ = write!(
                    out,
                    r#"<rect x="{x0:.1}" y="{y0:.1}" width="{:.1}" height="{:.1}" fill="{}"/>"#,
                    x1 - x0 + 0.5,
                    y1 - y0 + 0.5,
                    CLASSES[class].2
                );
            }
        };
        for i in 0..nx {
            let class = at(i, j).map(|w| class_of(if open > 0.0 { w.xy().norm() / open } else { 0.0 }));
            if let Some(c) = class {
                counts[c] += 1;
            }
            if run.map(|(_, c)| Some(c)) != Some(class) {
                flush(&mut out, run, i);
                run = class.map(|c| (i, c));
            }
        }
        flush(&mut out, run, nx);
    }
    out.push_str("</g>");
    draw_buildings(&mut out, &v, buildings);
    arrows(&mut out, s, &v, open, &at);
    close_panel(&mut out, &v, &ticks);
    legend(&mut out, TOP + PANEL + 80.0, open);
    out.push_str("</svg>");
    (out, counts)
}

/// An arrow every few columns, pointing downwind, its length proportional to the speed
/// (the open wind at this height is the spacing between arrows).
fn arrows(out: &mut String, s: &WindSlice, v: &MapView, open: f64, at: &dyn Fn(usize, usize) -> Option<Vector3<f64>>) {
    let g = &s.field.grid;
    let span = (s.area[2] - s.area[0]).max(s.area[3] - s.area[1]);
    let every = ((span / ARROWS_ACROSS / g.spacing_m).round() as usize).max(1);
    let _ = write!(out, r##"<g stroke="#222222" stroke-width="1.4" fill="none">"##);
    for j in (every / 2..g.dims[1]).step_by(every) {
        for i in (every / 2..g.dims[0]).step_by(every) {
            let Some(w) = at(i, j) else { continue };
            let speed = w.xy().norm();
            if open <= 0.0 || speed < 1e-6 {
                continue;
            }
            let len_m = 0.8 * every as f64 * g.spacing_m * (speed / open).min(1.6);
            let [e, n, _] = g.centre(i, j, 0);
            let (dx, dy) = (w.x / speed, w.y / speed);
            let (x0, y0) = v.px(e - dx * len_m / 2.0, n - dy * len_m / 2.0);
            let (x1, y1) = v.px(e + dx * len_m / 2.0, n + dy * len_m / 2.0);
            // Head: two strokes 25° off the shaft, a quarter of its length.
            let (ux, uy) = ((x1 - x0), (y1 - y0));
            let head = 0.25;
            let rot = |a: f64| (ux * a.cos() - uy * a.sin(), ux * a.sin() + uy * a.cos());
            let (l, r) = (rot(25f64.to_radians()), rot(-25f64.to_radians()));
            let _ = write!(
                out,
                r#"<path d="M{x0:.1},{y0:.1}L{x1:.1},{y1:.1}M{:.1},{:.1}L{x1:.1},{y1:.1}L{:.1},{:.1}"/>"#,
                x1 - l.0 * head,
                y1 - l.1 * head,
                x1 - r.0 * head,
                y1 - r.1 * head
            );
        }
    }
    out.push_str("</g>");
}

fn legend(out: &mut String, y: f64, open: f64) {
    let w = 150.0;
    let left = (WIDTH - w * CLASSES.len() as f64) / 2.0;
    for (k, (from, to, fill)) in CLASSES.iter().enumerate() {
        let x = left + k as f64 * w;
        let _ = write!(
            out,
            r##"<rect x="{x:.1}" y="{y:.1}" width="{:.1}" height="18" fill="{fill}" stroke="#888888" stroke-width="0.6"/>"##,
            w - 6.0
        );
        let label = if to.is_infinite() {
            format!("≥ {from} ({:.1}+ m/s)", from * open)
        } else {
            format!("{from}–{to} ({:.1}–{:.1})", from * open, to * open)
        };
        text(out, x + (w - 6.0) / 2.0, y + 38.0, 13.0, "middle", "", &label);
    }
    text(out, WIDTH / 2.0, y - 10.0, 14.0, "middle", "", "speed / open-ground speed at this height (m/s)");
}
