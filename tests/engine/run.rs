//! The local runner end to end: determinism, independence from sharding, threads vs
//! processes, crashes as events, and what it refuses. The pilot process: `pilot.rs`.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use sadesim::runner::{RunError, RunOptions, run_local};
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::{Area, HomePlacement};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::run::{Clock, ClockMode};
use sadesim_integration_tests::{fly_to_and_land, plan, world};

fn out_root(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-run-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A short as-fast-as-possible run: `n` drones take off, fly 40 m north, land.
fn scenario(n: u32, per_shard: u32) -> SimulationRun {
    RunBuilder::test()
        .with_drones(n)
        .with_drones_per_shard(per_shard)
        .with(|r| {
            r.spec.duration = "40s".parse().unwrap();
            r.spec.clock = Some(Clock { mode: ClockMode::AsFastAsPossible, factor: None });
            // Small home disc; the world keeps it (and so the short flights) free of buildings.
            let homes = r.spec.fleet[0].homes.clone();
            if let HomePlacement::RandomInArea(a) = homes {
                r.spec.fleet[0].homes = HomePlacement::RandomInArea(Area { radius_m: 60.0, ..a });
            }
            let frame = LocalFrame::new(r.spec.origin.geo());
            let HomePlacement::RandomInArea(a) = &r.spec.fleet[0].homes else { unreachable!() };
            let c =
                frame.to_enu(sadesim_crds::geo::GeoPoint::new(a.center.latitude_deg, a.center.longitude_deg, 181.0));
            let wp = frame.to_geodetic(Enu::new(c.east_m, c.north_m + 40.0, 0.0));
            r.spec.fleet[0].mission = Some(fly_to_and_land(wp, 10.0, 12.0, None, 6.0));
        })
        .build()
}

fn run(run: &SimulationRun, root: &Path, processes: bool) -> Result<sadesim::runner::RunReport, RunError> {
    let worker = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/debug/sim-worker");
    let options = RunOptions {
        out_root: Some(root.to_path_buf()),
        processes,
        worker: Some(worker),
        mavlink: false,
        ..RunOptions::default()
    };
    run_local(run, &options, Arc::new(AtomicBool::new(false)))
}

fn bytes(dir: &Path, file: &str) -> String {
    std::fs::read_to_string(dir.join(file)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(file).display()))
}

/// Events without the `runStarted` line, which names the shard count.
fn drone_events(dir: &Path) -> String {
    bytes(dir, "events.jsonl").lines().filter(|l| !l.contains("runStarted")).collect::<Vec<_>>().join("\n")
}

/// Equality without dumping megabytes on failure.
fn assert_same(a: &str, b: &str, what: &str) {
    if a != b {
        let line = a.lines().zip(b.lines()).position(|(x, y)| x != y).unwrap_or(0);
        panic!("{what} differ at line {}: {:?} vs {:?}", line + 1, a.lines().nth(line), b.lines().nth(line));
    }
}

#[test]
fn same_scenario_and_seed_give_identical_recordings() {
    let root = out_root("determinism");
    let a = run(&scenario(3, 100), &root.join("a"), false).unwrap();
    let b = run(&scenario(3, 100), &root.join("b"), false).unwrap();
    assert_eq!(a.summary.end_reason, EndReason::Duration);
    for file in ["trajectory.csv", "events.jsonl", "trajectory.geojson", "plan.json"] {
        assert_same(&bytes(&a.out_dir, file), &bytes(&b.out_dir, file), file);
    }
    // The run did something: every drone took off and landed again.
    assert!(a.summary.per_drone.iter().all(|d| d.took_off && d.landed && !d.crashed), "{:?}", a.summary.per_drone);
    // A different seed changes the noise, hence the trajectory.
    let c = run(&scenario(3, 100).clone_with_seed(99), &root.join("c"), false).unwrap();
    assert_ne!(bytes(&a.out_dir, "trajectory.csv"), bytes(&c.out_dir, "trajectory.csv"));
    std::fs::remove_dir_all(&root).unwrap();
}

