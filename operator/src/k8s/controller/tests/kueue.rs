//! Reconciling a run admitted through Kueue: the Workload alone until admission, then the run.

use super::*;

const WORKLOAD: &str = "/apis/kueue.x-k8s.io/v1beta2/namespaces/team-a/workloads/test-run";

/// The run's Workload as Kueue shows it, with `conditions` (`type`, `status`, `reason`,
/// `message`) and, once quota is reserved, every podSet admitted to the flavor `spot`.
fn kueue_workload(conditions: &[(&str, &str, &str, &str)]) -> Value {
    let reserved = conditions.iter().any(|c| c.0 == "QuotaReserved" && c.1 == "True");
    let conditions: Vec<Value> = conditions
        .iter()
        .map(|(t, st, r, m)| {
            json!({"type": t, "status": st, "reason": r, "message": m, "lastTransitionTime": "2027-01-15T08:00:00Z"})
        })
        .collect();
    let assignments: Vec<Value> = ["assets", "coordinator", "router", "shard", "pilot"]
        .iter()
        .map(|name| json!({"name": name, "flavors": {"cpu": "spot", "memory": "spot"}, "count": 1}))
        .collect();
    let mut status = json!({"conditions": conditions});
    if reserved {
        status["admission"] = json!({"clusterQueue": "shared-cq", "podSetAssignments": assignments});
    }
    json!({
        "apiVersion": "kueue.x-k8s.io/v1beta2",
        "kind": "Workload",
        "metadata": {"name": "test-run", "namespace": NS, "resourceVersion": "7"},
        "spec": {"queueName": "team-a-queue", "podSets": []},
        "status": status,
    })
}

