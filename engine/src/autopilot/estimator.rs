//! State estimator: position and velocity from IMU, GNSS and barometer.
//!
//! A per-axis linear Kalman filter with state `[position, velocity]` (ENU, m and m/s),
//! predicted with the IMU's specific force rotated into ENU (plus gravity) and corrected by
//! GNSS position/velocity fixes and barometric height, less the barometer's offset from
//! GNSS height, which a bias estimator beside the filter learns from every fix. This is
//! the part of PX4's EKF2 that matters to a mission: GNSS noise and bias flow into the position estimate, so a biased
//! or degraded receiver really moves the vehicle, and without GNSS the estimate drifts on
//! integrated accelerometer noise.
//!
//! # Simplification
//! Attitude is taken from an ideal AHRS (the true attitude) and body rates from the noisy
//! gyro. A real EKF's attitude error (~0.5° level, a few degrees of heading) is omitted:
//! it changes little for waypoint missions, while a multirotor's accelerometer cannot
//! observe tilt in flight without the full EKF. Recorded as a departure in
//! docs/architecture.md.

use nalgebra::{UnitQuaternion, Vector3};

/// Standard gravity, m/s^2.
pub const G_MPS2: f64 = 9.80665;

/// Accelerometer noise driving the prediction, m/s^2 (1 sigma) — covers IMU noise plus
/// unmodelled vibration.
const ACCEL_PROCESS_SIGMA_MPS2: f64 = 0.35;
/// Smallest GNSS velocity noise a fix is fused with, m/s (1 sigma; PX4's EKF2_GPS_V_NOISE
/// is 0.3, u-blox M8/M9 report ~0.15 at open sky).
const GNSS_VEL_SIGMA_MPS: f64 = 0.15;
/// Barometric height noise, m (1 sigma).
const BARO_SIGMA_M: f64 = 0.5;
/// The barometer's offset from GNSS height must be known to this (1 sigma, m) before the
/// vehicle arms ([`Estimator::height_settled`]): home altitude is the estimate at arming, so
/// its error becomes every altitude target's. About 3 s of fixes at 5 Hz in open sky.
pub const HEIGHT_SETTLED_SIGMA_M: f64 = 0.25;
/// ... or the offset has been learnt from fixes for this long, s, whatever their quality
/// (PX4 asks its GNSS checks to pass for `EKF2_REQ_GPS_H`, 10 s): in a street canyon,
/// where a fix's vertical error is metres, 0.25 m would take minutes.
pub const HEIGHT_SETTLED_AFTER_S: f64 = 10.0;
/// How fast the barometer's offset from GNSS height may wander, m per √s (1 sigma): the
/// bias estimator's process noise (PX4's `EKF2_BARO_BIAS` bias estimator). Weather and
/// sensor heating move a real baro by centimetres per minute.
const BARO_BIAS_WALK_M_PER_SQRT_S: f64 = 0.01;
/// Without a GNSS fix for this long, the horizontal estimate is no longer trusted (PX4's
/// EKF2 position timeout is similar).
pub const GNSS_TIMEOUT_S: f64 = 1.0;
/// Smallest position noise a fix is fused with, m (PX4's EKF2_GPS_P_NOISE default): a
/// receiver's accuracy estimate is not believed below it.
pub const GNSS_MIN_SIGMA_M: f64 = 0.5;
/// A fix whose horizontal position innovation exceeds this many standard deviations of the
/// innovation is rejected (PX4's EKF2_GPS_P_GATE default): a jump of tens of metres from a
/// receiver in a street canyon is not believed, and rejected fixes do not count as GNSS.
pub const GNSS_POSITION_GATE_SD: f64 = 5.0;
/// Floor of the innovation's standard deviation in the gate, m (so the gate is at least
/// 10 m). This per-axis filter's covariance is optimistic (it models neither IMU biases nor
/// attitude errors: ~0.1 m where the estimate really errs by ~0.5 m), and a gate on it
/// alone refused open-sky fixes 2.6 m off; jumps of tens of metres are still refused.
pub const GNSS_GATE_MIN_SD_M: f64 = 2.0;
/// After this long without a fused fix the estimate is reset to the next fix instead of
/// gating it (PX4's EKF2_NOAID_TOUT default, 5 s): dead reckoning has drifted by then, and
/// a gate on a drifted estimate would refuse good fixes for ever.
pub const GNSS_RESET_AFTER_S: f64 = 5.0;

