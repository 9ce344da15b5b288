//! The run as one Kueue Workload: its podSets, the flavors Kueue chose, the label only with
//! Kueue on.

use super::super::tests::*;
use super::super::*;
use sadesim_crds::SimulationRun;

/// A run that names a Kueue LocalQueue.
trait Queue {
    fn with_queue(self, q: &str) -> Self;
}

impl Queue for SimulationRun {
    fn with_queue(mut self, q: &str) -> Self {
        self.spec.queue = Some(q.into());
        self
    }
}

/// With Kueue, the run is one Workload: a podSet per role with the pods' own templates and
/// counts, so Kueue reserves exactly what the run's pods request, all at once. No Job is
/// labelled for Kueue or suspended (the run is admitted before any Job exists).
#[test]
fn a_queued_run_is_one_kueue_workload_with_a_pod_set_per_role() {
    let mut run = piloted(3).with_queue("team-a");
    run.spec.fleet[0].count = 600; // 3 shards, 3 router segments
    let plan = planned(&run);
    let settings = ClusterSettings { kueue: true, ..s3() };
    let children = children(&run, &plan, &settings, Stage::ALL);
    assert_eq!(count_key(&json(&children), "suspend"), 0);
    let Some(Child::Workload(w)) = workload(&run, &plan, &settings) else { panic!("a queued run has a Workload") };
    let w = &w;
    assert_eq!(w.metadata.name.as_deref(), Some("test-run"));
    assert_eq!(w.spec.queue_name, "team-a");
    // Kueue's visibility API dereferences spec.priority of every pending Workload.
    assert_eq!(serde_json::to_value(&w.spec).unwrap()["priority"], 0);
    assert_eq!(w.metadata.labels.as_ref().unwrap()[KUEUE_QUEUE_LABEL], "team-a");
    let owner = &w.metadata.owner_references.as_ref().unwrap()[0];
    assert_eq!((owner.kind.as_str(), owner.controller), ("SimulationRun", Some(true)));
    for c in &children {
        assert!(c.labels().unwrap().get(KUEUE_QUEUE_LABEL).is_none(), "{} is not queued by itself", c.name());
    }
    let sets: Vec<(&str, i32)> = w.spec.pod_sets.iter().map(|p| (p.name.as_str(), p.count)).collect();
    let (shards, segments) = (plan.shards.len() as i32, plan.segments.len() as i32);
    assert!(shards >= 2 && segments >= 2, "{shards} shards, {segments} segments");
    assert_eq!(sets, [("assets", 1), ("coordinator", 1), ("router", segments), ("shard", shards), ("pilot", 1)]);
    // Each podSet's requests are its pods' requests.
    let requests = |spec: &k8s_openapi::api::core::v1::PodSpec| {
        spec.containers.iter().map(|c| c.resources.as_ref().unwrap().requests.clone()).collect::<Vec<_>>()
    };
    for (name, spec) in pod_specs(&children) {
        let role = children.iter().find(|c| c.name() == name).and_then(|c| c.role()).unwrap();
        let set = w.spec.pod_sets.iter().find(|p| p.name == role.label()).expect("a podSet per role");
        assert_eq!(requests(set.template.spec.as_ref().unwrap()), requests(&spec), "{name}");
    }
    assert_eq!(kueue_queue(&plan, &settings), Some("team-a"));
    // The Workload validates as Kueue's CRD would have it: at most 8 podSets, DNS-label names.
    assert!(w.spec.pod_sets.len() <= 8);
    let value = serde_json::to_value(w).unwrap();
    assert_eq!(value["apiVersion"], "kueue.x-k8s.io/v1beta2");
    assert_eq!(value["kind"], "Workload");
}

/// Kueue's admission names a ResourceFlavor per podSet: each role's pods get that flavor's
/// node labels and tolerations, and only that role's.
#[test]
fn admitted_pods_go_to_the_flavor_kueue_chose_for_their_role() {
    use k8s_openapi::api::core::v1::Toleration;
    let run = piloted(3).with_queue("team-a");
    let plan = planned(&run);
    let settings = ClusterSettings { kueue: true, ..s3() };
    let mut children = children(&run, &plan, &settings, Stage::ALL);
    let assignments = vec![
        PodSetAssignment {
            name: "shard".into(),
            flavors: [("cpu".into(), "spot".into()), ("memory".into(), "spot".into())].into(),
        },
        PodSetAssignment { name: "coordinator".into(), flavors: [("cpu".into(), "on-demand".into())].into() },
    ];
    let spot = FlavorPlacement {
        node_labels: [("cloud.example.com/capacity".into(), "spot".into())].into(),
        tolerations: vec![Toleration {
            key: Some("spot".into()),
            operator: Some("Exists".into()),
            ..Default::default()
        }],
    };
    let flavors = [("spot".to_string(), spot.clone()), ("on-demand".to_string(), FlavorPlacement::default())].into();
    place(&mut children, &assignments, &flavors);
    for (name, spec) in pod_specs(&children) {
        let on_spot = name.starts_with("test-run-shard");
        let selector = spec.node_selector.clone().unwrap_or_default();
        assert_eq!(selector == spot.node_labels, on_spot, "{name}: {selector:?}");
        assert_eq!(spec.tolerations.clone().unwrap_or_default() == spot.tolerations, on_spot, "{name}");
    }
}

#[test]
fn without_a_queue_or_with_kueue_off_no_kueue_label_appears() {
    for (queue, kueue) in [(None, true), (Some("team-a"), false)] {
        let mut run = piloted(3);
        run.spec.queue = queue.map(String::from);
        let plan = planned(&run);
        let children = children(&run, &plan, &ClusterSettings { kueue, ..s3() }, Stage::ALL);
        let text = serde_json::to_string(&children).unwrap();
        assert!(!text.contains("kueue.x-k8s.io"), "queue {queue:?}, kueue {kueue}");
        assert_eq!(count_key(&json(&children), "suspend"), 0);
    }
}

/// `spec.queue` on an operator without Kueue is refused (Valid=False), not ignored: the run
/// would otherwise bypass the quota its team asked to be admitted under.
#[test]
fn a_queue_without_the_kueue_integration_is_refused_naming_the_field() {
    let mut run = piloted(1);
    run.spec.queue = Some("team-a".into());
    let plan = planned(&run);
    let off = problems(&plan, &s3());
    let found = off.iter().find(|p| p.field == "spec.queue").expect("refused");
    assert!(
        found.fatal && found.message.contains("\"team-a\"") && found.message.contains("kueue.enabled"),
        "{found:?}"
    );
    let on = ClusterSettings { kueue: true, ..s3() };
    assert!(!problems(&plan, &on).iter().any(|p| p.field == "spec.queue"));
    // Without spec.queue nothing is said either way.
    run.spec.queue = None;
    assert!(!problems(&planned(&run), &s3()).iter().any(|p| p.field == "spec.queue"));
}
