//! The urban wind by OpenFOAM, run locally: writes the case of [`sadesim_wind::foam_case`]
//! to a directory, runs `blockMesh`, `snappyHexMesh -overwrite`, `simpleFoam` and
//! `postProcess -func writeCellCentres -latestTime` there (one process each, logs in
//! `CASE/log.<program>`), and maps the result onto the wind grid
//! ([`sadesim_wind::foam_import`]). Also reads a case a user computed elsewhere
//! ([`import_case_dir`]).
//!
//! OpenFOAM is Debian's `openfoam` package (v1912): its programs on `PATH`, its data under
//! `WM_PROJECT_DIR` (default `/usr/share/openfoam`, Debian's path). Nothing else of its
//! shell environment is needed.
//!
//! # A case directory
//! `CASE/<time>/U` and `CASE/<time>/C` (ASCII `volVectorField`s), `<time>` the latest time
//! directory that holds `U`; `C` from `postProcess -func writeCellCentres`. Coordinates in
//! the run's ENU metres, velocities in m/s; see [`sadesim_wind::foam_import`] for the
//! reference speed and the coverage the grid needs.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use sadesim_wind::foam_case::{CaseSpec, case_buildings, case_files};
use sadesim_wind::foam_import::{ImportError, ImportSpec, import_case};
use sadesim_wind::{SectorField, WindGrid};
use sadesim_world::World;

/// Where Debian's package puts OpenFOAM's data (`etc/controlDict`, ...).
pub const DEFAULT_WM_PROJECT_DIR: &str = "/usr/share/openfoam";

/// The programs a run needs, in order.
pub const PROGRAMS: [&str; 4] = ["blockMesh", "snappyHexMesh", "simpleFoam", "postProcess"];

/// Why OpenFOAM's wind could not be computed or read.
#[derive(Debug, thiserror::Error)]
pub enum OpenFoamRunError {
    /// A program is not on `PATH`, or OpenFOAM's data directory is missing.
    #[error(
        "{what}: install Debian's openfoam (`apt-get install openfoam`, or `bash tests/install-tools.sh`); its data must be at WM_PROJECT_DIR (default {DEFAULT_WM_PROJECT_DIR})"
    )]
    NotInstalled { what: String },
    /// A program exited with an error.
    #[error("{program} failed ({status}) in {case}; the end of its log {log}:\n{tail}")]
    Failed { program: String, status: String, case: PathBuf, log: PathBuf, tail: String },
    /// The case directory is not empty: an old run's time directories would be read as this one's.
    #[error("{0}: the case directory exists and is not empty; give a new or empty directory")]
    NotEmpty(PathBuf),
    /// A file or directory cannot be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// No time directory holds the velocity.
    #[error(
        "{case}: no time directory holds the velocity U (time directories: {times}); expected CASE/<time>/U, written by the solver with `writeFormat ascii`"
    )]
    NoVelocity { case: PathBuf, times: String },
    /// The latest time with `U` has no cell centres `C`.
    #[error(
        "{file} is missing: the cell centres of time {time}; run `postProcess -func writeCellCentres -time {time}` in the case"
    )]
    NoCellCentres { file: PathBuf, time: String },
    /// A field is compressed.
    #[error("{0} is compressed: gunzip it (or rerun with `writeCompression off;` in system/controlDict)")]
    Compressed(PathBuf),
    /// `C` or `U` cannot be read or do not cover the grid.
    #[error(transparent)]
    Import(#[from] ImportError),
}

/// What a run of the case did.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseRun {
    /// Cells of the final mesh (of `C`).
    pub cells: usize,
    /// simpleFoam's iterations, and whether its residuals fell below the targets before
    /// the iteration limit.
    pub iterations: usize,
    pub converged: bool,
    /// Wall time of meshing (blockMesh, snappyHexMesh), solving, and writing the cell centres, s.
    pub mesh_s: f64,
    pub solve_s: f64,
    pub post_s: f64,
}

/// `Ok` when OpenFOAM can run here, else the reason ([`OpenFoamRunError::NotInstalled`]).
///
/// # Errors
/// A program of [`PROGRAMS`] is not on `PATH`, or `WM_PROJECT_DIR` has no `etc/controlDict`.
pub fn check_installed() -> Result<(), OpenFoamRunError> {
    for program in PROGRAMS {
        if find_on_path(program).is_none() {
            return Err(OpenFoamRunError::NotInstalled { what: format!("{program} is not on PATH") });
        }
    }
    let project = project_dir();
    if !project.join("etc/controlDict").is_file() {
        return Err(OpenFoamRunError::NotInstalled {
            what: format!("WM_PROJECT_DIR={} has no etc/controlDict", project.display()),
        });
    }
    Ok(())
}

