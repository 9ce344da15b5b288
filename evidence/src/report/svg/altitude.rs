//! The altitude timeline (the paper's Fig. 4G): height above ground against sim time, one
//! panel per group, with the zones' and the groups' altitude limits.

use std::fmt::Write;

use sadesim_crds::zones::AltitudeReference;

use super::draw::{VIOLATION_FILL, ZONE_STROKE, drones, esc, open_svg, path_data, text, title};
use crate::report::data::{RunData, Track};
use crate::report::model::{self, GroupStyle, M_PER_FT, ZoneShape, ft};

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
    title(&mut out, ALT_WIDTH, &format!("Height above ground of run {run}, by group (thick: inside a zone)"));
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

/// One legend row at (`lx`, `*ly`): a 30 px line in `colour`, `width` wide (`extra`: more
/// attributes), and its label; `*ly` moves to the next row.
fn legend_line(out: &mut String, lx: f64, ly: &mut f64, colour: &str, width: &str, extra: &str, label: &str) {
    let _ = write!(
        out,
        r#"<line x1="{lx:.1}" y1="{0:.1}" x2="{1:.1}" y2="{0:.1}" stroke="{colour}" stroke-width="{width}"{extra}/>"#,
        *ly - 5.0,
        lx + 30.0,
    );
    text(out, lx + 38.0, *ly, 13.0, "start", "", label);
    *ly += 22.0;
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
        let floor = as_agl(z.floor.height_m, z.floor.reference);
        let ceiling = as_agl(z.ceiling.height_m, z.ceiling.reference);
        // (height, dash, label): the lease band (solid), the floor when above ground and the
        // ceiling (dashed).
        let zone_lines = [
            z.min_altitude_agl_m.map(|m| (m, "", format!("{} lease minimum {:.0} ft ({:.1} m)", z.name, ft(m), m))),
            z.max_altitude_agl_m.map(|m| (m, "", format!("{} lease maximum {:.0} ft", z.name, ft(m)))),
            Some(floor).filter(|&f| f > 0.0).map(|f| (f, "6 4", format!("{} floor {:.0} ft", z.name, ft(f)))),
            Some((ceiling, "6 4", format!("{} ceiling {:.0} ft", z.name, ft(ceiling)))),
        ];
        lines.extend(zone_lines.into_iter().flatten().map(|(agl_m, dash, label)| RefLine {
            agl_m,
            always: visited,
            colour: ZONE_STROKE,
            dash,
            label,
        }));
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
        legend_line(out, lx, &mut ly, l.colour, "2", &dash, &l.label);
    }
    legend_line(out, lx, &mut ly, style.colour, "1.3", "", "one line per drone");
    let inside = if presences.is_empty() {
        "inside a zone (never)".to_string()
    } else {
        format!("inside a zone ({} stays)", presences.len())
    };
    legend_line(out, lx, &mut ly, &darker(style.colour), "4", "", &inside);
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

/// `#rrggbb` at 60 % brightness: the thick "inside a zone" segments stand out from the
/// group's thin lines.
fn darker(colour: &str) -> String {
    let c = u32::from_str_radix(colour.trim_start_matches('#'), 16).unwrap_or(0x555555);
    let ch = |shift: u32| ((((c >> shift) & 0xff) as f64) * 0.6).round() as u32;
    format!("#{:02x}{:02x}{:02x}", ch(16), ch(8), ch(0))
}
