//! What every child shares: metadata (labels, ownerReference), the locked-down pod and
//! container security contexts, volumes, resources, credentials.

use std::collections::BTreeMap;

use k8s_openapi::api::core::v1::{
    Capabilities, Container, EmptyDirVolumeSource, EnvFromSource, EnvVar, EnvVarSource, PodSecurityContext, PodSpec,
    ResourceRequirements, SeccompProfile, SecretEnvSource, SecretKeySelector, SecurityContext, Volume, VolumeMount,
};
use k8s_openapi::apimachinery::pkg::api::resource::Quantity;
use k8s_openapi::apimachinery::pkg::apis::meta::v1::{ObjectMeta, OwnerReference};
use sadesim_crds::SimulationRun;
use sadesim_crds::fleet::Credential;
use sadesim_crds::ground_stations::SIGNING_KEY_ENV;
use sadesim_crds::plan::{RoleResources, RunPlan};

use super::{ClusterSettings, OWNER_API_VERSION, OWNER_KIND, ROLE_LABEL, RUN_LABEL, Role};
use sadesim_planner::credential_env_var;

/// Uid and gid every pod runs as (distroless `nonroot`).
pub const RUN_AS_ID: i64 = 65532;
/// Where the run's ConfigMaps are mounted.
pub const CONFIG_DIR: &str = "/etc/sadesim";
/// `plan.json` in every role's pod.
pub const PLAN_PATH: &str = "/etc/sadesim/plan.json";
/// `fleet.json` in the pilot's pod (`SADESIM_FLEET`).
pub const FLEET_PATH: &str = "/etc/sadesim/fleet.json";
/// The run as applied, in the pilot's pod (the fleet ConfigMap's `scenario.json`).
pub const SCENARIO_PATH: &str = "/etc/sadesim/scenario.json";
/// Writable output folder (emptyDir): the coordinator's run folder, the pilot's `SADESIM_OUT`.
pub const OUT_DIR: &str = "/var/run/sadesim/out";
/// The coordinator's downward-API file of its Pod's annotations (`--control-file`): the
/// operator ends a run by annotating the Pod (`sadesim.io/stop`).
pub const CONTROL_FILE: &str = "/var/run/sadesim/control/annotations";
/// The mount point of the volume holding [`CONTROL_FILE`].
pub const CONTROL_DIR: &str = "/var/run/sadesim/control";
/// Writable scratch (emptyDir): the root filesystem is read-only.
pub const TMP_DIR: &str = "/tmp";

/// The memory limit is this many times the planned request: the estimate is an estimate,
/// and an OOM-killed shard ends the run. CPU has no limit (throttling a lockstep shard slows
/// every shard).
pub const MEMORY_LIMIT_FACTOR: u32 = 2;

/// The inputs every builder reads.
pub(super) struct Context<'a> {
    pub run: &'a SimulationRun,
    pub plan: &'a RunPlan,
    pub settings: &'a ClusterSettings,
    /// Run name.
    pub name: &'a str,
    pub namespace: &'a str,
    /// `plan.json` and `fleet.json` as stored, serialized once: the ConfigMaps hold them,
    /// and every pod's volume names the ConfigMaps their size asks for.
    pub plan_json: String,
    pub fleet_json: String,
}

impl<'a> Context<'a> {
    pub fn new(run: &'a SimulationRun, plan: &'a RunPlan, settings: &'a ClusterSettings) -> Self {
        Self {
            run,
            plan,
            settings,
            name: &plan.run.name,
            namespace: &plan.run.namespace,
            plan_json: super::config::plan_json(plan),
            fleet_json: super::config::fleet_json(plan),
        }
    }

