//! The report of a real (short, scripted) run: self-contained, complete, readable as PNG,
//! and strict about malformed files.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, OnceLock};

use resvg::tiny_skia;
use sadesim_crds::criteria::Criterion;
use sadesim_crds::fixtures::{HOMES, RunBuilder, near_homes, zone};
use sadesim_crds::fleet::{Area, HomePlacement, Mission, MissionItem, Role};
use sadesim_crds::run::{Clock, ClockMode};

use sadesim_evidence::report::*;
use sadesim_sources::assets::find_world;

use crate::runner::{RunOptions, run_local};

/// Two groups: `intruders` (2 drones, public safety) fly 300 m north straight through zone
/// `wall` without a lease; `bystander` (1 drone, journalist) takes off and lands.
fn scenario() -> sadesim_crds::SimulationRun {
    RunBuilder::test()
        .with(|r| {
            r.spec.duration = "60s".parse().unwrap();
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            let at = near_homes(r.spec.origin.geo());
            let target = at(0.0, 300.0);
            let mut intruders = r.spec.fleet[0].clone();
            intruders.name = "intruders".into();
            intruders.count = 2;
            intruders.role = Role::PublicSafety;
            intruders.homes = HomePlacement::RandomInArea(Area { name: None, center: HOMES, radius_m: 30.0 });
            intruders.mission = Some(Mission {
                items: vec![
                    MissionItem::Takeoff { altitude_agl_m: 20.0 },
                    MissionItem::Waypoint {
                        latitude_deg: target.latitude_deg,
                        longitude_deg: target.longitude_deg,
                        altitude_agl_m: 25.0,
                        hold_s: None,
                    },
                    MissionItem::Land {},
                ],
                speed_mps: Some(10.0),
            });
            let mut bystander = r.spec.fleet[0].clone();
            bystander.name = "bystander".into();
            bystander.count = 1;
            bystander.role = Role::Journalist;
            bystander.homes = HomePlacement::RandomInArea(Area { name: None, center: HOMES, radius_m: 30.0 });
            r.spec.fleet = vec![intruders, bystander];
            let polygon = vec![at(-150.0, 120.0), at(150.0, 120.0), at(150.0, 220.0), at(-150.0, 220.0)];
            let mut wall = zone("wall", polygon, 100.0);
            wall.policy.authorized_operators = vec!["nobody".into()];
            wall.policy.min_altitude_agl_m = Some(60.0);
            r.spec.zones = vec![wall];
            r.spec.criteria = vec![Criterion::NoUnauthorizedEntries {}, Criterion::NoCrashes {}];
        })
        .build()
}

/// The run folder of [`scenario`], flown once per test binary by the local runner (which
/// writes the report itself).
fn run_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = std::env::temp_dir().join(format!("sadesim-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let options = RunOptions { out_root: Some(root), mavlink: false, ..RunOptions::default() };
        let report = run_local(&scenario(), &options, Arc::new(AtomicBool::new(false))).expect("the fixture run");
        assert_eq!(report.report_error, None, "the runner's report failed");
        report.out_dir
    })
}

/// A private copy of the fixture run folder, to change files in.
fn copy_of_run(name: &str) -> PathBuf {
    let dst = std::env::temp_dir().join(format!("sadesim-report-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dst);
    std::fs::create_dir_all(&dst).unwrap();
    for entry in std::fs::read_dir(run_dir()).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_file() {
            std::fs::copy(entry.path(), dst.join(entry.file_name())).unwrap();
        }
    }
    dst
}

fn read(dir: &Path, file: &str) -> String {
    std::fs::read_to_string(dir.join(file)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(file).display()))
}

