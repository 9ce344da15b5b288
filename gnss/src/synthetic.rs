//! Synthetic GPS- and Galileo-like constellations in TLE form, for tests and demonstrations
//! that need a full sky without an orbit file:
//! - GPS-like: a Walker 24/6/2 pattern (six planes 60° apart at 55°, four satellites per
//!   plane, 2.0056 revolutions a day: a 26 560 km orbit), the shape of GPS's 24 slots;
//! - Galileo-like: a Walker 24/3/1 pattern (three planes at 56°, eight per plane,
//!   1.7048 revolutions a day: a 29 600 km orbit), Galileo's nominal constellation.
//!
//! Together they are the sky of a dual-constellation receiver (u-blox M8/M9 track GPS and
//! Galileo at once). They are *not* the real constellations of any day: bring CelesTrak's
//! `gnss` file for that.
//!
//! [`NOMINAL_TLE`] is both of them as a file shipped with the project (`gnss/data/`,
//! element sets of 2020-11-30T12:00:00Z): the sky of a run whose constellation names no file.

/// One Walker constellation: `planes` × `per_plane` satellites, phasing factor `phasing`.
struct Walker {
    name: &'static str,
    first_norad: u32,
    planes: u32,
    per_plane: u32,
    phasing: u32,
    inclination_deg: f64,
    mean_motion_rev_per_day: f64,
}

const GPS_LIKE: Walker = Walker {
    name: "GPS WALKER G",
    first_norad: 90_001,
    planes: 6,
    per_plane: 4,
    phasing: 2,
    inclination_deg: 55.0,
    mean_motion_rev_per_day: 2.005_63,
};

const GALILEO_LIKE: Walker = Walker {
    name: "GALILEO WALKER E",
    first_norad: 91_001,
    planes: 3,
    per_plane: 8,
    phasing: 1,
    inclination_deg: 56.0,
    mean_motion_rev_per_day: 1.704_75,
};

/// The default orbit file: [`walker_gps_galileo_tle`] as shipped in
/// `gnss/data/nominal-gps-galileo.tle` (a test keeps the two equal). Circular orbits without
/// drag, so SGP4 keeps them in shape for years around their epoch: any run epoch gives a
/// plausible dual-constellation sky, not a real day's.
pub const NOMINAL_TLE: &str = include_str!("../data/nominal-gps-galileo.tle");

/// What errors and logs call [`NOMINAL_TLE`].
pub const NOMINAL_NAME: &str = "the built-in nominal GPS + Galileo constellation (gnss/data/nominal-gps-galileo.tle)";

/// The TLE checksum: the digits of the line's first 68 characters summed, each `-` counting
/// one, modulo 10.
pub fn tle_checksum(line: &str) -> u32 {
    line.chars().take(68).map(|c| if c == '-' { 1 } else { c.to_digit(10).unwrap_or(0) }).sum::<u32>() % 10
}

/// The 24 GPS-like satellites in three-line form (`GPS WALKER Gnn`, NORAD numbers 90001..),
/// epoch 2020-11-30T12:00:00Z (`20335.5`).
pub fn walker_gps_tle() -> String {
    walker_tle(&GPS_LIKE)
}

/// The GPS-like and the Galileo-like constellations (48 satellites), epoch
/// 2020-11-30T12:00:00Z.
pub fn walker_gps_galileo_tle() -> String {
    walker_tle(&GPS_LIKE) + &walker_tle(&GALILEO_LIKE)
}

fn walker_tle(w: &Walker) -> String {
    let mut out = String::new();
    let total = w.planes * w.per_plane;
    for plane in 0..w.planes {
        for slot in 0..w.per_plane {
            let k = plane * w.per_plane + slot;
            let n = w.first_norad + k;
            let raan = f64::from(plane) * 360.0 / f64::from(w.planes);
            let anomaly = (f64::from(slot) * 360.0 / f64::from(w.per_plane)
                + f64::from(plane * w.phasing) * 360.0 / f64::from(total))
                % 360.0;
            let l1 = format!("1 {n:05}U 20001A   20335.50000000  .00000000  00000-0  00000-0 0  999");
            let l2 = format!(
                "2 {n:05} {:8.4} {raan:8.4} 0001000 {:8.4} {anomaly:8.4} {:11.8}{:5}",
                w.inclination_deg, 0.0, w.mean_motion_rev_per_day, 1
            );
            out += &format!("{}{:02}\n", w.name, k + 1);
            out += &format!("{l1}{}\n{l2}{}\n", tle_checksum(&l1), tle_checksum(&l2));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::orbits::{Constellation, System};

    #[test]
    fn the_walker_files_are_valid_tle_files_of_navigation_satellites_at_their_heights() {
        let text = walker_gps_galileo_tle();
        assert!(text.lines().all(|l| l.contains("WALKER") || l.len() == 69), "{text}");
        let c = Constellation::from_tle(&text).unwrap();
        assert_eq!(c.satellites.len(), 48);
        let epoch = c.satellites[0].epoch_unix_s;
        assert_eq!(epoch, 1_606_737_600.0, "2020-11-30T12:00:00Z");
        for p in c.positions(epoch + 3600.0) {
            let s = &c.satellites[p.index];
            let r_km = (p.ecef.x_m.powi(2) + p.ecef.y_m.powi(2) + p.ecef.z_m.powi(2)).sqrt() / 1000.0;
            let expected_km = if s.system == System::Gps { 26_560.0 } else { 29_600.0 };
            assert!((r_km - expected_km).abs() < 60.0, "{} at {r_km} km", s.name);
        }
        assert_eq!(c.satellites.iter().filter(|s| s.system == System::Galileo).count(), 24);
        assert_eq!(Constellation::from_tle(&walker_gps_tle()).unwrap().satellites.len(), 24);
    }

    /// Regenerate with `SADESIM_WRITE_NOMINAL=1 cargo test -p sadesim-gnss nominal`.
    #[test]
    fn the_shipped_nominal_file_is_what_the_generator_writes() {
        let generated = walker_gps_galileo_tle();
        if std::env::var_os("SADESIM_WRITE_NOMINAL").is_some() {
            let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/nominal-gps-galileo.tle");
            std::fs::write(path, &generated).unwrap();
        }
        assert_eq!(NOMINAL_TLE, generated, "gnss/data/nominal-gps-galileo.tle is stale: regenerate it");
    }
}
