//! A picture of a run's world before anyone flies it (`sadesim assets show`): the world
//! square seen from above with the ground tinted by elevation, open spaces, every building
//! coloured by its height, the zones in pink with their names, each group's homes as dots
//! in the group's colour, the origin, a scale bar and a legend. Metres east and north of
//! the run's origin, north up.
//!
//! Built from the same [`World`] the shards fly in (loaded from the asset bundle or built)
//! and the [`RunPlan`] (homes, zones), so what it shows is what the run will meet.

use std::fmt::Write;

use sadesim_crds::plan::RunPlan;
use sadesim_world::{Footprint, World};

use super::model::{self, GroupStyle, ZoneShape};
use super::svg::{FONT, esc};

/// Canvas and map square, pixels.
const WIDTH: f64 = 1400.0;
const MAP: f64 = 1200.0;
const MAP_LEFT: f64 = 100.0;
const MAP_TOP: f64 = 110.0;
/// Ground tint cells per side.
const GROUND_CELLS: usize = 60;

/// Building height bands (roof above its base, metres) and their fills, low to high.
const HEIGHT_BANDS: [(f64, &str); 6] = [
    (10.0, "#c9d6e3"),
    (20.0, "#9fb7cf"),
    (40.0, "#6f93b8"),
    (80.0, "#46709c"),
    (150.0, "#2a4f7a"),
    (f64::INFINITY, "#142c4a"),
];
const OPEN_FILL: &str = "#bfe3a8";
const ZONE_FILL: &str = "#ff4fa3";
const ZONE_STROKE: &str = "#b0125f";

/// The fill of a building `height_m` tall.
fn height_fill(height_m: f64) -> &'static str {
    HEIGHT_BANDS.iter().find(|(top, _)| height_m < *top).map_or(HEIGHT_BANDS[5].1, |(_, fill)| fill)
}

/// Metres east/north -> pixels: the world square fills the map square, north up.
#[derive(Clone, Copy)]
struct View {
    extent_m: f64,
    scale: f64,
}

impl View {
    fn px(self, e: f64, n: f64) -> (f64, f64) {
        (MAP_LEFT + (e + self.extent_m) * self.scale, MAP_TOP + (self.extent_m - n) * self.scale)
    }
}

/// SVG path data of a footprint's rings (even-odd: holes stay open).
fn rings_path(v: View, f: &Footprint) -> String {
    let mut d = String::new();
    for ring in f.rings() {
        for (k, [e, n]) in ring.iter().enumerate() {
            let (x, y) = v.px(*e, *n);
            let _ = write!(d, "{}{x:.1},{y:.1}", if k == 0 { "M" } else { "L" });
        }
        d.push('Z');
    }
    d
}

fn text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, content: &str) {
    let _ = write!(
        out,
        r##"<text x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="{anchor}" stroke="#ffffff" stroke-width="3" paint-order="stroke">{}</text>"##,
        esc(content)
    );
}

/// A "nice" scale bar length for a map `span_m` wide: 1, 2 or 5 x 10^k, about a fifth.
fn scale_bar_m(span_m: f64) -> f64 {
    let target = span_m / 5.0;
    let p = 10f64.powf(target.log10().floor());
    [5.0, 2.0, 1.0].into_iter().map(|k| k * p).find(|&m| m <= target).unwrap_or(p)
}

