//! Why a run ended and why a drone crashed, as typed values with the strings the run's
//! outputs carry: `runEnded.reason` in `events.jsonl` and the recordings' logs,
//! `summary.json`'s `endReason`, the coordinator's stop requests (stdin line, Pod
//! annotation) and `crashed.with`.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// How a run ended. Serialised as its [`fmt::Display`] string (`duration`, `pilotExited`,
/// `shardFailed: shard 1 failed: connection closed`, ...); any other string reads back as
/// [`EndReason::Requested`], so a reason written by a newer or older runner still parses.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub enum EndReason {
    /// The scenario's `duration` of simulated time passed.
    #[default]
    Duration,
    /// The runner was interrupted (Ctrl-C, SIGTERM): the run ended after the current window.
    Interrupted,
    /// The pilot exited and `pilot.onExit` is `endRun`.
    PilotExited,
    /// The pilot could not be started (the run then fails).
    PilotFailed,
    /// The operator asked: `spec.abort: true`.
    Aborted,
    /// The operator asked: the SimulationRun was deleted.
    Deleted,
    /// The operator asked: another role (a router, the pilot's image) failed.
    RoleFailed,
    /// The operator asked: the spec no longer plans.
    InvalidSpec,
    /// The operator asked: Kueue evicted the run's Workload.
    Evicted,
    /// A shard failed; the text says which and how (`shard 1 (10.77.0.3:40122) failed:
    /// connection closed`). Written `shardFailed: <text>`.
    ShardFailed(String),
    /// The pilot sent no MAVLink to any drone it flies within `spec.pilot.connectTimeoutS`
    /// of wall time while the run held at the release (the run then fails); the text says
    /// so (`the pilot did not connect within 300 s: ...`). Written `pilotNotConnected: <text>`.
    PilotNotConnected(String),
    /// A stop request with a reason of the requester's own (the `sadesim.io/stop`
    /// annotation set by hand, a stdin line), kept as given.
    Requested(String),
}

/// The prefix of [`EndReason::ShardFailed`]'s string, machine-matchable.
pub const SHARD_FAILED: &str = "shardFailed";

/// The prefix of [`EndReason::PilotNotConnected`]'s string, machine-matchable.
pub const PILOT_NOT_CONNECTED: &str = "pilotNotConnected";

impl EndReason {
    /// The reasons without text, with their strings (what [`FromStr`] recognises).
    const NAMED: [(EndReason, &'static str); 9] = [
        (EndReason::Duration, "duration"),
        (EndReason::Interrupted, "interrupted"),
        (EndReason::PilotExited, "pilotExited"),
        (EndReason::PilotFailed, "pilotFailed"),
        (EndReason::Aborted, "aborted"),
        (EndReason::Deleted, "deleted"),
        (EndReason::RoleFailed, "roleFailed"),
        (EndReason::InvalidSpec, "invalidSpec"),
        (EndReason::Evicted, "evicted"),
    ];

    /// True when the run failed rather than ended as asked: a shard or the pilot failed, or
    /// the pilot never connected.
    pub fn is_failure(&self) -> bool {
        matches!(self, EndReason::ShardFailed(_) | EndReason::PilotFailed | EndReason::PilotNotConnected(_))
    }
}

impl fmt::Display for EndReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EndReason::ShardFailed(what) => write!(f, "{SHARD_FAILED}: {what}"),
            EndReason::PilotNotConnected(what) => write!(f, "{PILOT_NOT_CONNECTED}: {what}"),
            EndReason::Requested(reason) => f.write_str(reason),
            named => {
                let name = Self::NAMED.iter().find(|(r, _)| r == named).map(|(_, s)| *s);
                f.write_str(name.expect("every variant without text is in NAMED"))
            }
        }
    }
}

impl FromStr for EndReason {
    type Err = std::convert::Infallible;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Some((reason, _)) = Self::NAMED.iter().find(|(_, name)| *name == s) {
            return Ok(reason.clone());
        }
        let text = |prefix: &str| s.strip_prefix(prefix).and_then(|rest| rest.strip_prefix(": ")).map(str::to_string);
        Ok(match (text(SHARD_FAILED), text(PILOT_NOT_CONNECTED)) {
            (Some(what), _) => EndReason::ShardFailed(what),
            (_, Some(what)) => EndReason::PilotNotConnected(what),
            _ => EndReason::Requested(s.to_string()),
        })
    }
}

impl From<&str> for EndReason {
    fn from(s: &str) -> Self {
        let Ok(reason) = s.parse();
        reason
    }
}

impl Serialize for EndReason {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for EndReason {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = String::deserialize(deserializer)?;
        Ok(EndReason::from(text.as_str()))
    }
}

/// What a drone crashed into (`crashed.with`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[serde(rename_all = "camelCase")]
pub enum CrashCause {
    /// It touched down faster than the landing gear takes.
    Ground,
    /// Its rotor disc touched a building.
    Building,
}

impl CrashCause {
    /// The cause's name in events and messages (serde's name, without serializing).
    pub fn as_str(self) -> &'static str {
        match self {
            CrashCause::Ground => "ground",
            CrashCause::Building => "building",
        }
    }
}

impl fmt::Display for CrashCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn end_reasons_keep_their_strings_both_ways() {
        for (reason, name) in EndReason::NAMED {
            assert_eq!(reason.to_string(), name);
            assert_eq!(EndReason::from(name), reason);
            assert_eq!(serde_json::to_string(&reason).unwrap(), format!("\"{name}\""));
        }
        let failed = EndReason::ShardFailed("shard 1 (10.0.0.3:4000) failed: connection closed".into());
        let text = "shardFailed: shard 1 (10.0.0.3:4000) failed: connection closed";
        assert_eq!(failed.to_string(), text);
        assert_eq!(EndReason::from(text), failed);
        assert_eq!(serde_json::from_str::<EndReason>(&format!("\"{text}\"")).unwrap(), failed);
    }

    #[test]
    fn a_pilot_that_never_connected_keeps_its_text_and_is_a_failure() {
        let text = "pilotNotConnected: the pilot did not connect within 5 s: no MAVLink reached any of its 2 drones";
        let reason = EndReason::from(text);
        assert_eq!(reason, EndReason::PilotNotConnected(text["pilotNotConnected: ".len()..].to_string()));
        assert_eq!(reason.to_string(), text);
        assert!(reason.is_failure());
        assert_eq!(EndReason::from("pilotNotConnectedx"), EndReason::Requested("pilotNotConnectedx".into()));
    }

    #[test]
    fn other_reasons_are_kept_as_requested() {
        assert_eq!(EndReason::from("operatorSaidSo"), EndReason::Requested("operatorSaidSo".into()));
        assert_eq!(EndReason::from("operatorSaidSo").to_string(), "operatorSaidSo");
        // Only the exact prefix with its separator is a shard failure.
        assert_eq!(EndReason::from("shardFailedx"), EndReason::Requested("shardFailedx".into()));
        assert!(EndReason::from("shardFailed: shard 0 failed: x").is_failure());
        assert!(!EndReason::Aborted.is_failure());
    }

    #[test]
    fn crash_causes_serialise_as_before() {
        assert_eq!(serde_json::to_string(&CrashCause::Building).unwrap(), "\"building\"");
        assert_eq!(serde_json::from_str::<CrashCause>("\"ground\"").unwrap(), CrashCause::Ground);
        assert_eq!(CrashCause::Ground.as_str(), "ground");
    }
}