fn project_dir() -> PathBuf {
    std::env::var_os("WM_PROJECT_DIR").map_or_else(|| PathBuf::from(DEFAULT_WM_PROJECT_DIR), PathBuf::from)
}

fn find_on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(program)).find(|p| p.is_file())
}

/// The sector of the wind from `direction_from_deg` over `grid` (laid over `world`) by
/// OpenFOAM: the case of [`CaseSpec::for_grid`] run in `case_dir` (created; it must not
/// hold anything yet), mapped onto the grid. `progress` gets one line per step. The
/// sector's `iterations` are simpleFoam's. Minutes for a city block on one core.
///
/// # Errors
/// [`OpenFoamRunError`]: OpenFOAM not installed, a program failing (naming its log), the
/// case directory not empty, or the result not covering the grid.
pub fn compute_sector(
    world: &World,
    grid: &WindGrid,
    direction_from_deg: f64,
    case_dir: &Path,
    progress: impl FnMut(&str),
) -> Result<SectorField, OpenFoamRunError> {
    let spec = CaseSpec::for_grid(grid, direction_from_deg);
    let run = run_case(world, &spec, case_dir, progress)?;
    let mut sector = import_case_dir(
        grid,
        case_dir,
        ImportSpec { direction_from_deg, reference_speed_ms: spec.reference_speed_ms },
    )?;
    sector.iterations = run.iterations;
    Ok(sector)
}

/// Writes `spec`'s case over `world` to `case_dir` (created; it must not hold anything
/// yet) and runs it: blockMesh, snappyHexMesh (not when no building is in the case),
/// simpleFoam, the cell centres.
///
/// # Errors
/// As [`compute_sector`], but the import.
pub fn run_case(
    world: &World,
    spec: &CaseSpec,
    case_dir: &Path,
    mut progress: impl FnMut(&str),
) -> Result<CaseRun, OpenFoamRunError> {
    check_installed()?;
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| OpenFoamRunError::Io { path, source }
    };
    fs::create_dir_all(case_dir).map_err(io(case_dir))?;
    if fs::read_dir(case_dir).map_err(io(case_dir))?.next().is_some() {
        return Err(OpenFoamRunError::NotEmpty(case_dir.to_path_buf()));
    }
    for (rel, bytes) in case_files(world, spec) {
        let path = case_dir.join(rel);
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(io(parent))?;
        }
        fs::write(&path, bytes).map_err(io(&path))?;
    }
    let buildings = case_buildings(world, spec).len();
    let ([nx, ny], nu, ng) = spec.background_cells();
    progress(&format!(
        "OpenFOAM case in {}: {buildings} buildings, background {nx} x {ny} x {} cells",
        case_dir.display(),
        nu + ng
    ));

    let t = Instant::now();
    run_program(case_dir, "blockMesh", &[])?;
    if buildings > 0 {
        progress("snappyHexMesh: meshing around the buildings");
        run_program(case_dir, "snappyHexMesh", &["-overwrite"])?;
    }
    let mesh_s = t.elapsed().as_secs_f64();
    progress(&format!("simpleFoam: at most {} iterations", spec.max_iterations));
    let t = Instant::now();
    run_program(case_dir, "simpleFoam", &[])?;
    let solve_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    run_program(case_dir, "postProcess", &["-func", "writeCellCentres", "-latestTime"])?;
    let post_s = t.elapsed().as_secs_f64();

    let log = case_dir.join("log.simpleFoam");
    let text = fs::read_to_string(&log).map_err(io(&log))?;
    let iterations = text.lines().filter(|l| l.starts_with("Time = ")).count();
    let converged = text.contains("SIMPLE solution converged");
    let cells = mesh_cells(case_dir)?;
    progress(&format!(
        "OpenFOAM: {cells} cells, {iterations} iterations ({}), mesh {mesh_s:.0} s, solver {solve_s:.0} s",
        if converged { "converged" } else { "iteration limit" }
    ));
    Ok(CaseRun { cells, iterations, converged, mesh_s, solve_s, post_s })
}

/// Cells of the case's mesh, from `constant/polyMesh/owner`'s header note (`nCells:N`).
fn mesh_cells(case_dir: &Path) -> Result<usize, OpenFoamRunError> {
    let path = case_dir.join("constant/polyMesh/owner");
    let text = fs::read_to_string(&path).map_err(|source| OpenFoamRunError::Io { path: path.clone(), source })?;
    let n = text
        .split("nCells:")
        .nth(1)
        .and_then(|s| s.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|s| s.parse().ok());
    Ok(n.unwrap_or(0))
}

