//! Children of small and large runs: names, labels, owners, lockdown, resources, optional
//! roles, and sizes against the API server's limits; the helpers the children's modules'
//! tests share (the Kueue Workload, the NetworkPolicy and the pilot Job are tested beside
//! their modules).

use k8s_openapi::api::core::v1::{Container, PodSpec};
use k8s_openapi::apimachinery::pkg::api::resource::Quantity;
use sadesim_crds::SimulationRun;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::{Credential, SecretKeyRef};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::{Archive, Rendering};
use serde_json::Value;

use super::*;
use sadesim_planner::{Addressing, fleet_file, plan};

pub(super) const UID: &str = "6f1c0a52-3c1e-4d7e-9a59-1f0e7c1d2b3a";

pub(super) fn with_uid(run: SimulationRun) -> SimulationRun {
    let mut run = run;
    run.metadata.uid = Some(UID.into());
    run
}

pub(super) fn planned(run: &SimulationRun) -> RunPlan {
    plan(run).expect("fixture plans")
}

pub(super) fn s3() -> ClusterSettings {
    ClusterSettings {
        default_archive_url: Some("s3://sadesim-runs/team-a".into()),
        object_store_secret: Some("sadesim-object-store".into()),
        ..ClusterSettings::default()
    }
}

/// A run flown by a pilot image with a Secret credential: every role present.
pub(super) fn piloted(drones: u32) -> SimulationRun {
    with_uid(
        RunBuilder::test()
            .with_drones(drones)
            .with_pilot(&["python3", "/app/pilot.py"])
            .with(|r| {
                let pilot = r.spec.pilot.as_mut().unwrap();
                pilot.image = Some("registry.example/team-a/pilot:1.2".into());
                r.spec.fleet[0].credential =
                    Some(Credential::SecretKeyRef(SecretKeyRef { name: "alpha-token".into(), key: "token".into() }));
            })
            .build(),
    )
}

pub(super) fn kinds_and_names(children: &[Child]) -> Vec<(String, String)> {
    children.iter().map(|c| (c.kind().to_string(), c.name().to_string())).collect()
}

pub(super) fn pair(kind: &str, name: &str) -> (String, String) {
    (kind.to_string(), name.to_string())
}

/// Every pod spec among the children, with the name of the object that holds it.
pub(super) fn pod_specs(children: &[Child]) -> Vec<(String, PodSpec)> {
    children
        .iter()
        .filter_map(|c| {
            let spec = match c {
                Child::Pod(p) => p.spec.clone(),
                Child::Job(j) => j.spec.as_ref().and_then(|s| s.template.spec.clone()),
                Child::Deployment(d) => d.spec.as_ref().and_then(|s| s.template.spec.clone()),
                _ => None,
            };
            spec.map(|s| (c.name().to_string(), s))
        })
        .collect()
}

pub(super) fn container(children: &[Child], name: &str) -> Container {
    pod_specs(children)
        .into_iter()
        .find(|(n, _)| n == name)
        .map(|(_, s)| s.containers[0].clone())
        .unwrap_or_else(|| panic!("no pod spec in {name}: {:?}", kinds_and_names(children)))
}

pub(super) fn json(children: &[Child]) -> Value {
    serde_json::to_value(children).unwrap()
}

/// Every object key named `key` anywhere in `v`.
pub(super) fn count_key(v: &Value, key: &str) -> usize {
    match v {
        Value::Object(m) => m.iter().map(|(k, v)| usize::from(k == key) + count_key(v, key)).sum(),
        Value::Array(a) => a.iter().map(|v| count_key(v, key)).sum(),
        _ => 0,
    }
}

pub(super) fn requests(c: &Container) -> (String, String) {
    let r = c.resources.as_ref().unwrap().requests.as_ref().unwrap();
    (r["cpu"].0.clone(), r["memory"].0.clone())
}

#[test]
fn a_small_run_has_every_role_in_apply_order() {
    let run = piloted(3);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    assert_eq!(
        kinds_and_names(&children),
        vec![
            pair("ConfigMap", "test-run-config"),
            pair("ConfigMap", "test-run-fleet"),
            pair("NetworkPolicy", "test-run-isolation"),
            pair("Job", "test-run-assets"),
            pair("Service", "test-run-airspace"),
            pair("Pod", "test-run-coordinator"),
            pair("Service", "test-run-mavlink-0"),
            pair("Pod", "test-run-router-0"),
            pair("Service", "test-run-shards"),
            pair("Job", "test-run-shard"),
            pair("Job", "test-run-pilot"),
        ]
    );
}

#[test]
fn role_labels_name_one_role_each_and_nothing_else() {
    for role in Role::ALL {
        assert_eq!(Role::from_label(role.label()), Some(role));
        assert_eq!(role.to_string(), role.label());
    }
    let labels: std::collections::BTreeSet<_> = Role::ALL.iter().map(|r| r.label()).collect();
    assert_eq!(labels.len(), Role::ALL.len(), "labels are distinct");
    for other in ["", "Shard", "shards", "worker"] {
        assert_eq!(Role::from_label(other), None, "{other:?}");
    }
}

