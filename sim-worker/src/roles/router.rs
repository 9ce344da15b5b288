//! `sim-worker router`: the MAVLink router of one segment (DESIGN §3), set up from the plan.
//!
//! The plan gives the segment's GCS ports and, per drone, its system id, shard and endpoint
//! port; only the host of the drone endpoints depends on where the run is deployed, so it
//! is a flag: `127.0.0.1` locally, the shard pods' DNS names on Kubernetes.
//!
//! MAVLink signing on the GCS side (`spec.groundStations.signing`): the passphrase comes from
//! the environment variable `SADESIM_MAVLINK_SIGNING_KEY` ([`signing_key`]), never from a
//! flag, which `ps` shows to every user of the machine.
//!
//! Reports are JSON lines on stdout: `{"type":"listening",...}` once the sockets are bound,
//! `{"type":"stopped","stats":{...}}` at the end.

use std::collections::HashMap;
use std::ffi::OsString;
use std::io::Write;
use std::net::{IpAddr, SocketAddr, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sadesim_crds::ground_stations::{MIN_PASSPHRASE_CHARS, SIGNING_KEY_ENV};
use sadesim_crds::plan::RunPlan;
use serde::Serialize;

use super::RoleError;
use crate::mavlink::router::{self, RoutedDrone, RouterConfig, RouterStats};
use sadesim_engine::mavlink::signing::SecretKey;

/// `--drone-host` when not given: every shard runs on this machine.
pub const DEFAULT_DRONE_HOST: &str = "127.0.0.1";
/// How long the router keeps trying to resolve drone hosts: shard pods appear in DNS only
/// once they are scheduled, which may be after the router pod starts.
pub const RESOLVE_TIMEOUT: Duration = Duration::from_secs(60);
/// Pause between resolution attempts.
const RESOLVE_RETRY: Duration = Duration::from_millis(500);

/// What `sim-worker router` was asked to serve.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RouterOptions {
    /// Router segment index into `plan.segments`.
    pub segment: u32,
    /// Interface of the GCS sockets (`0.0.0.0`: every interface, as a pod behind a Service
    /// needs).
    pub bind: IpAddr,
    /// Host of the drone endpoints, a name or an address. `{run}` is replaced by the run's
    /// name and `{shard}` by the drone's shard index, so on Kubernetes
    /// `{run}-shard-{shard}.{run}-shards` names pod `{shard}` of the Indexed Job
    /// `<run>-shard` behind the headless Service `<run>-shards`.
    pub drone_host: String,
    /// MAVLink signing key for the GCS side; required when the plan asks for signing
    /// (`spec.groundStations.signing`).
    pub signing: Option<SecretKey>,
}

/// One line of the router's stdout.
#[derive(Serialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Report {
    /// Bound and routing; `signing`: ground stations must sign their frames.
    Listening { segment: u32, gcs_udp: String, gcs_tcp: String, drones: usize, signing: bool },
    /// Stopped (SIGINT/SIGTERM); the counters of the whole run.
    Stopped { stats: RouterStats },
}

fn report(r: &Report) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, r);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// Serves segment `options.segment` of `plan` until `stop` is set.
///
/// # Errors
/// A segment the plan does not have, a `--drone-host` with an unknown placeholder or a host
/// that does not resolve within [`RESOLVE_TIMEOUT`], or a GCS port in use.
pub fn run(plan: &RunPlan, options: &RouterOptions, stop: &AtomicBool) -> Result<RouterStats, RoleError> {
    let deadline = Instant::now() + RESOLVE_TIMEOUT;
    let config = config(plan, options, &mut |host| loop {
        match resolve(host) {
            Ok(ip) => return Ok(ip),
            Err(e) if Instant::now() >= deadline || stop.load(Ordering::Relaxed) => return Err(e),
            Err(_) => std::thread::sleep(RESOLVE_RETRY),
        }
    })?;
    let drones = config.drones.len();
    let signing = config.signing.is_some();
    let mut handle = router::start(config)?;
    report(&Report::Listening {
        segment: options.segment,
        gcs_udp: handle.gcs_udp().to_string(),
        gcs_tcp: handle.gcs_tcp().to_string(),
        drones,
        signing,
    });
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
    }
    handle.stop();
    let stats = handle.stats();
    report(&Report::Stopped { stats });
    Ok(stats)
}

