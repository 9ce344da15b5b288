//! `<run>-isolation`: the run's NetworkPolicy (issue 19, "isolation per run"). On a shared
//! cluster nothing else stops one team's pod from commanding another team's drones: the
//! MAVLink routers, the drone endpoints on the shard pods and the airspace API accept
//! whoever reaches them.
//!
//! The policy selects every pod of the run but the renderer (whose page is read-only and
//! is reached by port-forward or an Ingress) and admits, on ingress:
//! - any port from the run's own pods (the shard link, MAVLink between router, shards and
//!   pilot, the airspace API the pilot calls, the cameras it reads);
//! - from `spec.groundStations.allowFrom` (CIDRs): the routers' GCS ports (UDP and TCP),
//!   the drone endpoints (UDP and TCP, one range) and the airspace API.
//!
//! Egress is not restricted: pods reach object storage, DNS and the image registry as
//! before. Enforcement needs a CNI that implements NetworkPolicy (Calico, Cilium; k3d's
//! default does, kind's kindnet since Kubernetes 1.29); docs/kubernetes.md says so.

use k8s_openapi::api::networking::v1::{
    IPBlock, NetworkPolicy, NetworkPolicyIngressRule, NetworkPolicyPeer, NetworkPolicyPort, NetworkPolicySpec,
};
use k8s_openapi::apimachinery::pkg::apis::meta::v1::{LabelSelector, LabelSelectorRequirement};
use k8s_openapi::apimachinery::pkg::util::intstr::IntOrString;

use super::pod::Context;
use super::{ROLE_LABEL, RUN_LABEL, Role, names};

/// The pods the policy isolates: the run's, but the renderer.
fn isolated_pods(ctx: &Context) -> LabelSelector {
    LabelSelector {
        match_labels: Some([(RUN_LABEL.to_string(), ctx.name.to_string())].into()),
        match_expressions: Some(vec![LabelSelectorRequirement {
            key: ROLE_LABEL.into(),
            operator: "NotIn".into(),
            values: Some(vec![Role::Renderer.label().into()]),
        }]),
    }
}

fn port(protocol: &str, port: u16, end_port: Option<u16>) -> NetworkPolicyPort {
    NetworkPolicyPort {
        protocol: Some(protocol.into()),
        port: Some(IntOrString::Int(port.into())),
        end_port: end_port.filter(|end| *end > port).map(i32::from),
    }
}

/// What ground stations may reach: every router's GCS ports, the drones' endpoints (one
/// range, UDP and TCP) and the airspace API.
fn ground_station_ports(ctx: &Context) -> Vec<NetworkPolicyPort> {
    let plan = ctx.plan;
    let mut ports = Vec::new();
    for s in &plan.segments {
        ports.push(port("UDP", s.gcs_udp, None));
        ports.push(port("TCP", s.gcs_tcp, None));
    }
    let endpoints = plan.drones.iter().map(|d| d.ports.endpoint);
    if let (Some(first), Some(last)) = (endpoints.clone().min(), endpoints.max()) {
        ports.push(port("UDP", first, Some(last)));
        ports.push(port("TCP", first, Some(last)));
    }
    ports.push(port("TCP", plan.services.airspace_http, None));
    ports
}

/// `<run>-isolation`.
pub(super) fn network_policy(ctx: &Context) -> NetworkPolicy {
    let own_pods = NetworkPolicyPeer {
        pod_selector: Some(LabelSelector {
            match_labels: Some([(RUN_LABEL.to_string(), ctx.name.to_string())].into()),
            match_expressions: None,
        }),
        ..Default::default()
    };
    let mut ingress = vec![NetworkPolicyIngressRule { from: Some(vec![own_pods]), ports: None }];
    let allowed = ctx.plan.spec.ground_stations.as_ref().map(|g| g.allow_from.as_slice()).unwrap_or_default();
    if !allowed.is_empty() {
        let from = allowed
            .iter()
            .map(|cidr| NetworkPolicyPeer {
                ip_block: Some(IPBlock { cidr: cidr.clone(), except: None }),
                ..Default::default()
            })
            .collect();
        ingress.push(NetworkPolicyIngressRule { from: Some(from), ports: Some(ground_station_ports(ctx)) });
    }
    NetworkPolicy {
        metadata: ctx.meta(names::isolation(ctx.name), Role::Network),
        spec: Some(NetworkPolicySpec {
            pod_selector: Some(isolated_pods(ctx)),
            policy_types: Some(vec!["Ingress".into()]),
            ingress: Some(ingress),
            egress: None,
        }),
    }
}

#[cfg(test)]
mod tests;
