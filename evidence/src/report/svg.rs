//! The report's plots as SVG text: the trajectory map (the paper's Fig. 4A: every drone's
//! path coloured by group, the zones drawn over the city) and the altitude timeline (Fig.
//! 4G: height above ground against sim time, one panel per group, with the zones' and
//! the groups' altitude limits).
//!
//! Pure functions of the run's data: no I/O, the same input gives the same bytes. Text
//! uses the font family `DejaVu Sans` (embedded for the PNGs, see `png.rs`). Map
//! coordinates are metres east and north of the run's origin (`spec.origin`), the frame
//! of `trajectory.csv`; screen y grows downwards, so north is flipped.

use std::fmt::Write;

use super::data::{RunData, Sample, Track};
use super::model::{self, GroupStyle, M_PER_FT, ZoneShape, ft};
use sadesim_crds::zones::AltitudeReference;

/// Font of every text element.
pub const FONT: &str = "DejaVu Sans";
/// Fill of a zone (the paper's translucent pink), its outline and its label.
const ZONE_FILL: &str = "#ff4fa3";
const ZONE_STROKE: &str = "#b0125f";
/// Violations: a marker where one started on the map, a band over its time on the timeline.
const VIOLATION_FILL: &str = "#ffd400";
/// Building footprints under the tracks.
const BUILDING_FILL: &str = "#e2e2e2";

/// An axis-aligned building footprint, metres east/north of the origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    pub east_min_m: f64,
    pub north_min_m: f64,
    pub east_max_m: f64,
    pub north_max_m: f64,
}

/// XML text and attribute escape.
pub fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `<text>` with a white halo so it stays readable over tracks.
fn text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, extra: &str, content: &str) {
    let _ = write!(
        out,
        r#"<text x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="{anchor}" {extra}>{}</text>"#,
        esc(content)
    );
}

