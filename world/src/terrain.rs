//! Ground height: a gentle, smooth, seeded relief, exactly 0 at the origin.
//!
//! The ground is a sum of [`WAVES`] plane waves (ENU metres, `p = (east, north)`):
//!
//! ```text
//! h(p) = sum_i a_i (sin(k_i . p + phi_i) - sin(phi_i))
//! ```
//!
//! with amplitude `a_i` (m), wave vector `k_i` (rad/m, |k_i| = 2 pi / lambda_i) and phase
//! `phi_i`. Subtracting `sin(phi_i)` makes `h(0) = 0` exactly, so ENU `up` equals height
//! above the origin's ground and z = 0 is `spec.origin.altitudeMslM`.
//!
//! Bounds, from |sin| <= 1 and |cos| <= 1:
//! - `|h| <= sum_i a_i (1 + |sin phi_i|) <= 2 sum_i a_i` ([`Terrain::max_abs_up_m`]);
//! - slope `|grad h| <= sum_i a_i |k_i|` ([`Terrain::max_slope`]).
//!
//! Parameter choice: wavelengths 0.6-3 km and amplitudes 0.5-1 m give a few metres of
//! relief across a city (about +-2 m typically, never beyond 8 m) with slopes of at most 4.2 %:
//! enough that AGL and MSL altitudes visibly differ, gentle enough for streets and for
//! boxes standing on the ground at their centre (a 40 m footprint's corner sits < 1 m off).

use sadesim_crds::random::Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Number of plane waves in the relief.
pub const WAVES: usize = 4;
const MIN_WAVELENGTH_M: f64 = 600.0;
const MAX_WAVELENGTH_M: f64 = 3000.0;
const MIN_AMPLITUDE_M: f64 = 0.5;
const MAX_AMPLITUDE_M: f64 = 1.0;

/// One plane wave: `a (sin(kx east + ky north + phi) - sin(phi))`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
struct Wave {
    amplitude_m: f64,
    k_east_rad_per_m: f64,
    k_north_rad_per_m: f64,
    phase_rad: f64,
    sin_phase: f64,
}

/// The ground: the seeded relief (see the module docs for the formula and its bounds), or
/// a grid resampled from a digital elevation model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Terrain {
    relief: Relief,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
enum Relief {
    /// z = 0 everywhere.
    Flat,
    /// The seeded plane waves.
    Waves([Wave; WAVES]),
    /// A DEM resampled on a grid.
    Grid(GroundGrid),
}

/// Ground heights on a square ENU grid (from a DEM), bilinear between samples, held at the
/// edge value outside.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundGrid {
    /// East and north of sample (0, 0), metres.
    east0_m: f64,
    north0_m: f64,
    cell_m: f64,
    n: usize,
    /// Row-major from the south-west, `up` metres above the origin's altitude.
    up_m: Vec<f64>,
}

impl GroundGrid {
    /// Samples `up(east, north)` on an `n x n` grid from `(-half, -half)` to `(half, half)`.
    pub fn sample(half_m: f64, n: usize, mut up: impl FnMut(f64, f64) -> f64) -> Self {
        let n = n.max(2);
        let cell_m = 2.0 * half_m / (n - 1) as f64;
        let mut values = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                values.push(up(-half_m + i as f64 * cell_m, -half_m + j as f64 * cell_m));
            }
        }
        Self { east0_m: -half_m, north0_m: -half_m, cell_m, n, up_m: values }
    }

    fn up_m(&self, east_m: f64, north_m: f64) -> f64 {
        let last = (self.n - 1) as f64;
        let fi = ((east_m - self.east0_m) / self.cell_m).clamp(0.0, last);
        let fj = ((north_m - self.north0_m) / self.cell_m).clamp(0.0, last);
        let (i, j) = ((fi as usize).min(self.n - 2), (fj as usize).min(self.n - 2));
        let (u, v) = (fi - i as f64, fj - j as f64);
        let at = |i: usize, j: usize| self.up_m[j * self.n + i];
        (1.0 - u) * (1.0 - v) * at(i, j)
            + u * (1.0 - v) * at(i + 1, j)
            + (1.0 - u) * v * at(i, j + 1)
            + u * v * at(i + 1, j + 1)
    }

    fn max_abs_up_m(&self) -> f64 {
        self.up_m.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Largest slope between neighbouring samples (bilinear patches slope no more).
    fn max_slope(&self) -> f64 {
        let n = self.n;
        let at = |i: usize, j: usize| self.up_m[j * n + i];
        let mut slope: f64 = 0.0;
        for j in 0..n {
            for i in 0..n {
                if i + 1 < n {
                    slope = slope.max((at(i + 1, j) - at(i, j)).abs() / self.cell_m);
                }
                if j + 1 < n {
                    slope = slope.max((at(i, j + 1) - at(i, j)).abs() / self.cell_m);
                }
            }
        }
        slope
    }
}

