//! The pilot process of a run: `pilot.json` (what happened to it, a local run), the `pilot`
//! section of `summary.json` (how it ended and whether that was as `spec.pilot.expectedExit`
//! asks), and the judgement of its exit shared by `sadesim run` and the operator.

use serde::{Deserialize, Serialize};

use super::verdict::{CriterionResult, RunVerdict};
use crate::run::{ExpectedExit, PilotExit};

/// What happened to the pilot: `pilot.json` in the output folder.
///
/// Simulated times are those the runner had seen when it acted: the end of the window in
/// which it noticed (in-process), or the coordinator's latest report, at most about one
/// simulated second old (`--processes`).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct PilotRecord {
    /// `spec.pilot.command`.
    pub command: Vec<String>,
    /// Working directory (the scenario file's folder).
    pub working_dir: String,
    pub on_exit: PilotExit,
    /// `spec.pilot.expectedExit` (default `success`).
    #[serde(default)]
    pub expected_exit: ExpectedExit,
    /// The log file, in the output folder.
    pub log: String,
    /// Process id while it ran.
    pub pid: Option<u32>,
    /// Simulated time at which the pilot was started, s; `None` when the run ended before
    /// the pilots were released.
    pub started_at_s: Option<f64>,
    /// Simulated time at which the pilot's exit was seen (or the runner stopped it), s.
    pub exited_at_s: Option<f64>,
    /// Wall-clock seconds from the start of the run to the exit (or the stop).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exited_at_wall_s: Option<f64>,
    /// Exit code when the pilot exited normally.
    pub exit_code: Option<i32>,
    /// Signal number when a signal ended it (15 SIGTERM, 9 SIGKILL).
    pub signal: Option<i32>,
    /// True when the run ended first and the runner stopped the pilot.
    pub stopped_by_runner: bool,
}

impl PilotRecord {
    /// One line for the terminal, e.g. `started at 0.02 s, exited with code 0 at 12.30 s`.
    pub fn describe(&self) -> String {
        let Some(started) = self.started_at_s else {
            return "not started: the run ended before the pilots were released".into();
        };
        let how = exit_words(self.exit_code, self.signal);
        let at = self.exited_at_s.unwrap_or(started);
        let wall = self.exited_at_wall_s.map(|w| format!(" ({w:.1} s wall)")).unwrap_or_default();
        if self.stopped_by_runner {
            format!("started at {started:.2} s, still running at the end of the run, stopped ({how})")
        } else {
            format!("started at {started:.2} s, exited with {how} at {at:.2} s{wall}")
        }
    }

    /// How the pilot ended, for [`ExpectedExit::judge`].
    pub fn end(&self) -> PilotEnd {
        match (self.started_at_s, self.stopped_by_runner) {
            (None, _) => PilotEnd::NotStarted,
            (Some(_), true) => PilotEnd::StillRunning,
            (Some(_), false) => PilotEnd::Exited { code: self.exit_code, signal: self.signal },
        }
    }

    /// The `pilot` section of `summary.json`, with `log_tail` (the last lines of the log).
    pub fn outcome(&self, log_tail: Vec<String>) -> PilotOutcome {
        let failure = self.expected_exit.judge(&self.end());
        PilotOutcome {
            expected_exit: self.expected_exit,
            started_at_s: self.started_at_s,
            exited_at_s: self.exited_at_s.filter(|_| self.started_at_s.is_some()),
            exited_at_wall_s: self.exited_at_wall_s.filter(|_| self.started_at_s.is_some()),
            exit_code: self.exit_code,
            signal: self.signal,
            stopped_by_runner: self.stopped_by_runner,
            as_expected: failure.is_none(),
            description: self.describe(),
            failure,
            log: self.log.clone(),
            log_tail,
        }
    }
}

/// `code 3`, `SIGKILL`, `signal 11`.
pub fn exit_words(code: Option<i32>, signal: Option<i32>) -> String {
    match (code, signal) {
        (Some(code), _) => format!("code {code}"),
        (None, Some(15)) => "SIGTERM".into(),
        (None, Some(9)) => "SIGKILL".into(),
        (None, Some(s)) => format!("signal {s}"),
        (None, None) => "unknown status".into(),
    }
}

