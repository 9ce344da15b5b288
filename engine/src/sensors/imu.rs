//! `Imu`: MEMS accelerometer and gyroscope with white noise and wandering biases.

use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::random::Rng;

use super::noise::{GaussMarkov, SensorStream, normal3, sensor_rng, white_sigma};

/// Standard gravity, m/s² (CGPM 1901).
pub const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

/// IMU noise parameters. Defaults are the ADIS16448 figures used by PX4's Gazebo SITL
/// (rotors_simulator `gazebo_imu_plugin`), a typical MEMS IMU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuConfig {
    /// Accelerometer white noise density, m/s²/√Hz.
    pub accel_noise_density: f64,
    /// Accelerometer bias random walk, m/s² per √s.
    pub accel_bias_walk: f64,
    /// Correlation time bounding the accelerometer bias walk, s (`f64::INFINITY`: unbounded).
    pub accel_bias_tau_s: f64,
    /// Gyroscope white noise density, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Gyroscope bias random walk, rad/s per √s.
    pub gyro_bias_walk: f64,
    /// Correlation time bounding the gyroscope bias walk, s.
    pub gyro_bias_tau_s: f64,
}

impl Default for ImuConfig {
    fn default() -> Self {
        Self {
            accel_noise_density: 0.004,
            accel_bias_walk: 0.006,
            accel_bias_tau_s: 300.0,
            // 2 · 35 deg/h/√Hz and 2 · 4 deg/h/√s in rad.
            gyro_noise_density: 2.0 * 35.0 / 3600.0 * std::f64::consts::PI / 180.0,
            gyro_bias_walk: 2.0 * 4.0 / 3600.0 * std::f64::consts::PI / 180.0,
            gyro_bias_tau_s: 1000.0,
        }
    }
}

/// One IMU reading, body FLU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuSample {
    /// Specific force (acceleration minus gravity), m/s²: +9.81 on z at rest and level.
    pub accel_body_mps2: Vector3<f64>,
    /// Angular rate, rad/s.
    pub gyro_body_rps: Vector3<f64>,
}

/// Accelerometer and gyroscope of one drone. Biases start at zero and wander.
#[derive(Clone, Debug)]
pub struct Imu {
    config: ImuConfig,
    rng: Rng,
    accel_bias_body_mps2: Vector3<f64>,
    gyro_bias_body_rps: Vector3<f64>,
    accel_bias: GaussMarkov,
    gyro_bias: GaussMarkov,
    /// Samples, and their seconds, since the biases last stepped.
    bias_pending: (u32, f64),
}

/// The biases step once every this many samples (10 ms at 1 kHz), over the time since
/// their last step. Why: the Gauss-Markov step is exact for any interval, and a bias that
/// wanders over seconds to hours gains nothing from being redrawn every millisecond, while
/// its six normal draws per sample were a tenth of a drone-step's instructions (issue 20).
/// What changes is only that each bias is held for 10 ms between steps.
pub const BIAS_STEP_SAMPLES: u32 = 10;

impl Imu {
    /// Noise from the drone's `(seed, global index, Purpose::Sensors)` stream.
    pub fn new(config: ImuConfig, seed: u64, drone_global_index: u32) -> Self {
        let rng = sensor_rng(seed, drone_global_index, SensorStream::Imu);
        Self {
            config,
            rng,
            accel_bias_body_mps2: Vector3::zeros(),
            gyro_bias_body_rps: Vector3::zeros(),
            accel_bias: GaussMarkov::default(),
            gyro_bias: GaussMarkov::default(),
            bias_pending: (0, 0.0),
        }
    }

    /// One reading after `dt_s` since the previous one.
    ///
    /// `true_accel_enu_mps2` is the kinematic acceleration in world ENU, `true_rate_body_rps`
    /// the angular velocity in body FLU, `attitude` rotates body FLU into world ENU.
    /// Specific force f = a - g with g = (0, 0, -9.80665) ENU, rotated into the body:
    /// f_body = attitude⁻¹ · f_enu. White noise per sample: σ = density / √dt.
    pub fn measure(
        &mut self,
        true_accel_enu_mps2: Vector3<f64>,
        true_rate_body_rps: Vector3<f64>,
        attitude: &UnitQuaternion<f64>,
        dt_s: f64,
    ) -> ImuSample {
        let c = self.config;
        // Fixed draw order: accel bias, gyro bias (6 normals, every BIAS_STEP_SAMPLES-th
        // sample), accel noise, gyro noise (6 normals every sample).
        self.bias_pending.0 += 1;
        self.bias_pending.1 += dt_s;
        if self.bias_pending.0 >= BIAS_STEP_SAMPLES {
            let (_, pending_s) = std::mem::take(&mut self.bias_pending);
            self.accel_bias_body_mps2 = self.accel_bias.step3(
                self.accel_bias_body_mps2,
                c.accel_bias_walk,
                c.accel_bias_tau_s,
                pending_s,
                &mut self.rng,
            );
            self.gyro_bias_body_rps = self.gyro_bias.step3(
                self.gyro_bias_body_rps,
                c.gyro_bias_walk,
                c.gyro_bias_tau_s,
                pending_s,
                &mut self.rng,
            );
        }
        let accel_noise = normal3(&mut self.rng, white_sigma(c.accel_noise_density, dt_s));
        let gyro_noise = normal3(&mut self.rng, white_sigma(c.gyro_noise_density, dt_s));

        let gravity_enu_mps2 = Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2);
        let specific_force_body = attitude.inverse_transform_vector(&(true_accel_enu_mps2 - gravity_enu_mps2));
        ImuSample {
            accel_body_mps2: specific_force_body + self.accel_bias_body_mps2 + accel_noise,
            gyro_body_rps: true_rate_body_rps + self.gyro_bias_body_rps + gyro_noise,
        }
    }

    /// Current biases (accelerometer m/s², gyroscope rad/s), body FLU: the truth an
    /// estimator's bias states can be compared with.
    pub fn biases(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.accel_bias_body_mps2, self.gyro_bias_body_rps)
    }
}

#[cfg(test)]
mod tests;
