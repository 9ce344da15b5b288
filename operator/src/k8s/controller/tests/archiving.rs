//! Reconciling a run that ended, was aborted or deleted: pod logs archived before their
//! workloads go, the finalizer last.

use super::*;

/// Settings that archive into the folder `tmp` (`file://`, which a cluster refuses; the
/// controller tests allow it to read what was archived).
fn archive_into(tmp: &std::path::Path) -> ClusterSettings {
    ClusterSettings {
        default_archive_url: Some(format!("file://{}", tmp.display())),
        file_archives: true,
        ..Default::default()
    }
}

#[tokio::test]
async fn a_finished_coordinator_ends_the_run_and_stops_the_shards_first() {
    let mut run = in_phase(new_run(), Phase::Running);
    run.status.as_mut().unwrap().start_time = Some(Time(t0()));
    let summary = json!({"type": "finished", "summary": {
        "run": "test-run", "endReason": "duration", "simTimeS": 120.0, "wallTimeS": 40.0, "realTimeFactor": 3.0,
        "drones": 1, "shards": 1, "airborne": 0, "crashed": 0, "events": 12, "pilotsReleasedAtS": 0.01, "perDrone": [],
        "verdict": {"passed": true, "criteria": []}}});
    let cluster = Cluster {
        run: Some(run),
        jobs: vec![job("shard", Some("Complete"), 0)],
        pods: vec![
            pod("test-run-shard-0", "shard", "Succeeded", true),
            pod("test-run-coordinator", "coordinator", "Succeeded", false),
        ],
        logs: BTreeMap::from([("test-run-coordinator".to_string(), format!("{summary}\n"))]),
        ..Default::default()
    };
    // The archive is an object store the test does not reach: no logs are due in this step.
    let tmp = tempdir("finished");
    let settings = archive_into(&tmp);
    let (seen, _) = reconcile_once(cluster, settings, t0() + SignedDuration::from_secs(40)).await;
    assert!(applies(&seen).is_empty(), "nothing is created once the run ended: {:?}", paths(&seen));
    let delete = seen.iter().find(|s| s.method == Method::DELETE).expect("shards stopped");
    assert_eq!(delete.path, format!("/apis/batch/v1/namespaces/{NS}/jobs"));
    assert_eq!(
        delete.query.get("labelSelector").map(String::as_str),
        Some("sadesim.io/run=test-run,sadesim.io/role=shard")
    );
    assert_eq!(delete.body["propagationPolicy"], "Background");
    // The shard pod's log went to the archive before the delete.
    let log = std::fs::read_to_string(tmp.join("team-a/test-run/uid-1/logs/test-run-shard-0.log")).unwrap();
    assert!(log.contains("could not be read"), "{log}");
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Archiving));
    assert_eq!(status.sim_time_s, Some(120.0));
    assert_eq!(status.real_time_factor, Some(3.0));
    assert_eq!(status.verdict.as_ref().map(|v| v.passed), Some(true));
    assert_eq!(condition(&status, ct::RUNNING).reason, "Finished");
    assert_eq!(event_reasons(&seen), ["Archiving"]);
}

