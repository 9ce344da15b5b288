//! A single-frequency (L1) code receiver: pseudoranges and range rates to the satellites
//! whose signals reach the antenna strongly enough, and the weighted least-squares position,
//! velocity and clock solution a receiver computes from them.
//!
//! The errors are the measurement's, so the fix's error *emerges* from the geometry:
//! - code noise from the signal's C/N0 (the SIGMA-ε form, σ² = C · 10^(−C/N0 / 10),
//!   Hartinger & Brunner 1999), with `C` chosen so that an open-sky fix matches the u-blox
//!   M8/M9 figures of the statistical receiver (~0.5 m horizontal, 1-sigma per axis);
//! - a slowly varying multipath term per satellite (first-order Gauss–Markov, τ = 30 s),
//!   larger at low elevation and for reflected signals;
//! - a reflected (NLOS) signal's extra path, whole: the receiver cannot tell it from a
//!   direct one, so it pulls the solution away from the truth;
//! - a receiver clock bias and drift, estimated with the position (they do not reach the
//!   fix, as in a real receiver).
//!
//! Not modelled: ionosphere and troposphere residuals after broadcast corrections (~1 m,
//! common to nearby receivers), satellite clock and orbit errors, carrier smoothing, RAIM
//! (fault exclusion) and one clock per constellation (one clock for all systems).

use std::sync::Arc;

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};
use sadesim_crds::random::{Purpose, Rng};
use sadesim_world::World;

use crate::dop::Dop;
use crate::run_sky::RunSky;
use crate::signal::{SignalPath, cn0_dbhz, signal_path};

/// Signals weaker than this are not used in the solution, dB-Hz (a receiver's tracking
/// and navigation threshold; u-blox M8 tracks down to ~15 dB-Hz but weights or drops
/// measurements below ~25 dB-Hz).
pub const TRACKING_THRESHOLD_DBHZ: f64 = 25.0;

/// SIGMA-ε constant of the code noise, m²·Hz: 47 dB-Hz (the zenith) gives 0.45 m, 37 dB-Hz
/// (a low satellite) 1.4 m, 29 dB-Hz (a low reflection) 3.5 m.
pub const SIGMA_EPSILON_M2HZ: f64 = 10_000.0;

/// Range-rate (Doppler) noise at 47 dB-Hz, m/s; scales with the code noise.
pub const RANGE_RATE_SIGMA_MPS: f64 = 0.04;

/// Correlation time of the multipath term, s: a drone moves metres in it and the
/// reflection geometry of a street changes over tens of seconds.
pub const MULTIPATH_TAU_S: f64 = 30.0;

/// Multipath 1-sigma of a direct signal at the horizon (falls to 0 at the zenith), m; and of
/// a reflected signal (its own fading, on top of its detour), m.
pub const MULTIPATH_LOS_HORIZON_M: f64 = 0.3;
pub const MULTIPATH_REFLECTED_M: f64 = 1.0;

/// Fixes with a PDOP (HDOP for a 2D fix) above this are not output (u-blox's default
/// navigation mask, `pDop` 25): four satellites all along a street's axis solve for a
/// position hundreds of metres off.
pub const MAX_DOP: f64 = 25.0;

/// Least-squares iterations and the step (m) below which the solution has converged.
const MAX_ITERATIONS: usize = 10;
const CONVERGED_M: f64 = 1e-4;

/// A solution farther than this from the first guess is a divergence, m.
const MAX_STEP_FROM_GUESS_M: f64 = 100_000.0;

/// The 1-sigma code noise of a signal of `cn0` dB-Hz, m.
pub fn code_sigma_m(cn0_dbhz: f64) -> f64 {
    (SIGMA_EPSILON_M2HZ * 10f64.powf(-cn0_dbhz / 10.0)).sqrt()
}

/// One satellite's measurement at one epoch, with what the receiver knows of it (the
/// satellite's broadcast position and velocity, the signal's C/N0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    pub satellite_enu_m: Vector3<f64>,
    pub satellite_velocity_enu_mps: Vector3<f64>,
    /// Measured pseudorange, m (range plus clock bias plus errors).
    pub pseudorange_m: f64,
    /// Measured range rate, m/s.
    pub range_rate_mps: f64,
    /// The receiver's own 1-sigma for the pseudorange and range rate (from C/N0).
    pub sigma_m: f64,
    pub rate_sigma_mps: f64,
}

