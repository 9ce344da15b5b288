//! What the operator sees of a run's children, reduced to what the phase machine needs:
//! each role's state (pure functions of the Job and Pod objects listed by the run label).

use k8s_openapi::api::batch::v1::Job;
use k8s_openapi::api::core::v1::Pod;

use std::collections::BTreeMap;

use super::progress::CoordinatorReport;
use crate::k8s::children::{
    FlavorPlacement, Kind, PendingWorkload, ROLE_LABEL, Role, Workload as KueueWorkload, workload_condition,
};

/// Label Kubernetes puts on the pods of an Indexed Job: the shard index.
pub const COMPLETION_INDEX_LABEL: &str = "batch.kubernetes.io/job-completion-index";

/// Container waiting reasons that never resolve by themselves: the role has failed.
const FATAL_WAITING_REASONS: [&str; 6] = [
    "ErrImagePull",
    "ImagePullBackOff",
    "InvalidImageName",
    "CreateContainerConfigError",
    "CreateContainerError",
    "CrashLoopBackOff",
];

/// State of one workload (a Job or a Pod).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WorkState {
    /// Created, not running yet (scheduling, pulling, init).
    Pending,
    /// Kueue holds the Job (`spec.suspend: true`).
    Suspended,
    Running,
    Succeeded,
    /// Failed, with the reason Kubernetes gave (`BackoffLimitExceeded: ...`, `OOMKilled`, ...).
    Failed(String),
}

/// One observed Job or Pod of the run.
#[derive(Clone, Debug, PartialEq)]
pub struct Workload {
    /// [`Kind::Job`] or [`Kind::Pod`].
    pub kind: Kind,
    pub name: String,
    /// The role `sadesim.io/role` names; `None` when the label is missing or names no role
    /// (an object labelled by hand with the run's label).
    pub role: Option<Role>,
    pub state: WorkState,
    /// Pods only: the Pod belongs to a Job (its logs are archived with the Job's role).
    pub job_owned: bool,
    /// Pods only: the Ready condition is true.
    pub ready: bool,
    /// Pods of an Indexed Job: the completion index (the shard index for shards).
    pub index: Option<u32>,
    /// Pods only: the termination message of a container that exited (the assets role
    /// writes its outcome there).
    pub message: Option<String>,
}

/// Everything observed about a run's children and the coordinator's reports.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Observed {
    pub jobs: Vec<Workload>,
    pub pods: Vec<Workload>,
    /// The coordinator's log tail, when its pod has started.
    pub coordinator: Option<CoordinatorReport>,
    /// The run's Kueue Workload, when it exists (runs admitted through Kueue).
    pub queue: Option<QueueObservation>,
}

/// The run's Kueue Workload and what Kueue says around it.
#[derive(Clone, Debug, PartialEq)]
pub struct QueueObservation {
    pub workload: KueueWorkload,
    /// Its entry in the LocalQueue's pending list (Kueue's visibility API), while pending
    /// and when the API answers.
    pub pending: Option<PendingWorkload>,
    /// The ResourceFlavors its admission names, by name.
    pub flavors: BTreeMap<String, FlavorPlacement>,
}

impl QueueObservation {
    /// Kueue admitted the whole run (and has not evicted it since).
    pub fn admitted(&self) -> bool {
        self.workload.is(workload_condition::ADMITTED) && self.evicted().is_none()
    }

    /// Kueue evicted the Workload (preempted by a higher priority, deactivated, timed out):
    /// `reason: message`.
    pub fn evicted(&self) -> Option<String> {
        let evicted = self.workload.condition(workload_condition::EVICTED).filter(|c| c.status == "True")?;
        Some(format!("{}: {}", evicted.reason, evicted.message))
    }
}

impl Observed {
    /// Builds the observation from listed objects.
    pub fn from_objects(jobs: &[Job], pods: &[Pod], coordinator: Option<CoordinatorReport>) -> Self {
        Self {
            jobs: jobs.iter().map(job_workload).collect(),
            pods: pods.iter().map(pod_workload).collect(),
            coordinator,
            queue: None,
        }
    }

