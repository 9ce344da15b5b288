//! The OpenFOAM field import (`sadesim_wind::openfoam` and `foam_import::import_case`: a
//! case's cell centres `C` and velocity `U`, ASCII `volVectorField` files a user brings) on
//! arbitrary text, mapped onto a small wind grid.
//!
//! The input is `C`, a zero byte, then `U` (the seeds: `wind/src/fuzz_seeds.rs`). What is
//! asserted: never a panic, a hang or a runaway allocation (a declared list count is not
//! trusted); an error is one line naming the file; a field read has finite components, `C`
//! and `U` as many cells; an imported sector has one finite factor per grid cell, zero in
//! solid cells.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sadesim_wind::foam_import::{ImportSpec, import_case};
use sadesim_wind::openfoam::{parse_case_fields, parse_vector_field};
use sadesim_wind::{GridSpec, WindGrid};
use sadesim_world::World;
use std::sync::OnceLock;

/// The grid the seeds cover: an open 16 m square in cells of 4 m, 40 m up (160 cells).
fn grid() -> &'static WindGrid {
    static GRID: OnceLock<WindGrid> = OnceLock::new();
    GRID.get_or_init(|| WindGrid::over(&World::of_buildings(8.0, vec![]), GridSpec { spacing_m: 4.0, top_factor: 2.0 }))
}

fn one_line(file: &str, message: &str) {
    assert!(!message.contains('\n'), "not one line: {message:?}");
    assert!(message.starts_with(file), "the error does not name {file}: {message:?}");
}

fuzz_target!(|data: &[u8]| {
    let (c, u) = match data.iter().position(|&b| b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    let (c, u) = (String::from_utf8_lossy(c), String::from_utf8_lossy(u));
    match parse_vector_field("CASE/C", &c) {
        Ok(values) => assert!(values.iter().flatten().all(|v| v.is_finite())),
        Err(e) => one_line("CASE/C", &e.to_string()),
    }
    match parse_case_fields("CASE/C", &c, "CASE/U", &u) {
        Ok(f) => {
            assert_eq!(f.centres_m.len(), f.velocity_mps.len());
            assert!(f.velocity_mps.iter().flatten().all(|v| v.is_finite()));
        }
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "not one line: {m:?}");
            assert!(m.starts_with("CASE/"), "the error names no file: {m:?}");
        }
    }
    let g = grid();
    let spec = ImportSpec { direction_from_deg: 270.0, reference_speed_ms: 8.0 };
    match import_case(g, "CASE/C", &c, "CASE/U", &u, spec) {
        Ok(s) => {
            for values in [&s.east, &s.north, &s.up] {
                assert_eq!(values.len(), g.cells());
                assert!(values.iter().all(|v| v.is_finite()), "a non-finite factor");
            }
            for (i, solid) in g.solid.iter().enumerate() {
                if *solid {
                    assert_eq!([s.east[i], s.north[i], s.up[i]], [0.0; 3]);
                }
            }
        }
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "not one line: {m:?}");
            assert!(m.starts_with("CASE/"), "the error names no file: {m:?}");
        }
    }
});
