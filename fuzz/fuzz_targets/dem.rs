//! `sadesim_world::dem::Dem::read` on arbitrary bytes (as a GeoTIFF, and as an SRTM tile by
//! name), then sampling what it read: a DEM or a one-line error, never a panic, a hang or a
//! runaway allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sadesim_crds::geo::{GeoPoint, LocalFrame};
use sadesim_world::dem::Dem;

fuzz_target!(|data: &[u8]| {
    // The first byte names the file: the TIFF reader goes by the magic bytes, the SRTM
    // reader by a name like N60E024.hgt (and a size no fuzzer input reaches, but its name
    // parsing does).
    let Some((&name, bytes)) = data.split_first() else { return };
    let name = match name % 4 {
        0 => "dem.tif",
        1 => "N60E024.hgt",
        2 => "s09w178.HGT",
        _ => "tile.hgt",
    };
    match Dem::read(bytes, name) {
        Ok(dem) => {
            // The seeds' grid is around 60.0-60.05 N, 24.0-24.1 E (world/src/dem/tests.rs).
            for (lat, lon) in [(60.02, 24.05), (60.0, 24.0), (-1e9, f64::NAN), (89.9, 179.9)] {
                if let Some(z) = dem.elevation_m(lat, lon) {
                    assert!(z.is_finite());
                }
            }
            let frame = LocalFrame::new(GeoPoint::new(60.025, 24.05, 0.0));
            if let Err(e) = dem.check_covers(&frame, 1000.0) {
                assert!(!e.to_string().contains('\n'));
            }
        }
        Err(e) => {
            let message = e.to_string();
            assert!(!message.is_empty() && !message.contains('\n'), "not one line: {message:?}");
        }
    }
});