/// Runs `program args` in `case_dir` with OpenFOAM's environment, its output (both
/// streams) in `case_dir/log.<program>`.
fn run_program(case_dir: &Path, program: &str, args: &[&str]) -> Result<(), OpenFoamRunError> {
    let log_path = case_dir.join(format!("log.{program}"));
    let io = |source| OpenFoamRunError::Io { path: log_path.clone(), source };
    let log = fs::File::create(&log_path).map_err(io)?;
    let err = log.try_clone().map_err(io)?;
    let case_abs = fs::canonicalize(case_dir).unwrap_or_else(|_| case_dir.to_path_buf());
    let status = Command::new(program)
        .args(args)
        .current_dir(&case_abs)
        .env("WM_PROJECT_DIR", project_dir())
        // One process, and no OpenMPI refusal to run as root in containers.
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        // Else OpenFOAM warns that PWD is not the working directory.
        .env("PWD", &case_abs)
        .stdin(Stdio::null())
        .stdout(log)
        .stderr(err)
        .status()
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => {
                OpenFoamRunError::NotInstalled { what: format!("{program} is not on PATH") }
            }
            _ => OpenFoamRunError::Io { path: PathBuf::from(program), source: e },
        })?;
    if status.success() {
        return Ok(());
    }
    let text = fs::read_to_string(&log_path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    let tail = lines[lines.len().saturating_sub(20)..].join("\n");
    Err(OpenFoamRunError::Failed {
        program: program.to_string(),
        status: status.to_string(),
        case: case_dir.to_path_buf(),
        log: log_path,
        tail,
    })
}

/// The `C` and `U` of a case directory: those of its latest time directory holding `U`,
/// as `(C path, C text, U path, U text)`.
///
/// # Errors
/// [`OpenFoamRunError::NoVelocity`], [`OpenFoamRunError::NoCellCentres`],
/// [`OpenFoamRunError::Compressed`], or a file that cannot be read.
pub fn read_case_dir(case_dir: &Path) -> Result<(PathBuf, String, PathBuf, String), OpenFoamRunError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| OpenFoamRunError::Io { path, source }
    };
    // Time directories: names that are numbers (`0`, `500`, `0.5`, `1e+03`).
    let mut times: Vec<(f64, String)> = fs::read_dir(case_dir)
        .map_err(io(case_dir))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.parse::<f64>().ok().filter(|t| t.is_finite()).map(|t| (t, name))
        })
        .collect();
    times.sort_by(|a, b| b.0.total_cmp(&a.0));
    let Some((_, time)) = times.iter().find(|(_, name)| {
        let dir = case_dir.join(name);
        dir.join("U").is_file() || dir.join("U.gz").is_file()
    }) else {
        let mut names: Vec<&str> = times.iter().map(|(_, n)| n.as_str()).collect();
        names.reverse();
        let times = if names.is_empty() { "none".to_string() } else { names.join(", ") };
        return Err(OpenFoamRunError::NoVelocity { case: case_dir.to_path_buf(), times });
    };
    let dir = case_dir.join(time);
    let (c, u) = (dir.join("C"), dir.join("U"));
    if !u.is_file() {
        return Err(OpenFoamRunError::Compressed(dir.join("U.gz")));
    }
    if !c.is_file() {
        if dir.join("C.gz").is_file() {
            return Err(OpenFoamRunError::Compressed(dir.join("C.gz")));
        }
        return Err(OpenFoamRunError::NoCellCentres { file: c, time: time.clone() });
    }
    // Lossy: a binary file still shows its ASCII header, and the reader refuses it by its
    // `format binary` with the fix.
    let read = |p: &Path| fs::read(p).map(|b| String::from_utf8_lossy(&b).into_owned()).map_err(io(p));
    let c_text = read(&c)?;
    let u_text = read(&u)?;
    Ok((c, c_text, u, u_text))
}