impl Terrain {
    /// Flat ground at z = 0 (a mapped city without a DEM: no invented relief).
    pub fn flat() -> Self {
        Self { relief: Relief::Flat }
    }

    /// The ground of a DEM, resampled on `grid`.
    pub fn from_grid(grid: GroundGrid) -> Self {
        Self { relief: Relief::Grid(grid) }
    }

    /// Whether a decoded grid has its `n x n` samples (n >= 2) and a positive cell.
    pub(crate) fn is_consistent(&self) -> bool {
        match &self.relief {
            Relief::Flat | Relief::Waves(_) => true,
            Relief::Grid(g) => g.n >= 2 && g.n.checked_mul(g.n) == Some(g.up_m.len()) && g.cell_m > 0.0,
        }
    }

    /// Draws the relief from `rng`: exactly `4 * WAVES` draws, so what is drawn after it does
    /// not depend on the terrain.
    pub fn generate(rng: &mut Rng) -> Self {
        let waves = std::array::from_fn(|_| {
            // Log-uniform wavelength: as many long swells as short undulations.
            let wavelength_m = MIN_WAVELENGTH_M * (MAX_WAVELENGTH_M / MIN_WAVELENGTH_M).powf(rng.next_f64());
            let heading_rad = rng.uniform(0.0, TAU);
            let k = TAU / wavelength_m;
            let amplitude_m = rng.uniform(MIN_AMPLITUDE_M, MAX_AMPLITUDE_M);
            let phase_rad = rng.uniform(0.0, TAU);
            Wave {
                amplitude_m,
                k_east_rad_per_m: k * heading_rad.cos(),
                k_north_rad_per_m: k * heading_rad.sin(),
                phase_rad,
                sin_phase: phase_rad.sin(),
            }
        });
        Self { relief: Relief::Waves(waves) }
    }

    /// Ground height above the origin's ground (ENU up), metres, at a horizontal position.
    /// Defined everywhere, also outside the world's extent.
    pub fn up_m(&self, east_m: f64, north_m: f64) -> f64 {
        match &self.relief {
            Relief::Flat => 0.0,
            Relief::Waves(waves) => waves
                .iter()
                .map(|w| {
                    let arg = w.k_east_rad_per_m * east_m + w.k_north_rad_per_m * north_m + w.phase_rad;
                    w.amplitude_m * (arg.sin() - w.sin_phase)
                })
                .sum(),
            Relief::Grid(grid) => grid.up_m(east_m, north_m),
        }
    }

    /// Upper bound of `|up_m|` anywhere, metres.
    pub fn max_abs_up_m(&self) -> f64 {
        match &self.relief {
            Relief::Flat => 0.0,
            Relief::Waves(waves) => waves.iter().map(|w| w.amplitude_m * (1.0 + w.sin_phase.abs())).sum(),
            Relief::Grid(grid) => grid.max_abs_up_m(),
        }
    }

    /// Upper bound of the ground slope `|grad h|` anywhere (metres per metre).
    pub fn max_slope(&self) -> f64 {
        match &self.relief {
            Relief::Flat => 0.0,
            Relief::Waves(waves) => {
                waves.iter().map(|w| w.amplitude_m * w.k_east_rad_per_m.hypot(w.k_north_rad_per_m)).sum()
            }
            Relief::Grid(grid) => grid.max_slope(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_crds::random::Purpose;

    #[test]
    fn bounds_hold_and_origin_is_zero_for_every_seed() {
        for seed in 0..200 {
            let t = Terrain::generate(&mut Rng::stream(seed, 0, Purpose::World));
            assert!(t.max_abs_up_m() <= 2.0 * WAVES as f64 * MAX_AMPLITUDE_M);
            assert!(t.max_slope() <= 0.042, "seed {seed}: slope bound {}", t.max_slope());
            assert_eq!(t.up_m(0.0, 0.0), 0.0);
        }
    }
}