/// The `<g id="panel-full">` part of the map (the whole-run panel).
fn full_panel(map: &str) -> &str {
    let start = map.find(r#"<g id="panel-full">"#).expect("a whole-run panel");
    let end = map[start..].find(r#"<g id="panel-zoom">"#).map_or(map.len(), |k| start + k);
    &map[start..end]
}

#[test]
fn the_runner_writes_a_self_contained_report_with_every_drone_zone_and_verdict() {
    let dir = run_dir();
    let html = read(dir, HTML_FILE);
    for file in ["report/map.svg", "report/altitude.svg", "report/map.png", "report/altitude.png"] {
        assert!(dir.join(file).is_file(), "{file} missing");
    }
    // Listed in the manifest: the report was written before it.
    let manifest = read(dir, "manifest.json");
    assert!(manifest.contains("report.html") && manifest.contains("report/map.png"), "{manifest}");
    // Self-contained: no URL at all (no external script, style, font or image).
    assert!(!html.contains("http://") && !html.contains("https://"), "a URL in the page");
    assert!(!html.contains("<script") && !html.contains("<link") && !html.contains("src="), "an external resource");
    // One track per drone on the whole-run map, coloured by its group.
    let panel = full_panel(&html);
    for drone in 0..3 {
        assert_eq!(panel.matches(&format!(r#"class="track" data-drone="{drone}""#)).count(), 1, "drone {drone}");
    }
    assert_eq!(panel.matches(r#"class="track""#).count(), 3);
    for (drone, colour) in [(0, "#d62728"), (1, "#d62728"), (2, "#1f77b4")] {
        let track = &panel[panel.find(&format!(r#"class="track" data-drone="{drone}""#)).unwrap()..];
        let track = &track[..track.find("</path>").unwrap()];
        assert!(track.contains(&format!(r#"stroke="{colour}""#)), "drone {drone} not in {colour}");
    }
    // What the recordings cost this run, from summary.json.
    let summary: sim_worker::record::RunSummary = serde_json::from_str(&read(dir, "summary.json")).unwrap();
    let c = summary.recording_cpu_s;
    assert!(c.mcap > 0.0, "{c:?}");
    assert!(html.contains(&format!("{:.2} s recording.mcap, {:.2} s ULogs", c.mcap, c.ulog)), "recording CPU row");
    // What each shard's thread spent stepping its drones, by shard.
    assert_eq!(summary.shard_cpu_s.len(), summary.shards as usize, "{:?}", summary.shard_cpu_s);
    assert!(summary.shard_cpu_s.iter().all(|&s| s > 0.0), "{:?}", summary.shard_cpu_s);
    // The zone polygon on both panels, named.
    assert_eq!(html.matches(r#"class="zone" data-zone="wall""#).count(), 2);
    assert!(html.contains("wall (0-328 ft AGL)"), "zone label");
    // The intruders flew through the zone: a failed verdict with the criterion and the
    // violations listed by drone.
    assert!(html.contains(r#"<span id="verdict" class="badge fail">FAILED</span>"#));
    assert!(html.contains("noUnauthorizedEntries"));
    let violations = &html[html.find(r#"id="violations-table""#).expect("violations table")..];
    let violations = &violations[..violations.find("</table>").unwrap()];
    assert!(violations.contains("intruders-0") && violations.contains("intruders-1"), "{violations}");
    assert!(violations.contains("unauthorizedEntry"));
    assert!(!violations.contains("bystander-0"));
    // The altitude timeline: one panel per group with the zone's lease minimum.
    assert!(html.contains(r#"id="alt-intruders""#) && html.contains(r#"id="alt-bystander""#));
    assert!(html.contains("wall lease minimum 197 ft"));
    // The standalone SVGs are the inline ones plus their namespace.
    let map = read(dir, "report/map.svg");
    assert!(map.starts_with(r#"<svg xmlns="http://www.w3.org/2000/svg" id="map""#));
}

#[test]
fn gnss_rows_give_a_timeline_of_three_series_and_a_map_of_the_estimate_error() {
    use std::fmt::Write;
    // The fixture flew without a constellation: no GNSS plots.
    assert!(!run_dir().join("report/gnss-map.svg").exists() && !read(run_dir(), HTML_FILE).contains("gnss-timeline"));
    // Its copy with gnss.csv rows as a canyon run writes them: drone 0's estimate is 12 m off
    // from 21 s, the others stay at 0.5 m.
    let dir = copy_of_run("gnss");
    let mut csv = String::from("time_s,drone,fix_type,satellites,hdop,fix_error_m,estimate_error_m\n");
    for t in 1..=30 {
        for d in 0..3 {
            let error = if d == 0 && t > 20 { 12.0 } else { 0.5 };
            writeln!(csv, "{t}.000,{d},3,{},0.90,{error:.2},{error:.2}", 20 - d).unwrap();
        }
    }
    std::fs::write(dir.join("gnss.csv"), csv).unwrap();
    let files = write_report(&dir, find_world).unwrap();
    for file in ["gnss-timeline.svg", "gnss-timeline.png", "gnss-map.svg", "gnss-map.png"] {
        assert!(files.images.contains(&dir.join("report").join(file)), "{file} not written");
    }
    let html = read(&dir, HTML_FILE);
    let timeline = html.split(r#"id="gnss-timeline""#).nth(1).expect("a GNSS timeline").split("</svg>").next().unwrap();
    for series in ["satellites", "hdop", "estimate_error"] {
        assert_eq!(timeline.matches(&format!(r#"data-series="{series}""#)).count(), 3, "{series}");
    }
    // A dot per row with an estimate, coloured by its class; the 12 m ones (10-20 m, red)
    // are drawn last, over the rest.
    let map = read(&dir, "report/gnss-map.svg");
    assert!(html.contains(r#"id="gnss-map""#));
    let dots: Vec<&str> = map.split(r#"<circle class="gnss-error""#).skip(1).collect();
    assert_eq!(dots.len(), 90);
    let red: Vec<bool> = dots.iter().map(|d| d.contains(r##"fill="#d73027""##)).collect();
    assert_eq!(red.iter().filter(|r| **r).count(), 10);
    assert!(red[80..].iter().all(|r| *r), "the worst errors are on top");
    assert!(dots[89].contains(r#"data-drone="0" data-error-m="12.00""#));
    assert!(map.contains("10–20 m (11 %)") && map.contains("&lt; 1 m (89 %)"), "the legend's shares");
}

/// Width and height from a PNG's IHDR chunk, after checking the signature.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |k: usize| u32::from_be_bytes(bytes[k..k + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn png_plots_decode_and_show_the_tracks_and_the_zone() {
    let dir = run_dir();
    for (file, svg) in [("map", "report/map.svg"), ("altitude", "report/altitude.svg")] {
        let bytes = std::fs::read(dir.join(format!("report/{file}.png"))).unwrap();
        let (w, h) = png_size(&bytes);
        let svg = read(dir, svg);
        let declared = |attr: &str| -> u32 {
            let k = svg.find(&format!(r#" {attr}=""#)).unwrap() + attr.len() + 3;
            svg[k..].split('"').next().unwrap().parse().unwrap()
        };
        assert_eq!((w, h), (declared("width"), declared("height")), "{file}");
        let pixmap = tiny_skia::Pixmap::decode_png(&bytes).expect("decodes");
        let pixels = pixmap.pixels();
        let not_white = pixels.iter().filter(|p| (p.red(), p.green(), p.blue()) != (255, 255, 255)).count();
        assert!(not_white > pixels.len() / 50, "{file}: only {not_white} drawn pixels");
        // Public safety red (#d62728) is drawn: the intruders' tracks and lines.
        let red = pixels.iter().filter(|p| p.red() > 190 && p.green() < 70 && p.blue() < 70).count();
        assert!(red > 100, "{file}: {red} red pixels");
        // Text is drawn (dark pixels in the title band), with the embedded font.
        let title_band = &pixels[(20 * w as usize)..(40 * w as usize)];
        assert!(
            title_band.iter().filter(|p| p.red() < 80 && p.green() < 80 && p.blue() < 80).count() > 200,
            "{file}: no title"
        );
    }
    // The zone's pink fill is on the map.
    let map = tiny_skia::Pixmap::decode_png(&std::fs::read(dir.join("report/map.png")).unwrap()).unwrap();
    let pink =
        map.pixels().iter().filter(|p| p.red() > 240 && p.green() > 180 && p.green() < 225 && p.blue() > 210).count();
    assert!(pink > 500, "{pink} pink pixels");
}

#[test]
fn every_request_in_airspace_json_has_a_row_with_its_verdict() {
    let dir = copy_of_run("requests");
    let mut airspace: serde_json::Value = serde_json::from_str(&read(&dir, "airspace.json")).unwrap();
    airspace["requests"] = serde_json::json!([
        {"id": 1, "timeS": 12.5, "zone": "wall", "drone": 0, "droneName": "intruders-0", "operator": "acme",
         "altitude": {"minAglM": 20.0, "maxAglM": 30.0}, "verdict": "denied", "reason": "insufficient_credentials"},
        {"id": 2, "timeS": 14.0, "zone": "wall", "drone": 2, "droneName": "bystander-0", "operator": "acme",
         "altitude": {"minAglM": 60.0, "maxAglM": 80.0}, "verdict": "granted", "lease": "lease-1"},
        {"id": 3, "timeS": 15.0, "zone": "wall", "drone": 1, "droneName": "intruders-1", "operator": "acme",
         "altitude": {"minAglM": 20.0, "maxAglM": 30.0}, "verdict": "denied", "reason": "insufficient_credentials"}
    ]);
    std::fs::write(dir.join("airspace.json"), serde_json::to_vec(&airspace).unwrap()).unwrap();
    write_report(&dir, find_world).unwrap();
    let html = read(&dir, HTML_FILE);
    let table = &html[html.find(r#"id="requests-table""#).unwrap()..];
    let table = &table[..table.find("</table>").unwrap()];
    assert_eq!(table.matches(r#"data-request=""#).count(), 3, "{table}");
    for (id, drone, verdict) in
        [(1, "intruders-0", "denied"), (2, "bystander-0", "granted"), (3, "intruders-1", "denied")]
    {
        let row = &table[table.find(&format!(r#"data-request="{id}""#)).unwrap()..];
        let row = &row[..row.find("</tr>").unwrap()];
        assert!(row.contains(drone) && row.contains(&format!("<td>{verdict}</td>")), "{row}");
    }
    assert!(table.contains("insufficient_credentials") && table.contains("lease-1"));
    // Per group: the intruders asked twice (2 of 2 drones), both denied.
    let groups = &html[html.find(r#"id="requests-by-group""#).unwrap()..];
    let intruders = &groups[groups.find("intruders").unwrap()..];
    let intruders = &intruders[..intruders.find("</tr>").unwrap()];
    assert!(intruders.contains(">2 of 2<"), "{intruders}");
}

#[test]
fn a_malformed_trajectory_fails_naming_the_file_line_and_column() {
    let dir = copy_of_run("bad-csv");
    let csv = read(&dir, "trajectory.csv");
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    // Line 5 of the file (the header is line 1): east_m (column 8) is not a number.
    let mut fields: Vec<String> = lines[4].split(',').map(String::from).collect();
    fields[7] = "12.5.3".into();
    lines[4] = fields.join(",");
    std::fs::write(dir.join("trajectory.csv"), lines.join("\n")).unwrap();
    let err = write_report(&dir, find_world).unwrap_err().to_string();
    assert!(err.contains("trajectory.csv: line 5: column `east_m`") && err.contains("\"12.5.3\""), "{err}");
    // A row with a missing field.
    lines[4] = "1.0,0,intruders-0".into();
    std::fs::write(dir.join("trajectory.csv"), lines.join("\n")).unwrap();
    let err = write_report(&dir, find_world).unwrap_err().to_string();
    assert!(err.contains("trajectory.csv: line 5: 3 fields, the header has 22"), "{err}");
}

#[test]
fn malformed_json_files_name_the_file_and_the_field() {
    let dir = copy_of_run("bad-json");
    let mut airspace: serde_json::Value = serde_json::from_str(&read(&dir, "airspace.json")).unwrap();
    airspace["violations"][0]["kind"] = "flyingTooFast".into();
    std::fs::write(dir.join("airspace.json"), serde_json::to_vec_pretty(&airspace).unwrap()).unwrap();
    let err = write_report(&dir, find_world).unwrap_err().to_string();
    assert!(err.contains("airspace.json: field `violations[0].kind`") && err.contains("flyingTooFast"), "{err}");
    let dir = copy_of_run("bad-events");
    let events = format!("{}{{\"timeS\": \"late\"}}\n", read(&dir, "events.jsonl"));
    let line = events.lines().count();
    std::fs::write(dir.join("events.jsonl"), events).unwrap();
    let err = write_report(&dir, find_world).unwrap_err().to_string();
    assert!(err.contains(&format!("events.jsonl: line {line}: not an event")), "{err}");
}

#[test]
fn missing_files_are_noted_and_a_missing_plan_is_an_error() {
    let dir = std::env::temp_dir().join(format!("sadesim-report-{}-plan-only", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let err = write_report(&dir, find_world).unwrap_err().to_string();
    assert!(err.contains("plan.json: failed to read"), "{err}");
    std::fs::copy(run_dir().join("plan.json"), dir.join("plan.json")).unwrap();
    write_report(&dir, find_world).unwrap();
    let html = read(&dir, HTML_FILE);
    for file in ["trajectory.csv", "events.jsonl", "airspace.json", "summary.json", "world.json"] {
        assert!(html.contains(&format!("{file}: not recorded")), "{file}");
    }
    assert!(html.contains(r#"class="badge unknown">NOT JUDGED<"#));
    assert!(html.contains("No trajectory recorded"));
    png_size(&std::fs::read(dir.join("report/map.png")).unwrap());
}

#[test]
fn rebuilding_an_unchanged_folder_writes_the_same_bytes() {
    let dir = copy_of_run("rebuild");
    let files = ["report.html", "report/map.svg", "report/altitude.svg", "report/map.png", "report/altitude.png"];
    write_report(&dir, find_world).unwrap();
    let first: Vec<Vec<u8>> = files.iter().map(|f| std::fs::read(dir.join(f)).unwrap()).collect();
    write_report(&dir, find_world).unwrap();
    for (f, bytes) in files.iter().zip(&first) {
        assert_eq!(&std::fs::read(dir.join(f)).unwrap(), bytes, "{f} changed");
    }
}

#[test]
fn a_folder_that_cannot_take_the_plots_fails_naming_the_path() {
    let dir = copy_of_run("unwritable");
    std::fs::remove_file(dir.join(HTML_FILE)).unwrap();
    // A file where the plots' folder goes.
    std::fs::write(dir.join(IMAGES_DIR), b"not a folder").unwrap();
    let err = write_report(&dir, find_world).unwrap_err().to_string();
    assert!(err.contains(&format!("{}: cannot create", dir.join(IMAGES_DIR).display())), "{err}");
    // The page is written last: no page without its plots.
    assert!(!dir.join(HTML_FILE).exists());
}
