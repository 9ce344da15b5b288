//! Cross-check of the two urban wind methods on a real city block (issue 17): the built-in
//! diagnostic field (Röckle zones and the mass-consistent adjustment) and OpenFOAM
//! (snappyHexMesh and simpleFoam, `sadesim_wind::foam_case`) on the same wind grid over a
//! block of the Helsinki world; prints the agreement as one JSON line. docs/wind-cfd.md has
//! the numbers.
//!
//! ```text
//! cargo run --release -p sim-worker --example wind_crosscheck -- \
//!     [--scenario examples/maps/helsinki.yaml] [--block-m 300] [--cell-m 5] \
//!     [--direction-deg 225] [--refine 1] [--max-iterations 600] [--centre E,N] [--case DIR [--reuse]]
//! ```
//!
//! - World: the scenario's (its OSM extract beside it, `Helsinki.osm.pbf`). The block is a
//!   `--block-m` square: centred at `--centre` (ENU metres) or, by default, at the point of
//!   a 25 m lattice, the block inside the world square, where the buildings whose footprint
//!   centre is in the block have the largest sum of footprint area x height²
//!   (favouring tall buildings). Those buildings become a world of their own, moved so the
//!   block's centre is the origin, on flat ground at their heights (the rest of the city
//!   is left out: both methods see the same buildings).
//! - Grid: `--cell-m` cubes over the block, up to twice the tallest building
//!   (`GridSpec { top_factor: 2 }`).
//! - Wind from `--direction-deg` (a sector of the default 8, so the diagnostic field is
//!   not blended): the diagnostic sector; OpenFOAM's case of `CaseSpec::for_grid` with
//!   `--refine` levels at the buildings and at most `--max-iterations` iterations, in
//!   `--case` (default a temporary directory; it must not exist or be empty). With
//!   `--reuse`, the case in `--case` is not run again, only read (same other flags).
//! - Speed: the magnitude of the factor vector (speed / reference speed 10 m above open ground).
//! - Correlation: Pearson's, of the two methods' speeds over the fluid cells 20-60 m above
//!   the ground; and of the speeds over each method's undisturbed profile at the cell's
//!   height (what the buildings change, without the profile's growth with height).
//! - Wake cells: fluid cells below the roof of a building that lies upwind of them within
//!   three of its heights (walking upwind from the cell's centre in half-cell steps, the
//!   first building whose footprint holds the point and whose roof is above the cell) and
//!   at least 2 m above the ground. Speed reduction there: `1 - speed / undisturbed speed
//!   at the cell's height`, each method against its own inflow profile (the diagnostic's
//!   `ln(z/z0)/ln(10/z0)`, OpenFOAM's `ln((z+z0)/z0)/ln((10+z0)/z0)`, z0 = 1 m), averaged
//!   over the wake cells.

use std::path::PathBuf;
use std::time::Instant;

use sadesim_wind::compare::correlation;
use sadesim_wind::foam_case::{CaseSpec, REFERENCE_HEIGHT_M};
use sadesim_wind::foam_import::ImportSpec;
use sadesim_wind::profile::FIELD_PROFILE;
use sadesim_wind::rockle::WindAxes;
use sadesim_wind::{GridSpec, SectorField, UrbanWindField, WindGrid};
use sadesim_world::{Building, Footprint, World};
use sim_worker::wind_field::openfoam_run::{import_case_dir, run_case};

struct Args {
    scenario: PathBuf,
    block_m: f64,
    cell_m: f64,
    direction_deg: f64,
    refine: u32,
    max_iterations: u32,
    centre: Option<[f64; 2]>,
    case: Option<PathBuf>,
    reuse: bool,
}

fn args() -> Args {
    let mut a = Args {
        scenario: PathBuf::from("examples/maps/helsinki.yaml"),
        block_m: 300.0,
        cell_m: 5.0,
        direction_deg: 225.0,
        refine: 1,
        max_iterations: 600,
        centre: None,
        case: None,
        reuse: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--reuse" {
            a.reuse = true;
            continue;
        }
        let value = it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        let num = |v: &str| v.parse::<f64>().unwrap_or_else(|_| panic!("{flag}: not a number: {v}"));
        match flag.as_str() {
            "--scenario" => a.scenario = PathBuf::from(value),
            "--block-m" => a.block_m = num(&value),
            "--cell-m" => a.cell_m = num(&value),
            "--direction-deg" => a.direction_deg = num(&value),
            "--refine" => a.refine = num(&value) as u32,
            "--max-iterations" => a.max_iterations = num(&value) as u32,
            "--centre" => {
                let v: Vec<f64> = value.split(',').map(num).collect();
                a.centre = Some([v[0], v[1]]);
            }
            "--case" => a.case = Some(PathBuf::from(value)),
            other => panic!("unknown flag {other}"),
        }
    }
    a
}