/// What the estimator outputs for the controllers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub position_enu_m: Vector3<f64>,
    pub velocity_enu_mps: Vector3<f64>,
    /// Body -> ENU.
    pub attitude: UnitQuaternion<f64>,
    pub rate_body_rps: Vector3<f64>,
    /// 1-sigma horizontal position uncertainty, m.
    pub eph_m: f64,
    /// 1-sigma vertical position uncertainty, m.
    pub epv_m: f64,
}

impl From<&Estimate> for crate::autopilot::control::EstimatedState {
    fn from(e: &Estimate) -> Self {
        Self {
            position_enu_m: e.position_enu_m,
            velocity_enu_mps: e.velocity_enu_mps,
            attitude: e.attitude,
            rate_body_rps: e.rate_body_rps,
        }
    }
}

/// What the estimator did with a GNSS fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GnssFusion {
    /// The first fix: the filter starts at it.
    Initialised,
    /// Fused into the estimate.
    Fused,
    /// Failed the innovation gate: not used, and not counted as GNSS.
    Rejected,
    /// The estimate jumped to the fix after too long without one; the jump (ENU, m), which
    /// the navigator adds to its setpoints so that the vehicle does not fly the jump (as
    /// PX4's position controller does on an EKF2 reset).
    Reset(Vector3<f64>),
}

impl GnssFusion {
    pub fn is_used(self) -> bool {
        self != GnssFusion::Rejected
    }
}

/// A GNSS fix as the estimator consumes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssMeasurement {
    pub position_enu_m: Vector3<f64>,
    pub velocity_enu_mps: Vector3<f64>,
    /// Reported 1-sigma horizontal / vertical accuracy, m.
    pub eph_m: f64,
    pub epv_m: f64,
    /// Reported 1-sigma of each velocity component, m/s.
    pub velocity_sigma_mps: f64,
}

/// Kalman filter over one axis: position p (m), velocity v (m/s).
#[derive(Clone, Copy, Debug)]
struct Axis {
    x: [f64; 2],
    /// Covariance [[pp, pv], [pv, vv]].
    p: [[f64; 2]; 2],
}

impl Axis {
    fn new(position: f64, sigma_p: f64) -> Self {
        Self { x: [position, 0.0], p: [[sigma_p * sigma_p, 0.0], [0.0, 1.0]] }
    }

    /// x' = F x + B a with F = [[1, dt], [0, 1]], B = [dt^2/2, dt]; P' = F P F^T + Q with the
    /// white-acceleration Q = sigma_a^2 [[dt^4/4, dt^3/2], [dt^3/2, dt^2]].
    fn predict(&mut self, accel: f64, dt: f64, sigma_a: f64) {
        let [p, v] = self.x;
        self.x = [p + v * dt + 0.5 * accel * dt * dt, v + accel * dt];
        let [[a, b], [_, d]] = self.p;
        let q = sigma_a * sigma_a;
        let (dt2, dt3, dt4) = (dt * dt, dt * dt * dt, dt * dt * dt * dt);
        let pp = a + 2.0 * dt * b + dt2 * d + q * dt4 / 4.0;
        let pv = b + dt * d + q * dt3 / 2.0;
        let vv = d + q * dt2;
        self.p = [[pp, pv], [pv, vv]];
    }

    /// Scalar measurement of state component `i` (0 position, 1 velocity) with variance r.
    fn update(&mut self, i: usize, z: f64, r: f64) {
        let s = self.p[i][i] + r;
        let k = [self.p[0][i] / s, self.p[1][i] / s];
        let innovation = z - self.x[i];
        self.x[0] += k[0] * innovation;
        self.x[1] += k[1] * innovation;
        // P' = (I - K H) P, with H selecting component i: row r loses k_r times row i.
        let p = self.p;
        for (row, ki) in k.iter().enumerate() {
            self.p[row] = [p[row][0] - ki * p[i][0], p[row][1] - ki * p[i][1]];
        }
    }
}

/// The estimator of one drone.
#[derive(Clone, Debug)]
pub struct Estimator {
    axes: Option<[Axis; 3]>,
    attitude: UnitQuaternion<f64>,
    rate_body_rps: Vector3<f64>,
    /// Sim time of the last GNSS fix, s.
    last_gnss_s: Option<f64>,
    /// The barometer's offset from GNSS height, estimated (PX4's baro bias estimator).
    baro_bias: Option<BaroBias>,
    /// The last barometric height, m up from the origin's altitude (before the bias).
    last_baro_up_m: Option<f64>,
}

