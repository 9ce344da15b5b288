//! The fleet file a pilot reads (`SADESIM_FLEET`), built from a plan and an addressing
//! mode: where the pilot runs decides which host names and ports it must use.

use std::collections::BTreeMap;

use sadesim_crds::fleet::Credential;
use sadesim_crds::fleet_file::{FLEET_FILE_VERSION, FleetDrone, FleetFile, MavlinkUrls};
use sadesim_crds::plan::RunPlan;
use sadesim_crds::zones::Zone;
use serde_json::{Value, json};

/// How the pilot reaches the run's services.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Addressing {
    /// Everything on one host (`sadesim run`).
    Local { host: String },
    /// In-cluster DNS names (Kubernetes): shard pods of the Indexed Job `<run>-shard`
    /// behind the headless Service `<run>-shards`, the airspace Service `<run>-airspace`,
    /// router Services `<run>-mavlink-<segment>`.
    Cluster,
}

/// The environment variable that gives a pilot the run's onboard-camera listing
/// (`<frame server>/cameras`), locally and on a cluster.
pub const CAMERAS_URL_ENV: &str = "SADESIM_CAMERAS_URL";

/// Where a cluster run's onboard camera frames are served, or `None` without cameras: the
/// coordinator renders them and serves them on the plan's renderer port of its Service
/// `<run>-airspace` (port `view-feed`). Locally the address is known only once the server
/// listens (see [`add_camera_urls`]).
pub fn cluster_cameras_url(plan: &RunPlan) -> Option<String> {
    plan.spec.has_cameras().then(|| {
        let (run, ns) = (&plan.run.name, &plan.run.namespace);
        format!("http://{run}-airspace.{ns}.svc:{}/cameras", plan.services.renderer_http)
    })
}

/// Name of the environment variable that carries a group's credential to the pilot.
pub fn credential_env_var(group: &str) -> String {
    format!("SADESIM_CREDENTIAL_{}", group.to_ascii_uppercase().replace('-', "_"))
}

/// Builds the fleet file.
pub fn fleet_file(plan: &RunPlan, addressing: &Addressing) -> FleetFile {
    let run = &plan.run.name;
    let ns = &plan.run.namespace;
    let svc = |name: String| format!("{name}.{ns}.svc");
    let services = plan.services;
    let (airspace_url, gcs_urls) = match addressing {
        Addressing::Local { host } => (
            format!("http://{host}:{}", services.airspace_http),
            plan.segments.iter().map(|s| format!("udpout://{host}:{}", s.gcs_udp)).collect(),
        ),
        Addressing::Cluster => (
            format!("http://{}:{}", svc(format!("{run}-airspace")), services.airspace_http),
            plan.segments
                .iter()
                .map(|s| format!("udpout://{}:{}", svc(format!("{run}-mavlink-{}", s.index)), s.gcs_udp))
                .collect(),
        ),
    };
    let drones = plan
        .drones
        .iter()
        .map(|d| {
            let group = &plan.spec.fleet[d.group_index as usize];
            let host = match addressing {
                Addressing::Local { host } => host.clone(),
                Addressing::Cluster => format!("{run}-shard-{}.{}", d.shard, svc(format!("{run}-shards"))),
            };
            FleetDrone {
                index: d.index,
                name: d.name.clone(),
                group: d.group.clone(),
                operator: d.operator.clone(),
                role: d.role,
                airframe: d.airframe.clone(),
                system_id: d.system_id,
                component_id: d.component_id,
                credential_env: group.credential.as_ref().map(|_: &Credential| credential_env_var(&group.name)),
                mavlink: MavlinkUrls {
                    api: format!("udpin://0.0.0.0:{}", d.ports.api_udp),
                    udp: format!("udpout://{host}:{}", d.ports.endpoint),
                    tcp: format!("tcpout://{host}:{}", d.ports.endpoint),
                },
                home: d.home.global,
                max_altitude_agl_m: group.altitude.max_agl_m,
                min_altitude_agl_m: group.altitude.min_agl_m,
                scripted: d.scripted,
                cameras: BTreeMap::new(),
            }
        })
        .collect();
    let mut file = FleetFile {
        version: FLEET_FILE_VERSION,
        run: run.clone(),
        origin: plan.spec.origin.geo(),
        airspace_url,
        gcs_urls,
        drones,
        zones: zones_geojson(&plan.spec.zones),
    };
    // In a cluster the frame server's address is fixed by the plan.
    if let (Addressing::Cluster, Some(url)) = (addressing, cluster_cameras_url(plan)) {
        add_camera_urls(&mut file, plan, &url);
    }
    file
}

/// Fills each drone's `cameras` with the base URL of its cameras' frames under
/// `cameras_url`, the frame server's `/cameras` (e.g. `http://127.0.0.1:8090/cameras`).
/// Locally the server's address is known only once it listens, so this comes after
/// [`fleet_file`]; [`Addressing::Cluster`] fleet files have them already.
pub fn add_camera_urls(fleet: &mut FleetFile, plan: &RunPlan, cameras_url: &str) {
    let base = cameras_url.trim_end_matches('/');
    for (drone, planned) in fleet.drones.iter_mut().zip(&plan.drones) {
        let group = &plan.spec.fleet[planned.group_index as usize];
        drone.cameras =
            group.cameras.iter().map(|c| (c.name.clone(), format!("{base}/{}/{}/", drone.name, c.name))).collect();
    }
}

/// Zones as a GeoJSON FeatureCollection: closed polygon rings of `[lon, lat]` (RFC 7946
/// order), with floor, ceiling, activity window and policy as properties.
pub fn zones_geojson(zones: &[Zone]) -> Value {
    let features: Vec<Value> = zones
        .iter()
        .map(|z| {
            let mut ring: Vec<Value> = z.polygon.iter().map(|v| json!([v.longitude_deg, v.latitude_deg])).collect();
            ring.push(ring[0].clone());
            json!({
                "type": "Feature",
                "id": z.name,
                "geometry": {"type": "Polygon", "coordinates": [ring]},
                "properties": {
                    "name": z.name,
                    "floor": z.floor(),
                    "ceiling": z.ceiling,
                    "activeFrom": z.active_from.map(|d| d.to_string()),
                    "activeUntil": z.active_until.map(|d| d.to_string()),
                    "policy": z.policy,
                },
            })
        })
        .collect();
    json!({"type": "FeatureCollection", "features": features})
}
