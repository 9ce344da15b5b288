//! MAVLink 2 signing on the router's ground-station side: what the router keeps to check
//! ground stations' frames and sign its own, and the rate-limited log of refusals.
//!
//! The drone side stays unsigned: the drones' endpoints are inside the run.

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use sadesim_engine::mavlink::signing::{Refusal, SecretKey, Signer, Verifier};

/// The link id in the signatures of frames the router sends to ground stations. Receivers
/// keep one replay stream per (link id, system id, component id); the system and component
/// ids are the drones', so one link id serves every ground station.
pub const ROUTER_LINK_ID: u8 = 0;
/// SETUP_SIGNING, which the router never passes on when it signs (it holds the key).
pub(super) const SETUP_SIGNING_ID: u32 = 256;
/// How often the refusals from one address are summed up on stderr after the first.
pub(super) const REFUSAL_REPORT_PERIOD: Duration = Duration::from_secs(10);
/// Addresses logged one by one; refusals from further addresses (a flood of spoofed
/// sources) are summed up together, so the log stays bounded.
pub(super) const MAX_LOGGED_SOURCES: usize = 64;

/// Signing state shared by the router's threads.
#[derive(Debug)]
pub(super) struct GcsSigning {
    /// Signs drone frames on their way to the ground stations.
    pub(super) signer: Signer,
    /// Checks ground stations' frames (one replay table for UDP and TCP: a frame captured
    /// on one and replayed on the other is still a replay).
    pub(super) verifier: Mutex<Verifier>,
    pub(super) refusals: Mutex<RefusalLog>,
}

impl GcsSigning {
    pub(super) fn new(key: SecretKey, segment: u32) -> Self {
        Self {
            signer: Signer::new(key.clone(), ROUTER_LINK_ID),
            verifier: Mutex::new(Verifier::new(key)),
            refusals: Mutex::new(RefusalLog::new(segment)),
        }
    }
}

/// Refusals per reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Counts([u64; Refusal::ALL.len()]);

impl Counts {
    fn add(&mut self, why: Refusal) {
        self.0[Refusal::ALL.iter().position(|&r| r == why).expect("every reason is listed")] += 1;
    }

    fn total(&self) -> u64 {
        self.0.iter().sum()
    }

    /// "unsigned 3, bad signature 1"
    fn describe(&self) -> String {
        let parts: Vec<String> =
            Refusal::ALL.iter().zip(self.0).filter(|(_, n)| *n > 0).map(|(r, n)| format!("{r} {n}")).collect();
        parts.join(", ")
    }
}

/// Which refusals to log, so that a ground station without the key (or a flood of forged
/// frames) cannot fill the log: the first refusal from an address is logged at once, the
/// following ones are counted and summed up every [`REFUSAL_REPORT_PERIOD`]. An address
/// with nothing refused over a whole period is forgotten (its next refusal is logged at
/// once again). Time is passed in.
#[derive(Debug)]
pub(super) struct RefusalLog {
    segment: u32,
    /// Refusals not yet reported, per address logged one by one.
    sources: HashMap<SocketAddr, Counts>,
    /// Refusals from addresses beyond [`MAX_LOGGED_SOURCES`].
    others: Counts,
    /// When the counts are reported next; `None` while there is nothing to report.
    next_report: Option<Instant>,
}

impl RefusalLog {
    pub(super) fn new(segment: u32) -> Self {
        Self { segment, sources: HashMap::new(), others: Counts::default(), next_report: None }
    }

    /// Notes a frame from `source` refused at `now`; returns the line to log at once (the
    /// first refusal from this address).
    pub(super) fn refused(&mut self, source: SocketAddr, why: Refusal, now: Instant) -> Option<String> {
        self.next_report.get_or_insert(now + REFUSAL_REPORT_PERIOD);
        if let Some(counts) = self.sources.get_mut(&source) {
            counts.add(why);
            return None;
        }
        if self.sources.len() >= MAX_LOGGED_SOURCES {
            self.others.add(why);
            return None;
        }
        self.sources.insert(source, Counts::default());
        Some(format!(
            "MAVLink router, segment {}: refused a frame from {source}: {why} (MAVLink signing is on: ground \
             stations must sign with the run's passphrase); further refusals from {source} are summed up every {} s",
            self.segment,
            REFUSAL_REPORT_PERIOD.as_secs()
        ))
    }

    /// The summary lines due at `now` (none before the period is over), by address.
    pub(super) fn due(&mut self, now: Instant) -> Vec<String> {
        match self.next_report {
            Some(at) if now >= at => {}
            _ => return Vec::new(),
        }
        let period = REFUSAL_REPORT_PERIOD.as_secs();
        let segment = self.segment;
        let mut lines = BTreeMap::new();
        self.sources.retain(|source, counts| {
            if counts.total() == 0 {
                return false;
            }
            let line = format!(
                "MAVLink router, segment {segment}: refused {} more frame(s) from {source} in the last {period} s: {}",
                counts.total(),
                counts.describe()
            );
            lines.insert(*source, line);
            *counts = Counts::default();
            true
        });
        let mut lines: Vec<String> = lines.into_values().collect();
        if self.others.total() > 0 {
            lines.push(format!(
                "MAVLink router, segment {segment}: refused {} frame(s) from addresses beyond the first \
                 {MAX_LOGGED_SOURCES} in the last {period} s: {}",
                self.others.total(),
                self.others.describe()
            ));
            self.others = Counts::default();
        }
        self.next_report = (!lines.is_empty()).then_some(now + REFUSAL_REPORT_PERIOD);
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([192, 0, 2, 1], port))
    }

    #[test]
    fn the_first_refusal_is_logged_then_a_sum_per_period() {
        let mut log = RefusalLog::new(2);
        let t0 = Instant::now();
        let first = log.refused(addr(1), Refusal::Unsigned, t0).expect("logged at once");
        assert!(first.contains("segment 2") && first.contains("192.0.2.1:1: unsigned"), "{first}");
        for _ in 0..40 {
            assert_eq!(log.refused(addr(1), Refusal::Unsigned, t0), None);
        }
        assert_eq!(log.refused(addr(1), Refusal::BadSignature, t0), None);
        assert!(log.due(t0 + Duration::from_secs(1)).is_empty(), "not before the period");
        let summary = log.due(t0 + REFUSAL_REPORT_PERIOD);
        assert_eq!(summary.len(), 1);
        assert!(summary[0].contains("refused 41 more frame(s) from 192.0.2.1:1"), "{summary:?}");
        assert!(summary[0].ends_with("unsigned 40, bad signature 1"), "{summary:?}");
        // Quiet for a period: forgotten, and its next refusal is logged at once again.
        assert!(log.due(t0 + 2 * REFUSAL_REPORT_PERIOD).is_empty());
        assert!(log.refused(addr(1), Refusal::OldTimestamp, t0 + 3 * REFUSAL_REPORT_PERIOD).is_some());
    }

    #[test]
    fn a_flood_of_sources_is_summed_up_in_one_line() {
        let mut log = RefusalLog::new(0);
        let t0 = Instant::now();
        let logged = (0..1000).filter_map(|p| log.refused(addr(p), Refusal::BadSignature, t0)).count();
        assert_eq!(logged, MAX_LOGGED_SOURCES);
        let summary = log.due(t0 + REFUSAL_REPORT_PERIOD);
        assert_eq!(summary.len(), 1, "the first {MAX_LOGGED_SOURCES} refused once each: nothing more to say");
        assert!(summary[0].contains("refused 936 frame(s) from addresses beyond the first 64"), "{summary:?}");
    }
}
