//! The main rules of each section, on the fixture run with one thing broken: each test
//! asserts the path and the message a user sees, and that the valid fixture passes.

use kube::core::Duration;
use serde_json::json;

use super::*;
use crate::criteria::Criterion;
use crate::fixtures::{CHICAGO, RunBuilder};
use crate::fleet::{HomePlacement, LatLon, MissionItem};
use crate::run::Clock;

/// The problems of `run` as `path: message` lines (empty when valid).
fn problems(run: &SimulationRun) -> Vec<String> {
    match validate(run) {
        Ok(()) => Vec::new(),
        Err(e) => e.0.iter().map(ToString::to_string).collect(),
    }
}

/// The fixture with `edit` applied, and its problems.
fn problems_of(edit: impl FnOnce(&mut SimulationRun)) -> Vec<String> {
    problems(&RunBuilder::test().with(edit).build())
}

fn duration(text: &str) -> Duration {
    text.parse().expect("a valid Go duration")
}

#[test]
fn the_fixture_is_valid() {
    assert_eq!(problems(&RunBuilder::test().with_zone("tfr").build()), Vec::<String>::new());
}

#[test]
fn every_problem_is_listed_in_one_pass_in_section_order() {
    let found = problems_of(|r| {
        r.metadata.name = Some("Bad_Name".into());
        r.spec.fleet[0].count = 0;
        r.spec.queue = Some("-queue".into());
    });
    let paths: Vec<&str> = found.iter().map(|l| l.split(':').next().unwrap()).collect();
    assert_eq!(paths, ["metadata.name", "spec.fleet[0].count", "spec.queue"], "{found:?}");
    assert!(found[1].ends_with("must be between 1 and 10000, got 0"), "{found:?}");
}

#[test]
fn a_missing_run_name_is_required() {
    let found = problems_of(|r| r.metadata.name = None);
    assert_eq!(found, ["metadata.name: is required (a DNS label such as `chicago-museum`)"]);
}

#[test]
fn durations_must_be_positive_and_at_most_a_day() {
    assert_eq!(duration_s(&duration("-90s")), -90.0);
    let found = problems_of(|r| r.spec.duration = duration("0s"));
    assert_eq!(found, ["spec.duration: must be a positive duration such as `90s` or `15m`, got 0ns"]);
    let found = problems_of(|r| r.spec.duration = duration("25h"));
    assert_eq!(found.len(), 1);
    assert!(found[0].starts_with("spec.duration: must be at most 86400 s"), "{found:?}");
}

#[test]
fn a_scaled_clock_needs_a_factor_and_only_it_may_have_one() {
    let scaled = |factor| Clock { mode: crate::run::ClockMode::Scaled, factor };
    let found = problems_of(|r| r.spec.clock = Some(scaled(None)));
    assert_eq!(found, ["spec.clock.factor: is required with mode `scaled` (e.g. 4.0)"]);
    let found = problems_of(|r| r.spec.clock = Some(Clock { factor: Some(2.0), ..Clock::default() }));
    assert_eq!(found, ["spec.clock.factor: is only allowed with mode `scaled`"]);
    assert_eq!(problems_of(|r| r.spec.clock = Some(scaled(Some(4.0)))), Vec::<String>::new());
}

#[test]
fn an_unusable_origin_skips_the_checks_that_need_it() {
    let found = problems_of(|r| {
        r.spec.origin.latitude_deg = 89.0;
        r.spec.fleet[0].homes = HomePlacement::Explicit(vec![LatLon { latitude_deg: 0.0, longitude_deg: 0.0 }]);
    });
    // No "outside the world" noise for the home: the world cannot be placed.
    assert_eq!(found, ["spec.origin.latitudeDeg: must be between -85 and 85, got 89"]);
}

#[test]
fn homes_must_lie_inside_the_world() {
    let found = problems_of(|r| {
        r.spec.fleet[0].homes = HomePlacement::Explicit(vec![LatLon {
            latitude_deg: CHICAGO.latitude_deg + 0.1, // about 11 km north
            longitude_deg: CHICAGO.longitude_deg,
        }]);
    });
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("spec.fleet[0].homes.explicit[0]: must lie inside the world"), "{found:?}");
    assert!(found[0].contains("north of the origin"), "{found:?}");
}