/// The barometer's offset from the GNSS height frame, m: a scalar Kalman filter beside the
/// position filter, as PX4's EKF2 keeps one for each height source that is not the
/// reference.
///
/// Why: the offset is unknown to the vehicle (pressure altitude is not height above the
/// origin, and it drifts with weather). Fixing it once, from the estimate at the first baro
/// sample, froze that one GNSS fix's vertical error (σ 0.8 m) into the height for the whole
/// flight: the barometer, fused at 50 Hz, then held the estimate there, and takeoffs
/// settled 0.5-1.2 m off their target depending on the seed. Each fused GNSS fix now
/// measures the offset (`baro − gnss height`, noise `epv² + σ_baro²`), so it averages over
/// fixes to centimetres within seconds and follows the baro's slow drift.
#[derive(Clone, Copy, Debug)]
struct BaroBias {
    /// Baro height minus GNSS height, m.
    offset_m: f64,
    /// Its variance, m².
    variance_m2: f64,
    /// Sim time of the last update, s.
    time_s: f64,
    /// Sim time of the first estimate, s.
    started_s: f64,
}

impl BaroBias {
    /// One measurement `baro − gnss height` (m) of variance `r` (m²) at `time_s`.
    fn update(&mut self, time_s: f64, measured_m: f64, r: f64) {
        let dt = (time_s - self.time_s).max(0.0);
        self.time_s = time_s;
        self.variance_m2 += BARO_BIAS_WALK_M_PER_SQRT_S * BARO_BIAS_WALK_M_PER_SQRT_S * dt;
        let k = self.variance_m2 / (self.variance_m2 + r);
        self.offset_m += k * (measured_m - self.offset_m);
        self.variance_m2 *= 1.0 - k;
    }
}

impl Default for Estimator {
    fn default() -> Self {
        Self {
            axes: None,
            attitude: UnitQuaternion::identity(),
            rate_body_rps: Vector3::zeros(),
            last_gnss_s: None,
            baro_bias: None,
            last_baro_up_m: None,
        }
    }
}

impl Estimator {
    /// Prediction with an IMU sample: specific force (body FLU, m/s^2), gyro (body, rad/s),
    /// and the AHRS attitude (body -> ENU).
    pub fn predict(
        &mut self,
        accel_body_mps2: Vector3<f64>,
        gyro_body_rps: Vector3<f64>,
        attitude: UnitQuaternion<f64>,
        dt_s: f64,
    ) {
        self.attitude = attitude;
        self.rate_body_rps = gyro_body_rps;
        // Specific force excludes gravity: a = R f + g, with g = (0, 0, -9.81) in ENU.
        let accel_enu = attitude * accel_body_mps2 - Vector3::new(0.0, 0.0, G_MPS2);
        if let Some(axes) = &mut self.axes {
            for (axis, a) in axes.iter_mut().zip(accel_enu.iter()) {
                axis.predict(*a, dt_s, ACCEL_PROCESS_SIGMA_MPS2);
            }
        }
    }

