//! The whole pilot: read the fleet file, ask the authority for its zones, plan every
//! drone's task, fly all drones at once (one thread each) and report who came home.
//! `main.rs` only turns the command line into [`Options`]; tests can call [`run`] too.

use std::path::PathBuf;

use sadesim_crds::fleet::Role;
use sadesim_crds::fleet_file::{FLEET_FILE_VERSION, FleetFile};
use sadesim_crds::geo::LocalFrame;

use crate::airspace::{ApiError, Client};
use crate::flight::{self, Context, DroneSpec};
use crate::http::HttpError;
use crate::plan::{self, Member, Task};
use crate::zones::{self, ZonesError};

/// What to fly and how (validated command-line arguments).
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The fleet file (`SADESIM_FLEET`).
    pub fleet: PathBuf,
    /// The scenario file, for its parks and its wind; `None`: hobbyists wander round home
    /// and the way home is planned against a headwind.
    pub scenario: Option<PathBuf>,
    /// The zone of the case study; `None`: the first zone the authority lists.
    pub zone: Option<String>,
    /// The non-compliant variant: journalists enter after a denial.
    pub journalists_ignore_denials: bool,
    /// A worse pilot version, for sweeps that compare versions: each journalist ignores its
    /// denial with this probability (0 to 1), drawn from the run's `spec.seed` (from the
    /// scenario) and the drone's index, so some flights of a sweep break the rules.
    pub ignore_denials_share: f64,
    /// Seed of the hobbyists' random waypoints.
    pub seed: u64,
}

/// Why the pilot could not start flying.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    #[error("failed to read the fleet file {path}: {error}")]
    ReadFleet { path: String, error: std::io::Error },
    #[error("fleet file {path}: not a SADE-SIM fleet file: {error}")]
    ParseFleet { path: String, error: serde_json::Error },
    #[error("fleet file {path}: version {found} (this pilot reads version {FLEET_FILE_VERSION})")]
    FleetVersion { path: String, found: u32 },
    #[error("fleet file {path}: airspaceUrl: {error}")]
    AirspaceUrl { path: String, error: HttpError },
    /// The authority is down or answered `GET /zones` with an error.
    #[error("the airspace authority at {url} did not list its zones: {error}")]
    Zones { url: String, error: ApiError },
    #[error("GET /zones: {0}")]
    ZonesShape(ZonesError),
    #[error("--zone {name}: the authority has no such zone (it has: {known})")]
    UnknownZone { name: String, known: String },
    #[error("the airspace authority lists no zone: the case study needs one")]
    NoZone,
    #[error("failed to read the scenario {path}: {error}")]
    ReadScenario { path: String, error: std::io::Error },
    #[error("scenario {path}: {error}")]
    ParseScenario { path: String, error: String },
}

/// How the flights went: the drones that did not come home cleanly, with why.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Report {
    pub flown: usize,
    /// `(drone name, reason)`, in fleet order.
    pub failures: Vec<(String, String)>,
}

