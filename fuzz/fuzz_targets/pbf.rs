//! `sadesim_world::osm::read_pbf` on arbitrary bytes: a city or a one-line error, never a
//! panic (an index out of bounds, an arithmetic overflow: cargo fuzz builds with debug
//! assertions), a hang or a runaway allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sadesim_crds::geo::{GeoPoint, LocalFrame};
use sadesim_world::osm;

/// The seeds' origin and extent (`world/src/osm/tests.rs`, which writes them): an input
/// that keeps the seed's header covers the square and reaches the assembly.
const ORIGIN: GeoPoint = GeoPoint { latitude_deg: 60.17, longitude_deg: 24.95, altitude_msl_m: 10.0 };
const EXTENT_M: f64 = 1000.0;

fuzz_target!(|data: &[u8]| {
    match osm::read_pbf(data, &LocalFrame::new(ORIGIN), EXTENT_M) {
        Ok(city) => {
            let s = &city.stats;
            assert_eq!(s.buildings, city.buildings.len());
            assert_eq!(s.heights_tagged + s.heights_from_levels + s.heights_defaulted, s.buildings);
            assert_eq!(s.parts, city.buildings.iter().filter(|b| b.part).count());
            for b in &city.buildings {
                let f = b.building.footprint();
                let [w, s, e, n] = f.bounds();
                assert!(w >= -EXTENT_M - 1e-6 && e <= EXTENT_M + 1e-6 && s >= -EXTENT_M - 1e-6 && n <= EXTENT_M + 1e-6);
                assert!(b.building.height_m() > 0.0);
            }
        }
        Err(e) => {
            let message = e.to_string();
            assert!(!message.is_empty() && !message.contains('\n'), "not one line: {message:?}");
        }
    }
});
