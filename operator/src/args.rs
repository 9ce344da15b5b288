//! The operator's flags, each also read from an environment variable (the Helm chart sets
//! them), and their validated form [`crate::k8s::controller::OperatorOptions`].

/// Flags of `sadesim operator` (each also read from the environment variable shown).
#[derive(Debug, clap::Parser)]
#[command(name = "sadesim-operator", version, about = "SADE-SIM Kubernetes operator")]
pub struct OperatorArgs {
    /// Image of sim-worker (assets, shard, coordinator, router and renderer roles).
    #[arg(long, env = "SADESIM_WORKER_IMAGE", default_value = "ghcr.io/sadesim/sim-worker:0.1.0")]
    pub worker_image: String,
    /// Image of sim-worker with OpenFOAM (images/sim-worker-openfoam.Dockerfile): the assets
    /// Job of runs whose `environment.wind.urban.model` is `openfoam`.
    #[arg(long, env = "SADESIM_OPENFOAM_IMAGE", default_value = "ghcr.io/sadesim/sim-worker-openfoam:0.1.0")]
    pub openfoam_image: String,
    /// Image of sim-worker with Mesa's Vulkan drivers (images/sim-worker-camera.Dockerfile):
    /// the coordinator of runs with onboard cameras, which renders their frames.
    #[arg(long, env = "SADESIM_CAMERA_IMAGE", default_value = "ghcr.io/sadesim/sim-worker-camera:0.1.0")]
    pub camera_image: String,
    /// Archive URL for runs without spec.archive (s3://bucket/prefix, gs://..., az://...).
    #[arg(long, env = "SADESIM_DEFAULT_ARCHIVE_URL")]
    pub default_archive_url: Option<String>,
    /// Secret whose keys become environment variables of the roles that write the archive.
    #[arg(long, env = "SADESIM_OBJECT_STORE_SECRET")]
    pub object_store_secret: Option<String>,
    /// Service type of the MAVLink router Services.
    #[arg(long, env = "SADESIM_ROUTER_SERVICE_TYPE", default_value = "ClusterIP",
          value_parser = ["ClusterIP", "NodePort", "LoadBalancer"])]
    pub router_service_type: String,
    /// Let Kueue admit runs whose spec.queue names a LocalQueue, each as one Kueue Workload
    /// (kueue.x-k8s.io/v1beta2, Kueue 0.15 or later) (true|false).
    #[arg(long, env = "SADESIM_KUEUE", value_name = "BOOL", num_args = 0..=1, default_value = "false",
          default_missing_value = "true", action = clap::ArgAction::Set,
          value_parser = clap::builder::BoolishValueParser::new())]
    pub kueue: bool,
    /// Runs active at once per namespace without Kueue (0 = unlimited).
    #[arg(long, env = "SADESIM_MAX_CONCURRENT_RUNS", default_value_t = 0)]
    pub max_concurrent_runs: u32,
    /// Address of /metrics and /healthz.
    #[arg(long, env = "SADESIM_METRICS_ADDR", default_value = "0.0.0.0:8080")]
    pub metrics_addr: std::net::SocketAddr,
    /// Elect a leader through a Lease before reconciling (true|false).
    #[arg(long, env = "SADESIM_LEADER_ELECTION", value_name = "BOOL", num_args = 0..=1, default_value = "true",
          default_missing_value = "true", action = clap::ArgAction::Set,
          value_parser = clap::builder::BoolishValueParser::new())]
    pub leader_election: bool,
    /// Reconcile without electing a leader (a single replica).
    #[arg(long)]
    pub no_leader_election: bool,
}

impl OperatorArgs {
    /// The validated options (POD_NAMESPACE and POD_NAME name the Lease's namespace and
    /// holder).
    pub fn options(self) -> crate::k8s::controller::OperatorOptions {
        let env = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        crate::k8s::controller::OperatorOptions {
            settings: crate::k8s::children::ClusterSettings {
                worker_image: self.worker_image,
                openfoam_image: self.openfoam_image,
                camera_image: self.camera_image,
                default_archive_url: self.default_archive_url.filter(|u| !u.is_empty()),
                object_store_secret: self.object_store_secret.filter(|s| !s.is_empty()),
                router_service_type: self.router_service_type,
                kueue: self.kueue,
                file_archives: false,
            },
            max_concurrent_runs: self.max_concurrent_runs,
            metrics_addr: self.metrics_addr,
            leader_election: self.leader_election && !self.no_leader_election,
            lease_namespace: env("POD_NAMESPACE"),
            identity: env("POD_NAME"),
        }
    }
}