#[test]
fn every_child_is_owned_by_the_run_and_labelled_with_run_and_role() {
    let run = piloted(3).tap_rendering();
    let plan = planned(&run);
    for child in children(&run, &plan, &s3(), Stage::ALL) {
        let v = serde_json::to_value(&child).unwrap();
        let meta = &v["metadata"];
        assert_eq!(meta["namespace"], "default", "{}", child.name());
        assert_eq!(meta["labels"][RUN_LABEL], "test-run", "{}", child.name());
        let role = meta["labels"][ROLE_LABEL].as_str().unwrap();
        assert!(Role::from_label(role).is_some(), "{}: role {role}", child.name());
        let owners = meta["ownerReferences"].as_array().unwrap();
        assert_eq!(owners.len(), 1, "{}", child.name());
        let o = &owners[0];
        assert_eq!(
            (o["apiVersion"].as_str(), o["kind"].as_str(), o["name"].as_str(), o["uid"].as_str()),
            (Some("sadesim.io/v1alpha1"), Some("SimulationRun"), Some("test-run"), Some(UID)),
        );
        assert_eq!((o["controller"].as_bool(), o["blockOwnerDeletion"].as_bool()), (Some(true), Some(true)));
        assert!(v["apiVersion"].is_string() && v["kind"] == child.kind().as_str(), "{v}");
    }
}

pub(super) trait TapRendering {
    fn tap_rendering(self) -> Self;
}

impl TapRendering for SimulationRun {
    fn tap_rendering(mut self) -> Self {
        self.spec.rendering = Some(Rendering { enabled: true, gpus: None });
        self
    }
}

#[test]
fn every_pod_is_locked_down() {
    let run = piloted(3).tap_rendering();
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let specs = pod_specs(&children);
    assert_eq!(specs.len(), 6, "assets, coordinator, router, shard, renderer, pilot");
    for (name, spec) in specs {
        let pod = spec.security_context.as_ref().unwrap();
        assert_eq!(
            (pod.run_as_non_root, pod.run_as_user, pod.run_as_group),
            (Some(true), Some(65532), Some(65532)),
            "{name}"
        );
        assert_eq!(pod.seccomp_profile.as_ref().unwrap().type_, "RuntimeDefault", "{name}");
        assert_eq!(spec.automount_service_account_token, Some(false), "{name}");
        assert!(spec.host_network.is_none() && spec.host_pid.is_none() && spec.host_ipc.is_none(), "{name}");
        for c in spec.containers.iter().chain(spec.init_containers.iter().flatten()) {
            let s = c.security_context.as_ref().unwrap();
            assert_eq!(s.run_as_non_root, Some(true), "{name}");
            assert_eq!(s.allow_privilege_escalation, Some(false), "{name}");
            assert_eq!(s.read_only_root_filesystem, Some(true), "{name}");
            assert_eq!(s.privileged, Some(false), "{name}");
            assert_eq!(s.capabilities.as_ref().unwrap().drop.as_deref(), Some(&["ALL".to_string()][..]), "{name}");
            assert!(s.capabilities.as_ref().unwrap().add.is_none(), "{name}");
            // The root filesystem is read-only: /tmp must be a writable volume.
            let tmp = c.volume_mounts.iter().flatten().find(|m| m.mount_path == "/tmp").expect("a /tmp mount");
            assert_eq!(tmp.read_only, Some(false), "{name}");
            let volume = spec.volumes.iter().flatten().find(|v| v.name == tmp.name).unwrap();
            assert!(volume.empty_dir.is_some(), "{name}");
        }
    }
}

#[test]
fn resources_come_from_the_plan() {
    let run = piloted(250).with_drones_per_shard_of(100);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let q = |r: sadesim_crds::plan::RoleResources| (format!("{}m", r.cpu_millis), format!("{}Mi", r.memory_mib));
    // Shards of 100, 100 and 50 drones: the one template requests the biggest.
    let biggest = plan.resources.shards.iter().max_by_key(|r| r.cpu_millis).copied().unwrap();
    assert_ne!(plan.resources.shards[0], plan.resources.shards[2]);
    assert_eq!(requests(&container(&children, "test-run-shard")), q(biggest));
    assert_eq!(requests(&container(&children, "test-run-coordinator")), q(plan.resources.coordinator));
    assert_eq!(requests(&container(&children, "test-run-router-0")), q(plan.resources.router));
    assert_eq!(requests(&container(&children, "test-run-assets")), q(plan.resources.assets));
    assert_eq!(requests(&container(&children, "test-run-pilot")), q(plan.resources.pilot.unwrap()));
    let limits = container(&children, "test-run-coordinator").resources.unwrap().limits.unwrap();
    assert_eq!(limits["memory"], Quantity(format!("{}Mi", plan.resources.coordinator.memory_mib * 2)));
    assert!(!limits.contains_key("cpu"), "no CPU limit: throttling one shard slows the lockstep");
}

pub(super) trait PerShard {
    fn with_drones_per_shard_of(self, n: u32) -> Self;
}

impl PerShard for SimulationRun {
    fn with_drones_per_shard_of(mut self, n: u32) -> Self {
        self.spec.sharding = Some(sadesim_crds::run::Sharding { drones_per_shard: n, ..Default::default() });
        self
    }
}