/// A least-squares fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution {
    pub position_enu_m: Vector3<f64>,
    pub velocity_enu_mps: Vector3<f64>,
    /// Receiver clock bias, m (c × seconds).
    pub clock_bias_m: f64,
    /// DOP of the satellites used (unweighted, as receivers report it). For a 2D fix:
    /// HDOP of the horizontal solution, VDOP and PDOP infinite.
    pub dop: Dop,
    /// 1-sigma of the weighted solution, horizontal (root sum of east and north variances)
    /// and vertical, m (what a receiver reports as EPH/EPV): the formal covariance scaled by
    /// the a-posteriori variance factor when there are more satellites than unknowns and
    /// the residuals are larger than the C/N0 model expects (a reflected signal's detour
    /// shows in them), as receivers' accuracy estimates grow in street canyons.
    pub eph_m: f64,
    pub epv_m: f64,
    /// 1-sigma of each velocity component, m/s (a receiver's sAcc), from the range rates'
    /// covariance and their own a-posteriori factor: a reflected signal's Doppler is the
    /// wall's geometry's, not the satellite's, and shows in the residuals while moving.
    pub velocity_sigma_mps: f64,
    pub satellites_used: u8,
    /// False for a 2D fix: the height was held at the previous fix's.
    pub three_d: bool,
}

/// Solves position, clock bias, velocity and clock drift from `measurements` by weighted
/// Gauss–Newton from `guess` (ENU, m). Four or more satellites: a 3D fix; three: a 2D fix
/// with the height held at `held_up_m` (when given); else `None`. `None` too when the
/// geometry is singular or too poor ([`MAX_DOP`]), or the iteration diverges.
pub fn solve(measurements: &[Measurement], guess: Vector3<f64>, held_up_m: Option<f64>) -> Option<Solution> {
    let three_d = measurements.len() >= 4;
    if !three_d && (measurements.len() < 3 || held_up_m.is_none()) {
        return None;
    }
    let mut x = guess;
    if let (false, Some(up)) = (three_d, held_up_m) {
        x.z = up;
    }
    let mut clock_m = 0.0;
    let mut normal = Matrix4::zeros();
    let mut converged = false;
    for _ in 0..MAX_ITERATIONS {
        let terms = measurements.iter().map(|m| {
            let to_sat = m.satellite_enu_m - x;
            let range = to_sat.norm();
            (geometry_row(&(to_sat / range), three_d), m.pseudorange_m - range - clock_m, m.sigma_m)
        });
        let rhs;
        (normal, rhs) = normal_equations(terms, three_d);
        let step = normal.try_inverse()? * rhs;
        x += step.xyz();
        clock_m += step.w;
        if step.xyz().norm() < CONVERGED_M {
            converged = true;
            break;
        }
    }
    if !converged || !x.iter().all(|c| c.is_finite()) || (x - guess).norm() > MAX_STEP_FROM_GUESS_M {
        return None;
    }
    let unknowns = if three_d { 4 } else { 3 };
    let residuals =
        measurements.iter().map(|m| (m.pseudorange_m - (m.satellite_enu_m - x).norm() - clock_m, m.sigma_m));
    let cov = normal.try_inverse()? * variance_factor(residuals, measurements.len(), unknowns);
    let units: Vec<Vector3<f64>> = measurements.iter().map(|m| (m.satellite_enu_m - x).normalize()).collect();
    let (velocity, velocity_sigma_mps) = solve_velocity(measurements, &units, three_d, unknowns)?;
    let dop = if three_d {
        Dop::of(&units.iter().map(|u| [u.x, u.y, u.z]).collect::<Vec<_>>())?
    } else {
        horizontal_dop(&units)?
    };
    if (if three_d { dop.pdop } else { dop.hdop }) > MAX_DOP {
        return None;
    }
    Some(Solution {
        position_enu_m: x,
        velocity_enu_mps: velocity,
        clock_bias_m: clock_m,
        dop,
        eph_m: (cov[(0, 0)] + cov[(1, 1)]).sqrt(),
        epv_m: if three_d { cov[(2, 2)].sqrt() } else { f64::INFINITY },
        velocity_sigma_mps,
        satellites_used: measurements.len().min(usize::from(u8::MAX)) as u8,
        three_d,
    })
}

