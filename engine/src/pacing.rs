//! Clock pacing: how simulated time relates to the wall clock (DESIGN §5). Pure: the
//! coordinator passes wall time in, so tests need no sleeping.

use std::time::{Duration, Instant};

use sadesim_crds::run::{Clock, ClockMode};

/// The wall clock a paced run follows. The engine reads it and waits on it only through
/// this trait; `sim_worker::transport::SystemClock` is the machine's.
pub trait WallClock {
    /// The current instant.
    fn now(&self) -> Instant;
    /// Blocks the calling thread for `duration`.
    fn sleep(&self, duration: Duration);
}

/// Decides how long to wait before simulating up to a sim time.
#[derive(Clone, Copy, Debug)]
pub struct Pacer {
    /// Simulated seconds per wall second; `None` = as fast as possible.
    factor: Option<f64>,
}

impl Pacer {
    pub fn new(clock: &Clock) -> Self {
        let factor = match clock.mode {
            ClockMode::Realtime => Some(1.0),
            ClockMode::Scaled => Some(clock.factor.unwrap_or(1.0)),
            ClockMode::AsFastAsPossible => None,
        };
        Self { factor }
    }

    /// Wall time to wait before releasing the window that ends at `sim_time_s`, given the
    /// wall time `elapsed` since the run started. Zero when behind (we never skip physics
    /// to catch up: a slow machine simply runs slower than requested, and the real-time
    /// factor in the status shows it).
    pub fn wait_before(&self, sim_time_s: f64, elapsed: Duration) -> Duration {
        self.due_after(sim_time_s).map_or(Duration::ZERO, |due| due.saturating_sub(elapsed))
    }

    /// When simulated time `sim_time_s` is due, as wall time since the clock started;
    /// `None` when the run is not paced (as fast as possible: nothing is ever late).
    pub fn due_after(&self, sim_time_s: f64) -> Option<Duration> {
        self.factor.map(|f| Duration::from_secs_f64((sim_time_s / f).max(0.0)))
    }

    pub fn is_paced(&self) -> bool {
        self.factor.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realtime_waits_until_wall_clock_catches_up() {
        let p = Pacer::new(&Clock { mode: ClockMode::Realtime, factor: None });
        assert_eq!(p.wait_before(2.0, Duration::from_millis(1500)), Duration::from_millis(500));
        assert_eq!(p.wait_before(2.0, Duration::from_secs(3)), Duration::ZERO, "behind: no wait, no skip");
    }

    #[test]
    fn scaled_divides_and_afap_never_waits() {
        let p = Pacer::new(&Clock { mode: ClockMode::Scaled, factor: Some(4.0) });
        assert_eq!(p.wait_before(4.0, Duration::ZERO), Duration::from_secs(1));
        assert_eq!(p.due_after(6.0), Some(Duration::from_millis(1500)));
        let p = Pacer::new(&Clock { mode: ClockMode::AsFastAsPossible, factor: None });
        assert_eq!(p.wait_before(1000.0, Duration::ZERO), Duration::ZERO);
        assert_eq!(p.due_after(1000.0), None);
        assert!(!p.is_paced());
    }
}