#[test]
fn the_shard_job_is_indexed_fails_on_any_shard_failure_and_matches_the_headless_service() {
    let run = piloted(250).with_drones_per_shard_of(100);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let Some(Child::Job(job)) = children.iter().find(|c| c.name() == "test-run-shard") else { panic!() };
    let spec = job.spec.as_ref().unwrap();
    assert_eq!(spec.completion_mode.as_deref(), Some("Indexed"));
    assert_eq!((spec.completions, spec.parallelism, spec.backoff_limit), (Some(3), Some(3), Some(0)));
    let rules = &spec.pod_failure_policy.as_ref().unwrap().rules;
    assert!(rules.iter().all(|r| r.action == "FailJob"));
    let pod = spec.template.spec.as_ref().unwrap();
    assert_eq!(pod.restart_policy.as_deref(), Some("Never"), "podFailurePolicy needs Never");
    assert_eq!(pod.subdomain.as_deref(), Some("test-run-shards"));
    let args = pod.containers[0].args.clone().unwrap();
    let coordinator = args.iter().position(|a| a == "--coordinator").map(|i| args[i + 1].clone()).unwrap();
    assert_eq!(coordinator, "test-run-airspace.default.svc:7400");
    // The headless Service selects exactly the shard pods.
    let Some(Child::Service(svc)) = children.iter().find(|c| c.name() == "test-run-shards") else { panic!() };
    let svc = svc.spec.as_ref().unwrap();
    assert_eq!(svc.cluster_ip.as_deref(), Some("None"));
    let labels = job.spec.as_ref().unwrap().template.metadata.as_ref().unwrap().labels.clone().unwrap();
    assert!(svc.selector.as_ref().unwrap().iter().all(|(k, v)| labels.get(k) == Some(v)));
}

/// The names the router dials, the names the pilot reads in its fleet file and the names
/// the cluster's DNS gives (Indexed Job hostname `<job>-<index>` + subdomain) agree.
#[test]
fn router_fleet_file_and_dns_agree_on_every_address() {
    let run = piloted(600).with_drones_per_shard_of(100);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let fleet = fleet_file(&plan, &Addressing::Cluster);
    let Some(Child::Job(job)) = children.iter().find(|c| c.name() == "test-run-shard") else { panic!() };
    let subdomain = job.spec.as_ref().unwrap().template.spec.as_ref().unwrap().subdomain.clone().unwrap();
    let router = container(&children, "test-run-router-1");
    let args = router.args.unwrap();
    let template = args.iter().position(|a| a == "--drone-host").map(|i| args[i + 1].clone()).unwrap();
    for d in &fleet.drones {
        let shard = plan.drones[d.index as usize].shard;
        let dns = format!("{}-{shard}.{subdomain}.default.svc", job.metadata.name.as_deref().unwrap());
        let routed = template.replace("{run}", "test-run").replace("{shard}", &shard.to_string());
        let port = plan.drones[d.index as usize].ports.endpoint;
        assert_eq!(routed, dns);
        assert_eq!(d.mavlink.tcp, format!("tcpout://{dns}:{port}"));
    }
    // Airspace API and GCS endpoints: the Services that exist, on the ports they expose.
    assert_eq!(fleet.airspace_url, "http://test-run-airspace.default.svc:8480");
    assert_eq!(fleet.gcs_urls.len(), 3);
    for (s, url) in fleet.gcs_urls.iter().enumerate() {
        let name = names::mavlink_service("test-run", s as u32);
        let Some(Child::Service(svc)) = children.iter().find(|c| c.name() == name) else { panic!("no {name}") };
        let udp = svc
            .spec
            .as_ref()
            .unwrap()
            .ports
            .as_ref()
            .unwrap()
            .iter()
            .find(|p| p.protocol.as_deref() == Some("UDP"))
            .unwrap();
        assert_eq!(url, &format!("udpout://{name}.default.svc:{}", udp.port));
        assert_eq!(udp.port, 14550 + s as i32);
    }
}

#[test]
fn the_renderer_exists_only_with_rendering_on() {
    let off = piloted(3);
    let on = piloted(3).tap_rendering();
    let count = |run: &SimulationRun| {
        let children = children(run, &planned(run), &s3(), Stage::ALL);
        children.iter().filter(|c| c.name() == "test-run-renderer").map(|c| c.kind()).collect::<Vec<_>>()
    };
    assert_eq!(count(&off), []);
    assert_eq!(count(&on), [Kind::Service, Kind::Deployment]);
}

#[test]
fn the_renderer_follows_the_coordinators_live_stream() {
    let run = piloted(3).tap_rendering();
    let children = children(&run, &planned(&run), &s3(), Stage::ALL);
    let port = planned(&run).services.renderer_http;
    // The coordinator serves the stream on the renderer port, published by its Service.
    let coordinator = container(&children, "test-run-coordinator");
    let args = coordinator.args.clone().unwrap();
    let at = args.iter().position(|a| a == "--view-bind").expect("--view-bind");
    assert_eq!(args[at + 1], format!("0.0.0.0:{port}"));
    let Some(Child::Service(svc)) = children.iter().find(|c| c.name() == "test-run-airspace") else { panic!() };
    let ports = svc.spec.as_ref().unwrap().ports.as_ref().unwrap();
    assert!(ports.iter().any(|p| p.name.as_deref() == Some("view-feed") && p.port == i32::from(port)), "{ports:?}");
    // The renderer follows it through that Service and loads the world's bundle.
    let renderer = container(&children, "test-run-renderer");
    let args = renderer.args.unwrap();
    let at = args.iter().position(|a| a == "--feed").expect("--feed");
    assert_eq!(args[at + 1], format!("test-run-airspace.default.svc:{port}"));
    assert!(args.iter().any(|a| a == "--assets"), "{args:?}");
    // Without rendering, the coordinator has no stream and its Service no such port.
    let off = piloted(3);
    let children = children_of(&off);
    assert!(!container(&children, "test-run-coordinator").args.unwrap().contains(&"--view-bind".to_string()));
}