    /// `sadesim.io/run` and `sadesim.io/role` (and the recommended `app.kubernetes.io/*`).
    pub fn labels(&self, role: Role) -> BTreeMap<String, String> {
        BTreeMap::from([
            (RUN_LABEL.to_string(), self.name.to_string()),
            (ROLE_LABEL.to_string(), role.label().to_string()),
            ("app.kubernetes.io/name".to_string(), "sadesim".to_string()),
            ("app.kubernetes.io/instance".to_string(), self.name.to_string()),
            ("app.kubernetes.io/component".to_string(), role.label().to_string()),
            ("app.kubernetes.io/managed-by".to_string(), "sadesim-operator".to_string()),
        ])
    }

    /// The labels a Service or controller selects a role's pods by.
    pub fn selector(&self, role: Role) -> BTreeMap<String, String> {
        BTreeMap::from([
            (RUN_LABEL.to_string(), self.name.to_string()),
            (ROLE_LABEL.to_string(), role.label().to_string()),
        ])
    }

    /// The run as controlling owner: deleting the run deletes the child (foreground
    /// deletion waits for it).
    pub fn owner(&self) -> OwnerReference {
        OwnerReference {
            api_version: OWNER_API_VERSION.into(),
            kind: OWNER_KIND.into(),
            name: self.name.to_string(),
            uid: self.run.metadata.uid.clone().or_else(|| self.plan.run.uid.clone()).unwrap_or_default(),
            controller: Some(true),
            block_owner_deletion: Some(true),
        }
    }

    /// Metadata of a top-level child.
    pub fn meta(&self, name: String, role: Role) -> ObjectMeta {
        ObjectMeta {
            name: Some(name),
            namespace: Some(self.namespace.to_string()),
            labels: Some(self.labels(role)),
            owner_references: Some(vec![self.owner()]),
            ..Default::default()
        }
    }

    /// Metadata of a pod template.
    pub fn template_meta(&self, role: Role) -> ObjectMeta {
        ObjectMeta { labels: Some(self.labels(role)), ..Default::default() }
    }

    /// Archive credentials for roles that write object storage.
    pub fn object_store_env(&self) -> Option<Vec<EnvFromSource>> {
        self.settings.object_store_secret.as_ref().map(|secret| {
            vec![EnvFromSource {
                secret_ref: Some(SecretEnvSource { name: secret.clone(), optional: Some(false) }),
                ..Default::default()
            }]
        })
    }

    /// `SADESIM_CREDENTIAL_<GROUP>` for every group with a credential: from the Secret key
    /// it names, or inline (`value`, visible to whoever reads the run).
    pub fn credential_env(&self) -> Vec<EnvVar> {
        self.plan
            .spec
            .fleet
            .iter()
            .filter_map(|g| Some(credential_var(credential_env_var(&g.name), g.credential.as_ref()?)))
            .collect()
    }

    /// `SADESIM_MAVLINK_SIGNING_KEY` when the run signs MAVLink on the GCS side
    /// (`spec.groundStations.signing`): the passphrase from the Secret key it names, or
    /// inline. For the routers only: no other role needs it.
    pub fn signing_env(&self) -> Option<EnvVar> {
        let signing = self.plan.spec.ground_stations.as_ref()?.signing.as_ref()?;
        Some(credential_var(SIGNING_KEY_ENV.into(), &signing.key))
    }

    /// `SADESIM_RUN`, `SADESIM_NAMESPACE` and `SADESIM_RUN_UID`.
    pub fn run_env(&self) -> Vec<EnvVar> {
        let uid = self.owner().uid;
        [
            ("SADESIM_RUN", self.name.to_string()),
            ("SADESIM_NAMESPACE", self.namespace.to_string()),
            ("SADESIM_RUN_UID", uid),
        ]
        .into_iter()
        .map(|(k, v)| env(k, v))
        .collect()
    }
}

/// Variable `name` holding `credential`: from the Secret key it names (which must exist:
/// the pod does not start without it), or inline.
fn credential_var(name: String, credential: &Credential) -> EnvVar {
    match credential {
        Credential::Value(v) => EnvVar { name, value: Some(v.clone()), value_from: None },
        Credential::SecretKeyRef(r) => EnvVar {
            name,
            value: None,
            value_from: Some(EnvVarSource {
                secret_key_ref: Some(SecretKeySelector {
                    name: r.name.clone(),
                    key: r.key.clone(),
                    optional: Some(false),
                }),
                ..Default::default()
            }),
        },
    }
}

