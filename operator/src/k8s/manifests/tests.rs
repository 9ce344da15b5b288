//! `sadesim manifests`: YAML documents, the placeholder uid, namespaces, errors.

use serde::Deserialize;

use super::*;

const RUN: &str = r#"
apiVersion: sadesim.io/v1alpha1
kind: SimulationRun
metadata: {name: demo, namespace: team-a}
spec:
  origin: {latitudeDeg: 41.8796, longitudeDeg: -87.6237, altitudeMslM: 181}
  duration: 1m
  fleet:
    - name: scouts
      count: 3
      airframe: x500
      operator: acme
      homes: {randomInArea: {center: {latitudeDeg: 41.8826, longitudeDeg: -87.6225}, radiusM: 100}}
      altitude: {maxAglM: 60}
      mission: {items: [{takeoff: {altitudeAglM: 20}}, {land: {}}]}
"#;

fn render(text: &str, namespace: Option<&str>) -> Result<String, String> {
    let mut out = Vec::new();
    write_manifests(text, namespace, &ClusterSettings::default(), &mut out)?;
    Ok(String::from_utf8(out).unwrap())
}

fn documents(yaml: &str) -> Vec<serde_json::Value> {
    serde_yaml::Deserializer::from_str(yaml).map(|d| serde_json::Value::deserialize(d).unwrap()).collect()
}

#[test]
fn every_child_is_one_yaml_document_with_the_placeholder_uid_explained() {
    let text = render(RUN, None).unwrap();
    assert!(text.starts_with("# sadesim manifests: the children of SimulationRun team-a/demo"), "{text}");
    assert!(text.contains(&format!("placeholder {PLACEHOLDER_UID}")));
    let docs = documents(&text);
    let names: Vec<String> = docs
        .iter()
        .map(|d| format!("{}/{}", d["kind"].as_str().unwrap(), d["metadata"]["name"].as_str().unwrap()))
        .collect();
    // No object-store archive by default: no assets Job (and a warning says so).
    assert_eq!(
        names,
        [
            "ConfigMap/demo-config",
            "ConfigMap/demo-fleet",
            "NetworkPolicy/demo-isolation",
            "Service/demo-airspace",
            "Pod/demo-coordinator",
            "Service/demo-mavlink-0",
            "Pod/demo-router-0",
            "Service/demo-shards",
            "Job/demo-shard",
        ]
    );
    assert!(text.contains("# warning: spec.archive.url: not set"), "{text}");
    for d in &docs {
        assert_eq!(d["metadata"]["namespace"], "team-a");
        assert_eq!(d["metadata"]["ownerReferences"][0]["uid"], PLACEHOLDER_UID);
    }
}

#[test]
fn the_namespace_flag_wins_and_a_real_uid_is_kept() {
    let with_uid = RUN.replace("namespace: team-a}", "namespace: team-a, uid: 1b4e28ba-2fa1-11d2-883f-0016d3cca427}");
    let text = render(&with_uid, Some("team-b")).unwrap();
    assert!(!text.contains("placeholder"));
    for d in documents(&text) {
        assert_eq!(d["metadata"]["namespace"], "team-b");
        assert_eq!(d["metadata"]["ownerReferences"][0]["uid"], "1b4e28ba-2fa1-11d2-883f-0016d3cca427");
    }
    // The in-cluster addresses follow the namespace.
    assert!(text.contains("demo-airspace.team-b.svc:7400"));
}

#[test]
fn several_runs_are_printed_one_after_the_other() {
    let two = format!("{RUN}\n---\n{}", RUN.replace("name: demo", "name: other"));
    let text = render(&two, None).unwrap();
    let docs = documents(&text);
    assert_eq!(docs.len(), 18);
    assert!(docs.iter().any(|d| d["metadata"]["name"] == "other-shard"));
}

#[test]
fn an_invalid_run_is_an_error_naming_the_field_and_prints_nothing() {
    let bad = RUN.replace("count: 3", "count: 0");
    let mut out = Vec::new();
    let e = write_manifests(&bad, None, &ClusterSettings::default(), &mut out).unwrap_err();
    assert!(e.contains("spec.fleet[0].count"), "{e}");
    assert!(out.is_empty());
}

#[test]
fn a_run_the_operator_refuses_says_so_at_the_top() {
    let piloted = RUN.replace("      mission: {items: [{takeoff: {altitudeAglM: 20}}, {land: {}}]}\n", "")
        + "  pilot: {command: [python3, pilot.py]}\n";
    let text = render(&piloted, None).unwrap();
    assert!(text.contains("# error (the operator fails this run with Valid=False"), "{text}");
    assert!(text.contains("spec.pilot.image: required on Kubernetes"), "{text}");
    assert!(!text.contains("demo-pilot"));
}

#[test]
fn a_world_file_on_a_local_path_is_refused_as_the_operator_refuses_it() {
    let mapped =
        RUN.replace("  duration: 1m\n", "  duration: 1m\n  world: {terrain: {dem: {file: maps/N41W088.hgt}}}\n");
    let mut out = Vec::new();
    let e = write_manifests(&mapped, None, &ClusterSettings::default(), &mut out).unwrap_err();
    assert!(e.starts_with("document 1: spec.world.terrain.dem.file: \"maps/N41W088.hgt\" is a path"), "{e}");
    assert!(out.is_empty());
}
