//! The run's NetworkPolicy: its own pods and its ground stations, nothing else.

use sadesim_crds::fixtures::RunBuilder;

use super::super::tests::*;
use super::super::*;

/// Whether `selector` selects an object labelled `labels` (matchLabels, In, NotIn: what the
/// run's NetworkPolicy uses).
fn selects(
    selector: &k8s_openapi::apimachinery::pkg::apis::meta::v1::LabelSelector,
    labels: &std::collections::BTreeMap<String, String>,
) -> bool {
    let by_label = selector.match_labels.iter().flatten().all(|(k, v)| labels.get(k) == Some(v));
    let by_expression = selector.match_expressions.iter().flatten().all(|e| {
        let value = labels.get(&e.key);
        let listed = value.is_some_and(|v| e.values.iter().flatten().any(|x| x == v));
        match e.operator.as_str() {
            "In" => listed,
            "NotIn" => !listed,
            other => panic!("operator {other} not expected"),
        }
    });
    by_label && by_expression
}

/// The labels of every pod a child makes (Pods, and the templates of Jobs and Deployments).
fn pod_labels(children: &[Child]) -> Vec<(String, std::collections::BTreeMap<String, String>)> {
    children
        .iter()
        .filter_map(|c| {
            let labels = match c {
                Child::Pod(p) => p.metadata.labels.clone(),
                Child::Job(j) => j.spec.as_ref()?.template.metadata.as_ref()?.labels.clone(),
                Child::Deployment(d) => d.spec.as_ref()?.template.metadata.as_ref()?.labels.clone(),
                _ => None,
            };
            labels.map(|l| (c.name().to_string(), l))
        })
        .collect()
}

/// The run's NetworkPolicy isolates every pod of the run but the renderer: its own pods
/// reach each other on any port, ground stations in `allowFrom` reach only the routers'
/// GCS ports, the drone endpoints and the airspace API, and nothing else gets in.
#[test]
fn the_network_policy_admits_the_run_s_own_pods_and_its_ground_stations_only() {
    use k8s_openapi::apimachinery::pkg::util::intstr::IntOrString;
    use sadesim_crds::ground_stations::GroundStations;
    let mut run = piloted(600).with_drones_per_shard_of(100).tap_rendering();
    let other = children_of(&with_uid(
        RunBuilder::test().with(|r| r.metadata.name = Some("other-run".into())).with_drones(3).build(),
    ));
    let policy_of = |children: &[Child]| match children.iter().find(|c| c.kind() == Kind::NetworkPolicy) {
        Some(Child::NetworkPolicy(p)) => p.clone(),
        _ => panic!("no NetworkPolicy"),
    };
    let children = children_of(&run);
    let policy = policy_of(&children);
    assert_eq!(policy.metadata.name.as_deref(), Some("test-run-isolation"));
    let spec = policy.spec.clone().unwrap();
    assert_eq!(spec.policy_types.as_deref(), Some(&["Ingress".to_string()][..]));
    let isolated = spec.pod_selector.clone().unwrap_or_default();
    let pods = pod_labels(&children);
    assert!(pods.len() >= 6, "{pods:?}");
    for (name, labels) in &pods {
        assert_eq!(selects(&isolated, labels), name != "test-run-renderer", "{name}");
    }
    for (name, labels) in pod_labels(&other) {
        assert!(!selects(&isolated, &labels), "another run's {name}");
    }
    // Without ground stations: one rule, from the run's own pods (every port).
    let ingress = spec.ingress.unwrap();
    assert_eq!(ingress.len(), 1);
    let own = ingress[0].from.as_ref().unwrap()[0].pod_selector.clone().unwrap();
    assert!(ingress[0].ports.is_none());
    assert!(pods.iter().all(|(_, l)| selects(&own, l)));
    assert!(pod_labels(&other).iter().all(|(_, l)| !selects(&own, l)), "another run's pods are not its own");

    // With ground stations: a second rule, from those ranges, to the MAVLink and airspace ports.
    let cidrs = vec!["10.20.0.0/16".to_string(), "192.168.7.0/24".to_string()];
    run.spec.ground_stations = Some(GroundStations { allow_from: cidrs.clone(), signing: None });
    let plan = planned(&run);
    let ingress = policy_of(&super::super::children(&run, &plan, &s3(), Stage::ALL)).spec.unwrap().ingress.unwrap();
    assert_eq!(ingress.len(), 2);
    let from: Vec<String> =
        ingress[1].from.iter().flatten().map(|p| p.ip_block.as_ref().unwrap().cidr.clone()).collect();
    assert_eq!(from, cidrs);
    let ports = ingress[1].ports.clone().unwrap();
    let admits = |protocol: &str, number: u16| {
        ports.iter().any(|p| {
            let IntOrString::Int(first) = p.port.clone().unwrap() else { panic!("named port") };
            let last = p.end_port.unwrap_or(first);
            p.protocol.as_deref() == Some(protocol) && (first..=last).contains(&i32::from(number))
        })
    };
    assert_eq!(plan.segments.len(), 3);
    for s in &plan.segments {
        assert!(admits("UDP", s.gcs_udp) && admits("TCP", s.gcs_tcp), "segment {}", s.index);
    }
    for d in &plan.drones {
        assert!(admits("UDP", d.ports.endpoint) && admits("TCP", d.ports.endpoint), "{}", d.name);
    }
    assert!(admits("TCP", plan.services.airspace_http));
    // Not the shard link, the live stream, or the cameras: those are the run's own.
    assert!(!admits("TCP", plan.services.coordinator) && !admits("TCP", plan.services.renderer_http));
}
