//! How a satellite's signal reaches an antenna among buildings and hills: directly (line
//! of sight), once reflected off a facade (non-line-of-sight, NLOS), or not at all; and how
//! strong it arrives (C/N0).
//!
//! Frames and units: the world's ENU (metres from the run origin, `z` up); `to_sat` is the
//! unit vector from the antenna towards the satellite. A satellite is ~20 000 km away, so
//! its rays over a city are parallel: a reflection's extra path is computed for a source
//! at infinity (error below 1e-4 of the detour).
//!
//! # Model
//! - Line of sight: the ray from the antenna towards the satellite meets no building prism
//!   (the world's grid-walk segment query) and stays above the terrain.
//! - Reflection: only vertical facades (footprint edges between a building's base and roof)
//!   within [`REFLECTION_SEARCH_RADIUS_M`]; a single specular bounce (the image-antenna
//!   method); both legs (antenna to facade, facade to satellite) must be clear. Of several
//!   reflections the shortest detour is received (the earliest, usually strongest).
//!   Roofs, the ground, diffraction round edges and multi-bounce paths are not modelled.
//! - C/N0: an elevation profile of an open-sky antenna (see [`cn0_dbhz`]), minus
//!   [`REFLECTION_LOSS_DB`] for a reflected signal.

use nalgebra::Vector3;
use sadesim_world::World;

/// Facades farther than this from the antenna are not searched for reflections, m. The
/// NLOS signals of urban canyons come off the street's own and the next block's facades;
/// a far facade's reflection also arrives weaker (longer path, more shadowing).
pub const REFLECTION_SEARCH_RADIUS_M: f64 = 150.0;

/// Power lost at a facade, dB. Measured reflection losses of L1 signals off concrete,
/// brick and glass facades lie between ~3 and ~15 dB (Groves, *Principles of GNSS, Inertial
/// and Multisensor Integrated Navigation Systems*, 2nd ed., 2013, §10.1); 8 dB is mid-range.
pub const REFLECTION_LOSS_DB: f64 = 8.0;

/// C/N0 of a line-of-sight signal at the zenith and on the horizon, dB-Hz: a patch antenna
/// of a small drone sees 45–48 dB-Hz overhead and ~35 dB-Hz near the horizon.
pub const CN0_ZENITH_DBHZ: f64 = 47.0;
pub const CN0_HORIZON_DBHZ: f64 = 35.0;

/// Horizontal step of the terrain march, m: below the spacing of the DEMs users bring
/// (SRTM 30 m) so a ridge between samples is not skipped.
const TERRAIN_STEP_M: f64 = 10.0;

/// A facade this close (m) to the antenna is the one the antenna touches, not a reflector.
const MIN_REFLECTOR_DISTANCE_M: f64 = 0.05;

/// Offset from a facade for the rays that leave it, m: a ray starting exactly on the wall
/// would find the wall itself.
const FACADE_OFFSET_M: f64 = 0.02;

/// How one satellite's signal reaches the antenna.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SignalPath {
    /// Directly.
    LineOfSight,
    /// The direct ray is blocked; the signal arrives once reflected off a facade.
    Reflected {
        /// Extra path length over the (blocked) direct path, m: the pseudorange's error.
        excess_m: f64,
        /// Unit vector from the antenna towards the reflection point (where the signal
        /// appears to come from), ENU.
        arrival_enu: Vector3<f64>,
        /// The reflecting building (index into `World::buildings`).
        building: usize,
    },
    /// Neither a direct nor a single-reflection path exists.
    Blocked,
}

impl SignalPath {
    pub fn is_line_of_sight(&self) -> bool {
        matches!(self, SignalPath::LineOfSight)
    }
}

/// The signal path from a satellite in direction `to_sat` (unit, ENU) to the antenna.
pub fn signal_path(world: &World, antenna: &Vector3<f64>, to_sat: &Vector3<f64>) -> SignalPath {
    if line_of_sight(world, antenna, to_sat) {
        return SignalPath::LineOfSight;
    }
    best_reflection(world, antenna, to_sat)
}

/// Whether the ray from `from` towards the satellite (unit `to_sat`, ENU) is clear of
/// buildings and terrain. A satellite at or below the horizon is never in sight.
pub fn line_of_sight(world: &World, from: &Vector3<f64>, to_sat: &Vector3<f64>) -> bool {
    if to_sat.z <= 0.0 {
        return false;
    }
    let (_, roofs_up_m) = world.building_band_up_m();
    if from.z < roofs_up_m {
        // Far enough along the ray to clear the tallest roof (the index walks only the
        // part of the segment inside the buildings' height band and the world square).
        let reach_m = (roofs_up_m - from.z) / to_sat.z + 1.0;
        if world.segment_hits_building(*from, from + to_sat * reach_m).is_some() {
            return false;
        }
    }
    !terrain_blocks(world, from, to_sat)
}