trait WithSeed {
    fn clone_with_seed(&self, seed: u64) -> SimulationRun;
}
impl WithSeed for SimulationRun {
    fn clone_with_seed(&self, seed: u64) -> SimulationRun {
        let mut r = self.clone();
        r.spec.seed = Some(seed);
        r
    }
}

#[test]
fn trajectories_do_not_depend_on_sharding_or_on_processes() {
    let root = out_root("sharding");
    let one_shard = run(&scenario(4, 4), &root.join("one"), false).unwrap();
    let four_shards = run(&scenario(4, 1), &root.join("four"), false).unwrap();
    assert_eq!(one_shard.summary.shards, 1);
    assert_eq!(four_shards.summary.shards, 4);
    assert_same(
        &bytes(&one_shard.out_dir, "trajectory.csv"),
        &bytes(&four_shards.out_dir, "trajectory.csv"),
        "trajectories",
    );
    assert_same(&drone_events(&one_shard.out_dir), &drone_events(&four_shards.out_dir), "events");
    // The same four shards as sim-worker processes over TCP.
    let processes = run(&scenario(4, 1), &root.join("processes"), true).unwrap();
    assert_same(
        &bytes(&four_shards.out_dir, "trajectory.csv"),
        &bytes(&processes.out_dir, "trajectory.csv"),
        "trajectories",
    );
    assert_same(&bytes(&four_shards.out_dir, "events.jsonl"), &bytes(&processes.out_dir, "events.jsonl"), "events");
    assert!(processes.out_dir.join("shard-3.log").exists());
    std::fs::remove_dir_all(&root).unwrap();
}

