//! An OpenFOAM case of the wind over a rectangle of the world: the files of a steady RANS
//! run (blockMesh background mesh, snappyHexMesh around the buildings as an STL surface,
//! simpleFoam with standard k-epsilon and an atmospheric boundary-layer inflow), written as
//! bytes; running them is the caller's (`sim_worker::wind_field::openfoam_run`).
//!
//! Frame: the case's axes are the run's ENU axes, in metres from the run's origin, with no
//! rotation or offset (x = east, y = north, z = up), so the cell centres the case writes are
//! ENU positions the wind grid can be sampled at directly.
//!
//! # The case
//! - Domain: the rectangle `rect_m` from the ground (flat, at `ground_up_m`) to `top_up_m`.
//!   Buildings that overlap the rectangle are in the STL whole; snappyHexMesh cuts the ones
//!   that cross the domain's sides at the side (their walls there are simply not in the
//!   mesh).
//! - Mesh: blockMesh cubes of `background_cell_m` from the ground up to `uniform_up_to_m`,
//!   then growing by at most [`VERTICAL_GROWTH`] a cell up to the top (the flow above the
//!   wind grid matters only as the upper boundary's distance); snappyHexMesh refines
//!   `refine_levels` times at the building surfaces (each level halves the cell) and snaps
//!   to them (implicit feature snapping: no surfaceFeatureExtract needed).
//! - Inflow: OpenFOAM's `atmBoundaryLayerInletVelocity`/`K`/`Epsilon` (Richards & Hoxey
//!   1993, library libatmosphericModels): `U(z) = u*/κ ln((z - z_ground + z0)/z0)` with
//!   `u* = κ U_ref / ln((10 + z0)/z0)`, so the inflow is `reference_speed_ms` 10 m above
//!   the ground; `k = u*²/√Cμ`, `ε = u*³/(κ (z - z_ground + z0))`. The sides the wind blows
//!   into the domain through (outward normal against the wind, more than [`PARALLEL_COS`])
//!   get it, the sides it leaves through are outlets (p = 0, zero gradient), and a side the
//!   wind is parallel to is a slip wall. In v1912 the ABL velocity condition is itself an
//!   inletOutlet, so air leaving through an inlet side near a building is not forced in.
//! - Walls: the ground is a rough wall (`nutkAtmRoughWallFunction` with `z0_m`, the same
//!   roughness as the inflow, so the profile is in equilibrium with the ground), the
//!   buildings smooth walls with the standard wall functions. The top is slip.
//! - Solver: simpleFoam, SIMPLEC, linearUpwind for U, k and ε, as the cube case
//!   (`tests/cfd/openfoam_cube.py`); it stops when every initial residual is below
//!   [`RESIDUAL_TARGETS`] or after `max_iterations`.
//!
//! The profile differs from the field's [`crate::profile::FIELD_PROFILE`] by the `+ z0`
//! inside the logarithm (OpenFOAM's form, finite at the ground): 3 % at 30 m with z0 = 1 m.

use std::fmt::Write as _;

use sadesim_world::mesh::buildings_mesh;
use sadesim_world::{Building, World};

use crate::grid::WindGrid;
use crate::profile::FIELD_PROFILE;
use crate::rockle::WindAxes;

/// Height of the reference speed above the ground, metres (the field's reference height).
pub const REFERENCE_HEIGHT_M: f64 = 10.0;
/// Largest ratio of neighbouring cell heights above the uniform layers.
pub const VERTICAL_GROWTH: f64 = 1.2;
/// A side is parallel to the wind (slip) when the cosine between its outward normal and
/// the wind's direction is below this in magnitude (3°).
pub const PARALLEL_COS: f64 = 0.05;
/// simpleFoam stops when every initial residual is below these (SIMPLE residualControl):
/// a coarser target than the cube's, the city case is for a grid of metre-sized cells.
pub const RESIDUAL_TARGETS: [(&str, f64); 4] = [("p", 1e-3), ("U", 1e-4), ("k", 1e-4), ("epsilon", 1e-4)];
/// Kinematic viscosity of air, m²/s.
const NU_AIR: f64 = 1.5e-5;
const KAPPA: f64 = 0.41;
const C_MU: f64 = 0.09;

