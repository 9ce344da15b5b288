use std::collections::HashSet;

use proptest::prelude::*;
use sadesim_crds::fixtures::{CHICAGO, RunBuilder};
use sadesim_crds::fleet::{Area, HomePlacement, LatLon};
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;

use super::*;

/// The invariants every plan must satisfy, whatever the fleet.
fn check_invariants(plan: &RunPlan, expected_drones: u32, per_shard: u32) {
    let n = plan.drones.len() as u32;
    assert_eq!(n, expected_drones);
    // Indices are 0..n in order.
    assert!(plan.drones.iter().enumerate().all(|(i, d)| d.index == i as u32));
    // Every drone in exactly one shard: shard ranges tile 0..n and agree with drone.shard.
    let mut owner = vec![None; n as usize];
    for s in &plan.shards {
        assert!(s.drone_count >= 1 && s.drone_count <= per_shard, "{s:?}");
        for i in s.first_drone..s.first_drone + s.drone_count {
            assert_eq!(owner[i as usize], None, "drone {i} in two shards");
            owner[i as usize] = Some(s.index);
        }
    }
    for d in &plan.drones {
        assert_eq!(owner[d.index as usize], Some(d.shard), "drone {} shard mismatch", d.index);
    }
    assert_eq!(plan.shards.len() as u32, n.div_ceil(per_shard));
    // System ids 1..=250 and unique within each segment; segments tile the fleet.
    assert_eq!(plan.segments.len() as u32, n.div_ceil(SYSTEM_IDS_PER_SEGMENT));
    for seg in &plan.segments {
        let ids: Vec<u8> = plan.drones.iter().filter(|d| d.segment == seg.index).map(|d| d.system_id).collect();
        assert_eq!(ids.len() as u32, seg.drone_count);
        assert!(ids.iter().all(|&id| (1..=250).contains(&id)));
        assert_eq!(ids.iter().collect::<HashSet<_>>().len(), ids.len(), "duplicate sysid in segment {}", seg.index);
    }
    // Every port unique: drone API and endpoint ports, GCS ports and services together.
    let mut udp = HashSet::new();
    for d in &plan.drones {
        assert!(udp.insert(d.ports.api_udp), "api port {} reused", d.ports.api_udp);
        assert!(udp.insert(d.ports.endpoint), "endpoint port {} reused", d.ports.endpoint);
    }
    for s in &plan.segments {
        assert!(udp.insert(s.gcs_udp), "gcs udp {} reused", s.gcs_udp);
        assert!(udp.insert(s.gcs_tcp), "gcs tcp {} reused", s.gcs_tcp);
    }
    let services = plan.services;
    for p in [services.coordinator, services.airspace_http, services.renderer_http, services.metrics] {
        assert!(udp.insert(p), "service port {p} reused");
    }
    assert_eq!(plan.resources.shards.len(), plan.shards.len());
}

#[test]
fn fleets_of_1_32_1000_and_10000_drones_plan_correctly() {
    for n in [1, 32, 1000, 10_000] {
        let run = RunBuilder::test().with_drones(n).build();
        let plan = plan(&run).unwrap();
        check_invariants(&plan, n, 100);
    }
}

#[test]
fn px4_port_conventions_hold() {
    let plan = plan(&RunBuilder::test().with_drones(12).build()).unwrap();
    assert_eq!(plan.drones[0].ports.api_udp, 14540, "MAVSDK's default udpin://0.0.0.0:14540 sees drone 0");
    assert_eq!(plan.drones[9].ports.api_udp, 14549);
    assert_ne!(plan.drones[10].ports.api_udp, 14550, "14550 belongs to the GCS");
    assert_eq!(plan.segments[0].gcs_udp, 14550);
    assert_eq!(plan.segments[0].gcs_tcp, 5760);
    assert_eq!(plan.drones[0].system_id, 1);
}

#[test]
fn segment_boundary_at_250_drones() {
    let plan = plan(&RunBuilder::test().with_drones(251).build()).unwrap();
    assert_eq!(plan.drones[249].system_id, 250);
    assert_eq!(plan.drones[249].segment, 0);
    assert_eq!(plan.drones[250].system_id, 1);
    assert_eq!(plan.drones[250].segment, 1);
    assert_eq!(plan.segments[1].gcs_udp, 14551);
}