/// The scenario's world, its extract's path made absolute against the scenario's folder.
fn load_world(scenario: &std::path::Path) -> World {
    let text = std::fs::read_to_string(scenario).unwrap_or_else(|e| panic!("{}: {e}", scenario.display()));
    let mut run = sadesim_crds::document::parse_run(&text).unwrap_or_else(|e| panic!("{}: {e}", scenario.display()));
    let base = scenario.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
    if let Some(osm) = run.spec.world.as_mut().and_then(|w| w.osm.as_mut()) {
        let path = PathBuf::from(&osm.file);
        if path.is_relative() {
            osm.file = base.join(path).display().to_string();
        }
    }
    sadesim_sources::world::load_world(&run.spec).unwrap_or_else(|e| panic!("{}: {e}", scenario.display()))
}

/// The buildings whose footprint's bounding-box centre is in the `side` square centred at
/// `c`, moved by `-c`, on flat ground.
fn block(world: &World, c: [f64; 2], side: f64) -> Vec<Building> {
    let h = side / 2.0;
    world
        .buildings_in_rect(&[c[0] - h, c[1] - h, c[0] + h, c[1] + h])
        .into_iter()
        .map(|b| &world.buildings()[b])
        .filter(|b| {
            let m = b.footprint().bounds_center();
            (m[0] - c[0]).abs() < h && (m[1] - c[1]).abs() < h
        })
        .filter_map(|b| {
            let f = b.footprint();
            let shift = |ring: &[[f64; 2]]| ring.iter().map(|p| [p[0] - c[0], p[1] - c[1]]).collect::<Vec<_>>();
            let footprint = Footprint::new(shift(f.outer()), f.holes().iter().map(|r| shift(r)).collect()).ok()?;
            Building::new(footprint, 0.0, b.height_m()).ok()
        })
        .collect()
}

/// Sum of footprint area x height² of a block's buildings.
fn weight(buildings: &[Building]) -> f64 {
    buildings.iter().map(|b| b.footprint_area_m2() * b.height_m().powi(2)).sum()
}

fn speed(s: &SectorField, c: usize) -> f64 {
    (f64::from(s.east[c]).powi(2) + f64::from(s.north[c]).powi(2) + f64::from(s.up[c]).powi(2)).sqrt()
}

/// The wake cells of the module's documentation.
fn wake_cells(world: &World, grid: &WindGrid, direction_deg: f64) -> Vec<usize> {
    let up = WindAxes::from_deg(direction_deg).downwind.map(|d| -d);
    let tallest = world.buildings().iter().map(Building::height_m).fold(0.0, f64::max);
    let step = grid.spacing_m / 2.0;
    let mut out = Vec::new();
    for k in 0..grid.dims[2] {
        for j in 0..grid.dims[1] {
            for i in 0..grid.dims[0] {
                let c = grid.index(i, j, k);
                let agl = grid.height_agl_m(i, j, k);
                if grid.solid[c] || agl < 2.0 || agl > tallest {
                    continue;
                }
                let [e, n, u] = grid.centre(i, j, k);
                let mut s = step;
                while s <= 3.0 * tallest {
                    let (pe, pn) = (e + up[0] * s, n + up[1] * s);
                    if let Some(b) = world.building_at(pe, pn).filter(|b| b.roof_up_m() > u) {
                        if s <= 3.0 * b.height_m() {
                            out.push(c);
                        }
                        break;
                    }
                    s += step;
                }
            }
        }
    }
    out
}

/// OpenFOAM's inflow profile (atmBoundaryLayerInletVelocity) as a factor of the 10 m speed.
fn abl_factor(agl: f64, z0: f64) -> f64 {
    ((agl.max(0.0) + z0) / z0).ln() / ((REFERENCE_HEIGHT_M + z0) / z0).ln()
}