pub(super) fn children_of(run: &SimulationRun) -> Vec<Child> {
    children(run, &planned(run), &s3(), Stage::ALL)
}

pub(super) fn gpu_limit(c: &Container) -> Option<String> {
    c.resources.as_ref()?.limits.as_ref()?.get("nvidia.com/gpu").map(|q| q.0.clone())
}

/// GPUs go to the pod that renders on the server: the coordinator, which renders the
/// onboard cameras. Browsers draw the live view, so the renderer never asks for one.
#[test]
fn gpus_go_to_the_coordinator_that_renders_the_cameras_and_only_when_asked() {
    let with = |gpus: Option<u32>| {
        let mut run = piloted(3);
        run.spec.rendering = Some(Rendering { enabled: true, gpus });
        run.spec.fleet[0].cameras = vec![sadesim_crds::fixtures::down_camera()];
        children_of(&run)
    };
    let coordinator = container(&with(None), "test-run-coordinator");
    assert_eq!(gpu_limit(&coordinator), None);
    let no_capability = |c: &Container| c.env.iter().flatten().all(|e| e.name != "NVIDIA_DRIVER_CAPABILITIES");
    assert!(no_capability(&coordinator), "no GPU, no NVIDIA runtime settings");
    let children = with(Some(2));
    let coordinator = container(&children, "test-run-coordinator");
    assert_eq!(gpu_limit(&coordinator).as_deref(), Some("2"));
    // NVIDIA's runtime mounts its Vulkan driver only for the `graphics` capability.
    let caps = coordinator.env.iter().flatten().find(|e| e.name == "NVIDIA_DRIVER_CAPABILITIES").unwrap();
    assert!(caps.value.as_deref().unwrap().split(',').any(|c| c == "graphics"), "{caps:?}");
    for (name, spec) in pod_specs(&children) {
        let asks = spec.containers.iter().any(|c| gpu_limit(c).is_some());
        assert_eq!(asks, name == "test-run-coordinator", "{name}");
    }
}

/// A run with onboard cameras runs on a cluster: the coordinator renders them in the image
/// that has Vulkan, serves them on its Service's `view-feed` port, and the pilot finds them
/// there through its fleet file and `SADESIM_CAMERAS_URL`.
#[test]
fn onboard_cameras_run_in_the_camera_image_and_the_pilot_gets_their_urls() {
    let settings = ClusterSettings { camera_image: "registry.example/camera:3".into(), ..s3() };
    let mut run = piloted(2).tap_rendering();
    run.spec.fleet[0].cameras = vec![sadesim_crds::fixtures::down_camera()];
    let plan = planned(&run);
    assert!(
        problems(&plan, &settings).iter().all(|p| !p.field.contains("cameras")),
        "{:?}",
        problems(&plan, &settings)
    );
    let children = children(&run, &plan, &settings, Stage::ALL);
    let coordinator = container(&children, "test-run-coordinator");
    assert_eq!(coordinator.image.as_deref(), Some("registry.example/camera:3"));
    for other in ["test-run-shard", "test-run-renderer", "test-run-router-0"] {
        assert_eq!(container(&children, other).image, Some(settings.worker_image.clone()), "{other}");
    }
    // The frame server listens on every interface, on the port the Service exposes.
    let args = coordinator.args.unwrap();
    let view = args.iter().position(|a| a == "--view-bind").map(|i| args[i + 1].clone());
    assert_eq!(view.as_deref(), Some("0.0.0.0:8490"));
    let Some(Child::Service(svc)) = children.iter().find(|c| c.name() == "test-run-airspace") else { panic!() };
    let ports = svc.spec.as_ref().unwrap().ports.as_ref().unwrap();
    assert!(ports.iter().any(|p| p.name.as_deref() == Some("view-feed") && p.port == 8490), "{ports:?}");
    // The pilot's two ways to the frames name that Service and port.
    let url = "http://test-run-airspace.default.svc:8490/cameras";
    let pilot_env = container(&children, "test-run-pilot").env.unwrap();
    let cameras_env = pilot_env.iter().find(|e| e.name == "SADESIM_CAMERAS_URL").and_then(|e| e.value.as_deref());
    assert_eq!(cameras_env, Some(url));
    let Some(Child::ConfigMap(cm)) = children.iter().find(|c| c.name() == "test-run-fleet") else { panic!() };
    let fleet: Value = serde_json::from_str(&cm.data.as_ref().unwrap()["fleet.json"]).unwrap();
    for d in fleet["drones"].as_array().unwrap() {
        assert_eq!(d["cameras"]["down"], format!("{url}/{}/down/", d["name"].as_str().unwrap()));
    }
    // The same run's coordinator plans the CPU its cameras render with.
    let without = planned(&piloted(2).tap_rendering());
    assert!(plan.resources.coordinator.cpu_millis > without.resources.coordinator.cpu_millis);
    // Without cameras: the small image, and no camera variable.
    let run = piloted(2).tap_rendering();
    let children = children_of(&run);
    assert_eq!(container(&children, "test-run-coordinator").image, Some(s3().worker_image));
    assert!(container(&children, "test-run-pilot").env.unwrap().iter().all(|e| e.name != "SADESIM_CAMERAS_URL"));
}

