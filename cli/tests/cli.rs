//! End-to-end tests of the `sadesim` binary: what a user sees at the terminal.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn sadesim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sadesim")).args(args).current_dir(repo()).output().expect("sadesim runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn files_in(dir: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join(dir))
        .unwrap_or_else(|e| panic!("{dir}: {e}"))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    v.sort();
    v
}

#[test]
fn examples_and_valid_scenarios_validate() {
    let mut files = files_in("examples");
    files.retain(|p| p.extension().is_some_and(|e| e == "yaml"));
    files.extend(files_in("tests/scenarios/valid"));
    // The cluster end-to-end test's scenarios (tests/e2e/run.sh cannot run here).
    files.extend(files_in("tests/e2e").into_iter().filter(|p| p.extension().is_some_and(|e| e == "yaml")));
    assert!(files.iter().any(|p| p.ends_with("tests/e2e/pilot-exit.yaml")), "{files:?}");
    let args: Vec<&str> = files.iter().map(|p| p.to_str().unwrap()).collect();
    let mut all = vec!["validate"];
    all.extend(args);
    let out = sadesim(&all);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("ok: ") && text(&out).contains("chicago-museum (32 drones in 3 groups, 1 zone)"),
        "{}",
        text(&out)
    );
}

#[test]
fn each_broken_scenario_fails_naming_its_field() {
    let files = files_in("tests/scenarios/invalid");
    assert!(files.len() >= 20, "expected the broken-scenario collection, found {}", files.len());
    for file in files {
        let content = std::fs::read_to_string(&file).unwrap();
        let expect = content
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("# expect: "))
            .unwrap_or_else(|| panic!("{}: first line must be `# expect: <path>...`", file.display()));
        let out = sadesim(&["validate", file.to_str().unwrap()]);
        let report = text(&out);
        assert_eq!(out.status.code(), Some(1), "{}: {report}", file.display());
        for path in expect.split_whitespace() {
            assert!(report.contains(&format!("{path}:")), "{}: expected `{path}:` in\n{report}", file.display());
        }
    }
}

