//! What recording costs: the CPU time the recorder's threads spend on each kind of file,
//! measured inside the run (`summary.json` `recordingCpuS`, `sadesim bench --recording`):
//! the caller's thread for `events.jsonl` and the trajectories, the `recorder` thread
//! ([`super::StreamWriter`]) for MCAP and ULog.
//!
//! Measured with the thread's CPU clock (`CLOCK_THREAD_CPUTIME_ID`: user + system time of
//! this thread only), so other threads (shards, routers) and time spent waiting do not
//! count. Each reading is one system call: one per kind of file per sync window, plus one.

pub use sadesim_crds::outcome::summary::RecordingCost;

/// CPU time of the calling thread so far, s.
fn thread_cpu_s() -> f64 {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// A stopwatch of this thread's CPU time split into consecutive laps: each
/// [`Lap::add_to`] charges the time since the previous one (or the start) to an account,
/// so consecutive pieces of work cost one clock reading each.
#[derive(Debug)]
pub struct Lap {
    last_s: f64,
}

impl Lap {
    pub fn start() -> Self {
        Self { last_s: thread_cpu_s() }
    }

    /// Adds the CPU time since the previous lap to `*account`, s.
    pub fn add_to(&mut self, account: &mut f64) {
        let now = thread_cpu_s();
        *account += now - self.last_s;
        self.last_s = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laps_count_work_on_this_thread_and_not_sleep() {
        let (mut busy, mut asleep) = (0.0, 0.0);
        let mut lap = Lap::start();
        // A fixed amount of work (tens of ms), whatever else the machine is doing.
        let mut x = 0u64;
        for _ in 0..20_000_000 {
            x = std::hint::black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1));
        }
        std::hint::black_box(x);
        lap.add_to(&mut busy);
        std::thread::sleep(std::time::Duration::from_millis(50));
        lap.add_to(&mut asleep);
        assert!(busy > 0.002, "20 M multiply-adds measured {busy} s");
        assert!(asleep < busy / 10.0, "sleeping 50 ms measured {asleep} s, 20 ms of work {busy} s");
    }
}