/// The router configuration of one segment; `resolve` turns a drone host into an address
/// (called once per distinct host).
///
/// # Errors
/// Unknown segment, bad `--drone-host` template, a host `resolve` fails on, or a plan that
/// asks for signing without a key in `options` (a router must never serve such a run
/// unsigned).
pub fn config(
    plan: &RunPlan,
    options: &RouterOptions,
    resolve: &mut dyn FnMut(&str) -> std::io::Result<IpAddr>,
) -> Result<RouterConfig, RoleError> {
    let wants_signing = plan.spec.ground_stations.as_ref().is_some_and(|g| g.signing.is_some());
    if wants_signing && options.signing.is_none() {
        return Err(RoleError::RouterSetup(format!(
            "spec.groundStations.signing is set but {SIGNING_KEY_ENV} is not: give the router the passphrase \
             in that environment variable"
        )));
    }
    let segment = plan.segments.get(options.segment as usize).ok_or_else(|| {
        RoleError::RouterSetup(format!(
            "--segment {}: the plan has {} router segment(s), numbered from 0",
            options.segment,
            plan.segments.len()
        ))
    })?;
    let mut resolved: HashMap<String, IpAddr> = HashMap::new();
    let mut drones = Vec::new();
    for d in plan.drones.iter().filter(|d| d.segment == options.segment) {
        let host = drone_host(&options.drone_host, &plan.run.name, d.shard)?;
        let ip = match resolved.get(&host) {
            Some(ip) => *ip,
            None => {
                let ip = resolve(&host).map_err(|e| {
                    RoleError::RouterSetup(format!("--drone-host: failed to resolve {host} (drone {}): {e}", d.name))
                })?;
                resolved.insert(host, ip);
                ip
            }
        };
        drones.push(RoutedDrone { system_id: d.system_id, endpoint: SocketAddr::new(ip, d.ports.endpoint) });
    }
    Ok(RouterConfig {
        segment: options.segment,
        gcs_udp: SocketAddr::new(options.bind, segment.gcs_udp),
        gcs_tcp: SocketAddr::new(options.bind, segment.gcs_tcp),
        drones,
        signing: options.signing.clone(),
    })
}

/// The signing key from the value of `SADESIM_MAVLINK_SIGNING_KEY` (`None`: not set, no
/// signing): SHA-256 of the passphrase's UTF-8 bytes, all of them.
///
/// # Errors
/// A value that is not UTF-8 or shorter than 8 characters (the scenario's rule for an inline
/// passphrase, which a Secret's value escapes).
pub fn signing_key(value: Option<OsString>) -> Result<Option<SecretKey>, RoleError> {
    let Some(value) = value else { return Ok(None) };
    let passphrase = value
        .into_string()
        .map_err(|_| RoleError::RouterSetup(format!("{SIGNING_KEY_ENV}: the passphrase is not valid UTF-8")))?;
    let chars = passphrase.chars().count();
    if chars < MIN_PASSPHRASE_CHARS {
        return Err(RoleError::RouterSetup(format!(
            "{SIGNING_KEY_ENV}: the passphrase must be at least {MIN_PASSPHRASE_CHARS} characters, got {chars}"
        )));
    }
    if passphrase.ends_with(['\n', '\r']) {
        // Not trimmed: the key is the hash of every byte, as the ground stations compute it.
        eprintln!(
            "warning: {SIGNING_KEY_ENV} ends with a line break, which is part of the passphrase: ground stations \
             must use it too (a Secret made with `kubectl create secret generic --from-file` keeps the file's \
             last line break; `--from-literal` does not)"
        );
    }
    Ok(Some(SecretKey::from_passphrase(&passphrase)))
}

/// Expands `{run}` and `{shard}` in a `--drone-host` template.
///
/// # Errors
/// Any other brace left after expansion (a mistyped placeholder would otherwise become a
/// host name that never resolves).
pub fn drone_host(template: &str, run: &str, shard: u32) -> Result<String, RoleError> {
    let host = template.replace("{run}", run).replace("{shard}", &shard.to_string());
    if host.contains(['{', '}']) || host.is_empty() {
        return Err(RoleError::RouterSetup(format!(
            "--drone-host {template:?}: expected a host name or address; only {{run}} and {{shard}} are replaced"
        )));
    }
    Ok(host)
}

/// Resolves a host, preferring IPv4 (the drone endpoints bind IPv4 locally).
fn resolve(host: &str) -> std::io::Result<IpAddr> {
    if let Ok(ip) = host.parse::<IpAddr>() {
        return Ok(ip);
    }
    let addrs: Vec<SocketAddr> = (host, 0).to_socket_addrs()?.collect();
    addrs
        .iter()
        .find(|a| a.is_ipv4())
        .or(addrs.first())
        .map(SocketAddr::ip)
        .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "no address"))
}

#[cfg(test)]
mod tests {
    use std::net::Ipv4Addr;

    use sadesim_crds::fixtures::RunBuilder;

    use super::*;
    use sadesim_engine::fixtures::plan_of;

    /// The planned run of `n` drones, `per_shard` drones per shard: 250 drones per router
    /// segment (system ids restart at 1 in each).
    fn plan(n: u32, per_shard: u32) -> RunPlan {
        plan_of(RunBuilder::test().with_drones(n).with_drones_per_shard(per_shard).build())
    }

    /// `drone`'s endpoint port on `host`.
    fn endpoint(plan: &RunPlan, host: &str, drone: usize) -> String {
        format!("{host}:{}", plan.drones[drone].ports.endpoint)
    }

