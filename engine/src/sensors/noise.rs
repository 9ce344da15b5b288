//! Shared noise building blocks: per-sensor random streams, white noise, wandering biases.

use nalgebra::Vector3;
use sadesim_crds::random::{Purpose, Rng};

/// Which sensor a `Purpose::Sensors` sub-stream feeds. IMU, barometer and magnetometer
/// share the drone's `(seed, drone, Purpose::Sensors)` stream; each gets an independent
/// child stream so one sensor's draws never shift or correlate with another's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SensorStream {
    Imu,
    Barometer,
    Magnetometer,
}

/// The child stream of `sensor` for drone `drone_global_index`: seeded with the n-th
/// output of the drone's `Purpose::Sensors` stream (n fixed per sensor, never derived from
/// the enum order, so adding a sensor cannot change recorded runs).
pub(crate) fn sensor_rng(seed: u64, drone_global_index: u32, sensor: SensorStream) -> Rng {
    let n = match sensor {
        SensorStream::Imu => 0,
        SensorStream::Barometer => 1,
        SensorStream::Magnetometer => 2,
    };
    let mut parent = Rng::stream(seed, u64::from(drone_global_index), Purpose::Sensors);
    let child_seed = (0..=n).map(|_| parent.next_u64()).last().unwrap_or_default();
    Rng::stream(child_seed, u64::from(drone_global_index), Purpose::Sensors)
}

/// Three independent N(0, sigma²) draws.
pub(crate) fn normal3(rng: &mut Rng, sigma: f64) -> Vector3<f64> {
    Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma
}

/// Per-sample standard deviation of white noise of density `density` (unit/√Hz) sampled
/// every `dt_s`: σ = density / √dt (unit). 0 for a non-positive dt (no new sample).
pub(crate) fn white_sigma(density: f64, dt_s: f64) -> f64 {
    if dt_s > 0.0 { density / dt_s.sqrt() } else { 0.0 }
}

/// One exact step of a first-order Gauss-Markov bias b' = -b/τ + q·η (unit-intensity η):
///
/// b ← e^{-dt/τ} b + q · sqrt(τ/2 · (1 - e^{-2dt/τ})) · n          [q in unit/√s, τ in s]
///
/// For dt ≪ τ it is a random walk (std q·√t); τ bounds it at q·sqrt(τ/2). τ = ∞ gives the
/// pure random walk b ← b + q·√dt·n. `n` is a standard normal draw. The sensors step
/// through [`GaussMarkov`], which remembers the coefficients; this is the definition the
/// tests hold it to.
#[cfg(test)]
pub(crate) fn gauss_markov_step(b: f64, walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64, n: f64) -> f64 {
    let (decay, sigma) = gauss_markov_coefficients(walk_per_sqrt_s, tau_s, dt_s);
    decay * b + sigma * n
}

/// One Gauss-Markov process's discretisation, remembered: `(e^{-dt/τ}, σ)` of the exact
/// step (b ← e^{-dt/τ} b + σ n, σ = q · sqrt(τ/2 · (1 - e^{-2dt/τ}))) depend only on `(q, τ, dt)`, which stay the same step after step
/// with the fixed physics step, so the two transcendentals are computed when they change
/// instead of every step. The values are the computed ones, bit for bit.
#[derive(Clone, Debug, Default)]
pub(crate) struct GaussMarkov {
    /// `(q, τ, dt)` as bits, and their `(decay, sigma)`.
    last: Option<([u64; 3], (f64, f64))>,
}

impl GaussMarkov {
    fn coefficients(&mut self, walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64) -> (f64, f64) {
        let key = [walk_per_sqrt_s.to_bits(), tau_s.to_bits(), dt_s.to_bits()];
        match self.last {
            Some((k, value)) if k == key => value,
            _ => {
                let value = gauss_markov_coefficients(walk_per_sqrt_s, tau_s, dt_s);
                self.last = Some((key, value));
                value
            }
        }
    }

    /// One exact step of the bias `b` with the standard normal draw `n`.
    pub(crate) fn step(&mut self, b: f64, walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64, n: f64) -> f64 {
        let (decay, sigma) = self.coefficients(walk_per_sqrt_s, tau_s, dt_s);
        decay * b + sigma * n
    }

