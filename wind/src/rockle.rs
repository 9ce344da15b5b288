//! The first guess of the diagnostic model, after Röckle (1990) as urban dispersion codes
//! use it (QUIC-URB: Pardyjak & Brown 2003; Singh et al. 2008): the undisturbed log profile,
//! then, per building, empirical zones where the streamwise wind is replaced:
//!
//! - **upwind displacement** (the front eddy): an ellipsoid of length
//!   `L_F = 2 W / (1 + 0.8 W / H)` and height `0.6 H` before the upwind face, wind 0;
//! - **cavity** (near wake): an ellipsoid of length
//!   `L_R = 1.8 W / ((L / H)^0.3 (1 + 0.24 W / H))` (Fackrell 1984), height `H` and the
//!   building's width behind the downwind face, reversed flow
//!   `u = -u_H (1 - d / d_c)^2` where `d` is the distance behind the face and `d_c` the
//!   cavity's length at that height and offset;
//! - **far wake**: out to three cavity lengths, the deficit `u = u0(z) (1 - (d_c / d)^1.5)`;
//! - **rooftop recirculation** (Wilson 1979's scaling, as QUIC-URB uses it): the flow
//!   separates at the roof's upwind edge into a bubble of length `L_c = 0.9 R` and height
//!   `H_c = 0.22 R` over the roof, `R = B_s^(2/3) B_l^(1/3)` (`B_s`, `B_l` the smaller and
//!   larger of `H` and `W`), cut off where the roof ends; inside, reversed flow
//!   `u = -u_H (1 - Δz / z_c(x)) / 2`, `Δz` the height over the roof and `z_c(x)` the
//!   bubble's height at `x` from the edge (an ellipse).
//!
//! `L` is the building's length along the wind, `W` its width across it and `H` its height
//! (the extent of its footprint projected on the wind's axes: an oblique or irregular
//! building is its bounding rectangle in the wind frame). Where zones of several buildings
//! overlap the lowest streamwise wind wins (a cavity inside another's wake stays a
//! cavity), so the guess does not depend on the order of the buildings.
//!
//! - **street canyon** (Röckle 1990's vortex with Singh et al. 2008's criterion, as
//!   QUIC-URB and QES-Winds apply it): where another building's facade stands across the
//!   wind less than the cavity length `L_R` behind a building's downwind face (skimming
//!   flow), the cells between them below both roofs hold a vortex instead of the cavity:
//!   `u = -u_H (x / (S/2)) ((S - x) / (S/2))` along the wind and
//!   `w = -u_H |(1 - x / (S/2)) / 2| (1 - (S - x) / (S/2))` upward, `x` the distance from
//!   the upwind building's back wall and `S` the gap at that cell (found by marching
//!   downwind through the grid at the cell's height, so a lower downwind building gives a
//!   canyon only up to its roof). The air rises along the upwind building's back wall,
//!   returns against the wind near the street and sinks along the downwind facade. Where
//!   canyons of several buildings claim a cell the one of the nearest back wall wins.
//!
//! The guess is not mass-consistent; [`crate::solver`] makes it so.

use sadesim_world::World;

use crate::grid::WindGrid;
use crate::profile::LogProfile;

/// Unit vectors of the wind frame in ENU (east, north): `downwind` where the air goes,
/// `across` 90° to its left.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindAxes {
    pub downwind: [f64; 2],
    pub across: [f64; 2],
}

impl WindAxes {
    /// For a wind blowing *from* `direction_from_deg` (clockwise from north): from 270°
    /// (west) it blows toward +east.
    pub fn from_deg(direction_from_deg: f64) -> Self {
        let t = direction_from_deg.to_radians();
        let downwind = [-t.sin(), -t.cos()];
        Self { downwind, across: [-downwind[1], downwind[0]] }
    }

    /// `(s, t)`: metres along the wind and across it.
    fn project(&self, e: f64, n: f64) -> (f64, f64) {
        (e * self.downwind[0] + n * self.downwind[1], e * self.across[0] + n * self.across[1])
    }
}

/// One building in the wind frame.
#[derive(Clone, Copy, Debug)]
struct Obstacle {
    /// Upwind and downwind faces, metres along the wind.
    s_front: f64,
    s_back: f64,
    /// Centre and half-width across the wind, metres.
    t_centre: f64,
    half_width: f64,
    base_up_m: f64,
    height_m: f64,
}