#[test]
fn same_input_same_plan_byte_for_byte() {
    let run = RunBuilder::test().with_drones(300).with_group("bravo", 7).with_zone("museum").build();
    let a = serde_json::to_string(&plan(&run).unwrap()).unwrap();
    let b = serde_json::to_string(&plan(&run.clone()).unwrap()).unwrap();
    assert_eq!(a, b);
    let other_seed = plan(&RunBuilder::test().with_drones(300).with_group("bravo", 7).with_seed(8).build()).unwrap();
    assert_ne!(
        serde_json::to_string(&other_seed.drones).unwrap(),
        serde_json::to_string(&plan(&run).unwrap().drones).unwrap()
    );
}

#[test]
fn random_homes_stay_in_their_area_and_areas_share_round_robin() {
    let parks = vec![
        Area {
            name: Some("a".into()),
            center: LatLon { latitude_deg: 41.8826, longitude_deg: -87.6226 },
            radius_m: 100.0,
        },
        Area {
            name: Some("b".into()),
            center: LatLon { latitude_deg: 41.8757, longitude_deg: -87.6189 },
            radius_m: 50.0,
        },
    ];
    let run = RunBuilder::test()
        .with_drones(10)
        .with(|r| r.spec.fleet[0].homes = HomePlacement::Areas(parks.clone()))
        .build();
    let plan = plan(&run).unwrap();
    let frame = LocalFrame::new(run.spec.origin.geo());
    for (k, d) in plan.drones.iter().enumerate() {
        let park = &parks[k % 2];
        let (cx, cy) = frame.to_plane(park.center.latitude_deg, park.center.longitude_deg);
        let dist = (d.home.local.east_m - cx).hypot(d.home.local.north_m - cy);
        assert!(dist <= park.radius_m, "drone {k} {dist} m from its park");
        // Local and global homes are the same point.
        let back = frame.to_enu(d.home.global);
        assert!((back.east_m - d.home.local.east_m).abs() < 1e-6 && (back.north_m - d.home.local.north_m).abs() < 1e-6);
    }
}

#[test]
fn explicit_homes_are_kept_exactly() {
    let at = LatLon { latitude_deg: CHICAGO.latitude_deg + 0.001, longitude_deg: CHICAGO.longitude_deg };
    let run = RunBuilder::test().with(|r| r.spec.fleet[0].homes = HomePlacement::Explicit(vec![at])).build();
    let plan = plan(&run).unwrap();
    let g = plan.drones[0].home.global;
    assert!((g.latitude_deg - at.latitude_deg).abs() < 1e-9 && (g.longitude_deg - at.longitude_deg).abs() < 1e-9);
    assert!((plan.drones[0].home.local.north_m - 111.0).abs() < 1.0);
}

#[test]
fn asset_key_follows_world_inputs_only() {
    let base = RunBuilder::test().with_zone("museum");
    let key = |b: RunBuilder| plan(&b.build()).unwrap().asset_cache_key;
    let k0 = key(base.clone());
    assert_eq!(k0.len(), 64);
    assert_eq!(k0, key(base.clone().with_seed(99)), "the run seed does not shape the world");
    assert_eq!(k0, key(base.clone().with_drones(5)), "fleet size does not shape the world");
    assert_ne!(k0, key(base.clone().with(|r| r.spec.origin.altitude_msl_m += 1.0)));
    assert_ne!(k0, key(base.clone().with(|r| r.spec.zones[0].ceiling.height_m = 99.0)));
    assert_ne!(
        k0,
        key(base.with(|r| r.spec.world = Some(sadesim_crds::run::World { extent_m: 2000.0, ..Default::default() })))
    );
}

#[test]
fn invalid_runs_are_not_planned() {
    let run = RunBuilder::test().with(|r| r.spec.fleet[0].count = 0).build();
    let err = plan(&run).unwrap_err();
    assert!(err.to_string().contains("spec.fleet[0].count: must be between 1 and 10000, got 0"), "{err}");
}