fn main() {
    let a = args();
    let started = Instant::now();
    let city = load_world(&a.scenario);
    let extent = city.extent_m();
    let centre = a.centre.unwrap_or_else(|| {
        // The block must lie inside the world square.
        let reach = extent - a.block_m / 2.0;
        let steps = (reach / 25.0).floor() as i64;
        let mut best = ([0.0, 0.0], f64::NEG_INFINITY);
        for j in -steps..=steps {
            for i in -steps..=steps {
                let c = [i as f64 * 25.0, j as f64 * 25.0];
                let w = weight(&block(&city, c, a.block_m));
                if w > best.1 {
                    best = (c, w);
                }
            }
        }
        best.0
    });
    let buildings = block(&city, centre, a.block_m);
    let tallest = buildings.iter().map(Building::height_m).fold(0.0, f64::max);
    let over_20 = buildings.iter().filter(|b| b.height_m() > 20.0).count();
    eprintln!(
        "block of {} m centred at ENU ({:.0}, {:.0}) m: {} buildings, {over_20} taller than 20 m, tallest {tallest:.1} m",
        a.block_m,
        centre[0],
        centre[1],
        buildings.len()
    );
    let world = World::of_buildings(a.block_m / 2.0, buildings);

    // The diagnostic sector (the direction must be one of the 8 sectors).
    let t = Instant::now();
    let mut field = UrbanWindField::new(&world, GridSpec { spacing_m: a.cell_m, top_factor: 2.0 }, 8);
    let sectors = field.sectors_for(a.direction_deg);
    assert_eq!(sectors.len(), 1, "--direction-deg must be a multiple of 45");
    field.ensure_sector(&world, sectors[0].0);
    let diagnostic_s = t.elapsed().as_secs_f64();
    let grid = field.grid.clone();
    let diag = &field.sectors[0].1;

    // OpenFOAM on the same grid.
    let mut spec = CaseSpec::for_grid(&grid, a.direction_deg);
    spec.refine_levels = a.refine;
    spec.max_iterations = a.max_iterations;
    let case = a
        .case
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join(format!("sadesim-crosscheck-{}", std::process::id())));
    let run = if a.reuse {
        None
    } else {
        Some(run_case(&world, &spec, &case, |line| eprintln!("{line}")).unwrap_or_else(|e| panic!("{e}")))
    };
    let foam = import_case_dir(
        &grid,
        &case,
        ImportSpec { direction_from_deg: a.direction_deg, reference_speed_ms: spec.reference_speed_ms },
    )
    .unwrap_or_else(|e| panic!("{e}"));

    // Correlation at 20-60 m AGL.
    let (mut fa, mut da) = (Vec::new(), Vec::new());
    // The same speeds over the undisturbed profile's at the cell's height (each method's
    // own): what the buildings do, without the profile's growth with height.
    let (mut fr, mut dr) = (Vec::new(), Vec::new());
    let mut fluid = 0usize;
    for k in 0..grid.dims[2] {
        for j in 0..grid.dims[1] {
            for i in 0..grid.dims[0] {
                let c = grid.index(i, j, k);
                if grid.solid[c] {
                    continue;
                }
                fluid += 1;
                let agl = grid.height_agl_m(i, j, k);
                if (20.0..=60.0).contains(&agl) {
                    fa.push(speed(&foam, c));
                    da.push(speed(diag, c));
                    fr.push(speed(&foam, c) / abl_factor(agl, spec.z0_m));
                    dr.push(speed(diag, c) / FIELD_PROFILE.factor(agl));
                }
            }
        }
    }
    let r = correlation(&fa, &da);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;

    // Wake reduction, each method against its own inflow profile.
    let wake = wake_cells(&world, &grid, a.direction_deg);
    let nx = grid.dims[0];
    let agl_of = |c: usize| {
        let (i, j, k) = (c % nx, (c / nx) % grid.dims[1], c / (nx * grid.dims[1]));
        grid.height_agl_m(i, j, k)
    };
    let reduction = |s: &SectorField, profile: &dyn Fn(f64) -> f64| {
        mean(&wake.iter().map(|&c| 1.0 - speed(s, c) / profile(agl_of(c))).collect::<Vec<_>>())
    };
    let wake_diag = reduction(diag, &|z| FIELD_PROFILE.factor(z));
    let wake_foam = reduction(&foam, &|z| abl_factor(z, spec.z0_m));
    let result = serde_json::json!({
        "block_centre_enu_m": centre,
        "block_m": a.block_m,
        "buildings": world.buildings().len(),
        "tallest_m": tallest,
        "direction_from_deg": a.direction_deg,
        "grid": { "dims": grid.dims, "cell_m": grid.spacing_m, "fluid_cells": fluid },
        "openfoam": run.map(|run| serde_json::json!({ "cells": run.cells, "iterations": run.iterations,
                      "converged": run.converged, "mesh_s": (run.mesh_s * 10.0).round() / 10.0,
                      "solve_s": (run.solve_s * 10.0).round() / 10.0, "refine_levels": spec.refine_levels })),
        "openfoam_grid_mass_residual": foam.residual,
        "diagnostic": { "seconds": (diagnostic_s * 10.0).round() / 10.0, "iterations": diag.iterations,
                        "mass_residual": diag.residual },
        "speed_20_60m": { "cells": fa.len(), "correlation": r, "mean_openfoam": mean(&fa), "mean_diagnostic": mean(&da),
                          "correlation_over_profile": correlation(&fr, &dr) },
        "wake": { "cells": wake.len(), "reduction_openfoam": wake_foam, "reduction_diagnostic": wake_diag },
        "wall_s": (started.elapsed().as_secs_f64() * 10.0).round() / 10.0,
        "case": case.display().to_string(),
    });
    println!("{result}");
}
