//! The GNSS error map: every drone's path in grey over the buildings, and a dot a second
//! in flight (a `gnss.csv` row) coloured by the estimate error there, so the streets where
//! the fix went bad stand out. Metres east and north of the run's origin, as the flight map.

use std::fmt::Write;

use super::draw::{esc, open_svg, path_data, text, title};
use super::map::{Footprint, MapView, close_panel, data_bounds, draw_buildings, open_panel};
use crate::report::data::{GnssSample, RunData, Track};

const WIDTH: f64 = 1600.0;
const TOP: f64 = 92.0;
const PANEL_W: f64 = 1200.0;
const PANEL_H: f64 = 760.0;
/// Dots drawn at most: beyond this a drone's rows are thinned by a common stride (a
/// thousand drones over ten minutes would be 600 000 circles, more than a browser draws
/// comfortably). The CSV keeps every row.
const MAX_DOTS: usize = 20_000;

/// Error classes, metres: `[from, to)` and the colour (green to dark red, distinct in
/// grey scale and for the common colour-vision deficiencies).
const CLASSES: [(f64, f64, &str); 6] = [
    (0.0, 1.0, "#1a9850"),
    (1.0, 2.0, "#91cf60"),
    (2.0, 5.0, "#fee08b"),
    (5.0, 10.0, "#fc8d59"),
    (10.0, 20.0, "#d73027"),
    (20.0, f64::INFINITY, "#67001f"),
];

/// The class index of an error in metres.
fn class_of(error_m: f64) -> usize {
    CLASSES.iter().position(|(from, to, _)| error_m >= *from && error_m < *to).unwrap_or(CLASSES.len() - 1)
}

fn class_label(k: usize) -> String {
    match CLASSES[k] {
        (from, to, _) if to.is_infinite() => format!("≥ {from} m"),
        (0.0, to, _) => format!("< {to} m"),
        (from, to, _) => format!("{from}–{to} m"),
    }
}

/// Where `drone` was at `time_s`: the track sample nearest in time (the trajectory is
/// sampled at least as often as `gnss.csv`).
fn position_at(tracks: &[Track], drone: u32, time_s: f64) -> Option<(f64, f64)> {
    let samples = &tracks.iter().find(|t| t.drone == drone)?.samples;
    let i = samples.partition_point(|s| s.time_s < time_s);
    let nearest = [i.checked_sub(1), Some(i)]
        .into_iter()
        .flatten()
        .filter_map(|k| samples.get(k))
        .min_by(|a, b| (a.time_s - time_s).abs().total_cmp(&(b.time_s - time_s).abs()))?;
    Some((nearest.east_m, nearest.north_m))
}

