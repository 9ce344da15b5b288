//! Semantic validation of a `SimulationRun`: everything the schema cannot say.
//!
//! `validate` returns *all* problems at once, each naming the field path and what is
//! expected (`spec.fleet[2].count: must be between 1 and 10000, got 0`), so a user fixes a
//! scenario in one pass. It is pure: no I/O, no clock.
//!
//! [`schema_problems`] is the structural pass that runs before typed reading (every missing
//! field and wrong type at once); `validate` runs on the typed run.
//!
//! The sections live in their own modules: `problems` (the list and its phrasing),
//! `world`, `fleet` (groups, missions, the pilot), `zones`, `environment` and `criteria`.

mod camera;
mod criteria;
mod environment;
mod fleet;
mod problems;
mod schema;
mod world;
mod zones;

use crate::fleet::Credential;
use crate::ground_stations::{GroundStations, MIN_PASSPHRASE_CHARS, Signing};
use crate::run::{ClockMode, SimulationRun, SimulationRunSpec};

use problems::Problems;
pub(crate) use problems::is_dns_label;
pub use problems::{FieldError, ValidationErrors, duration_s};
pub use schema::schema_problems;

/// Longest run name: children are named `<run>-<role>-<n>` and must fit 63 characters.
pub const MAX_RUN_NAME_LEN: usize = 40;
/// Longest simulated duration, seconds (24 h).
pub const MAX_DURATION_S: f64 = 86_400.0;

/// Validates a run.
///
/// # Errors
/// Every problem found, with its field path.
pub fn validate(run: &SimulationRun) -> Result<(), ValidationErrors> {
    let mut p = Problems::default();
    match run.metadata.name.as_deref() {
        None | Some("") => p.add("metadata.name", "is required (a DNS label such as `chicago-museum`)"),
        Some(name) => p.dns_label("metadata.name", name, MAX_RUN_NAME_LEN),
    }
    check_spec(&run.spec, &mut p);
    if p.0.is_empty() { Ok(()) } else { Err(ValidationErrors(p.0)) }
}

fn check_spec(spec: &SimulationRunSpec, p: &mut Problems) {
    // Origin first: every horizontal check below depends on it.
    let o = &spec.origin;
    let origin_ok = p.range("spec.origin.latitudeDeg", o.latitude_deg, -85.0, 85.0)
        & p.range("spec.origin.longitudeDeg", o.longitude_deg, -180.0, 180.0)
        & p.range("spec.origin.altitudeMslM", o.altitude_msl_m, -500.0, 9000.0);

    let duration_s = p.duration("spec.duration", &spec.duration, MAX_DURATION_S);

    if let Some(clock) = &spec.clock {
        match (clock.mode, clock.factor) {
            (ClockMode::Scaled, Some(f)) => {
                p.range("spec.clock.factor", f, 0.01, 1000.0);
            }
            (ClockMode::Scaled, None) => p.add("spec.clock.factor", "is required with mode `scaled` (e.g. 4.0)"),
            (_, Some(_)) => p.add("spec.clock.factor", "is only allowed with mode `scaled`"),
            (_, None) => {}
        }
    }
    if let Some(seed) = spec.seed
        && seed > i64::MAX as u64
    {
        p.add("spec.seed", format!("must be at most {} (Kubernetes integers are 64-bit signed), got {seed}", i64::MAX));
    }
    if let Some(rate) = spec.physics_rate_hz {
        p.range_int("spec.physicsRateHz", rate.into(), 50, 10_000);
    }

    let bounds = world::check_world(spec, origin_ok, p);

    let group_names = fleet::check_fleet(spec, bounds.as_ref(), p);
    let zone_names = zones::check_zones(spec, bounds.as_ref(), duration_s, p);
    if let Some(b) = &bounds {
        zones::check_zone_interactions(spec, b, p);
    }
    environment::check_environment(spec, &group_names, p);
    camera::check_cameras(spec, bounds.as_ref(), p);
    fleet::check_pilot(spec, p);

    let sharding = spec.sharding();
    p.range_int("spec.sharding.dronesPerShard", sharding.drones_per_shard.into(), 1, 2000);
    p.range_int("spec.sharding.syncWindowSteps", sharding.sync_window_steps.into(), 1, 1000);
    let rates = spec.recording().rates;
    for (field, hz) in [
        ("groundTruthHz", rates.ground_truth_hz),
        ("estimatorHz", rates.estimator_hz),
        ("actuatorsHz", rates.actuators_hz),
        ("statusHz", rates.status_hz),
    ] {
        p.range(format!("spec.recording.rates.{field}"), hz, 0.1, 1000.0);
    }

    if let Some(archive) = &spec.archive {
        check_archive_url(&archive.url, p);
    }
    if let Some(queue) = &spec.queue {
        p.dns_label("spec.queue", queue, 63);
    }
    if let Some(stations) = &spec.ground_stations {
        check_ground_stations(stations, p);
    }
    let rendering = spec.rendering();
    if let Some(gpus) = rendering.gpus {
        p.range_int("spec.rendering.gpus", gpus.into(), 1, 8);
        if !rendering.enabled {
            p.add("spec.rendering.gpus", "asks GPUs for a renderer that is off: set spec.rendering.enabled to true");
        } else if !spec.has_cameras() {
            // GPUs go to the pod that renders onboard cameras; the live view draws in each
            // browser, so without cameras a GPU would be reserved and never used.
            p.add(
                "spec.rendering.gpus",
                "asks GPUs, but nothing renders on the server without onboard cameras (the live view draws in each browser): declare spec.fleet[].cameras or remove gpus",
            );
        }
    }
    criteria::check_criteria(spec, &group_names, &zone_names, p);
}

