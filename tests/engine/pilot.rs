//! The pilot process of `sadesim run`: started at release with the fleet file, its
//! environment and a log; its exit ends the run (`endRun`) or not (`continue`); a pilot
//! still running at the end is stopped; one that cannot start fails the run.
//!
//! The pilots here are shell scripts. The runs keep `mavlink: false` (scripted groups
//! only) except where a group without a mission is the point; that test holds
//! [`mavlink_ports`].

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use sadesim::runner::pilot::{PilotError, PilotRecord};
use sadesim::runner::{RunError, RunOptions, RunReport, run_local};
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::Credential;
use sadesim_crds::fleet_file::FleetFile;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::run::{Clock, ClockMode, EnvVar, Pilot, PilotExit};
use sadesim_integration_tests::{mavlink_ports, plan};

use crate::local::options;

fn root(name: &str) -> PathBuf {
    crate::local::scratch("pilot", name)
}

/// Two scripted drones (take off to 30 m, land) flown by `command` as the pilot.
fn scenario(command: &[&str], duration: &str, clock: Clock) -> SimulationRun {
    RunBuilder::test()
        .with_drones(2)
        .with(|r| {
            r.spec.duration = duration.parse().unwrap();
            r.spec.clock = Some(clock);
            r.spec.pilot = Some(Pilot {
                image: None,
                command: command.iter().map(|s| s.to_string()).collect(),
                container_command: None,
                env: vec![EnvVar { name: "MY_VAR".into(), value: "from the scenario".into() }],
                ..Pilot::default()
            });
        })
        .build()
}

fn afap() -> Clock {
    Clock { mode: ClockMode::AsFastAsPossible, factor: None }
}

/// Paced, so the pilot has wall time to act before the run ends.
fn scaled(factor: f64) -> Clock {
    Clock { mode: ClockMode::Scaled, factor: Some(factor) }
}

fn run(r: &SimulationRun, options: &RunOptions) -> Result<RunReport, RunError> {
    run_local(r, options, Arc::new(AtomicBool::new(false)))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn pilot_json(out_dir: &Path) -> PilotRecord {
    serde_json::from_str(&read(&out_dir.join("pilot.json"))).unwrap()
}

/// Alive and not a zombie (a container's init may never reap orphans).
fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .is_ok_and(|stat| stat.rsplit_once(") ").is_some_and(|(_, rest)| !rest.starts_with('Z')))
}

/// Writes what the pilot saw at its start into the output folder, then exits 3.
const RECORDING_PILOT: &str = r#"
grep -c pilotsReleased "$SADESIM_OUT/events.jsonl" > "$SADESIM_OUT/seen-release"
printf '%s\n' "$SADESIM_FLEET" "$SADESIM_RUN" "$SADESIM_OUT" "$SADESIM_CREDENTIAL_ALPHA" "$MY_VAR" "$(pwd -P)" > "$SADESIM_OUT/seen-env"
echo to-stdout
echo to-stderr >&2
exit 3
"#;