/// How a pilot ended, as far as its expectation cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PilotEnd {
    /// The run ended before the pilots were released.
    NotStarted,
    /// It was still running when the run ended (and was stopped then).
    StillRunning,
    /// It exited by itself: with a code, or killed by a signal.
    Exited { code: Option<i32>, signal: Option<i32> },
}

impl ExpectedExit {
    /// `None` when `end` is what this expectation allows, else why not (one sentence naming
    /// the exit and the expectation).
    pub fn judge(self, end: &PilotEnd) -> Option<String> {
        let expected = self.as_str();
        match (self, end) {
            (ExpectedExit::Any, _) | (_, PilotEnd::NotStarted) => None,
            (ExpectedExit::Success, PilotEnd::StillRunning) => None,
            (ExpectedExit::Success, PilotEnd::Exited { code: Some(0), .. }) => None,
            (ExpectedExit::Failure, PilotEnd::Exited { code: Some(c), .. }) if *c != 0 => None,
            (ExpectedExit::Failure, PilotEnd::Exited { code: None, signal: Some(_) }) => None,
            (ExpectedExit::Failure, PilotEnd::StillRunning) => {
                Some(format!("the pilot was still running when the run ended; spec.pilot.expectedExit is {expected}"))
            }
            (_, PilotEnd::Exited { code, signal }) => Some(format!(
                "the pilot exited with {} before the run ended; spec.pilot.expectedExit is {expected}",
                exit_words(*code, *signal)
            )),
        }
    }
}

/// The pilot in `summary.json` (`pilot`): how it ended, whether that is what
/// `spec.pilot.expectedExit` asks, and the last lines of its log.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct PilotOutcome {
    pub expected_exit: ExpectedExit,
    /// Simulated time the pilot started, s (absent: the run ended before the release).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub started_at_s: Option<f64>,
    /// Simulated time of its exit (or of the runner's stop), s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exited_at_s: Option<f64>,
    /// Wall-clock seconds from the start of the run to its exit (or the stop).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exited_at_wall_s: Option<f64>,
    /// Exit code when it exited normally.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exit_code: Option<i32>,
    /// Signal number when a signal ended it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signal: Option<i32>,
    /// It was still running when the run ended, and the runner stopped it.
    pub stopped_by_runner: bool,
    /// Its end is what `expectedExit` allows (a failed expectation fails the run).
    pub as_expected: bool,
    /// One line, e.g. `started at 0.02 s, exited with code 1 at 12.30 s (4.1 s wall)`.
    pub description: String,
    /// Why its end fails the run (absent when as expected).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// The log file, in the run folder.
    pub log: String,
    /// The last lines of the log (at most [`LOG_TAIL_LINES`]).
    #[serde(default)]
    pub log_tail: Vec<String>,
}

/// Lines of the pilot's log kept in [`PilotOutcome::log_tail`].
pub const LOG_TAIL_LINES: usize = 20;
/// Longest line kept in a log tail, characters (longer ones are cut, ending in `…`).
pub const LOG_TAIL_LINE_CHARS: usize = 400;

/// The path of the verdict's entry for a pilot whose end was not as expected.
pub const EXPECTED_EXIT_PATH: &str = "spec.pilot.expectedExit";

impl PilotOutcome {
    /// Adds the pilot's failed expectation to `verdict` (which then fails), as an entry
    /// beside the criteria: path `spec.pilot.expectedExit`, kind `expectedExit`. Nothing
    /// when the pilot ended as expected.
    pub fn judge_into(&self, verdict: &mut RunVerdict) {
        let Some(failure) = &self.failure else { return };
        verdict.passed = false;
        verdict.criteria.push(CriterionResult {
            path: EXPECTED_EXIT_PATH.into(),
            criterion: "expectedExit".into(),
            passed: false,
            summary: format!("{}; expected {}", self.description, self.expected_exit.as_str()),
            failures: vec![format!("{failure} (its log: {})", self.log)],
        });
    }
}

