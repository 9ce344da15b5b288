//! The seed corpus of the orbit-file fuzz target (`fuzz/fuzz_targets/orbits.rs`), written
//! when `SADESIM_FUZZ_SEEDS` names a folder (`tests/fuzz.sh` sets it): the crate's own orbit
//! files cut small (a fuzzer mutates every byte of a small file more often), in each form the
//! reader takes (TLE, 2LE, 3LE, and OMM in its four encodings), each checked to read.
//! Nothing is committed.

use crate::omm::Encoding;
use crate::omm::tests::encode;
use crate::orbits::{Constellation, System};
use crate::synthetic::{NOMINAL_TLE, walker_gps_galileo_tle};

/// The first `n` non-empty lines of `text`.
fn lines(text: &str, n: usize) -> String {
    text.lines().filter(|l| !l.trim().is_empty()).take(n).map(|l| format!("{l}\n")).collect()
}

#[test]
fn the_fuzz_seeds_are_orbit_files_that_read() {
    let walker = walker_gps_galileo_tle();
    let three_line = lines(&walker, 6);
    // Two-line form (no names): taken as GPS.
    let two_line: String = lines(&walker, 6)
        .lines()
        .filter(|l| l.starts_with("1 ") || l.starts_with("2 "))
        .map(|l| format!("{l}\n"))
        .collect();
    // Named with CelesTrak's `0 ` prefix, one Galileo among others, CRLF line ends.
    let galileo = walker.lines().skip(24 * 3).take(3).collect::<Vec<_>>().join("\r\n");
    let prefixed = format!("0 {}\r\n", galileo);
    // A catalogue: a non-navigation object the reader skips, then a navigation satellite.
    let catalogue = format!(
        "ISS (ZARYA)\n{}{}",
        lines(&walker, 3).lines().skip(1).map(|l| format!("{l}\n")).collect::<String>(),
        lines(NOMINAL_TLE, 3)
    );
    let seeds = [
        ("walker-3le.tle", three_line),
        ("walker-2le.tle", two_line),
        ("galileo-prefixed.tle", prefixed),
        ("catalogue.tle", catalogue),
        ("nominal.tle", lines(NOMINAL_TLE, 9)),
    ];
    // The same two satellites (one GPS, one Galileo) as OMM in each encoding.
    let pair = Constellation::parse(&format!("{}{}", lines(&walker, 3), galileo.replace("\r\n", "\n")))
        .expect("the pair reads");
    let pair: Vec<sgp4::Elements> = (0..pair.satellites.len()).map(|i| pair.elements(i).clone()).collect();
    let omm = [
        ("pair.kvn", encode(&pair, Encoding::Kvn)),
        ("pair.xml", encode(&pair, Encoding::Xml)),
        ("pair.json", encode(&pair, Encoding::Json)),
        ("pair.csv", encode(&pair, Encoding::Csv)),
    ];
    let seeds: Vec<(&str, String)> = seeds.into_iter().chain(omm).collect();
    for (name, text) in &seeds {
        let c = Constellation::parse(text).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!c.positions(c.newest_epoch_unix_s()).is_empty(), "{name}");
    }
    let galileo = Constellation::parse(&seeds[2].1).unwrap();
    assert_eq!(galileo.satellites[0].system, System::Galileo);
    let Some(root) = std::env::var_os("SADESIM_FUZZ_SEEDS") else { return };
    let dir = std::path::Path::new(&root).join("orbits");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, text) in &seeds {
        std::fs::write(dir.join(name), text).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
}
