//! Runtime roles as process entry points (`sim-worker <role>`): the same code the local
//! runner uses in-process, behind TCP.

pub mod assets;
pub mod control;
pub mod coordinator;
pub mod renderer;
pub mod router;
pub mod shard;
pub mod wait_release;

use std::path::Path;
use std::sync::Arc;

use sadesim_crds::plan::{PLAN_FORMAT_VERSION, RunPlan};
use sadesim_world::World;

use sadesim_engine::env::urban_wind_field;

/// Why a role could not start.
#[derive(Debug, thiserror::Error)]
pub enum RoleError {
    #[error("failed to read the plan {path}: {source}")]
    ReadPlan { path: String, source: std::io::Error },
    #[error("failed to write {path}: {source}")]
    Write { path: String, source: std::io::Error },
    /// A file stored in parts (`sadesim_crds::parts`) that does not join.
    #[error("{0}")]
    Parts(#[from] sadesim_crds::parts::PartsError),
    #[error("the plan {path} is not a RunPlan: {source}")]
    ParsePlan { path: String, source: serde_json::Error },
    #[error("the plan {path} has format version {found}; this sim-worker reads version {PLAN_FORMAT_VERSION}")]
    PlanVersion { path: String, found: u32 },
    #[error("network: {0}")]
    Io(#[from] std::io::Error),
    /// The shard cannot be built or its sockets opened.
    #[error(transparent)]
    ShardStart(#[from] crate::shard_io::StartError),
    #[error(transparent)]
    Coordinator(#[from] sadesim_engine::coordinator::CoordinatorError),
    #[error("failed to record into {path}: {source}")]
    Record { path: String, source: std::io::Error },
    #[error("{0}")]
    Protocol(String),
    /// The coordinator stopped waiting for its shards (`--connect-timeout`, or Ctrl-C).
    #[error("{0}")]
    NotConnected(String),
    #[error(transparent)]
    Router(#[from] crate::mavlink::router::RouterError),
    /// The plan and flags do not describe a router (unknown segment, bad `--drone-host`).
    #[error("{0}")]
    RouterSetup(String),
    /// `--control-file` cannot be read (the message names the flag and the file).
    #[error("{0}")]
    ControlFile(std::io::Error),
    /// The run's world cannot be read (its extract).
    #[error(transparent)]
    World(#[from] sadesim_sources::world::WorldReadError),
    /// `--assets` names a bundle that cannot be loaded (missing, damaged, another format).
    #[error(transparent)]
    Assets(#[from] sadesim_sources::assets::AssetsError),
    /// The run's GNSS constellation cannot be read (its orbit file, its epoch).
    #[error(transparent)]
    Sky(#[from] sadesim_sources::gnss::SkyReadError),
    /// The run's urban wind field cannot be made (OpenFOAM, an imported case).
    #[error("urban wind field: {0}")]
    Wind(String),
}

/// The run's world, for every role that needs it (shards fly in it, the coordinator
/// records it and draws it in the report, the assets role stores it): loaded from the asset
/// bundle at `assets` (`world.bin`, checked against the bundle's manifest), else built from
/// the plan and the files it names (deterministic, so every role builds the same one; a
/// cluster run without an object-store cache does this).
///
/// # Errors
/// The bundle cannot be loaded, or the world's files cannot be read.
pub fn world(plan: &RunPlan, assets: Option<&str>) -> Result<Arc<World>, RoleError> {
    let started = std::time::Instant::now();
    let world = match assets {
        Some(url) => sadesim_sources::assets::load_bundle(url)?,
        None => sadesim_sources::world::load_world(&plan.spec)?,
    };
    // On stderr (the role's log): where the world came from.
    let from = assets.map_or_else(
        || "built from the plan (no --assets)".to_string(),
        |u| format!("loaded from the asset bundle {u}"),
    );
    let ms = started.elapsed().as_secs_f64() * 1e3;
    eprintln!("world: {} buildings, {from} in {ms:.0} ms", world.buildings().len());
    Ok(Arc::new(world))
}

/// The run's GNSS sky for the shards' ranging receivers (`None` without a constellation):
/// the orbit file read and placed over the origin at the run's epoch.
///
/// # Errors
/// The orbit file cannot be read or parsed, or the epoch is not a time.
pub fn sky(plan: &RunPlan) -> Result<Option<Arc<sadesim_gnss::RunSky>>, RoleError> {
    let sky = sadesim_sources::gnss::load_sky(&plan.spec)?;
    if let Some(s) = &sky {
        eprintln!(
            "sky: {} navigation satellites, mask {}°, t = 0 at UNIX {:.0} s",
            s.constellation().satellites.len(),
            s.mask_deg(),
            s.epoch_unix_s()
        );
    }
    Ok(sky.map(Arc::new))
}

/// The shard's surroundings: `world`, `sky` and the urban wind field, loaded from the
/// asset cache entry beside the world's (`assets`: the world entry's URL; the `<run>-assets`
/// Job or the local runner stored it) or, without one, made here (an imported OpenFOAM
/// case is always read here). Logged on stderr (the role's log) with where it came from
/// and what it took.
///
/// # Errors
/// An OpenFOAM field cannot be made (not installed, a program failing, a case that does not
/// read or cover the grid).
pub fn surroundings(
    plan: &RunPlan,
    world: Arc<World>,
    sky: Option<Arc<sadesim_gnss::RunSky>>,
    assets: Option<&str>,
) -> Result<sadesim_engine::shard::Surroundings, RoleError> {
    use sadesim_sources::wind::{load_wind, wind_entry_url_beside, wind_key};
    use sadesim_wind::request::wind_request;
    let started = std::time::Instant::now();
    let Some(request) = wind_request(&plan.spec, &world) else {
        return Ok(sadesim_engine::shard::Surroundings { world, sky, wind: None });
    };
    let cached = match (wind_key(&plan.asset_cache_key, &request), assets) {
        (Some(key), Some(assets)) => {
            let url = wind_entry_url_beside(assets, &key);
            match load_wind(&url) {
                Ok(field) => {
                    eprintln!("urban wind: loaded from {url}");
                    Some(field)
                }
                Err(e) => {
                    eprintln!("urban wind: not in the asset cache ({e}); making it here");
                    None
                }
            }
        }
        _ => None,
    };
    let field = match cached {
        Some(field) => field,
        None => match urban_wind_field(&plan.spec, &world) {
            Some(field) => field,
            None => {
                let scratch = std::env::temp_dir().join(format!("sadesim-wind-{}", std::process::id()));
                let built = crate::wind_field::build_field(&world, &request, &scratch, |done, total| {
                    eprintln!("urban wind: sector {done} of {total} made");
                });
                let _ = std::fs::remove_dir_all(&scratch);
                built.map_err(|e| RoleError::Wind(e.to_string()))?
            }
        },
    };
    eprintln!("{}", sadesim_engine::env::describe_urban_wind(&field, started.elapsed().as_secs_f64()));
    Ok(sadesim_engine::shard::Surroundings { world, sky, wind: Some(Arc::new(field)) })
}

/// The bytes of the file `path`, whole or joined from its parts beside it
/// ([`sadesim_crds::parts::join`]): how roles read what the operator mounts from ConfigMaps.
///
/// # Errors
/// [`PartsError`](sadesim_crds::parts::PartsError): unreadable, missing, or parts that do
/// not join.
pub fn read_parts(path: &Path) -> Result<Vec<u8>, sadesim_crds::parts::PartsError> {
    sadesim_crds::parts::join(path, |file| match std::fs::read(file) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(sadesim_crds::parts::PartsError::Io { path: file.display().to_string(), source }),
    })
}

/// Reads a RunPlan written by the planner (`plan.json`), whole or, as the operator stores a
/// large plan, in parts beside it (`plan.json.part-000`, ..., checked against
/// `plan.json.sha256`).
///
/// # Errors
/// Unreadable file or parts, parts that do not join, not a plan, or another plan format
/// version.
pub fn read_plan(path: &Path) -> Result<RunPlan, RoleError> {
    let name = path.display().to_string();
    let bytes = read_parts(path)?;
    let plan: RunPlan =
        serde_json::from_slice(&bytes).map_err(|source| RoleError::ParsePlan { path: name.clone(), source })?;
    if plan.format_version != PLAN_FORMAT_VERSION {
        return Err(RoleError::PlanVersion { path: name, found: plan.format_version });
    }
    Ok(plan)
}

#[cfg(test)]
mod tests {
    use sadesim_crds::parts::{PartsError, digest_name, part_name, sha256_hex, split};

    use super::read_parts;
    use crate::record::test_dir::TempDir;

    /// A file the operator stored in parts, read from the folder its ConfigMaps are mounted
    /// in: joined whole; a part that cannot be read is named with the reader's error.
    #[test]
    fn a_mounted_file_in_parts_is_read_whole() {
        let dir = TempDir::new("read-parts");
        let text = "plan ".repeat(500);
        for (i, part) in split(&text, 1000).iter().enumerate() {
            std::fs::write(dir.0.join(part_name("plan.json", i)), part).unwrap();
        }
        std::fs::write(dir.0.join(digest_name("plan.json")), sha256_hex(text.as_bytes())).unwrap();
        assert_eq!(read_parts(&dir.0.join("plan.json")).unwrap(), text.as_bytes());
        let missing = read_parts(&dir.0.join("fleet.json")).unwrap_err();
        assert!(matches!(missing, PartsError::Missing { .. }), "{missing}");
        // A folder where a part should be: not "missing", the read error itself.
        std::fs::remove_file(dir.0.join(part_name("plan.json", 1))).unwrap();
        std::fs::create_dir(dir.0.join(part_name("plan.json", 1))).unwrap();
        let unreadable = read_parts(&dir.0.join("plan.json")).unwrap_err();
        assert!(
            matches!(&unreadable, PartsError::Io { path, .. } if path.ends_with("plan.json.part-001")),
            "{unreadable}"
        );
    }
}
