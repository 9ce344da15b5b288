//! The pilot Job: its fleet file, scenario, credentials, command and image.

use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use serde_json::Value;

use super::super::tests::*;
use super::super::*;

#[test]
fn the_pilot_gets_the_fleet_file_run_and_credentials_from_secrets() {
    let run = piloted(3);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let c = container(&children, "test-run-pilot");
    assert_eq!(c.image.as_deref(), Some("registry.example/team-a/pilot:1.2"));
    assert_eq!(c.command, Some(vec!["python3".to_string(), "/app/pilot.py".to_string()]));
    let env = c.env.unwrap();
    let value = |n: &str| env.iter().find(|e| e.name == n).and_then(|e| e.value.clone());
    assert_eq!(value("SADESIM_FLEET").as_deref(), Some(FLEET_PATH));
    assert_eq!(value("SADESIM_RUN").as_deref(), Some("test-run"));
    let cred = env.iter().find(|e| e.name == "SADESIM_CREDENTIAL_ALPHA").unwrap();
    let from = cred.value_from.as_ref().unwrap().secret_key_ref.as_ref().unwrap();
    assert_eq!((from.name.as_str(), from.key.as_str(), cred.value.as_deref()), ("alpha-token", "token", None));
    // The coordinator checks the same credential.
    let coord = container(&children, "test-run-coordinator").env.unwrap();
    assert!(coord.iter().any(|e| e.name == "SADESIM_CREDENTIAL_ALPHA" && e.value_from == cred.value_from));
    // The fleet file is mounted from its ConfigMap, which holds the in-cluster addresses.
    let Some(Child::ConfigMap(cm)) = children.iter().find(|c| c.name() == "test-run-fleet") else { panic!() };
    let fleet: Value = serde_json::from_str(&cm.data.as_ref().unwrap()["fleet.json"]).unwrap();
    assert_eq!(fleet["airspaceUrl"], "http://test-run-airspace.default.svc:8480");
    let mounts = container(&children, "test-run-pilot").volume_mounts.unwrap();
    let spec = pod_specs(&children).into_iter().find(|(n, _)| n == "test-run-pilot").unwrap().1;
    let fleet_mount = mounts.iter().find(|m| m.mount_path == CONFIG_DIR).unwrap();
    let volume = spec.volumes.unwrap().into_iter().find(|v| v.name == fleet_mount.name).unwrap();
    let sources = volume.projected.unwrap().sources.unwrap();
    let names: Vec<_> = sources.iter().map(|s| s.config_map.as_ref().unwrap().name.as_str()).collect();
    assert_eq!(names, ["test-run-fleet"]);
    // A small fleet file needs no joining: the only init container holds the pilot until
    // the coordinator releases the pilots, polling the airspace API's health.
    let init = spec.init_containers.unwrap();
    assert_eq!(init.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(), ["wait-release"]);
    assert_eq!(init[0].args.as_deref().unwrap(), ["wait-release", "http://test-run-airspace.default.svc:8480/healthz"]);
}

/// The pilot reads the scenario it flies in, as locally (`SADESIM_SCENARIO`), and runs
/// `containerCommand` in its image when the local `command` would not work there.
#[test]
fn the_pilot_gets_its_scenario_and_its_container_command() {
    let mut run = piloted(3);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let env = container(&children, "test-run-pilot").env.unwrap();
    let scenario = env.iter().find(|e| e.name == "SADESIM_SCENARIO").and_then(|e| e.value.clone());
    assert_eq!(scenario.as_deref(), Some("/etc/sadesim/scenario.json"));
    let Some(Child::ConfigMap(cm)) = children.iter().find(|c| c.name() == "test-run-fleet") else { panic!() };
    let text = &cm.data.as_ref().unwrap()["scenario.json"];
    let parsed = sadesim_crds::document::parse_run(text).expect("a scenario sadesim reads");
    assert_eq!(parsed.spec, run.spec);
    assert_eq!(parsed.metadata.namespace.as_deref(), Some("default"));
    let command_of = |run: &SimulationRun| container(&children_of(run), "test-run-pilot").command;
    assert_eq!(command_of(&run), Some(vec!["python3".to_string(), "/app/pilot.py".to_string()]));
    let pilot = run.spec.pilot.as_mut().unwrap();
    pilot.command = vec!["cargo".into(), "run".into(), "-p".into(), "my-pilot".into()];
    pilot.container_command = Some(vec!["/usr/local/bin/my-pilot".into()]);
    assert_eq!(command_of(&run), Some(vec!["/usr/local/bin/my-pilot".to_string()]));
    run.spec.pilot.as_mut().unwrap().container_command = Some(vec![]);
    assert_eq!(command_of(&run), None, "[]: the image's own entrypoint");
}

#[test]
fn a_pilot_without_an_image_is_refused_on_a_cluster_and_gets_no_job() {
    let run = with_uid(RunBuilder::test().with_pilot(&["./pilot.sh"]).build());
    let plan = planned(&run);
    let p = problems(&plan, &s3());
    assert!(p.iter().any(|p| p.fatal && p.field == "spec.pilot.image"), "{p:?}");
    assert!(!children(&run, &plan, &s3(), Stage::ALL).iter().any(|c| c.name() == "test-run-pilot"));
    // A run with every problem solved has none.
    assert_eq!(problems(&planned(&piloted(3)), &s3()), vec![]);
}
