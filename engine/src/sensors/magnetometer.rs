//! `Magnetometer`: the Earth's field in body FLU, with white noise and a wandering bias.

use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::random::Rng;

use super::noise::{GaussMarkov, SensorStream, normal3, sensor_rng, white_sigma};

/// A fixed geomagnetic field (no variation over a city-scale world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EarthField {
    /// Total intensity, gauss (1 G = 100 µT).
    pub total_gauss: f64,
    /// Inclination (dip), degrees below horizontal; positive in the northern hemisphere.
    pub inclination_deg: f64,
    /// Declination, degrees east of true north (negative = west).
    pub declination_deg: f64,
}

impl EarthField {
    /// Roughly Chicago (WMM, 2025): 55 µT, dip 70°, declination 3.5° W.
    pub fn chicago() -> Self {
        Self { total_gauss: 0.55, inclination_deg: 70.0, declination_deg: -3.5 }
    }

    /// Field vector in world ENU, gauss: horizontal part F·cos(I) toward magnetic north,
    /// which lies D clockwise of true north, and F·sin(I) pointing down.
    pub fn field_enu_gauss(&self) -> Vector3<f64> {
        let (inc, dec) = (self.inclination_deg.to_radians(), self.declination_deg.to_radians());
        let horizontal = self.total_gauss * inc.cos();
        Vector3::new(horizontal * dec.sin(), horizontal * dec.cos(), -self.total_gauss * inc.sin())
    }
}

impl Default for EarthField {
    fn default() -> Self {
        Self::chicago()
    }
}

/// Magnetometer parameters. Noise defaults are PX4 Gazebo SITL's magnetometer plugin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagnetometerConfig {
    pub field: EarthField,
    /// White noise density, gauss/√Hz.
    pub noise_density: f64,
    /// Bias random walk, gauss per √s.
    pub bias_walk: f64,
    /// Correlation time bounding the bias walk, s.
    pub bias_tau_s: f64,
}

impl Default for MagnetometerConfig {
    fn default() -> Self {
        Self { field: EarthField::chicago(), noise_density: 0.4e-3, bias_walk: 6.4e-6, bias_tau_s: 600.0 }
    }
}

/// One magnetometer reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagSample {
    /// Magnetic field, body FLU, gauss.
    pub field_body_gauss: Vector3<f64>,
}

/// Magnetometer of one drone.
#[derive(Clone, Debug)]
pub struct Magnetometer {
    config: MagnetometerConfig,
    rng: Rng,
    bias_body_gauss: Vector3<f64>,
    bias: GaussMarkov,
}

impl Magnetometer {
    /// Noise from the drone's `(seed, global index, Purpose::Sensors)` stream.
    pub fn new(config: MagnetometerConfig, seed: u64, drone_global_index: u32) -> Self {
        let rng = sensor_rng(seed, drone_global_index, SensorStream::Magnetometer);
        Self { config, rng, bias_body_gauss: Vector3::zeros(), bias: GaussMarkov::default() }
    }

    /// One reading after `dt_s` since the previous one; `attitude` rotates body FLU into
    /// world ENU. B_body = attitude⁻¹ · B_enu + bias + noise (σ = density / √dt).
    pub fn measure(&mut self, attitude: &UnitQuaternion<f64>, dt_s: f64) -> MagSample {
        let c = self.config;
        self.bias_body_gauss = self.bias.step3(self.bias_body_gauss, c.bias_walk, c.bias_tau_s, dt_s, &mut self.rng);
        let noise = normal3(&mut self.rng, white_sigma(c.noise_density, dt_s));
        let field = attitude.inverse_transform_vector(&c.field.field_enu_gauss());
        MagSample { field_body_gauss: field + self.bias_body_gauss + noise }
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::FRAC_PI_2;

    use super::*;

    #[test]
    fn field_has_the_configured_intensity_dip_and_declination() {
        let b = EarthField::chicago().field_enu_gauss();
        assert!((b.norm() - 0.55).abs() < 1e-12);
        let dip = (-b.z).atan2(b.xy().norm()).to_degrees();
        assert!((dip - 70.0).abs() < 1e-9, "{dip}");
        let declination = b.x.atan2(b.y).to_degrees();
        assert!((declination + 3.5).abs() < 1e-9, "{declination}");
    }

    #[test]
    fn heading_follows_the_attitude() {
        let config = MagnetometerConfig { noise_density: 0.0, bias_walk: 0.0, ..Default::default() };
        let mut mag = Magnetometer::new(config, 1, 0);
        for yaw_deg in [0.0_f64, 45.0, 90.0, 200.0] {
            // Yaw in ENU (counter-clockwise from east); compass heading = 90° - yaw.
            let attitude = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians());
            let b = mag.measure(&attitude, 0.01).field_body_gauss;
            // Level magnetometer in FLU (y left): heading clockwise from magnetic north is
            // atan2(B_y, B_x) (FRD would negate B_y); true heading adds the declination.
            let true_heading = (b.y.atan2(b.x).to_degrees() - 3.5).rem_euclid(360.0);
            let want = (90.0 - yaw_deg).rem_euclid(360.0);
            let error = (true_heading - want + 180.0).rem_euclid(360.0) - 180.0;
            assert!(error.abs() < 1e-6, "yaw {yaw_deg}: heading {true_heading} vs {want}");
        }
        let nose_down = UnitQuaternion::from_euler_angles(0.0, FRAC_PI_2, 0.0);
        let b = mag.measure(&nose_down, 0.01).field_body_gauss;
        assert!(b.x > 0.5, "the downward field component is along body x when nose down: {b}");
    }

    #[test]
    fn noise_std_matches_the_density_and_is_seeded() {
        let config = MagnetometerConfig { bias_walk: 0.0, ..Default::default() };
        let run = |seed| {
            let mut mag = Magnetometer::new(config, seed, 0);
            (0..10_000).map(|_| mag.measure(&UnitQuaternion::identity(), 0.01).field_body_gauss).collect::<Vec<_>>()
        };
        let samples = run(5);
        let truth = EarthField::chicago().field_enu_gauss();
        let std = (samples.iter().map(|b| (b.x - truth.x).powi(2)).sum::<f64>() / 1e4).sqrt();
        eprintln!("mag std {std:.5} G (want {:.5})", 0.4e-3 / 0.1);
        assert!((std / 0.004 - 1.0).abs() < 0.05, "{std}");
        assert_eq!(samples, run(5));
        assert_ne!(samples, run(6));
    }
}