#[test]
fn fleet_file_gives_urls_credentials_and_closed_zone_rings() {
    let run = RunBuilder::test()
        .with_drones(2)
        .with_pilot(&["python3", "pilot.py"])
        .with_zone("museum")
        .with(|r| r.spec.fleet[0].credential = Some(sadesim_crds::fleet::Credential::Value("s3cret".into())))
        .build();
    let plan = plan(&run).unwrap();
    let local = fleet_file(&plan, &Addressing::Local { host: "127.0.0.1".into() });
    assert_eq!(local.drones[0].mavlink.api, "udpin://0.0.0.0:14540");
    assert_eq!(local.drones[1].mavlink.udp, "udpout://127.0.0.1:24601");
    assert_eq!(local.airspace_url, "http://127.0.0.1:8480");
    assert_eq!(local.drones[0].credential_env.as_deref(), Some("SADESIM_CREDENTIAL_ALPHA"));
    assert!(!serde_json::to_string(&local).unwrap().contains("s3cret"), "credential values never enter the fleet file");
    let ring = &local.zones["features"][0]["geometry"]["coordinates"][0];
    assert_eq!(ring.as_array().unwrap().len(), 5);
    assert_eq!(ring[0], ring[4]);
    assert_eq!(ring[0][0].as_f64().unwrap(), run.spec.zones[0].polygon[0].longitude_deg, "GeoJSON is [lon, lat]");
    let cluster = fleet_file(&plan, &Addressing::Cluster);
    assert_eq!(cluster.drones[0].mavlink.tcp, "tcpout://test-run-shard-0.test-run-shards.default.svc:24600");
    assert_eq!(cluster.airspace_url, "http://test-run-airspace.default.svc:8480");
}

