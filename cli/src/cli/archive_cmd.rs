//! `sadesim archive ls|verify|get|put`: run archives and their manifests.

use std::io::Write;
use std::path::Path;

use super::{ArchiveCommand, CliError, Outcome, count};

/// `sadesim archive ...`: exit 1 (`Problems`) when a run does not match its manifest.
pub(super) fn archive_command(command: ArchiveCommand, out: &mut dyn Write) -> Result<Outcome, CliError> {
    use indicatif::HumanBytes;
    use sadesim_evidence::archive::Archive;

    match command {
        ArchiveCommand::Ls { url } => {
            let archive = Archive::open(&url)?;
            let runs = archive.list()?;
            if runs.is_empty() {
                writeln!(out, "no runs in {}", archive.url())?;
                return Ok(Outcome::Success);
            }
            let width = runs.iter().map(|r| r.path.len()).max().unwrap_or(0).max(3);
            writeln!(out, "{:<width$}  {:>6}  {:>10}  status", "run", "files", "size")?;
            for r in &runs {
                let status = if r.complete { "complete" } else { "incomplete (no manifest.json)" };
                writeln!(out, "{:<width$}  {:>6}  {:>10}  {status}", r.path, r.files, HumanBytes(r.bytes).to_string())?;
            }
            writeln!(out, "{} in {}", count(runs.len(), "run"), archive.url())?;
            Ok(Outcome::Success)
        }
        ArchiveCommand::Verify { location, quiet } => {
            let mut archive = Archive::open(&location)?;
            archive.set_progress(!quiet);
            let report = archive.verify("")?;
            report_check(out, &report, "verified")
        }
        ArchiveCommand::Get { location, dir, quiet } => {
            let mut archive = Archive::open(&location)?;
            archive.set_progress(!quiet);
            let report = archive.get("", &dir)?;
            let outcome = report_check(out, &report, "downloaded")?;
            writeln!(out, "  into {}", dir.display())?;
            Ok(outcome)
        }
        ArchiveCommand::Put { dir, url, namespace, run, uid, quiet } => {
            let name_of = |p: Option<&Path>, flag| {
                p.and_then(|p| p.file_name())
                    .and_then(|n| n.to_str())
                    .map(String::from)
                    .ok_or_else(|| CliError::ArchiveName { dir: dir.display().to_string(), flag })
            };
            let absolute = std::path::absolute(&dir).unwrap_or_else(|_| dir.clone());
            let uid = match uid {
                Some(u) => u,
                None => name_of(Some(&absolute), "uid")?,
            };
            let run = match run {
                Some(r) => r,
                None => name_of(absolute.parent(), "run")?,
            };
            let mut archive = Archive::open(&url)?;
            archive.set_progress(!quiet);
            let uploaded = archive.upload_run(&dir, &namespace, &run, &uid)?;
            let m = &uploaded.manifest;
            writeln!(
                out,
                "uploaded {} ({}) to {}/ ({} written last)",
                count(m.file_count, "file"),
                HumanBytes(m.total_bytes),
                uploaded.url,
                sadesim_evidence::archive::MANIFEST_FILE
            )?;
            Ok(Outcome::Success)
        }
    }
}

/// Prints a verify/get report: one line per problem, then the verdict.
fn report_check(
    out: &mut dyn Write,
    report: &sadesim_evidence::archive::VerifyReport,
    verb: &str,
) -> Result<Outcome, CliError> {
    use indicatif::HumanBytes;
    if report.passed() {
        writeln!(
            out,
            "ok: {}: {} {} ({}) match {}",
            report.url,
            verb,
            count(report.files_checked, "file"),
            HumanBytes(report.bytes_checked),
            sadesim_evidence::archive::MANIFEST_FILE
        )?;
        return Ok(Outcome::Success);
    }
    writeln!(out, "error: {}: {}", report.url, count(report.problems.len(), "problem"))?;
    for p in &report.problems {
        writeln!(out, "  {p}")?;
    }
    Ok(Outcome::Problems)
}