/// The sector of a case directory (run here or elsewhere) on `grid`
/// ([`read_case_dir`], then [`sadesim_wind::foam_import::import_case`]).
///
/// # Errors
/// As [`read_case_dir`], and [`OpenFoamRunError::Import`] naming the file and the problem.
pub fn import_case_dir(grid: &WindGrid, case_dir: &Path, spec: ImportSpec) -> Result<SectorField, OpenFoamRunError> {
    let (c, c_text, u, u_text) = read_case_dir(case_dir)?;
    Ok(import_case(grid, &c.display().to_string(), &c_text, &u.display().to_string(), &u_text, spec)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("sadesim-openfoam-run-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    const C: &str = "FoamFile { format ascii; class volVectorField; object C; }\n\
                     dimensions [0 1 0 0 0 0 0];\ninternalField nonuniform List<vector> 1((0.5 0.5 0.5));\n";
    const U: &str = "FoamFile { format ascii; class volVectorField; object U; }\n\
                     dimensions [0 1 -1 0 0 0 0];\ninternalField uniform (1 0 0);\n";

    #[test]
    fn the_latest_time_with_u_is_read_and_a_missing_c_says_how_to_write_it() {
        let case = temp("layout");
        for (t, files) in [("0", vec![("U", U)]), ("100", vec![("U", U), ("C", C)]), ("250", vec![("U", U)])] {
            fs::create_dir_all(case.join(t)).unwrap();
            for (name, text) in files {
                fs::write(case.join(t).join(name), text).unwrap();
            }
        }
        fs::create_dir_all(case.join("constant")).unwrap();
        let err = read_case_dir(&case).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(&err, OpenFoamRunError::NoCellCentres { time, .. } if time == "250"), "{msg}");
        assert!(msg.ends_with("250/C is missing: the cell centres of time 250; run `postProcess -func writeCellCentres -time 250` in the case"), "{msg}");

        fs::write(case.join("250/C"), C).unwrap();
        let (c, c_text, u, _) = read_case_dir(&case).unwrap();
        assert_eq!((c, u), (case.join("250/C"), case.join("250/U")));
        assert_eq!(c_text, C);

        fs::remove_file(case.join("250/C")).unwrap();
        fs::write(case.join("250/C.gz"), b"\x1f\x8b").unwrap();
        assert!(
            matches!(read_case_dir(&case).unwrap_err(), OpenFoamRunError::Compressed(p) if p == case.join("250/C.gz"))
        );
        let _ = fs::remove_dir_all(&case);
    }

    #[test]
    fn a_case_without_u_names_its_time_directories() {
        let case = temp("no-u");
        fs::create_dir_all(case.join("0")).unwrap();
        fs::create_dir_all(case.join("500")).unwrap();
        fs::write(case.join("500/p"), "").unwrap();
        let msg = read_case_dir(&case).unwrap_err().to_string();
        assert!(msg.contains("no time directory holds the velocity U (time directories: 0, 500)"), "{msg}");
        let _ = fs::remove_dir_all(&case);
    }

    #[test]
    fn a_nan_in_u_is_named_with_its_file_and_line() {
        let case = temp("nan");
        fs::create_dir_all(case.join("100")).unwrap();
        fs::write(case.join("100/C"), C).unwrap();
        fs::write(case.join("100/U"), U.replace("uniform (1 0 0)", "nonuniform List<vector> 1((nan 0 0))")).unwrap();
        let grid = sadesim_wind::WindGrid::over(
            &World::of_buildings(5.0, vec![]),
            sadesim_wind::GridSpec { spacing_m: 5.0, top_factor: 2.0 },
        );
        let spec = ImportSpec { direction_from_deg: 0.0, reference_speed_ms: 5.0 };
        let msg = import_case_dir(&grid, &case, spec).unwrap_err().to_string();
        let want = format!(
            "{}:3: entry 0 (0-based) of the internal field has a non-finite component (nan)",
            case.join("100/U").display()
        );
        assert!(msg.starts_with(&want), "{msg}");
        let _ = fs::remove_dir_all(&case);
    }

    #[test]
    fn a_missing_program_says_to_install_openfoam_and_a_failing_one_names_its_log() {
        let case = temp("programs");
        let err = run_program(&case, "noSuchFoamProgram", &[]).unwrap_err();
        assert!(err.to_string().starts_with("noSuchFoamProgram is not on PATH: install Debian's openfoam"), "{err}");
        if check_installed().is_err() {
            eprintln!("skipped the failing run: OpenFOAM is not installed");
            return;
        }
        // blockMesh in a directory without system/controlDict.
        let err = run_program(&case, "blockMesh", &[]).unwrap_err();
        let OpenFoamRunError::Failed { ref program, ref log, ref tail, .. } = err else { panic!("{err:?}") };
        assert_eq!((program.as_str(), log), ("blockMesh", &case.join("log.blockMesh")));
        assert!(tail.contains("controlDict"), "{tail}");
        assert!(
            err.to_string().contains(&format!("the end of its log {}", case.join("log.blockMesh").display())),
            "{err}"
        );
        let _ = fs::remove_dir_all(&case);
    }
}