#[test]
fn optional_jobs_follow_the_stage() {
    let run = piloted(3);
    let plan = planned(&run);
    let names_at = |stage| children(&run, &plan, &s3(), stage).iter().map(|c| c.name().to_string()).collect::<Vec<_>>();
    let none = names_at(Stage { assets_job: false, pilot: false, stop: None });
    assert!(!none.iter().any(|n| n == "test-run-assets" || n == "test-run-pilot"), "{none:?}");
    let assets = names_at(Stage { assets_job: true, pilot: false, stop: None });
    assert!(assets.contains(&"test-run-assets".to_string()) && !assets.contains(&"test-run-pilot".to_string()));
    let pilot = names_at(Stage { assets_job: false, pilot: true, stop: None });
    assert!(!pilot.contains(&"test-run-assets".to_string()) && pilot.contains(&"test-run-pilot".to_string()));
    // The roles that run the whole time exist at every stage.
    for n in ["test-run-config", "test-run-fleet", "test-run-coordinator", "test-run-shard", "test-run-router-0"] {
        assert!(none.contains(&n.to_string()), "{n}");
    }
}

#[test]
fn without_an_object_store_there_is_no_assets_job_and_no_upload() {
    let run = piloted(3);
    let plan = planned(&run);
    let settings = ClusterSettings::default();
    let children = children(&run, &plan, &settings, Stage::ALL);
    assert!(!children.iter().any(|c| c.name() == "test-run-assets"));
    let env = container(&children, "test-run-coordinator").env.unwrap();
    assert!(!env.iter().any(|e| e.name == "SADESIM_ARCHIVE_URL"));
    let p = problems(&plan, &settings);
    assert!(p.iter().any(|p| p.field == "spec.archive.url" && !p.fatal), "{p:?}");
    // A file:// archive would be a folder inside the pod: warned about, not uploaded to.
    let mut local = run.clone();
    local.spec.archive = Some(Archive { url: "file://runs".into() });
    let plan = planned(&local);
    assert_eq!(upload_url(&plan, &s3()), None);
    assert!(problems(&plan, &s3()).iter().any(|p| p.message.contains("lost with it")));
}

/// Without an object-store archive there is no bundle: each shard builds the world from
/// its files, so a map or DEM in a bucket is read with the object-store credentials.
#[test]
fn shards_read_a_world_in_a_bucket_with_the_object_store_credentials() {
    use crate::k8s::controller::planning::fixture;
    let run = fixture::over_tile(piloted(3));
    let data = sadesim_world::WorldData { dem: Some(fixture::tile()), osm: None };
    let plan = sadesim_planner::plan_with(&run, &data).expect("plans over the tile");
    let secret_only =
        ClusterSettings { object_store_secret: Some("sadesim-object-store".into()), ..Default::default() };
    let shard = container(&children(&run, &plan, &secret_only, Stage::ALL), "test-run-shard");
    assert!(!shard.args.clone().unwrap_or_default().iter().any(|a| a == "--assets"), "no bundle without an archive");
    assert_eq!(shard.env_from.expect("credentials")[0].secret_ref.as_ref().unwrap().name, "sadesim-object-store");
    // A procedural world needs none.
    let plain = planned(&piloted(3));
    let shard = container(&children(&piloted(3), &plain, &secret_only, Stage::ALL), "test-run-shard");
    assert!(shard.env_from.is_none());
}

#[test]
fn the_coordinator_uploads_its_run_folder_with_values_from_the_environment() {
    let run = piloted(3);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let c = container(&children, "test-run-coordinator");
    let env: Vec<(String, Option<String>)> = c.env.clone().unwrap().into_iter().map(|e| (e.name, e.value)).collect();
    assert!(env.contains(&("SADESIM_ARCHIVE_URL".into(), Some("s3://sadesim-runs/team-a".into()))), "{env:?}");
    assert!(env.contains(&("SADESIM_RUN_UID".into(), Some(UID.into()))));
    let assets = asset_cache_location(&plan, &s3());
    assert!(env.contains(&("SADESIM_ASSETS_URL".into(), assets)), "the coordinator loads the world bundle: {env:?}");
    assert_eq!(c.env_from.unwrap()[0].secret_ref.as_ref().unwrap().name, "sadesim-object-store");
    assert_eq!(c.command.as_deref(), Some(&[super::pod::SIM_WORKER.to_string()][..]), "one program, no shell");
    let args = c.args.unwrap();
    assert_eq!(args[..3], ["coordinator", "--plan", "/etc/sadesim/plan.json"]);
    assert_eq!(args.last().map(String::as_str), Some("--finish-run"), "{args:?}");
    assert!(!args.iter().any(|a| a.contains("s3://")), "URLs come from the environment, never spliced into arguments");
    assert_eq!(
        archive_location(&plan, &s3()).as_deref(),
        Some(format!("s3://sadesim-runs/team-a/default/test-run/{UID}/").as_str())
    );
    // The coordinator's output folder is writable.
    assert!(c.volume_mounts.unwrap().iter().any(|m| m.mount_path == OUT_DIR && m.read_only == Some(false)));
}