/// The last [`LOG_TAIL_LINES`] lines of `text` (a log's end), each cut to
/// [`LOG_TAIL_LINE_CHARS`] characters; blank trailing lines are dropped.
pub fn log_tail(text: &str) -> Vec<String> {
    let lines: Vec<&str> = text.trim_end().lines().collect();
    lines[lines.len().saturating_sub(LOG_TAIL_LINES)..]
        .iter()
        .map(|l| {
            let l = l.trim_end_matches('\r');
            match l.char_indices().nth(LOG_TAIL_LINE_CHARS) {
                Some((cut, _)) => format!("{}…", &l[..cut]),
                None => l.to_string(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exited(code: Option<i32>, signal: Option<i32>) -> PilotEnd {
        PilotEnd::Exited { code, signal }
    }

    #[test]
    fn each_expectation_judges_each_end() {
        use ExpectedExit::{Any, Failure, Success};
        let ends = [
            PilotEnd::NotStarted,
            PilotEnd::StillRunning,
            exited(Some(0), None),
            exited(Some(1), None),
            exited(None, Some(9)),
        ];
        let passes = |e: ExpectedExit| ends.iter().map(|end| e.judge(end).is_none()).collect::<Vec<_>>();
        assert_eq!(passes(Success), [true, true, true, false, false]);
        assert_eq!(passes(Failure), [true, false, false, true, true]);
        assert_eq!(passes(Any), [true; 5]);
        assert_eq!(
            Success.judge(&exited(Some(1), None)).unwrap(),
            "the pilot exited with code 1 before the run ended; spec.pilot.expectedExit is success"
        );
        assert!(Success.judge(&exited(None, Some(9))).unwrap().contains("exited with SIGKILL"));
    }

    #[test]
    fn a_failed_expectation_fails_the_verdict_with_its_reason() {
        let record = PilotRecord {
            command: vec!["p".into()],
            working_dir: "/s".into(),
            on_exit: PilotExit::EndRun,
            expected_exit: ExpectedExit::Success,
            log: "pilot.log".into(),
            pid: Some(7),
            started_at_s: Some(0.5),
            exited_at_s: Some(12.3),
            exited_at_wall_s: Some(4.25),
            exit_code: Some(1),
            signal: None,
            stopped_by_runner: false,
        };
        let outcome = record.outcome(vec!["ModuleNotFoundError: No module named 'cv2'".into()]);
        assert!(!outcome.as_expected);
        assert_eq!(outcome.description, "started at 0.50 s, exited with code 1 at 12.30 s (4.2 s wall)");
        let mut verdict = RunVerdict { passed: true, criteria: vec![] };
        outcome.judge_into(&mut verdict);
        assert!(!verdict.passed);
        let entry = &verdict.criteria[0];
        assert_eq!(
            (entry.path.as_str(), entry.criterion.as_str(), entry.passed),
            (EXPECTED_EXIT_PATH, "expectedExit", false)
        );
        assert!(entry.failures[0].ends_with("(its log: pilot.log)"), "{entry:?}");
        let json = serde_json::to_value(&outcome).unwrap();
        assert_eq!(json["exitCode"], 1);
        assert_eq!(json["exitedAtWallS"], 4.25);
        assert_eq!(json["logTail"][0], "ModuleNotFoundError: No module named 'cv2'");

        let fine = PilotRecord { exit_code: Some(0), ..record };
        let mut verdict = RunVerdict { passed: true, criteria: vec![] };
        fine.outcome(vec![]).judge_into(&mut verdict);
        assert_eq!(verdict, RunVerdict { passed: true, criteria: vec![] });
    }

    #[test]
    fn a_log_tail_is_the_last_lines_cut_to_length() {
        let text: String = (0..30).map(|i| format!("line {i}\n")).collect::<String>() + "\n\n";
        let tail = log_tail(&text);
        assert_eq!(tail.len(), LOG_TAIL_LINES);
        assert_eq!((tail[0].as_str(), tail[19].as_str()), ("line 10", "line 29"));
        let long = "é".repeat(LOG_TAIL_LINE_CHARS + 5);
        assert_eq!(log_tail(&long)[0].chars().count(), LOG_TAIL_LINE_CHARS + 1);
        assert!(log_tail("").is_empty());
    }
}
