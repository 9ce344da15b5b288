//! The trajectory map (the paper's Fig. 4A): every drone's path coloured by group, the zones
//! and building footprints, in metres east and north of the run's origin.

use std::fmt::Write;

use super::draw::{VIOLATION_FILL, ZONE_FILL, ZONE_STROKE, drones, esc, halo_text, open_svg, path_data, text, title};
use crate::report::data::{RunData, Sample, Track};
use crate::report::model::{self, GroupStyle, ZoneShape, ft};

/// Building footprints under the tracks.
const BUILDING_FILL: &str = "#e2e2e2";

/// A building footprint, metres east/north of the origin: its bounding rectangle, and its
/// rings when it is not that rectangle (a mapped building; courtyards as holes).
#[derive(Clone, Debug, PartialEq)]
pub struct Footprint {
    pub east_min_m: f64,
    pub north_min_m: f64,
    pub east_max_m: f64,
    pub north_max_m: f64,
    /// Outer ring then holes, `[east_m, north_m]`; `None` for an axis-aligned rectangle.
    pub rings: Option<Vec<Vec<[f64; 2]>>>,
}

/// Maps metres east/north to pixels, with the same scale on both axes.
#[derive(Clone, Copy, Debug)]
pub(super) struct MapView {
    /// Plot area in pixels: left, top, width, height.
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    east_min: f64,
    north_max: f64,
    /// Pixels per metre.
    scale: f64,
}

impl MapView {
    /// Fits `[east_min, north_min, east_max, north_max]` (grown by `pad` of its size) in
    /// the plot area, centred, one scale for both axes.
    pub(super) fn fit(area: [f64; 4], bounds: [f64; 4], pad: f64) -> Self {
        let [x, y, w, h] = area;
        let (mut w_m, mut h_m) = ((bounds[2] - bounds[0]).max(1.0), (bounds[3] - bounds[1]).max(1.0));
        w_m *= 1.0 + 2.0 * pad;
        h_m *= 1.0 + 2.0 * pad;
        let scale = (w / w_m).min(h / h_m);
        let (ce, cn) = ((bounds[0] + bounds[2]) / 2.0, (bounds[1] + bounds[3]) / 2.0);
        Self { x, y, w, h, east_min: ce - w / scale / 2.0, north_max: cn + h / scale / 2.0, scale }
    }

    pub(super) fn px(&self, e: f64, n: f64) -> (f64, f64) {
        (self.x + (e - self.east_min) * self.scale, self.y + (self.north_max - n) * self.scale)
    }

    fn east_max(&self) -> f64 {
        self.east_min + self.w / self.scale
    }

    fn north_min(&self) -> f64 {
        self.north_max - self.h / self.scale
    }

    fn sees(&self, f: &Footprint) -> bool {
        f.east_max_m >= self.east_min
            && f.east_min_m <= self.east_max()
            && f.north_max_m >= self.north_min()
            && f.north_min_m <= self.north_max
    }
}

/// Bounds of everything the full map must show: tracks, zones.
pub(super) fn data_bounds(tracks: &[Track], zones: &[ZoneShape]) -> Option<[f64; 4]> {
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    let mut any = false;
    for s in tracks.iter().flat_map(|t| &t.samples) {
        b = [b[0].min(s.east_m), b[1].min(s.north_m), b[2].max(s.east_m), b[3].max(s.north_m)];
        any = true;
    }
    for z in zones {
        let zb = z.bounds();
        b = [b[0].min(zb[0]), b[1].min(zb[1]), b[2].max(zb[2]), b[3].max(zb[3])];
        any = true;
    }
    any.then_some(b)
}

/// The map's geometry: one panel with everything, and a second one around the zones
/// (where the paper's Fig. 4A shows paths entering or turning away) when there are any.
const MAP_WIDTH: f64 = 1600.0;
const MAP_PANEL: f64 = 660.0;
const MAP_TOP: f64 = 92.0;

