//! `GnssReceiver`: position and velocity fixes at a fixed rate, and no fix during outages.
//! Two models: the statistical receiver (a random-walk bias and white noise scaled by the
//! environment's `GnssCondition`), and the ranging receiver (`sadesim_gnss`: pseudoranges
//! to the constellation's satellites, blocked and reflected by the world's buildings, and a
//! least-squares fix) when the run names a constellation.

use std::sync::Arc;

use nalgebra::Vector3;
use sadesim_crds::environment::Gnss;
use sadesim_crds::random::{Purpose, Rng};
use sadesim_gnss::{RangingReceiver, RunSky};
use sadesim_world::World;

use super::noise::{GaussMarkov, normal3};
use crate::env::GnssCondition;

/// MAVLink `GPS_FIX_TYPE_NO_FIX`: receiver present, no position.
pub const GPS_FIX_TYPE_NO_FIX: u8 = 1;
/// MAVLink `GPS_FIX_TYPE_2D_FIX`: horizontal position only (three satellites, height held).
pub const GPS_FIX_TYPE_2D_FIX: u8 = 2;
/// MAVLink `GPS_FIX_TYPE_3D_FIX`.
pub const GPS_FIX_TYPE_3D_FIX: u8 = 3;
/// A 3D fix needs at least four satellites (x, y, z and clock bias).
pub const MIN_SATELLITES_3D: u8 = 4;

/// Fix epochs a call may be early by and still count as due, s (float time steps).
const EPOCH_TOLERANCE_S: f64 = 1e-9;

/// Receiver parameters, validated spec values with defaults filled in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssConfig {
    /// Fix rate, Hz.
    pub rate_hz: f64,
    /// Horizontal (per axis) and vertical white position noise at open sky, 1-sigma, m.
    pub horizontal_sigma_m: f64,
    pub vertical_sigma_m: f64,
    /// Position bias random walk, m per √s (per axis, unbounded).
    pub bias_walk_m_per_sqrt_s: f64,
    /// Horizontal (per axis) and vertical white velocity noise at open sky, 1-sigma, m/s.
    pub horizontal_velocity_sigma_mps: f64,
    pub vertical_velocity_sigma_mps: f64,
    /// Constant position error added to every fix, world ENU, m (`spec.environment.gnss.bias`;
    /// zero by default). Both receivers apply it.
    pub fixed_bias_enu_m: Vector3<f64>,
}

impl GnssConfig {
    /// The spec's receiver (`spec.environment.gnss`), defaults where absent: 5 Hz,
    /// 0.5 m / 0.8 m, 0.01 m/√s, no fixed bias; velocity noise 0.05 / 0.08 m/s (u-blox
    /// M8/M9 class).
    pub fn from_spec(spec: Option<&Gnss>) -> Self {
        let get = |f: fn(&Gnss) -> Option<f64>, default: f64| spec.and_then(f).unwrap_or(default);
        Self {
            rate_hz: get(|g| g.rate_hz, 5.0),
            horizontal_sigma_m: get(|g| g.horizontal_sigma_m, 0.5),
            vertical_sigma_m: get(|g| g.vertical_sigma_m, 0.8),
            bias_walk_m_per_sqrt_s: get(|g| g.bias_walk_m_per_sqrt_s, 0.01),
            horizontal_velocity_sigma_mps: 0.05,
            vertical_velocity_sigma_mps: 0.08,
            fixed_bias_enu_m: spec
                .and_then(|g| g.bias)
                .map_or_else(Vector3::zeros, |b| Vector3::new(b.east_m, b.north_m, b.up_m)),
        }
    }
}

impl Default for GnssConfig {
    fn default() -> Self {
        Self::from_spec(None)
    }
}

/// One receiver output, at the fix rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// Simulated time of the measurement, s.
    pub time_s: f64,
    /// Position, world ENU, m. Zero (meaningless) without a fix (`fix_type` below 2; a 2D
    /// fix holds the height of the last 3D fix).
    pub position_enu_m: Vector3<f64>,
    /// Velocity, world ENU, m/s. Zero (meaningless) without a fix.
    pub velocity_enu_mps: Vector3<f64>,
    /// MAVLink GPS_FIX_TYPE: [`GPS_FIX_TYPE_3D_FIX`], [`GPS_FIX_TYPE_2D_FIX`] (the ranging
    /// receiver with three satellites) or [`GPS_FIX_TYPE_NO_FIX`]. The estimator fuses 3D
    /// fixes only (as PX4's EKF2 by default).
    pub fix_type: u8,
    /// Satellites used (0 during an outage).
    pub satellites: u8,
    /// Estimated 1-sigma horizontal / vertical accuracy of the white noise, m; infinite
    /// without a fix (saturates to MAVLink's "unknown" UINT16_MAX when cast).
    pub eph_m: f64,
    pub epv_m: f64,
    /// Estimated 1-sigma of each velocity component, m/s (a receiver's speed accuracy);
    /// infinite without a fix.
    pub velocity_sigma_mps: f64,
    /// Dilutions of precision, unitless; infinite without a fix.
    pub hdop: f64,
    pub vdop: f64,
    /// What the ranging receiver's antenna saw (`None` for the statistical receiver).
    pub sky: Option<SkyCounts>,
}