/// Whether the terrain rises above the ray before the ray clears the highest ground of the
/// world square (or leaves the square).
fn terrain_blocks(world: &World, from: &Vector3<f64>, to_sat: &Vector3<f64>) -> bool {
    let ground_max_m = world.stats().ground_max_up_m;
    let horizontal = to_sat.xy().norm();
    if from.z >= ground_max_m || horizontal < 1e-9 {
        return false;
    }
    let extent_m = world.extent_m();
    // Ray parameter per horizontal step.
    let ds = TERRAIN_STEP_M / horizontal;
    let mut s = ds;
    loop {
        let p = from + to_sat * s;
        if p.z >= ground_max_m || p.x.abs() > extent_m || p.y.abs() > extent_m {
            return false;
        }
        if world.ground_up_m(p.x, p.y) > p.z {
            return true;
        }
        s += ds;
    }
}

/// The shortest single-bounce path off a vertical facade near the antenna, else
/// [`SignalPath::Blocked`].
///
/// For a facade with horizontal unit normal `n` facing the antenna at distance `d`, the
/// image of the antenna lies `2 d` behind the wall; the reflected signal travels as if
/// from the satellite straight to the image, so it meets the wall at
/// `P = A - 2 d n + (d / (u·n)) u` and its extra path over the direct one is `2 d (u·n)`.
fn best_reflection(world: &World, antenna: &Vector3<f64>, to_sat: &Vector3<f64>) -> SignalPath {
    let r = REFLECTION_SEARCH_RADIUS_M;
    let candidates = world.buildings_in_rect(&[antenna.x - r, antenna.y - r, antenna.x + r, antenna.y + r]);
    let mut best = SignalPath::Blocked;
    let mut best_excess_m = f64::INFINITY;
    for k in candidates {
        let building = &world.buildings()[k];
        for (p, q) in building.footprint().edges() {
            let edge = Vector3::new(q[0] - p[0], q[1] - p[1], 0.0);
            let len2 = edge.norm_squared();
            if len2 < 1e-6 {
                continue;
            }
            let len = len2.sqrt();
            let mut n = Vector3::new(-edge.y / len, edge.x / len, 0.0);
            let rel = Vector3::new(antenna.x - p[0], antenna.y - p[1], 0.0);
            let mut d = rel.dot(&n);
            if d < 0.0 {
                n = -n;
                d = -d;
            }
            let un = to_sat.dot(&n);
            // The satellite must shine on the face the antenna sees.
            if !(MIN_REFLECTOR_DISTANCE_M..=r).contains(&d) || un <= 1e-6 {
                continue;
            }
            let excess_m = 2.0 * d * un;
            if excess_m >= best_excess_m {
                continue;
            }
            let hit = antenna - n * (2.0 * d) + to_sat * (d / un);
            let along = (hit - Vector3::new(p[0], p[1], 0.0)).dot(&edge) / len2;
            if !(0.0..=1.0).contains(&along)
                || hit.z < building.base_up_m()
                || hit.z > building.roof_up_m()
                || hit.z < world.ground_up_m(hit.x, hit.y)
            {
                continue;
            }
            let off_wall = hit + n * FACADE_OFFSET_M;
            if world.segment_hits_building(*antenna, off_wall).is_some() || !line_of_sight(world, &off_wall, to_sat) {
                continue;
            }
            best_excess_m = excess_m;
            best = SignalPath::Reflected { excess_m, arrival_enu: (hit - antenna).normalize(), building: k };
        }
    }
    best
}

/// Carrier-to-noise density of a signal, dB-Hz: linear in the sine of the elevation
/// between [`CN0_HORIZON_DBHZ`] and [`CN0_ZENITH_DBHZ`] (the shape of an open-sky
/// receiver's C/N0 against elevation), [`REFLECTION_LOSS_DB`] less when reflected;
/// `None` when blocked.
pub fn cn0_dbhz(elevation_deg: f64, path: &SignalPath) -> Option<f64> {
    let los = CN0_HORIZON_DBHZ + (CN0_ZENITH_DBHZ - CN0_HORIZON_DBHZ) * elevation_deg.to_radians().sin().max(0.0);
    match path {
        SignalPath::LineOfSight => Some(los),
        SignalPath::Reflected { .. } => Some(los - REFLECTION_LOSS_DB),
        SignalPath::Blocked => None,
    }
}

#[cfg(test)]
mod tests;