/// Velocity and clock drift from the range rates (`rate - u·v_sat = -u·v + drift`), and the
/// per-component 1-sigma of the velocity (RMS over the solved axes, a-posteriori scaled).
fn solve_velocity(
    measurements: &[Measurement],
    units: &[Vector3<f64>],
    three_d: bool,
    unknowns: usize,
) -> Option<(Vector3<f64>, f64)> {
    let observed = |m: &Measurement, u: &Vector3<f64>| m.range_rate_mps - u.dot(&m.satellite_velocity_enu_mps);
    let terms =
        measurements.iter().zip(units).map(|(m, u)| (geometry_row(u, three_d), observed(m, u), m.rate_sigma_mps));
    let (normal, rhs) = normal_equations(terms, three_d);
    let q = normal.try_inverse()?;
    let x = q * rhs;
    let residuals = measurements
        .iter()
        .zip(units)
        .map(|(m, u)| (observed(m, u) - geometry_row(u, three_d).dot(&x), m.rate_sigma_mps));
    let factor = variance_factor(residuals, measurements.len(), unknowns);
    let axes = if three_d { 3.0 } else { 2.0 };
    let variance = (q[(0, 0)] + q[(1, 1)] + if three_d { q[(2, 2)] } else { 0.0 }) / axes;
    Some((x.xyz(), (variance * factor).sqrt()))
}

/// The row of a range (or range rate) in the geometry matrix for a satellite at unit line of
/// sight `u` (ENU): its derivatives by east, north, up (0 in a 2D fix: the height is held)
/// and by the receiver clock.
fn geometry_row(u: &Vector3<f64>, three_d: bool) -> Vector4<f64> {
    Vector4::new(-u.x, -u.y, if three_d { -u.z } else { 0.0 }, 1.0)
}

/// The weighted normal equations `(GᵀWG, GᵀWy)` of `(row, observation, 1-sigma)` terms. In
/// a 2D fix the held height gets a unit diagonal: the matrix stays invertible and the
/// right-hand side's zero keeps the height where it is.
fn normal_equations(
    terms: impl Iterator<Item = (Vector4<f64>, f64, f64)>,
    three_d: bool,
) -> (Matrix4<f64>, Vector4<f64>) {
    let mut normal = Matrix4::zeros();
    let mut rhs = Vector4::zeros();
    for (row, observed, sigma) in terms {
        let w = 1.0 / (sigma * sigma);
        normal += row * row.transpose() * w;
        rhs += row * (w * observed);
    }
    if !three_d {
        normal[(2, 2)] = 1.0;
    }
    (normal, rhs)
}

/// The a-posteriori variance factor of a weighted least-squares solution: the sum of the
/// squared `(residual / 1-sigma)` over the redundancy (`count - unknowns`), at least 1; 1
/// without redundancy (nothing to judge the residuals by).
fn variance_factor(residuals: impl Iterator<Item = (f64, f64)>, count: usize, unknowns: usize) -> f64 {
    let redundancy = count.saturating_sub(unknowns);
    if redundancy == 0 {
        return 1.0;
    }
    let ssr: f64 = residuals.map(|(r, sigma)| r * r / (sigma * sigma)).sum();
    (ssr / redundancy as f64).max(1.0)
}

/// The DOP of a 2D solution (east, north, clock): HDOP and TDOP; the rest infinite.
fn horizontal_dop(units: &[Vector3<f64>]) -> Option<Dop> {
    let mut normal = Matrix3::zeros();
    for u in units {
        let row = Vector3::new(-u.x, -u.y, 1.0);
        normal += row * row.transpose();
    }
    let q = normal.try_inverse()?;
    let hdop = (q[(0, 0)] + q[(1, 1)]).sqrt();
    hdop.is_finite().then(|| Dop {
        gdop: f64::INFINITY,
        pdop: f64::INFINITY,
        hdop,
        vdop: f64::INFINITY,
        tdop: q[(2, 2)].sqrt(),
    })
}

/// What one epoch saw: the satellites by signal path, and the fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceiverEpoch {
    /// Satellites above the elevation mask.
    pub above_mask: u8,
    /// Of those: received directly, received once reflected (NLOS), received strongly
    /// enough to be used.
    pub line_of_sight: u8,
    pub reflected: u8,
    pub tracked: u8,
    /// The fix; `None` with fewer than 3 tracked satellites (or 3 and no earlier height).
    pub solution: Option<Solution>,
}

/// The ranging receiver of one drone.
#[derive(Clone, Debug)]
pub struct RangingReceiver {
    sky: Arc<RunSky>,
    world: Arc<World>,
    rng: Rng,
    /// Unit-variance Gauss–Markov state of each constellation satellite's multipath.
    multipath: Vec<f64>,
    last_time_s: Option<f64>,
    clock_bias_m: f64,
    clock_drift_mps: f64,
    last_fix: Option<Vector3<f64>>,
}