    /// Correction with a GNSS fix at sim time `time_s`. The first fix, and the first after
    /// [`GNSS_RESET_AFTER_S`] without a fused one, (re)initialises the filter; any other is
    /// fused unless its horizontal innovation fails the [`GNSS_POSITION_GATE_SD`] gate.
    pub fn fuse_gnss(&mut self, time_s: f64, fix: &GnssMeasurement) -> GnssFusion {
        let eph = fix.eph_m.max(GNSS_MIN_SIGMA_M);
        let epv = fix.epv_m.max(GNSS_MIN_SIGMA_M);
        let velocity_sigma = fix.velocity_sigma_mps.max(GNSS_VEL_SIGMA_MPS);
        let stale = self.last_gnss_s.is_some_and(|t| time_s - t > GNSS_RESET_AFTER_S);
        if stale && let Some(axes) = self.axes.take() {
            let before = Vector3::new(axes[0].x[0], axes[1].x[0], axes[2].x[0]);
            self.last_gnss_s = Some(time_s);
            self.axes = Some([
                Axis { x: [fix.position_enu_m.x, axes[0].x[1]], ..Axis::new(0.0, eph) },
                Axis { x: [fix.position_enu_m.y, axes[1].x[1]], ..Axis::new(0.0, eph) },
                Axis { x: [fix.position_enu_m.z, axes[2].x[1]], ..Axis::new(0.0, epv) },
            ]);
            return GnssFusion::Reset(fix.position_enu_m - before);
        }
        if let Some(axes) = &self.axes {
            let ratio = |k: usize| {
                let innovation = fix.position_enu_m[k] - axes[k].x[0];
                let variance = (axes[k].p[0][0] + eph * eph).max(GNSS_GATE_MIN_SD_M * GNSS_GATE_MIN_SD_M);
                innovation * innovation / (GNSS_POSITION_GATE_SD.powi(2) * variance)
            };
            if ratio(0).max(ratio(1)) > 1.0 {
                return GnssFusion::Rejected;
            }
        }
        self.last_gnss_s = Some(time_s);
        match &mut self.axes {
            None => {
                self.axes = Some([
                    Axis::new(fix.position_enu_m.x, eph),
                    Axis::new(fix.position_enu_m.y, eph),
                    Axis::new(fix.position_enu_m.z, epv),
                ]);
                return GnssFusion::Initialised;
            }
            Some(axes) => {
                for (i, axis) in axes.iter_mut().enumerate() {
                    let r = if i < 2 { eph * eph } else { epv * epv };
                    axis.update(0, fix.position_enu_m[i], r);
                    axis.update(1, fix.velocity_enu_mps[i], velocity_sigma * velocity_sigma);
                }
            }
        }
        if let (Some(bias), Some(baro)) = (&mut self.baro_bias, self.last_baro_up_m) {
            bias.update(time_s, baro - fix.position_enu_m.z, epv * epv + BARO_SIGMA_M * BARO_SIGMA_M);
        }
        GnssFusion::Fused
    }

    /// Correction with a barometric height (metres up from the origin's altitude) at sim
    /// time `time_s`, less the estimated baro offset ([`BaroBias`]; the first reading after
    /// the first fix starts it from the estimate).
    pub fn fuse_baro(&mut self, time_s: f64, baro_up_m: f64) {
        let Some(axes) = &mut self.axes else { return };
        self.last_baro_up_m = Some(baro_up_m);
        let z = axes[2];
        let bias = self.baro_bias.get_or_insert(BaroBias {
            offset_m: baro_up_m - z.x[0],
            variance_m2: z.p[0][0] + BARO_SIGMA_M * BARO_SIGMA_M,
            time_s,
            started_s: time_s,
        });
        axes[2].update(0, baro_up_m - bias.offset_m, BARO_SIGMA_M * BARO_SIGMA_M);
    }

    /// The barometer's offset from GNSS height is known to [`HEIGHT_SETTLED_SIGMA_M`], or
    /// has been learnt for [`HEIGHT_SETTLED_AFTER_S`].
    pub fn height_settled(&self) -> bool {
        self.baro_bias.is_some_and(|b| {
            b.variance_m2 <= HEIGHT_SETTLED_SIGMA_M * HEIGHT_SETTLED_SIGMA_M
                || b.time_s - b.started_s >= HEIGHT_SETTLED_AFTER_S
        })
    }

    /// A position estimate exists (at least one fix so far).
    pub fn is_initialized(&self) -> bool {
        self.axes.is_some()
    }

    /// GNSS fixes are arriving (the last one is recent).
    pub fn gnss_healthy(&self, time_s: f64) -> bool {
        self.last_gnss_s.is_some_and(|t| time_s - t <= GNSS_TIMEOUT_S)
    }

    /// The current estimate; `None` before the first GNSS fix.
    pub fn estimate(&self) -> Option<Estimate> {
        let axes = self.axes.as_ref()?;
        Some(Estimate {
            position_enu_m: Vector3::new(axes[0].x[0], axes[1].x[0], axes[2].x[0]),
            velocity_enu_mps: Vector3::new(axes[0].x[1], axes[1].x[1], axes[2].x[1]),
            attitude: self.attitude,
            rate_body_rps: self.rate_body_rps,
            eph_m: axes[0].p[0][0].max(axes[1].p[0][0]).sqrt(),
            epv_m: axes[2].p[0][0].sqrt(),
        })
    }
}

#[cfg(test)]
mod tests {
    use sadesim_crds::random::{Purpose, Rng};

    use super::*;

