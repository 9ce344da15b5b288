//! What the router drops from ground stations, said on stderr without letting a peer fill
//! the log: frames refused by signing, bytes that are not MAVLink, frames with a bad
//! checksum, frames from a UDP ground station that found no place. The first refusal from an address is logged at once with its reason (for
//! garbage: which byte, where, and why it is not MAVLink), the following ones are counted
//! and summed up every [`REFUSAL_REPORT_PERIOD`].

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use super::config::{MAX_UDP_GCS, UDP_GCS_LIVENESS};
use sadesim_engine::mavlink::frame::DatagramFrames;
use sadesim_engine::mavlink::signing::{IFLAG_SIGNED, Refusal};

/// How often the refusals from one address are summed up on stderr after the first.
pub(super) const REFUSAL_REPORT_PERIOD: Duration = Duration::from_secs(10);
/// Addresses logged one by one; refusals from further addresses (a flood of spoofed
/// sources) are summed up together, so the log stays bounded.
pub(super) const MAX_LOGGED_SOURCES: usize = 64;

/// What was dropped from a ground station.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Dropped {
    /// A frame refused by MAVLink signing.
    Signing(Refusal),
    /// Bytes that are no part of a MAVLink 2 frame (counted in bytes).
    NotMavlink,
    /// A frame whose checksum does not match.
    BadChecksum,
    /// A frame from a new UDP ground station while [`MAX_UDP_GCS`] live ones hold every place.
    NoPlace,
}

/// Slots in [`Counts`]: the signing reasons, then garbage, bad checksums, no place.
const SLOTS: usize = Refusal::ALL.len() + 3;
const NOT_MAVLINK: usize = Refusal::ALL.len();
const BAD_CHECKSUM: usize = Refusal::ALL.len() + 1;
const NO_PLACE: usize = Refusal::ALL.len() + 2;

impl Dropped {
    fn slot(self) -> usize {
        match self {
            Dropped::Signing(why) => Refusal::ALL.iter().position(|&r| r == why).expect("every reason is listed"),
            Dropped::NotMavlink => NOT_MAVLINK,
            Dropped::BadChecksum => BAD_CHECKSUM,
            Dropped::NoPlace => NO_PLACE,
        }
    }
}

/// Refusals per reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Counts([u64; SLOTS]);

impl Counts {
    fn add(&mut self, why: Dropped, n: u64) {
        self.0[why.slot()] += n;
    }

    fn is_empty(&self) -> bool {
        self.0.iter().all(|&n| n == 0)
    }

    /// "refused 3 more frame(s) and dropped 40 byte(s) that are not MAVLink" (`more`: "more ").
    fn amount(&self, more: &str) -> String {
        let frames: u64 = self.0.iter().enumerate().filter(|(i, _)| *i != NOT_MAVLINK).map(|(_, n)| n).sum();
        let bytes = self.0[NOT_MAVLINK];
        match (frames, bytes) {
            (f, 0) => format!("refused {f} {more}frame(s)"),
            (0, b) => format!("dropped {b} {more}byte(s) that are not MAVLink"),
            (f, b) => format!("refused {f} {more}frame(s) and dropped {b} byte(s) that are not MAVLink"),
        }
    }

    /// "unsigned 3, bad signature 1, not MAVLink 40 bytes"
    fn describe(&self) -> String {
        let name = |slot: usize, n: u64| match slot {
            NOT_MAVLINK => format!("not MAVLink {n} bytes"),
            BAD_CHECKSUM => format!("bad checksum {n}"),
            NO_PLACE => format!("no place among the UDP ground stations {n}"),
            i => format!("{} {n}", Refusal::ALL[i]),
        };
        let parts: Vec<String> =
            self.0.iter().enumerate().filter(|(_, n)| **n > 0).map(|(slot, n)| name(slot, *n)).collect();
        parts.join(", ")
    }
}

