//! Kueue: the whole run as one Kueue Workload, admitted as one gang.
//!
//! A run with `spec.queue` (under an operator with Kueue on) is first only a Workload
//! `<run>` (`kueue.x-k8s.io/v1beta2`) in its namespace, owned by the run, with one podSet
//! per role: assets, coordinator, router (one pod per segment), shard (one per shard),
//! renderer and pilot, each with the pod template the operator will create, so Kueue counts
//! exactly what the run's pods request. Kueue reserves quota for all of them at once or for
//! none (preempting, borrowing from the cohort, per its ClusterQueue's rules) and marks the
//! Workload `Admitted`. Only then does the operator create the run's children, none of them
//! labelled for Kueue (the run was admitted already), each pod placed on the ResourceFlavor
//! Kueue chose for its role ([`place`]).
//!
//! This is the contract Kueue offers custom workload controllers (AppWrapper's pattern):
//! the controller owns the Workload, waits for `Admitted`, stops on `Evicted`. Why not the
//! alternatives (docs/kubernetes.md, "Why one Workload"):
//! - Kueue's Job integration makes one Workload per Job: the shards, the pilot and the
//!   assets Job would be admitted separately, so a full queue could leave a run flying
//!   without its pilot, and the coordinator and routers (plain pods) would not be counted.
//! - Plain-pod groups need bare pods (the shards are an Indexed Job) and the pod
//!   integration on cluster-wide.
//! - A JobSet needs the JobSet controller installed, and the coordinator, routers and the
//!   renderer are not run-to-completion Jobs.
//!
//! On clusters where Kueue manages Jobs without a queue label
//! (`manageJobsWithoutQueueName: true`), Kueue must know that the run's Jobs belong to a
//! Kueue-managed owner: its configuration lists `SimulationRun.v1alpha1.sadesim.io` under
//! `integrations.externalFrameworks` (the Helm chart's `kueue` notes and
//! docs/kubernetes.md show it); the Jobs carry a controller ownerReference to the run.

use std::collections::BTreeMap;

use k8s_openapi::api::core::v1::{PodTemplateSpec, Toleration};
use k8s_openapi::apimachinery::pkg::apis::meta::v1::{Condition, ObjectMeta};
use kube::CustomResource;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::status::KueueStatus;
use serde::{Deserialize, Serialize};

use super::{Child, ClusterSettings, Role};

/// The label that names the LocalQueue of a Workload.
pub const KUEUE_QUEUE_LABEL: &str = "kueue.x-k8s.io/queue-name";

/// Kueue's API group and the version the operator speaks (served since Kueue 0.15; the
/// e2e walkthrough pins Kueue 0.19).
pub const KUEUE_API_VERSION: &str = "kueue.x-k8s.io/v1beta2";

/// The Workload's conditions the operator reads.
pub mod condition {
    pub const QUOTA_RESERVED: &str = "QuotaReserved";
    pub const ADMITTED: &str = "Admitted";
    pub const EVICTED: &str = "Evicted";
    pub const FINISHED: &str = "Finished";
}

/// A Kueue Workload (`kueue.x-k8s.io/v1beta2`): only the fields the operator writes and
/// reads. Unknown fields Kueue adds are ignored on read and never written (server-side
/// apply leaves them to their managers).
#[derive(CustomResource, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[kube(
    group = "kueue.x-k8s.io",
    version = "v1beta2",
    kind = "Workload",
    namespaced,
    status = "WorkloadStatus",
    schema = "disabled",
    derive = "PartialEq"
)]
#[serde(rename_all = "camelCase")]
pub struct WorkloadSpec {
    /// The LocalQueue (`spec.queue` of the run).
    pub queue_name: String,
    /// One per role, at most 8 (Kueue's limit; a run has at most 6).
    pub pod_sets: Vec<PodSet>,
    /// The Workload's priority in its queues: 0, what Kueue's own job integrations give a
    /// workload without a priority class. Kueue reads it without checking: its visibility
    /// API (v0.17.0) panics on a pending Workload without one. (Read as 0 when absent.)
    #[serde(default)]
    pub priority: i32,
}

/// Pods of one role: `count` pods from `template`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct PodSet {
    /// The role's label (`shard`, `router`, ...).
    pub name: String,
    pub count: i32,
    pub template: PodTemplateSpec,
}