/// The preview of `world` for `plan` as SVG.
pub fn svg(world: &World, plan: &RunPlan) -> String {
    let extent = world.extent_m().max(1.0);
    let v = View { extent_m: extent, scale: MAP / (2.0 * extent) };
    let styles = model::group_styles(plan);
    let zones = model::zone_shapes(plan);
    let legend_rows = 3 + styles.len().div_ceil(3);
    let height = MAP_TOP + MAP + 60.0 + legend_rows as f64 * 28.0;
    let mut out = String::new();
    let _ = write!(
        out,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH:.0}" height="{height:.0}" viewBox="0 0 {WIDTH:.0} {height:.0}" font-family="{FONT}" fill="#222222"><rect width="100%" height="100%" fill="#ffffff"/>"##
    );
    let stats = world.stats();
    let source = match &stats.osm {
        Some(osm) => format!(
            "OpenStreetMap: {} buildings ({} heights tagged, {} from levels, {} defaulted), {} open spaces",
            world.buildings().len(),
            osm.heights_tagged,
            osm.heights_from_levels,
            osm.heights_defaulted,
            world.open_spaces().len()
        ),
        None => format!("procedural city: {} buildings, {} parks", world.buildings().len(), stats.park_count),
    };
    let _ = write!(
        out,
        r#"<text x="{:.0}" y="40" font-size="26" font-weight="bold" text-anchor="middle">World of run {}: {:.0} m x {:.0} m</text>"#,
        WIDTH / 2.0,
        esc(&plan.run.name),
        2.0 * extent,
        2.0 * extent
    );
    let ground = format!(
        "ground {:.1} to {:.1} m from the origin's {:.1} m MSL",
        stats.ground_min_up_m, stats.ground_max_up_m, plan.spec.origin.altitude_msl_m
    );
    text(&mut out, WIDTH / 2.0, 74.0, 16.0, "middle", &format!("{source}; {ground}"));
    let _ = write!(
        out,
        r#"<clipPath id="map"><rect x="{MAP_LEFT}" y="{MAP_TOP}" width="{MAP}" height="{MAP}"/></clipPath><g clip-path="url(#map)">"#
    );
    ground_tint(&mut out, world, v);
    open_spaces(&mut out, world, plan, v);
    buildings(&mut out, world, v);
    zones_drawn(&mut out, &zones, v);
    routes(&mut out, plan, &styles, v);
    homes(&mut out, plan, &styles, v);
    out.push_str("</g>");
    let _ = write!(
        out,
        r##"<rect x="{MAP_LEFT}" y="{MAP_TOP}" width="{MAP}" height="{MAP}" fill="none" stroke="#555555"/>"##
    );
    // The origin and a scale bar.
    let (ox, oy) = v.px(0.0, 0.0);
    let _ = write!(
        out,
        r##"<path class="origin" d="M{:.1},{oy:.1}H{:.1}M{ox:.1},{:.1}V{:.1}" stroke="#000000" stroke-width="2"/>"##,
        ox - 10.0,
        ox + 10.0,
        oy - 10.0,
        oy + 10.0
    );
    text(&mut out, ox + 8.0, oy - 8.0, 14.0, "start", "origin");
    let bar_m = scale_bar_m(2.0 * extent);
    let (bx, by) = (MAP_LEFT + 20.0, MAP_TOP + MAP - 24.0);
    let _ =
        write!(out, r##"<rect x="{bx:.1}" y="{by:.1}" width="{:.1}" height="6" fill="#000000"/>"##, bar_m * v.scale);
    text(&mut out, bx, by - 8.0, 14.0, "start", &format!("{bar_m:.0} m"));
    text(&mut out, MAP_LEFT + MAP - 20.0, MAP_TOP + 30.0, 18.0, "end", "N ↑");
    legend(&mut out, &styles, MAP_TOP + MAP + 40.0);
    out.push_str("</svg>");
    out
}

