//! Shared SVG primitives of the report's plots: the font and colours, XML escaping, text,
//! the `<svg>` opening, path data and label wording.

use std::fmt::Write;

/// Fill of a zone (the paper's translucent pink), its outline and its label.
pub(super) const ZONE_FILL: &str = "#ff4fa3";
pub(super) const ZONE_STROKE: &str = "#b0125f";
/// Violations: a marker where one started on the map, a band over its time on the timeline.
pub(super) const VIOLATION_FILL: &str = "#ffd400";

pub use crate::markup::{FONT, esc};

/// `<text>` with a white halo so it stays readable over tracks.
pub(super) fn text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, extra: &str, content: &str) {
    let _ = write!(
        out,
        r#"<text x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="{anchor}" {extra}>{}</text>"#,
        esc(content)
    );
}

/// A plot's title: bold, centred over a plot `width` pixels wide.
pub(super) fn title(out: &mut String, width: f64, content: &str) {
    text(out, width / 2.0, 34.0, 24.0, "middle", r#"font-weight="bold""#, content);
}

pub(super) fn halo_text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, extra: &str, content: &str) {
    let attrs = format!(r##"stroke="#ffffff" stroke-width="4" stroke-linejoin="round" paint-order="stroke" {extra}"##);
    text(out, x, y, size, anchor, &attrs, content);
}

pub(super) fn open_svg(out: &mut String, id: &str, width: f64, height: f64, title: &str) {
    let _ = write!(
        out,
        r##"<svg xmlns="http://www.w3.org/2000/svg" id="{id}" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="{FONT}" fill="#222222"><title>{}</title><rect width="100%" height="100%" fill="#ffffff"/>"##,
        esc(title)
    );
}

/// SVG path data through `points` (already in pixels), dropping points closer than
/// `min_px` to the last one kept (the last point is always kept).
pub(in crate::report) fn path_data(points: impl Iterator<Item = (f64, f64)>, min_px: f64) -> String {
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

/// "1 drone", "5 drones".
pub(super) fn drones(n: usize) -> String {
    if n == 1 { "1 drone".into() } else { format!("{n} drones") }
}