/// With Kueue the whole run is one Workload: while Kueue holds it, the operator applies
/// only the Workload (no Job, Pod or ConfigMap exists), reads the queue position from
/// Kueue's visibility API and shows it; once Kueue admits it, every role is created —
/// the pilot with the shards, none labelled for Kueue or suspended — on the flavor Kueue
/// chose.
#[tokio::test]
async fn with_kueue_the_whole_run_is_one_workload_admitted_at_once() {
    let mut run = pilot_run();
    run.spec.queue = Some("team-a-queue".into());
    let settings = ClusterSettings { kueue: true, ..s3_settings() };

    // 1. New: the Workload is applied, nothing else; no quota or queue of our own is read.
    let cluster = Cluster { run: Some(run.clone()), ..Default::default() };
    let (seen, _) = reconcile_once(cluster, settings.clone(), t0()).await;
    assert!(!seen.iter().any(|s| s.path.ends_with("/resourcequotas") || s.path == RUNS), "{:?}", paths(&seen));
    let applied = applies(&seen);
    assert_eq!(applied.iter().map(|s| s.path.as_str()).collect::<Vec<_>>(), [WORKLOAD], "{:?}", paths(&seen));
    assert_apply(applied[0]);
    let body = &applied[0].body;
    assert_eq!(
        (body["apiVersion"].as_str(), body["kind"].as_str()),
        (Some("kueue.x-k8s.io/v1beta2"), Some("Workload"))
    );
    assert_eq!(body["spec"]["queueName"], "team-a-queue");
    let sets: Vec<&str> =
        body["spec"]["podSets"].as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert_eq!(sets, ["assets", "coordinator", "router", "shard", "pilot"]);
    assert_eq!(body["metadata"]["ownerReferences"][0]["kind"], "SimulationRun");
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Queued));
    assert_eq!(condition(&status, ct::SCHEDULED).reason, "KueuePending");

    // 2. Pending behind another team's run: position from the visibility API, Kueue's reason.
    let queued = in_phase(run.clone(), Phase::Queued);
    let pending = json!({"kind": "PendingWorkloadsSummary", "apiVersion": "visibility.kueue.x-k8s.io/v1beta2", "metadata": {}, "items": [
        {"metadata": {"name": "other-run", "namespace": NS}, "priority": 0, "localQueueName": "team-a-queue", "positionInClusterQueue": 0, "positionInLocalQueue": 0},
        {"metadata": {"name": "test-run", "namespace": NS}, "priority": 0, "localQueueName": "team-a-queue", "positionInClusterQueue": 2, "positionInLocalQueue": 1}
    ]});
    let waiting = kueue_workload(&[(
        "QuotaReserved",
        "False",
        "Pending",
        "couldn't assign flavors to pod set shard: insufficient unused quota for cpu in flavor spot",
    )]);
    let cluster =
        Cluster { run: Some(queued.clone()), workload: Some(waiting), pending: Some(pending), ..Default::default() };
    let (seen, _) = reconcile_once(cluster, settings.clone(), t0()).await;
    assert!(seen.iter().any(|s| s.path
        == "/apis/visibility.kueue.x-k8s.io/v1beta2/namespaces/team-a/localqueues/team-a-queue/pendingworkloads"));
    assert!(!applies(&seen).iter().any(|s| !s.path.contains("/workloads/")), "{:?}", paths(&seen));
    let status = the_status_write(&seen);
    let k = status.kueue.as_ref().unwrap();
    assert_eq!((k.workload.as_str(), k.state.as_str()), ("test-run", "Pending"));
    assert_eq!((k.position_in_local_queue, k.position_in_cluster_queue), (Some(1), Some(2)));
    assert!(k.message.as_deref().unwrap().contains("insufficient unused quota"));
    assert!(condition(&status, ct::SCHEDULED).message.contains("position 1 in the LocalQueue"));

    // A Kueue without the visibility API: no position, and the run still waits.
    let waiting = kueue_workload(&[("QuotaReserved", "False", "Pending", "")]);
    let cluster = Cluster { run: Some(queued.clone()), workload: Some(waiting), ..Default::default() };
    let (seen, _) = reconcile_once(cluster, settings.clone(), t0()).await;
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::Queued));
    assert_eq!(status.kueue.unwrap().position_in_local_queue, None);

    // 3. Admitted onto the flavor `spot`: the config and assets Job start, on spot nodes.
    let admitted = kueue_workload(&[
        ("QuotaReserved", "True", "QuotaReserved", "Quota reserved in ClusterQueue shared-cq"),
        ("Admitted", "True", "Admitted", "The workload is admitted"),
    ]);
    let spot = json!({"apiVersion": "kueue.x-k8s.io/v1beta2", "kind": "ResourceFlavor", "metadata": {"name": "spot"},
        "spec": {"nodeLabels": {"instance-type": "spot"}, "tolerations": [{"key": "spot", "operator": "Exists", "effect": "NoSchedule"}]}});
    let flavors = BTreeMap::from([("spot".to_string(), spot)]);
    let cluster =
        Cluster { run: Some(queued), workload: Some(admitted.clone()), flavors: flavors.clone(), ..Default::default() };
    let (seen, metrics) = reconcile_once(cluster, settings.clone(), t0()).await;
    assert!(seen.iter().any(|s| s.path == "/apis/kueue.x-k8s.io/v1beta2/resourceflavors/spot"));
    let status = the_status_write(&seen);
    assert_eq!(status.phase, Some(Phase::GeneratingAssets));
    assert_eq!(condition(&status, ct::SCHEDULED).reason, "AdmittedByKueue");
    assert_eq!(status.kueue.as_ref().unwrap().cluster_queue.as_deref(), Some("shared-cq"));
    let assets = applies(&seen).into_iter().find(|s| s.path.ends_with("/jobs/test-run-assets")).expect("assets Job");
    assert_eq!(assets.body["spec"]["template"]["spec"]["nodeSelector"]["instance-type"], "spot");
    assert!(!applies(&seen).iter().any(|s| s.path.contains("/workloads/")), "the Workload is not re-applied");
    assert!(
        metrics.encode().contains("sadesim_operator_queue_wait_seconds_count 1"),
        "the wait for admission is measured"
    );

    // 4. Starting: shards and pilot together, unlabelled, never suspended, on spot.
    let mut started = in_phase(run, Phase::Starting);
    started.status.as_mut().unwrap().conditions = vec![];
    let cluster = Cluster {
        run: Some(started),
        jobs: vec![job("shard", None, 1)],
        workload: Some(admitted),
        flavors,
        ..Default::default()
    };
    let (seen, _) = reconcile_once(cluster, settings, t0()).await;
    let jobs: Vec<&Seen> = applies(&seen).into_iter().filter(|s| s.path.contains("/jobs/")).collect();
    let names: Vec<&str> = jobs.iter().map(|s| s.path.rsplit('/').next().unwrap()).collect();
    assert_eq!(names, ["test-run-shard", "test-run-pilot"]);
    for j in jobs {
        assert!(j.body["metadata"]["labels"].get(KUEUE_QUEUE_LABEL).is_none(), "{}", j.path);
        assert!(j.body["spec"].get("suspend").is_none(), "{}", j.path);
        let spec = &j.body["spec"]["template"]["spec"];
        assert_eq!(spec["nodeSelector"]["instance-type"], "spot", "{}", j.path);
        assert_eq!(spec["tolerations"][0]["key"], "spot", "{}", j.path);
    }
}