/// What a case computes and how finely.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseSpec {
    /// The domain's horizontal extent: ENU `[east0, north0, east1, north1]`, metres.
    pub rect_m: [f64; 4],
    /// ENU up of the domain's bottom, the ground (taken flat), metres.
    pub ground_up_m: f64,
    /// ENU up of the domain's top, metres.
    pub top_up_m: f64,
    /// Background cells are cubes of this edge up to `uniform_up_to_m`, metres.
    pub background_cell_m: f64,
    /// ENU up to which the background cells are cubes; above, they grow, metres.
    pub uniform_up_to_m: f64,
    /// snappyHexMesh refinement levels at the building surfaces (each halves the cell).
    pub refine_levels: u32,
    /// The wind blows from this direction, degrees clockwise from north.
    pub direction_from_deg: f64,
    /// Undisturbed wind speed 10 m above the ground at the inflow, m/s.
    pub reference_speed_ms: f64,
    /// Roughness length of the ground and the inflow profile, metres.
    pub z0_m: f64,
    /// simpleFoam stops after this many iterations if not converged before.
    pub max_iterations: u32,
}

impl CaseSpec {
    /// A case over `grid`'s square: the same horizontal extent (so the case covers every
    /// grid cell), background cells of the grid's spacing up to the grid's top and one
    /// refinement level at the buildings; the domain's top twice as high above the ground
    /// as the grid's (the upper boundary away from the roofs); the inflow at 10 m/s over
    /// the field's roughness (z0 = 1 m); at most 1000 iterations.
    pub fn for_grid(grid: &WindGrid, direction_from_deg: f64) -> Self {
        let h = grid.spacing_m;
        let [nx, ny, _] = grid.dims;
        let [e0, n0, _] = grid.corner_m;
        // The grid's lowest cells may be below the ground (solid); the case starts at it.
        let ground = grid.ground_up_m.iter().copied().fold(f64::INFINITY, f64::min);
        let ground = if ground.is_finite() { ground } else { grid.corner_m[2] };
        let grid_top = grid.top_up_m();
        Self {
            rect_m: [e0, n0, e0 + nx as f64 * h, n0 + ny as f64 * h],
            ground_up_m: ground,
            top_up_m: ground + 2.0 * (grid_top - ground),
            background_cell_m: h,
            uniform_up_to_m: grid_top,
            refine_levels: 1,
            direction_from_deg,
            reference_speed_ms: 10.0,
            z0_m: FIELD_PROFILE.roughness_length_m,
            max_iterations: 1000,
        }
    }

    /// Background cells along east, north and up (the last: uniform layers, graded layers).
    pub fn background_cells(&self) -> ([usize; 2], usize, usize) {
        let [e0, n0, e1, n1] = self.rect_m;
        let h = self.background_cell_m;
        let across = |len: f64| ((len / h).round() as usize).max(1);
        let uniform_top = self.uniform_up_to_m.clamp(self.ground_up_m + h, self.top_up_m);
        let n_uniform = across(uniform_top - self.ground_up_m);
        let rest = self.top_up_m - (self.ground_up_m + n_uniform as f64 * h);
        let (n_graded, _) = graded(rest, h, VERTICAL_GROWTH);
        ([across(e1 - e0), across(n1 - n0)], n_uniform, n_graded)
    }
}