/// A first scenario written from scratch misses four required fields: one `validate` names
/// all four (not one per run), as `kubectl apply` would.
#[test]
fn validate_lists_every_missing_required_field_in_one_run() {
    let dir = std::env::temp_dir().join(format!("sadesim-cli-missing-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("from-scratch.yaml");
    std::fs::write(
        &file,
        "apiVersion: sadesim.io/v1alpha1\nkind: SimulationRun\nmetadata: {name: first}\nspec:\n  \
         origin: {latitudeDeg: 41.88, longitudeDeg: -87.62}\n  duration: 1m\n  fleet:\n  \
         - {name: solo, count: 1, airframe: x500, mission: {items: [{takeoff: {altitudeAglM: 10}}, {land: {}}]}}\n",
    )
    .unwrap();
    let out = sadesim(&["validate", file.to_str().unwrap()]);
    let report = text(&out);
    assert_eq!(out.status.code(), Some(1), "{report}");
    assert!(report.contains("document 1: 4 structural problems"), "{report}");
    for path in ["spec.fleet[0].operator", "spec.fleet[0].homes", "spec.fleet[0].altitude", "spec.origin.altitudeMslM"]
    {
        assert!(report.contains(&format!("  {path}: Required value")), "expected {path} in\n{report}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn huge_and_deeply_nested_inputs_are_refused_cleanly() {
    let dir = std::env::temp_dir().join(format!("sadesim-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 50 MB: refused by size before parsing.
    let big = dir.join("big.yaml");
    let mut body = String::from(
        "apiVersion: sadesim.io/v1alpha1\nkind: SimulationRun\nmetadata: {name: big}\nspec:\n  padding: |\n",
    );
    let line = format!("    {}\n", "x".repeat(100));
    while body.len() < 50 * 1024 * 1024 {
        body.push_str(&line);
    }
    std::fs::write(&big, body).unwrap();
    let out = sadesim(&["validate", big.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("larger than"), "{}", text(&out));
    // Deep nesting: refused by the depth limit, not a stack overflow or a hang.
    let deep = dir.join("deep.yaml");
    std::fs::write(&deep, format!("spec: {}{}\n", "[".repeat(200_000), "]".repeat(200_000))).unwrap();
    let out = sadesim(&["validate", deep.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("recursion limit"), "{}", text(&out));
    let deep_json = dir.join("deep.json");
    std::fs::write(&deep_json, format!("{{\"spec\": {}{}}}", "[".repeat(200_000), "]".repeat(200_000))).unwrap();
    let out = sadesim(&["validate", deep_json.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("recursion limit"), "{}", text(&out));
    // Not UTF-8: the byte offset is named.
    let binary = dir.join("binary.yaml");
    std::fs::write(&binary, b"apiVersion: sadesim.io/v1alpha1\n\xff\xfe").unwrap();
    let out = sadesim(&["validate", binary.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out).contains("invalid byte at offset 32"), "{}", text(&out));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn validate_reads_stdin() {
    let example = std::fs::read(repo().join("examples/quickstart.yaml")).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_sadesim"))
        .args(["validate", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    child.stdin.take().unwrap().write_all(&example).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", text(&out));
}

#[test]
fn plan_summarises_groups_shards_segments_and_ports() {
    let out = sadesim(&["plan", "examples/chicago-museum.yaml"]);
    let report = text(&out);
    assert!(out.status.success(), "{report}");
    for needle in ["Groups (32 drones)", "public-safety", "Shards", "MAVLink router segments", "14550", "5760", "14540"]
    {
        assert!(report.contains(needle), "missing {needle:?} in\n{report}");
    }
    let out = sadesim(&["plan", "--json", "examples/chicago-museum.yaml"]);
    assert!(out.status.success(), "{}", text(&out));
    let plan: sadesim_crds::plan::RunPlan = serde_json::from_slice(&out.stdout).expect("plan --json is a RunPlan");
    assert_eq!(plan.drones.len(), 32);
    assert_eq!(plan.run.name, "chicago-museum");
    let out = sadesim(&["plan", "--fleet", "examples/chicago-museum.yaml"]);
    let fleet: sadesim_crds::fleet_file::FleetFile = serde_json::from_slice(&out.stdout).expect("fleet file JSON");
    assert_eq!(fleet.drones[0].mavlink.api, "udpin://0.0.0.0:14540");
}

#[test]
fn plan_refuses_invalid_runs_with_all_problems() {
    let file = repo().join("tests/scenarios/invalid/multi-error.yaml");
    let out = sadesim(&["plan", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let expect = std::fs::read_to_string(&file).unwrap();
    let expect = expect.lines().next().unwrap().strip_prefix("# expect: ").unwrap().to_string();
    for path in expect.split_whitespace() {
        assert!(text(&out).contains(path), "{}", text(&out));
    }
}

#[test]
fn crd_command_prints_the_checked_in_crds() {
    let out = sadesim(&["crd"]);
    assert!(out.status.success());
    let file = |name: &str| std::fs::read_to_string(repo().join("crds").join(name)).unwrap();
    let checked_in =
        format!("{}---\n{}", file("sadesim.io_simulationruns.yaml"), file("sadesim.io_simulationsweeps.yaml"));
    assert_eq!(String::from_utf8(out.stdout).unwrap(), checked_in);
}

#[test]
fn help_explains_the_commands() {
    let out = sadesim(&["--help"]);
    let help = text(&out);
    for cmd in ["validate", "plan", "crd"] {
        assert!(help.contains(cmd), "{help}");
    }
}

#[test]
fn ctrl_c_ends_a_run_cleanly_and_keeps_its_output() {
    let dir = std::env::temp_dir().join(format!("sadesim-ctrlc-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // The quickstart at real time: long enough to be interrupted.
    let scenario = std::fs::read_to_string(repo().join("examples/quickstart.yaml"))
        .unwrap()
        .replace("clock: {mode: asFastAsPossible}", "clock: {mode: realtime}");
    assert!(scenario.contains("mode: realtime"));
    let file = dir.join("realtime.yaml");
    std::fs::write(&file, scenario).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_sadesim"))
        .args(["run", file.to_str().unwrap(), "--quiet", "--no-mavlink", "--out", dir.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_secs(3));
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", text(&out));
    assert!(text(&out).contains("ended (interrupted)"), "{}", text(&out));
    let run_dir = std::fs::read_dir(dir.join("quickstart")).unwrap().next().unwrap().unwrap().path();
    let events = std::fs::read_to_string(run_dir.join("events.jsonl")).unwrap();
    assert!(events.lines().last().unwrap().contains(r#""event":"runEnded","reason":"interrupted""#), "{events}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["endReason"], "interrupted");
    let sim_time = summary["simTimeS"].as_f64().unwrap();
    assert!((1.0..10.0).contains(&sim_time), "real time: about 3 s simulated, got {sim_time}");
    let rows = std::fs::read_to_string(run_dir.join("trajectory.csv")).unwrap().lines().count();
    assert!(rows > 40, "trajectory rows kept: {rows}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The quickstart with `pilot` added before its zones; `mission: false` drops the missions.
fn quickstart_with_pilot(pilot: &str, mission: bool) -> String {
    let scenario = std::fs::read_to_string(repo().join("examples/quickstart.yaml")).unwrap();
    let zones = scenario.find("  # A small restricted zone").unwrap();
    let start = if mission { zones } else { scenario.find("      mission:").unwrap() };
    format!("{}  pilot:\n{pilot}\n{}", &scenario[..start], &scenario[zones..])
}

#[test]
fn run_refuses_external_pilots_without_mavlink_naming_the_field() {
    // The quickstart flown by an external MAVLink pilot instead of its scripted mission.
    let scenario = quickstart_with_pilot("    command: [python3, pilot.py]\n", false);
    let dir = std::env::temp_dir().join(format!("sadesim-unsupported-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("pilot.yaml");
    std::fs::write(&file, scenario).unwrap();
    let out = sadesim(&["run", file.to_str().unwrap(), "--quiet", "--no-mavlink", "--out", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        text(&out).contains(
            "pilot.yaml: spec.fleet: groups scouts have no mission, so the pilot (spec.pilot) flies them over MAVLink: external pilots need the MAVLink endpoints; drop --no-mavlink"
        ),
        "{}",
        text(&out)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_starts_the_pilot_from_the_scenario_folder_and_reports_its_exit() {
    let dir = std::env::temp_dir().join(format!("sadesim-pilot-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("pilots")).unwrap();
    std::fs::write(dir.join("pilots/pilot.sh"), "echo flying\necho 'lost the link' >&2\nexit 4\n").unwrap();
    let file = dir.join("run.yaml");
    std::fs::write(&file, quickstart_with_pilot("    command: [sh, pilots/pilot.sh]\n", true)).unwrap();
    let out_dir = dir.join("out");
    // From another directory: the pilot's relative path is the scenario folder's.
    let run = |extra: &str| {
        let mut args =
            vec!["run", file.to_str().unwrap(), "--quiet", "--no-mavlink", "--out", out_dir.to_str().unwrap()];
        args.extend(extra.split_whitespace());
        sadesim(&args)
    };
    let out = run("");
    // A pilot that exits non-zero fails the run: exit 1, its code and its log's last lines.
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("run quickstart ended (pilotExited)"), "{}", text(&out));
    // The pilot starts in the window after the pilots are released (2.8 s in the
    // quickstart, once every drone's height has settled).
    assert!(text(&out).contains("  pilot: started at 2.81 s, exited with code 4 at "), "{}", text(&out));
    assert!(text(&out).contains(
        "  pilot FAILED: the pilot exited with code 4 before the run ended; spec.pilot.expectedExit is success\n  last lines of pilot.log:\n    | flying\n    | lost the link\n"
    ), "{}", text(&out));
    assert!(text(&out).contains("criteria FAILED: 2 of 3 passed"), "{}", text(&out));
    assert!(
        text(&out).contains("    FAIL spec.pilot.expectedExit expectedExit: started at 2.81 s, exited with code 4 at "),
        "{}",
        text(&out)
    );
    // Declared as expected, the same exit passes.
    let expected = quickstart_with_pilot("    command: [sh, pilots/pilot.sh]\n    expectedExit: failure\n", true);
    std::fs::write(&file, expected).unwrap();
    let out = run("");
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(text(&out).contains("  pilot: started at 2.81 s, exited with code 4 at "), "{}", text(&out));
    assert!(text(&out).contains("criteria PASSED: 2 of 2 passed"), "{}", text(&out));
    // --no-pilot: nobody exits, the run lasts its three minutes.
    let out = run("--no-pilot");
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(text(&out).contains("run quickstart ended (duration) at 180.0 s"), "{}", text(&out));
    assert!(!text(&out).contains("pilot:"), "{}", text(&out));
    // The report is written and its path printed.
    let line = text(&out).lines().find(|l| l.starts_with("  report: ")).map(str::to_owned);
    let html = line.as_deref().and_then(|l| l.strip_prefix("  report: ")).unwrap_or_default();
    assert!(html.ends_with("report.html") && std::path::Path::new(html).exists(), "{}", text(&out));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_exits_1_when_a_criterion_fails_and_lists_the_failures() {
    let dir = std::env::temp_dir().join(format!("sadesim-criteria-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let run = |name: &str, scenario: &str| {
        let file = dir.join(name);
        std::fs::write(&file, scenario).unwrap();
        sadesim(&["run", file.to_str().unwrap(), "--quiet", "--no-mavlink", "--out", dir.to_str().unwrap()])
    };
    // As shipped, the quickstart keeps its 60 m limit: it passes.
    let scenario = std::fs::read_to_string(repo().join("examples/quickstart.yaml")).unwrap();
    let ok = run("pass.yaml", &scenario);
    assert_eq!(ok.status.code(), Some(0), "{}", text(&ok));
    assert!(text(&ok).contains("criteria PASSED: 2 of 2 passed"), "{}", text(&ok));
    // Move its zone onto Crown Fountain, the second waypoint, above 20 m: every scout
    // flies in without a lease. Exit 1, every scout named with the zone.
    let intruding = scenario
        .replace(
            "        - {latitudeDeg: 41.8801, longitudeDeg: -87.6242}\n        - {latitudeDeg: 41.8790, longitudeDeg: -87.6242}\n        - {latitudeDeg: 41.8790, longitudeDeg: -87.6228}\n        - {latitudeDeg: 41.8801, longitudeDeg: -87.6228}",
            "        - {latitudeDeg: 41.8820, longitudeDeg: -87.6245}\n        - {latitudeDeg: 41.8812, longitudeDeg: -87.6245}\n        - {latitudeDeg: 41.8812, longitudeDeg: -87.6235}\n        - {latitudeDeg: 41.8820, longitudeDeg: -87.6235}",
        )
        .replace("      ceiling: {heightM: 60, reference: agl}", "      floor: {heightM: 20, reference: agl}\n      ceiling: {heightM: 60, reference: agl}")
        .replace("    - altitudeLimitsRespected: {}", "    - altitudeLimitsRespected: {}\n    - noUnauthorizedEntries: {}");
    assert_eq!(intruding.matches("41.8812").count(), 2, "the quickstart's zone changed: update this test");
    let failed = run("fail.yaml", &intruding);
    let out = text(&failed);
    assert_eq!(failed.status.code(), Some(1), "{out}");
    assert!(out.contains("criteria FAILED: 2 of 3 passed"), "{out}");
    assert!(out.contains("FAIL spec.criteria[2] noUnauthorizedEntries"), "{out}");
    for k in 0..4 {
        assert!(out.contains(&format!("- scouts-{k} inside museum")), "scouts-{k} not listed: {out}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_ground_stations_need_a_run_with_mavlink() {
    let o = sadesim(&["bench", "--drones", "2", "--seconds", "1", "--ground-stations"]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("--ground-stations listens to MAVLink telemetry: it needs --mavlink or --whole-stack"),
        "{}",
        text(&o)
    );
}