impl Obstacle {
    fn length_m(&self) -> f64 {
        self.s_back - self.s_front
    }

    fn width_m(&self) -> f64 {
        2.0 * self.half_width
    }

    /// Front-eddy length `L_F`, metres.
    fn front_length_m(&self) -> f64 {
        let (w, h) = (self.width_m(), self.height_m);
        2.0 * w / (1.0 + 0.8 * w / h)
    }

    /// Rooftop bubble length `L_c` and height `H_c`, metres (Wilson 1979).
    fn rooftop_m(&self) -> (f64, f64) {
        let (w, h) = (self.width_m(), self.height_m);
        let r = w.min(h).powf(2.0 / 3.0) * w.max(h).powf(1.0 / 3.0);
        (0.9 * r, 0.22 * r)
    }

    /// Cavity length `L_R`, metres (Fackrell 1984, as Röckle and QUIC use it).
    fn cavity_length_m(&self) -> f64 {
        let (l, w, h) = (self.length_m().max(1e-3), self.width_m(), self.height_m);
        1.8 * w / ((l / h).powf(0.3) * (1.0 + 0.24 * w / h))
    }
}

/// The first guess for one wind direction, per cell (0 in solid cells).
#[derive(Clone, Debug, PartialEq)]
pub struct FirstGuess {
    /// Along the wind (multiply by the axes' `downwind` for east and north), as a factor of
    /// the reference wind.
    pub streamwise: Vec<f64>,
    /// Upward, the same factor: zero but in street canyons.
    pub up: Vec<f64>,
}

/// The first guess for one wind direction: the log profile, with each building's zones
/// applied, then the street-canyon vortices.
pub fn first_guess(world: &World, grid: &WindGrid, axes: WindAxes, profile: &LogProfile) -> FirstGuess {
    let [nx, ny, nz] = grid.dims;
    let mut u = vec![0.0; grid.cells()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = grid.index(i, j, k);
                if !grid.solid[c] {
                    u[c] = profile.factor(grid.height_agl_m(i, j, k));
                }
            }
        }
    }
    let obstacles: Vec<Obstacle> = world.buildings().iter().map(|b| Obstacle::of(b, axes)).collect();
    for o in &obstacles {
        apply_zones(grid, axes, profile, o, &mut u);
    }
    let mut canyon = Canyons { up: vec![0.0; grid.cells()], back_wall_m: vec![f64::INFINITY; grid.cells()] };
    for o in &obstacles {
        apply_canyon(grid, axes, profile, o, &mut u, &mut canyon);
    }
    FirstGuess { streamwise: u, up: canyon.up }
}