/// Which refusals to log, so that a ground station sending garbage, a ground station without
/// the key, or a flood of forged frames cannot fill the log: the first refusal from an
/// address is logged at once, the following ones are counted and summed up every
/// [`REFUSAL_REPORT_PERIOD`]. An address with nothing refused over a whole period is
/// forgotten (its next refusal is logged at once again). Time is passed in.
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

    /// The router's segment (for other log lines).
    pub(super) fn segment(&self) -> u32 {
        self.segment
    }

    /// Notes `n` frames (bytes, for garbage) from `source` dropped at `now` for `why`;
    /// returns the line to log at once (the first refusal from this address). `detail`
    /// says what was wrong (the offending byte, the message); asked only for that line.
    pub(super) fn refused(
        &mut self,
        source: SocketAddr,
        why: Dropped,
        n: u64,
        now: Instant,
        detail: impl FnOnce() -> String,
    ) -> Option<String> {
        self.next_report.get_or_insert(now + REFUSAL_REPORT_PERIOD);
        if let Some(counts) = self.sources.get_mut(&source) {
            counts.add(why, n);
            return None;
        }
        if self.sources.len() >= MAX_LOGGED_SOURCES {
            self.others.add(why, n);
            return None;
        }
        self.sources.insert(source, Counts::default());
        let segment = self.segment;
        let period = REFUSAL_REPORT_PERIOD.as_secs();
        let first = match why {
            Dropped::Signing(why) => format!(
                "refused a frame from {source}: {why} (MAVLink signing is on: ground stations must sign with the \
                 run's passphrase)"
            ),
            Dropped::NotMavlink => format!("dropped {n} byte(s) from {source} that are not MAVLink: {}", detail()),
            Dropped::BadChecksum => format!("dropped {n} frame(s) from {source}: {}", detail()),
            Dropped::NoPlace => format!(
                "refused {n} frame(s) from the new UDP ground station {source}: all {MAX_UDP_GCS} places are held by \
                 ground stations heard within the last {} s (it gets no telemetry; a place frees when its station is \
                 silent for longer)",
                UDP_GCS_LIVENESS.as_secs()
            ),
        };
        Some(format!(
            "MAVLink router, segment {segment}: {first}; further refusals from {source} are summed up every {period} s"
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
            if counts.is_empty() {
                return false;
            }
            let line = format!(
                "MAVLink router, segment {segment}: {} from {source} in the last {period} s: {}",
                counts.amount("more "),
                counts.describe()
            );
            lines.insert(*source, line);
            *counts = Counts::default();
            true
        });
        let mut lines: Vec<String> = lines.into_values().collect();
        if !self.others.is_empty() {
            lines.push(format!(
                "MAVLink router, segment {segment}: {} from addresses beyond the first {MAX_LOGGED_SOURCES} in the \
                 last {period} s: {}",
                self.others.amount(""),
                self.others.describe()
            ));
            self.others = Counts::default();
        }
        self.next_report = (!lines.is_empty()).then_some(now + REFUSAL_REPORT_PERIOD);
        lines
    }
}

/// MAVLink 2: the start marker, then 9 header bytes; 2 checksum bytes; 13 signature bytes.
const STX_V2: u8 = 0xFD;
const STX_V1: u8 = 0xFE;
const HEADER_V2: usize = 10;
const CHECKSUM: usize = 2;
const SIGNATURE: usize = 13;