    const LEVEL_AT_REST: Vector3<f64> = Vector3::new(0.0, 0.0, G_MPS2);

    fn fix(p: Vector3<f64>, v: Vector3<f64>) -> GnssMeasurement {
        GnssMeasurement { position_enu_m: p, velocity_enu_mps: v, eph_m: 0.5, epv_m: 0.8, velocity_sigma_mps: 0.15 }
    }

    #[test]
    fn converges_to_noisy_fixes_and_averages_the_noise() {
        let mut est = Estimator::default();
        let mut rng = Rng::stream(1, 0, Purpose::Gnss);
        let truth = Vector3::new(10.0, -5.0, 2.0);
        let dt = 0.001;
        let mut err_sum = 0.0;
        let mut n = 0;
        for step in 0..20_000 {
            let t = step as f64 * dt;
            est.predict(LEVEL_AT_REST, Vector3::zeros(), UnitQuaternion::identity(), dt);
            if step % 200 == 0 {
                let noisy = truth + Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 0.5;
                est.fuse_gnss(t, &fix(noisy, Vector3::zeros()));
            }
            if step > 10_000 {
                err_sum += (est.estimate().unwrap().position_enu_m - truth).norm();
                n += 1;
            }
        }
        let mean_err = err_sum / n as f64;
        assert!(mean_err < 0.35, "filtered error {mean_err} m should beat the 0.5 m/axis fix noise");
    }

    #[test]
    fn a_gnss_bias_moves_the_estimate() {
        let mut est = Estimator::default();
        let bias = Vector3::new(3.0, 0.0, 0.0);
        for step in 0..10_000 {
            est.predict(LEVEL_AT_REST, Vector3::zeros(), UnitQuaternion::identity(), 0.001);
            if step % 200 == 0 {
                est.fuse_gnss(step as f64 * 0.001, &fix(bias, Vector3::zeros()));
            }
        }
        let e = est.estimate().unwrap();
        assert!((e.position_enu_m.x - 3.0).abs() < 0.1, "{e:?}");
    }

    #[test]
    fn tracks_acceleration_between_fixes_and_drifts_without_gnss() {
        let mut est = Estimator::default();
        est.fuse_gnss(0.0, &fix(Vector3::zeros(), Vector3::zeros()));
        // 1 m/s^2 eastward for 2 s with fixes every 0.2 s: ends near x = 2 m, v = 2 m/s.
        let accel_body = Vector3::new(1.0, 0.0, G_MPS2);
        for step in 1..=2000 {
            let t = step as f64 * 0.001;
            est.predict(accel_body, Vector3::zeros(), UnitQuaternion::identity(), 0.001);
            if step % 200 == 0 {
                est.fuse_gnss(t, &fix(Vector3::new(0.5 * t * t, 0.0, 0.0), Vector3::new(t, 0.0, 0.0)));
            }
        }
        let e = est.estimate().unwrap();
        assert!((e.position_enu_m.x - 2.0).abs() < 0.1 && (e.velocity_enu_mps.x - 2.0).abs() < 0.1, "{e:?}");
        assert!(est.gnss_healthy(2.0) && !est.gnss_healthy(3.5));
        // Uncertainty grows while dead-reckoning.
        let before = e.eph_m;
        for _ in 0..5000 {
            est.predict(LEVEL_AT_REST, Vector3::zeros(), UnitQuaternion::identity(), 0.001);
        }
        assert!(est.estimate().unwrap().eph_m > before * 2.0);
    }

    #[test]
    fn a_fix_that_jumps_is_rejected_until_dead_reckoning_has_gone_on_too_long() {
        fn run(est: &mut Estimator, t: &mut f64, seconds: f64, at: Vector3<f64>) -> Vec<bool> {
            let mut used = Vec::new();
            for step in 0..(seconds * 1000.0) as usize {
                *t += 0.001;
                est.predict(LEVEL_AT_REST, Vector3::zeros(), UnitQuaternion::identity(), 0.001);
                if step % 200 == 199 {
                    used.push(est.fuse_gnss(*t, &fix(at, Vector3::zeros())).is_used());
                }
            }
            used
        }
        let mut est = Estimator::default();
        let mut t = 0.0;
        assert!(run(&mut est, &mut t, 10.0, Vector3::zeros()).iter().all(|&u| u));
        // A canyon's fix 40 m east (eph 0.5 m): rejected, so GNSS is unhealthy after 1 s
        // and the estimate stays put.
        let jumped = run(&mut est, &mut t, 2.0, Vector3::new(40.0, 0.0, 0.0));
        assert!(jumped.iter().all(|&u| !u), "{jumped:?}");
        assert!(!est.gnss_healthy(t) && est.estimate().unwrap().position_enu_m.x.abs() < 1.0);
        // Still 40 m east 5 s after the last fused fix: the estimate resets to it.
        let later = run(&mut est, &mut t, 4.0, Vector3::new(40.0, 0.0, 0.0));
        assert!(later.contains(&true) && est.gnss_healthy(t), "{later:?}");
        assert!((est.estimate().unwrap().position_enu_m.x - 40.0).abs() < 1.0);
    }