/// The coordinator Pod reads its own annotations from a file; a stop changes only the
/// annotation, nothing a running Pod cannot change.
#[test]
fn a_stop_is_an_annotation_the_coordinator_reads_through_a_downward_api_file() {
    let run = piloted(3);
    let plan = planned(&run);
    let pod_of = |stop| {
        let stage = Stage { assets_job: false, pilot: true, stop };
        let children = children(&run, &plan, &s3(), stage);
        children
            .into_iter()
            .find_map(|c| match c {
                Child::Pod(p) if p.metadata.name.as_deref() == Some("test-run-coordinator") => Some(p),
                _ => None,
            })
            .expect("a coordinator pod")
    };
    let running = pod_of(None);
    let stopping = pod_of(Some(EndReason::PilotExited));
    assert_eq!(running.metadata.annotations, None);
    assert_eq!(stopping.metadata.annotations, Some([(STOP_ANNOTATION.to_string(), "pilotExited".to_string())].into()));
    assert_eq!(running.spec, stopping.spec, "the spec of a running Pod cannot change");
    assert_eq!(running.metadata.labels, stopping.metadata.labels);

    // The file the coordinator is given is the one the volume projects.
    let spec = running.spec.unwrap();
    let c = &spec.containers[0];
    let args = c.args.as_ref().unwrap();
    let named = args.iter().position(|a| a == "--control-file").map(|i| args[i + 1].as_str());
    assert_eq!(named, Some(CONTROL_FILE));
    let m = c.volume_mounts.as_ref().unwrap().iter().find(|m| m.name == "control").expect("control mount");
    assert_eq!(m.read_only, Some(true));
    let volume = spec.volumes.as_ref().unwrap().iter().find(|v| v.name == "control").expect("control volume");
    let items = volume.downward_api.as_ref().unwrap().items.as_ref().unwrap();
    assert_eq!(items.len(), 1);
    assert_eq!(format!("{}/{}", m.mount_path, items[0].path), CONTROL_FILE);
    assert_eq!(items[0].field_ref.as_ref().unwrap().field_path, "metadata.annotations");
}

#[test]
fn only_the_routers_get_the_signing_passphrase_from_its_secret() {
    use sadesim_crds::ground_stations::{GroundStations, SIGNING_KEY_ENV, Signing};
    let mut run = piloted(600).with_drones_per_shard_of(100);
    let key = Credential::SecretKeyRef(SecretKeyRef { name: "gcs-signing".into(), key: "passphrase".into() });
    run.spec.ground_stations = Some(GroundStations { allow_from: vec![], signing: Some(Signing { key }) });
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let mut routers = 0;
    for (name, spec) in pod_specs(&children) {
        for c in spec.containers.iter().chain(spec.init_containers.iter().flatten()) {
            let env = c.env.iter().flatten().filter(|e| e.name == SIGNING_KEY_ENV).collect::<Vec<_>>();
            if !name.starts_with("test-run-router-") {
                assert!(env.is_empty(), "{name} must not get the signing passphrase");
                continue;
            }
            routers += 1;
            assert_eq!(env.len(), 1, "{name}");
            assert_eq!(env[0].value, None, "{name}: the passphrase is not written into the pod");
            let from = env[0].value_from.as_ref().unwrap().secret_key_ref.as_ref().unwrap();
            assert_eq!(
                (from.name.as_str(), from.key.as_str(), from.optional),
                ("gcs-signing", "passphrase", Some(false))
            );
            // Never on the command line.
            assert!(!c.args.iter().flatten().any(|a| a.contains("signing")), "{name}: {:?}", c.args);
        }
    }
    assert_eq!(routers, 3, "one router per segment of 250 drones");
    // Without signing the routers get no such variable.
    let plain = piloted(3);
    let router = container(&children_of(&plain), "test-run-router-0");
    assert!(!router.env.unwrap().iter().any(|e| e.name == SIGNING_KEY_ENV));
}

#[test]
fn a_thousand_drones_make_ten_shard_pods_four_routers_and_configmaps_under_the_limit() {
    let run = with_uid(RunBuilder::test().with_drones(1000).build());
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let Some(Child::Job(job)) = children.iter().find(|c| c.name() == "test-run-shard") else { panic!() };
    let spec = job.spec.as_ref().unwrap();
    assert_eq!((spec.completions, spec.parallelism), (Some(10), Some(10)), "1000 drones / 100 per shard");
    let routers =
        children.iter().filter(|c| matches!(c, Child::Pod(_)) && c.name().starts_with("test-run-router-")).count();
    let services = children.iter().filter(|c| c.name().starts_with("test-run-mavlink-")).count();
    assert_eq!((routers, services), (4, 4), "ceil(1000 / 250) segments");
    for c in &children {
        if let Child::ConfigMap(cm) = c {
            let bytes: usize = cm.data.iter().flatten().map(|(k, v)| k.len() + v.len()).sum();
            assert!(bytes < CONFIG_MAP_LIMIT_BYTES * 3 / 4, "{}: {bytes} bytes", c.name());
        }
        // Every object, plan included, well under etcd's 1.5 MiB request limit.
        let size = serde_json::to_vec(c).unwrap().len();
        assert!(size < 1024 * 1024, "{} is {size} bytes", c.name());
    }
    assert_eq!(problems(&plan, &s3()), vec![]);
    // The plan in the ConfigMap is the plan.
    let Some(Child::ConfigMap(cm)) = children.iter().find(|c| c.name() == "test-run-config") else { panic!() };
    let stored: RunPlan = serde_json::from_str(&cm.data.as_ref().unwrap()["plan.json"]).unwrap();
    assert_eq!(stored, plan);
}