/// Plans and flies every drone of the fleet file that is not `scripted`, logging one line
/// per decision on stdout. Returns when every drone's thread has finished.
///
/// # Errors
/// The fleet file, the authority's zone list, `--zone` or the scenario are unusable: no
/// drone has been touched then. Problems of single drones are in the [`Report`].
pub fn run(options: &Options) -> Result<Report, StartError> {
    let path = options.fleet.display().to_string();
    let text =
        std::fs::read_to_string(&options.fleet).map_err(|error| StartError::ReadFleet { path: path.clone(), error })?;
    let fleet: FleetFile =
        serde_json::from_str(&text).map_err(|error| StartError::ParseFleet { path: path.clone(), error })?;
    if fleet.version != FLEET_FILE_VERSION {
        return Err(StartError::FleetVersion { path, found: fleet.version });
    }
    let frame = LocalFrame::new(fleet.origin);
    let client = Client::new(&fleet.airspace_url).map_err(|error| StartError::AirspaceUrl { path, error })?;
    let url = fleet.airspace_url.clone();
    let collection = client.zones().map_err(|error| StartError::Zones { url, error })?;
    let zones = zones::from_geojson(&collection, &frame).map_err(StartError::ZonesShape)?;
    let target = match &options.zone {
        Some(name) => zones.iter().position(|z| &z.name == name).ok_or_else(|| StartError::UnknownZone {
            name: name.clone(),
            known: zones.iter().map(|z| z.name.as_str()).collect::<Vec<_>>().join(", "),
        })?,
        None if zones.is_empty() => return Err(StartError::NoZone),
        None => 0,
    };
    let (parks, wind, run_seed) = match &options.scenario {
        Some(file) => {
            let path = file.display().to_string();
            let text = std::fs::read_to_string(file)
                .map_err(|error| StartError::ReadScenario { path: path.clone(), error })?;
            let run = sadesim_crds::document::parse_run(&text)
                .map_err(|e| StartError::ParseScenario { path, error: e.to_string() })?;
            (plan::parks(&run.spec, &frame), Some(plan::wind(&run.spec)), run.spec.seed.unwrap_or(0))
        }
        None => (Vec::new(), None, 0),
    };

    let drones: Vec<_> = fleet.drones.iter().filter(|d| !d.scripted).collect();
    let members: Vec<Member> = drones
        .iter()
        .map(|d| Member { role: d.role, home: frame.to_plane(d.home.latitude_deg, d.home.longitude_deg) })
        .collect();
    let tasks = plan::assign(&members, &zones[target].outline, &parks);
    let specs: Vec<DroneSpec> = drones
        .iter()
        .zip(&members)
        .map(|(d, m)| {
            let token = d.credential_env.as_ref().and_then(|var| {
                let token = std::env::var(var).ok();
                if token.is_none() {
                    println!("{}: no credential: the variable {var} is not set; asking without one", d.name);
                }
                token
            });
            DroneSpec {
                index: d.index,
                name: d.name.clone(),
                operator: d.operator.clone(),
                airframe: d.airframe.clone(),
                system_id: d.system_id,
                component_id: d.component_id,
                udp_url: d.mavlink.udp.clone(),
                home: m.home,
                max_altitude_agl_m: d.max_altitude_agl_m,
                token,
            }
        })
        .collect();
    let count = |role: Role| drones.iter().filter(|d| d.role == role).count();
    println!(
        "chicago-pilot: run {}: flying {} drones ({} public safety, {} journalists, {} recreational) round zone {} \
         (authority {}){}",
        fleet.run,
        drones.len(),
        count(Role::PublicSafety),
        count(Role::Journalist),
        count(Role::Recreational),
        zones[target].name,
        fleet.airspace_url,
        match (options.journalists_ignore_denials, options.ignore_denials_share) {
            (true, _) => "; journalists IGNORE denials".to_string(),
            (false, share) if share > 0.0 => format!("; each journalist ignores its denial with probability {share}"),
            _ => String::new(),
        }
    );
    for (spec, task) in specs.iter().zip(&tasks) {
        if let Task::PublicSafety { hold, watch } = task {
            println!(
                "  {}: hold at ({:.0}, {:.0}) m, watch from ({:.0}, {:.0}) m",
                spec.name, hold.0, hold.1, watch.0, watch.1
            );
        }
    }

    let ctx = Context {
        client,
        frame,
        zones,
        target,
        journalists_ignore_denials: options.journalists_ignore_denials,
        ignore_denials_share: options.ignore_denials_share,
        run_seed,
        seed: options.seed,
        wind,
    };
    let results: Vec<Result<(), String>> = std::thread::scope(|s| {
        let handles: Vec<_> = specs
            .iter()
            .zip(&tasks)
            .map(|(spec, task)| {
                let ctx = &ctx;
                std::thread::Builder::new()
                    .name(spec.name.clone())
                    .spawn_scoped(s, move || flight::fly(spec, ctx, task))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| match h {
                Ok(h) => h.join().unwrap_or_else(|_| Err("the drone's thread panicked".to_owned())),
                Err(e) => Err(format!("failed to start the drone's thread: {e}")),
            })
            .collect()
    });
    let failures =
        specs.iter().zip(results).filter_map(|(spec, r)| r.err().map(|reason| (spec.name.clone(), reason))).collect();
    Ok(Report { flown: specs.len(), failures })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Read, Write};

    /// A fleet file with no drones, pointing at `airspace_url`.
    fn fleet_file(dir: &std::path::Path, version: u32, airspace_url: &str) -> PathBuf {
        let path = dir.join(format!("fleet-{version}.json"));
        let fleet = serde_json::json!({
            "version": version, "run": "t",
            "origin": {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237, "altitudeMslM": 181.0},
            "airspaceUrl": airspace_url, "gcsUrls": [], "drones": [],
            "zones": {"type": "FeatureCollection", "features": []}
        });
        std::fs::write(&path, fleet.to_string()).unwrap();
        path
    }

    fn options(fleet: PathBuf, zone: Option<&str>) -> Options {
        Options {
            fleet,
            scenario: None,
            zone: zone.map(str::to_owned),
            journalists_ignore_denials: false,
            ignore_denials_share: 0.0,
            seed: 1,
        }
    }

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("chicago-pilot-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Serves `GET /zones` with one zone, `connections` times.
    fn fake_authority(connections: usize) -> String {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("http://{}", listener.local_addr().unwrap());
        std::thread::spawn(move || {
            let body = serde_json::json!({"type": "FeatureCollection", "features": [{
                "type": "Feature", "id": "museum-tfr",
                "geometry": {"type": "Polygon", "coordinates": [[
                    [-87.6245, 41.8807], [-87.6245, 41.8781], [-87.6208, 41.8781], [-87.6208, 41.8807], [-87.6245, 41.8807]
                ]]},
                "properties": {"name": "museum-tfr", "policy": {"minAltitudeAglM": 106.68}}
            }]})
            .to_string();
            for _ in 0..connections {
                let (mut s, _) = listener.accept().unwrap();
                let mut buf = [0u8; 2048];
                let _ = s.read(&mut buf).unwrap();
                let head = format!(
                    "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
                    body.len()
                );
                s.write_all(head.as_bytes()).unwrap();
                s.write_all(body.as_bytes()).unwrap();
            }
        });
        url
    }

    #[test]
    fn unusable_fleet_files_are_start_errors_naming_the_file() {
        let dir = temp_dir("fleet");
        let missing = dir.join("nope.json");
        let e = run(&options(missing, None)).unwrap_err();
        assert!(matches!(e, StartError::ReadFleet { .. }) && e.to_string().contains("nope.json"), "{e}");
        let bad = dir.join("bad.json");
        std::fs::write(&bad, "{\"version\": 1}").unwrap();
        let e = run(&options(bad, None)).unwrap_err();
        assert!(e.to_string().contains("not a SADE-SIM fleet file") && e.to_string().contains("`run`"), "{e}");
        let e = run(&options(fleet_file(&dir, 99, "http://127.0.0.1:1"), None)).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("fleet file {}: version 99 (this pilot reads version 1)", dir.join("fleet-99.json").display())
        );
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn an_unreachable_authority_stops_the_pilot_before_any_drone_flies() {
        let dir = temp_dir("down");
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let url = format!("http://127.0.0.1:{port}");
        let e = run(&options(fleet_file(&dir, 1, &url), None)).unwrap_err();
        assert!(matches!(e, StartError::Zones { .. }), "{e}");
        assert!(e.to_string().starts_with(&format!("the airspace authority at {url} did not list its zones")), "{e}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn the_zone_is_looked_up_by_name_and_an_empty_fleet_flies_nothing() {
        let dir = temp_dir("zones");
        let fleet = fleet_file(&dir, 1, &fake_authority(2));
        let e = run(&options(fleet.clone(), Some("stadium"))).unwrap_err();
        assert_eq!(e.to_string(), "--zone stadium: the authority has no such zone (it has: museum-tfr)");
        let report = run(&options(fleet, Some("museum-tfr"))).unwrap();
        assert_eq!(report, Report { flown: 0, failures: Vec::new() });
        std::fs::remove_dir_all(dir).unwrap();
    }
}
