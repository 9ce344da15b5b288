//! An OpenFOAM case's wind mapped onto the wind grid: the cell centres `C` and velocity `U`
//! of a case (run by `sim_worker::wind_field::openfoam_run`, or computed elsewhere by a user)
//! become a [`SectorField`] of factors of the reference wind.
//!
//! # What a case must be
//! - Frame: the case's coordinates are the run's ENU metres (x = east, y = north, z = up,
//!   from the run's origin), as [`crate::foam_case`] writes them. A case in another frame
//!   must be moved first (OpenFOAM's `transformPoints`).
//! - Reference speed: the factors are `U / reference_speed_ms`, the speed of the case's
//!   undisturbed inflow 10 m above open ground (the field's reference,
//!   [`crate::profile::FIELD_PROFILE`]). A case file does not say it: it is the caller's,
//!   the value the case's inlet was set up with (`Uref` with `Zref 10` of
//!   `atmBoundaryLayerInletVelocity`; for a case of this crate, [`crate::foam_case::CaseSpec`]'s
//!   `reference_speed_ms`).
//! - Coverage: every fluid cell of the grid must have a case cell centre inside it or
//!   within one grid spacing of its centre; the case's cells may reach beyond the grid.
//!   Exception: fluid grid cells inside the case's extent and within two cells of a
//!   building or the ground that the case's mesh does not reach (an enclosed courtyard,
//!   a gap between buildings snappyHexMesh closed: it keeps only the region connected to
//!   the inflow) are still air.
//!
//! # Mapping
//! A fluid grid cell gets the mean of the case's cells whose centres fall inside it (an
//! unweighted mean: `C` carries no volumes; snappyHexMesh's cells inside one grid cell are
//! of similar size); with none, the nearest case cell centre within one spacing of its
//! centre (a cell at a wall whose case cells were cut away, or a case coarser than the
//! grid). Solid cells get 0, as the diagnostic field's. Case cells are put in buckets of
//! the grid's cells, so mapping is linear in the cells of both.

use crate::field::SectorField;
use crate::grid::WindGrid;
use crate::openfoam::{CaseFields, FoamError, parse_case_fields};

/// How to read a case's velocities as a sector of the field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImportSpec {
    /// The case's wind blows from this direction, degrees clockwise from north (the
    /// sector's label; the velocities are taken as they are).
    pub direction_from_deg: f64,
    /// The case's undisturbed inflow speed 10 m above open ground, m/s.
    pub reference_speed_ms: f64,
}

/// Why a case cannot become a sector field. `file` is the name the caller gave.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ImportError {
    /// `C` or `U` cannot be read (the file, line and problem are in the message).
    #[error(transparent)]
    Foam(#[from] FoamError),
    /// The reference speed is not a positive number.
    #[error(
        "{file}: the reference speed {speed_ms} m/s is not a positive number: expected the case's inflow speed 10 m above open ground"
    )]
    ReferenceSpeed { file: String, speed_ms: f64 },
    /// The case has no cell.
    #[error("{file}: the case has no cell")]
    NoCells { file: String },
    /// Fluid cells of the grid have no case cell near them.
    #[error("{0}")]
    NotCovered(Box<Uncovered>),
}

/// The fluid grid cells a case does not cover ([`ImportError::NotCovered`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "{file}: the case does not cover the world's wind grid: {cells} fluid grid cells have no case cell centre inside them or within {tolerance_m} m of their centre, the first at ENU ({:.1}, {:.1}, {:.1}) m; the case's cell centres span ENU {} m, the grid {} m (the case's coordinates must be the run's ENU metres)",
    first_enu_m[0], first_enu_m[1], first_enu_m[2], show_box(case_box_m), show_box(grid_box_m)
)]
pub struct Uncovered {
    /// The cell centres' file.
    pub file: String,
    /// How many fluid grid cells, and the first's centre (in index order), ENU metres.
    pub cells: usize,
    pub first_enu_m: [f64; 3],
    /// The largest distance from a grid cell's centre to a case cell's centre, metres.
    pub tolerance_m: f64,
    /// Smallest and largest corner of the case's cell centres and of the grid, ENU metres.
    pub case_box_m: [[f64; 3]; 2],
    pub grid_box_m: [[f64; 3]; 2],
}

fn show_box(b: &[[f64; 3]; 2]) -> String {
    format!("({:.1}, {:.1}, {:.1})..({:.1}, {:.1}, {:.1})", b[0][0], b[0][1], b[0][2], b[1][0], b[1][1], b[1][2])
}