/// A 10 000-drone run on a cluster is 100 shard pods: the coordinator's lockstep over 100
/// shard processes (one drone each, TCP over loopback) flies the same run as 2 shards.
#[test]
fn a_coordinator_runs_a_hundred_shard_processes_as_two_shards() {
    let root = out_root("hundred");
    let mut hundred = scenario(100, 1);
    let mut two = scenario(100, 50);
    for r in [&mut hundred, &mut two] {
        r.spec.duration = "4s".parse().unwrap();
    }
    let processes = run(&hundred, &root.join("processes"), true).unwrap();
    let threads = run(&two, &root.join("two"), false).unwrap();
    assert_eq!((processes.summary.shards, threads.summary.shards), (100, 2));
    assert_same(
        &bytes(&threads.out_dir, "trajectory.csv"),
        &bytes(&processes.out_dir, "trajectory.csv"),
        "trajectories",
    );
    assert!(processes.out_dir.join("shard-99.log").exists());
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn urban_gnss_does_not_depend_on_sharding_or_on_processes() {
    // The ranging receiver under the synthetic GPS + Galileo sky: the same pseudoranges
    // (hence fixes, estimates and flights) in one shard, four, and four processes.
    let root = out_root("urban-gnss");
    std::fs::create_dir_all(&root).unwrap();
    let orbits = root.join("walker.tle");
    std::fs::write(&orbits, sadesim_gnss::synthetic::walker_gps_galileo_tle()).unwrap();
    let with_sky = |per_shard: u32| {
        let mut r = scenario(4, per_shard);
        r.spec.environment = Some(
            serde_json::from_value(
                serde_json::json!({"gnss": {"constellation": {"file": orbits.display().to_string()}}}),
            )
            .unwrap(),
        );
        r
    };
    let one = run(&with_sky(4), &root.join("one"), false).unwrap();
    let four = run(&with_sky(1), &root.join("four"), false).unwrap();
    let processes = run(&with_sky(1), &root.join("processes"), true).unwrap();
    let gnss = |r: &sadesim::runner::RunReport| {
        let g: Vec<_> = r.summary.per_drone.iter().map(|d| d.gnss.clone()).collect();
        assert!(g.iter().all(|g| g.as_ref().is_some_and(|g| g.reflected_share.is_some())), "ranging receivers: {g:?}");
        serde_json::to_string(&g).unwrap()
    };
    assert_same(&gnss(&one), &gnss(&four), "GNSS statistics, 1 vs 4 shards");
    assert_same(&gnss(&four), &gnss(&processes), "GNSS statistics, threads vs processes");
    for other in [&four, &processes] {
        let (a, b) = (bytes(&one.out_dir, "trajectory.csv"), bytes(&other.out_dir, "trajectory.csv"));
        assert_same(&a, &b, "trajectories");
    }
    // And not the statistical receiver's flight.
    let plain = run(&scenario(4, 4), &root.join("plain"), false).unwrap();
    assert_ne!(bytes(&one.out_dir, "trajectory.csv"), bytes(&plain.out_dir, "trajectory.csv"));
    // gnss.csv comes with the constellation only, the same in every layout.
    assert!(!plain.out_dir.join("gnss.csv").exists());
    assert_same(&bytes(&one.out_dir, "gnss.csv"), &bytes(&processes.out_dir, "gnss.csv"), "gnss.csv");
    assert!(bytes(&one.out_dir, "gnss.csv").lines().count() > 4 * 10, "a row per drone per second in flight");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_shard_process_that_dies_before_connecting_fails_the_run_naming_it() {
    let root = out_root("shard-dies");
    std::fs::create_dir_all(&root).unwrap();
    // A sim-worker whose shard role fails at start (as a shard whose plan or world cannot
    // be read would); the coordinator is the real one, left waiting for it.
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/debug/sim-worker");
    let wrapper = root.join("sim-worker");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\nif [ \"$1\" = shard ]; then echo 'cannot build the world' >&2; exit 3; fi\nexec '{}' \"$@\"\n",
            real.display()
        ),
    )
    .unwrap();
    let mut permissions = std::fs::metadata(&wrapper).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut permissions, 0o755);
    std::fs::set_permissions(&wrapper, permissions).unwrap();
    let options = RunOptions {
        out_root: Some(root.join("runs")),
        processes: true,
        worker: Some(wrapper),
        mavlink: false,
        ..RunOptions::default()
    };
    let error = run_local(&scenario(2, 1), &options, Arc::new(AtomicBool::new(false))).expect_err("no shard runs");
    let message = error.to_string();
    // Both shards fail; whichever the runner saw first is named, with its log.
    let named = ["0", "1"].into_iter().find(|i| message.contains(&format!("shard {i} exited (exit status: 3)")));
    let named = named.unwrap_or_else(|| panic!("no shard named: {message}"));
    assert!(message.contains("before the run started") && message.contains(&format!("shard-{named}.log")), "{message}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn flying_into_a_building_is_a_crash_event_and_the_run_goes_on() {
    let root = out_root("crash");
    let mut r = scenario(2, 100);
    // Aim drone 0's mission straight through the tallest building within 1.5 km of home
    // (outside the fixture's open park).
    let p = plan(&r);
    let w = world(&p);
    let home = p.drones[0].home.local;
    let tower = w
        .buildings()
        .iter()
        .filter(|b| {
            let [e, n] = b.footprint().bounds_center();
            (e - home.east_m).hypot(n - home.north_m) < 1500.0
        })
        .max_by(|a, b| a.height_m().total_cmp(&b.height_m()))
        .expect("downtown has buildings");
    assert!(tower.height_m() > 20.0);
    let frame = LocalFrame::new(r.spec.origin.geo());
    let [tower_east_m, tower_north_m] = tower.footprint().bounds_center();
    let target = frame.to_geodetic(Enu::new(tower_east_m, tower_north_m, 0.0));
    r.spec.duration = "3m".parse().unwrap();
    r.spec.fleet[0].count = 2;
    r.spec.fleet[0].altitude.max_agl_m = 200.0;
    r.spec.fleet[0].mission = Some(fly_to_and_land(target, 15.0, 15.0, None, 10.0));
    let report = run(&r, &root, false).unwrap();
    let events = bytes(&report.out_dir, "events.jsonl");
    assert!(events.contains(r#""event":"crashed","with":"building""#), "{events}");
    assert_eq!(report.summary.crashed, 2, "both drones flew the same route into the tower");
    assert_eq!(report.summary.end_reason, EndReason::Duration);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_live_view_leaves_the_run_unchanged() {
    // The view only reads the coordinator's windows: the same seed flies the same bits
    // with it on or off (the browser side is tested in tests/interop/test_view.py).
    let with_view = |on: bool| {
        let mut r = scenario(2, 2);
        r.spec.rendering = Some(sadesim_crds::run::Rendering { enabled: on, gpus: None });
        r
    };
    let root = out_root("view-unchanged");
    let off = run(&with_view(false), &root.join("off"), false).unwrap();
    let on = run(&with_view(true), &root.join("on"), false).unwrap();
    assert_eq!(bytes(&on.out_dir, "trajectory.csv"), bytes(&off.out_dir, "trajectory.csv"));
    assert_eq!(bytes(&on.out_dir, "events.jsonl"), bytes(&off.out_dir, "events.jsonl"));
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_live_view_with_worker_processes_flies_the_same_run() {
    // With --processes the coordinator process serves the view (`--view-bind`), as its pod
    // does on a cluster; the run is the same as the in-process one.
    let mut r = scenario(2, 1);
    r.spec.rendering = Some(sadesim_crds::run::Rendering { enabled: true, gpus: None });
    let root = out_root("view-processes");
    let threads = run(&r, &root.join("threads"), false).unwrap();
    let processes = run(&r, &root.join("processes"), true).unwrap();
    assert_eq!(bytes(&processes.out_dir, "trajectory.csv"), bytes(&threads.out_dir, "trajectory.csv"));
    let log = bytes(&processes.out_dir, "coordinator.log");
    assert!(log.contains("live view: http://127.0.0.1:"), "{log}");
    std::fs::remove_dir_all(&root).unwrap();
}

/// The camera images recorded in `dir/recording.mcap`, in file order: (topic, log time, data).
fn recorded_images(dir: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let file = std::fs::read(dir.join("recording.mcap")).unwrap();
    mcap::MessageStream::new(&file)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic.contains("/cameras/"))
        .map(|m| (m.channel.topic.clone(), m.log_time, m.data.into_owned()))
        .collect()
}

#[test]
fn onboard_cameras_with_worker_processes_take_the_same_frames() {
    // The coordinator process renders the cameras (as the runner does in-process) and
    // records them: the same seed gives the same images, frame for frame.
    if !Path::new("/usr/share/vulkan/icd.d")
        .read_dir()
        .is_ok_and(|mut d| d.any(|e| e.is_ok_and(|e| e.file_name().to_string_lossy().starts_with("lvp_icd"))))
    {
        eprintln!("skipped: needs Mesa's lavapipe (mesa-vulkan-drivers, tests/install-tools.sh)");
        return;
    }
    let mut r = scenario(2, 1);
    r.spec.duration = "6s".parse().unwrap();
    r.spec.rendering = Some(sadesim_crds::run::Rendering { enabled: true, gpus: None });
    r.spec.fleet[0].cameras = vec![sadesim_crds::camera::Camera {
        width_px: 64,
        height_px: 48,
        rate_hz: 5.0,
        record_rate_hz: Some(5.0),
        depth: true,
        ..sadesim_crds::fixtures::down_camera()
    }];
    let root = out_root("cameras-processes");
    let threads = run(&r, &root.join("threads"), false).unwrap();
    let processes = run(&r, &root.join("processes"), true).unwrap();
    assert_eq!(bytes(&processes.out_dir, "trajectory.csv"), bytes(&threads.out_dir, "trajectory.csv"));
    let tally = |report: &sadesim::runner::RunReport| -> Vec<(String, u64)> {
        report.summary.cameras.iter().map(|c| (c.drone.clone(), c.frames)).collect()
    };
    assert_eq!(tally(&threads), [("alpha-0".to_string(), 30), ("alpha-1".to_string(), 30)], "6 s at 5 Hz per drone");
    assert_eq!(tally(&processes), tally(&threads));
    let (a, b) = (recorded_images(&threads.out_dir), recorded_images(&processes.out_dir));
    assert_eq!(a.len(), 2 * 30 * 3, "image, calibration and depth per frame");
    assert!(a == b, "the recorded frames differ between threads and processes");
    let log = bytes(&processes.out_dir, "coordinator.log");
    assert!(log.contains("onboard cameras: http://127.0.0.1:"), "{log}");
    std::fs::remove_dir_all(&root).unwrap();
}