/// `(cells, ratio last/first)` of a segment of `length` m starting with cells of about
/// `first` m that grow geometrically by at most `max_growth` a cell (0 cells for nothing).
fn graded(length: f64, first: f64, max_growth: f64) -> (usize, f64) {
    if length <= 0.5 * first {
        return (0, 1.0);
    }
    let mut n = 1usize;
    loop {
        if (n as f64) * first >= length {
            return (n, 1.0);
        }
        // Sum of n cells growing by q: first (q^n - 1) / (q - 1); the growth that fills
        // `length`, by bisection.
        let (mut lo, mut hi) = (1.0f64, 10.0f64);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if first * (mid.powi(n as i32) - 1.0) / (mid - 1.0) < length {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let q = 0.5 * (lo + hi);
        if q <= max_growth {
            return (n, q.powi(n as i32 - 1));
        }
        n += 1;
    }
}

/// The buildings of `world` the case meshes: every one whose footprint's bounding box
/// overlaps the domain's rectangle, by index.
pub fn case_buildings(world: &World, spec: &CaseSpec) -> Vec<usize> {
    let [e0, n0, e1, n1] = spec.rect_m;
    world
        .buildings_in_rect(&spec.rect_m)
        .into_iter()
        .filter(|&b| {
            let r = world.buildings()[b].footprint().bounds();
            r[0] < e1 && r[2] > e0 && r[1] < n1 && r[3] > n0
        })
        .collect()
}

/// The case's files: `(path relative to the case directory, contents)`. Every file is
/// ASCII; `constant/triSurface/buildings.stl` has the buildings the case meshes
/// ([`case_buildings`]) as closed solids reaching 1 m below the ground (so snappyHexMesh
/// cuts them cleanly at the ground). With no building in the rectangle the STL has no
/// facet and snappyHexMesh must not be run (the background mesh is the case's mesh).
pub fn case_files(world: &World, spec: &CaseSpec) -> Vec<(String, Vec<u8>)> {
    let files = [
        ("constant/triSurface/buildings.stl", buildings_stl(world, spec)),
        ("system/controlDict", control_dict(spec)),
        ("system/blockMeshDict", block_mesh_dict(spec)),
        ("system/snappyHexMeshDict", snappy_dict(spec)),
        ("system/fvSchemes", foam_file("dictionary", "fvSchemes", FV_SCHEMES)),
        ("system/fvSolution", fv_solution()),
        (
            "constant/transportProperties",
            foam_file("dictionary", "transportProperties", &format!("transportModel Newtonian;\nnu {NU_AIR:e};\n")),
        ),
        (
            "constant/turbulenceProperties",
            foam_file(
                "dictionary",
                "turbulenceProperties",
                "simulationType RAS;\nRAS\n{\n    RASModel kEpsilon;\n    turbulence on;\n    printCoeffs on;\n}\n",
            ),
        ),
    ];
    let mut out: Vec<(String, Vec<u8>)> = files.into_iter().map(|(p, t)| (p.to_string(), t.into_bytes())).collect();
    out.extend(initial_fields(spec).into_iter().map(|(p, t)| (p, t.into_bytes())));
    out
}

/// The number of triangles in [`case_files`]' STL.
pub fn stl_facets(stl: &[u8]) -> usize {
    String::from_utf8_lossy(stl).lines().filter(|l| l.trim_start().starts_with("facet normal")).count()
}

fn foam_file(class: &str, object: &str, body: &str) -> String {
    format!(
        "FoamFile\n{{\n    version     2.0;\n    format      ascii;\n    class       {class};\n    object      {object};\n}}\n// Written by sadesim-wind (foam_case.rs).\n\n{body}"
    )
}

/// ASCII STL of the case's buildings, ENU metres, normals outwards.
fn buildings_stl(world: &World, spec: &CaseSpec) -> String {
    let below = spec.ground_up_m - 1.0;
    let solids: Vec<Building> = case_buildings(world, spec)
        .into_iter()
        .filter_map(|b| {
            let b = &world.buildings()[b];
            Building::new(b.footprint().clone(), below, b.roof_up_m() - below).ok()
        })
        .collect();
    let mesh = buildings_mesh(&World::of_buildings(world.extent_m(), solids));
    let mut s = String::from("solid buildings\n");
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions_enu_m[i as usize]);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        // Degenerate triangles (slivers of the footprint's triangulation) carry no surface.
        if len < 1e-9 {
            continue;
        }
        let _ = writeln!(s, "  facet normal {:e} {:e} {:e}\n    outer loop", n[0] / len, n[1] / len, n[2] / len);
        for p in [a, b, c] {
            let _ = writeln!(s, "      vertex {:.4} {:.4} {:.4}", p[0], p[1], p[2]);
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid buildings\n");
    s
}

fn control_dict(spec: &CaseSpec) -> String {
    let n = spec.max_iterations.max(1);
    foam_file(
        "dictionary",
        "controlDict",
        &format!(
            "application simpleFoam;\n\
             // The atmospheric boundary-layer conditions.\n\
             libs (\"libatmosphericModels.so\");\n\
             startFrom startTime;\nstartTime 0;\nstopAt endTime;\nendTime {n};\ndeltaT 1;\n\
             writeControl timeStep;\nwriteInterval {n};\npurgeWrite 0;\n\
             // ASCII: sadesim_wind::openfoam reads no binary field.\n\
             writeFormat ascii;\nwritePrecision 8;\nwriteCompression off;\n\
             timeFormat general;\ntimePrecision 6;\nrunTimeModifiable false;\n"
        ),
    )
}

/// One block over the domain; vertices in ENU metres. The vertical grading is a
/// multi-grading: `n_uniform` cubes, then `n_graded` growing cells.
fn block_mesh_dict(spec: &CaseSpec) -> String {
    let [e0, n0, e1, n1] = spec.rect_m;
    let (z0, z1) = (spec.ground_up_m, spec.top_up_m);
    let ([nx, ny], n_uniform, n_graded) = spec.background_cells();
    let h = spec.background_cell_m;
    let uniform_len = n_uniform as f64 * h;
    let z_grading = if n_graded == 0 {
        "1".to_string()
    } else {
        let (_, ratio) = graded(z1 - z0 - uniform_len, h, VERTICAL_GROWTH);
        let total = z1 - z0;
        let cells = (n_uniform + n_graded) as f64;
        format!(
            "(({:.6} {:.6} 1) ({:.6} {:.6} {:.6}))",
            uniform_len / total,
            n_uniform as f64 / cells,
            1.0 - uniform_len / total,
            n_graded as f64 / cells,
            ratio
        )
    };
    let v = |x: f64, y: f64, z: f64| format!("    ({x:.4} {y:.4} {z:.4})\n");
    let vertices: String = [
        v(e0, n0, z0),
        v(e1, n0, z0),
        v(e1, n1, z0),
        v(e0, n1, z0),
        v(e0, n0, z1),
        v(e1, n0, z1),
        v(e1, n1, z1),
        v(e0, n1, z1),
    ]
    .concat();
    let patch = |name: &str, kind: &str, face: &str| {
        format!("    {name}\n    {{\n        type {kind};\n        faces ( {face} );\n    }}\n")
    };
    let boundary = [
        patch("ground", "wall", "(0 3 2 1)"),
        patch("top", "patch", "(4 5 6 7)"),
        patch("west", "patch", "(0 4 7 3)"),
        patch("east", "patch", "(1 2 6 5)"),
        patch("south", "patch", "(0 1 5 4)"),
        patch("north", "patch", "(3 7 6 2)"),
    ]
    .concat();
    foam_file(
        "dictionary",
        "blockMeshDict",
        &format!(
            "// ENU metres: x east, y north, z up.\nscale 1;\n\nvertices\n(\n{vertices});\n\n\
             blocks\n(\n    hex (0 1 2 3 4 5 6 7) ({nx} {ny} {nz}) simpleGrading (1 1 {z_grading})\n);\n\n\
             edges ();\n\nboundary\n(\n{boundary});\n\nmergePatchPairs ();\n",
            nz = n_uniform + n_graded
        ),
    )
}

fn snappy_dict(spec: &CaseSpec) -> String {
    let [e0, n0, _, _] = spec.rect_m;
    let h = spec.background_cell_m;
    let l = spec.refine_levels;
    // A point in the air: above the first background cell's centre, 1 % of the domain's
    // height below the top (above every roof, off every cell face).
    let inside =
        [e0 + 0.5 * h + 0.0123, n0 + 0.5 * h + 0.0171, spec.top_up_m - 0.01 * (spec.top_up_m - spec.ground_up_m)];
    foam_file(
        "dictionary",
        "snappyHexMeshDict",
        &format!(
            "castellatedMesh true;\nsnap true;\naddLayers false;\n\n\
             geometry\n{{\n    buildings.stl {{ type triSurfaceMesh; name buildings; }}\n}}\n\n\
             castellatedMeshControls\n{{\n\
             \x20   maxLocalCells 2000000;\n    maxGlobalCells 4000000;\n    minRefinementCells 0;\n\
             \x20   maxLoadUnbalance 0.1;\n    nCellsBetweenLevels 2;\n    features ();\n\
             \x20   refinementSurfaces\n    {{\n        buildings {{ level ({l} {l}); patchInfo {{ type wall; }} }}\n    }}\n\
             \x20   resolveFeatureAngle 30;\n    refinementRegions {{ }}\n\
             \x20   locationInMesh ({:.4} {:.4} {:.4});\n    allowFreeStandingZoneFaces true;\n}}\n\n\
             snapControls\n{{\n    nSmoothPatch 3;\n    tolerance 2.0;\n    nSolveIter 30;\n    nRelaxIter 5;\n\
             \x20   nFeatureSnapIter 10;\n    implicitFeatureSnap true;\n    explicitFeatureSnap false;\n\
             \x20   multiRegionFeatureSnap false;\n}}\n\n\
             addLayersControls\n{{\n    relativeSizes true;\n    layers {{ }}\n    expansionRatio 1.0;\n\
             \x20   finalLayerThickness 0.3;\n    minThickness 0.1;\n    nGrow 0;\n    featureAngle 60;\n\
             \x20   nRelaxIter 3;\n    nSmoothSurfaceNormals 1;\n    nSmoothNormals 3;\n    nSmoothThickness 10;\n\
             \x20   maxFaceThicknessRatio 0.5;\n    maxThicknessToMedialRatio 0.3;\n    minMedialAxisAngle 90;\n\
             \x20   nBufferCellsNoExtrude 0;\n    nLayerIter 50;\n}}\n\n\
             meshQualityControls\n{{\n    maxNonOrtho 65;\n    maxBoundarySkewness 20;\n    maxInternalSkewness 4;\n\
             \x20   maxConcave 80;\n    minVol 1e-13;\n    minTetQuality 1e-15;\n    minArea -1;\n    minTwist 0.02;\n\
             \x20   minDeterminant 0.001;\n    minFaceWeight 0.05;\n    minVolRatio 0.01;\n    minTriangleTwist -1;\n\
             \x20   nSmoothScale 4;\n    errorReduction 0.75;\n    relaxed {{ maxNonOrtho 75; }}\n}}\n\n\
             mergeTolerance 1e-6;\n",
            inside[0], inside[1], inside[2]
        ),
    )
}

const FV_SCHEMES: &str = "ddtSchemes { default steadyState; }
gradSchemes { default Gauss linear; grad(U) cellLimited Gauss linear 1; grad(k) cellLimited Gauss linear 1; grad(epsilon) cellLimited Gauss linear 1; }
divSchemes
{
    default none;
    div(phi,U) bounded Gauss linearUpwind grad(U);
    div(phi,k) bounded Gauss linearUpwind grad(k);
    div(phi,epsilon) bounded Gauss linearUpwind grad(epsilon);
    div((nuEff*dev2(T(grad(U))))) Gauss linear;
}
// Limited non-orthogonal correction: snapped cells at the walls are not orthogonal.
laplacianSchemes { default Gauss linear limited corrected 0.33; }
interpolationSchemes { default linear; }
snGradSchemes { default limited corrected 0.33; }
wallDist { method meshWave; }
";

fn fv_solution() -> String {
    let targets: String = RESIDUAL_TARGETS.iter().map(|(f, v)| format!("        {f} {v:e};\n")).collect();
    foam_file(
        "dictionary",
        "fvSolution",
        &format!(
            "solvers\n{{\n    p {{ solver GAMG; smoother GaussSeidel; tolerance 1e-7; relTol 0.1; }}\n\
             \x20   \"(U|k|epsilon)\" {{ solver smoothSolver; smoother symGaussSeidel; tolerance 1e-8; relTol 0.1; }}\n}}\n\
             SIMPLE\n{{\n    nNonOrthogonalCorrectors 0;\n    consistent yes;\n    residualControl\n    {{\n{targets}    }}\n}}\n\
             relaxationFactors\n{{\n    equations {{ U 0.9; \".*\" 0.7; }}\n}}\n"
        ),
    )
}

/// What a side of the domain is for a wind direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Side {
    /// The wind enters: the ABL profile (inletOutlet).
    Inlet,
    /// The wind leaves: p = 0, zero gradient.
    Outlet,
    /// The wind is parallel to it: slip.
    Parallel,
}