    #[test]
    fn baro_holds_height_and_nothing_before_first_fix() {
        let mut est = Estimator::default();
        assert!(est.estimate().is_none() && !est.is_initialized());
        est.fuse_baro(0.0, 5.0); // ignored before initialisation
        est.fuse_gnss(0.0, &fix(Vector3::new(0.0, 0.0, 1.0), Vector3::zeros()));
        est.fuse_baro(0.0, 11.0); // starts the offset: baro reads 10 m high
        for _ in 0..100 {
            est.fuse_baro(0.0, 13.0); // climbed 2 m
        }
        assert!((est.estimate().unwrap().position_enu_m.z - 3.0).abs() < 0.1);
    }

    #[test]
    fn the_baro_offset_is_learnt_from_gnss_not_frozen_at_the_first_fix() {
        // Resting at z = 0 with the baro reading 10 m high. The first fix is 1 m high (the
        // receiver's vertical noise is 0.8 m); the later ones scatter around the truth. A
        // baro offset taken once from the first estimate would hold the height 1 m high for
        // ever; the bias estimator averages it out over the fixes.
        let mut est = Estimator::default();
        let mut rng = Rng::stream(3, 0, Purpose::Gnss);
        let dt = 0.001;
        est.fuse_gnss(0.0, &fix(Vector3::new(0.0, 0.0, 1.0), Vector3::zeros()));
        est.fuse_baro(0.0, 10.0);
        assert!(!est.height_settled(), "one fix cannot settle the baro offset");
        let mut settled_at = None;
        for step in 1..=20_000u32 {
            let t = f64::from(step) * dt;
            est.predict(LEVEL_AT_REST, Vector3::zeros(), UnitQuaternion::identity(), dt);
            if step % 200 == 0 {
                let z = 0.8 * rng.normal();
                est.fuse_gnss(t, &fix(Vector3::new(0.0, 0.0, z), Vector3::zeros()));
            }
            if step % 20 == 0 {
                est.fuse_baro(t, 10.0 + 0.2 * rng.normal());
            }
            if settled_at.is_none() && est.height_settled() {
                settled_at = Some(t);
            }
        }
        // 0.25 m from fixes of 0.8 m and a baro of 0.5 m (as the filter models it): about
        // 14 fixes, 3 s at 5 Hz.
        let settled_at = settled_at.expect("the height settles");
        assert!((2.0..4.0).contains(&settled_at), "settled after {settled_at} s");
    }

    #[test]
    fn with_poor_fixes_the_height_settles_after_ten_seconds_of_them() {
        // A street canyon: 4 m of vertical error per fix would need minutes to reach 0.25 m.
        let mut est = Estimator::default();
        let poor = |z: f64| GnssMeasurement { epv_m: 4.0, ..fix(Vector3::new(0.0, 0.0, z), Vector3::zeros()) };
        est.fuse_gnss(0.0, &poor(0.0));
        let mut settled_at = None;
        for k in 1..=100u32 {
            let t = f64::from(k) * 0.2;
            est.fuse_baro(t, 10.0);
            est.fuse_gnss(t, &poor(0.0));
            if settled_at.is_none() && est.height_settled() {
                settled_at = Some(t);
            }
        }
        let settled_at = settled_at.expect("the height settles");
        assert!(
            (HEIGHT_SETTLED_AFTER_S..HEIGHT_SETTLED_AFTER_S + 0.5).contains(&settled_at),
            "settled at {settled_at} s"
        );
        let z = est.estimate().unwrap().position_enu_m.z;
        assert!(z.abs() < 0.25, "height estimate {z:.2} m after 20 s at rest (truth 0)");
    }
}
