//! Planning a run on the cluster: the planner, with the files a mapped world names (the
//! OpenStreetMap extract of `world.source: osm`, the DEM of `world.terrain.dem`) read from
//! object storage.
//!
//! The planner needs the world: homes are drawn on its open ground and refused inside its
//! buildings, and the asset cache key hashes the files' bytes. So the operator reads them,
//! once per (uid, generation) like every plan (`Context::plan_of`), on a blocking thread
//! (object-store reads block), and plans with them exactly as `sadesim run` does. The
//! `<run>-assets` Job then builds the world's bundle from the same files; shards and the
//! coordinator load the bundle.
//!
//! # Caveats
//! The files are read whole into the operator's memory for the time of planning: clip
//! large extracts to the region (`osmium extract -b ...`) before putting them in a bucket.

use std::sync::Arc;

use sadesim_crds::SimulationRun;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::run::SimulationRunSpec;
use sadesim_evidence::archive::is_object_store;
use sadesim_planner::PlanError;
use sadesim_sources::world::{WorldReadError, world_files};
use sadesim_world::WorldData;

/// Why a run does not plan on the cluster.
#[derive(Debug, thiserror::Error)]
pub enum PlanFailure {
    /// The planner refused the run (every validation problem, or the world).
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A world file is a local path: the operator and the pods share no disk with the user.
    #[error(
        "{field}: {file:?} is a path on the machine that wrote the scenario; a Kubernetes run reads its world files from object storage: upload it and give its URL (s3://bucket/key, gs://... or az://...; credentials from the operator's object-store Secret)"
    )]
    LocalFile { field: &'static str, file: String },
    /// A world file could not be read or decoded (the message names the field and URL).
    #[error(transparent)]
    Read(#[from] WorldReadError),
    /// The blocking read was cancelled or panicked.
    #[error("reading the world's files did not finish: {0}")]
    Task(String),
}

impl PlanFailure {
    /// A fetch that failed for a reason that may pass (the store unreachable, a server
    /// error, the store not configurable yet): worth retrying, not a verdict on the spec.
    pub fn may_pass(&self) -> bool {
        use sadesim_evidence::archive::ArchiveError;
        matches!(
            self,
            PlanFailure::Task(_)
                | PlanFailure::Read(WorldReadError::Fetch {
                    source: ArchiveError::Download { .. } | ArchiveError::Open { .. } | ArchiveError::Runtime(_),
                    ..
                })
        )
    }
}

/// Reads the files a run's world names. The operator reads them from object storage
/// ([`ObjectStoreFiles`]); tests read fixtures.
pub trait WorldFiles: Send + Sync {
    /// The decoded files of `spec`'s world.
    ///
    /// # Errors
    /// A file cannot be fetched, or is not a map or DEM that covers the world.
    fn read(&self, spec: &SimulationRunSpec) -> Result<WorldData, WorldReadError>;
}

/// The world's files from object storage (credentials from the operator's environment:
/// the Helm chart's object-store Secret).
#[derive(Debug, Default)]
pub struct ObjectStoreFiles;

impl WorldFiles for ObjectStoreFiles {
    fn read(&self, spec: &SimulationRunSpec) -> Result<WorldData, WorldReadError> {
        sadesim_sources::world::read_data(spec)
    }
}

/// The first world file of `spec` that a cluster cannot read: a local path or `file://`
/// URL (pure; decides before anything is fetched).
pub fn local_file(spec: &SimulationRunSpec) -> Option<PlanFailure> {
    world_files(spec)
        .into_iter()
        .find(|(_, file)| !is_object_store(file))
        .map(|(field, file)| PlanFailure::LocalFile { field, file })
}

/// Plans `run` as the operator does, blocking while `files` reads a mapped world's files
/// (also what `sadesim manifests` prints, with the files read on the user's machine).
///
/// # Errors
/// [`PlanFailure`]: the run does not validate, a world file is local or cannot be read,
/// or the planner's refusal.
pub fn plan_blocking(run: &SimulationRun, files: &dyn WorldFiles) -> Result<RunPlan, PlanFailure> {
    if world_files(&run.spec).is_empty() {
        return Ok(sadesim_planner::plan(run)?);
    }
    // Validation problems first: they name the field even when a file is also wrong.
    sadesim_crds::validate::validate(run).map_err(PlanError::from)?;
    if let Some(failure) = local_file(&run.spec) {
        return Err(failure);
    }
    let data = files.read(&run.spec)?;
    Ok(sadesim_planner::plan_with(run, &data)?)
}

/// [`plan_blocking`] for the reconcile loop: a procedural world at once, a mapped one on a
/// blocking thread (object-store reads block).
///
/// # Errors
/// As [`plan_blocking`]; [`PlanFailure::Task`] when the thread did not finish.
pub async fn plan(run: &SimulationRun, files: Arc<dyn WorldFiles>) -> Result<RunPlan, PlanFailure> {
    if world_files(&run.spec).is_empty() {
        return Ok(sadesim_planner::plan(run)?);
    }
    let run = run.clone();
    tokio::task::spawn_blocking(move || plan_blocking(&run, files.as_ref()))
        .await
        .map_err(|e| PlanFailure::Task(e.to_string()))?
}

/// Test support: the fixture origin's SRTM tile as a DEM.
#[cfg(test)]
pub(crate) mod fixture {
    /// Where the tests keep it: an object-store URL.
    pub const TILE_URL: &str = "s3://maps/srtm/N41W088.hgt";

    /// The fixture origin's SRTM tile (N41W088: 41-42 N, 88-87 W), 1 201 x 1 201 samples
    /// rising 1 m per sample eastwards from 150 m.
    pub fn tile() -> sadesim_world::dem::Dem {
        let mut bytes = Vec::with_capacity(1201 * 1201 * 2);
        for _ in 0..1201 {
            for i in 0..1201i16 {
                bytes.extend_from_slice(&(150 + i).to_be_bytes());
            }
        }
        sadesim_world::dem::Dem::read(&bytes, TILE_URL).expect("a valid tile")
    }

    /// The fixture run over [`tile`] at [`TILE_URL`].
    pub fn over_tile(mut run: sadesim_crds::SimulationRun) -> sadesim_crds::SimulationRun {
        use sadesim_crds::run::{DemFile, TerrainSpec, World};
        run.spec.world =
            Some(World { terrain: Some(TerrainSpec { dem: DemFile { file: TILE_URL.into() } }), ..Default::default() });
        run
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_crds::fixtures::RunBuilder;
    use sadesim_crds::run::{DemFile, TerrainSpec, World};

    fn with_dem(file: &str) -> SimulationRun {
        RunBuilder::test()
            .with(|r| {
                r.spec.world = Some(World {
                    terrain: Some(TerrainSpec { dem: DemFile { file: file.into() } }),
                    ..Default::default()
                })
            })
            .build()
    }

    /// A store that does not answer is retried (nothing cached, no verdict on the spec); an
    /// object that is not there is the spec's problem.
    #[test]
    fn only_fetch_failures_that_may_pass_are_retried() {
        use sadesim_evidence::archive::ArchiveError;
        let fetch = |source| PlanFailure::Read(WorldReadError::Fetch { field: "spec.world.osm.file", source });
        assert!(fetch(ArchiveError::Runtime(std::io::Error::other("no threads"))).may_pass());
        assert!(!fetch(ArchiveError::NotFound { url: "s3://maps/x.osm.pbf".into() }).may_pass());
        assert!(!PlanFailure::LocalFile { field: "spec.world.osm.file", file: "x".into() }.may_pass());
        let missing = fetch(ArchiveError::NotFound { url: "s3://maps/x.osm.pbf".into() }).to_string();
        assert_eq!(
            missing,
            "spec.world.osm.file: s3://maps/x.osm.pbf: nothing there (no such folder, or no objects under this prefix)"
        );
    }

    #[test]
    fn local_paths_and_file_urls_are_refused_naming_the_field() {
        for file in ["/data/N41W088.hgt", "maps/N41W088.hgt", "file:///data/N41W088.hgt"] {
            let failure = local_file(&with_dem(file).spec).expect("refused").to_string();
            assert!(failure.starts_with("spec.world.terrain.dem.file: "), "{failure}");
            assert!(failure.contains(file) && failure.contains("s3://bucket/key"), "{failure}");
        }
        assert!(local_file(&with_dem("s3://maps/N41W088.hgt").spec).is_none());
        assert!(local_file(&RunBuilder::test().build().spec).is_none(), "a procedural world names no file");
    }
}
