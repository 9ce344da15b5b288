//! What the coordinator reports on stdout (`sadesim_crds::outcome::coordinator::Report` JSON
//! lines), read back from the tail of its pod log: simulated time, whether the pilots were
//! released, and the final summary with the criteria verdict.

use sadesim_crds::outcome::coordinator::Report;
use sadesim_crds::outcome::ending::EndReason;
use sadesim_crds::status::Verdict;

/// Lines of the coordinator's log the operator reads per reconcile. Progress comes once
/// per simulated second, so 20 lines cover 20 s of simulated time between reconciles.
pub const TAIL_LINES: i64 = 20;

/// The coordinator's latest word, from its log tail.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoordinatorReport {
    /// Latest simulated time reported (progress or pilotsReleased), seconds.
    pub sim_time_s: Option<f64>,
    /// A `pilotsReleased` line is in the tail, or simulated time advances (progress lines
    /// follow the release).
    pub pilots_released: bool,
    /// The `finished` line: the run is over and its files are written.
    pub finished: Option<Finished>,
    /// The `failed` line: `(role, reason)`, e.g. `("shard 3", "connection reset ...")`.
    pub failed: Option<(String, String)>,
}

/// The end of a run as the coordinator summarised it.
#[derive(Clone, Debug, PartialEq)]
pub struct Finished {
    /// Simulated seconds at the end.
    pub sim_time_s: f64,
    /// Simulated seconds per wall-clock second over the whole run.
    pub real_time_factor: f64,
    /// Why the run ended (`duration`, `pilotExited`, `interrupted`, ...).
    pub end_reason: EndReason,
    /// The criteria's outcome (absent when the run did not get that far).
    pub verdict: Option<Verdict>,
}

/// Parses a log tail; lines that are not coordinator reports (other log output) are skipped.
pub fn parse_tail(text: &str) -> CoordinatorReport {
    let mut report = CoordinatorReport::default();
    for line in text.lines() {
        let Ok(r) = serde_json::from_str::<Report>(line.trim()) else { continue };
        match r {
            Report::Listening { .. } => {}
            Report::Progress { sim_time_s, .. } => {
                report.sim_time_s = Some(sim_time_s);
                report.pilots_released |= sim_time_s > 0.0;
            }
            Report::PilotsReleased { sim_time_s } => {
                report.sim_time_s = Some(report.sim_time_s.unwrap_or(0.0).max(sim_time_s));
                report.pilots_released = true;
            }
            Report::Failed { role, shard, reason, summary, .. } => {
                let role = format!("{role:?}").to_lowercase();
                let role = match shard {
                    Some(i) => format!("{role} {i}"),
                    None => role,
                };
                if let Some(s) = &summary {
                    report.sim_time_s = Some(s.sim_time_s);
                }
                report.failed = Some((role, reason));
            }
            Report::Finished { summary } => {
                let verdict = summary.verdict.as_ref().map(|v| Verdict {
                    passed: v.passed,
                    failures: v
                        .criteria
                        .iter()
                        .filter(|c| !c.passed)
                        .map(|c| format!("{} {}: {}", c.path, c.criterion, c.summary))
                        .collect(),
                    unauthorized_entries: None,
                    crashes: Some(summary.crashed),
                });
                report.sim_time_s = Some(summary.sim_time_s);
                report.pilots_released |= summary.pilots_released_at_s.is_some();
                report.finished = Some(Finished {
                    sim_time_s: summary.sim_time_s,
                    real_time_factor: summary.real_time_factor,
                    end_reason: summary.end_reason.clone(),
                    verdict,
                });
            }
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_progress_release_and_skips_other_lines() {
        let text = "starting up\n{\"type\":\"listening\",\"address\":\"0.0.0.0:7400\",\"airspace\":\"http://0.0.0.0:8000\"}\n\
            {\"type\":\"pilotsReleased\",\"simTimeS\":0.01}\n\
            {\"type\":\"progress\",\"simTimeS\":1.0,\"airborne\":4,\"onGround\":0,\"crashed\":0}\n\
            {\"type\":\"progress\",\"simTimeS\":2.0,\"airborne\":4,\"onGround\":0,\"crashed\":0}\n";
        let r = parse_tail(text);
        assert_eq!(r.sim_time_s, Some(2.0));
        assert!(r.pilots_released);
        assert!(r.finished.is_none());
    }

    #[test]
    fn nothing_reported_before_the_release() {
        let r = parse_tail("{\"type\":\"listening\",\"address\":\"a\",\"airspace\":\"b\"}\n");
        assert_eq!(r, CoordinatorReport::default());
    }
}