/// The trajectory map. `buildings` may be empty (drawn only where they are known).
pub fn map(data: &RunData, styles: &[GroupStyle], zones: &[ZoneShape], buildings: &[Footprint]) -> String {
    let tracks = data.tracks.as_deref().unwrap_or_default();
    let run = &data.plan.run.name;
    let legend_rows = styles.len().div_ceil(2) + 2;
    let height = MAP_TOP + MAP_PANEL + 80.0 + legend_rows as f64 * 26.0 + 20.0;
    let mut out = String::new();
    open_svg(&mut out, "map", MAP_WIDTH, height, &format!("Flight paths of {run}"));
    title(&mut out, MAP_WIDTH, &format!("Flight paths of run {run}: {} by group, zones in pink", drones(tracks.len())));
    let Some(bounds) = data_bounds(tracks, zones) else {
        text(&mut out, MAP_WIDTH / 2.0, MAP_TOP + 100.0, 20.0, "middle", "", "No trajectory recorded and no zones");
        out.push_str("</svg>");
        return out;
    };
    let mut panels: Vec<(&str, String, MapView)> = Vec::new();
    if zones.is_empty() {
        let area = [(MAP_WIDTH - MAP_PANEL * 2.0) / 2.0 + 40.0, MAP_TOP, MAP_PANEL * 2.0 - 80.0, MAP_PANEL];
        panels.push(("full", "Whole run".into(), MapView::fit(area, bounds, 0.04)));
    } else {
        let full = [95.0, MAP_TOP, MAP_PANEL, MAP_PANEL];
        panels.push(("full", "Whole run".into(), MapView::fit(full, bounds, 0.04)));
        let mut zb = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for z in zones {
            let b = z.bounds();
            zb = [zb[0].min(b[0]), zb[1].min(b[1]), zb[2].max(b[2]), zb[3].max(b[3])];
        }
        // Three zone widths across, at least 600 m: the approach and the boundary.
        let half = ((zb[2] - zb[0]).max(zb[3] - zb[1]) * 1.5).max(300.0);
        let (ce, cn) = ((zb[0] + zb[2]) / 2.0, (zb[1] + zb[3]) / 2.0);
        let zoom = [ce - half, cn - half, ce + half, cn + half];
        let names: Vec<&str> = zones.iter().map(|z| z.name.as_str()).collect();
        let area = [MAP_WIDTH - 40.0 - MAP_PANEL, MAP_TOP, MAP_PANEL, MAP_PANEL];
        panels.push(("zoom", format!("Around {}", names.join(", ")), MapView::fit(area, zoom, 0.0)));
    }
    for (id, title, view) in &panels {
        map_panel(&mut out, id, title, view, data, tracks, styles, zones, buildings);
    }
    map_legend(&mut out, styles, tracks, zones, !buildings.is_empty(), MAP_TOP + MAP_PANEL + 78.0);
    out.push_str("</svg>");
    out
}

