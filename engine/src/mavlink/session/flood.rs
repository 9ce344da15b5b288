//! How much a session takes from each peer: a flood (thousands of COMMAND_LONG, SET_MODE
//! or mission items a second, a pilot's bug or a hostile one) is cut to a budget, so it
//! cannot keep the drone's other peers from being served, fill the reply queue, or cost
//! the shard its windows. What goes over the budget is dropped unread, counted, and said:
//! a STATUSTEXT warning to the drone's peers and a `commandRejected` run event, at the
//! first drop of a flood and then once every [`REPORT_PERIOD_S`] while it lasts.
//!
//! The budget is a token bucket per peer (system id, component id) in simulated time:
//! [`BURST`] frames at once, refilled at [`PER_S`] a simulated second. That is far above
//! what a ground station or an SDK sends (a heartbeat a second, setpoints at 50 Hz, one
//! mission item per round trip, a parameter download of one request), also when the run
//! is slower than real time (at a real-time factor of 0.1 a 50 Hz pilot sends 500 frames
//! per simulated second). Peers are tracked up to [`MAX_PEERS`]; frames from further
//! peers (a flood of forged system ids) share one more bucket, so forging ids gains nothing.
//! PX4 has no such budget: its receive buffer overflows and the kernel drops datagrams,
//! silently.

use crate::events::EventKind;

/// Frames a peer may send at once.
pub const BURST: f64 = 500.0;
/// Frames a peer may send per simulated second, after the burst.
pub const PER_S: f64 = 2500.0;
/// Peers with a bucket of their own.
pub const MAX_PEERS: usize = 16;
/// While a flood lasts, it is reported again this often (simulated seconds).
pub const REPORT_PERIOD_S: f64 = 10.0;

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    /// Simulated time of the last refill.
    at_s: f64,
    /// Frames dropped since the last report.
    unreported: u64,
    /// When the current flood was last reported; `None` outside a flood.
    reported_at_s: Option<f64>,
}

impl Bucket {
    fn full(now_s: f64) -> Self {
        Self { tokens: BURST, at_s: now_s, unreported: 0, reported_at_s: None }
    }

    fn refill(&mut self, now_s: f64) {
        let elapsed = (now_s - self.at_s).max(0.0);
        self.tokens = (self.tokens + elapsed * PER_S).min(BURST);
        self.at_s = self.at_s.max(now_s);
    }

    /// Idle long enough to be as good as a new bucket (nothing to remember).
    fn is_idle(&self) -> bool {
        self.tokens >= BURST && self.reported_at_s.is_none()
    }
}

/// What the session must say about a flood.
#[derive(Debug, Clone, PartialEq)]
pub struct FloodReport {
    /// STATUSTEXT for the drone's peers (at most 50 characters).
    pub status_text: String,
    /// The run event.
    pub event: EventKind,
}

/// The per-peer budgets of one session.
#[derive(Debug, Default)]
pub struct InboundBudget {
    peers: Vec<((u8, u8), Bucket)>,
    /// Shared by peers beyond [`MAX_PEERS`].
    others: Option<Bucket>,
    /// Frames dropped in all.
    pub dropped: u64,
}

impl InboundBudget {
    /// Takes one frame from `peer` at `now_s`: whether to handle it (`false`: drop it), and
    /// what to report when this frame starts a flood or a report of one is due.
    pub fn take(&mut self, peer: (u8, u8), now_s: f64) -> (bool, Option<FloodReport>) {
        let bucket = self.bucket(peer, now_s);
        bucket.refill(now_s);
        let accepted = bucket.tokens >= 1.0;
        if accepted {
            bucket.tokens -= 1.0;
        } else {
            bucket.unreported += 1;
        }
        let due = bucket.reported_at_s.is_some_and(|t| now_s - t >= REPORT_PERIOD_S);
        let report = match bucket.reported_at_s {
            // The first frame dropped: a flood starts.
            None if !accepted => {
                bucket.reported_at_s = Some(now_s);
                bucket.unreported = 0;
                Some(report(peer, 1, true))
            }
            // A period since the last report: what was dropped since, or the flood is over.
            Some(_) if due => {
                let n = std::mem::take(&mut bucket.unreported);
                bucket.reported_at_s = (n > 0).then_some(now_s);
                (n > 0).then(|| report(peer, n, false))
            }
            _ => None,
        };
        if !accepted {
            self.dropped += 1;
        }
        (accepted, report)
    }

