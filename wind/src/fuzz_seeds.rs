//! The seed corpus of the OpenFOAM import fuzz target (`fuzz/fuzz_targets/openfoam.rs`),
//! written when `SADESIM_FUZZ_SEEDS` names a folder (`tests/fuzz.sh` sets it): a case's `C`,
//! a zero byte, then its `U`, over the target's grid (an open 16 m square in cells of 4 m),
//! in each form of internal field the reader takes, each checked to import. Nothing is
//! committed.

use sadesim_world::World;

use crate::foam_import::{ImportSpec, import_case};
use crate::grid::{GridSpec, WindGrid};

/// A `volVectorField` file: the header, `dimensions`, then `internal` as written.
fn field(object: &str, dims: &str, internal: &str) -> String {
    format!(
        "/* seed */\nFoamFile\n{{\n    version 2.0;\n    format ascii;\n    class volVectorField;\n    object {object};\n}}\n\ndimensions {dims};\n\ninternalField {internal};\n\nboundaryField\n{{\n    ground {{ type noSlip; }}\n}}\n"
    )
}

/// `nonuniform List<vector> N ( (x y z) ... )`, one entry a line.
fn list(values: &[[f64; 3]]) -> String {
    let entries: String = values.iter().map(|v| format!("({} {} {})\n", v[0], v[1], v[2])).collect();
    format!("nonuniform List<vector>\n{}\n(\n{entries})", values.len())
}

#[test]
fn the_fuzz_seeds_are_cases_that_import() {
    let grid = WindGrid::over(&World::of_buildings(8.0, vec![]), GridSpec { spacing_m: 4.0, top_factor: 2.0 });
    let [nx, ny, nz] = grid.dims;
    let centres: Vec<[f64; 3]> = (0..nz)
        .flat_map(|k| (0..ny).flat_map(move |j| (0..nx).map(move |i| (i, j, k))))
        .map(|(i, j, k)| grid.centre(i, j, k))
        .collect();
    let wind: Vec<[f64; 3]> = centres.iter().map(|p| [8.0 + 0.05 * p[2], 0.1 * p[0], -0.01 * p[2]]).collect();
    let c = field("C", "[0 1 0 0 0 0 0]", &list(&centres));
    let seeds = [
        ("nonuniform", c.clone(), field("U", "[0 1 -1 0 0 0 0]", &list(&wind))),
        ("uniform", c.clone(), field("U", "[0 1 -1 0 0 0 0]", "uniform (8 0.5 0)")),
        (
            "compact",
            c.clone(),
            field("U", "[0 1 -1 0 0 0 0]", &format!("nonuniform List<vector> {}{{(7.5 0 0.25)}}", centres.len())),
        ),
    ];
    let spec = ImportSpec { direction_from_deg: 270.0, reference_speed_ms: 8.0 };
    let mut files = Vec::new();
    for (name, c, u) in &seeds {
        let sector = import_case(&grid, "C", c, "U", u, spec).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(sector.east.len(), grid.cells(), "{name}");
        files.push((*name, [c.as_bytes(), &[0], u.as_bytes()].concat()));
    }
    let Some(root) = std::env::var_os("SADESIM_FUZZ_SEEDS") else { return };
    let dir = std::path::Path::new(&root).join("openfoam");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, bytes) in &files {
        std::fs::write(dir.join(name), bytes).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
}