#[tokio::test]
async fn abort_stops_the_pilot_first_archiving_its_log() {
    let mut run = in_phase(pilot_run(), Phase::Running);
    run.spec.abort = true;
    run.metadata.generation = Some(2);
    let tmp = tempdir("abort");
    let cluster = Cluster {
        run: Some(run),
        jobs: vec![job("shard", None, 1), job("pilot", None, 1)],
        pods: vec![
            pod("test-run-shard-0", "shard", "Running", true),
            pod("test-run-pilot-x1", "pilot", "Running", true),
            pod("test-run-coordinator", "coordinator", "Running", false),
        ],
        logs: BTreeMap::from([
            ("test-run-pilot-x1".to_string(), "pilot says hello\n".to_string()),
            ("test-run-coordinator".to_string(), String::new()),
        ]),
        ..Default::default()
    };
    let settings = archive_into(&tmp);
    let (seen, _) = reconcile_once(cluster, settings, t0()).await;
    let order: Vec<String> = seen
        .iter()
        .filter(|s| {
            matches!(s.method, Method::DELETE)
                || s.path.ends_with("/test-run-pilot-x1/log")
                || s.path.ends_with("/status")
        })
        .map(|s| format!("{} {}", s.method, s.path.rsplit('/').take(2).collect::<Vec<_>>().join("<")))
        .collect();
    assert_eq!(
        order,
        ["GET log<test-run-pilot-x1", "DELETE jobs<team-a", "PATCH status<test-run"],
        "{:?}",
        paths(&seen)
    );
    let delete = seen.iter().find(|s| s.method == Method::DELETE).unwrap();
    assert_eq!(
        delete.query.get("labelSelector").map(String::as_str),
        Some("sadesim.io/run=test-run,sadesim.io/role=pilot")
    );
    let folder = tmp.join("team-a/test-run/uid-1");
    assert_eq!(std::fs::read_to_string(folder.join("logs/test-run-pilot-x1.log")).unwrap(), "pilot says hello\n");
    let manifest: Value = serde_json::from_slice(&std::fs::read(folder.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["files"][0]["path"], "logs/test-run-pilot-x1.log");
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Archiving));
    assert_eq!(condition(&status, ct::RUNNING).reason, "Aborted");
    assert_eq!(status.observed_generation, Some(2));
    assert!(applies(&seen).is_empty());
}

#[tokio::test]
async fn deletion_archives_the_remaining_logs_then_removes_the_finalizer() {
    let mut run = in_phase(new_run(), Phase::Archiving);
    run.metadata.deletion_timestamp = Some(Time(t0()));
    let tmp = tempdir("delete");
    let cluster = Cluster {
        run: Some(run),
        pods: vec![
            pod("test-run-coordinator", "coordinator", "Succeeded", false),
            pod("test-run-router-0", "router", "Running", false),
        ],
        logs: BTreeMap::from([
            ("test-run-coordinator".to_string(), "{\"type\":\"listening\"}\n".to_string()),
            ("test-run-router-0".to_string(), "router up\n".to_string()),
        ]),
        ..Default::default()
    };
    let settings = archive_into(&tmp);
    let (seen, _) = reconcile_once(cluster, settings, t0()).await;
    let deletes: Vec<String> = seen.iter().filter(|s| s.method == Method::DELETE).map(|s| s.path.clone()).collect();
    assert_eq!(
        deletes,
        [
            "/apis/batch/v1/namespaces/team-a/jobs",
            "/api/v1/namespaces/team-a/pods",
            "/apis/apps/v1/namespaces/team-a/deployments",
            "/api/v1/namespaces/team-a/services",
        ]
    );
    let folder = tmp.join("team-a/test-run/uid-1");
    assert_eq!(std::fs::read_to_string(folder.join("logs/test-run-router-0.log")).unwrap(), "router up\n");
    assert!(folder.join("logs/test-run-coordinator.log").exists());
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Aborted));
    assert_eq!(condition(&status, ct::ARCHIVED).status, "True");
    assert_eq!(status.archive.as_ref().unwrap().files, Some(2));
    // The finalizer goes last, after the status.
    let last = seen.last().unwrap();
    assert!(last.is(Method::PATCH, &format!("{RUNS}/test-run")), "{:?}", paths(&seen));
    assert_eq!(last.body, json!({"metadata": {"finalizers": [], "resourceVersion": "42"}}));
    let archive = seen.iter().position(|s| s.path.ends_with("/log")).unwrap();
    let first_delete = seen.iter().position(|s| s.method == Method::DELETE).unwrap();
    assert!(archive < first_delete, "logs are read before anything is deleted");
}

#[tokio::test]
async fn deleting_a_finished_run_only_removes_the_finalizer() {
    let mut run = in_phase(new_run(), Phase::Succeeded);
    run.metadata.deletion_timestamp = Some(Time(t0()));
    let (seen, _) = reconcile_once(Cluster { run: Some(run), ..Default::default() }, s3_settings(), t0()).await;
    assert_eq!(paths(&seen), [format!("PATCH {RUNS}/test-run")]);
    assert_eq!(seen[0].body["metadata"]["finalizers"], json!([]));
}