fn halo_text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, extra: &str, content: &str) {
    let attrs = format!(r##"stroke="#ffffff" stroke-width="4" stroke-linejoin="round" paint-order="stroke" {extra}"##);
    text(out, x, y, size, anchor, &attrs, content);
}

fn open_svg(out: &mut String, id: &str, width: f64, height: f64, title: &str) {
    let _ = write!(
        out,
        r##"<svg xmlns="http://www.w3.org/2000/svg" id="{id}" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="{FONT}" fill="#222222"><title>{}</title><rect width="100%" height="100%" fill="#ffffff"/>"##,
        esc(title)
    );
}

/// Maps metres east/north to pixels, with the same scale on both axes.
#[derive(Clone, Copy, Debug)]
struct MapView {
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
    fn fit(area: [f64; 4], bounds: [f64; 4], pad: f64) -> Self {
        let [x, y, w, h] = area;
        let (mut w_m, mut h_m) = ((bounds[2] - bounds[0]).max(1.0), (bounds[3] - bounds[1]).max(1.0));
        w_m *= 1.0 + 2.0 * pad;
        h_m *= 1.0 + 2.0 * pad;
        let scale = (w / w_m).min(h / h_m);
        let (ce, cn) = ((bounds[0] + bounds[2]) / 2.0, (bounds[1] + bounds[3]) / 2.0);
        Self { x, y, w, h, east_min: ce - w / scale / 2.0, north_max: cn + h / scale / 2.0, scale }
    }

    fn px(&self, e: f64, n: f64) -> (f64, f64) {
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

/// SVG path data through `points` (already in pixels), dropping points closer than
/// `min_px` to the last one kept (the last point is always kept).
pub(super) fn path_data(points: impl Iterator<Item = (f64, f64)>, min_px: f64) -> String {
    let mut d = String::new();
    let mut last: Option<(f64, f64)> = None;
    let mut pending: Option<(f64, f64)> = None;
    for p in points {
        match last {
            None => {
                let _ = write!(d, "M{:.1} {:.1}", p.0, p.1);
                last = Some(p);
            }
            Some(l) if (p.0 - l.0).abs() >= min_px || (p.1 - l.1).abs() >= min_px => {
                let _ = write!(d, "L{:.1} {:.1}", p.0, p.1);
                last = Some(p);
                pending = None;
            }
            Some(_) => pending = Some(p),
        }
    }
    if let Some(p) = pending {
        let _ = write!(d, "L{:.1} {:.1}", p.0, p.1);
    }
    d
}

/// Bounds of everything the full map must show: tracks, zones.
fn data_bounds(tracks: &[Track], zones: &[ZoneShape]) -> Option<[f64; 4]> {
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
    text(
        &mut out,
        MAP_WIDTH / 2.0,
        34.0,
        24.0,
        "middle",
        r#"font-weight="bold""#,
        &format!("Flight paths of run {run}: {} by group, zones in pink", drones(tracks.len())),
    );
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
    // Buildings, then zones, then tracks: the paths stay visible over everything.
    if !buildings.is_empty() {
        let _ = write!(out, r#"<g fill="{BUILDING_FILL}">"#);
        for b in buildings.iter().filter(|b| v.sees(b)) {
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
    out.push_str("</g>");
    let _ = write!(
        out,
        r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="#444444" stroke-width="1.2"/>"##,
        v.x, v.y, v.w, v.h
    );
    // Tick labels and axis titles.
    for e in &east_ticks {
        let (x, _) = v.px(*e, 0.0);
        text(out, x, v.y + v.h + 20.0, 13.0, "middle", "", &model::tick_label(*e));
    }
    for n in &north_ticks {
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

/// Geometry of the altitude timeline.
const ALT_WIDTH: f64 = 1600.0;
const ALT_LEFT: f64 = 95.0;
const ALT_PLOT_W: f64 = 1010.0;
const ALT_PANEL_H: f64 = 250.0;
const ALT_GAP: f64 = 92.0;
const ALT_TOP: f64 = 84.0;

/// A horizontal reference line of an altitude panel.
struct RefLine {
    agl_m: f64,
    /// Always within the panel's range (the group's own limits, the zones it entered).
    always: bool,
    colour: &'static str,
    dash: &'static str,
    label: String,
}

/// The altitude timeline: one panel per group, height above ground (metres left, feet
/// right) against sim time, with the group's altitude limit and each zone's floor,
/// ceiling and lease constraints; drones' stays inside a zone drawn thick.
pub fn altitude(data: &RunData, styles: &[GroupStyle], zones: &[ZoneShape]) -> String {
    let tracks = data.tracks.as_deref().unwrap_or_default();
    let run = &data.plan.run.name;
    let panels = styles.len().max(1);
    let height = ALT_TOP + panels as f64 * (ALT_PANEL_H + ALT_GAP) + 10.0;
    let mut out = String::new();
    open_svg(&mut out, "altitude", ALT_WIDTH, height, &format!("Altitude timeline of {run}"));
    text(
        &mut out,
        ALT_WIDTH / 2.0,
        34.0,
        24.0,
        "middle",
        r#"font-weight="bold""#,
        &format!("Height above ground of run {run}, by group (thick: inside a zone)"),
    );
    let end_s = data
        .summary
        .as_ref()
        .map(|s| s.sim_time_s)
        .filter(|t| *t > 0.0)
        .or_else(|| tracks.iter().filter_map(|t| t.samples.last()).map(|s| s.time_s).reduce(f64::max))
        .unwrap_or(data.plan.duration_s)
        .max(1.0);
    if tracks.is_empty() {
        text(&mut out, ALT_WIDTH / 2.0, ALT_TOP + 100.0, 20.0, "middle", "", "No trajectory recorded");
    }
    let released = data.summary.as_ref().and_then(|s| s.pilots_released_at_s);
    for (i, style) in styles.iter().enumerate() {
        let top = ALT_TOP + i as f64 * (ALT_PANEL_H + ALT_GAP);
        altitude_panel(&mut out, data, style, zones, tracks, top, end_s, released);
    }
    out.push_str("</svg>");
    out
}

#[allow(clippy::too_many_arguments)]
fn altitude_panel(
    out: &mut String,
    data: &RunData,
    style: &GroupStyle,
    zones: &[ZoneShape],
    tracks: &[Track],
    top: f64,
    end_s: f64,
    released: Option<f64>,
) {
    let group_tracks: Vec<&Track> = tracks.iter().filter(|t| t.group == style.name).collect();
    let presences: Vec<_> = data
        .airspace
        .as_ref()
        .map(|a| a.compliance.presences.iter().filter(|p| group_tracks.iter().any(|t| t.drone == p.drone)).collect())
        .unwrap_or_default();
    // Reference lines: the group's limits, then each zone's (heights AGL; an MSL height is
    // shown relative to the origin's ground).
    let origin_msl = data.plan.spec.origin.altitude_msl_m;
    let as_agl = |h: f64, r: AltitudeReference| match r {
        AltitudeReference::Agl => h,
        AltitudeReference::Msl => h - origin_msl,
    };
    let mut lines = vec![RefLine {
        agl_m: style.max_agl_m,
        always: true,
        colour: "#444444",
        dash: "10 5",
        label: format!("{} limit {:.0} ft ({:.1} m)", style.name, ft(style.max_agl_m), style.max_agl_m),
    }];
    if let Some(min) = style.min_agl_m {
        lines.push(RefLine {
            agl_m: min,
            always: true,
            colour: "#444444",
            dash: "3 4",
            label: format!("{} cruise minimum {:.0} ft", style.name, ft(min)),
        });
    }
    for z in zones {
        let visited = presences.iter().any(|p| p.zone == z.name);
        if let Some(min) = z.min_altitude_agl_m {
            lines.push(RefLine {
                agl_m: min,
                always: visited,
                colour: ZONE_STROKE,
                dash: "",
                label: format!("{} lease minimum {:.0} ft ({:.1} m)", z.name, ft(min), min),
            });
        }
        if let Some(max) = z.max_altitude_agl_m {
            lines.push(RefLine {
                agl_m: max,
                always: visited,
                colour: ZONE_STROKE,
                dash: "",
                label: format!("{} lease maximum {:.0} ft", z.name, ft(max)),
            });
        }
        let floor = as_agl(z.floor.height_m, z.floor.reference);
        if floor > 0.0 {
            lines.push(RefLine {
                agl_m: floor,
                always: visited,
                colour: ZONE_STROKE,
                dash: "6 4",
                label: format!("{} floor {:.0} ft", z.name, ft(floor)),
            });
        }
        let ceiling = as_agl(z.ceiling.height_m, z.ceiling.reference);
        lines.push(RefLine {
            agl_m: ceiling,
            always: visited,
            colour: ZONE_STROKE,
            dash: "6 4",
            label: format!("{} ceiling {:.0} ft", z.name, ft(ceiling)),
        });
    }
    // The panel spans the group's heights and its own limits, and the lines of the zones
    // it entered; the lines of other zones are drawn only when they fall inside (else the
    // legend says they are above), so a low-flying group is not squashed.
    let data_max = group_tracks.iter().flat_map(|t| &t.samples).map(|s| s.height_agl_m).fold(0.0, f64::max);
    let lines_max = lines.iter().filter(|l| l.always).map(|l| l.agl_m).fold(0.0, f64::max);
    let y_max = (data_max.max(lines_max) * 1.1).max(10.0);
    let (lines, above): (Vec<RefLine>, Vec<RefLine>) = lines.into_iter().partition(|l| l.agl_m <= y_max);
    let y_min = group_tracks.iter().flat_map(|t| &t.samples).map(|s| s.height_agl_m).fold(0.0, f64::min).min(0.0);
    let (x0, w, h) = (ALT_LEFT, ALT_PLOT_W, ALT_PANEL_H);
    let tx = |t: f64| x0 + t / end_s * w;
    let ty = |m: f64| top + (y_max - m) / (y_max - y_min) * h;
    let id = format!("alt-{}", esc(&style.name));
    let _ = write!(
        out,
        r##"<g id="{id}"><clipPath id="clip-{id}"><rect x="{x0:.1}" y="{top:.1}" width="{w:.1}" height="{h:.1}"/></clipPath><rect x="{x0:.1}" y="{top:.1}" width="{w:.1}" height="{h:.1}" fill="#fbfbf8"/>"##
    );
    text(
        out,
        x0,
        top - 12.0,
        17.0,
        "start",
        &format!(r#"font-weight="bold" fill="{}""#, style.colour),
        &format!("{}: {} ({}, operator {})", style.name, drones(group_tracks.len()), style.role, style.operator),
    );
    // Grid: metres on the left, feet on the right.
    let m_ticks = model::ticks(y_min, y_max, 6);
    let ft_ticks = model::ticks(ft(y_min), ft(y_max), 7);
    let t_ticks = model::time_ticks(end_s, 10);
    out.push_str(r##"<g stroke="#dddddd" stroke-width="1">"##);
    for m in &m_ticks {
        let _ = write!(out, r#"<line x1="{x0:.1}" y1="{0:.1}" x2="{1:.1}" y2="{0:.1}"/>"#, ty(*m), x0 + w);
    }
    for t in &t_ticks {
        let _ = write!(out, r#"<line x1="{0:.1}" y1="{top:.1}" x2="{0:.1}" y2="{1:.1}"/>"#, tx(*t), top + h);
    }
    out.push_str("</g>");
    let _ = write!(out, r#"<g clip-path="url(#clip-{id})">"#);
    if let Some(r) = released {
        let x = tx(r);
        let _ = write!(
            out,
            r##"<line x1="{x:.1}" y1="{top:.1}" x2="{x:.1}" y2="{:.1}" stroke="#777777" stroke-width="1.2" stroke-dasharray="2 3"/>"##,
            top + h
        );
        text(out, x + 4.0, top + 14.0, 12.0, "start", r##"fill="#555555""##, "pilots released");
    }
    // Violations of the group's drones: a red band over their duration.
    if let Some(a) = &data.airspace {
        for v in a.compliance.violations.iter().filter(|v| group_tracks.iter().any(|t| t.drone == v.drone)) {
            let (xa, xb) = (tx(v.start_s), tx(v.end_s.unwrap_or(end_s)));
            let _ = write!(
                out,
                r##"<rect class="violation" x="{xa:.1}" y="{top:.1}" width="{:.1}" height="{h:.1}" fill="{VIOLATION_FILL}" fill-opacity="0.3"><title>{} {}</title></rect>"##,
                (xb - xa).max(2.0),
                esc(&v.drone_name),
                v.kind.as_str()
            );
        }
    }
    // One line per drone, shades of the group's colour; thick where inside a zone.
    for (k, t) in group_tracks.iter().enumerate() {
        let opacity = 0.55 + 0.4 * ((k % 4) as f64 / 3.0);
        let d = path_data(t.samples.iter().map(|s| (tx(s.time_s), ty(s.height_agl_m))), 0.7);
        let _ = write!(
            out,
            r#"<path class="altitude" data-drone="{}" d="{d}" fill="none" stroke="{}" stroke-width="1.3" stroke-opacity="{opacity:.2}" stroke-linejoin="round"><title>{}</title></path>"#,
            t.drone,
            style.colour,
            esc(&t.name)
        );
        for p in presences.iter().filter(|p| p.drone == t.drone) {
            let until = p.exited_s.unwrap_or(end_s);
            let inside = t.samples.iter().filter(|s| s.time_s >= p.entered_s && s.time_s <= until);
            let d = path_data(inside.map(|s| (tx(s.time_s), ty(s.height_agl_m))), 0.7);
            if !d.is_empty() {
                let _ = write!(
                    out,
                    r#"<path class="inside" d="{d}" fill="none" stroke="{}" stroke-width="4" stroke-linecap="round"><title>{} inside {}</title></path>"#,
                    darker(style.colour),
                    esc(&t.name),
                    esc(&p.zone)
                );
            }
        }
    }
    for l in &lines {
        let y = ty(l.agl_m);
        let dash = if l.dash.is_empty() { String::new() } else { format!(r#" stroke-dasharray="{}""#, l.dash) };
        let _ = write!(
            out,
            r#"<line class="limit" x1="{x0:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="{}" stroke-width="2"{dash}/>"#,
            x0 + w,
            l.colour
        );
    }
    out.push_str("</g>");
    let _ = write!(
        out,
        r##"<rect x="{x0:.1}" y="{top:.1}" width="{w:.1}" height="{h:.1}" fill="none" stroke="#444444" stroke-width="1.2"/>"##
    );
    for m in &m_ticks {
        text(out, x0 - 8.0, ty(*m) + 4.5, 13.0, "end", "", &model::tick_label(*m));
    }
    for f in &ft_ticks {
        let y = ty(f * M_PER_FT);
        let _ = write!(
            out,
            r##"<line x1="{0:.1}" y1="{y:.1}" x2="{1:.1}" y2="{y:.1}" stroke="#444444"/>"##,
            x0 + w,
            x0 + w + 5.0
        );
        text(out, x0 + w + 8.0, y + 4.5, 13.0, "start", "", &model::tick_label(*f));
    }
    for t in &t_ticks {
        text(out, tx(*t), top + h + 18.0, 13.0, "middle", "", &model::clock(*t));
    }
    text(out, x0 + w / 2.0, top + h + 40.0, 14.0, "middle", "", "simulated time since the start (min:s)");
    let (cx, cy) = (x0 - 58.0, top + h / 2.0);
    text(out, cx, cy, 14.0, "middle", &format!(r#"transform="rotate(-90 {cx:.1} {cy:.1})""#), "metres AGL");
    let (cx, cy) = (x0 + w + 62.0, top + h / 2.0);
    text(out, cx, cy, 14.0, "middle", &format!(r#"transform="rotate(90 {cx:.1} {cy:.1})""#), "feet AGL");
    // Legend right of the panel: the lines drawn, and what is above the panel.
    let lx = x0 + w + 90.0;
    let mut ly = top + 12.0;
    for l in &lines {
        let dash = if l.dash.is_empty() { String::new() } else { format!(r#" stroke-dasharray="{}""#, l.dash) };
        let _ = write!(
            out,
            r#"<line x1="{lx:.1}" y1="{0:.1}" x2="{1:.1}" y2="{0:.1}" stroke="{2}" stroke-width="2"{dash}/>"#,
            ly - 5.0,
            lx + 30.0,
            l.colour
        );
        text(out, lx + 38.0, ly, 13.0, "start", "", &l.label);
        ly += 22.0;
    }
    let _ = write!(
        out,
        r#"<line x1="{lx:.1}" y1="{0:.1}" x2="{1:.1}" y2="{0:.1}" stroke="{2}" stroke-width="1.3"/>"#,
        ly - 5.0,
        lx + 30.0,
        style.colour
    );
    text(out, lx + 38.0, ly, 13.0, "start", "", "one line per drone");
    ly += 22.0;
    let _ = write!(
        out,
        r#"<line x1="{lx:.1}" y1="{0:.1}" x2="{1:.1}" y2="{0:.1}" stroke="{2}" stroke-width="4"/>"#,
        ly - 5.0,
        lx + 30.0,
        darker(style.colour)
    );
    let inside = if presences.is_empty() {
        "inside a zone (never)".to_string()
    } else {
        format!("inside a zone ({} stays)", presences.len())
    };
    text(out, lx + 38.0, ly, 13.0, "start", "", &inside);
    ly += 22.0;
    let violations = data.airspace.as_ref().map_or(0, |a| {
        a.compliance.violations.iter().filter(|v| group_tracks.iter().any(|t| t.drone == v.drone)).count()
    });
    if violations > 0 {
        let _ = write!(
            out,
            r#"<rect x="{lx:.1}" y="{:.1}" width="30" height="14" fill="{VIOLATION_FILL}" fill-opacity="0.3"/>"#,
            ly - 12.0
        );
        text(out, lx + 38.0, ly, 13.0, "start", "", &format!("a violation lasts ({violations})"));
        ly += 22.0;
    }
    for z in zones.iter().filter(|z| !presences.iter().any(|p| p.zone == z.name)) {
        text(out, lx, ly, 13.0, "start", r##"fill="#666666""##, &format!("{} not entered", z.name));
        ly += 20.0;
    }
    for l in &above {
        text(
            out,
            lx,
            ly,
            13.0,
            "start",
            r##"fill="#666666""##,
            &format!("{} (above this panel)", l.label.split(" (").next().unwrap_or(&l.label)),
        );
        ly += 20.0;
    }
    let _ = ly;
    out.push_str("</g>");
}

/// "1 drone", "5 drones".
fn drones(n: usize) -> String {
    if n == 1 { "1 drone".into() } else { format!("{n} drones") }
}

/// `#rrggbb` at 60 % brightness: the thick "inside a zone" segments stand out from the
/// group's thin lines.
fn darker(colour: &str) -> String {
    let c = u32::from_str_radix(colour.trim_start_matches('#'), 16).unwrap_or(0x555555);
    let ch = |shift: u32| ((((c >> shift) & 0xff) as f64) * 0.6).round() as u32;
    format!("#{:02x}{:02x}{:02x}", ch(16), ch(8), ch(0))
}