/// 10 000 drones: the plan (4.6 MB) and the fleet file no longer fit one ConfigMap, so they
/// are stored in parts, each ConfigMap and every other object under the API server's limits,
/// 100 shard pods; the worker pods mount every part of the plan in one folder, and the
/// pilot's pod joins its fleet file before the pilot starts.
#[test]
fn ten_thousand_drones_store_the_plan_in_parts_every_object_under_its_limit() {
    let run = with_uid(
        RunBuilder::test()
            .with_drones(10_000)
            .with_pilot(&["python3", "/app/pilot.py"])
            .with(|r| r.spec.pilot.as_mut().unwrap().image = Some("registry.example/p:1".into()))
            .build(),
    );
    let plan = planned(&run);
    assert_eq!(plan.shards.len(), 100);
    let (plan_bytes, fleet_bytes) = config_map_sizes(&plan);
    assert!(plan_bytes > 4 * CONFIG_MAP_LIMIT_BYTES && fleet_bytes > 3 * CONFIG_MAP_LIMIT_BYTES);
    assert_eq!(problems(&plan, &s3()), vec![], "10 000 drones run on a cluster");
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let mut config = std::collections::BTreeMap::new();
    let mut fleet = std::collections::BTreeMap::new();
    for c in &children {
        let size = serde_json::to_vec(c).unwrap().len();
        assert!(size < 1024 * 1024, "{} is {size} bytes: over etcd's 1.5 MiB with the request around it", c.name());
        if let Child::ConfigMap(cm) = c {
            let data = cm.data.clone().unwrap();
            let bytes: usize = data.iter().map(|(k, v)| k.len() + v.len()).sum();
            assert!(bytes < CONFIG_MAP_LIMIT_BYTES, "{}: {bytes} bytes", c.name());
            let into = if c.name().starts_with("test-run-config") { &mut config } else { &mut fleet };
            into.extend(data);
        }
    }
    // The parts, side by side as the projected volume mounts them, join back into the plan.
    assert!(config.len() >= 6 && !config.contains_key("plan.json"), "{:?}", config.keys());
    let mounted: std::collections::BTreeMap<&str, &String> =
        config.iter().chain(&fleet).map(|(file, text)| (file.as_str(), text)).collect();
    let read = |file: &str| {
        sadesim_crds::parts::join(std::path::Path::new(file), |p| {
            Ok(mounted.get(p.to_str().unwrap()).map(|text| text.as_bytes().to_vec()))
        })
        .unwrap()
    };
    let joined_plan: RunPlan = serde_json::from_slice(&read("plan.json")).unwrap();
    assert_eq!(joined_plan, plan);
    assert_eq!(read("fleet.json"), serde_json::to_vec(&fleet_file(&plan, &Addressing::Cluster)).unwrap());
    // Every worker pod mounts every part of the plan.
    let config_maps: Vec<String> =
        children.iter().filter(|c| c.name().starts_with("test-run-config")).map(|c| c.name().to_string()).collect();
    for (name, spec) in pod_specs(&children).into_iter().filter(|(n, _)| n != "test-run-pilot") {
        let volume = spec.volumes.unwrap().into_iter().find(|v| v.name == "config").unwrap();
        let sources = volume.projected.unwrap().sources.unwrap();
        let names: Vec<String> = sources.iter().map(|s| s.config_map.as_ref().unwrap().name.clone()).collect();
        assert_eq!(names, config_maps, "{name}");
    }
    // The pilot reads the fleet file an init container joined.
    let spec = pod_specs(&children).into_iter().find(|(n, _)| n == "test-run-pilot").unwrap().1;
    let join = &spec.init_containers.as_ref().unwrap()[0];
    assert_eq!(join.args.as_ref().unwrap()[..2], ["join".to_string(), FLEET_PATH.to_string()]);
    let out = join.args.as_ref().unwrap()[3].clone();
    let pilot_env = spec.containers[0].env.clone().unwrap();
    assert_eq!(pilot_env.iter().find(|e| e.name == "SADESIM_FLEET").and_then(|e| e.value.clone()), Some(out));
}

#[test]
fn children_are_deterministic() {
    let run = piloted(40);
    let plan = planned(&run);
    assert_eq!(
        serde_json::to_string(&children(&run, &plan, &s3(), Stage::ALL)).unwrap(),
        serde_json::to_string(&children(&run, &plan, &s3(), Stage::ALL)).unwrap()
    );
}

/// The coordinator pod's arguments: the `sim-worker coordinator` flags (the process test
/// `sim-worker/tests/coordinator_pod.rs` runs the role with the same ones), binding every
/// interface of the pod on the planned ports, and `--finish-run` last.
#[test]
fn the_coordinator_pod_runs_the_coordinator_role_on_the_planned_ports() {
    let run = piloted(3);
    let plan = planned(&run);
    let children = children(&run, &plan, &s3(), Stage::ALL);
    let args = container(&children, "test-run-coordinator").args.unwrap();
    let value = |flag: &str| args.iter().position(|a| a == flag).map(|i| args[i + 1].clone());
    assert_eq!(value("--listen"), Some(format!("0.0.0.0:{}", plan.services.coordinator)));
    assert_eq!(value("--airspace-bind"), Some(format!("0.0.0.0:{}", plan.services.airspace_http)));
    assert_eq!(value("--out").as_deref(), Some(super::pod::OUT_DIR));
    let flags: Vec<&str> = args.iter().filter(|a| a.starts_with("--")).map(String::as_str).collect();
    assert_eq!(
        flags,
        ["--plan", "--listen", "--airspace-bind", "--out", "--control-file", "--hold-for-pilot", "--finish-run"]
    );
}