    /// Nothing of the run exists.
    pub fn is_empty(&self) -> bool {
        self.jobs.is_empty() && self.pods.is_empty()
    }

    /// The Jobs of `role`.
    pub fn jobs_of(&self, role: Role) -> impl Iterator<Item = &Workload> + '_ {
        self.jobs.iter().filter(move |w| w.role == Some(role))
    }

    /// The Pods of `role`.
    pub fn pods_of(&self, role: Role) -> impl Iterator<Item = &Workload> + '_ {
        self.pods.iter().filter(move |w| w.role == Some(role))
    }

    /// The first failure of any role: `(role label, reason)`. Jobs speak for their pods (a Job
    /// retries failed pods up to its backoff limit); bare pods speak for themselves.
    ///
    /// Not the pilot Job's end: the pilot is the program under test, and its exit, with
    /// whatever status, is a finding judged by the criteria, as in `sadesim run`
    /// ([`Observed::pilot_end`]). A pilot whose image cannot be pulled never ran: that is
    /// a failure (its pod's fatal waiting reason).
    pub fn failure(&self) -> Option<(String, String)> {
        let jobs = self.jobs.iter().filter(|j| j.role != Some(Role::Pilot));
        let bare_pods = self.pods.iter().filter(|p| !p.job_owned);
        let fatal_job_pods =
            self.pods.iter().filter(|p| p.job_owned && matches!(&p.state, WorkState::Failed(r) if is_fatal_waiting(r)));
        jobs.chain(bare_pods).chain(fatal_job_pods).find_map(|w| match &w.state {
            WorkState::Failed(reason) => {
                let role = w.role.map_or("unlabelled", Role::label);
                Some((role.to_string(), format!("{} {}: {reason}", w.kind, w.name)))
            }
            _ => None,
        })
    }

    /// How the pilot Job ended, once it has: `Ok(name)` complete, `Err(description)`
    /// failed (its pod exited non-zero, was OOM-killed or evicted).
    pub fn pilot_end(&self) -> Option<Result<String, String>> {
        self.jobs_of(Role::Pilot).find_map(|w| match &w.state {
            WorkState::Succeeded => Some(Ok(format!("Job {} complete", w.name))),
            WorkState::Failed(reason) => Some(Err(format!("Job {} failed: {reason}", w.name))),
            _ => None,
        })
    }

    /// The pilot container's exit code once its Job has ended: 0 for a complete Job, the
    /// failed pod's code (`container pilot Error (exit code 1)`; 128 + n for signal n) for
    /// a failed one; `None` while it runs or when no pod says.
    pub fn pilot_exit_code(&self) -> Option<i32> {
        match self.pilot_end()? {
            Ok(_) => Some(0),
            Err(_) => self.pods_of(Role::Pilot).find_map(|p| match &p.state {
                WorkState::Failed(reason) => exit_code_in(reason),
                _ => None,
            }),
        }
    }

    /// The pilot container's termination message: with `FallbackToLogsOnError` (the pilot
    /// Job's policy), the last lines of its log when it failed.
    pub fn pilot_message(&self) -> Option<&str> {
        self.pods_of(Role::Pilot).find_map(|p| p.message.as_deref())
    }

    /// The coordinator pod's state, when it exists.
    pub fn coordinator_state(&self) -> Option<&WorkState> {
        self.pods_of(Role::Coordinator).map(|w| &w.state).next()
    }

    /// Some Job of `role` exists.
    pub fn has_job(&self, role: Role) -> bool {
        self.jobs_of(role).next().is_some()
    }

    /// Some Job of `role` is held by Kueue.
    pub fn suspended(&self, role: Role) -> bool {
        self.jobs_of(role).any(|w| w.state == WorkState::Suspended)
    }
}

/// `N` in a failed pod's `... (exit code N)` ([`pod_workload`]).
fn exit_code_in(reason: &str) -> Option<i32> {
    let (_, rest) = reason.rsplit_once("(exit code ")?;
    rest.strip_suffix(')')?.parse().ok()
}