/// The map; `None` without `gnss.csv` or without trajectories.
pub fn gnss_map(data: &RunData, buildings: &[Footprint]) -> Option<String> {
    let samples = data.gnss.as_deref()?;
    let tracks = data.tracks.as_deref().filter(|t| !t.is_empty())?;
    let bounds = data_bounds(tracks, &[])?;
    let run = &data.plan.run.name;
    let height = TOP + PANEL_H + 110.0;
    let mut out = String::new();
    open_svg(&mut out, "gnss-map", WIDTH, height, &format!("GNSS error map of {run}"));
    title(&mut out, WIDTH, &format!("Estimate error along the tracks of run {run}"));
    let v = MapView::fit([(WIDTH - PANEL_W) / 2.0, TOP, PANEL_W, PANEL_H], bounds, 0.04);
    let ticks = open_panel(&mut out, "gnss", "Horizontal distance of the estimate from the truth, once a second", &v);
    draw_buildings(&mut out, &v, buildings);
    for t in tracks {
        let d = path_data(t.samples.iter().map(|s| v.px(s.east_m, s.north_m)), 0.8);
        let _ = write!(out, r##"<path d="{d}" fill="none" stroke="#8a8a8a" stroke-width="1"/>"##);
    }
    let with_error: Vec<(&GnssSample, f64)> =
        samples.iter().filter_map(|s| s.estimate_error_m.map(|e| (s, e))).collect();
    let stride = with_error.len().div_ceil(MAX_DOTS).max(1);
    let mut dots: Vec<(usize, f64, f64, &GnssSample, f64)> = Vec::new();
    let mut counts = [0usize; CLASSES.len()];
    for (k, (s, error_m)) in with_error.into_iter().enumerate() {
        counts[class_of(error_m)] += 1;
        if k % stride != 0 {
            continue;
        }
        if let Some((e, n)) = position_at(tracks, s.drone, s.time_s) {
            let (x, y) = v.px(e, n);
            dots.push((class_of(error_m), x, y, s, error_m));
        }
    }
    // Worse errors on top: a bad street is not hidden under good dots of another pass.
    dots.sort_by(|a, b| a.0.cmp(&b.0).then(a.4.total_cmp(&b.4)));
    for (class, x, y, s, error_m) in dots {
        let name = data.plan.drones.get(s.drone as usize).map_or("?", |d| d.name.as_str());
        let _ = write!(
            out,
            r##"<circle class="gnss-error" data-drone="{}" data-error-m="{error_m:.2}" cx="{x:.1}" cy="{y:.1}" r="4" fill="{}" stroke="#333333" stroke-width="0.4"><title>{} at {:.0} s: {error_m:.1} m</title></circle>"##,
            s.drone,
            CLASSES[class].2,
            esc(name),
            s.time_s
        );
    }
    close_panel(&mut out, &v, &ticks);
    // Legend: the classes with how many seconds of flight fell in each.
    let total: usize = counts.iter().sum();
    let y = TOP + PANEL_H + 90.0;
    let mut x = 95.0;
    text(&mut out, x, y, 15.0, "start", r#"font-weight="bold""#, "estimate error:");
    x += 150.0;
    for (k, count) in counts.iter().enumerate() {
        let _ = write!(
            out,
            r##"<circle cx="{:.1}" cy="{:.1}" r="6" fill="{}" stroke="#333333" stroke-width="0.6"/>"##,
            x + 6.0,
            y - 5.0,
            CLASSES[k].2
        );
        let share = if total == 0 { 0.0 } else { *count as f64 / total as f64 * 100.0 };
        text(&mut out, x + 18.0, y, 15.0, "start", "", &format!("{} ({share:.0} %)", class_label(k)));
        x += 200.0;
    }
    if stride > 1 {
        text(&mut out, WIDTH - 40.0, y + 22.0, 13.0, "end", "", &format!("every {stride}th second drawn"));
    }
    out.push_str("</svg>");
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::data::Sample;

    #[test]
    fn errors_fall_in_their_class_and_labels_read_as_ranges() {
        assert_eq!([0.2, 1.0, 4.9, 5.0, 19.9, 250.0].map(class_of), [0, 1, 2, 3, 4, 5]);
        assert_eq!(class_label(0), "< 1 m");
        assert_eq!(class_label(2), "2–5 m");
        assert_eq!(class_label(5), "≥ 20 m");
    }

    #[test]
    fn a_row_sits_at_the_track_sample_nearest_its_time() {
        let at = |t: f64, e: f64| Sample {
            time_s: t,
            east_m: e,
            north_m: -e,
            up_m: 10.0,
            height_agl_m: 10.0,
            on_ground: false,
            crashed: false,
        };
        let tracks = vec![Track {
            drone: 3,
            name: "a".into(),
            group: "g".into(),
            samples: vec![at(0.0, 0.0), at(0.5, 5.0), at(1.0, 10.0)],
        }];
        assert_eq!(position_at(&tracks, 3, 0.7), Some((5.0, -5.0)));
        assert_eq!(position_at(&tracks, 3, 0.8), Some((10.0, -10.0)));
        assert_eq!(position_at(&tracks, 3, 9.0), Some((10.0, -10.0)));
        assert_eq!(position_at(&tracks, 4, 0.5), None);
    }
}