impl RangingReceiver {
    /// Noise from the drone's `(seed, global index, Purpose::Gnss)` stream, so the
    /// measurements do not depend on sharding.
    pub fn new(sky: Arc<RunSky>, world: Arc<World>, seed: u64, drone_global_index: u32) -> Self {
        let mut rng = Rng::stream(seed, u64::from(drone_global_index), Purpose::Gnss);
        // A TCXO's clock: up to a millisecond of bias (300 km) and 0.1 ppm of drift.
        let clock_bias_m = rng.uniform(-3.0e5, 3.0e5);
        let clock_drift_mps = rng.uniform(-30.0, 30.0);
        let multipath = (0..sky.constellation().satellites.len()).map(|_| rng.normal()).collect();
        Self { sky, world, rng, multipath, last_time_s: None, clock_bias_m, clock_drift_mps, last_fix: None }
    }

    /// Measures and solves at sim time `time_s` for an antenna at `antenna_enu_m` moving at
    /// `velocity_enu_mps` (the truth). Call at the fix epochs, in increasing time.
    pub fn measure(
        &mut self,
        time_s: f64,
        antenna_enu_m: Vector3<f64>,
        velocity_enu_mps: Vector3<f64>,
    ) -> ReceiverEpoch {
        let dt_s = self.last_time_s.map_or(0.0, |t| (time_s - t).max(0.0));
        self.last_time_s = Some(time_s);
        let phi = (-dt_s / MULTIPATH_TAU_S).exp();
        let kick = (1.0 - phi * phi).sqrt();
        for m in &mut self.multipath {
            *m = phi * *m + kick * self.rng.normal();
        }
        self.clock_bias_m += self.clock_drift_mps * dt_s;

        let sky = self.sky.clone();
        let states = sky.at(time_s);
        let mask_sin = sky.mask_deg().to_radians().sin();
        let mut epoch = ReceiverEpoch { above_mask: 0, line_of_sight: 0, reflected: 0, tracked: 0, solution: None };
        let mut measurements = Vec::with_capacity(states.len());
        for s in states.iter() {
            let to_sat = s.position_enu_m - antenna_enu_m;
            let range_m = to_sat.norm();
            let u = to_sat / range_m;
            if u.z < mask_sin {
                continue;
            }
            epoch.above_mask += 1;
            let path = signal_path(&self.world, &antenna_enu_m, &u);
            let elevation_deg = u.z.asin().to_degrees();
            let (excess_m, arrival, multipath_m) = match path {
                SignalPath::LineOfSight => {
                    epoch.line_of_sight += 1;
                    (0.0, u, MULTIPATH_LOS_HORIZON_M * (1.0 - u.z))
                }
                SignalPath::Reflected { excess_m, arrival_enu, .. } => {
                    epoch.reflected += 1;
                    (excess_m, arrival_enu, MULTIPATH_REFLECTED_M)
                }
                SignalPath::Blocked => continue,
            };
            let Some(cn0) = cn0_dbhz(elevation_deg, &path).filter(|c| *c >= TRACKING_THRESHOLD_DBHZ) else {
                continue;
            };
            epoch.tracked += 1;
            let sigma_m = code_sigma_m(cn0);
            let rate_sigma_mps = RANGE_RATE_SIGMA_MPS * sigma_m / code_sigma_m(crate::signal::CN0_ZENITH_DBHZ);
            let pseudorange_m = range_m
                + self.clock_bias_m
                + excess_m
                + multipath_m * self.multipath[s.index]
                + sigma_m * self.rng.normal();
            // The satellite's motion along the direct line; the antenna's along the
            // direction the signal arrives from.
            let range_rate_mps = u.dot(&s.velocity_enu_mps) - arrival.dot(&velocity_enu_mps)
                + self.clock_drift_mps
                + rate_sigma_mps * self.rng.normal();
            measurements.push(Measurement {
                satellite_enu_m: s.position_enu_m,
                satellite_velocity_enu_mps: s.velocity_enu_mps,
                pseudorange_m,
                range_rate_mps,
                sigma_m,
                rate_sigma_mps,
            });
        }
        let guess = self.last_fix.unwrap_or_else(Vector3::zeros);
        epoch.solution = solve(&measurements, guess, self.last_fix.map(|p| p.z));
        if let Some(s) = &epoch.solution {
            self.last_fix = Some(s.position_enu_m);
        }
        epoch
    }
}

#[cfg(test)]
mod tests;