#[test]
fn group_names_are_unique_labels_and_airframes_are_presets() {
    let found = problems(&RunBuilder::test().with_group("alpha", 1).build());
    assert_eq!(found, [r#"spec.fleet[1].name: duplicate group name "alpha": group names must be unique"#]);
    let found = problems_of(|r| r.spec.fleet[0].airframe = "x9000".into());
    assert_eq!(found.len(), 1);
    assert!(found[0].starts_with(r#"spec.fleet[0].airframe: unknown airframe preset "x9000", expected one of:"#));
    let found = problems_of(|r| r.spec.fleet[0].operator = "-acme".into());
    assert!(found[0].starts_with("spec.fleet[0].operator: must be 1 to 63 letters"), "{found:?}");
}

#[test]
fn the_altitude_minimum_is_below_the_maximum_and_missions_stay_below_the_maximum() {
    let found = problems_of(|r| r.spec.fleet[0].altitude.min_agl_m = Some(120.0));
    assert_eq!(found, ["spec.fleet[0].altitude.minAglM: must be below altitude.maxAglM (120), got 120"]);
    assert_eq!(problems_of(|r| r.spec.fleet[0].altitude.min_agl_m = Some(25.0)), Vec::<String>::new());
    let found = problems_of(|r| {
        r.spec.fleet[0].mission.as_mut().unwrap().items[0] = MissionItem::Takeoff { altitude_agl_m: 150.0 };
    });
    assert_eq!(
        found,
        ["spec.fleet[0].mission.items[0].takeoff.altitudeAglM: is above the group's altitude.maxAglM (120 m), got 150"]
    );
}

#[test]
fn a_mission_starts_with_takeoff() {
    let found = problems_of(|r| {
        r.spec.fleet[0].mission.as_mut().unwrap().items.remove(0);
    });
    assert_eq!(found, ["spec.fleet[0].mission.items[0]: a mission must start with a `takeoff` item"]);
}

#[test]
fn groups_without_a_mission_need_a_pilot() {
    let found = problems_of(|r| r.spec.fleet[0].mission = None);
    assert_eq!(found.len(), 1);
    assert!(found[0].starts_with("spec.pilot: is required: groups without a mission (alpha)"), "{found:?}");
    assert_eq!(problems(&RunBuilder::test().with_pilot(&["./pilot"]).build()), Vec::<String>::new());
}

#[test]
fn zone_floors_are_below_ceilings_and_homes_outside_ground_zones() {
    let found = problems(
        &RunBuilder::test()
            .with_zone("tfr")
            .with(|r| r.spec.zones[0].ceiling.height_m = -10.0)
            .with(|r| r.spec.fleet[0].homes = HomePlacement::Explicit(vec![CHICAGO]))
            .build(),
    );
    assert_eq!(
        found,
        [
            "spec.zones[0].ceiling: floor must be below ceiling: floor 0 m agl, ceiling -10 m agl",
            r#"spec.fleet[0].homes.explicit[0]: is inside zone "tfr", which reaches the ground: drones would start inside restricted airspace"#,
        ]
    );
}

#[test]
fn zone_polygons_need_three_distinct_vertices_without_a_closing_repeat() {
    let found = problems(&RunBuilder::test().with_zone("tfr").with(|r| r.spec.zones[0].polygon.truncate(2)).build());
    assert_eq!(found, ["spec.zones[0].polygon: must have at least 3 vertices, got 2"]);
    let found = problems(
        &RunBuilder::test()
            .with_zone("tfr")
            .with(|r| {
                let first = r.spec.zones[0].polygon[0];
                r.spec.zones[0].polygon.push(first);
            })
            .build(),
    );
    assert_eq!(found.len(), 1);
    assert!(found[0].starts_with("spec.zones[0].polygon[4]: repeats vertex 0"), "{found:?}");
}

#[test]
fn criteria_name_existing_groups_and_zones() {
    let found = problems_of(|r| {
        r.spec.criteria =
            vec![Criterion::ReachZone { groups: vec!["beta".into()], zone: "museum".into(), within: duration("1m") }]
    });
    assert_eq!(
        found,
        [
            r#"spec.criteria[0].reachZone.groups[0]: unknown group "beta", expected one of: alpha"#,
            r#"spec.criteria[0].reachZone.zone: unknown zone "museum", expected one of: (none defined)"#,
        ]
    );
}

#[test]
fn archive_urls_need_a_known_scheme() {
    let found = problems_of(|r| r.spec.archive = Some(crate::run::Archive { url: "ftp://host/runs".into() }));
    assert_eq!(found, [r#"spec.archive.url: unsupported scheme "ftp": expected file, s3, gs or az"#]);
}

/// The structural pass, on JSON values: what typed reading would stop at, all at once.
#[test]
fn the_schema_pass_lists_missing_fields_types_enums_and_unknown_fields() {
    let doc = json!({
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "metadata": {"name": "x"},
        "spec": {
            "origin": {"latitudeDeg": 41.88, "longitudeDeg": "west"},
            "clock": {"mode": "fast"},
            "fleet": [{"name": "a", "count": 1.5, "airframe": "x500", "operator": "acme",
                       "homes": {}, "altitude": {"maxAglM": 100}, "colour": "red"}],
        },
    });
    let found: Vec<String> = schema_problems(&doc).iter().map(ToString::to_string).collect();
    assert_eq!(
        found,
        [
            "spec.duration: Required value",
            r#"spec.clock.mode: Unsupported value: "fast": supported values: "realtime", "scaled", "asFastAsPossible""#,
            "spec.fleet[0].colour: unknown field `colour`, expected one of `airframe`, `altitude`, `cameras`, `count`, `credential`, `geofence`, `homes`, `mission`, `name`, `operator`, `role`",
            "spec.fleet[0].count: must be of type integer, got number 1.5",
            "spec.fleet[0].homes: Required value: exactly one of `explicit`, `randomInArea`, `areas`",
            "spec.origin.altitudeMslM: Required value",
            r#"spec.origin.longitudeDeg: must be of type number, got string "west""#,
        ]
    );
    assert_eq!(schema_problems(&json!({"apiVersion": "v", "kind": "k"})).len(), 1, "spec is required");
}

/// A valid document has no structural problem: the pass never refuses what typed
/// reading accepts.
#[test]
fn the_schema_pass_accepts_the_fixture() {
    let run = RunBuilder::test().with_zone("tfr").with(|r| r.spec.criteria = vec![Criterion::NoCrashes {}]).build();
    let doc = serde_json::to_value(&run).unwrap();
    assert_eq!(schema_problems(&doc), Vec::<FieldError>::new());
}

#[test]
fn an_osm_world_names_its_extract_and_nothing_of_the_procedural_city() {
    use crate::run::{City, OsmExtract, World, WorldSource};
    let osm = |file: &str| World {
        source: WorldSource::Osm,
        osm: Some(OsmExtract { file: file.into(), default_height_m: None }),
        ..World::default()
    };
    assert_eq!(problems_of(|r| r.spec.world = Some(osm("helsinki.osm.pbf"))), Vec::<String>::new());
    assert_eq!(problems_of(|r| r.spec.world = Some(osm("file:///data/helsinki.osm.pbf"))), Vec::<String>::new());
    let found = problems_of(|r| r.spec.world = Some(World { osm: None, ..osm("x") }));
    assert_eq!(found, ["spec.world.osm: is required with source osm: the extract's file"]);
    let found = problems_of(|r| r.spec.world = Some(World { source: WorldSource::Procedural, ..osm("x") }));
    assert_eq!(found, ["spec.world.osm: is only allowed with source osm"]);
    // Object storage: what a Kubernetes run reads its world from.
    for url in ["s3://maps/helsinki.osm.pbf", "gs://maps/fi/helsinki.osm.pbf", "az://maps/helsinki.osm.pbf"] {
        assert_eq!(problems_of(|r| r.spec.world = Some(osm(url))), Vec::<String>::new(), "{url}");
    }
    let found = problems_of(|r| r.spec.world = Some(osm("s3://maps")));
    assert_eq!(found, ["spec.world.osm.file: s3:// must name a file inside a bucket, e.g. s3://maps/helsinki.osm.pbf"]);
    let found = problems_of(|r| r.spec.world = Some(osm("https://example.com/helsinki.osm.pbf")));
    assert_eq!(found.len(), 1);
    assert!(found[0].starts_with("spec.world.osm.file: unsupported scheme \"https\""), "{found:?}");
    let found = problems_of(|r| {
        r.spec.world = Some(World { city: Some(City::default()), open_areas: vec![], ..osm("x") });
    });
    assert_eq!(found.len(), 1);
    assert!(found[0].starts_with("spec.world.city: shapes the procedural city only"), "{found:?}");
}

#[test]
fn a_gnss_constellation_needs_a_file_a_time_and_no_noise_figures() {
    let found = problems_of(|r| {
        r.spec.environment = Some(
            serde_json::from_value(serde_json::json!({"gnss": {
                "constellation": {"file": "ftp://host/gps.tle", "epoch": "yesterday", "elevationMaskDeg": 75},
                "horizontalSigmaM": 2.0
            }}))
            .unwrap(),
        );
        r.spec.criteria =
            vec![Criterion::EstimatedPositionError { groups: vec!["beta".into()], max_horizontal_m: 0.0 }];
    });
    assert_eq!(
        found,
        [
            r#"spec.environment.gnss.constellation.file: unsupported scheme "ftp": expected a path, file://, s3://, gs:// or az:// (http is not fetched)"#,
            r#"spec.environment.gnss.constellation.epoch: "yesterday" is not an RFC 3339 UTC time: expected e.g. 2020-12-01T12:00:00Z"#,
            "spec.environment.gnss.constellation.elevationMaskDeg: must be between 0 and 60, got 75",
            "spec.environment.gnss.horizontalSigmaM: is not allowed with constellation: the ranging receiver's errors come from the satellites' geometry and signal paths, not from a noise figure",
            r#"spec.criteria[0].estimatedPositionError.groups[0]: unknown group "beta", expected one of: alpha"#,
            "spec.criteria[0].estimatedPositionError.maxHorizontalM: must be between 0.1 and 1000, got 0",
        ]
    );
    let fine = problems_of(|r| {
        r.spec.environment = Some(
            serde_json::from_value(serde_json::json!({"gnss": {"rateHz": 5,
                "constellation": {"file": "s3://orbits/gnss.tle", "epoch": "2020-12-01T12:00:00Z"}}}))
            .unwrap(),
        );
    });
    assert!(fine.is_empty(), "{fine:?}");
}

#[test]
fn a_gnss_bias_beyond_100_m_is_refused_naming_the_field() {
    let with_bias = |bias: serde_json::Value| {
        problems_of(|r| {
            r.spec.environment = Some(serde_json::from_value(serde_json::json!({"gnss": {"bias": bias}})).unwrap());
        })
    };
    assert_eq!(
        with_bias(serde_json::json!({"eastM": 150.0, "northM": -3.5})),
        ["spec.environment.gnss.bias.eastM: must be between -100 and 100, got 150"]
    );
    assert!(with_bias(serde_json::json!({"eastM": 3.0, "northM": -2.0, "upM": 0.5})).is_empty());
    // The ranging receiver takes a bias too: it is not a noise figure.
    let ranging = problems_of(|r| {
        r.spec.environment = Some(
            serde_json::from_value(serde_json::json!({"gnss": {"bias": {"northM": 4.0}, "constellation": {}}}))
                .unwrap(),
        );
    });
    assert!(ranging.is_empty(), "{ranging:?}");
}

#[test]
fn an_imported_openfoam_case_needs_model_openfoam_a_folder_and_the_runs_direction() {
    let with_urban = |urban: serde_json::Value| {
        problems_of(|r| {
            r.spec.environment = Some(
                serde_json::from_value(
                    serde_json::json!({"wind": {"speedMps": 8, "directionFromDeg": 270, "urban": urban}}),
                )
                .unwrap(),
            );
        })
    };
    let found = with_urban(serde_json::json!({"model": "diagnostic",
        "case": {"dir": " ", "directionFromDeg": 250, "referenceSpeedMps": 0}}));
    assert_eq!(
        found,
        [
            "spec.environment.wind.urban.case: is only allowed with model: openfoam (an imported OpenFOAM case)",
            "spec.environment.wind.urban.case.dir: must name the OpenFOAM case directory",
            "spec.environment.wind.urban.case.referenceSpeedMps: must be between 0.1 and 100, got 0",
            "spec.environment.wind.urban.case.directionFromDeg: the case's wind blows from 250° but spec.environment.wind.directionFromDeg is 270°: an imported case holds one direction; set them equal or use model: openfoam without case (OpenFOAM runs for the run's direction)",
        ]
    );
    // Within half a degree is the same direction; OpenFOAM without a case needs nothing more.
    let fine = with_urban(serde_json::json!({"model": "openfoam",
        "case": {"dir": "cfd/case", "directionFromDeg": 269.8, "referenceSpeedMps": 10}}));
    assert!(fine.is_empty(), "{fine:?}");
    assert!(with_urban(serde_json::json!({"model": "openfoam"})).is_empty());
}

#[test]
fn gpus_for_the_renderer_are_bounded_and_need_it_on_and_cameras_to_render() {
    use crate::run::Rendering;
    let camera = crate::fixtures::down_camera();
    let with = |enabled: bool, gpus: Option<u32>| {
        let camera = camera.clone();
        problems_of(move |r| {
            r.spec.rendering = Some(Rendering { enabled, gpus });
            r.spec.fleet[0].cameras = vec![camera];
        })
    };
    assert!(with(true, Some(1)).is_empty(), "{:?}", with(true, Some(1)));
    assert!(with(true, None).is_empty());
    let no_cameras = problems_of(|r| r.spec.rendering = Some(Rendering { enabled: true, gpus: Some(1) }));
    assert_eq!(no_cameras.len(), 1);
    assert!(no_cameras[0].starts_with("spec.rendering.gpus: asks GPUs, but nothing renders"), "{no_cameras:?}");
    assert_eq!(with(true, Some(0)), ["spec.rendering.gpus: must be between 1 and 8, got 0"]);
    assert_eq!(with(true, Some(9)), ["spec.rendering.gpus: must be between 1 and 8, got 9"]);
    let off = with(false, Some(1));
    assert!(off.iter().any(|p| p.starts_with("spec.rendering.gpus: asks GPUs for a renderer that is off")), "{off:?}");
    assert!(off.iter().all(|p| !p.contains("nothing renders")), "one reason at a time: {off:?}");
}

#[test]
fn cameras_and_markers_name_their_bad_fields() {
    use crate::camera::{Camera, GroundMarker};
    use crate::run::Rendering;
    let camera =
        |rate_hz: f64, width_px: u32| Camera { rate_hz, width_px, depth: true, ..crate::fixtures::down_camera() };
    let marker = |id: u32| GroundMarker {
        name: "pad".into(),
        position: crate::fleet::LatLon { latitude_deg: 41.8826, longitude_deg: -87.6225 },
        size_m: 1.0,
        yaw_deg: 0.0,
        aruco_id: id,
    };
    let run = |cameras: Vec<Camera>, rendering: bool, markers: Vec<GroundMarker>| {
        problems_of(move |r| {
            r.spec.fleet[0].cameras = cameras;
            r.spec.rendering = Some(Rendering { enabled: rendering, gpus: None });
            r.spec.world.get_or_insert_with(Default::default).markers = markers;
        })
    };
    assert!(
        run(vec![camera(10.0, 160)], true, vec![marker(7)]).is_empty(),
        "{:?}",
        run(vec![camera(10.0, 160)], true, vec![])
    );
    assert_eq!(
        run(vec![camera(10.0, 8)], true, vec![]),
        ["spec.fleet[0].cameras[0].widthPx: must be between 16 and 4096, got 8"]
    );
    let off_grid = run(vec![camera(30.0, 160)], true, vec![]);
    assert!(
        off_grid[0].starts_with("spec.fleet[0].cameras[0].rateHz: 30 Hz does not divide the 100 Hz"),
        "{off_grid:?}"
    );
    let too_fast = run(vec![camera(200.0, 160)], true, vec![]);
    assert!(too_fast[0].starts_with("spec.fleet[0].cameras[0].rateHz: must be between"), "{too_fast:?}");
    let off = run(vec![camera(10.0, 160)], false, vec![]);
    assert!(off[0].starts_with("spec.fleet[0].cameras: onboard cameras are rendered by the renderer"), "{off:?}");
    assert_eq!(
        run(vec![camera(10.0, 160)], true, vec![marker(50)]),
        ["spec.world.markers[0].arucoId: must be between 0 and 49, got 50"]
    );
    let recorded = |record: f64| Camera { record_rate_hz: Some(record), ..camera(10.0, 160) };
    assert!(run(vec![recorded(5.0)], true, vec![]).is_empty());
    assert!(run(vec![recorded(0.0)], true, vec![]).is_empty(), "0 records no frames");
    let uneven = run(vec![recorded(3.0)], true, vec![]);
    assert!(
        uneven[0]
            .starts_with("spec.fleet[0].cameras[0].recordRateHz: 3 Hz does not divide the camera's rateHz (10 Hz)"),
        "{uneven:?}"
    );
    assert_eq!(
        run(vec![recorded(20.0)], true, vec![]),
        ["spec.fleet[0].cameras[0].recordRateHz: must be between 0 and 10, got 20"]
    );
    let unseen = run(vec![], true, vec![marker(1)]);
    assert!(unseen[0].starts_with("spec.world.markers: only onboard cameras see markers"), "{unseen:?}");
}

#[test]
fn ground_station_ranges_must_be_cidrs_naming_the_entry() {
    use crate::ground_stations::GroundStations;
    let with = |cidrs: &[&str]| {
        let allow_from = cidrs.iter().map(|c| c.to_string()).collect();
        problems_of(move |r| r.spec.ground_stations = Some(GroundStations { allow_from, signing: None }))
    };
    assert!(with(&["10.20.0.0/16", "192.168.1.7/32", "fd00::/8", "0.0.0.0/0"]).is_empty());
    let bad = with(&["10.20.0.0/16", "10.20.0.0", "10.0.0.0/33", "fd00::/129", "example.org/8"]);
    assert_eq!(bad.len(), 4, "{bad:?}");
    assert!(
        bad[0].starts_with("spec.groundStations.allowFrom[1]: must be an address range in CIDR notation"),
        "{bad:?}"
    );
    assert!(bad[1].starts_with("spec.groundStations.allowFrom[2]: the prefix length of an IPv4 range is at most 32"));
    assert!(bad[2].starts_with("spec.groundStations.allowFrom[3]: the prefix length of an IPv6 range is at most 128"));
    assert!(bad[3].contains("\"example.org/8\""), "{bad:?}");
}

#[test]
fn a_container_command_needs_an_image_and_a_program() {
    let with = |image: Option<&str>, container: Vec<&str>| {
        let image = image.map(str::to_string);
        let container: Vec<String> = container.into_iter().map(str::to_string).collect();
        problems_of(move |r| {
            let pilot = r.spec.pilot.get_or_insert_with(|| {
                crate::fixtures::RunBuilder::test().with_pilot(&["./p"]).build().spec.pilot.unwrap()
            });
            pilot.image = image;
            pilot.container_command = Some(container);
        })
    };
    assert!(with(Some("registry.example/p:1"), vec!["/usr/local/bin/p", "--flag"]).is_empty());
    assert!(with(Some("registry.example/p:1"), vec![]).is_empty(), "[]: the image's entrypoint");
    assert_eq!(
        with(None, vec!["p"]),
        ["spec.pilot.containerCommand: is the command in the pilot's image: it needs spec.pilot.image"]
    );
    assert_eq!(with(Some("registry.example/p:1"), vec![" "]), ["spec.pilot.containerCommand[0]: must name a program"]);
}

#[test]
fn a_signing_passphrase_needs_eight_characters_and_a_secret_is_taken_as_is() {
    use crate::fleet::{Credential, SecretKeyRef};
    use crate::ground_stations::{GroundStations, Signing};
    let with = |key: Credential| {
        problems_of(move |r| {
            r.spec.ground_stations = Some(GroundStations { allow_from: vec![], signing: Some(Signing { key }) })
        })
    };
    assert_eq!(with(Credential::Value("8 chars!".into())), Vec::<String>::new());
    // Counted in characters, not bytes: "äöüäöüä" is 14 bytes.
    let short = with(Credential::Value("äöüäöüä".into()));
    assert_eq!(short, ["spec.groundStations.signing.key.value: the passphrase must be at least 8 characters, got 7"]);
    let secret = Credential::SecretKeyRef(SecretKeyRef { name: "gcs-signing".into(), key: "passphrase".into() });
    assert_eq!(with(secret), Vec::<String>::new(), "signing is supported: no refusal");
}
