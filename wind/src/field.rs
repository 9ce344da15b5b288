//! The urban wind field: per inflow sector, the adjusted wind at every cell centre as a
//! factor of the reference wind (the undisturbed wind 10 m above open ground, see
//! [`crate::profile::FIELD_PROFILE`]), so one field serves every speed; a scenario's
//! direction blends the two nearest sectors.

use nalgebra::Vector3;
use sadesim_world::World;

use crate::grid::{GridSpec, WindGrid};
use crate::profile::{FIELD_PROFILE, LogProfile};
use crate::rockle::{WindAxes, first_guess};
use crate::solver::adjust;

/// Default number of inflow sectors (45° apart).
pub const DEFAULT_SECTORS: u32 = 8;

/// Version of the built-in model's numbers: part of the asset cache key of a stored field,
/// so a change to the first guess or the solver that changes any value must bump it (a
/// stored field of the old model is then a cache miss, not a silently different run).
pub const DIAGNOSTIC_MODEL_VERSION: u32 = 3;

/// One sector's field: the wind blowing from `direction_from_deg`, per cell, ENU, as
/// factors of the reference wind (f32: a field is tens of megabytes; the factors need no
/// more than 7 digits).
#[derive(Clone, Debug, PartialEq)]
pub struct SectorField {
    pub direction_from_deg: f64,
    pub east: Vec<f32>,
    pub north: Vec<f32>,
    pub up: Vec<f32>,
    /// The mass-conservation residual of the adjusted field and of its first guess
    /// ([`crate::solver::Adjusted::residual`]), and the solver's iterations.
    pub residual: f64,
    pub first_guess_residual: f64,
    pub iterations: usize,
}

/// The one or two sectors a wind direction blends, with their weights (sector index,
/// weight); a slice of them by `Deref`, and iterable by value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SectorBlend {
    sectors: [(u32, f64); 2],
    len: usize,
}

impl SectorBlend {
    /// The sectors of `sector_count` around the compass that a wind from
    /// `direction_from_deg` blends, and their weights (one sector when it is exactly on
    /// one): what a field needs before any sector is computed.
    pub fn of(sector_count: u32, direction_from_deg: f64) -> Self {
        let d = direction_from_deg.rem_euclid(360.0) / (360.0 / f64::from(sector_count));
        let k0 = d.floor();
        let w = d - k0;
        let k0 = (k0 as u32) % sector_count;
        let k1 = (k0 + 1) % sector_count;
        if w < 1e-9 {
            SectorBlend { sectors: [(k0, 1.0), (k0, 0.0)], len: 1 }
        } else {
            SectorBlend { sectors: [(k0, 1.0 - w), (k1, w)], len: 2 }
        }
    }
}

impl std::ops::Deref for SectorBlend {
    type Target = [(u32, f64)];

    fn deref(&self) -> &[(u32, f64)] {
        &self.sectors[..self.len]
    }
}

impl IntoIterator for SectorBlend {
    type Item = (u32, f64);
    type IntoIter = std::iter::Take<std::array::IntoIter<(u32, f64), 2>>;

    fn into_iter(self) -> Self::IntoIter {
        self.sectors.into_iter().take(self.len)
    }
}

/// The field of a world: its grid and the sectors computed so far (a run computes the one
/// or two its direction needs; an asset build may compute all).
#[derive(Clone, Debug, PartialEq)]
pub struct UrbanWindField {
    pub grid: WindGrid,
    /// Sectors around the compass: sector `k` is the wind from `k * 360 / sector_count`.
    pub sector_count: u32,
    /// Computed sectors, by index.
    pub sectors: Vec<(u32, SectorField)>,
    pub profile: LogProfile,
}

impl UrbanWindField {
    /// The grid over `world` with no sector computed yet.
    pub fn new(world: &World, spec: GridSpec, sector_count: u32) -> Self {
        Self {
            grid: WindGrid::over(world, spec),
            sector_count: sector_count.max(1),
            sectors: Vec::new(),
            profile: FIELD_PROFILE,
        }
    }

    /// Degrees between sectors.
    pub fn sector_step_deg(&self) -> f64 {
        360.0 / f64::from(self.sector_count)
    }

    /// The sectors a wind from `direction_from_deg` blends and their weights (one sector
    /// when it is exactly on one). No allocation: the flight samples it per drone.
    pub fn sectors_for(&self, direction_from_deg: f64) -> SectorBlend {
        SectorBlend::of(self.sector_count, direction_from_deg)
    }

    /// Computes sector `k` over `world` (the world the grid was laid over) unless it is there.
    pub fn ensure_sector(&mut self, world: &World, k: u32) {
        if self.sectors.iter().any(|(s, _)| *s == k) {
            return;
        }
        let direction_from_deg = f64::from(k) * self.sector_step_deg();
        let field = sector(world, &self.grid, direction_from_deg, &self.profile);
        self.sectors.push((k, field));
        self.sectors.sort_by_key(|(s, _)| *s);
    }