/// What Kueue says about the Workload.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct WorkloadStatus {
    #[serde(default)]
    pub conditions: Vec<Condition>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub admission: Option<WorkloadAdmission>,
}

impl Workload {
    /// Kueue's condition `type_`, when it has set one.
    pub fn condition(&self, type_: &str) -> Option<&Condition> {
        self.status.as_ref()?.conditions.iter().find(|c| c.type_ == type_)
    }

    /// Kueue's condition `type_` is `True`.
    pub fn is(&self, type_: &str) -> bool {
        self.condition(type_).is_some_and(|c| c.status == "True")
    }
}

/// Where Kueue admitted the Workload.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct WorkloadAdmission {
    #[serde(default)]
    pub cluster_queue: String,
    #[serde(default)]
    pub pod_set_assignments: Vec<PodSetAssignment>,
}

/// The ResourceFlavor chosen per resource for one podSet.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct PodSetAssignment {
    pub name: String,
    /// Resource name (`cpu`, `memory`, `nvidia.com/gpu`) -> ResourceFlavor name.
    #[serde(default)]
    pub flavors: BTreeMap<String, String>,
}

/// A pending Workload in Kueue's visibility API
/// (`visibility.kueue.x-k8s.io/v1beta2 .../localqueues/<q>/pendingworkloads`).
#[derive(Deserialize, Clone, Debug, PartialEq, Default)]
#[serde(rename_all = "camelCase")]
pub struct PendingWorkload {
    #[serde(default)]
    pub metadata: ObjectMeta,
    #[serde(default)]
    pub position_in_cluster_queue: i32,
    #[serde(default)]
    pub position_in_local_queue: i32,
}

/// The visibility API's answer.
#[derive(Deserialize, Clone, Debug, PartialEq, Default)]
pub struct PendingWorkloadsSummary {
    #[serde(default)]
    pub items: Vec<PendingWorkload>,
}

/// The path of the LocalQueue's pending Workloads in Kueue's visibility API.
pub fn pending_workloads_path(namespace: &str, queue: &str) -> String {
    format!("/apis/visibility.kueue.x-k8s.io/v1beta2/namespaces/{namespace}/localqueues/{queue}/pendingworkloads")
}

/// What a ResourceFlavor (cluster-scoped) asks of the pods placed on it: the spec of
/// `kueue.x-k8s.io/v1beta2 ResourceFlavor`, only `nodeLabels` and `tolerations` (its
/// `nodeTaints` are the nodes' business).
#[derive(CustomResource, Serialize, Deserialize, Clone, Debug, PartialEq, Default)]
#[kube(
    group = "kueue.x-k8s.io",
    version = "v1beta2",
    kind = "ResourceFlavor",
    schema = "disabled",
    derive = "PartialEq"
)]
#[serde(rename_all = "camelCase")]
pub struct FlavorPlacement {
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub node_labels: BTreeMap<String, String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tolerations: Vec<Toleration>,
}

/// The LocalQueue of the run, when Kueue is on and the run names one.
pub fn kueue_queue<'a>(plan: &'a RunPlan, settings: &ClusterSettings) -> Option<&'a str> {
    plan.spec.queue.as_deref().filter(|_| settings.kueue)
}