fn is_fatal_waiting(reason: &str) -> bool {
    FATAL_WAITING_REASONS.iter().any(|r| reason.starts_with(r))
}

fn role_of(labels: Option<&std::collections::BTreeMap<String, String>>) -> Option<Role> {
    labels.and_then(|l| l.get(ROLE_LABEL)).and_then(|r| Role::from_label(r))
}

/// A Job's state from its conditions (`Failed`/`Complete`), `spec.suspend` and `active`.
pub fn job_workload(job: &Job) -> Workload {
    let status = job.status.as_ref();
    let condition = |t: &str| {
        status
            .and_then(|s| s.conditions.as_ref())
            .into_iter()
            .flatten()
            .find(|c| c.type_ == t && c.status == "True")
            .cloned()
    };
    let state = if let Some(c) = condition("Failed") {
        let reason = c.reason.unwrap_or_else(|| "Failed".into());
        WorkState::Failed(match c.message {
            Some(m) if !m.is_empty() => format!("{reason}: {m}"),
            _ => reason,
        })
    } else if condition("Complete").is_some() {
        WorkState::Succeeded
    } else if job.spec.as_ref().and_then(|s| s.suspend) == Some(true) {
        WorkState::Suspended
    } else if status.and_then(|s| s.active).unwrap_or(0) > 0 {
        WorkState::Running
    } else {
        WorkState::Pending
    };
    Workload {
        kind: Kind::Job,
        name: job.metadata.name.clone().unwrap_or_default(),
        role: role_of(job.metadata.labels.as_ref()),
        state,
        job_owned: false,
        ready: false,
        index: None,
        message: None,
    }
}

/// A Pod's state from its phase and container statuses.
pub fn pod_workload(pod: &Pod) -> Workload {
    let status = pod.status.as_ref();
    let containers = status.and_then(|s| s.container_statuses.as_deref()).unwrap_or_default();
    let phase = status.and_then(|s| s.phase.as_deref()).unwrap_or("Pending");
    let fatal_wait = containers.iter().find_map(|c| {
        let w = c.state.as_ref()?.waiting.as_ref()?;
        let reason = w.reason.as_deref()?;
        is_fatal_waiting(reason).then(|| match w.message.as_deref() {
            Some(m) if !m.is_empty() => format!("{reason}: {m}"),
            _ => reason.to_string(),
        })
    });
    let terminated_reason = || {
        containers.iter().find_map(|c| {
            let t = c.state.as_ref()?.terminated.as_ref()?;
            (t.exit_code != 0).then(|| {
                let reason = t.reason.clone().unwrap_or_else(|| "Error".into());
                format!("container {} {reason} (exit code {})", c.name, t.exit_code)
            })
        })
    };
    let state = match (phase, fatal_wait) {
        (_, Some(reason)) => WorkState::Failed(reason),
        ("Failed", None) => WorkState::Failed(
            terminated_reason().or_else(|| status.and_then(|s| s.reason.clone())).unwrap_or_else(|| "Failed".into()),
        ),
        ("Succeeded", None) => WorkState::Succeeded,
        ("Running", None) => WorkState::Running,
        _ => WorkState::Pending,
    };
    let ready = status
        .and_then(|s| s.conditions.as_ref())
        .into_iter()
        .flatten()
        .any(|c| c.type_ == "Ready" && c.status == "True");
    let labels = pod.metadata.labels.as_ref();
    Workload {
        kind: Kind::Pod,
        name: pod.metadata.name.clone().unwrap_or_default(),
        role: role_of(labels),
        state,
        job_owned: pod.metadata.owner_references.iter().flatten().any(|o| o.kind == "Job"),
        ready,
        index: labels.and_then(|l| l.get(COMPLETION_INDEX_LABEL)).and_then(|v| v.parse().ok()),
        message: containers
            .iter()
            .find_map(|c| c.state.as_ref()?.terminated.as_ref()?.message.clone())
            .filter(|m| !m.is_empty()),
    }
}
