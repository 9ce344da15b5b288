//! `Barometer`: pressure altitude with white noise and slow drift, ISA pressure and
//! temperature.

use sadesim_crds::random::Rng;

use super::imu::STANDARD_GRAVITY_MPS2;
use super::noise::{GaussMarkov, SensorStream, sensor_rng};

/// ISA sea-level pressure, Pa.
pub const ISA_SEA_LEVEL_PRESSURE_PA: f64 = 101_325.0;
/// ISA sea-level temperature, K.
pub const ISA_SEA_LEVEL_TEMPERATURE_K: f64 = 288.15;
/// ISA tropospheric lapse rate, K/m.
pub const ISA_LAPSE_RATE_K_PER_M: f64 = 0.0065;
/// Molar mass of dry air, kg/mol.
const MOLAR_MASS_AIR_KG_PER_MOL: f64 = 0.028_964_4;
/// Universal gas constant, J/(mol·K).
const GAS_CONSTANT_J_PER_MOL_K: f64 = 8.314_462_618;
const KELVIN_AT_0_DEGC: f64 = 273.15;

/// ISA temperature at `alt_msl_m` (troposphere, below 11 km), K: T = T0 - L·h.
pub fn isa_temperature_k(alt_msl_m: f64) -> f64 {
    ISA_SEA_LEVEL_TEMPERATURE_K - ISA_LAPSE_RATE_K_PER_M * alt_msl_m
}

/// ISA static pressure at `alt_msl_m` (troposphere), Pa:
/// p = p0 · (1 - L·h / T0)^(g0·M / (R·L)), exponent ≈ 5.2559.
pub fn isa_pressure_pa(alt_msl_m: f64) -> f64 {
    let exponent =
        STANDARD_GRAVITY_MPS2 * MOLAR_MASS_AIR_KG_PER_MOL / (GAS_CONSTANT_J_PER_MOL_K * ISA_LAPSE_RATE_K_PER_M);
    ISA_SEA_LEVEL_PRESSURE_PA * (isa_temperature_k(alt_msl_m) / ISA_SEA_LEVEL_TEMPERATURE_K).powf(exponent)
}

/// Barometer noise parameters (typical MEMS barometer such as MS5611/BMP388).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BarometerConfig {
    /// White noise of each altitude reading, 1-sigma, metres.
    pub noise_sigma_m: f64,
    /// Drift random walk (weather, sensor heating), m per √s.
    pub drift_walk_m_per_sqrt_s: f64,
    /// Correlation time bounding the drift, s: steady std = walk · sqrt(τ/2).
    pub drift_tau_s: f64,
}

impl Default for BarometerConfig {
    fn default() -> Self {
        // Drift std 0.01·√5 = 0.022 m after 5 s, bounded at 0.17 m.
        Self { noise_sigma_m: 0.2, drift_walk_m_per_sqrt_s: 0.01, drift_tau_s: 600.0 }
    }
}

/// One barometer reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaroSample {
    /// Pressure altitude above mean sea level, metres (noisy, drifting).
    pub alt_msl_m: f64,
    /// Static pressure, Pa: the ISA pressure of `alt_msl_m`, so the two always agree.
    pub pressure_pa: f64,
    /// Air temperature, °C: ISA at the true altitude.
    pub temperature_degc: f64,
}

/// Barometer of one drone.
#[derive(Clone, Debug)]
pub struct Barometer {
    config: BarometerConfig,
    rng: Rng,
    drift_m: f64,
    drift: GaussMarkov,
}

impl Barometer {
    /// Noise from the drone's `(seed, global index, Purpose::Sensors)` stream.
    pub fn new(config: BarometerConfig, seed: u64, drone_global_index: u32) -> Self {
        let rng = sensor_rng(seed, drone_global_index, SensorStream::Barometer);
        Self { config, rng, drift_m: 0.0, drift: GaussMarkov::default() }
    }

    /// One reading after `dt_s` since the previous one (two normals per call).
    pub fn measure(&mut self, true_alt_msl_m: f64, dt_s: f64) -> BaroSample {
        let c = self.config;
        self.drift_m = self.drift.step(self.drift_m, c.drift_walk_m_per_sqrt_s, c.drift_tau_s, dt_s, self.rng.normal());
        let alt_msl_m = true_alt_msl_m + self.drift_m + c.noise_sigma_m * self.rng.normal();
        BaroSample {
            alt_msl_m,
            pressure_pa: isa_pressure_pa(alt_msl_m),
            temperature_degc: isa_temperature_k(true_alt_msl_m) - KELVIN_AT_0_DEGC,
        }
    }

    /// Current drift, metres.
    pub fn drift_m(&self) -> f64 {
        self.drift_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isa_matches_the_standard_table() {
        assert!((isa_pressure_pa(0.0) - 101_325.0).abs() < 1e-9);
        // ICAO standard atmosphere: 1000 m -> 89 874.6 Pa, 8.5 °C; 5000 m -> 54 019.9 Pa.
        assert!((isa_pressure_pa(1000.0) - 89_874.6).abs() < 1.0, "{}", isa_pressure_pa(1000.0));
        assert!((isa_pressure_pa(5000.0) - 54_019.9).abs() < 2.0, "{}", isa_pressure_pa(5000.0));
        assert!((isa_temperature_k(1000.0) - KELVIN_AT_0_DEGC - 8.5).abs() < 1e-9);
    }

    #[test]
    fn readings_are_truth_plus_noise_with_consistent_pressure() {
        let mut baro = Barometer::new(BarometerConfig { drift_walk_m_per_sqrt_s: 0.0, ..Default::default() }, 4, 2);
        let samples: Vec<BaroSample> = (0..10_000).map(|_| baro.measure(180.0, 0.02)).collect();
        let mean = samples.iter().map(|s| s.alt_msl_m).sum::<f64>() / 1e4;
        let std = (samples.iter().map(|s| (s.alt_msl_m - mean).powi(2)).sum::<f64>() / 1e4).sqrt();
        eprintln!("baro mean {mean:.4} m, std {std:.4} m (configured 0.2)");
        assert!((mean - 180.0).abs() < 0.01 && (std / 0.2 - 1.0).abs() < 0.05);
        let s = samples[0];
        assert!((s.pressure_pa - isa_pressure_pa(s.alt_msl_m)).abs() < 1e-9);
        // ~12 Pa per metre near sea level.
        assert!((isa_pressure_pa(180.0) - s.pressure_pa).abs() < 12.0 * 1.0);
        assert!((s.temperature_degc - (15.0 - 0.0065 * 180.0)).abs() < 1e-9);
    }

    #[test]
    fn drift_wanders_and_is_reproducible() {
        let run = |seed| {
            let mut baro = Barometer::new(BarometerConfig::default(), seed, 0);
            let alts: Vec<f64> = (0..6000).map(|_| baro.measure(200.0, 0.1).alt_msl_m).collect();
            (alts, baro.drift_m())
        };
        let (a, drift) = run(1);
        assert_ne!(drift, 0.0);
        assert!(drift.abs() < 1.0, "{drift}");
        assert_eq!(a, run(1).0);
        assert_ne!(a, run(2).0);
    }
}