/// A plain environment variable.
pub fn env(name: &str, value: impl Into<String>) -> EnvVar {
    EnvVar { name: name.into(), value: Some(value.into()), value_from: None }
}

/// Requests from the plan; memory limited to [`MEMORY_LIMIT_FACTOR`] times the request.
pub fn resources(r: RoleResources) -> ResourceRequirements {
    ResourceRequirements {
        requests: Some(BTreeMap::from([
            ("cpu".to_string(), Quantity(format!("{}m", r.cpu_millis))),
            ("memory".to_string(), Quantity(format!("{}Mi", r.memory_mib))),
        ])),
        limits: Some(BTreeMap::from([(
            "memory".to_string(),
            Quantity(format!("{}Mi", u64::from(r.memory_mib) * u64::from(MEMORY_LIMIT_FACTOR))),
        )])),
        ..Default::default()
    }
}

/// Non-root, read-only root filesystem, no privilege escalation, no capabilities.
pub fn container_security() -> SecurityContext {
    SecurityContext {
        run_as_non_root: Some(true),
        run_as_user: Some(RUN_AS_ID),
        run_as_group: Some(RUN_AS_ID),
        allow_privilege_escalation: Some(false),
        read_only_root_filesystem: Some(true),
        privileged: Some(false),
        capabilities: Some(Capabilities { drop: Some(vec!["ALL".into()]), add: None }),
        seccomp_profile: Some(runtime_default()),
        ..Default::default()
    }
}

fn runtime_default() -> SeccompProfile {
    SeccompProfile { type_: "RuntimeDefault".into(), localhost_profile: None }
}

/// The pod-level half of the lockdown, plus no service-account token (no role talks to the
/// API server) and no service links (a namespace with many runs would flood the env).
pub fn pod_spec(containers: Vec<Container>, volumes: Vec<Volume>, restart_policy: &str) -> PodSpec {
    PodSpec {
        containers,
        volumes: Some(volumes),
        restart_policy: Some(restart_policy.into()),
        automount_service_account_token: Some(false),
        enable_service_links: Some(false),
        security_context: Some(PodSecurityContext {
            run_as_non_root: Some(true),
            run_as_user: Some(RUN_AS_ID),
            run_as_group: Some(RUN_AS_ID),
            fs_group: Some(RUN_AS_ID),
            seccomp_profile: Some(runtime_default()),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// An emptyDir volume.
pub fn empty_dir(name: &str) -> Volume {
    Volume { name: name.into(), empty_dir: Some(EmptyDirVolumeSource::default()), ..Default::default() }
}

/// Mounts `volume` at `path`.
pub fn mount(volume: &str, path: &str, read_only: bool) -> VolumeMount {
    VolumeMount { name: volume.into(), mount_path: path.into(), read_only: Some(read_only), ..Default::default() }
}

/// A worker-image container of `role` (its name) running `command` with `args`,
/// `plan.json` mounted and `/tmp` writable.
pub fn worker_container(
    ctx: &Context,
    role: Role,
    command: Vec<String>,
    args: Vec<String>,
    r: RoleResources,
) -> Container {
    Container {
        name: role.label().into(),
        image: Some(ctx.settings.worker_image.clone()),
        command: Some(command),
        args: if args.is_empty() { None } else { Some(args) },
        env: Some(ctx.run_env()),
        resources: Some(resources(r)),
        security_context: Some(container_security()),
        volume_mounts: Some(vec![mount("config", CONFIG_DIR, true), mount("tmp", TMP_DIR, false)]),
        // The last lines of the log are the reason shown in `kubectl describe` on failure.
        termination_message_policy: Some("FallbackToLogsOnError".into()),
        ..Default::default()
    }
}

/// The `sim-worker` binary in the worker image.
pub const SIM_WORKER: &str = "/usr/local/bin/sim-worker";