fn pilot_exit_ends_the_run(processes: bool) {
    let root = root(if processes { "exit-processes" } else { "exit-threads" });
    let mut r = scenario(&["sh", "-c", RECORDING_PILOT], "10m", afap());
    r.spec.fleet[0].credential = Some(Credential::Value("s3cret".into()));
    let report = run(&r, &options(&root, processes)).unwrap();
    let (s, out) = (&report.summary, &report.out_dir);

    // The run ended because the pilot exited, long before its 10 minutes.
    assert_eq!(s.end_reason, EndReason::PilotExited);
    assert!(s.sim_time_s < 600.0, "{}", s.sim_time_s);
    assert!(read(&out.join("events.jsonl")).trim_end().ends_with(r#""event":"runEnded","reason":"pilotExited"}"#));
    let p = pilot_json(out);
    assert_eq!((p.exit_code, p.signal, p.stopped_by_runner), (Some(3), None, false), "{p:?}");
    assert_eq!(report.pilot.as_ref(), Some(&p));

    // Started only after the release, which it found in events.jsonl.
    let released = s.pilots_released_at_s.expect("pilots were released");
    let started = p.started_at_s.expect("the pilot started");
    assert!(started >= released && p.exited_at_s.unwrap() >= started, "{p:?}, released at {released}");
    assert_eq!(read(&out.join("seen-release")).trim(), "1");

    // Its environment and working directory.
    let env = read(&out.join("seen-env"));
    let env: Vec<&str> = env.lines().collect();
    let out_abs = std::path::absolute(out).unwrap();
    assert_eq!(env[0], out_abs.join("fleet.json").to_str().unwrap());
    assert_eq!(env[1..5], ["test-run", out_abs.to_str().unwrap(), "s3cret", "from the scenario"]);
    assert_eq!(Path::new(env[5]), root.join("scenario").canonicalize().unwrap());

    // The fleet file it was pointed at describes the run's drones, without the credential.
    let fleet_text = read(Path::new(env[0]));
    assert!(!fleet_text.contains("s3cret"));
    let fleet: FleetFile = serde_json::from_str(&fleet_text).unwrap();
    let names: Vec<String> = plan(&r).drones.iter().map(|d| d.name.clone()).collect();
    assert_eq!(fleet.drones.iter().map(|d| d.name.clone()).collect::<Vec<_>>(), names);
    assert_eq!(fleet.drones[0].credential_env.as_deref(), Some("SADESIM_CREDENTIAL_ALPHA"));

    let log = read(&out.join("pilot.log"));
    assert!(log.contains("to-stdout") && log.contains("to-stderr"), "{log}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn pilot_starts_after_release_with_the_fleet_file_and_its_exit_ends_the_run() {
    pilot_exit_ends_the_run(false);
}

#[test]
fn pilot_exit_ends_the_run_with_processes_too() {
    pilot_exit_ends_the_run(true);
}

/// Asks the airspace API named in the fleet file for `/healthz` (bash's `/dev/tcp`, no
/// HTTP client needed) and writes the status line and the URL into the output folder.
const AIRSPACE_PILOT: &str = r#"
url=$(grep -o '"airspaceUrl": *"[^"]*"' "$SADESIM_FLEET" | sed 's/.*"http:\/\/\([^"]*\)"/\1/')
exec 3<>"/dev/tcp/${url%:*}/${url##*:}"
printf 'GET /healthz HTTP/1.0\r\n\r\n' >&3
head -n1 <&3 | tr -d '\r' > "$SADESIM_OUT/seen-airspace"
echo "$url" >> "$SADESIM_OUT/seen-airspace"
"#;

/// Another program holds the plan's airspace port: the API answers on another one, and the
/// fleet file tells the pilot where (with worker processes the coordinator process picks
/// the port, and the runner learns it from the coordinator).
fn fleet_file_names_the_airspace_api_where_it_answers(processes: bool) {
    let root = root(if processes { "airspace-processes" } else { "airspace-threads" });
    let r = scenario(&["bash", "-c", AIRSPACE_PILOT], "10m", afap());
    let planned = plan(&r).services.airspace_http;
    // Held by this test, or by another program already: taken either way.
    let _held = std::net::TcpListener::bind(("127.0.0.1", planned));
    let report = run(&r, &options(&root, processes)).unwrap();
    assert_eq!(report.summary.end_reason, EndReason::PilotExited);
    let seen = read(&report.out_dir.join("seen-airspace"));
    let lines: Vec<&str> = seen.lines().collect();
    assert!(lines[0].starts_with("HTTP/1.") && lines[0].ends_with(" 200 OK"), "{seen}");
    assert!(lines[1].starts_with("127.0.0.1:") && lines[1] != format!("127.0.0.1:{planned}"), "{seen}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_fleet_file_names_the_airspace_api_where_it_answers() {
    fleet_file_names_the_airspace_api_where_it_answers(false);
}

#[test]
fn the_fleet_file_names_the_airspace_api_where_it_answers_with_processes_too() {
    fleet_file_names_the_airspace_api_where_it_answers(true);
}

#[test]
fn with_on_exit_continue_the_run_goes_on_to_its_duration() {
    let root = root("continue");
    // 20 s at 20x: a second of wall time, plenty for `sh` to exit first.
    let mut r = scenario(&["sh", "-c", "exit 0"], "20s", scaled(20.0));
    r.spec.pilot.as_mut().unwrap().on_exit = Some(PilotExit::Continue);
    let report = run(&r, &options(&root, false)).unwrap();
    assert_eq!((&report.summary.end_reason, report.summary.sim_time_s), (&EndReason::Duration, 20.0));
    let p = pilot_json(&report.out_dir);
    assert_eq!((p.exit_code, p.stopped_by_runner, p.on_exit), (Some(0), false, PilotExit::Continue), "{p:?}");
    assert!(p.exited_at_s.unwrap() < 20.0, "{p:?}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_pilot_still_running_at_the_end_is_stopped_with_what_it_started() {
    let root = root("terminate");
    // The pilot starts a grandchild and waits for it; 5 s at 5x leaves it a second to do so.
    let pilot = r#"sleep 600 & echo $! > "$SADESIM_OUT/grandchild.pid"; wait"#;
    let r = scenario(&["sh", "-c", pilot], "5s", scaled(5.0));
    let wall = Instant::now();
    let report = run(&r, &options(&root, false)).unwrap();
    assert!(wall.elapsed() < Duration::from_secs(30), "the run waited for the pilot: {:?}", wall.elapsed());
    assert_eq!(report.summary.end_reason, EndReason::Duration);
    let p = pilot_json(&report.out_dir);
    assert_eq!((p.exit_code, p.signal, p.stopped_by_runner), (None, Some(15), true), "SIGTERM sufficed: {p:?}");
    assert_eq!(p.exited_at_s, Some(5.0));
    let grandchild: u32 = read(&report.out_dir.join("grandchild.pid")).trim().parse().unwrap();
    assert!(!alive(p.pid.unwrap()), "the pilot is gone");
    assert!(!alive(grandchild), "and so is the process it started");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_pilot_program_that_does_not_exist_fails_the_run_naming_it() {
    let root = root("missing");
    for program in ["sadesim-no-such-pilot", "./pilots/missing.sh"] {
        let err = run(&scenario(&[program, "--fly"], "1m", afap()), &options(&root, false)).unwrap_err();
        assert!(matches!(err, RunError::Pilot(PilotError::Start { .. })), "{err}");
        let msg = err.to_string();
        assert!(msg.starts_with(&format!("spec.pilot.command[0]: failed to start {program:?}")), "{msg}");
        assert!(msg.contains("program not found"), "{msg}");
    }
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn no_pilot_leaves_the_pilot_to_the_user_and_still_writes_the_fleet_file() {
    let root = root("no-pilot");
    let r = scenario(&["sh", "-c", r#"touch "$SADESIM_OUT/started"; exit 0"#], "3s", afap());
    let report = run(&r, &RunOptions { start_pilot: false, ..options(&root, false) }).unwrap();
    assert_eq!((&report.summary.end_reason, report.summary.sim_time_s), (&EndReason::Duration, 3.0));
    assert!(report.pilot.is_none());
    for absent in ["started", "pilot.json", "pilot.log"] {
        assert!(!report.out_dir.join(absent).exists(), "{absent}");
    }
    let fleet: FleetFile = serde_json::from_str(&read(&report.out_dir.join("fleet.json"))).unwrap();
    assert_eq!(fleet.drones.len(), 2);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn groups_without_a_mission_need_mavlink() {
    let root = root("needs-mavlink");
    let r = RunBuilder::test().with_pilot(&["sh", "-c", "exit 0"]).build();
    let err = run(&r, &options(&root, false)).unwrap_err();
    assert!(matches!(err, RunError::NeedsMavlink { .. }), "{err}");
    assert!(err.to_string().starts_with("spec.fleet: groups alpha have no mission"), "{err}");
    assert!(err.to_string().ends_with("drop --no-mavlink"), "{err}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_group_without_a_mission_is_left_to_the_pilot_with_mavlink_on() {
    let _ports = mavlink_ports();
    let root = root("external");
    let mut r = RunBuilder::test().with_pilot(&["sh", "-c", "exit 0"]).build();
    r.spec.duration = "10m".parse().unwrap();
    r.spec.clock = Some(afap());
    let report = run(&r, &RunOptions { mavlink: true, ..options(&root, false) }).unwrap();
    assert_eq!(report.summary.end_reason, EndReason::PilotExited);
    let fleet: FleetFile = serde_json::from_str(&read(&report.out_dir.join("fleet.json"))).unwrap();
    assert!(!fleet.drones[0].scripted);
    // Nobody flew it: the pilot exited without a word.
    assert!(!report.summary.per_drone[0].took_off);
    std::fs::remove_dir_all(&root).unwrap();
}
