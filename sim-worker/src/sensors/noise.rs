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
/// pure random walk b ← b + q·√dt·n. `n` is a standard normal draw.
pub(crate) fn gauss_markov_step(b: f64, walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64, n: f64) -> f64 {
    let (decay, sigma) = gauss_markov_coefficients(walk_per_sqrt_s, tau_s, dt_s);
    decay * b + sigma * n
}

/// `(e^{-dt/τ}, q · sqrt(τ/2 · (1 - e^{-2dt/τ})))` of [`gauss_markov_step`]; `(1, q·√dt)` for
/// τ = ∞. Two transcendentals, which depend only on `(q, τ, dt)`: with the fixed physics
/// step every sensor asks the same few triples every step, so the last [`MEMO`] triples
/// of this thread are remembered and their coefficients reused, bit for bit.
fn gauss_markov_coefficients(walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64) -> (f64, f64) {
    let key = [walk_per_sqrt_s.to_bits(), tau_s.to_bits(), dt_s.to_bits()];
    COEFFICIENTS.with(|memo| {
        let mut memo = memo.borrow_mut();
        if let Some(&(_, value)) = memo.entries.iter().flatten().find(|(k, _)| *k == key) {
            return value;
        }
        let value = compute_gauss_markov_coefficients(walk_per_sqrt_s, tau_s, dt_s);
        let slot = memo.next;
        memo.entries[slot] = Some((key, value));
        memo.next = (slot + 1) % MEMO;
        value
    })
}

/// How many `(q, τ, dt)` triples a thread remembers: IMU accel and gyro biases, the
/// magnetometer's, the barometer's drift and GNSS at their own steps fit.
const MEMO: usize = 8;

/// `(q, τ, dt)` as bits, and their `(decay, sigma)`.
type Entry = ([u64; 3], (f64, f64));

#[derive(Default)]
struct Memo {
    entries: [Option<Entry>; MEMO],
    next: usize,
}

thread_local! {
    static COEFFICIENTS: std::cell::RefCell<Memo> = std::cell::RefCell::new(Memo::default());
}

fn compute_gauss_markov_coefficients(walk_per_sqrt_s: f64, tau_s: f64, dt_s: f64) -> (f64, f64) {
    let dt_s = dt_s.max(0.0);
    if tau_s.is_infinite() {
        return (1.0, walk_per_sqrt_s * dt_s.sqrt());
    }
    let decay = (-dt_s / tau_s).exp();
    let sigma = walk_per_sqrt_s * (tau_s / 2.0 * -(-2.0 * dt_s / tau_s).exp_m1()).sqrt();
    (decay, sigma)
}

/// [`gauss_markov_step`] on each axis, drawing three normals.
pub(crate) fn gauss_markov_step3(
    b: Vector3<f64>,
    walk_per_sqrt_s: f64,
    tau_s: f64,
    dt_s: f64,
    rng: &mut Rng,
) -> Vector3<f64> {
    let (decay, sigma) = gauss_markov_coefficients(walk_per_sqrt_s, tau_s, dt_s);
    b.map(|axis| decay * axis + sigma * rng.normal())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The remembered coefficients are the computed ones, for more triples than the memo
    /// holds, asked in turn and again.
    #[test]
    fn remembered_coefficients_are_the_computed_ones() {
        let triples: Vec<(f64, f64, f64)> = (0..20)
            .map(|i| {
                (
                    0.01 * f64::from(i + 1),
                    if i % 5 == 0 { f64::INFINITY } else { 100.0 + f64::from(i) },
                    0.001 * f64::from(1 + i % 3),
                )
            })
            .collect();
        for _ in 0..3 {
            for &(q, tau, dt) in triples.iter().chain(triples.iter().take(3)) {
                let got = gauss_markov_coefficients(q, tau, dt);
                let want = compute_gauss_markov_coefficients(q, tau, dt);
                assert_eq!((got.0.to_bits(), got.1.to_bits()), (want.0.to_bits(), want.1.to_bits()));
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