fn check_ground_stations(stations: &GroundStations, p: &mut Problems) {
    for (i, cidr) in stations.allow_from.iter().enumerate() {
        if let Err(why) = parse_cidr(cidr) {
            p.add(format!("spec.groundStations.allowFrom[{i}]"), format!("{why}, got {cidr:?}"));
        }
    }
    // A Secret's value is checked by the router that reads it (same minimum).
    if let Some(Signing { key: Credential::Value(passphrase) }) = &stations.signing {
        let min = MIN_PASSPHRASE_CHARS;
        let chars = passphrase.chars().count();
        if chars < min {
            p.add(
                "spec.groundStations.signing.key.value",
                format!("the passphrase must be at least {min} characters, got {chars}"),
            );
        }
    }
}

/// An address range as NetworkPolicy `ipBlock.cidr` takes it: `address/prefix`, IPv4 with a
/// prefix of 0..=32 or IPv6 with 0..=128.
pub fn parse_cidr(cidr: &str) -> Result<(std::net::IpAddr, u8), String> {
    let expected = "must be an address range in CIDR notation such as 10.20.0.0/16 or fd00::/8";
    let (addr, prefix) = cidr.split_once('/').ok_or(expected)?;
    let addr: std::net::IpAddr = addr.parse().map_err(|_| expected)?;
    let prefix: u8 = prefix.parse().map_err(|_| expected)?;
    let max = if addr.is_ipv4() { 32 } else { 128 };
    if prefix > max {
        return Err(format!(
            "the prefix length of an {} range is at most {max}",
            if max == 32 { "IPv4" } else { "IPv6" }
        ));
    }
    Ok((addr, prefix))
}

fn check_archive_url(url: &str, p: &mut Problems) {
    let path = "spec.archive.url";
    let Some((scheme, rest)) = url.split_once("://") else {
        p.add(path, format!("must be a URL such as file://runs or s3://bucket/prefix, got {url:?}"));
        return;
    };
    match scheme {
        "file" if rest.is_empty() => p.add(path, "file:// needs a folder, e.g. file://runs or file:///var/sadesim"),
        "file" => {}
        "s3" | "gs" | "az" if rest.split('/').next().is_none_or(str::is_empty) => {
            p.add(path, format!("{scheme}:// needs a bucket name, e.g. {scheme}://my-bucket/runs"))
        }
        "s3" | "gs" | "az" => {}
        other => p.add(path, format!("unsupported scheme {other:?}: expected file, s3, gs or az")),
    }
}

#[cfg(test)]
mod tests;
