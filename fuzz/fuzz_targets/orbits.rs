//! Orbit files (`sadesim_gnss::Constellation::parse`: TLE and 3LE element sets, and OMM in
//! KVN, XML, JSON and CSV, as CelesTrak publishes them) on arbitrary text, then what a run
//! asks of a constellation: its age, its newest epoch and every satellite's position at a
//! few times.
//!
//! What is asserted: never a panic, a hang or a runaway allocation; an error is one line
//! naming the line of the file it is about (or saying what kind of file this is not); a
//! constellation has satellites, and every position SGP4 gives is a finite point.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sadesim_gnss::omm::At;
use sadesim_gnss::{Constellation, OrbitError};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match Constellation::parse(&text) {
        Ok(c) => {
            assert!(!c.satellites.is_empty());
            let newest = c.newest_epoch_unix_s();
            assert!(newest.is_finite(), "epoch {newest}");
            for dt in [0.0, 3600.0, -86_400.0 * 3.0, 86_400.0 * 400.0] {
                let _ = c.age_days(newest + dt);
                for p in c.positions(newest + dt) {
                    assert!(p.index < c.satellites.len());
                    let e = p.ecef;
                    // SGP4 may fail to propagate a decayed orbit (left out), never give a
                    // non-finite position.
                    assert!(e.x_m.is_finite() && e.y_m.is_finite() && e.z_m.is_finite(), "{p:?}");
                }
            }
            for (i, s) in c.satellites.iter().enumerate() {
                assert!(!s.name.is_empty());
                let _ = c.elements(i);
            }
        }
        Err(e) => {
            let message = e.to_string();
            assert!(!message.is_empty() && !message.contains('\n'), "not one line: {message:?}");
            let lines = text.lines().count().max(1);
            match e {
                OrbitError::Line { line, .. }
                | OrbitError::Set { at: At::Line(line), .. }
                | OrbitError::Elements { at: At::Line(line), .. } => {
                    assert!(line >= 1 && line <= lines, "line {line} of {lines}: {message}");
                }
                OrbitError::Set { at: At::Object(n), .. } | OrbitError::Elements { at: At::Object(n), .. } => {
                    assert!(n >= 1, "{message}");
                }
                OrbitError::UnknownFormat { .. } | OrbitError::NoNavigationSatellites { .. } => {}
            }
        }
    }
});