    fn options(segment: u32, drone_host: &str) -> RouterOptions {
        RouterOptions { segment, bind: IpAddr::V4(Ipv4Addr::UNSPECIFIED), drone_host: drone_host.into(), signing: None }
    }

    #[test]
    fn a_segment_gets_its_ports_and_only_its_drones() {
        let plan = plan(253, 100);
        let config = config(&plan, &options(1, DEFAULT_DRONE_HOST), &mut resolve).unwrap();
        let segment = &plan.segments[1];
        assert_eq!(config.gcs_udp, SocketAddr::from((Ipv4Addr::UNSPECIFIED, segment.gcs_udp)));
        assert_eq!(config.gcs_tcp, SocketAddr::from((Ipv4Addr::UNSPECIFIED, segment.gcs_tcp)));
        let drones: Vec<(u8, String)> = config.drones.iter().map(|d| (d.system_id, d.endpoint.to_string())).collect();
        let local = |drone| endpoint(&plan, "127.0.0.1", drone);
        assert_eq!(drones, [(1, local(250)), (2, local(251)), (3, local(252))]);
    }

    #[test]
    fn drone_hosts_follow_the_template_and_resolve_once_per_shard() {
        let plan = plan(4, 2);
        let mut asked = Vec::new();
        let config = config(&plan, &options(0, "{run}-shard-{shard}.{run}-shards"), &mut |host| {
            asked.push(host.to_string());
            Ok(IpAddr::V4(Ipv4Addr::new(10, 0, 0, asked.len() as u8)))
        })
        .unwrap();
        let run = &plan.run.name;
        assert_eq!(asked, [format!("{run}-shard-0.{run}-shards"), format!("{run}-shard-1.{run}-shards")]);
        let ips: Vec<String> = config.drones.iter().map(|d| d.endpoint.to_string()).collect();
        let at = |ip, drone| endpoint(&plan, ip, drone);
        assert_eq!(ips, [at("10.0.0.1", 0), at("10.0.0.1", 1), at("10.0.0.2", 2), at("10.0.0.2", 3)]);
    }

    #[test]
    fn bad_segments_and_templates_are_refused_with_the_flag_named() {
        let plan = plan(3, 100);
        let e = config(&plan, &options(1, DEFAULT_DRONE_HOST), &mut resolve).unwrap_err().to_string();
        assert!(e.contains("--segment 1") && e.contains("1 router segment"), "{e}");
        let e = config(&plan, &options(0, "{run}-{shards}"), &mut resolve).unwrap_err().to_string();
        assert!(e.contains("--drone-host") && e.contains("{shards}"), "{e}");
        let e = config(&plan, &options(0, "nowhere"), &mut |_| Err(std::io::ErrorKind::NotFound.into()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("failed to resolve nowhere"), "{e}");
    }

    #[test]
    fn a_plan_with_signing_needs_the_key_and_passes_it_on() {
        use sadesim_crds::fleet::Credential;
        use sadesim_crds::ground_stations::{GroundStations, Signing};
        let mut plan = plan(2, 100);
        let signing = Signing { key: Credential::Value("a long passphrase".into()) };
        plan.spec.ground_stations = Some(GroundStations { allow_from: vec![], signing: Some(signing) });
        let mut opts = options(0, DEFAULT_DRONE_HOST);
        let e = config(&plan, &opts, &mut resolve).unwrap_err().to_string();
        assert!(e.contains("spec.groundStations.signing") && e.contains(SIGNING_KEY_ENV), "{e}");
        opts.signing = Some(SecretKey::from_passphrase("a long passphrase"));
        assert_eq!(config(&plan, &opts, &mut resolve).unwrap().signing, opts.signing);
    }

    #[test]
    fn the_signing_key_comes_from_the_variable_and_short_ones_are_refused() {
        assert_eq!(signing_key(None).unwrap(), None);
        let key = signing_key(Some("correct horse".into())).unwrap();
        assert_eq!(key, Some(SecretKey::from_passphrase("correct horse")));
        let e = signing_key(Some("short".into())).unwrap_err().to_string();
        assert!(e.starts_with(SIGNING_KEY_ENV) && e.contains("at least 8 characters, got 5"), "{e}");
        // A line break is part of the passphrase (warned about, not trimmed).
        let with_newline = signing_key(Some("correct horse\n".into())).unwrap();
        assert_ne!(with_newline, key);
    }

    #[test]
    fn the_role_serves_until_stopped() {
        let mut plan = plan(2, 100);
        let mut opts = options(0, DEFAULT_DRONE_HOST);
        opts.bind = IpAddr::V4(Ipv4Addr::LOCALHOST);
        // The plan's fixed ports would collide with parallel tests: take free ones.
        plan.segments[0].gcs_udp = 0;
        plan.segments[0].gcs_tcp = 0;
        let drone = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        for d in &mut plan.drones {
            d.ports.endpoint = drone.local_addr().unwrap().port();
        }
        let stop = AtomicBool::new(true);
        let stats = run(&plan, &opts, &stop).unwrap();
        assert_eq!(stats.gcs_udp_clients, 0);
    }
}