/// Reads `C` and `U` from their texts (file names for errors, e.g. `CASE/500/C`) and maps
/// them onto `grid`.
///
/// # Errors
/// [`ImportError`]: either file unreadable ([`FoamError`]: binary, NaN, counts, ...), a bad
/// reference speed, or a case that does not cover the grid.
pub fn import_case(
    grid: &WindGrid,
    c_file: &str,
    c_text: &str,
    u_file: &str,
    u_text: &str,
    spec: ImportSpec,
) -> Result<SectorField, ImportError> {
    let fields = parse_case_fields(c_file, c_text, u_file, u_text)?;
    map_onto_grid(grid, &fields, c_file, spec)
}

/// Maps a case's cells onto `grid` (see the module's documentation); `c_file` names the
/// cell centres in errors. The sector's `residual` (and `first_guess_residual`, the same:
/// there is no first guess) is [`mass_residual`] of the mapped field; `iterations` is 0
/// (the solver's are the caller's to set).
///
/// # Errors
/// [`ImportError::ReferenceSpeed`], [`ImportError::NoCells`], [`ImportError::NotCovered`].
pub fn map_onto_grid(
    grid: &WindGrid,
    case: &CaseFields,
    c_file: &str,
    spec: ImportSpec,
) -> Result<SectorField, ImportError> {
    let file = c_file.to_string();
    if !(spec.reference_speed_ms.is_finite() && spec.reference_speed_ms > 0.0) {
        return Err(ImportError::ReferenceSpeed { file, speed_ms: spec.reference_speed_ms });
    }
    if case.centres_m.is_empty() {
        return Err(ImportError::NoCells { file });
    }
    let [nx, ny, nz] = grid.dims;
    let h = grid.spacing_m;
    // Buckets: the grid's cells and one more layer around them (a case cell just outside
    // the grid can be the nearest to a boundary cell), in compressed rows: `start[b]..start[b + 1]`
    // of `members` are the case cells in bucket `b`.
    let (bx, by, bz) = (nx + 2, ny + 2, nz + 2);
    let bucket_of = |p: &[f64; 3]| -> Option<usize> {
        let f = |v: f64, corner: f64, n: usize| {
            let i = ((v - corner) / h).floor() + 1.0;
            (i >= 0.0 && i < (n + 2) as f64).then_some(i as usize)
        };
        let (i, j, k) =
            (f(p[0], grid.corner_m[0], nx)?, f(p[1], grid.corner_m[1], ny)?, f(p[2], grid.corner_m[2], nz)?);
        Some((k * by + j) * bx + i)
    };
    let buckets: Vec<Option<usize>> = case.centres_m.iter().map(bucket_of).collect();
    let mut start = vec![0usize; bx * by * bz + 1];
    for b in buckets.iter().flatten() {
        start[b + 1] += 1;
    }
    for b in 0..bx * by * bz {
        start[b + 1] += start[b];
    }
    let mut fill = start.clone();
    let mut members = vec![0usize; start[bx * by * bz]];
    for (cell, b) in buckets.iter().enumerate() {
        if let Some(b) = b {
            members[fill[*b]] = cell;
            fill[*b] += 1;
        }
    }

    // The case's bounding box, and whether a grid cell is within two cells of a solid one
    // (a wall or the ground).
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &case.centres_m {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let in_case_box = |p: [f64; 3]| (0..3).all(|a| p[a] >= lo[a] - h && p[a] <= hi[a] + h);
    let near_wall = |i: usize, j: usize, k: usize| {
        let span = |v: usize, n: usize| v.saturating_sub(2)..=(v + 2).min(n - 1);
        span(k, nz).any(|kk| span(j, ny).any(|jj| span(i, nx).any(|ii| grid.solid[grid.index(ii, jj, kk)])))
    };
    let scale = 1.0 / spec.reference_speed_ms;
    let n = grid.cells();
    let (mut east, mut north, mut up) = (vec![0.0f64; n], vec![0.0f64; n], vec![0.0f64; n]);
    let mut uncovered = 0usize;
    let mut first_uncovered = None;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = grid.index(i, j, k);
                if grid.solid[c] {
                    continue;
                }
                let own = (((k + 1) * by + j + 1) * bx) + i + 1;
                let inside = &members[start[own]..start[own + 1]];
                let value = if inside.is_empty() {
                    nearest(
                        grid.centre(i, j, k),
                        h,
                        &case.centres_m,
                        |bi, bj, bk| {
                            let b = (bk * by + bj) * bx + bi;
                            &members[start[b]..start[b + 1]]
                        },
                        [i + 1, j + 1, k + 1],
                    )
                    .map(|m| case.velocity_mps[m])
                } else {
                    let mut sum = [0.0; 3];
                    for &m in inside {
                        for (s, v) in sum.iter_mut().zip(case.velocity_mps[m]) {
                            *s += v;
                        }
                    }
                    Some(sum.map(|s| s / inside.len() as f64))
                };
                match value {
                    Some(v) => {
                        east[c] = v[0] * scale;
                        north[c] = v[1] * scale;
                        up[c] = v[2] * scale;
                    }
                    // Inside the case's extent next to buildings: air the case's mesh does
                    // not reach, an enclosed courtyard or a gap snappyHexMesh closed, whose
                    // cells it removes (only the region connected to the inflow is
                    // meshed). Still air, as in a cavity; elsewhere a hole is an error.
                    None if in_case_box(grid.centre(i, j, k)) && near_wall(i, j, k) => {}
                    None => {
                        uncovered += 1;
                        first_uncovered.get_or_insert(grid.centre(i, j, k));
                    }
                }
            }
        }
    }
    if let Some(first_enu_m) = first_uncovered {
        let grid_hi = [0, 1, 2].map(|a| grid.corner_m[a] + grid.dims[a] as f64 * h);
        return Err(ImportError::NotCovered(Box::new(Uncovered {
            file,
            cells: uncovered,
            first_enu_m,
            tolerance_m: h,
            case_box_m: [lo, hi],
            grid_box_m: [grid.corner_m, grid_hi],
        })));
    }
    let residual = mass_residual(grid, &east, &north, &up);
    let narrow = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
    Ok(SectorField {
        direction_from_deg: spec.direction_from_deg,
        east: narrow(east),
        north: narrow(north),
        up: narrow(up),
        residual,
        first_guess_residual: residual,
        iterations: 0,
    })
}

