//! Kueue: which children a queued run hands to Kueue, and how.
//!
//! We use Kueue's built-in `batch/v1` Job integration (on in every Kueue install): a Job
//! labelled `kueue.x-k8s.io/queue-name` becomes one Kueue Workload, and Kueue admits all of
//! its pods at once or none. The run's gang is the shards' Indexed Job (every shard pod, the
//! bulk of the run's CPU and memory); the assets and pilot Jobs are small Workloads of their
//! own. Kueue's webhook suspends each labelled Job on creation and resumes it on admission:
//! the operator never writes `spec.suspend`, so its server-side applies never fight Kueue.
//!
//! The coordinator and router pods are plain pods outside Kueue (fixed and small: ~0.25 CPU
//! plus 0.1 per 250 drones); they idle until the shards are admitted. Plain-pod groups would
//! put them in the gang too, but Kueue ignores pods owned by a Job, so the shards would have
//! to be bare pods, and the pod integration must be enabled cluster-wide. docs/kubernetes.md
//! has the full reasoning.

use std::collections::BTreeMap;

use super::ClusterSettings;
use sadesim_crds::plan::RunPlan;

/// The label that hands a Job to a Kueue LocalQueue.
pub const KUEUE_QUEUE_LABEL: &str = "kueue.x-k8s.io/queue-name";

/// The LocalQueue of the run, when Kueue is on and the run names one.
pub fn kueue_queue<'a>(plan: &'a RunPlan, settings: &ClusterSettings) -> Option<&'a str> {
    plan.spec.queue.as_deref().filter(|_| settings.kueue)
}

/// Adds the queue label to a Job's labels when the run goes through Kueue.
pub(super) fn label_job(labels: &mut Option<BTreeMap<String, String>>, plan: &RunPlan, settings: &ClusterSettings) {
    if let Some(queue) = kueue_queue(plan, settings) {
        labels.get_or_insert_with(BTreeMap::new).insert(KUEUE_QUEUE_LABEL.into(), queue.into());
    }
}
