//! The wind grid: cubic cells over the world square, aligned with the run's ENU axes, from
//! the lowest ground up to a height above the tallest roof. A cell is *solid* when its
//! centre is inside a building or below the ground; the wind is zero there.

use sadesim_world::World;

/// Cell `(i, j, k)` (east, north, up) is at `k * ny * nx + j * nx + i` in every per-cell array.
#[derive(Clone, Debug, PartialEq)]
pub struct WindGrid {
    /// ENU of the corner of cell (0, 0, 0): its lowest east, north and up, metres.
    pub corner_m: [f64; 3],
    /// Edge of a cell, metres (the same along the three axes).
    pub spacing_m: f64,
    /// Cells along east, north, up.
    pub dims: [usize; 3],
    /// Per cell: inside a building or below the ground.
    pub solid: Vec<bool>,
    /// Per column `(i, j)` at `j * nx + i`: the ground's ENU up at its centre, metres.
    pub ground_up_m: Vec<f64>,
}

/// How the grid is laid over a world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// Cell edge, metres.
    pub spacing_m: f64,
    /// The grid reaches this far above the tallest building's base, as a multiple of its
    /// height (at least [`MIN_TOP_M`]): the wakes and the flow over the roofs die out by
    /// about twice a building's height, and above the grid the wind is the plain profile.
    pub top_factor: f64,
}

/// Default cell edge, metres: a 20 m street gets four cells across.
pub const DEFAULT_SPACING_M: f64 = 5.0;
/// At most this many cells along east or north by default: a large world gets a coarser
/// grid instead of one that does not fit in memory ([`GridSpec::default_for`]).
pub const MAX_DEFAULT_CELLS_ACROSS: f64 = 200.0;
/// The grid's top is at least this far above the lowest ground, metres.
pub const MIN_TOP_M: f64 = 40.0;

impl GridSpec {
    /// The default for a world of half-width `extent_m`: [`DEFAULT_SPACING_M`], coarser when
    /// the square would be more than [`MAX_DEFAULT_CELLS_ACROSS`] cells across (an 8 km
    /// square gets 40 m cells); the top at twice the tallest building.
    pub fn default_for(extent_m: f64) -> Self {
        let spacing_m = DEFAULT_SPACING_M.max((2.0 * extent_m / MAX_DEFAULT_CELLS_ACROSS).ceil());
        Self { spacing_m, top_factor: 2.0 }
    }
}

impl WindGrid {
    /// The grid over `world`'s square.
    pub fn over(world: &World, spec: GridSpec) -> Self {
        let h = spec.spacing_m;
        let extent = world.extent_m();
        let n_across = ((2.0 * extent) / h).ceil().max(1.0) as usize;
        let corner_en = -(n_across as f64) * h / 2.0;
        let mut ground_up_m = Vec::with_capacity(n_across * n_across);
        for j in 0..n_across {
            for i in 0..n_across {
                let (e, n) = (corner_en + (i as f64 + 0.5) * h, corner_en + (j as f64 + 0.5) * h);
                ground_up_m.push(world.ground_up_m(e, n));
            }
        }
        let lowest = ground_up_m.iter().copied().fold(f64::INFINITY, f64::min);
        let corner_up = (lowest / h).floor() * h;
        let tallest = world.buildings().iter().map(|b| b.roof_up_m() - corner_up).fold(0.0, f64::max);
        let highest_ground = ground_up_m.iter().copied().fold(f64::NEG_INFINITY, f64::max) - corner_up;
        let top = (tallest * spec.top_factor).max(MIN_TOP_M).max(highest_ground + MIN_TOP_M);
        let nz = (top / h).ceil() as usize;
        let dims = [n_across, n_across, nz];
        let mut grid =
            Self { corner_m: [corner_en, corner_en, corner_up], spacing_m: h, dims, solid: Vec::new(), ground_up_m };
        grid.solid = grid.voxelise(world);
        grid
    }

    /// Solid cells: below the ground at the column's centre, or inside a building (its
    /// footprint holds the column's centre and the cell's centre is between base and roof).
    fn voxelise(&self, world: &World) -> Vec<bool> {
        let [nx, ny, nz] = self.dims;
        let h = self.spacing_m;
        let mut solid = vec![false; nx * ny * nz];
        for j in 0..ny {
            for i in 0..nx {
                let [e, n, _] = self.centre(i, j, 0);
                let ground = self.ground_up_m[j * nx + i];
                let near = world.buildings_in_rect(&[e, n, e, n]);
                for k in 0..nz {
                    let up = self.corner_m[2] + (k as f64 + 0.5) * h;
                    let inside = up < ground
                        || near.iter().any(|&b| {
                            let b = &world.buildings()[b];
                            up >= b.base_up_m() && up <= b.roof_up_m() && b.footprint_contains(e, n)
                        });
                    solid[self.index(i, j, k)] = inside;
                }
            }
        }
        solid
    }

    pub fn cells(&self) -> usize {
        self.dims.iter().product()
    }

    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    /// ENU of the centre of cell `(i, j, k)`, metres.
    pub fn centre(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        let h = self.spacing_m;
        [
            self.corner_m[0] + (i as f64 + 0.5) * h,
            self.corner_m[1] + (j as f64 + 0.5) * h,
            self.corner_m[2] + (k as f64 + 0.5) * h,
        ]
    }

    /// Height of cell `(i, j, k)`'s centre above the ground of its column, metres.
    pub fn height_agl_m(&self, i: usize, j: usize, k: usize) -> f64 {
        self.centre(i, j, k)[2] - self.ground_up_m[j * self.dims[0] + i]
    }

    /// ENU up of the grid's top, metres: above it the wind is the plain profile.
    pub fn top_up_m(&self) -> f64 {
        self.corner_m[2] + self.dims[2] as f64 * self.spacing_m
    }
}