impl Obstacle {
    /// A building's bounding rectangle in the wind frame.
    fn of(b: &sadesim_world::Building, axes: WindAxes) -> Self {
        let (mut s0, mut s1, mut t0, mut t1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for [e, n] in b.footprint().outer() {
            let (s, t) = axes.project(*e, *n);
            (s0, s1, t0, t1) = (s0.min(s), s1.max(s), t0.min(t), t1.max(t));
        }
        Obstacle {
            s_front: s0,
            s_back: s1,
            t_centre: (t0 + t1) / 2.0,
            half_width: (t1 - t0) / 2.0,
            base_up_m: b.base_up_m(),
            height_m: b.height_m(),
        }
    }
}

/// The street-canyon pass's state: the vertical first guess, and per cell the distance
/// from the back wall of the canyon that set it (the nearest wins).
struct Canyons {
    up: Vec<f64>,
    back_wall_m: Vec<f64>,
}

/// The grid cells of a rectangle in the wind frame (`s` along, `t` across), as index
/// ranges `(i0..i1, j0..j1)` of the rectangle's bounds in ENU.
fn cells_of(grid: &WindGrid, axes: WindAxes, (s_lo, s_hi): (f64, f64), (t_lo, t_hi): (f64, f64)) -> [usize; 4] {
    let mut box_en = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for (s, t) in [(s_lo, t_lo), (s_lo, t_hi), (s_hi, t_lo), (s_hi, t_hi)] {
        let e = s * axes.downwind[0] + t * axes.across[0];
        let n = s * axes.downwind[1] + t * axes.across[1];
        box_en = [box_en[0].min(e), box_en[1].min(n), box_en[2].max(e), box_en[3].max(n)];
    }
    let [nx, ny, _] = grid.dims;
    let (i0, i1) = (grid_cell(grid, box_en[0], 0, nx), grid_cell(grid, box_en[2], 0, nx - 1) + 1);
    let (j0, j1) = (grid_cell(grid, box_en[1], 1, ny), grid_cell(grid, box_en[3], 1, ny - 1) + 1);
    [i0, i1, j0, j1]
}

/// The cell index along `axis` holding coordinate `v` (metres), clamped to `0..=max`.
fn grid_cell(grid: &WindGrid, v: f64, axis: usize, max: usize) -> usize {
    (((v - grid.corner_m[axis]) / grid.spacing_m).floor().max(0.0) as usize).min(max)
}

/// Visits the fluid cells of columns `[i0, i1, j0, j1]` (from [`cells_of`]) and levels
/// `k0..k1`, in index order, with the cell's index into the grid's arrays, its `[i, j, k]`,
/// its centre (ENU, metres) and the centre projected on the wind's axes `(s, t)`.
fn each_fluid_cell(
    grid: &WindGrid,
    axes: WindAxes,
    [i0, i1, j0, j1]: [usize; 4],
    (k0, k1): (usize, usize),
    mut visit: impl FnMut(usize, [usize; 3], [f64; 3], (f64, f64)),
) {
    for k in k0..k1 {
        for j in j0..j1 {
            for i in i0..i1 {
                let c = grid.index(i, j, k);
                if !grid.solid[c] {
                    let centre = grid.centre(i, j, k);
                    visit(c, [i, j, k], centre, axes.project(centre[0], centre[1]));
                }
            }
        }
    }
}

/// Puts the street-canyon vortex in the cells behind `o` where another building's facade
/// closes the gap within the cavity length (see the module's notes).
fn apply_canyon(
    grid: &WindGrid,
    axes: WindAxes,
    profile: &LogProfile,
    o: &Obstacle,
    u: &mut [f64],
    canyon: &mut Canyons,
) {
    if o.half_width <= 0.0 || o.height_m <= 0.0 {
        return;
    }
    let lr = o.cavity_length_m();
    let u_roof = profile.factor(o.height_m);
    let h = grid.spacing_m;
    let [nx, ny, nz] = grid.dims;
    let columns =
        cells_of(grid, axes, (o.s_back, o.s_back + lr), (o.t_centre - o.half_width, o.t_centre + o.half_width));
    let k0 = grid_cell(grid, o.base_up_m, 2, nz);
    let k1 = grid_cell(grid, o.base_up_m + o.height_m, 2, nz - 1) + 1;
    // A building cell (not ground) at the column of point (e, n) and level k, if in the grid.
    let building_at = |e: f64, n: f64, k: usize| -> Option<bool> {
        let (fi, fj) = ((e - grid.corner_m[0]) / h, (n - grid.corner_m[1]) / h);
        if fi < 0.0 || fj < 0.0 || fi >= nx as f64 || fj >= ny as f64 {
            return None;
        }
        let (i, j) = (fi as usize, fj as usize);
        let up = grid.corner_m[2] + (k as f64 + 0.5) * h;
        Some(grid.solid[grid.index(i, j, k)] && up >= grid.ground_up_m[j * nx + i])
    };
    each_fluid_cell(grid, axes, columns, (k0, k1), |c, [_, _, k], [e, n, up], (s, t)| {
        let (x, z) = (s - o.s_back, (up - o.base_up_m) / o.height_m);
        if x <= 0.0 || x > lr || z <= 0.0 || z > 1.0 || (t - o.t_centre).abs() > o.half_width {
            return;
        }
        // A nearer back wall's canyon already holds the cell: no need to march.
        if x >= canyon.back_wall_m[c] {
            return;
        }
        // March downwind at this level, half a cell a step, for the next facade.
        let mut r = 0.5 * h;
        let gap = loop {
            if x + r > lr {
                break None;
            }
            match building_at(e + r * axes.downwind[0], n + r * axes.downwind[1], k) {
                None => break None,
                Some(true) => break Some(x + r),
                Some(false) => r += 0.5 * h,
            }
        };
        let Some(gap) = gap else { return };
        let half = 0.5 * gap;
        canyon.back_wall_m[c] = x;
        u[c] = -u_roof * (x / half) * ((gap - x) / half);
        canyon.up[c] = -u_roof * (0.5 * (1.0 - x / half)).abs() * (1.0 - (gap - x) / half);
    });
}

/// Lowers `u` in the obstacle's front eddy, cavity and far wake.
fn apply_zones(grid: &WindGrid, axes: WindAxes, profile: &LogProfile, o: &Obstacle, u: &mut [f64]) {
    if o.half_width <= 0.0 || o.height_m <= 0.0 {
        return;
    }
    let (lf, lr) = (o.front_length_m(), o.cavity_length_m());
    // Wind at roof height over the building's ground, the cavity's return flow scale.
    let u_roof = profile.factor(o.height_m);
    let columns = cells_of(
        grid,
        axes,
        (o.s_front - lf, o.s_back + 3.0 * lr),
        (o.t_centre - o.half_width, o.t_centre + o.half_width),
    );
    let nz = grid.dims[2];
    let (lc, hc) = o.rooftop_m();
    let k1 = grid_cell(grid, o.base_up_m + o.height_m + hc, 2, nz - 1) + 1;
    let k0 = grid_cell(grid, o.base_up_m, 2, nz);
    each_fluid_cell(grid, axes, columns, (k0, k1), |c, [i, j, k], [_, _, up], (s, t)| {
        let z = (up - o.base_up_m) / o.height_m;
        let y = (t - o.t_centre) / o.half_width;
        if z < 0.0 || y.abs() > 1.0 {
            return;
        }
        let guess = if z > 1.0 {
            // Over the roof: the bubble from the upwind edge, within the roof.
            let (x, dz) = (s - o.s_front, up - o.base_up_m - o.height_m);
            let half = lc / 2.0;
            let z_c = hc * (1.0 - ((x - half) / half).powi(2)).max(0.0).sqrt();
            if s <= o.s_back && x >= 0.0 && dz < z_c { Some(-0.5 * u_roof * (1.0 - dz / z_c)) } else { None }
        } else if s < o.s_front {
            // The front eddy: an ellipsoid 0.6 H high.
            let zf = z / 0.6;
            let reach = lf * ((1.0 - zf * zf).max(0.0) * (1.0 - y * y)).sqrt();
            if o.s_front - s <= reach { Some(0.0) } else { None }
        } else if s > o.s_back {
            let d = s - o.s_back;
            let d_c = lr * ((1.0 - z * z) * (1.0 - y * y)).sqrt();
            if d <= d_c {
                let r = 1.0 - d / d_c;
                Some(-u_roof * r * r)
            } else if d <= 3.0 * d_c {
                Some(profile.factor(grid.height_agl_m(i, j, k)) * (1.0 - (d_c / d).powf(1.5)))
            } else {
                None
            }
        } else {
            None
        };
        if let Some(g) = guess {
            u[c] = u[c].min(g);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wind_axes_point_where_the_air_goes() {
        let west = WindAxes::from_deg(270.0);
        assert!((west.downwind[0] - 1.0).abs() < 1e-12 && west.downwind[1].abs() < 1e-12);
        // 90° left of an eastward wind is north.
        assert!((west.across[1] - 1.0).abs() < 1e-12);
        let north = WindAxes::from_deg(0.0);
        assert!((north.downwind[1] + 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_cube_has_the_published_zone_lengths() {
        let cube =
            Obstacle { s_front: 0.0, s_back: 10.0, t_centre: 0.0, half_width: 5.0, base_up_m: 0.0, height_m: 10.0 };
        // L_F = 2 W / 1.8 = 1.11 H; L_R = 1.8 / 1.24 = 1.45 H.
        assert!((cube.front_length_m() - 100.0 / 9.0).abs() < 1e-9);
        assert!((cube.cavity_length_m() - 18.0 / 1.24).abs() < 1e-9);
        // A long building (L = 4 H) has a shorter cavity, a wide one (W = 4 H) a longer.
        let long = Obstacle { s_back: 40.0, ..cube };
        let wide = Obstacle { half_width: 20.0, ..cube };
        assert!(long.cavity_length_m() < cube.cavity_length_m());
        assert!(wide.cavity_length_m() > cube.cavity_length_m());
        // Rooftop bubble of a cube: R = H, so 0.9 H long and 0.22 H high.
        let (lc, hc) = cube.rooftop_m();
        assert!((lc - 9.0).abs() < 1e-9 && (hc - 2.2).abs() < 1e-9);
    }
}
