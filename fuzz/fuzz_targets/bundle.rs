//! `sadesim_world::World::from_bytes` (the asset bundle's `world.bin`) on arbitrary bytes,
//! then the queries every role asks of a loaded world: a world that answers them or a
//! one-line error, never a panic, a hang or a runaway allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nalgebra::Vector3;
use sadesim_world::World;

fuzz_target!(|data: &[u8]| {
    match World::from_bytes(data) {
        Ok(world) => {
            let e = world.extent_m();
            for (x, y) in [(0.0, 0.0), (1.5, -2.5), (e, e), (-e, 0.5 * e), (1e12, f64::NAN)] {
                let _ = world.ground_up_m(x, y);
                let _ = world.surface_up_m(x, y);
                let _ = world.building_at(x, y);
                let _ = world.is_inside_building(Vector3::new(x, y, 5.0));
            }
            for (a, b) in [
                (Vector3::new(-e, 0.0, 5.0), Vector3::new(e, 0.0, 5.0)),
                (Vector3::new(-e, -e, 500.0), Vector3::new(e, e, -10.0)),
                (Vector3::new(3.0, 4.0, 1.0), Vector3::new(3.0, 4.0, 1.0)),
            ] {
                let _ = world.segment_hits_building(a, b);
            }
            let _ = world.stats().to_string();
        }
        Err(e) => {
            let message = e.to_string();
            assert!(!message.is_empty() && !message.contains('\n'), "not one line: {message:?}");
        }
    }
});