/// The case cell whose centre is nearest `p` and at most `h` from it, among the buckets
/// around bucket `b` (`p` is the centre of the grid cell of bucket `b`, buckets are `h`
/// wide: every point within `h` of `p` is in one of the 27).
fn nearest<'a>(
    p: [f64; 3],
    h: f64,
    centres: &[[f64; 3]],
    bucket: impl Fn(usize, usize, usize) -> &'a [usize],
    b: [usize; 3],
) -> Option<usize> {
    let mut best: Option<(f64, usize)> = None;
    for bk in b[2] - 1..=b[2] + 1 {
        for bj in b[1] - 1..=b[1] + 1 {
            for bi in b[0] - 1..=b[0] + 1 {
                for &m in bucket(bi, bj, bk) {
                    let q = centres[m];
                    let d2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2);
                    // Ties go to the lower cell index: the same case gives the same field.
                    if d2 <= h * h && best.is_none_or(|(bd, bm)| d2 < bd || (d2 == bd && m < bm)) {
                        best = Some((d2, m));
                    }
                }
            }
        }
    }
    best.map(|(_, m)| m)
}

/// The mass-conservation residual of a cell-centred field on `grid`, as
/// [`crate::solver::Adjusted::residual`] measures it: the largest net outflow of a fluid
/// cell over its faces per face area, in the field's units (factors: fractions of the
/// reference wind), with face values as the solver's first guess takes them (the mean of
/// the two cells; the inner cell's on the domain's sides and top; 0 at walls, the ground
/// included). A field interpolated from another mesh is not divergence-free on this one:
/// this says by how much.
pub fn mass_residual(grid: &WindGrid, east: &[f64], north: &[f64], up: &[f64]) -> f64 {
    let [nx, ny, nz] = grid.dims;
    // Normal velocity through the face between `a` (lower side) and `b` (upper side) of
    // component `v`; `None` is outside the grid.
    let face = |v: &[f64], a: Option<usize>, b: Option<usize>| -> f64 {
        match (a.map(|c| (grid.solid[c], v[c])), b.map(|c| (grid.solid[c], v[c]))) {
            (Some((false, x)), Some((false, y))) => 0.5 * (x + y),
            (Some((false, x)), None) | (None, Some((false, x))) => x,
            _ => 0.0,
        }
    };
    let mut worst = 0.0f64;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = grid.index(i, j, k);
                if grid.solid[c] {
                    continue;
                }
                let west = face(east, (i > 0).then(|| c - 1), Some(c));
                let east_f = face(east, Some(c), (i + 1 < nx).then(|| c + 1));
                let south = face(north, (j > 0).then(|| c - nx), Some(c));
                let north_f = face(north, Some(c), (j + 1 < ny).then(|| c + nx));
                // The grid's bottom is the ground: a wall.
                let below = if k == 0 { 0.0 } else { face(up, Some(c - nx * ny), Some(c)) };
                let above = face(up, Some(c), (k + 1 < nz).then(|| c + nx * ny));
                worst = worst.max((east_f - west + north_f - south + above - below).abs());
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use sadesim_world::{Building, Footprint, World};

    use super::*;
    use crate::grid::GridSpec;

    const H: f64 = 4.0;
    const U_REF: f64 = 8.0;

    /// A 10 m box on a 40 m square, cells of 4 m: 10 x 10 x 10 cells.
    fn grid() -> WindGrid {
        let fp = Footprint::new(vec![[-6.0, -6.0], [2.0, -6.0], [2.0, 2.0], [-6.0, 2.0]], vec![]).unwrap();
        let world = World::of_buildings(20.0, vec![Building::new(fp, 0.0, 10.0).unwrap()]);
        WindGrid::over(&world, GridSpec { spacing_m: H, top_factor: 2.0 })
    }

    /// The known wind, m/s: linear in position, so a symmetric mean over a cell is the value
    /// at its centre.
    fn wind(p: [f64; 3]) -> [f64; 3] {
        [U_REF * (1.0 + 0.01 * p[0] + 0.02 * p[2]), U_REF * 0.005 * p[1], -0.1 * p[2]]
    }

    /// A case on a lattice of `H / 2` (8 cells per grid cell) over the grid's box, its cells
    /// inside the building left out (as snappyHexMesh would), and `keep` deciding the rest.
    fn case(g: &WindGrid, keep: impl Fn([f64; 3]) -> bool) -> CaseFields {
        let d = H / 2.0;
        let mut centres = Vec::new();
        for k in 0..2 * g.dims[2] {
            for j in 0..2 * g.dims[1] {
                for i in 0..2 * g.dims[0] {
                    let p = [0, 1, 2].map(|a| g.corner_m[a] + ([i, j, k][a] as f64 + 0.5) * d);
                    let in_building = p[0] > -6.0 && p[0] < 2.0 && p[1] > -6.0 && p[1] < 2.0 && p[2] < 10.0;
                    if !in_building && keep(p) {
                        centres.push(p);
                    }
                }
            }
        }
        let velocity_mps = centres.iter().map(|p| wind(*p)).collect();
        CaseFields { centres_m: centres, velocity_mps }
    }

    const SPEC: ImportSpec = ImportSpec { direction_from_deg: 270.0, reference_speed_ms: U_REF };

    /// An ASCII volVectorField of `values`, one per line after 20 header lines.
    fn field_text(object: &str, dims: &str, values: &[[f64; 3]]) -> String {
        let mut s = format!(
            "FoamFile\n{{\n    version 2.0;\n    format ascii;\n    class volVectorField;\n    object {object};\n}}\n\ndimensions {dims};\n\ninternalField nonuniform List<vector>\n{}\n(\n",
            values.len()
        );
        for v in values {
            s.push_str(&format!("({} {} {})\n", v[0], v[1], v[2]));
        }
        s.push_str(")\n;\n\nboundaryField\n{\n}\n");
        s
    }

    #[test]
    fn a_finer_case_gives_each_fluid_cell_the_mean_of_its_case_cells() {
        let g = grid();
        let f = map_onto_grid(&g, &case(&g, |_| true), "CASE/100/C", SPEC).unwrap();
        let mut fluid = 0;
        for k in 0..g.dims[2] {
            for j in 0..g.dims[1] {
                for i in 0..g.dims[0] {
                    let c = g.index(i, j, k);
                    let got = [f.east[c], f.north[c], f.up[c]].map(f64::from);
                    if g.solid[c] {
                        assert_eq!(got, [0.0; 3], "solid cell {i} {j} {k}");
                        continue;
                    }
                    fluid += 1;
                    // Cells at the building's walls: the mean of the case cells outside it,
                    // not the centre's value; the rest exactly the centre's.
                    let p = g.centre(i, j, k);
                    let near_wall = p[0] > -10.0 && p[0] < 6.0 && p[1] > -10.0 && p[1] < 6.0 && p[2] < 14.0;
                    if near_wall {
                        continue;
                    }
                    let want = wind(p).map(|v| v / U_REF);
                    for a in 0..3 {
                        assert!((got[a] - want[a]).abs() < 1e-5, "cell {i} {j} {k}: {got:?} vs {want:?}");
                    }
                }
            }
        }
        assert!(fluid > 900, "{fluid}");
        assert_eq!(f.direction_from_deg, 270.0);
        assert!(f.residual.is_finite() && f.residual == f.first_guess_residual);
    }

    #[test]
    fn a_grid_cell_without_case_cells_takes_the_nearest_within_one_spacing() {
        let g = grid();
        // No case cell in grid cell (7, 7, 3): its neighbours' nearest centres are 0.83 H away.
        let hole = g.centre(7, 7, 3);
        let inside = |p: [f64; 3]| (0..3).all(|a| (p[a] - hole[a]).abs() < H / 2.0);
        let f = map_onto_grid(&g, &case(&g, |p| !inside(p)), "C", SPEC).unwrap();
        let c = g.index(7, 7, 3);
        // The nearest: the lowest-index of the equally near centres, (-H/4, ...) from the
        // cell's, at (hole - 3H/4, hole - H/4, hole - H/4).
        let want = wind([hole[0] - 0.25 * H, hole[1] - 0.25 * H, hole[2] - 0.75 * H]).map(|v| v / U_REF);
        let got = [f.east[c], f.north[c], f.up[c]].map(f64::from);
        for a in 0..3 {
            assert!((got[a] - want[a]).abs() < 1e-5, "{got:?} vs {want:?}");
        }
    }

    #[test]
    fn a_case_covering_half_the_grid_is_refused_naming_the_cells_and_boxes() {
        let g = grid();
        let err = map_onto_grid(&g, &case(&g, |p| p[0] < 8.0), "CASE/100/C", SPEC).unwrap_err();
        let ImportError::NotCovered(u) = &err else { panic!("{err:?}") };
        // The case's last centres are at x = 7 m: the grid's columns centred at x = 14 and
        // 18 m are more than one spacing away, 2 x 10 x 10 cells.
        assert_eq!(u.cells, 200, "{err}");
        assert_eq!(u.first_enu_m, [14.0, -18.0, 2.0]);
        let msg = err.to_string();
        assert!(
            msg.starts_with("CASE/100/C: the case does not cover the world's wind grid: 200 fluid grid cells"),
            "{msg}"
        );
        assert!(
            msg.contains(
                "span ENU (-19.0, -19.0, 1.0)..(7.0, 19.0, 39.0) m, the grid (-20.0, -20.0, 0.0)..(20.0, 20.0, 40.0) m"
            ),
            "{msg}"
        );
    }

    #[test]
    fn texts_are_read_and_mapped_and_their_errors_name_file_and_line() {
        let g = grid();
        let cf = case(&g, |_| true);
        let c = field_text("C", "[0 1 0 0 0 0 0]", &cf.centres_m);
        let u = field_text("U", "[0 1 -1 0 0 0 0]", &cf.velocity_mps);
        let f = import_case(&g, "CASE/100/C", &c, "CASE/100/U", &u, SPEC).unwrap();
        assert_eq!(f, map_onto_grid(&g, &cf, "CASE/100/C", SPEC).unwrap());

        // NaN in U, entry 5: line 14 + 5.
        let bad = u.replacen(
            &format!("({} {} {})", cf.velocity_mps[5][0], cf.velocity_mps[5][1], cf.velocity_mps[5][2]),
            "(nan 0 0)",
            1,
        );
        let err = import_case(&g, "CASE/100/C", &c, "CASE/100/U", &bad, SPEC).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("CASE/100/U:19: entry 5 (0-based) of the internal field has a non-finite component (nan)"),
            "{err}"
        );

        // U of another mesh.
        let short = field_text("U", "[0 1 -1 0 0 0 0]", &cf.velocity_mps[1..]);
        let err = import_case(&g, "CASE/100/C", &c, "CASE/100/U", &short, SPEC).unwrap_err();
        assert_eq!(
            err,
            ImportError::Foam(FoamError::DifferentCells {
                file: "CASE/100/C".into(),
                len: cf.centres_m.len(),
                other_file: "CASE/100/U".into(),
                other_len: cf.centres_m.len() - 1,
            })
        );

        let err = import_case(&g, "C", &c, "U", &u, ImportSpec { reference_speed_ms: 0.0, ..SPEC }).unwrap_err();
        assert!(matches!(err, ImportError::ReferenceSpeed { .. }), "{err:?}");
    }

    #[test]
    fn a_uniform_wind_over_open_ground_conserves_mass() {
        let world = World::of_buildings(20.0, vec![]);
        let g = WindGrid::over(&world, GridSpec { spacing_m: H, top_factor: 2.0 });
        let n = g.cells();
        assert_eq!(mass_residual(&g, &vec![1.0; n], &vec![0.5; n], &vec![0.0; n]), 0.0);
        // A vertical wind leaves the lowest cells through the top only: outflow 1 per face area.
        assert!((mass_residual(&g, &vec![0.0; n], &vec![0.0; n], &vec![1.0; n]) - 1.0).abs() < 1e-12);
    }
}