#[test]
fn fleet_file_gives_each_drone_its_camera_urls_once_the_frame_server_listens() {
    let run = RunBuilder::test()
        .with_drones(2)
        .with_group("no-camera", 1)
        .with_camera(sadesim_crds::fixtures::down_camera())
        .build();
    let plan = plan(&run).unwrap();
    let mut fleet = fleet_file(&plan, &Addressing::Local { host: "127.0.0.1".into() });
    assert!(fleet.drones.iter().all(|d| d.cameras.is_empty()));
    assert!(!serde_json::to_string(&fleet).unwrap().contains("cameras"), "no frame server, no cameras field");
    add_camera_urls(&mut fleet, &plan, "http://127.0.0.1:8091/cameras/");
    let urls: Vec<Vec<(&str, &str)>> =
        fleet.drones.iter().map(|d| d.cameras.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect()).collect();
    let first = &fleet.drones[0].name;
    assert_eq!(urls[0], [("down", format!("http://127.0.0.1:8091/cameras/{first}/down/").as_str())]);
    assert_eq!(urls[1].len(), 1);
    assert!(urls[2].is_empty(), "the group without cameras gets none");
    let json = serde_json::to_value(&fleet).unwrap();
    assert_eq!(json["drones"][0]["cameras"]["down"], format!("http://127.0.0.1:8091/cameras/{first}/down/"));
    // On a cluster the coordinator serves them on its Service's renderer port.
    let cluster = fleet_file(&plan, &Addressing::Cluster);
    assert_eq!(cluster_cameras_url(&plan).as_deref(), Some("http://test-run-airspace.default.svc:8490/cameras"));
    assert_eq!(
        cluster.drones[0].cameras["down"],
        format!("http://test-run-airspace.default.svc:8490/cameras/{first}/down/")
    );
    assert!(cluster.drones[2].cameras.is_empty());
    let without = super::plan(&RunBuilder::test().with_drones(2).build()).unwrap();
    assert_eq!(cluster_cameras_url(&without), None, "no cameras, no URL");
    assert!(fleet_file(&without, &Addressing::Cluster).drones.iter().all(|d| d.cameras.is_empty()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn any_fleet_plans_with_the_invariants(
        counts in proptest::collection::vec(1u32..700, 1..5),
        per_shard in 1u32..400,
        seed in 0..=i64::MAX as u64,
    ) {
        let mut b = RunBuilder::test().with_seed(seed).with_drones_per_shard(per_shard);
        b = b.with(|r| r.spec.fleet.clear());
        for (i, c) in counts.iter().enumerate() {
            b = b.with_group(&format!("g{i}"), *c);
        }
        let run = b.build();
        let plan = plan(&run).unwrap();
        check_invariants(&plan, counts.iter().sum(), per_shard);
        // Groups keep their order and sizes.
        for (i, c) in counts.iter().enumerate() {
            prop_assert_eq!(plan.drones.iter().filter(|d| d.group_index == i as u32).count() as u32, *c);
        }
    }
}

#[test]
fn random_homes_avoid_ground_zones() {
    // The fixture's zone is a ~200 m square at the origin; put the home disc right over it.
    let run = RunBuilder::test()
        .with_drones(200)
        .with_zone("museum")
        .with(|r| {
            r.spec.fleet[0].homes = HomePlacement::RandomInArea(Area { name: None, center: CHICAGO, radius_m: 300.0 })
        })
        .build();
    let plan = plan(&run).unwrap();
    let frame = LocalFrame::new(run.spec.origin.geo());
    let zone: Vec<_> =
        run.spec.zones[0].polygon.iter().map(|v| frame.to_plane(v.latitude_deg, v.longitude_deg)).collect();
    for d in &plan.drones {
        assert!(!sadesim_crds::polygon::contains(&zone, (d.home.local.east_m, d.home.local.north_m)), "{}", d.name);
    }
    // A disc entirely inside the zone leaves no room: refused by validation.
    let inside = RunBuilder::test()
        .with_zone("museum")
        .with(|r| {
            r.spec.fleet[0].homes = HomePlacement::RandomInArea(Area { name: None, center: CHICAGO, radius_m: 20.0 })
        })
        .build();
    assert!(plan_err(&inside).contains("spec.fleet[0].homes.randomInArea: lies entirely inside zone"));
}

fn plan_err(run: &sadesim_crds::SimulationRun) -> String {
    plan(run).unwrap_err().to_string()
}

/// A mapped city of one 20 x 20 m building centred 50 m north of the origin.
fn mapped(sha256: &str) -> (SimulationRun, sadesim_world::WorldData) {
    use sadesim_world::osm::{ElementId, HeightSource, OsmBuilding, OsmCity, OsmStats};
    use sadesim_world::{Building, Footprint};
    let run = RunBuilder::test()
        .with(|r| {
            r.spec.world = Some(sadesim_crds::run::World {
                source: sadesim_crds::run::WorldSource::Osm,
                osm: Some(sadesim_crds::run::OsmExtract { file: "city.osm.pbf".into(), default_height_m: None }),
                ..Default::default()
            })
        })
        .build();
    let square = Footprint::new(vec![[-10.0, 40.0], [10.0, 40.0], [10.0, 60.0], [-10.0, 60.0]], vec![]).unwrap();
    let building = OsmBuilding {
        id: ElementId::Way(1),
        building: Building::new(square, 0.0, 20.0).unwrap(),
        height_source: HeightSource::Tagged,
        part: false,
    };
    let city = OsmCity {
        source_sha256: sha256.into(),
        buildings: vec![building],
        open_areas: vec![],
        stats: OsmStats::default(),
    };
    (run, sadesim_world::WorldData { osm: Some(city), dem: None })
}

#[test]
fn a_mapped_world_needs_its_extract_and_its_bytes_shape_the_asset_key() {
    let (run, city) = mapped("aa");
    let e = plan(&run).unwrap_err();
    assert!(matches!(e, PlanError::World(_)), "{e}");
    let a = plan_with(&run, &city).unwrap();
    let (_, other) = mapped("bb");
    let b = plan_with(&run, &other).unwrap();
    assert_ne!(a.asset_cache_key, b.asset_cache_key, "a changed extract is a new world");
    assert_eq!(a.asset_cache_key, plan_with(&run, &city).unwrap().asset_cache_key);
    // The same bytes elsewhere (moved, or uploaded to a bucket) are the same world.
    let mut moved = run.clone();
    moved.spec.world.as_mut().unwrap().osm.as_mut().unwrap().file = "s3://maps/city.osm.pbf".into();
    assert_eq!(plan_with(&moved, &city).unwrap().asset_cache_key, a.asset_cache_key);
}

#[test]
fn an_explicit_home_inside_a_mapped_building_is_refused_by_name() {
    let (mut run, city) = mapped("aa");
    // 50 m north of the origin: inside the building.
    let inside = LatLon { latitude_deg: CHICAGO.latitude_deg + 50.0 / 111_100.0, longitude_deg: CHICAGO.longitude_deg };
    run.spec.fleet[0].homes = HomePlacement::Explicit(vec![inside]);
    let e = plan_with(&run, &city).unwrap_err().to_string();
    assert!(e.starts_with("spec.fleet[0].homes.explicit[0]: inside a building of the map (roof 20.0 m)"), "{e}");
}