    /// Computes every sector not computed yet (what the asset cache stores, so any
    /// direction reuses it), calling `progress(done, total)` after each.
    pub fn ensure_all(&mut self, world: &World, mut progress: impl FnMut(u32, u32)) {
        for k in 0..self.sector_count {
            self.ensure_sector(world, k);
            progress(k + 1, self.sector_count);
        }
    }

    /// Sector `k`, when computed.
    pub fn sector(&self, k: u32) -> Option<&SectorField> {
        self.sectors.iter().find(|(s, _)| *s == k).map(|(_, f)| f)
    }

    /// The wind factor at ENU `pos` for a wind from `direction_from_deg`: trilinear between
    /// cell centres (a solid cell counts as still air, so the wind fades towards walls),
    /// blended between the two sectors; the undisturbed profile outside the grid's square
    /// or above its top, and `None` when a sector it needs was not computed.
    pub fn factor_at(&self, pos: &Vector3<f64>, direction_from_deg: f64, height_agl_m: f64) -> Option<Vector3<f64>> {
        let g = &self.grid;
        let h = g.spacing_m;
        let [nx, ny, _] = g.dims;
        let f = |v: f64, corner: f64| (v - corner) / h - 0.5;
        let (fx, fy, fz) = (f(pos.x, g.corner_m[0]), f(pos.y, g.corner_m[1]), f(pos.z, g.corner_m[2]));
        let outside = fx < -0.5 || fy < -0.5 || fx > nx as f64 - 0.5 || fy > ny as f64 - 0.5 || pos.z >= g.top_up_m();
        let mut out = Vector3::zeros();
        // Two loops rather than a branch inside one: the profile's logarithms are only
        // computed outside the grid (the same values either way).
        if outside {
            let u = self.profile.factor(height_agl_m);
            for (k, w) in self.sectors_for(direction_from_deg) {
                self.sector(k)?;
                let axes = WindAxes::from_deg(f64::from(k) * self.sector_step_deg());
                out += Vector3::new(axes.downwind[0] * u, axes.downwind[1] * u, 0.0) * w;
            }
        } else {
            for (k, w) in self.sectors_for(direction_from_deg) {
                out += trilinear(g, self.sector(k)?, fx, fy, fz.max(-0.5)) * w;
            }
        }
        Some(out)
    }
}

/// One sector: the first guess, adjusted.
fn sector(world: &World, grid: &WindGrid, direction_from_deg: f64, profile: &LogProfile) -> SectorField {
    let axes = WindAxes::from_deg(direction_from_deg);
    let guess = first_guess(world, grid, axes, profile);
    let east: Vec<f64> = guess.streamwise.iter().map(|u| u * axes.downwind[0]).collect();
    let north: Vec<f64> = guess.streamwise.iter().map(|u| u * axes.downwind[1]).collect();
    let a = adjust(grid, &east, &north, &guess.up);
    let narrow = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
    SectorField {
        direction_from_deg,
        east: narrow(a.east),
        north: narrow(a.north),
        up: narrow(a.up),
        residual: a.residual,
        first_guess_residual: a.first_guess_residual,
        iterations: a.iterations,
    }
}

/// Trilinear interpolation between cell centres at fractional cell coordinates (clamped to
/// the outermost centres).
fn trilinear(g: &WindGrid, s: &SectorField, fx: f64, fy: f64, fz: f64) -> Vector3<f64> {
    let [nx, ny, nz] = g.dims;
    let split = |f: f64, n: usize| {
        let f = f.clamp(0.0, (n - 1) as f64);
        let i0 = (f.floor() as usize).min(n.saturating_sub(2));
        let t = if n > 1 { f - i0 as f64 } else { 0.0 };
        (i0, (i0 + 1).min(n - 1), t)
    };
    let (i0, i1, tx) = split(fx, nx);
    let (j0, j1, ty) = split(fy, ny);
    let (k0, k1, tz) = split(fz, nz);
    let mut v = Vector3::zeros();
    for (k, wz) in [(k0, 1.0 - tz), (k1, tz)] {
        for (j, wy) in [(j0, 1.0 - ty), (j1, ty)] {
            for (i, wx) in [(i0, 1.0 - tx), (i1, tx)] {
                let w = wx * wy * wz;
                if w == 0.0 {
                    continue;
                }
                let c = g.index(i, j, k);
                v += Vector3::new(f64::from(s.east[c]), f64::from(s.north[c]), f64::from(s.up[c])) * w;
            }
        }
    }
    v
}