/// The four sides `west, east, south, north` for the wind from `direction_from_deg`.
pub fn sides(direction_from_deg: f64) -> [(&'static str, Side); 4] {
    let d = WindAxes::from_deg(direction_from_deg).downwind;
    let side = |normal: [f64; 2]| {
        let c = normal[0] * d[0] + normal[1] * d[1];
        if c < -PARALLEL_COS {
            Side::Inlet
        } else if c > PARALLEL_COS {
            Side::Outlet
        } else {
            Side::Parallel
        }
    };
    [("west", side([-1.0, 0.0])), ("east", side([1.0, 0.0])), ("south", side([0.0, -1.0])), ("north", side([0.0, 1.0]))]
}

/// `0/U`, `0/p`, `0/k`, `0/epsilon`, `0/nut`.
fn initial_fields(spec: &CaseSpec) -> Vec<(String, String)> {
    let d = WindAxes::from_deg(spec.direction_from_deg).downwind;
    let z0 = spec.z0_m;
    let u_ref = spec.reference_speed_ms;
    let u_star = KAPPA * u_ref / ((REFERENCE_HEIGHT_M + z0) / z0).ln();
    // Internal fields start from the inflow's values at the reference height.
    let k0 = u_star * u_star / C_MU.sqrt();
    let eps0 = u_star.powi(3) / (KAPPA * (REFERENCE_HEIGHT_M + z0));
    let abl = format!(
        "flowDir ({:.9} {:.9} 0); zDir (0 0 1); Uref {u_ref}; Zref {REFERENCE_HEIGHT_M}; z0 uniform {z0}; zGround uniform {};",
        d[0], d[1], spec.ground_up_m
    );
    let u_internal = format!("({:.6} {:.6} 0)", d[0] * u_ref, d[1] * u_ref);
    let sides = sides(spec.direction_from_deg);

    // One field: its internal value and, per boundary, the condition.
    let field = |class: &str, object: &str, dims: &str, internal: &str, bc: &dyn Fn(&str) -> String| {
        let mut body = format!("dimensions {dims};\n\ninternalField uniform {internal};\n\nboundaryField\n{{\n");
        for patch in ["ground", "top", "buildings", "west", "east", "south", "north"] {
            let _ = writeln!(body, "    {patch} {{ {} }}", bc(patch));
        }
        body.push_str("}\n");
        (format!("0/{object}"), foam_file(class, object, &body))
    };
    let side_of = |patch: &str| sides.iter().find(|(n, _)| *n == patch).map(|(_, s)| *s);

    let u = field("volVectorField", "U", "[0 1 -1 0 0 0 0]", &u_internal, &|p| match (p, side_of(p)) {
        ("ground" | "buildings", _) => "type noSlip;".into(),
        ("top", _) | (_, Some(Side::Parallel)) => "type slip;".into(),
        (_, Some(Side::Inlet)) => format!("type atmBoundaryLayerInletVelocity; {abl} value uniform {u_internal};"),
        _ => format!("type inletOutlet; inletValue uniform (0 0 0); value uniform {u_internal};"),
    });
    let p = field("volScalarField", "p", "[0 2 -2 0 0 0 0]", "0", &|p| match (p, side_of(p)) {
        (_, Some(Side::Outlet)) => "type fixedValue; value uniform 0;".into(),
        ("top", _) | (_, Some(Side::Parallel)) => "type slip;".into(),
        _ => "type zeroGradient;".into(),
    });
    let turbulence = |name: &str, dims: &str, value: f64, abl_type: &str, wall: &str| {
        field("volScalarField", name, dims, &format!("{value:e}"), &|p| match (p, side_of(p)) {
            ("ground" | "buildings", _) => format!("type {wall}; value uniform {value:e};"),
            ("top", _) | (_, Some(Side::Parallel)) => "type slip;".into(),
            (_, Some(Side::Inlet)) => format!("type {abl_type}; {abl} value uniform {value:e};"),
            _ => format!("type inletOutlet; inletValue uniform {value:e}; value uniform {value:e};"),
        })
    };
    let k = turbulence("k", "[0 2 -2 0 0 0 0]", k0, "atmBoundaryLayerInletK", "kqRWallFunction");
    let eps = turbulence("epsilon", "[0 2 -3 0 0 0 0]", eps0, "atmBoundaryLayerInletEpsilon", "epsilonWallFunction");
    let nut = field("volScalarField", "nut", "[0 2 -1 0 0 0 0]", "0", &|p| match p {
        // The rough ground's wall function (z0 as the inflow's: the profile is in
        // equilibrium with the ground it flows over).
        "ground" => format!("type nutkAtmRoughWallFunction; z0 uniform {z0}; value uniform 0;"),
        "buildings" => "type nutkWallFunction; value uniform 0;".into(),
        _ => "type calculated; value uniform 0;".into(),
    });
    vec![u, p, k, eps, nut]
}

#[cfg(test)]
mod tests {
    use sadesim_world::{Building, Footprint};

    use super::*;
    use crate::grid::GridSpec;

    fn boxes() -> World {
        let rect = |e: f64, n: f64, w: f64| {
            Footprint::new(vec![[e - w, n - w], [e + w, n - w], [e + w, n + w], [e - w, n + w]], vec![]).unwrap()
        };
        World::of_buildings(
            100.0,
            vec![
                Building::new(rect(0.0, 0.0, 10.0), 0.0, 20.0).unwrap(),
                // Crosses the world's (and the case's) east side.
                Building::new(rect(98.0, 0.0, 5.0), 0.0, 10.0).unwrap(),
            ],
        )
    }

    fn file<'a>(files: &'a [(String, Vec<u8>)], path: &str) -> &'a str {
        let (_, bytes) = files.iter().find(|(p, _)| p == path).unwrap_or_else(|| panic!("no {path}"));
        std::str::from_utf8(bytes).unwrap()
    }

    #[test]
    fn for_grid_covers_the_grid_and_the_block_mesh_matches_the_rectangle() {
        let world = boxes();
        let grid = WindGrid::over(&world, GridSpec { spacing_m: 5.0, top_factor: 2.0 });
        let spec = CaseSpec::for_grid(&grid, 270.0);
        assert_eq!(spec.rect_m, [-100.0, -100.0, 100.0, 100.0]);
        assert_eq!((spec.ground_up_m, spec.uniform_up_to_m, spec.top_up_m), (0.0, 40.0, 80.0));
        let ([nx, ny], n_uniform, n_graded) = spec.background_cells();
        assert_eq!((nx, ny, n_uniform), (40, 40, 8));
        // 40 m above the uniform layers, growing from 5 m by at most 1.2: 6 cells.
        assert_eq!(n_graded, 6);
        let files = case_files(&world, &spec);
        let mesh = file(&files, "system/blockMeshDict");
        assert!(
            mesh.contains("(-100.0000 -100.0000 0.0000)") && mesh.contains("(100.0000 100.0000 80.0000)"),
            "{mesh}"
        );
        assert!(mesh.contains("(40 40 14)"), "{mesh}");
        assert!(mesh.contains("((0.500000 0.571429 1) (0.500000 0.428571 "), "{mesh}");
    }

    #[test]
    fn the_stl_holds_every_building_in_the_rectangle_as_a_closed_box() {
        let world = boxes();
        let grid = WindGrid::over(&world, GridSpec { spacing_m: 5.0, top_factor: 2.0 });
        let mut spec = CaseSpec::for_grid(&grid, 270.0);
        let files = case_files(&world, &spec);
        let stl = file(&files, "constant/triSurface/buildings.stl");
        // A box: two triangles per face, six faces.
        assert_eq!(stl_facets(stl.as_bytes()), 24);
        assert!(stl.starts_with("solid buildings") && stl.trim_end().ends_with("endsolid buildings"));
        // Reaching 1 m below the ground.
        assert!(stl.contains("vertex -10.0000 -10.0000 -1.0000"), "{stl}");
        assert_eq!(stl.matches("vertex").count(), 3 * 24);
        // A rectangle holding only the cube's west half still meshes it; one without
        // buildings has none.
        spec.rect_m = [-50.0, -50.0, 0.0, 50.0];
        assert_eq!(case_buildings(&world, &spec), vec![0]);
        spec.rect_m = [-90.0, -90.0, -50.0, -50.0];
        assert!(case_buildings(&world, &spec).is_empty());
        assert_eq!(stl_facets(file(&case_files(&world, &spec), "constant/triSurface/buildings.stl").as_bytes()), 0);
    }

    #[test]
    fn inlets_face_the_wind_and_outlets_face_away() {
        use Side::*;
        let names = |d: f64| sides(d).map(|(_, s)| s);
        // From the west: in through the west side, out through the east, slip north and south.
        assert_eq!(names(270.0), [Inlet, Outlet, Parallel, Parallel]);
        // From the south-west: in through west and south.
        assert_eq!(names(225.0), [Inlet, Outlet, Inlet, Outlet]);
        assert_eq!(names(0.0), [Parallel, Parallel, Outlet, Inlet]);
    }

    #[test]
    fn fields_name_the_abl_conditions_and_every_patch() {
        let world = boxes();
        let grid = WindGrid::over(&world, GridSpec { spacing_m: 5.0, top_factor: 2.0 });
        let files = case_files(&world, &CaseSpec::for_grid(&grid, 225.0));
        let u = file(&files, "0/U");
        assert_eq!(u.matches("atmBoundaryLayerInletVelocity").count(), 2, "{u}");
        assert!(u.contains("flowDir (0.707106781 0.707106781 0)"), "{u}");
        for f in ["0/U", "0/p", "0/k", "0/epsilon", "0/nut"] {
            for patch in ["ground", "top", "buildings", "west", "east", "south", "north"] {
                assert!(file(&files, f).contains(&format!("    {patch} {{")), "{f} lacks {patch}");
            }
        }
        assert!(file(&files, "system/controlDict").contains("writeFormat ascii;"));
        assert!(file(&files, "0/nut").contains("nutkAtmRoughWallFunction; z0 uniform 1;"));
    }
}
