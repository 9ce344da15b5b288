//! The urban wind by OpenFOAM on a small world, run for real (issue 17): one 20 m cube in
//! a 200 m square, the case of `CaseSpec::for_grid` (about 23 000 cells, ten seconds on
//! one core) through `compute_sector`, compared with the built-in diagnostic field on the
//! same grid. Skipped, saying why, where OpenFOAM is not installed
//! (`bash tests/install-tools.sh` installs Debian's openfoam).

use sadesim_wind::compare::correlation;
use sadesim_wind::{GridSpec, UrbanWindField};
use sadesim_world::{Building, Footprint, World};
use sim_worker::wind_field::openfoam_run::{check_installed, compute_sector};

/// Cube edge and cell, metres.
const H: f64 = 20.0;
const CELL: f64 = 5.0;

#[test]
fn openfoam_wind_around_a_cube_has_a_wake_and_agrees_with_the_diagnostic_field() {
    if let Err(e) = check_installed() {
        eprintln!("skipped: {e}");
        return;
    }
    let half = H / 2.0;
    let footprint = Footprint::new(vec![[-half, -half], [half, -half], [half, half], [-half, half]], vec![]).unwrap();
    let world = World::of_buildings(100.0, vec![Building::new(footprint, 0.0, H).unwrap()]);
    // The diagnostic field of the wind from the west (sector 6 of 8) on the same grid.
    let mut diagnostic = UrbanWindField::new(&world, GridSpec { spacing_m: CELL, top_factor: 2.0 }, 8);
    diagnostic.ensure_sector(&world, 6);
    let grid = diagnostic.grid.clone();

    let case = std::env::temp_dir().join(format!("sadesim-openfoam-world-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&case);
    let started = std::time::Instant::now();
    let foam =
        compute_sector(&world, &grid, 270.0, &case, |line| eprintln!("{line}")).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("OpenFOAM sector in {:.0} s, {} iterations", started.elapsed().as_secs_f64(), foam.iterations);

    let speed = |s: &sadesim_wind::SectorField, c: usize| {
        (f64::from(s.east[c]).powi(2) + f64::from(s.north[c]).powi(2) + f64::from(s.up[c]).powi(2)).sqrt()
    };
    let cell_at = |e: f64, n: f64, agl: f64| {
        let f = |v: f64, c: f64| ((v - c) / CELL).floor() as usize;
        grid.index(f(e, grid.corner_m[0]), f(n, grid.corner_m[1]), f(agl, grid.corner_m[2]))
    };
    // At half the cube's height on its centreline: 3 H upstream of the windward face, the
    // open flow; half a cube behind the leeward face, the recirculation.
    let upstream = speed(&foam, cell_at(-half - 3.0 * H, 1.0, 11.0));
    let lee = speed(&foam, cell_at(half + 0.5 * H, 1.0, 11.0));
    eprintln!("speed factor at 11 m AGL: upstream {upstream:.2}, lee {lee:.2}");
    assert!(upstream > 0.8, "upstream speed factor {upstream}");
    assert!(lee < 0.5 * upstream, "lee {lee} vs upstream {upstream}");

    // Speeds of the two methods over the fluid cells 5-40 m above the ground.
    let diag = &diagnostic.sectors[0].1;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for k in 0..grid.dims[2] {
        for j in 0..grid.dims[1] {
            for i in 0..grid.dims[0] {
                let c = grid.index(i, j, k);
                let agl = grid.height_agl_m(i, j, k);
                if !grid.solid[c] && (5.0..=40.0).contains(&agl) {
                    a.push(speed(&foam, c));
                    b.push(speed(diag, c));
                }
            }
        }
    }
    let r = correlation(&a, &b);
    eprintln!("correlation of speed, OpenFOAM vs diagnostic, {} cells 5-40 m AGL: {r:.3}", a.len());
    assert!(r > 0.5, "correlation {r}");
    let _ = std::fs::remove_dir_all(&case);
}
