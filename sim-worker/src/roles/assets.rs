//! `sim-worker assets`: the run's world built once into the asset cache (the `<run>-assets`
//! Job on Kubernetes), or found there: a verified entry of the plan's asset cache key is a
//! hit and nothing is built. A run with wind among buildings also gets its urban wind
//! field, every direction sector, in the entry beside the world's (logged on stderr with
//! its progress): the shards load it instead of computing it.
//!
//! The outcome is one JSON line ([`AssetsOutcome`]) on stdout and, with `--report-file`, in
//! that file: the Job sets it to the container's termination message
//! (`/dev/termination-log`), which the operator reads into the `AssetsReady` condition
//! (`CacheHit` or `Built`) without reading the logs.

use std::path::Path;

use sadesim_crds::outcome::assets::AssetsOutcome;
use sadesim_crds::plan::RunPlan;

use super::RoleError;

/// Builds (or finds) the bundle of `plan` in the cache at `archive_url`, prints the
/// outcome and writes it to `report_file`.
///
/// # Errors
/// The cache cannot be opened or written, the world's files cannot be read, or the report
/// file cannot be written.
pub fn run(plan: &RunPlan, archive_url: &str, report_file: Option<&Path>) -> Result<AssetsOutcome, RoleError> {
    // One scratch folder per call, not per process: two runs built at once in one process
    // (the tests do) must not remove each other's files.
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let scratch = std::env::temp_dir().join(format!("sadesim-assets-{}-{call}", std::process::id()));
    let started = std::time::Instant::now();
    let progress = |done: u32, total: u32| {
        eprintln!("urban wind: sector {done} of {total} computed ({:.1} s)", started.elapsed().as_secs_f64());
    };
    let build_wind = |world: &sadesim_world::World, request: &sadesim_wind::request::WindRequest| {
        crate::wind_field::build_field(world, request, &scratch.join("wind"), progress)
            .map_err(|e| sadesim_sources::assets::AssetsError::WindBuild(e.to_string()))
    };
    let built = sadesim_sources::assets::build_run_assets(plan, archive_url, &scratch, build_wind);
    let _ = std::fs::remove_dir_all(&scratch);
    let (outcome, wind) = built?;
    if let Some(wind) = wind {
        eprintln!("{wind}");
    }
    let line = serde_json::to_string(&outcome).expect("an outcome always serializes");
    println!("{line}");
    // On stderr (the role's log) in words.
    eprintln!("{outcome}");
    if let Some(path) = report_file {
        std::fs::write(path, &line).map_err(|source| RoleError::Record { path: path.display().to_string(), source })?;
    }
    Ok(outcome)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::test_dir::TempDir;
    use sadesim_engine::fixtures::{plan_of, run_with_groups};

    #[test]
    fn builds_once_then_reports_a_cache_hit_in_the_report_file() {
        let dir = TempDir::new("assets-role");
        let plan = plan_of(run_with_groups(&[("a", 1)]).build());
        let archive = format!("file://{}", dir.0.join("archive").display());
        let report = dir.0.join("termination-log");
        let first = run(&plan, &archive, Some(&report)).expect("builds");
        assert!(matches!(first, AssetsOutcome::Built { replaced: None, .. }), "{first:?}");
        let written: AssetsOutcome = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        assert_eq!(written, first);
        let second = run(&plan, &archive, Some(&report)).expect("hits");
        assert_eq!(second, AssetsOutcome::CacheHit { url: first.url().to_string() });
        let written: AssetsOutcome = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        assert_eq!(written.reason(), "CacheHit");
    }

    #[test]
    fn the_urban_wind_field_is_stored_beside_the_world_and_the_shards_load_it() {
        use sadesim_crds::environment::{Environment, UrbanWind, UrbanWindModel, Wind};
        let dir = TempDir::new("assets-role-wind");
        let windy = run_with_groups(&[("a", 1)]).with(|r| {
            r.spec.environment = Some(Environment {
                wind: Some(Wind {
                    speed_mps: 8.0,
                    direction_from_deg: 100.0,
                    reference_height_m: None,
                    turbulence: Default::default(),
                    urban: Some(UrbanWind {
                        model: UrbanWindModel::Diagnostic,
                        case: None,
                        spacing_m: None,
                        sectors: Some(4),
                    }),
                }),
                ..Default::default()
            });
        });
        let plan = plan_of(windy.build());
        let archive = format!("file://{}", dir.0.join("archive").display());
        let built = run(&plan, &archive, None).expect("builds");
        let world = crate::roles::world(&plan, Some(built.url())).expect("the bundle loads");
        // Loaded: every sector the asset role computed (a shard computing it itself would
        // have only the two that a wind from 100° blends).
        let loaded = crate::roles::surroundings(&plan, world.clone(), None, Some(built.url())).unwrap();
        let field = loaded.wind.expect("a field");
        assert_eq!(field.sectors.iter().map(|(k, _)| *k).collect::<Vec<_>>(), [0, 1, 2, 3]);
        let computed = crate::roles::surroundings(&plan, world, None, None).unwrap().wind.expect("a field");
        assert_eq!(computed.sectors.iter().map(|(k, _)| *k).collect::<Vec<_>>(), [1, 2]);
        // The same numbers either way.
        assert_eq!(field.sector(1), computed.sector(1));
    }
}