/// The assets Job runs the `sim-worker assets` role, which writes its outcome (cache hit or
/// built) to the container's termination message, where the operator reads it.
#[test]
fn the_assets_job_runs_the_assets_role_and_reports_in_its_termination_message() {
    let run = piloted(3);
    let plan = planned(&run);
    let c = container(&children(&run, &plan, &s3(), Stage::ALL), "test-run-assets");
    assert_eq!(c.command.as_deref(), Some(&[super::pod::SIM_WORKER.to_string()][..]));
    let args = c.args.unwrap();
    let value = |flag: &str| args.iter().position(|a| a == flag).map(|i| args[i + 1].clone());
    assert_eq!(args[0], "assets");
    assert_eq!(value("--plan").as_deref(), Some("/etc/sadesim/plan.json"));
    assert_eq!(value("--archive").as_deref(), Some("s3://sadesim-runs/team-a"));
    assert_eq!(value("--report-file"), c.termination_message_path);
    assert_eq!(c.termination_message_path.as_deref(), Some("/dev/termination-log"));
    assert_eq!(c.env_from.unwrap()[0].secret_ref.as_ref().unwrap().name, "sadesim-object-store");
}

#[test]
fn shards_load_the_world_bundle_the_assets_job_stores_when_there_is_an_object_store() {
    let run = piloted(3);
    let plan = planned(&run);
    let shard = container(&children(&run, &plan, &s3(), Stage::ALL), "test-run-shard");
    let args = shard.args.clone().unwrap_or_default();
    let at = args.iter().position(|a| a == "--assets").expect("--assets on the shard");
    let expected = asset_cache_location(&plan, &s3()).expect("an object store");
    assert_eq!(args[at + 1], expected);
    assert!(expected.ends_with(&format!("/assets/{}/world/", plan.asset_cache_key)), "{expected}");
    assert!(shard.env_from.is_some(), "the shard reads the bundle with the object-store credentials");
    // Without an object store there is no assets Job and each shard builds the world.
    let local = container(&children(&run, &plan, &ClusterSettings::default(), Stage::ALL), "test-run-shard");
    assert!(!local.args.unwrap_or_default().iter().any(|a| a == "--assets"));
}

#[test]
fn an_imported_openfoam_case_is_a_local_folder_the_pods_cannot_read() {
    use sadesim_crds::environment::{Environment, OpenFoamCase, UrbanWind, UrbanWindModel, Wind};
    let mut run = piloted(1);
    let wind = |case: Option<OpenFoamCase>| Wind {
        speed_mps: 8.0,
        direction_from_deg: 270.0,
        reference_height_m: None,
        turbulence: Default::default(),
        urban: Some(UrbanWind { model: UrbanWindModel::OpenFoam, case, spacing_m: None, sectors: None }),
    };
    let case = OpenFoamCase { dir: "/home/me/case".into(), direction_from_deg: 270.0, reference_speed_mps: 10.0 };
    run.spec.environment = Some(Environment { wind: Some(wind(Some(case))), ..Default::default() });
    let p = problems(&planned(&run), &s3());
    let found = p.iter().find(|p| p.field == "spec.environment.wind.urban.case").expect("refused");
    assert!(found.fatal && found.message.contains("\"/home/me/case\""), "{found:?}");
    // OpenFOAM in the assets phase is not refused: the Job runs it or finds it cached.
    run.spec.environment = Some(Environment { wind: Some(wind(None)), ..Default::default() });
    assert!(!problems(&planned(&run), &s3()).iter().any(|p| p.field.starts_with("spec.environment")));
}

/// The assets Job of an OpenFOAM run runs OpenFOAM, so it takes the image that has it; every
/// other pod of that run, and the assets Job of any other run, the small worker image.
#[test]
fn the_assets_job_of_an_openfoam_run_uses_the_openfoam_image() {
    use sadesim_crds::environment::{Environment, UrbanWind, UrbanWindModel, Wind};
    let settings = ClusterSettings { openfoam_image: "registry.example/foam:7".into(), ..s3() };
    let image_of = |run: &SimulationRun, name: &str| {
        container(&children(run, &planned(run), &settings, Stage::ALL), name).image.unwrap()
    };
    let mut run = piloted(1);
    assert_eq!(image_of(&run, "test-run-assets"), settings.worker_image);
    for (model, assets_image) in [
        (UrbanWindModel::OpenFoam, "registry.example/foam:7"),
        (UrbanWindModel::Diagnostic, settings.worker_image.as_str()),
        (UrbanWindModel::None, settings.worker_image.as_str()),
    ] {
        let urban = UrbanWind { model, case: None, spacing_m: None, sectors: None };
        let wind = Wind {
            speed_mps: 8.0,
            direction_from_deg: 270.0,
            reference_height_m: None,
            turbulence: Default::default(),
            urban: Some(urban),
        };
        run.spec.environment = Some(Environment { wind: Some(wind), ..Default::default() });
        assert_eq!(image_of(&run, "test-run-assets"), assets_image, "{model:?}");
        assert_eq!(image_of(&run, "test-run-shard"), settings.worker_image, "{model:?}");
        assert_eq!(image_of(&run, "test-run-coordinator"), settings.worker_image, "{model:?}");
    }
}
