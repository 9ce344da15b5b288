//! `sadesim sweep`: flags and printing over [`crate::sweep`].

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::args::{SweepArgs, SweepCommand};
use super::{CliError, Outcome, count};
use crate::sweep::{SweepError, SweepOptions, load, run_sweep};

pub(super) fn sweep(args: SweepArgs, out: &mut dyn Write) -> Result<Outcome, CliError> {
    if let Some(SweepCommand::Compare { old, new, alpha }) = args.command {
        return compare(&old, &new, alpha, out);
    }
    let file = args.file.expect("clap requires FILE without a subcommand");
    let loaded = match load(&file) {
        Ok(loaded) => loaded,
        Err(SweepError::Invalid { path, errors }) => {
            writeln!(out, "{path}: {}", count(errors.0.len(), "problem"))?;
            for e in &errors.0 {
                writeln!(out, "  {e}")?;
            }
            return Ok(Outcome::Problems);
        }
        Err(e) => return Err(CliError::Failed(e.to_string())),
    };
    if args.expand {
        for (i, r) in loaded.expansion.runs.iter().enumerate() {
            if i > 0 {
                writeln!(out, "---")?;
            }
            out.write_all(crate::sweep::run_yaml(&r.run).as_bytes())?;
        }
        return Ok(Outcome::Success);
    }
    let asset_cache = match (args.asset_cache, args.no_asset_cache) {
        (_, true) => None,
        (Some(url), false) => Some(url),
        (None, false) => Some(
            sadesim_sources::assets::local_cache_url(&|k| std::env::var(k).ok())
                .map_err(|e| CliError::Failed(e.to_string()))?,
        ),
    };
    let options = SweepOptions {
        out_root: args.out,
        jobs: args.jobs,
        progress: !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr()),
        clock: args.clock,
        asset_cache,
        mavlink: !args.no_mavlink,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    let runs = loaded.expansion.runs.len();
    writeln!(
        out,
        "sweep {}: {} x {} = {}",
        loaded.sweep.metadata.name.as_deref().unwrap_or_default(),
        count(loaded.expansion.cells.len(), "cell"),
        count(loaded.sweep.spec.repetitions() as usize, "repetition"),
        count(runs, "run")
    )?;
    out.flush()?;
    let outcome = run_sweep(&loaded, &options, stop).map_err(|e| CliError::Failed(e.to_string()))?;
    let r = &outcome.report;
    let t = &r.totals;
    writeln!(
        out,
        "  {} flown now, {} kept from before; {} of {} finished, {} passed",
        outcome.ran, outcome.skipped, t.rate.finished, t.expected, t.rate.passed
    )?;
    let level = (r.confidence * 100.0).round();
    for cell in &r.cells {
        let c = &cell.rate;
        let rate = c.pass_rate.map_or("    -".to_string(), |p| format!("{:5.1} %", 100.0 * p));
        writeln!(
            out,
            "  {:<32} {:>3}/{:<3} passed {rate}  ({level} % CI {:.2}..{:.2})",
            cell.label, c.passed, c.finished, c.ci_low, c.ci_high
        )?;
    }
    for (run, why) in &outcome.errors {
        writeln!(out, "  run {run} failed: {why}")?;
    }
    writeln!(out, "  report: {}", outcome.dir.join(sadesim_evidence::sweep::SWEEP_HTML).display())?;
    if outcome.interrupted {
        writeln!(out, "  interrupted: rerun the same command to fly the rest")?;
        return Ok(Outcome::Interrupted);
    }
    Ok(if outcome.errors.is_empty() && t.rate.finished == t.expected { Outcome::Success } else { Outcome::Problems })
}

/// A sweep's report from its folder or its `sweep.json`.
fn read_report(path: &Path) -> Result<sadesim_evidence::sweep::SweepReport, CliError> {
    let dir: PathBuf = if path.is_dir() { path.into() } else { path.parent().unwrap_or(Path::new(".")).into() };
    sadesim_evidence::sweep::read(&dir).map_err(|e| CliError::Failed(e.to_string()))
}

fn compare(old: &Path, new: &Path, alpha: f64, out: &mut dyn Write) -> Result<Outcome, CliError> {
    if !(alpha > 0.0 && alpha < 0.5) {
        return Err(CliError::Failed(format!("--alpha: must be above 0 and below 0.5 (e.g. 0.05), got {alpha}")));
    }
    let comparison = sadesim_evidence::sweep::compare(&read_report(old)?, &read_report(new)?, alpha);
    write!(out, "{comparison}")?;
    Ok(if comparison.significantly_worse() { Outcome::Problems } else { Outcome::Success })
}