/// What is wrong in `bytes` (one datagram, or one TCP read, as `what` says): the first byte
/// that is no part of a good frame, where it is, and why it starts no frame. For the first
/// refusal's log line; a frame split across two TCP reads may show as cut short.
pub(super) fn describe_bad_bytes(bytes: &[u8], what: &str) -> String {
    // Good frames are found where they lie; the first gap is the problem.
    let base = bytes.as_ptr() as usize;
    let mut at = 0;
    for f in DatagramFrames::new(bytes) {
        if f.bytes.as_ptr() as usize - base > at {
            break;
        }
        at += f.bytes.len();
    }
    let Some(&byte) = bytes.get(at) else {
        return format!("nothing wrong found in a {}-byte {what}", bytes.len());
    };
    let rest = &bytes[at..];
    let problem = match byte {
        STX_V2 if rest.len() < HEADER_V2 => {
            format!("a MAVLink 2 header cut short ({} of {HEADER_V2} bytes)", rest.len())
        }
        STX_V2 => {
            let signature = if rest[2] & IFLAG_SIGNED != 0 { SIGNATURE } else { 0 };
            let len = HEADER_V2 + usize::from(rest[1]) + CHECKSUM + signature;
            let message = u32::from(rest[7]) | u32::from(rest[8]) << 8 | u32::from(rest[9]) << 16;
            if rest.len() < len {
                format!(
                    "a MAVLink 2 frame (message id {message}) cut short: {} of the {len} bytes it declares",
                    rest.len()
                )
            } else {
                format!("a MAVLink 2 frame (message id {message}, {len} bytes) whose checksum does not match")
            }
        }
        STX_V1 => "a MAVLink 1 frame that does not check out (the router forwards MAVLink 2)".into(),
        other => format!("byte 0x{other:02x} is no MAVLink start marker (0xFD; 0xFE for MAVLink 1)"),
    };
    format!("at byte {at} of a {}-byte {what}, {problem}", bytes.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([192, 0, 2, 1], port))
    }

    fn none() -> String {
        String::new()
    }

    #[test]
    fn the_first_refusal_is_logged_then_a_sum_per_period() {
        let mut log = RefusalLog::new(2);
        let t0 = Instant::now();
        let unsigned = Dropped::Signing(Refusal::Unsigned);
        let first = log.refused(addr(1), unsigned, 1, t0, none).expect("logged at once");
        assert!(first.contains("segment 2") && first.contains("192.0.2.1:1: unsigned"), "{first}");
        for _ in 0..40 {
            assert_eq!(log.refused(addr(1), unsigned, 1, t0, none), None);
        }
        assert_eq!(log.refused(addr(1), Dropped::Signing(Refusal::BadSignature), 1, t0, none), None);
        assert!(log.due(t0 + Duration::from_secs(1)).is_empty(), "not before the period");
        let summary = log.due(t0 + REFUSAL_REPORT_PERIOD);
        assert_eq!(summary.len(), 1);
        assert!(summary[0].contains("refused 41 more frame(s) from 192.0.2.1:1"), "{summary:?}");
        assert!(summary[0].ends_with("unsigned 40, bad signature 1"), "{summary:?}");
        // Quiet for a period: forgotten, and its next refusal is logged at once again.
        assert!(log.due(t0 + 2 * REFUSAL_REPORT_PERIOD).is_empty());
        let later = t0 + 3 * REFUSAL_REPORT_PERIOD;
        assert!(log.refused(addr(1), Dropped::Signing(Refusal::OldTimestamp), 1, later, none).is_some());
    }

    #[test]
    fn a_flood_of_sources_is_summed_up_in_one_line() {
        let mut log = RefusalLog::new(0);
        let t0 = Instant::now();
        let bad = Dropped::Signing(Refusal::BadSignature);
        let logged = (0..1000).filter_map(|p| log.refused(addr(p), bad, 1, t0, none)).count();
        assert_eq!(logged, MAX_LOGGED_SOURCES);
        let summary = log.due(t0 + REFUSAL_REPORT_PERIOD);
        assert_eq!(summary.len(), 1, "the first {MAX_LOGGED_SOURCES} refused once each: nothing more to say");
        assert!(summary[0].contains("refused 936 frame(s) from addresses beyond the first 64"), "{summary:?}");
    }

    #[test]
    fn garbage_is_logged_once_with_its_byte_then_summed_in_bytes() {
        let mut log = RefusalLog::new(0);
        let t0 = Instant::now();
        let first = log
            .refused(addr(7), Dropped::NotMavlink, 300, t0, || describe_bad_bytes(b"GET / HTTP/1.0", "datagram"))
            .expect("logged at once");
        assert!(
            first.contains(
                "dropped 300 byte(s) from 192.0.2.1:7 that are not MAVLink: at byte 0 of a 14-byte datagram, byte \
                 0x47 is no MAVLink start marker"
            ),
            "{first}"
        );
        assert_eq!(log.refused(addr(7), Dropped::NotMavlink, 20, t0, || panic!("not asked again")), None);
        assert_eq!(log.refused(addr(7), Dropped::BadChecksum, 2, t0, || panic!("not asked again")), None);
        let summary = log.due(t0 + REFUSAL_REPORT_PERIOD);
        assert_eq!(
            summary,
            ["MAVLink router, segment 0: refused 2 more frame(s) and dropped 20 byte(s) that are not MAVLink from \
              192.0.2.1:7 in the last 10 s: not MAVLink 20 bytes, bad checksum 2"]
        );
    }

    #[test]
    fn bad_bytes_are_described_by_what_they_start() {
        use ::mavlink::MavHeader;
        use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavMessage};
        let good = sadesim_engine::mavlink::frame::encode(
            MavHeader { system_id: 255, component_id: 190, sequence: 0 },
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        );
        let mut bad_crc = good.clone();
        *bad_crc.last_mut().unwrap() ^= 0xFF;
        let n = good.len();
        let cases: [(Vec<u8>, String); 4] = [
            (
                [good.clone(), bad_crc].concat(),
                format!(
                    "at byte {n} of a {}-byte datagram, a MAVLink 2 frame (message id 0, {n} bytes) whose checksum does not match",
                    2 * n
                ),
            ),
            (
                [good.clone(), good[..n - 3].to_vec()].concat(),
                format!(
                    "at byte {n} of a {}-byte datagram, a MAVLink 2 frame (message id 0) cut short: {} of the {n} bytes it declares",
                    2 * n - 3,
                    n - 3
                ),
            ),
            (good[..4].to_vec(), "at byte 0 of a 4-byte datagram, a MAVLink 2 header cut short (4 of 10 bytes)".into()),
            (vec![0xFE, 9, 0, 0], "at byte 0 of a 4-byte datagram, a MAVLink 1 frame that does not check out".into()),
        ];
        for (bytes, want) in cases {
            let got = describe_bad_bytes(&bytes, "datagram");
            assert!(got.starts_with(&want), "{got}\nwanted {want}");
        }
    }
}