    /// One exact step on each axis, drawing three normals.
    pub(crate) fn step3(
        &mut self,
        b: Vector3<f64>,
        walk_per_sqrt_s: f64,
        tau_s: f64,
        dt_s: f64,
        rng: &mut Rng,
    ) -> Vector3<f64> {
        let (decay, sigma) = self.coefficients(walk_per_sqrt_s, tau_s, dt_s);
        b.map(|axis| decay * axis + sigma * rng.normal())
    }
}

/// `(e^{-dt/τ}, q · sqrt(τ/2 · (1 - e^{-2dt/τ})))` of the exact step; `(1, q·√dt)` for
/// τ = ∞. Two transcendentals: computed once per step and shared by the axes.
fn gauss_markov_coefficients(walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64) -> (f64, f64) {
    let dt_s = dt_s.max(0.0);
    if tau_s.is_infinite() {
        return (1.0, walk_per_sqrt_s * dt_s.sqrt());
    }
    let decay = (-dt_s / tau_s).exp();
    let sigma = walk_per_sqrt_s * (tau_s / 2.0 * -(-2.0 * dt_s / tau_s).exp_m1()).sqrt();
    (decay, sigma)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The remembered coefficients are the computed ones, for triples asked in turn, again
    /// and after a change of step.
    #[test]
    fn remembered_coefficients_are_the_computed_ones() {
        let mut gm = GaussMarkov::default();
        let triples: Vec<(f64, f64, f64)> = (0..20)
            .map(|i| {
                let tau = if i % 5 == 0 { f64::INFINITY } else { 100.0 + f64::from(i) };
                (0.01 * f64::from(i + 1), tau, 0.001 * f64::from(1 + i % 3))
            })
            .collect();
        for &(q, tau, dt) in triples.iter().chain(&triples) {
            for _ in 0..2 {
                let got = gm.coefficients(q, tau, dt);
                let want = gauss_markov_coefficients(q, tau, dt);
                assert_eq!((got.0.to_bits(), got.1.to_bits()), (want.0.to_bits(), want.1.to_bits()));
                assert_eq!(gm.step(2.0, q, tau, dt, 0.5).to_bits(), gauss_markov_step(2.0, q, tau, dt, 0.5).to_bits());
            }
        }
    }

    #[test]
    fn sensor_streams_are_distinct_and_reproducible() {
        let mut draws: Vec<u64> = [SensorStream::Imu, SensorStream::Barometer, SensorStream::Magnetometer]
            .iter()
            .map(|&s| sensor_rng(5, 3, s).next_u64())
            .collect();
        assert_eq!(draws[0], sensor_rng(5, 3, SensorStream::Imu).next_u64());
        draws.dedup();
        assert_eq!(draws.len(), 3);
        assert_ne!(draws[0], sensor_rng(5, 4, SensorStream::Imu).next_u64());
    }

    #[test]
    fn gauss_markov_is_a_random_walk_for_short_times_and_bounded_for_long() {
        // Over 2000 seeds: std after t is q·sqrt(τ/2·(1 - e^{-2t/τ})).
        let (q, tau) = (0.01, 100.0);
        let std_after = |t_end: f64, tau: f64| {
            let var = (0..2000u64)
                .map(|s| {
                    let mut rng = Rng::stream(s, 0, Purpose::Sensors);
                    let mut b = 0.0;
                    for _ in 0..(t_end as usize) {
                        b = gauss_markov_step(b, q, tau, 1.0, rng.normal());
                    }
                    b * b
                })
                .sum::<f64>()
                / 2000.0;
            var.sqrt()
        };
        let short = std_after(4.0, tau);
        assert!((short / (q * 2.0) - 1.0).abs() < 0.1, "{short}");
        let long = std_after(1000.0, tau);
        assert!((long / (q * (tau / 2.0).sqrt()) - 1.0).abs() < 0.1, "{long}");
        let walk = std_after(400.0, f64::INFINITY);
        assert!((walk / (q * 20.0) - 1.0).abs() < 0.1, "{walk}");
    }
}