    fn bucket(&mut self, peer: (u8, u8), now_s: f64) -> &mut Bucket {
        if let Some(i) = self.peers.iter().position(|(p, _)| *p == peer) {
            return &mut self.peers[i].1;
        }
        if self.peers.len() < MAX_PEERS {
            self.peers.push((peer, Bucket::full(now_s)));
            return &mut self.peers.last_mut().expect("just pushed").1;
        }
        // An idle peer's place is taken; otherwise the frame shares the others' bucket.
        let idle = self.peers.iter_mut().position(|(_, b)| {
            b.refill(now_s);
            b.is_idle()
        });
        if let Some(i) = idle {
            self.peers[i] = (peer, Bucket::full(now_s));
            return &mut self.peers[i].1;
        }
        self.others.get_or_insert_with(|| Bucket::full(now_s))
    }
}

fn report(peer: (u8, u8), dropped: u64, first: bool) -> FloodReport {
    let (system, component) = peer;
    let (status_text, reason) = if first {
        (
            format!("MAVLink flood from {system}/{component}: dropping"),
            format!(
                "flood: over {PER_S} frames per simulated second (bursts of {BURST}); frames from this peer over \
                 the limit are dropped unread"
            ),
        )
    } else {
        (
            format!("MAVLink flood from {system}/{component}: {dropped} dropped"),
            format!("flood: {dropped} more frames over the limit of {PER_S} per simulated second dropped"),
        )
    };
    FloodReport {
        status_text,
        event: EventKind::CommandRejected { command: format!("mavlink:{system}/{component}"), reason },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_burst_passes_then_the_rate_and_a_flood_is_reported_once_per_period() {
        let mut b = InboundBudget::default();
        let peer = (255, 190);
        for _ in 0..BURST as usize {
            assert_eq!(b.take(peer, 0.0), (true, None));
        }
        let (false, Some(first)) = b.take(peer, 0.0) else { panic!("the first drop is reported") };
        assert_eq!(first.status_text, "MAVLink flood from 255/190: dropping");
        assert!(first.status_text.len() <= 50);
        for _ in 0..1000 {
            assert_eq!(b.take(peer, 0.0), (false, None), "reported once");
        }
        // 20 ms later, 50 more frames are taken.
        let taken = (0..1000).filter(|_| b.take(peer, 0.02).0).count();
        assert_eq!(taken, 50);
        // Another peer is not affected.
        assert_eq!(b.take((254, 190), 0.02), (true, None));
        // A period later: what was dropped since.
        let (true, Some(count)) = b.take(peer, REPORT_PERIOD_S) else { panic!("a count is due") };
        assert_eq!(count.status_text, "MAVLink flood from 255/190: 1950 dropped");
        assert_eq!(b.dropped, 1 + 1000 + 950);
        // A quiet period: the flood is over, and the next drop starts a new one.
        assert_eq!(b.take(peer, 2.0 * REPORT_PERIOD_S), (true, None));
        let drops = (0..1000).filter_map(|_| b.take(peer, 2.0 * REPORT_PERIOD_S).1).collect::<Vec<_>>();
        assert_eq!(drops.len(), 1, "{drops:?}");
        assert!(drops[0].status_text.ends_with("dropping"));
    }

    #[test]
    fn forged_system_ids_share_one_bucket() {
        let mut b = InboundBudget::default();
        let taken = (0..20_000u32).filter(|i| b.take(((i % 250) as u8, 1), 0.0).0).count();
        // The first MAX_PEERS ids have buckets of their own (80 frames each, all taken);
        // the other 234 ids share one burst.
        assert_eq!(taken, MAX_PEERS * 80 + BURST as usize);
    }
}