#[allow(clippy::too_many_arguments)]
fn map_panel(
    out: &mut String,
    id: &str,
    title: &str,
    v: &MapView,
    data: &RunData,
    tracks: &[Track],
    styles: &[GroupStyle],
    zones: &[ZoneShape],
    buildings: &[Footprint],
) {
    let ticks = open_panel(out, id, title, v);
    // Buildings, then zones, then tracks: the paths stay visible over everything.
    draw_buildings(out, v, buildings);
    for z in zones {
        let pts: Vec<String> = z
            .ring_en_m
            .iter()
            .map(|[e, n]| {
                let (x, y) = v.px(*e, *n);
                format!("{x:.1},{y:.1}")
            })
            .collect();
        let _ = write!(
            out,
            r#"<polygon class="zone" data-zone="{}" points="{}" fill="{ZONE_FILL}" fill-opacity="0.28" stroke="{ZONE_STROKE}" stroke-width="2"/>"#,
            esc(&z.name),
            pts.join(" ")
        );
    }
    // Tracks, group by group, so the legend order is the drawing order.
    let min_px = 0.8;
    for t in tracks {
        let colour = model::style_of(styles, &t.group).map_or("#555555", |s| s.colour);
        let d = path_data(t.samples.iter().map(|s| v.px(s.east_m, s.north_m)), min_px);
        let _ = write!(
            out,
            r#"<path class="track" data-drone="{}" data-group="{}" d="{d}" fill="none" stroke="{colour}" stroke-width="1.6" stroke-opacity="0.85" stroke-linejoin="round"><title>{}</title></path>"#,
            t.drone,
            esc(&t.group),
            esc(&t.name)
        );
    }
    // Start (open circle) and end (filled square, or a cross for a crash) of every track.
    for t in tracks {
        let colour = model::style_of(styles, &t.group).map_or("#555555", |s| s.colour);
        let (Some(first), Some(last)) = (t.samples.first(), t.samples.last()) else { continue };
        let (x, y) = v.px(first.east_m, first.north_m);
        let _ = write!(
            out,
            r##"<circle cx="{x:.1}" cy="{y:.1}" r="6.5" fill="#ffffff" stroke="{colour}" stroke-width="2"/>"##
        );
        end_marker(out, v.px(last.east_m, last.north_m), colour, last);
    }
    // Where each violation started.
    if let Some(a) = &data.airspace {
        for viol in &a.compliance.violations {
            let (x, y) = v.px(viol.at.east_m, viol.at.north_m);
            let _ = write!(
                out,
                r##"<path class="violation" d="M{x:.1} {:.1}L{:.1} {:.1}L{:.1} {:.1}Z" fill="{VIOLATION_FILL}" stroke="#000000" stroke-width="1.2"><title>{} {}</title></path>"##,
                y - 7.0,
                x + 6.5,
                y + 5.0,
                x - 6.5,
                y + 5.0,
                esc(&viol.drone_name),
                viol.kind.as_str()
            );
        }
    }
    // Zone names on top of everything.
    for z in zones {
        let b = z.bounds();
        let (x, y) = v.px((b[0] + b[2]) / 2.0, b[3]);
        let small = (b[2] - b[0]) * v.scale < 60.0;
        let size = if small { 13.0 } else { 15.0 };
        let label = format!("{} ({})", z.name, z.vertical_label());
        halo_text(out, x, y - 6.0, size, "middle", &format!(r#"fill="{ZONE_STROKE}" font-weight="bold""#), &label);
    }
    close_panel(out, v, &ticks);
}

/// A map panel's background, title, grid and the clipped group its contents go in; returns
/// the east and north ticks for [`close_panel`].
pub(super) fn open_panel(out: &mut String, id: &str, title: &str, v: &MapView) -> (Vec<f64>, Vec<f64>) {
    let _ = write!(
        out,
        r#"<clipPath id="clip-{id}"><rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}"/></clipPath>"#,
        v.x, v.y, v.w, v.h
    );
    text(out, v.x + v.w / 2.0, v.y - 12.0, 18.0, "middle", r#"font-weight="bold""#, title);
    let _ = write!(
        out,
        r##"<g id="panel-{id}"><rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="#fbfbf8"/>"##,
        v.x, v.y, v.w, v.h
    );
    // Grid and ticks, metres from the origin.
    let span = (v.w / v.scale).max(v.h / v.scale);
    let target = if span > 2000.0 { 6 } else { 5 };
    let _ = write!(out, r##"<g stroke="#dddddd" stroke-width="1">"##);
    let east_ticks = model::ticks(v.east_min, v.east_max(), target);
    let north_ticks = model::ticks(v.north_min(), v.north_max, target);
    for e in &east_ticks {
        let (x, _) = v.px(*e, 0.0);
        let _ = write!(out, r#"<line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}"/>"#, v.y, v.y + v.h);
    }
    for n in &north_ticks {
        let (_, y) = v.px(0.0, *n);
        let _ = write!(out, r#"<line x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}"/>"#, v.x, v.x + v.w);
    }
    out.push_str("</g>");
    let _ = write!(out, r#"<g clip-path="url(#clip-{id})">"#);
    (east_ticks, north_ticks)
}

/// Closes [`open_panel`]'s clipped group: the frame, tick labels, axis titles, scale bar.
pub(super) fn close_panel(out: &mut String, v: &MapView, (east_ticks, north_ticks): &(Vec<f64>, Vec<f64>)) {
    out.push_str("</g>");
    let _ = write!(
        out,
        r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="#444444" stroke-width="1.2"/>"##,
        v.x, v.y, v.w, v.h
    );
    // Tick labels and axis titles.
    for e in east_ticks {
        let (x, _) = v.px(*e, 0.0);
        text(out, x, v.y + v.h + 20.0, 13.0, "middle", "", &model::tick_label(*e));
    }
    for n in north_ticks {
        let (_, y) = v.px(0.0, *n);
        text(out, v.x - 8.0, y + 4.5, 13.0, "end", "", &model::tick_label(*n));
    }
    text(out, v.x + v.w / 2.0, v.y + v.h + 44.0, 14.0, "middle", "", "metres east of the origin");
    let (cx, cy) = (v.x - 62.0, v.y + v.h / 2.0);
    text(
        out,
        cx,
        cy,
        14.0,
        "middle",
        &format!(r#"transform="rotate(-90 {cx:.1} {cy:.1})""#),
        "metres north of the origin",
    );
    scale_bar(out, v);
    out.push_str("</g>");
}

/// Building footprints (grey) in the panel.
pub(super) fn draw_buildings(out: &mut String, v: &MapView, buildings: &[Footprint]) {
    if buildings.is_empty() {
        return;
    }
    let _ = write!(out, r#"<g fill="{BUILDING_FILL}">"#);
    for b in buildings.iter().filter(|b| v.sees(b)) {
        if let Some(rings) = &b.rings {
            // Even-odd: holes stay open.
            let mut d = String::new();
            for ring in rings {
                for (k, [e, n]) in ring.iter().enumerate() {
                    let (x, y) = v.px(*e, *n);
                    let _ = write!(d, "{}{x:.1},{y:.1}", if k == 0 { "M" } else { "L" });
                }
                d.push('Z');
            }
            let _ = write!(out, r#"<path fill-rule="evenodd" d="{d}"/>"#);
            continue;
        }
        let (x0, y0) = v.px(b.east_min_m, b.north_max_m);
        let (x1, y1) = v.px(b.east_max_m, b.north_min_m);
        let _ = write!(
            out,
            r#"<rect x="{x0:.1}" y="{y0:.1}" width="{:.1}" height="{:.1}"/>"#,
            (x1 - x0).max(0.3),
            (y1 - y0).max(0.3)
        );
    }
    out.push_str("</g>");
}

fn end_marker(out: &mut String, (x, y): (f64, f64), colour: &str, last: &Sample) {
    if last.crashed {
        let _ = write!(
            out,
            r##"<path d="M{:.1} {:.1}L{:.1} {:.1}M{:.1} {:.1}L{:.1} {:.1}" stroke="#000000" stroke-width="3"/>"##,
            x - 6.0,
            y - 6.0,
            x + 6.0,
            y + 6.0,
            x - 6.0,
            y + 6.0,
            x + 6.0,
            y - 6.0
        );
    } else {
        let _ = write!(
            out,
            r##"<rect x="{:.1}" y="{:.1}" width="6" height="6" fill="{colour}" stroke="#000000" stroke-width="0.8"/>"##,
            x - 3.0,
            y - 3.0
        );
    }
}

/// A scale bar and a north arrow in the panel's lower left corner.
fn scale_bar(out: &mut String, v: &MapView) {
    let target_m = 120.0 / v.scale;
    let len_m = [10.0, 20.0, 50.0, 100.0, 200.0, 250.0, 500.0, 1000.0, 2000.0, 5000.0, 10_000.0]
        .into_iter()
        .rev()
        .find(|l| *l <= target_m)
        .unwrap_or(10.0);
    let (x, y) = (v.x + 16.0, v.y + v.h - 18.0);
    let len_px = len_m * v.scale;
    let _ = write!(
        out,
        r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="30" fill="#ffffff" fill-opacity="0.85"/><path d="M{x:.1} {:.1}V{y:.1}H{:.1}V{:.1}" fill="none" stroke="#000000" stroke-width="2"/>"##,
        x - 8.0,
        y - 22.0,
        len_px + 16.0 + 60.0,
        y - 6.0,
        x + len_px,
        y - 6.0
    );
    let label = if len_m >= 1000.0 { format!("{} km", len_m / 1000.0) } else { format!("{len_m} m") };
    text(out, x + len_px / 2.0, y - 9.0, 13.0, "middle", "", &label);
    let nx = x + len_px + 35.0;
    let _ = write!(
        out,
        r##"<path d="M{nx:.1} {:.1}L{:.1} {:.1}L{nx:.1} {:.1}L{:.1} {:.1}Z" fill="#000000"/>"##,
        y - 20.0,
        nx + 5.0,
        y - 4.0,
        y - 8.0,
        nx - 5.0,
        y - 4.0
    );
    text(out, nx + 14.0, y - 6.0, 13.0, "start", r#"font-weight="bold""#, "N");
}

fn map_legend(
    out: &mut String,
    styles: &[GroupStyle],
    tracks: &[Track],
    zones: &[ZoneShape],
    buildings: bool,
    top: f64,
) {
    let col_w = MAP_WIDTH / 2.0 - 60.0;
    for (i, s) in styles.iter().enumerate() {
        let (x, y) = (95.0 + (i % 2) as f64 * col_w, top + (i / 2) as f64 * 26.0);
        let recorded = tracks.iter().filter(|t| t.group == s.name).count();
        let _ = write!(
            out,
            r#"<line x1="{x:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{}" stroke-width="4"/>"#,
            y - 5.0,
            x + 34.0,
            y - 5.0,
            s.colour
        );
        let label = format!(
            "{}: {} of {} ({}, operator {}, at most {:.0} ft AGL)",
            s.name,
            recorded,
            drones(s.count as usize),
            s.role,
            s.operator,
            ft(s.max_agl_m)
        );
        text(out, x + 44.0, y, 15.0, "start", "", &label);
    }
    let y = top + styles.len().div_ceil(2) as f64 * 26.0 + 6.0;
    let mut x = 95.0;
    let mut item = |out: &mut String, symbol: String, label: &str, width: f64| {
        out.push_str(&symbol.replace("{X}", &format!("{x:.1}")).replace("{CX}", &format!("{:.1}", x + 10.0)));
        text(out, x + 26.0, y, 15.0, "start", "", label);
        x += width;
    };
    let yc = y - 5.0;
    if !zones.is_empty() {
        item(
            out,
            format!(
                r#"<rect x="{{X}}" y="{:.1}" width="20" height="14" fill="{ZONE_FILL}" fill-opacity="0.28" stroke="{ZONE_STROKE}" stroke-width="2"/>"#,
                yc - 7.0
            ),
            "zone (SADE Zone)",
            210.0,
        );
    }
    item(
        out,
        format!(r##"<circle cx="{{CX}}" cy="{yc:.1}" r="6.5" fill="#ffffff" stroke="#444444" stroke-width="2"/>"##),
        "start",
        100.0,
    );
    item(
        out,
        format!(
            r##"<rect x="{{X}}" y="{:.1}" width="7" height="7" transform="translate(6.5 0)" fill="#444444" stroke="#000000" stroke-width="0.8"/>"##,
            yc - 3.5
        ),
        "end (in a circle: back at its start)",
        330.0,
    );
    item(
        out,
        format!(
            r##"<path d="M{{X}} {:.1}l12 12m0 -12l-12 12" transform="translate(4 0)" stroke="#000000" stroke-width="3"/>"##,
            yc - 6.0
        ),
        "crash",
        100.0,
    );
    item(
        out,
        format!(
            r##"<path d="M{{CX}} {:.1}l6.5 12h-13Z" fill="{VIOLATION_FILL}" stroke="#000000" stroke-width="1.2"/>"##,
            yc - 7.0
        ),
        "violation (where it started)",
        260.0,
    );
    if buildings {
        item(
            out,
            format!(r#"<rect x="{{X}}" y="{:.1}" width="20" height="14" fill="{BUILDING_FILL}"/>"#, yc - 7.0),
            "buildings",
            130.0,
        );
    }
}
