//! `report.html`: one self-contained page (inline CSS and SVG, no script, no external
//! URL) that opens offline and can be attached to a review: the verdict first, then the
//! map and the altitude timeline, the zones, every request with its verdict, leases,
//! violations, per-drone totals, GNSS in flight (when a receiver flew) and the run's
//! metadata.

use std::collections::BTreeMap;
use std::fmt::Write;

use super::data::RunData;
use super::model::{self, GroupStyle, ZoneShape, ft, m_ft, time_cell};
use super::svg::esc;
use crate::markup::{cell, header, num};

const CSS: &str = r#"
body { font-family: "DejaVu Sans", "Helvetica Neue", Arial, sans-serif; margin: 0 auto; max-width: 1640px; padding: 0 20px 40px; color: #222; }
h1 { font-size: 26px; margin: 22px 0 6px; }
h2 { font-size: 20px; margin: 30px 0 8px; border-bottom: 2px solid #ddd; padding-bottom: 4px; }
p.sub { margin: 0 0 12px; color: #555; }
.badge { display: inline-block; padding: 3px 12px; border-radius: 4px; color: #fff; font-weight: bold; margin-left: 10px; font-size: 18px; vertical-align: middle; }
.pass { background: #2a8a3a; } .fail { background: #c0262d; } .unknown { background: #888; }
table { border-collapse: collapse; margin: 8px 0 14px; font-size: 14px; }
th, td { border: 1px solid #ccc; padding: 4px 8px; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.bad td { background: #fdecea; } tr.good td { background: #f1f8f1; }
.swatch { display: inline-block; width: 12px; height: 12px; border-radius: 2px; margin-right: 6px; vertical-align: -1px; }
.note { background: #fff7d6; border: 1px solid #e8d68a; padding: 6px 10px; margin: 8px 0; }
figure { margin: 10px 0 20px; } figure svg { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { color: #444; font-size: 14px; margin-top: 4px; max-width: 1200px; }
ul.failures { margin: 4px 0 0 18px; padding: 0; }
"#;

fn swatch(styles: &[GroupStyle], group: &str) -> String {
    let colour = model::style_of(styles, group).map_or("#888888", |s| s.colour);
    format!(r#"<span class="swatch" style="background:{colour}"></span>{}"#, esc(group))
}

/// The inline form of a plot: the `xmlns` declaration is implied inside HTML, and leaving
/// it out keeps the page free of any URL.
fn inline_svg(svg: &str) -> String {
    svg.replacen(r#" xmlns="http://www.w3.org/2000/svg""#, "", 1)
}

/// The folder as `<run>/<UTC time>`: the page is the same wherever the folder is copied.
fn folder_label(data: &RunData) -> String {
    let parts: Vec<String> = data
        .dir
        .components()
        .rev()
        .take(2)
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    parts.join("/")
}

/// The plots of `svg.rs` the page shows.
#[derive(Clone, Copy, Debug)]
pub struct Figures<'a> {
    pub map: &'a str,
    pub altitude: &'a str,
    /// Runs with a GNSS constellation (`gnss.csv`): the timeline and the error map.
    pub gnss_timeline: Option<&'a str>,
    pub gnss_map: Option<&'a str>,
}

/// The page.
pub fn page(data: &RunData, styles: &[GroupStyle], zones: &[ZoneShape], figures: &Figures) -> String {
    let plan = &data.plan;
    let mut out = String::new();
    let _ = write!(
        out,
        r#"<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1"><title>Run report: {}</title><style>{CSS}</style></head><body>"#,
        esc(&plan.run.name)
    );
    let (badge, class) = match data.summary.as_ref().and_then(|s| s.verdict.as_ref()) {
        Some(v) if v.passed => ("PASSED", "pass"),
        Some(_) => ("FAILED", "fail"),
        None => ("NOT JUDGED", "unknown"),
    };
    let _ = write!(
        out,
        r#"<h1>Run report: {}<span id="verdict" class="badge {class}">{badge}</span></h1><p class="sub">Namespace {}, folder {}, {} in {}, {}.</p>"#,
        esc(&plan.run.name),
        esc(&plan.run.namespace),
        esc(&folder_label(data)),
        count(plan.drones.len(), "drone"),
        count(plan.spec.fleet.len(), "group"),
        count(plan.spec.zones.len(), "zone")
    );
    for n in &data.notes {
        let _ = write!(out, r#"<div class="note">{}</div>"#, esc(n));
    }
    criteria(&mut out, data);
    let _ = write!(
        out,
        r#"<h2 id="map">Flight paths</h2><figure>{}<figcaption>Every drone's path from trajectory.csv, metres east and north of the run's origin ({:.5}, {:.5}), coloured by group; zones filled pink. Left: the whole run; right: the area around the zones, where drones enter or turn away. Circles mark where a drone started, squares where it ended.</figcaption></figure>"#,
        inline_svg(figures.map),
        plan.spec.origin.latitude_deg,
        plan.spec.origin.longitude_deg
    );
    let _ = write!(
        out,
        r#"<h2 id="altitude">Altitude timeline</h2><figure>{}<figcaption>Height above ground of every drone against simulated time, one panel per group (metres left, feet right). Dashed grey: the group's altitude limit; solid pink: a zone's minimum (or maximum) altitude for lease holders; dashed pink: a zone's floor and ceiling (lines above a group's heights are listed beside its panel instead). Thick dark segments: the drone was inside a zone; yellow bands: violations.</figcaption></figure>"#,
        inline_svg(figures.altitude)
    );
    zones_table(&mut out, data, zones);
    requests(&mut out, data, styles);
    leases(&mut out, data);
    violations(&mut out, data, styles);
    drones(&mut out, data, styles);
    gnss(&mut out, data, styles, figures);
    metadata(&mut out, data);
    out.push_str("</body></html>\n");
    out
}

fn criteria(out: &mut String, data: &RunData) {
    out.push_str(r#"<h2 id="criteria">Criteria</h2>"#);
    let Some(verdict) = data.summary.as_ref().and_then(|s| s.verdict.as_ref()) else {
        out.push_str(r#"<p class="note">No verdict recorded: summary.json is missing or has no verdict (the run did not finish).</p>"#);
        return;
    };
    if verdict.criteria.is_empty() {
        out.push_str("<p>The scenario has no criteria: the run passes by definition.</p>");
        return;
    }
    out.push_str(r#"<table id="criteria-table">"#);
    header(out, &["", "criterion", "result", "what was checked", "failures"]);
    for c in &verdict.criteria {
        let _ = write!(out, r#"<tr class="{}">"#, if c.passed { "good" } else { "bad" });
        cell(out, &c.path);
        cell(out, &c.criterion);
        cell(out, if c.passed { "passed" } else { "FAILED" });
        cell(out, &c.summary);
        if c.failures.is_empty() {
            cell(out, "none");
        } else {
            out.push_str(r#"<td><ul class="failures">"#);
            for f in &c.failures {
                let _ = write!(out, "<li>{}</li>", esc(f));
            }
            out.push_str("</ul></td>");
        }
        out.push_str("</tr>");
    }
    out.push_str("</table>");
}

fn zones_table(out: &mut String, data: &RunData, zones: &[ZoneShape]) {
    out.push_str(r#"<h2 id="zones">Zones</h2>"#);
    if zones.is_empty() {
        out.push_str("<p>The scenario has no zones.</p>");
        return;
    }
    out.push_str("<table>");
    header(
        out,
        &[
            "zone",
            "vertices",
            "floor - ceiling",
            "active",
            "authorized operators",
            "lease altitude",
            "capacity",
            "lease duration",
            "stays inside",
        ],
    );
    for (z, spec) in zones.iter().zip(&data.plan.spec.zones) {
        out.push_str("<tr>");
        cell(out, &z.name);
        num(out, &z.ring_en_m.len().to_string());
        cell(out, &z.vertical_label());
        let from = spec.active_from.as_ref().map_or("start".to_string(), |d| format!("{d}"));
        let until = spec.active_until.as_ref().map_or("end".to_string(), |d| format!("{d}"));
        cell(out, &format!("{from} to {until}"));
        let ops = &spec.policy.authorized_operators;
        cell(out, &if ops.is_empty() { "nobody".to_string() } else { ops.join(", ") });
        let band = match (z.min_altitude_agl_m, z.max_altitude_agl_m) {
            (None, None) => "any".to_string(),
            (Some(a), None) => format!("at or above {}", m_ft(a)),
            (None, Some(b)) => format!("at or below {}", m_ft(b)),
            (Some(a), Some(b)) => format!("{} to {}", m_ft(a), m_ft(b)),
        };
        cell(out, &band);
        cell(out, &spec.policy.capacity.map_or("unlimited".to_string(), |c| c.to_string()));
        cell(out, &spec.policy.lease_duration.as_ref().map_or("default".to_string(), |d| format!("{d}")));
        let stays = data.airspace.as_ref().map(|a| a.compliance.presences.iter().filter(|p| p.zone == z.name).count());
        cell(out, &stays.map_or("not recorded".to_string(), |n| n.to_string()));
        out.push_str("</tr>");
    }
    out.push_str("</table>");
}

/// Requests of one group for one zone: total, granted, denied, the drones that asked.
type Tally = (usize, usize, usize, Vec<u32>);

fn requests(out: &mut String, data: &RunData, styles: &[GroupStyle]) {
    out.push_str(r#"<h2 id="requests">Zone requests and verdicts</h2>"#);
    let Some(a) = &data.airspace else {
        out.push_str(r#"<p class="note">airspace.json: not recorded.</p>"#);
        return;
    };
    let group_of = |drone: u32| data.plan.drones.get(drone as usize).map_or("?", |d| d.group.as_str());
    // Per group (in fleet order) and zone: requests, granted, denied, drones that asked.
    let mut by_group: BTreeMap<(usize, String, String), Tally> = BTreeMap::new();
    for r in &a.requests {
        let g = group_of(r.drone);
        let order = styles.iter().position(|s| s.name == g).unwrap_or(usize::MAX);
        let e = by_group.entry((order, g.to_string(), r.zone.clone())).or_default();
        e.0 += 1;
        if r.verdict == "granted" {
            e.1 += 1;
        } else {
            e.2 += 1;
        }
        if !e.3.contains(&r.drone) {
            e.3.push(r.drone);
        }
    }
    if a.requests.is_empty() {
        out.push_str("<p>No drone asked for a zone.</p>");
    } else {
        out.push_str(r#"<table id="requests-by-group">"#);
        header(out, &["group", "zone", "drones that asked", "requests", "granted", "denied"]);
        for ((_, g, zone), (n, granted, denied, asked)) in &by_group {
            let size = model::style_of(styles, g).map_or(0, |s| s.count);
            let _ = write!(out, "<tr><td>{}</td>", swatch(styles, g));
            cell(out, zone);
            num(out, &format!("{} of {size}", asked.len()));
            num(out, &n.to_string());
            num(out, &granted.to_string());
            num(out, &denied.to_string());
            out.push_str("</tr>");
        }
        out.push_str("</table>");
        out.push_str(r#"<table id="requests-table">"#);
        header(
            out,
            &["#", "time", "drone", "group", "operator", "zone", "band asked (AGL)", "verdict", "reason", "lease"],
        );
        for r in &a.requests {
            let granted = r.verdict == "granted";
            let _ =
                write!(out, r#"<tr class="request {}" data-request="{}">"#, if granted { "good" } else { "" }, r.id);
            num(out, &r.id.to_string());
            num(out, &time_cell(r.time_s));
            cell(out, &r.drone_name);
            let _ = write!(out, "<td>{}</td>", swatch(styles, group_of(r.drone)));
            cell(out, &r.operator);
            cell(out, &r.zone);
            cell(
                out,
                &format!(
                    "{:.0}-{:.0} m ({:.0}-{:.0} ft)",
                    r.altitude.min_agl_m,
                    r.altitude.max_agl_m,
                    ft(r.altitude.min_agl_m),
                    ft(r.altitude.max_agl_m)
                ),
            );
            cell(out, &r.verdict);
            cell(out, r.reason.map_or("", |x| x.as_str()));
            cell(out, r.lease.as_deref().unwrap_or(""));
            out.push_str("</tr>");
        }
        out.push_str("</table>");
    }
}

fn leases(out: &mut String, data: &RunData) {
    let Some(a) = &data.airspace else { return };
    out.push_str(r#"<h2 id="leases">Leases</h2>"#);
    if a.leases.is_empty() {
        out.push_str("<p>No lease was granted.</p>");
        return;
    }
    out.push_str("<table>");
    header(out, &["lease", "drone", "zone", "granted", "expires", "released", "altitude constraint (AGL)"]);
    for l in &a.leases {
        out.push_str("<tr>");
        cell(out, &l.id);
        cell(out, &l.drone_name);
        cell(out, &l.zone);
        num(out, &time_cell(l.granted_at_s));
        num(out, &time_cell(l.expires_at_s));
        num(out, &l.released_at_s.map_or("not released".to_string(), time_cell));
        let c = &l.constraints;
        let band = match (c.min_altitude_agl_m, c.max_altitude_agl_m) {
            (None, None) => "none".to_string(),
            (Some(a), None) => format!("at or above {}", m_ft(a)),
            (None, Some(b)) => format!("at or below {}", m_ft(b)),
            (Some(a), Some(b)) => format!("{} to {}", m_ft(a), m_ft(b)),
        };
        cell(out, &band);
        out.push_str("</tr>");
    }
    out.push_str("</table>");
}

fn violations(out: &mut String, data: &RunData, styles: &[GroupStyle]) {
    out.push_str(r#"<h2 id="violations">Violations</h2>"#);
    let Some(a) = &data.airspace else {
        out.push_str(r#"<p class="note">airspace.json: not recorded, so no compliance record.</p>"#);
        return;
    };
    let c = &a.compliance;
    let end_s = data.summary.as_ref().map(|s| s.sim_time_s);
    if c.violations.is_empty() {
        out.push_str(r#"<p id="no-violations">No violation: no drone was in a zone without a lease, broke a lease's altitude constraint or flew above its group's limit.</p>"#);
    } else {
        out.push_str(r#"<table id="violations-table">"#);
        header(
            out,
            &[
                "rule",
                "drone",
                "group",
                "zone",
                "from",
                "duration",
                "where it started",
                "height AGL there",
                "limit",
                "worst",
            ],
        );
        for v in &c.violations {
            let group = data.plan.drones.get(v.drone as usize).map_or("?", |d| d.group.as_str());
            let _ = write!(out, r#"<tr class="violation bad">"#);
            cell(out, v.kind.as_str());
            let other = v
                .other
                .and_then(|o| data.plan.drones.get(o as usize))
                .map(|d| format!(" and {}", d.name))
                .unwrap_or_default();
            cell(out, &format!("{}{other}", v.drone_name));
            let _ = write!(out, "<td>{}</td>", swatch(styles, group));
            cell(out, v.zone.as_deref().unwrap_or(""));
            num(out, &time_cell(v.start_s));
            let duration = match (v.end_s, end_s) {
                (Some(e), _) => format!("{:.2} s", e - v.start_s),
                (None, Some(end)) => format!("{:.2} s (until the end)", end - v.start_s),
                (None, None) => "still open".to_string(),
            };
            num(out, &duration);
            cell(
                out,
                &format!(
                    "{:.5} N {:.5} {} ({:.0} m E, {:.0} m N)",
                    v.at.latitude_deg,
                    v.at.longitude_deg.abs(),
                    if v.at.longitude_deg < 0.0 { "W" } else { "E" },
                    v.at.east_m,
                    v.at.north_m
                ),
            );
            num(out, &m_ft(v.at.height_agl_m));
            num(out, &v.limit_m.map_or(String::new(), m_ft));
            num(out, &format!("{:.1} m", v.worst_m));
            out.push_str("</tr>");
        }
        out.push_str("</table>");
    }
    if !c.crashes.is_empty() {
        out.push_str(r#"<table id="crashes">"#);
        header(out, &["crashed drone", "time", "where"]);
        for (k, (drone, t)) in c.crashes.iter().enumerate() {
            out.push_str(r#"<tr class="bad">"#);
            cell(out, data.plan.drones.get(*drone as usize).map_or("?", |d| d.name.as_str()));
            num(out, &time_cell(*t));
            let place = c.crash_places.get(k).map_or(String::new(), |p| {
                format!(
                    "{:.5}, {:.5} ({:.0} m E, {:.0} m N), {:.1} m AGL",
                    p.latitude_deg, p.longitude_deg, p.east_m, p.north_m, p.height_agl_m
                )
            });
            cell(out, &place);
            out.push_str("</tr>");
        }
        out.push_str("</table>");
    }
    if let Some((d, t, a, b)) = c.closest_approach {
        let name = |i: u32| data.plan.drones.get(i as usize).map_or("?".to_string(), |d| d.name.clone());
        let _ = write!(
            out,
            "<p>Closest approach between airborne drones: {d:.1} m, {} and {} at {}.</p>",
            esc(&name(a)),
            esc(&name(b)),
            esc(&time_cell(t))
        );
    }
}

fn drones(out: &mut String, data: &RunData, styles: &[GroupStyle]) {
    out.push_str(r#"<h2 id="drones">Drones</h2>"#);
    let Some(s) = &data.summary else {
        out.push_str(r#"<p class="note">summary.json: not recorded, so no per-drone totals.</p>"#);
        return;
    };
    let stays: BTreeMap<u32, usize> = data.airspace.as_ref().map_or_else(BTreeMap::new, |a| {
        let mut m = BTreeMap::new();
        for p in &a.compliance.presences {
            *m.entry(p.drone).or_insert(0) += 1;
        }
        m
    });
    // The wind met, in runs with wind: where the buildings sheltered a drone or a street
    // channelled the flow.
    let with_wind = s.per_drone.iter().any(|d| d.wind.is_some());
    let mut names = vec![
        "drone",
        "group",
        "took off",
        "landed",
        "crashed",
        "max height AGL",
        "distance flown",
        "waypoints",
        "failsafes",
        "battery left",
        "zone stays",
    ];
    if with_wind {
        names.push("wind met (mean / max)");
    }
    out.push_str(r#"<table id="drones-table">"#);
    header(out, &names);
    for d in &s.per_drone {
        let _ = write!(out, r#"<tr class="{}">"#, if d.crashed { "bad" } else { "" });
        cell(out, &d.name);
        let _ = write!(out, "<td>{}</td>", swatch(styles, &d.group));
        cell(out, if d.took_off { "yes" } else { "no" });
        cell(out, if d.landed { "yes" } else { "no" });
        cell(out, if d.crashed { "CRASHED" } else { "no" });
        num(out, &m_ft(d.max_height_agl_m));
        num(out, &format!("{:.2} km", d.distance_m / 1000.0));
        num(out, &d.waypoints_reached.to_string());
        num(out, &d.failsafes.to_string());
        num(out, &format!("{:.0} %", d.final_battery_remaining * 100.0));
        num(out, &stays.get(&d.index).copied().unwrap_or(0).to_string());
        if with_wind {
            match d.wind {
                Some(w) => num(out, &format!("{:.1} / {:.1} m/s", w.mean_mps, w.max_mps)),
                None => cell(out, "—"),
            }
        }
        out.push_str("</tr>");
    }
    out.push_str("</table>");
}

/// Per drone, what its GNSS receiver did in flight (`summary.json`'s `gnss`): shown when
/// some drone has it. Rows of the worst estimates first are the reviewer's question.
fn gnss(out: &mut String, data: &RunData, styles: &[GroupStyle], figures: &Figures) {
    let Some(s) = &data.summary else { return };
    let mut rows: Vec<_> = s.per_drone.iter().filter_map(|d| d.gnss.as_ref().map(|g| (d, g))).collect();
    if rows.is_empty() {
        return;
    }
    let worst = |g: &sadesim_crds::outcome::summary::GnssSummary| g.estimate_error_m.map_or(0.0, |e| e.max);
    rows.sort_by(|a, b| worst(b.1).total_cmp(&worst(a.1)).then(a.0.index.cmp(&b.0.index)));
    out.push_str(r#"<h2 id="gnss">GNSS in flight</h2><p class="sub">Each drone's receiver while airborne: satellites in its fixes, dilution of precision, the share of the satellites above the mask received only by a facade reflection (urban GNSS; blank for the statistical receiver), and the horizontal distance from the truth of its fixes and of the estimate the autopilot flew on (median / 95th percentile / largest). Worst estimate first. recording.mcap has every epoch (<code>/drones/&lt;name&gt;/gnss_quality</code>).</p><table id="gnss-table">"#);
    header(
        out,
        &[
            "drone",
            "group",
            "epochs",
            "without 3D fix",
            "satellites (mean)",
            "HDOP (median)",
            "reflected",
            "fix error",
            "estimate error",
        ],
    );
    let stats = |e: Option<sadesim_crds::outcome::summary::ErrorStats>| {
        e.map_or_else(|| "–".to_string(), |e| format!("{:.1} / {:.1} / {:.1} m", e.median, e.p95, e.max))
    };
    for (d, g) in rows {
        let _ = write!(out, r#"<tr class="{}">"#, if g.epochs_without_3d_fix > 0 { "bad" } else { "" });
        cell(out, &d.name);
        let _ = write!(out, "<td>{}</td>", swatch(styles, &d.group));
        num(out, &g.epochs.to_string());
        num(out, &g.epochs_without_3d_fix.to_string());
        num(out, &format!("{:.1}", g.mean_satellites));
        num(out, &g.median_hdop.map_or_else(|| "–".to_string(), |h| format!("{h:.2}")));
        num(out, &g.reflected_share.map_or_else(String::new, |r| format!("{:.1} %", r * 100.0)));
        num(out, &stats(g.fix_error_m));
        num(out, &stats(g.estimate_error_m));
        out.push_str("</tr>");
    }
    out.push_str("</table>");
    if let Some(svg) = figures.gnss_timeline {
        let _ = write!(
            out,
            r#"<figure>{}<figcaption>Per group, once a second in flight (gnss.csv): the satellites in each drone's fix, its HDOP (drawn at most at 10) and its estimate error, the horizontal distance between the position the autopilot flew on and the truth. A street canyon shows as fewer satellites, a higher HDOP and a larger error at the same moments.</figcaption></figure>"#,
            inline_svg(svg)
        );
    }
    if let Some(svg) = figures.gnss_map {
        let _ = write!(
            out,
            r#"<figure>{}<figcaption>Where the estimate was off: every track in grey over the buildings, a dot a second in flight coloured by the estimate error there (the legend gives each class's share of the flight's seconds).</figcaption></figure>"#,
            inline_svg(svg)
        );
    }
}

fn metadata(out: &mut String, data: &RunData) {
    let plan = &data.plan;
    let spec = &plan.spec;
    out.push_str(r#"<h2 id="metadata">Run metadata</h2><table id="metadata-table">"#);
    let mut row = |k: &str, v: String| {
        let _ = write!(out, "<tr><th>{}</th><td>{}</td></tr>", esc(k), esc(&v));
    };
    row("run", format!("{} (namespace {})", plan.run.name, plan.run.namespace));
    row("folder", folder_label(data));
    let o = &spec.origin;
    row("origin", format!("{:.6}, {:.6}, {:.1} m MSL", o.latitude_deg, o.longitude_deg, o.altitude_msl_m));
    row("seed", plan.seed.to_string());
    row("planned duration", time_cell(plan.duration_s));
    let c = spec.clock();
    let clock_text = serde_json::to_value(c.mode).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default();
    row(
        "clock",
        match c.factor {
            Some(f) => format!("{clock_text} x{f}"),
            None => clock_text,
        },
    );
    row("physics", format!("{} Hz, {} steps per sync window", plan.physics_rate_hz, plan.sync_window_steps));
    row("drones and shards", format!("{} drones in {} shards", plan.drones.len(), plan.shards.len()));
    let groups: Vec<String> = spec
        .fleet
        .iter()
        .map(|g| {
            format!(
                "{} x{} {} ({}, max {:.0} ft AGL)",
                g.name,
                g.count,
                g.airframe,
                g.operator,
                ft(g.altitude.max_agl_m)
            )
        })
        .collect();
    row("groups", groups.join("; "));
    match (&data.world, spec.world().osm.as_ref()) {
        (Some(w), Some(extract)) => {
            let osm = w.osm.clone().unwrap_or_default();
            row(
                "world",
                format!(
                    "OpenStreetMap extract {}: {:.0} m half-width, {} buildings (median {:.0} m, tallest {:.0} m; heights {} tagged, {} from building:levels, {} defaulted), {} open areas",
                    extract.file,
                    w.extent_m,
                    w.building_count,
                    w.median_height_m,
                    w.max_height_m,
                    osm.heights_tagged,
                    osm.heights_from_levels,
                    osm.heights_defaulted,
                    w.park_count
                ),
            )
        }
        (Some(w), None) => row(
            "world",
            format!(
                "{:.0} m half-width, {} buildings (median {:.0} m, tallest {:.0} m), {} parks, seed {}",
                w.extent_m, w.building_count, w.median_height_m, w.max_height_m, w.park_count, w.seed
            ),
        ),
        (None, _) => row("world", "not recorded".into()),
    }
    if let Some(w) = &spec.environment().wind {
        row("wind", format!("{:.1} m/s from {:.0} deg", w.speed_mps, w.direction_from_deg));
    }
    match &data.summary {
        Some(s) => {
            row("end", format!("{} at {}", s.end_reason, time_cell(s.sim_time_s)));
            row("wall time", format!("{:.1} s (real-time factor {:.2})", s.wall_time_s, s.real_time_factor));
            let c = s.recording_cpu_s;
            row(
                "recording CPU",
                format!("{:.2} s recording.mcap, {:.2} s ULogs, {:.2} s other files", c.mcap, c.ulog, c.other),
            );
            row("pilots released", s.pilots_released_at_s.map_or("never".to_string(), time_cell));
            row("events", s.events.to_string());
            row("at the end", format!("{} airborne, {} crashed", s.airborne, s.crashed));
        }
        None => row("end", "not recorded (no summary.json)".into()),
    }
    if let Some(p) = &spec.pilot {
        row("pilot command", p.command.join(" "));
        row("pilot", data.pilot.as_ref().map_or("not recorded (no pilot.json)".to_string(), |r| r.describe()));
    }
    let tracks = data.tracks.as_ref().map_or("not recorded".to_string(), |t| {
        let samples: usize = t.iter().map(|t| t.samples.len()).sum();
        format!("{} drones, {samples} samples", t.len())
    });
    row("trajectory", tracks);
    row(
        "report generated",
        format!(
            "by sadesim {} from the files of this folder; `sadesim report FOLDER` rebuilds it",
            env!("CARGO_PKG_VERSION")
        ),
    );
    out.push_str("</table>");
}

/// "1 zone", "3 zones".
fn count(n: usize, what: &str) -> String {
    if n == 1 { format!("1 {what}") } else { format!("{n} {what}s") }
}
