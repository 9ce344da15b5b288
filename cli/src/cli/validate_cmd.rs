//! `sadesim validate`: every problem of every run in the scenario files, with its field path.

use std::io::Write;
use std::path::PathBuf;

use sadesim_crds::sweep::document::SWEEP_KIND;
use sadesim_crds::{SimulationRun, parse_runs, validate};

use super::scenario::read_scenario;
use super::{CliError, Outcome, count};

fn run_label(run: &SimulationRun) -> String {
    run.metadata.name.clone().unwrap_or_else(|| "(unnamed)".into())
}

pub(super) fn validate_files(files: &[PathBuf], out: &mut dyn Write) -> Result<Outcome, CliError> {
    let mut problems = 0usize;
    for file in files {
        let path = file.display().to_string();
        let text = match read_scenario(file) {
            Ok(t) => t,
            Err(e) => {
                writeln!(out, "error: {e}")?;
                problems += 1;
                continue;
            }
        };
        if sadesim_crds::sweep::document::first_kind(&text).as_deref() == Some(SWEEP_KIND) {
            problems += usize::from(!validate_sweep(file, out)?);
            continue;
        }
        let docs = match parse_runs(&text) {
            Ok(docs) => docs,
            Err(e) => {
                writeln!(out, "error: {path}: {e}")?;
                problems += 1;
                continue;
            }
        };
        for (i, doc) in docs.into_iter().enumerate() {
            let run = match doc {
                Ok(run) => run,
                Err(e) => {
                    writeln!(out, "error: {path}: {e}")?;
                    problems += 1;
                    continue;
                }
            };
            match validate(&run) {
                Ok(()) => writeln!(
                    out,
                    "ok: {path}: {} ({} in {}, {})",
                    run_label(&run),
                    count(run.spec.total_drones() as usize, "drone"),
                    count(run.spec.fleet.len(), "group"),
                    count(run.spec.zones.len(), "zone")
                )?,
                Err(errors) => {
                    let n = count(errors.0.len(), "problem");
                    writeln!(out, "error: {path}: document {} ({}): {n}", i + 1, run_label(&run))?;
                    for e in &errors.0 {
                        writeln!(out, "  {e}")?;
                    }
                    problems += 1;
                }
            }
        }
    }
    Ok(if problems == 0 { Outcome::Success } else { Outcome::Problems })
}

/// A sweep file: every problem of the sweep and of each of its runs. Whether it is valid.
fn validate_sweep(file: &std::path::Path, out: &mut dyn Write) -> Result<bool, CliError> {
    use crate::sweep::SweepError;
    let path = file.display().to_string();
    match crate::sweep::load(file) {
        Ok(loaded) => {
            let name = loaded.sweep.metadata.name.clone().unwrap_or_default();
            let e = &loaded.expansion;
            let runs = count(e.runs.len(), "run");
            writeln!(
                out,
                "ok: {path}: sweep {name} ({} x {} = {runs})",
                count(e.cells.len(), "cell"),
                count(loaded.sweep.spec.repetitions() as usize, "repetition")
            )?;
            Ok(true)
        }
        Err(SweepError::Invalid { errors, .. }) => {
            writeln!(out, "error: {path}: {}", count(errors.0.len(), "problem"))?;
            for e in &errors.0 {
                writeln!(out, "  {e}")?;
            }
            Ok(false)
        }
        Err(e) => {
            writeln!(out, "error: {e}")?;
            Ok(false)
        }
    }
}
