//! Reading scenario files: the size limit, exactly-one-run files and their problem reports.

use std::io::{Read, Write};
use std::path::Path;

use sadesim_crds::document::MAX_DOCUMENT_BYTES;
use sadesim_crds::{SimulationRun, parse_runs};

use super::{CliError, count};

/// Reads a scenario file (or stdin for `-`) without ever holding more than the size limit.
pub fn read_scenario(path: &Path) -> Result<String, CliError> {
    let name = path.display().to_string();
    let read_err = |source| CliError::Read { path: name.clone(), source };
    let mut reader: Box<dyn Read> =
        if name == "-" { Box::new(std::io::stdin()) } else { Box::new(std::fs::File::open(path).map_err(read_err)?) };
    let mut buf = Vec::new();
    reader.by_ref().take(MAX_DOCUMENT_BYTES as u64 + 1).read_to_end(&mut buf).map_err(read_err)?;
    if buf.len() > MAX_DOCUMENT_BYTES {
        return Err(CliError::TooLarge { path: name, limit: MAX_DOCUMENT_BYTES });
    }
    String::from_utf8(buf).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        read_err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (invalid byte at offset {at})"),
        ))
    })
}

/// Reads a file holding exactly one run; parse problems are reported on `out` (`None`).
pub(super) fn load_one(file: &Path, out: &mut dyn Write) -> Result<Option<SimulationRun>, CliError> {
    let path = file.display().to_string();
    let text = read_scenario(file)?;
    let mut docs = parse_runs(&text).map_err(|source| CliError::Document { path: path.clone(), source })?;
    if docs.len() != 1 {
        return Err(CliError::NotOneRun { path, count: docs.len() });
    }
    match docs.remove(0) {
        Ok(mut run) => {
            resolve_paths(&mut run, file);
            Ok(Some(run))
        }
        Err(e) => {
            writeln!(out, "error: {path}: {e}")?;
            Ok(None)
        }
    }
}

pub(super) fn report_problems(
    out: &mut dyn Write,
    path: &str,
    errors: &sadesim_crds::ValidationErrors,
) -> std::io::Result<()> {
    writeln!(out, "error: {path}: {}", count(errors.0.len(), "problem"))?;
    for e in &errors.0 {
        writeln!(out, "  {e}")?;
    }
    Ok(())
}

/// Makes the scenario's file paths absolute against the scenario file's folder
/// ([`sadesim_sources::world::resolve_paths`]). Stdin scenarios resolve against the working
/// directory.
fn resolve_paths(run: &mut SimulationRun, scenario: &Path) {
    let base = match scenario.as_os_str() == "-" {
        true => std::env::current_dir().unwrap_or_default(),
        false => scenario.parent().map(Path::to_path_buf).unwrap_or_default(),
    };
    sadesim_sources::world::resolve_paths(run, &base);
}
