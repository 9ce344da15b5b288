//! The sky grid (the paper's voxel grid): for every voxel of the world square and every
//! time slice, what the ranging receiver would see from the voxel's centre: satellites in
//! line of sight, satellites received only by a facade reflection, and the HDOP of those it
//! would use. Precomputed for users to inspect (where a city's canyons are, when the sky is
//! poor); the receiver itself casts its rays live (docs/performance.md measures both).
//!
//! Layout: arrays of `[slice, z, y, x]` in C order (x fastest); voxel `(k, j, i)` is centred
//! at east `x0 + (i + ½)·spacing`, north `y0 + (j + ½)·spacing`, up `z0 + (k + ½)·spacing`
//! (run ENU, metres); slice `s` is the sky at sim time `s · slice_s`.

use nalgebra::Vector3;
use sadesim_world::World;

use crate::dop::Dop;
use crate::receiver::TRACKING_THRESHOLD_DBHZ;
use crate::run_sky::RunSky;
use crate::signal::{SignalPath, cn0_dbhz, signal_path};

/// What to grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// Voxel edge, m.
    pub spacing_m: f64,
    /// Sim seconds between time slices.
    pub slice_s: f64,
    /// Time slices (at 0, slice_s, ...).
    pub slices: usize,
    /// Height of the grid's top above the world's lowest ground, m.
    pub top_m: f64,
}

/// The grid's values and where its voxels are.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyGrid {
    pub spec: GridSpec,
    /// Corner of voxel (0, 0, 0): east, north, up, m.
    pub origin_m: [f64; 3],
    /// Voxels along x (east), y (north), z (up).
    pub dims: [usize; 3],
    /// Per voxel, 1 inside a building or below the ground (its values are 0 / NaN).
    pub solid: Vec<u8>,
    /// Per slice and voxel: satellites above the mask in line of sight.
    pub line_of_sight: Vec<u8>,
    /// Per slice and voxel: satellites above the mask received only by a reflection.
    pub reflected: Vec<u8>,
    /// Per slice and voxel: HDOP of the satellites strong enough to use (NaN with fewer
    /// than four, or in a solid voxel).
    pub hdop: Vec<f32>,
}

impl SkyGrid {
    /// Voxels per slice.
    pub fn voxels(&self) -> usize {
        self.dims.iter().product()
    }

    /// The centre of voxel `(i, j, k)`, ENU m.
    pub fn centre(&self, i: usize, j: usize, k: usize) -> Vector3<f64> {
        let h = self.spec.spacing_m;
        let [x0, y0, z0] = self.origin_m;
        Vector3::new(x0 + (i as f64 + 0.5) * h, y0 + (j as f64 + 0.5) * h, z0 + (k as f64 + 0.5) * h)
    }
}