/// Satellites by signal path at one fix epoch (the ranging receiver): the evidence of why a
/// fix is good or bad, which a real receiver does not report but a simulator can.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SkyCounts {
    /// Above the elevation mask.
    pub above_mask: u8,
    /// Received directly.
    pub line_of_sight: u8,
    /// Received only by a facade reflection (non-line-of-sight).
    pub reflected: u8,
}

impl GnssFix {
    /// True when position and velocity are valid.
    pub fn has_3d_fix(&self) -> bool {
        self.fix_type >= GPS_FIX_TYPE_3D_FIX
    }
}

/// GNSS receiver of one drone.
#[derive(Clone, Debug)]
pub struct GnssReceiver {
    config: GnssConfig,
    rng: Rng,
    bias_enu_m: Vector3<f64>,
    bias: GaussMarkov,
    /// Time of the last fix epoch, s (`None` before the first).
    last_epoch_s: Option<f64>,
    /// Index of the next fix epoch; epoch k is due at k / rate_hz.
    next_epoch: u64,
    /// The ranging model, when the run names a constellation.
    ranging: Option<RangingReceiver>,
}

impl GnssReceiver {
    /// Noise from the drone's `(seed, global index, Purpose::Gnss)` stream.
    pub fn new(config: GnssConfig, seed: u64, drone_global_index: u32) -> Self {
        let rng = Rng::stream(seed, u64::from(drone_global_index), Purpose::Gnss);
        Self {
            config,
            rng,
            bias_enu_m: Vector3::zeros(),
            bias: GaussMarkov::default(),
            last_epoch_s: None,
            next_epoch: 0,
            ranging: None,
        }
    }

    /// The ranging receiver: fixes solved from pseudoranges to `sky`'s satellites as the
    /// antenna sees them among `world`'s buildings; `config`'s rate applies, its noise
    /// figures do not (validation refuses them with a constellation).
    pub fn ranging(
        config: GnssConfig,
        seed: u64,
        drone_global_index: u32,
        sky: Arc<RunSky>,
        world: Arc<World>,
    ) -> Self {
        let mut receiver = Self::new(config, seed, drone_global_index);
        receiver.ranging = Some(RangingReceiver::new(sky, world, seed, drone_global_index));
        receiver
    }

