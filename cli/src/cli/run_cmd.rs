//! `sadesim run`: one run locally, then its summary and criteria verdict.

use std::io::Write;
use std::path::Path;

use sadesim_crds::outcome::ending::EndReason;
use sadesim_planner as planner;

use super::scenario::{load_one, report_problems};
use super::{CliError, Outcome, count};

pub(super) fn run_file(
    file: &Path,
    mut options: crate::runner::RunOptions,
    clock: Option<sadesim_crds::run::Clock>,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    use std::io::IsTerminal;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    use crate::runner::{RunError, run_local};

    let path = file.display().to_string();
    let Some(mut run) = load_one(file, out)? else { return Ok(Outcome::Problems) };
    if clock.is_some() {
        run.spec.clock = clock;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    // Ctrl-C asks the coordinator to stop after the current window; the recorder then
    // closes its files. (Fails only if a handler is already installed: keep that one.)
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    options.progress &= std::io::stderr().is_terminal();
    match run_local(&run, &options, stop) {
        Ok(report) => {
            let s = &report.summary;
            let took_off = s.per_drone.iter().filter(|d| d.took_off).count();
            let landed = s.per_drone.iter().filter(|d| d.landed).count();
            writeln!(
                out,
                "run {} ended ({}) at {:.1} s simulated in {:.1} s wall (real-time factor {:.1})",
                s.run, s.end_reason, s.sim_time_s, s.wall_time_s, s.real_time_factor
            )?;
            writeln!(
                out,
                "  {} in {}: {took_off} took off, {landed} landed, {} airborne at the end, {} crashed; {} events",
                count(s.drones as usize, "drone"),
                count(s.shards as usize, "shard"),
                s.airborne,
                s.crashed,
                s.events
            )?;
            if let Some(p) = &report.pilot {
                let log = report.out_dir.join(&p.log);
                writeln!(out, "  pilot: {}; log: {}", p.describe(), log.display())?;
            }
            let pilot_failed = s.pilot.as_ref().filter(|p| !p.as_expected);
            if let Some(p) = pilot_failed {
                writeln!(out, "  pilot FAILED: {}", p.failure.as_deref().unwrap_or("its end was not as expected"))?;
                match p.log_tail.is_empty() {
                    true => writeln!(out, "  {} is empty", p.log)?,
                    false => writeln!(out, "  last lines of {}:", p.log)?,
                }
                for line in &p.log_tail {
                    writeln!(out, "    | {line}")?;
                }
            }
            // The hold at the release for the pilot (`pilotConnectWaitS`).
            let not_connected = match (&s.end_reason, s.pilot_connect_wait_s) {
                (EndReason::PilotNotConnected(why), _) => {
                    writeln!(out, "  FAILED: {why}")?;
                    true
                }
                (_, Some(waited)) => {
                    let at = s.pilots_released_at_s.unwrap_or_default();
                    writeln!(
                        out,
                        "  pilot connected after {waited:.1} s of wall time (simulated time held at {at:.2} s until then)"
                    )?;
                    false
                }
                _ => false,
            };
            if let Some(assets) = &report.assets {
                writeln!(out, "  world: {assets}")?;
            }
            writeln!(out, "  output: {}", report.out_dir.display())?;
            match &report.report_error {
                None => writeln!(
                    out,
                    "  report: {}",
                    report.out_dir.join(sadesim_crds::outcome::run_folder::REPORT).display()
                )?,
                Some(e) => writeln!(out, "  report: not written: {e}")?,
            }
            if let Some(url) = &report.archive {
                writeln!(out, "  archived: {url}/")?;
            }
            let failed = match &s.verdict {
                Some(v) if !v.criteria.is_empty() => {
                    report_verdict(out, v)?;
                    !v.passed
                }
                _ => false,
            } || pilot_failed.is_some();
            let failed = failed || not_connected;
            if s.end_reason == EndReason::Interrupted {
                return Ok(Outcome::Interrupted);
            }
            Ok(if failed { Outcome::Problems } else { Outcome::Success })
        }
        Err(RunError::Plan(planner::PlanError::Invalid(errors))) => {
            report_problems(out, &path, &errors)?;
            Ok(Outcome::Problems)
        }
        Err(RunError::Plan(e @ planner::PlanError::NoHome { .. })) => {
            writeln!(out, "error: {path}: {e}")?;
            Ok(Outcome::Problems)
        }
        Err(source) => Err(CliError::Run { path, source }),
    }
}

/// Prints the criteria verdict: one line per criterion, then each failure.
fn report_verdict(out: &mut dyn Write, v: &sadesim_engine::airspace::criteria::RunVerdict) -> std::io::Result<()> {
    let passed = v.criteria.iter().filter(|c| c.passed).count();
    let word = if v.passed { "PASSED" } else { "FAILED" };
    writeln!(out, "  criteria {word}: {passed} of {} passed", v.criteria.len())?;
    for c in &v.criteria {
        let mark = if c.passed { "pass" } else { "FAIL" };
        writeln!(out, "    {mark} {} {}: {}", c.path, c.criterion, c.summary)?;
        for f in c.failures.iter().take(20) {
            writeln!(out, "         - {f}")?;
        }
        if c.failures.len() > 20 {
            writeln!(out, "         ... and {} more (see summary.json)", c.failures.len() - 20)?;
        }
    }
    Ok(())
}