/// Computes the grid over `world`'s square under `sky`; `progress(done, total)` is called
/// after each horizontal layer of each slice.
pub fn compute(world: &World, sky: &RunSky, spec: GridSpec, mut progress: impl FnMut(usize, usize)) -> SkyGrid {
    let h = spec.spacing_m.max(0.5);
    let extent = world.extent_m();
    let n = ((2.0 * extent) / h).ceil().max(1.0) as usize;
    let z0 = world.stats().ground_min_up_m;
    let nz = (spec.top_m / h).ceil().max(1.0) as usize;
    let mut grid = SkyGrid {
        spec,
        origin_m: [-extent, -extent, z0],
        dims: [n, n, nz],
        solid: Vec::new(),
        line_of_sight: Vec::new(),
        reflected: Vec::new(),
        hdop: Vec::new(),
    };
    let voxels = grid.voxels();
    grid.solid = (0..voxels)
        .map(|v| {
            let c = grid.centre(v % n, (v / n) % n, v / (n * n));
            u8::from(world.is_inside_building(c) || c.z < world.ground_up_m(c.x, c.y))
        })
        .collect();
    let mask_sin = sky.mask_deg().to_radians().sin();
    let total = spec.slices * nz;
    for s in 0..spec.slices {
        let states = sky.at(s as f64 * spec.slice_s);
        for k in 0..nz {
            for v in k * n * n..(k + 1) * n * n {
                if grid.solid[v] == 1 {
                    grid.line_of_sight.push(0);
                    grid.reflected.push(0);
                    grid.hdop.push(f32::NAN);
                    continue;
                }
                let c = grid.centre(v % n, (v / n) % n, k);
                let (mut los, mut reflected, mut units) = (0u8, 0u8, Vec::new());
                for st in states.iter() {
                    let u = (st.position_enu_m - c).normalize();
                    if u.z < mask_sin {
                        continue;
                    }
                    let path = signal_path(world, &c, &u);
                    match path {
                        SignalPath::LineOfSight => los = los.saturating_add(1),
                        SignalPath::Reflected { .. } => reflected = reflected.saturating_add(1),
                        SignalPath::Blocked => continue,
                    }
                    if cn0_dbhz(u.z.asin().to_degrees(), &path).is_some_and(|c| c >= TRACKING_THRESHOLD_DBHZ) {
                        units.push([u.x, u.y, u.z]);
                    }
                }
                grid.line_of_sight.push(los);
                grid.reflected.push(reflected);
                grid.hdop.push(Dop::of(&units).map_or(f32::NAN, |d| d.hdop as f32));
            }
            progress(s * nz + k + 1, total);
        }
    }
    grid
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use sadesim_crds::geo::GeoPoint;
    use sadesim_world::{Building, Footprint};

    use super::*;
    use crate::orbits::Constellation;

    #[test]
    fn voxels_agree_with_the_live_signal_paths_and_buildings_are_solid() {
        let c = Constellation::from_tle(&crate::synthetic::walker_gps_galileo_tle()).unwrap();
        let epoch = c.newest_epoch_unix_s();
        let sky = Arc::new(RunSky::new(c, GeoPoint::new(60.17, 24.94, 10.0), epoch, 10.0));
        let slab = |e0: f64, e1: f64| {
            let square = vec![[e0, -100.0], [e1, -100.0], [e1, 100.0], [e0, 100.0]];
            Building::new(Footprint::new(square, vec![]).unwrap(), 0.0, 60.0).unwrap()
        };
        let world = World::of_buildings(100.0, vec![slab(-60.0, -10.0), slab(10.0, 60.0)]);
        let spec = GridSpec { spacing_m: 20.0, slice_s: 600.0, slices: 2, top_m: 80.0 };
        let mut calls = 0;
        let grid = compute(&world, &sky, spec, |done, total| {
            calls += 1;
            assert!(done <= total);
        });
        assert_eq!(grid.dims, [10, 10, 4]);
        assert_eq!(calls, 8, "a call per layer per slice");
        assert_eq!(grid.line_of_sight.len(), 2 * 400);
        // (i, j, k) = (5, 5, 0): the street's middle 10 m up; (2, 5, 0) inside the west slab.
        let v = |i: usize, j: usize, k: usize| k * 100 + j * 10 + i;
        assert_eq!(grid.solid[v(2, 5, 0)], 1);
        assert!(grid.hdop[v(2, 5, 0)].is_nan());
        for (s, (i, j, k)) in [(0, (5, 5, 0)), (1, (5, 5, 1)), (0, (0, 9, 3)), (1, (8, 1, 2))] {
            let c = grid.centre(i, j, k);
            let (mut los, mut refl) = (0, 0);
            for st in sky.at(s as f64 * 600.0).iter() {
                let u = (st.position_enu_m - c).normalize();
                if u.z >= 10f64.to_radians().sin() {
                    match signal_path(&world, &c, &u) {
                        SignalPath::LineOfSight => los += 1,
                        SignalPath::Reflected { .. } => refl += 1,
                        SignalPath::Blocked => {}
                    }
                }
            }
            let at = s * 400 + v(i, j, k);
            assert_eq!((grid.line_of_sight[at], grid.reflected[at]), (los, refl), "voxel {i},{j},{k} slice {s}");
        }
        let open = grid.line_of_sight[v(0, 9, 3)];
        let street = grid.line_of_sight[v(5, 5, 0)];
        assert!(street < open, "the street's floor sees less sky ({street}) than above the roofs ({open})");
    }
}