/// The ground as cells tinted from light (lowest) to brown (highest); one flat tint when
/// the ground varies by less than half a metre.
fn ground_tint(out: &mut String, world: &World, v: View) {
    let stats = world.stats();
    let (lo, hi) = (stats.ground_min_up_m, stats.ground_max_up_m);
    let extent = world.extent_m();
    if hi - lo < 0.5 {
        let (x, y) = v.px(-extent, extent);
        let _ = write!(out, r##"<rect x="{x:.1}" y="{y:.1}" width="{MAP}" height="{MAP}" fill="#f4f1e8"/>"##);
        return;
    }
    let cell_m = 2.0 * extent / GROUND_CELLS as f64;
    for j in 0..GROUND_CELLS {
        for i in 0..GROUND_CELLS {
            let (e, n) = (-extent + i as f64 * cell_m, extent - j as f64 * cell_m);
            let t = ((world.ground_up_m(e + cell_m / 2.0, n - cell_m / 2.0) - lo) / (hi - lo)).clamp(0.0, 1.0);
            // #f4f1e8 (low) to #b08a5a (high).
            let mix = |a: f64, b: f64| (a + (b - a) * t).round() as u8;
            let (x, y) = v.px(e, n);
            let size = cell_m * v.scale + 0.5;
            let _ = write!(
                out,
                r##"<rect x="{x:.1}" y="{y:.1}" width="{size:.1}" height="{size:.1}" fill="#{:02x}{:02x}{:02x}"/>"##,
                mix(244.0, 176.0),
                mix(241.0, 138.0),
                mix(232.0, 90.0)
            );
        }
    }
}

/// Mapped open spaces (polygons, named ones labelled) and the scenario's open areas
/// (`world.openAreas` discs).
fn open_spaces(out: &mut String, world: &World, plan: &RunPlan, v: View) {
    let _ = write!(out, r#"<g class="open-spaces" fill="{OPEN_FILL}" fill-rule="evenodd">"#);
    for space in world.open_spaces() {
        let _ = write!(out, r#"<path d="{}"/>"#, rings_path(v, &space.footprint));
    }
    let frame = sadesim_crds::geo::LocalFrame::new(plan.spec.origin.geo());
    for area in &plan.spec.world().open_areas {
        let (e, n) = frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
        let (x, y) = v.px(e, n);
        let _ =
            write!(out, r#"<circle cx="{x:.1}" cy="{y:.1}" r="{:.1}" fill-opacity="0.7"/>"#, area.radius_m * v.scale);
    }
    out.push_str("</g>");
    for space in world.open_spaces().iter().filter(|s| s.footprint.area_m2() > 5_000.0) {
        if let Some(name) = &space.name {
            let [e, n] = space.footprint.bounds_center();
            let (x, y) = v.px(e, n);
            text(out, x, y, 12.0, "middle", name);
        }
    }
}

/// Every building, filled by its height band.
fn buildings(out: &mut String, world: &World, v: View) {
    for (_, fill) in HEIGHT_BANDS {
        let _ = write!(out, r#"<g class="buildings" fill="{fill}" fill-rule="evenodd">"#);
        for b in world.buildings().iter().filter(|b| height_fill(b.height_m()) == fill) {
            let _ = write!(out, r#"<path d="{}"/>"#, rings_path(v, b.footprint()));
        }
        out.push_str("</g>");
    }
}

fn zones_drawn(out: &mut String, zones: &[ZoneShape], v: View) {
    for z in zones {
        let mut d = String::new();
        for (k, [e, n]) in z.ring_en_m.iter().enumerate() {
            let (x, y) = v.px(*e, *n);
            let _ = write!(d, "{}{x:.1},{y:.1}", if k == 0 { "M" } else { "L" });
        }
        let _ = write!(
            out,
            r#"<path class="zone" d="{d}Z" fill="{ZONE_FILL}" fill-opacity="0.35" stroke="{ZONE_STROKE}" stroke-width="2"/>"#
        );
        let b = z.bounds();
        let (x, y) = v.px((b[0] + b[2]) / 2.0, b[3]);
        text(out, x, y - 6.0, 15.0, "middle", &format!("{} ({})", z.name, z.vertical_label()));
    }
}

/// Each scripted group's route: from its first drone's home through its mission's
/// waypoints, dashed, in the group's colour (random recreational waypoints are not drawn).
fn routes(out: &mut String, plan: &RunPlan, styles: &[GroupStyle], v: View) {
    use sadesim_crds::fleet::MissionItem;
    let frame = sadesim_crds::geo::LocalFrame::new(plan.spec.origin.geo());
    for group in &plan.spec.fleet {
        let Some(mission) = &group.mission else { continue };
        let Some(first) = plan.drones.iter().find(|d| d.group == group.name) else { continue };
        let mut d = String::new();
        let (x, y) = v.px(first.home.local.east_m, first.home.local.north_m);
        let _ = write!(d, "M{x:.1},{y:.1}");
        for item in &mission.items {
            if let MissionItem::Waypoint { latitude_deg, longitude_deg, .. } = item {
                let (e, n) = frame.to_plane(*latitude_deg, *longitude_deg);
                let (x, y) = v.px(e, n);
                let _ = write!(d, "L{x:.1},{y:.1}");
            }
        }
        let colour = model::style_of(styles, &group.name).map_or("#555555", |s| s.colour);
        let _ = write!(
            out,
            r#"<path class="route" d="{d}" fill="none" stroke="{colour}" stroke-width="2.5" stroke-dasharray="8 5"/>"#
        );
    }
}

fn homes(out: &mut String, plan: &RunPlan, styles: &[GroupStyle], v: View) {
    for d in &plan.drones {
        let colour = model::style_of(styles, &d.group).map_or("#555555", |s| s.colour);
        let (x, y) = v.px(d.home.local.east_m, d.home.local.north_m);
        let _ =
            write!(out, r##"<circle class="home" cx="{x:.1}" cy="{y:.1}" r="4" fill="{colour}" stroke="#ffffff"/>"##);
    }
}

fn legend(out: &mut String, styles: &[GroupStyle], top: f64) {
    let mut x = MAP_LEFT;
    let swatch = |out: &mut String, x: f64, y: f64, fill: &str| {
        let _ = write!(
            out,
            r##"<rect x="{x:.1}" y="{:.1}" width="18" height="14" fill="{fill}" stroke="#777777"/>"##,
            y - 12.0
        );
    };
    text(out, x, top, 15.0, "start", "Building height:");
    x += 130.0;
    let mut low = 0.0;
    for (top_m, fill) in HEIGHT_BANDS {
        swatch(out, x, top, fill);
        let label = if top_m.is_finite() { format!("{low:.0}-{top_m:.0} m") } else { format!("{low:.0} m +") };
        text(out, x + 24.0, top, 14.0, "start", &label);
        x += 110.0;
        low = top_m;
    }
    let row = top + 28.0;
    swatch(out, MAP_LEFT, row, OPEN_FILL);
    text(out, MAP_LEFT + 24.0, row, 14.0, "start", "open space");
    let _ = write!(
        out,
        r#"<rect x="{:.1}" y="{:.1}" width="18" height="14" fill="{ZONE_FILL}" fill-opacity="0.35" stroke="{ZONE_STROKE}"/>"#,
        MAP_LEFT + 160.0,
        row - 12.0
    );
    text(out, MAP_LEFT + 184.0, row, 14.0, "start", "zone (floor-ceiling)");
    let _ = write!(
        out,
        r##"<path class="legend" d="M{:.1},{:.1}h24" stroke="#555555" stroke-width="2.5" stroke-dasharray="8 5"/>"##,
        MAP_LEFT + 400.0,
        row - 5.0
    );
    text(out, MAP_LEFT + 432.0, row, 14.0, "start", "scripted route (waypoints)");
    for (k, s) in styles.iter().enumerate() {
        let (col, line) = (k % 3, k / 3);
        let (x, y) = (MAP_LEFT + col as f64 * 400.0, row + 28.0 * (line + 1) as f64);
        let _ = write!(
            out,
            r##"<circle cx="{:.1}" cy="{:.1}" r="6" fill="{}" stroke="#ffffff"/>"##,
            x + 9.0,
            y - 5.0,
            s.colour
        );
        text(out, x + 24.0, y, 14.0, "start", &format!("{}: {} homes ({})", s.name, s.count, s.role));
    }
}

/// The preview as PNG.
///
/// # Errors
/// When the picture cannot be rasterised (a bug of the SVG, not of the world).
pub fn png(world: &World, plan: &RunPlan) -> Result<Vec<u8>, String> {
    super::png::render(&svg(world, plan))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_world::WorldInputs;

    fn planned() -> (World, RunPlan) {
        use sadesim_crds::fixtures::{RunBuilder, near_homes, zone};
        let run = RunBuilder::test()
            .with(|r| {
                let at = near_homes(r.spec.origin.geo());
                r.spec.zones.push(zone(
                    "museum",
                    vec![at(200.0, 0.0), at(300.0, 0.0), at(300.0, 80.0), at(200.0, 80.0)],
                    120.0,
                ));
            })
            .build();
        let plan = sadesim_planner::plan(&run).expect("plans");
        (World::generate(&WorldInputs::from_spec(&plan.spec, &[])), plan)
    }

    #[test]
    fn every_building_zone_and_home_is_drawn_and_the_png_decodes() {
        let (world, plan) = planned();
        let svg = svg(&world, &plan);
        // One path per building (in the height bands' groups), one per zone.
        let paths = svg.matches("<path d=\"M").count();
        assert_eq!(paths, world.buildings().len());
        assert_eq!(svg.matches(r#"<path class="zone""#).count(), plan.spec.zones.len());
        let routes = svg.matches(r#"class="route""#).count();
        assert_eq!(routes, plan.spec.fleet.iter().filter(|g| g.mission.is_some()).count());
        let homes = svg.matches(r#"class="home""#).count();
        assert_eq!(homes, plan.drones.len());
        assert!(svg.contains("museum ("), "the zone is labelled");
        let png = png(&world, &plan).expect("renders");
        assert_eq!(&png[1..4], b"PNG");
        let width = u32::from_be_bytes(png[16..20].try_into().unwrap());
        assert_eq!(width, WIDTH as u32);
    }

    #[test]
    fn heights_fall_in_their_bands_and_scale_bars_are_round() {
        assert_eq!(height_fill(5.0), HEIGHT_BANDS[0].1);
        assert_eq!(height_fill(25.0), HEIGHT_BANDS[2].1);
        assert_eq!(height_fill(500.0), HEIGHT_BANDS[5].1);
        assert_eq!(scale_bar_m(4000.0), 500.0);
        assert_eq!(scale_bar_m(900.0), 100.0);
        assert_eq!(scale_bar_m(12_000.0), 2000.0);
    }
}