/// The run's Workload: one podSet per role of `children` (every child of the run's life,
/// [`super::Stage::ALL`]), with the pod template each role's pods are created from and how
/// many there are. `meta` is the Workload's metadata (name, owner, run labels).
pub(super) fn workload(queue: &str, mut meta: ObjectMeta, children: &[Child]) -> Workload {
    let mut sets: Vec<PodSet> = Vec::new();
    let mut add = |role: Role, template: Option<PodTemplateSpec>, count: i32| {
        let Some(template) = template else { return };
        match sets.iter_mut().find(|s| s.name == role.label()) {
            // Routers: one Pod per segment, all from the same template.
            Some(set) => set.count += count,
            None => sets.push(PodSet { name: role.label().into(), count, template }),
        }
    };
    for child in children {
        let Some(role) = child.role() else { continue };
        match child {
            Child::Job(job) => {
                let spec = job.spec.as_ref();
                let count = spec.and_then(|s| s.parallelism.or(s.completions)).unwrap_or(1);
                add(role, spec.map(|s| s.template.clone()), count);
            }
            Child::Pod(pod) => {
                let template = PodTemplateSpec {
                    metadata: Some(ObjectMeta { labels: pod.metadata.labels.clone(), ..Default::default() }),
                    spec: pod.spec.clone(),
                };
                add(role, Some(template), 1);
            }
            Child::Deployment(d) => {
                let spec = d.spec.as_ref();
                add(role, spec.map(|s| s.template.clone()), spec.and_then(|s| s.replicas).unwrap_or(1));
            }
            _ => {}
        }
    }
    meta.labels.get_or_insert_with(BTreeMap::new).insert(KUEUE_QUEUE_LABEL.into(), queue.into());
    Workload {
        metadata: meta,
        spec: WorkloadSpec { queue_name: queue.into(), pod_sets: sets, priority: 0 },
        status: None,
    }
}

/// The state of the run's Workload as the run's status shows it.
pub fn status_of(workload: &Workload, pending: Option<&PendingWorkload>) -> KueueStatus {
    let is = |t: &str| workload.is(t);
    let state = if is(condition::FINISHED) {
        condition::FINISHED
    } else if is(condition::EVICTED) {
        condition::EVICTED
    } else if is(condition::ADMITTED) {
        condition::ADMITTED
    } else if is(condition::QUOTA_RESERVED) {
        condition::QUOTA_RESERVED
    } else {
        "Pending"
    };
    // Kueue's word: why it evicted, else why it waits (QuotaReserved=False says "couldn't
    // assign flavors ..." or "LocalQueue x doesn't exist").
    let said = |t: &str| workload.condition(t).map(|c| c.message.clone()).filter(|m| !m.is_empty());
    let message = match state {
        condition::EVICTED => said(condition::EVICTED),
        "Pending" => said(condition::QUOTA_RESERVED),
        _ => None,
    };
    KueueStatus {
        workload: workload.metadata.name.clone().unwrap_or_default(),
        state: state.into(),
        cluster_queue: workload
            .status
            .as_ref()
            .and_then(|s| s.admission.as_ref())
            .map(|a| a.cluster_queue.clone())
            .filter(|q| !q.is_empty()),
        position_in_local_queue: pending.map(|p| p.position_in_local_queue),
        position_in_cluster_queue: pending.map(|p| p.position_in_cluster_queue),
        message,
    }
}

/// Puts each role's pods on the ResourceFlavor Kueue assigned to its podSet: the flavor's
/// node labels join the pod's nodeSelector and its tolerations the pod's. `flavors` holds
/// the ResourceFlavors named in `assignments`; one not found places nothing (Kueue does not
/// admit onto a flavor that does not exist).
pub fn place(children: &mut [Child], assignments: &[PodSetAssignment], flavors: &BTreeMap<String, FlavorPlacement>) {
    for child in children.iter_mut() {
        let Some(role) = child.role() else { continue };
        let Some(assignment) = assignments.iter().find(|a| a.name == role.label()) else { continue };
        let spec = match child {
            Child::Job(job) => job.spec.as_mut().and_then(|s| s.template.spec.as_mut()),
            Child::Pod(pod) => pod.spec.as_mut(),
            Child::Deployment(d) => d.spec.as_mut().and_then(|s| s.template.spec.as_mut()),
            _ => None,
        };
        let Some(spec) = spec else { continue };
        // One flavor may serve several resources (cpu and memory): apply each once.
        let mut names: Vec<&String> = assignment.flavors.values().collect();
        names.sort();
        names.dedup();
        for flavor in names.into_iter().filter_map(|n| flavors.get(n)) {
            if !flavor.node_labels.is_empty() {
                let selector = spec.node_selector.get_or_insert_with(BTreeMap::new);
                selector.extend(flavor.node_labels.iter().map(|(k, v)| (k.clone(), v.clone())));
            }
            if !flavor.tolerations.is_empty() {
                let tolerations = spec.tolerations.get_or_insert_with(Vec::new);
                for t in &flavor.tolerations {
                    if !tolerations.contains(t) {
                        tolerations.push(t.clone());
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
