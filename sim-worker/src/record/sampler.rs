//! The sampling rule every recorded stream shares, so rows and messages line up across
//! files and across runs whatever the sync window.

/// A stream sampled at `hz` per simulated second, at sync-window boundaries: a sample at
/// the first window at or after each multiple of the period, at most one per window.
/// A run of T seconds thus has T x hz samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampler {
    hz: f64,
    /// Simulated time of the next sample, s.
    next_s: f64,
}

impl Sampler {
    /// First sample one period after the start.
    pub fn new(hz: f64) -> Self {
        Self { hz, next_s: 1.0 / hz }
    }

    /// First sample at the first window (time 0).
    pub fn including_start(hz: f64) -> Self {
        Self { hz, next_s: 0.0 }
    }

    /// Whether the window at `time_s` takes a sample (and if so, schedules the next).
    pub fn due(&mut self, time_s: f64) -> bool {
        if time_s + 1e-9 < self.next_s {
            return false;
        }
        self.next_s = ((time_s * self.hz + 1e-9).floor() + 1.0) / self.hz;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::Sampler;

    #[test]
    fn samples_at_the_first_window_at_or_after_each_multiple_of_the_period() {
        // 10 Hz over 15 ms windows: 0.105 is the first window at or after 0.1, and so on.
        let mut s = Sampler::new(10.0);
        let due: Vec<f64> = (1..=100).map(|k| f64::from(k) * 0.015).filter(|&t| s.due(t)).collect();
        let expected = [0.105, 0.2100, 0.3000, 0.405, 0.51, 0.6, 0.705, 0.81, 0.9, 1.005, 1.11, 1.2, 1.305, 1.41, 1.5];
        assert_eq!(due.len(), expected.len(), "{due:?}");
        for (a, b) in due.iter().zip(expected) {
            assert!((a - b).abs() < 1e-9, "{due:?}");
        }
        let mut from_start = Sampler::including_start(10.0);
        assert!(from_start.due(0.0) && !from_start.due(0.05) && from_start.due(0.1));
    }
}