    /// Call every physics step; returns a fix only when one is due (at `rate_hz`, on the
    /// grid k / rate_hz; if calls skip epochs, the next call yields one fix, not a burst).
    ///
    /// At each due epoch the bias walks by the time since the previous epoch (so it does not
    /// depend on how often `update` is called), then: position = truth + fixed bias + walking
    /// bias + white noise × `cond.sigma_scale`; velocity = truth + white noise × `cond.sigma_scale`. Without
    /// signal (`!cond.available`) or with fewer than 4 satellites the fix is
    /// `GPS_FIX_TYPE_NO_FIX`; the first epoch after the signal returns is a fresh 3D fix.
    /// Draws nine normals per epoch, fix or not, so an outage does not shift later noise.
    pub fn update(
        &mut self,
        time_s: f64,
        true_pos_enu_m: Vector3<f64>,
        true_vel_enu_mps: Vector3<f64>,
        cond: &GnssCondition,
    ) -> Option<GnssFix> {
        let c = self.config;
        if time_s + EPOCH_TOLERANCE_S < self.next_epoch as f64 / c.rate_hz {
            return None;
        }
        self.next_epoch = ((time_s + EPOCH_TOLERANCE_S) * c.rate_hz).floor().max(0.0) as u64 + 1;
        let dt_s = self.last_epoch_s.map_or(0.0, |last| time_s - last);
        self.last_epoch_s = Some(time_s);
        if let Some(ranging) = &mut self.ranging {
            let mut fix = ranging_fix(ranging, time_s, true_pos_enu_m, true_vel_enu_mps, cond);
            if fix.fix_type >= GPS_FIX_TYPE_2D_FIX {
                fix.position_enu_m += c.fixed_bias_enu_m;
            }
            return Some(fix);
        }

        self.bias_enu_m =
            self.bias.step3(self.bias_enu_m, c.bias_walk_m_per_sqrt_s, f64::INFINITY, dt_s, &mut self.rng);
        let scale = cond.sigma_scale;
        let sigma_pos = Vector3::new(c.horizontal_sigma_m, c.horizontal_sigma_m, c.vertical_sigma_m) * scale;
        let sigma_vel = Vector3::new(
            c.horizontal_velocity_sigma_mps,
            c.horizontal_velocity_sigma_mps,
            c.vertical_velocity_sigma_mps,
        ) * scale;
        let pos_noise = normal3(&mut self.rng, 1.0).component_mul(&sigma_pos);
        let vel_noise = normal3(&mut self.rng, 1.0).component_mul(&sigma_vel);

        if !cond.available || cond.satellites < MIN_SATELLITES_3D {
            return Some(GnssFix {
                time_s,
                position_enu_m: Vector3::zeros(),
                velocity_enu_mps: Vector3::zeros(),
                fix_type: GPS_FIX_TYPE_NO_FIX,
                satellites: if cond.available { cond.satellites } else { 0 },
                eph_m: f64::INFINITY,
                epv_m: f64::INFINITY,
                velocity_sigma_mps: f64::INFINITY,
                hdop: f64::INFINITY,
                vdop: f64::INFINITY,
                sky: None,
            });
        }
        // VDOP is not modelled by the environment yet: scale HDOP by the vertical to
        // horizontal noise ratio of the receiver (1.6 with defaults, typical at open sky).
        let vertical_ratio = if c.horizontal_sigma_m > 0.0 { c.vertical_sigma_m / c.horizontal_sigma_m } else { 1.6 };
        Some(GnssFix {
            time_s,
            position_enu_m: true_pos_enu_m + c.fixed_bias_enu_m + self.bias_enu_m + pos_noise,
            velocity_enu_mps: true_vel_enu_mps + vel_noise,
            fix_type: GPS_FIX_TYPE_3D_FIX,
            satellites: cond.satellites,
            eph_m: sigma_pos.x,
            epv_m: sigma_pos.z,
            velocity_sigma_mps: sigma_vel.x,
            hdop: cond.hdop,
            vdop: cond.hdop * vertical_ratio,
            sky: None,
        })
    }

    /// Current random-walk position bias, world ENU, m (without the fixed bias).
    pub fn bias_enu_m(&self) -> Vector3<f64> {
        self.bias_enu_m
    }

    pub fn config(&self) -> &GnssConfig {
        &self.config
    }
}

/// One fix epoch of the ranging receiver. The receiver measures in every epoch, outage or
/// not, so an outage does not shift later noise; during an outage (`!cond.available`) the
/// fix is dropped.
fn ranging_fix(
    ranging: &mut RangingReceiver,
    time_s: f64,
    true_pos_enu_m: Vector3<f64>,
    true_vel_enu_mps: Vector3<f64>,
    cond: &GnssCondition,
) -> GnssFix {
    let epoch = ranging.measure(time_s, true_pos_enu_m, true_vel_enu_mps);
    let sky = Some(SkyCounts {
        above_mask: epoch.above_mask,
        line_of_sight: epoch.line_of_sight,
        reflected: epoch.reflected,
    });
    match epoch.solution.filter(|_| cond.available) {
        Some(s) => GnssFix {
            time_s,
            position_enu_m: s.position_enu_m,
            velocity_enu_mps: s.velocity_enu_mps,
            fix_type: if s.three_d { GPS_FIX_TYPE_3D_FIX } else { GPS_FIX_TYPE_2D_FIX },
            satellites: s.satellites_used,
            eph_m: s.eph_m,
            epv_m: s.epv_m,
            velocity_sigma_mps: s.velocity_sigma_mps,
            hdop: s.dop.hdop,
            vdop: s.dop.vdop,
            sky,
        },
        None => GnssFix {
            time_s,
            position_enu_m: Vector3::zeros(),
            velocity_enu_mps: Vector3::zeros(),
            fix_type: GPS_FIX_TYPE_NO_FIX,
            satellites: if cond.available { epoch.tracked } else { 0 },
            eph_m: f64::INFINITY,
            epv_m: f64::INFINITY,
            velocity_sigma_mps: f64::INFINITY,
            hdop: f64::INFINITY,
            vdop: f64::INFINITY,
            sky,
        },
    }
}

#[cfg(test)]
mod tests;
