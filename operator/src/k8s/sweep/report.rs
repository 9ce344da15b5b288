//! The sweep report on a cluster: once every run of a sweep ended, `sweep.json` and
//! `sweep.html` ([`sadesim_evidence::sweep`]), built from the `summary.json` each run
//! archived, are written to `<base archive URL>/<namespace>/<sweep>/`, beside the runs' own
//! folders (`<base archive URL>/<namespace>/<run>/<uid>/`).
//!
//! [`records`] is pure (the summaries are read through the function it is given);
//! [`write`] does blocking I/O (an [`Archive`] drives its own runtime), so the reconcile
//! calls it from `tokio::task::spawn_blocking`, never on its own runtime.

use kube::ResourceExt;
use sadesim_crds::SimulationRun;
use sadesim_crds::outcome::summary::RunSummary;
use sadesim_crds::sweep::{Expansion, SimulationSweep};
use sadesim_evidence::archive::Archive;
use sadesim_evidence::sweep::{SWEEP_HTML, SWEEP_JSON, SweepRecord, build, html};

/// Why a sweep has no report (the condition `Reported=False`, reason `NoArchive`).
pub const NO_ARCHIVE: &str =
    "spec.base.spec.archive is not set and no run was archived: the sweep report is archived beside the runs";

/// The file of a run's folder the report reads.
const SUMMARY_FILE: &str = "summary.json";

/// Builds the sweep's report and writes `sweep.json` and `sweep.html` to
/// `<base archive URL>/<namespace>/<sweep>/` (the base archive URL is
/// `spec.base.spec.archive.url`). Blocking.
///
/// Returns the URL of that folder, or `None` when the base run has no archive (nothing is
/// written). A run that cannot be read still counts: the report lists it as not finished,
/// with the reason.
///
/// # Errors
/// The sweep has no namespace, the archive cannot be opened, or a file cannot be written:
/// a message naming the URL. Nothing is recorded; the caller tries again later.
pub fn write(sweep: &SimulationSweep, expansion: &Expansion, runs: &[SimulationRun]) -> Result<Option<String>, String> {
    let Some(root) = archive_root(sweep, runs) else {
        return Ok(None);
    };
    let name = sweep.name_any();
    let ns = sweep.namespace().ok_or_else(|| format!("sweep {name} has no namespace"))?;
    let records = records(expansion, runs, read_summary);
    let report = build(sweep, &expansion.cells, &records);
    let mut json = serde_json::to_vec_pretty(&report).expect("a report always serializes");
    json.push(b'\n');
    let archive = Archive::open(&root).map_err(|e| e.to_string())?;
    let folder = format!("{ns}/{name}");
    archive.put_file(&format!("{folder}/{SWEEP_JSON}"), json).map_err(|e| e.to_string())?;
    archive.put_file(&format!("{folder}/{SWEEP_HTML}"), html::page(&report).into_bytes()).map_err(|e| e.to_string())?;
    Ok(Some(format!("{}/{folder}", archive.url())))
}

/// The archive the sweep's report goes to: the base run's `spec.archive.url`, else the
/// archive the operator gave its runs (the operator's default archive URL): a run's
/// `status.archive.url` is `<archive>/<namespace>/<run>/<uid>`. `None` when neither is
/// known.
pub fn archive_root(sweep: &SimulationSweep, runs: &[SimulationRun]) -> Option<String> {
    if let Some(archive) = sweep.spec.base.spec.as_ref().and_then(|spec| spec.archive.as_ref()) {
        return Some(archive.url.clone());
    }
    runs.iter().filter_map(|r| r.status.as_ref()?.archive.as_ref()).find_map(|a| {
        let mut parts = a.url.trim_end_matches('/').rsplitn(4, '/');
        let (_uid, _run, _ns) = (parts.next()?, parts.next()?, parts.next()?);
        parts.next().filter(|root| root.contains("://") && !root.ends_with(':')).map(String::from)
    })
}

/// One record per run of `expansion`, in its order, matched to `runs` by name: `folder` is
/// the run's `status.archive.url` (empty when it has none), `summary` what `read` returns
/// for that URL, `error` why there is no summary (no such run, not archived, or `read`'s
/// message).
pub fn records(
    expansion: &Expansion,
    runs: &[SimulationRun],
    read: impl Fn(&str) -> Result<RunSummary, String>,
) -> Vec<SweepRecord> {
    expansion
        .runs
        .iter()
        .map(|sweep_run| {
            let name = sweep_run.name();
            let archived = runs
                .iter()
                .find(|r| r.metadata.name.as_deref() == Some(name))
                .map(|r| r.status.as_ref().and_then(|s| s.archive.as_ref()).map(|a| a.url.clone()));
            let (folder, summary) = match archived {
                None => (String::new(), Err(format!("no SimulationRun {name}"))),
                Some(None) => (String::new(), Err("not archived".to_string())),
                Some(Some(url)) => {
                    let summary = read(&url);
                    (url, summary)
                }
            };
            let (summary, error) = match summary {
                Ok(summary) => (Some(summary), None),
                Err(error) => (None, Some(error)),
            };
            SweepRecord {
                name: name.to_string(),
                cell: sweep_run.cell,
                repetition: sweep_run.repetition,
                seed: sweep_run.seed(),
                folder,
                summary,
                error,
            }
        })
        .collect()
}

/// The `summary.json` of the run archived at `url`, checked against the folder's manifest.
/// Blocking.
///
/// # Errors
/// Why it cannot be read (no manifest, not listed, damaged, unreadable) or parsed, naming
/// the URL.
pub fn read_summary(url: &str) -> Result<RunSummary, String> {
    let bytes = Archive::open(url).and_then(|a| a.read_checked("", SUMMARY_FILE)).map_err(|e| e.to_string())?;
    serde_json::from_slice(&bytes)
        .map_err(|e| format!("{}/{SUMMARY_FILE}: not a run summary: {e}", url.trim_end_matches('/')))
}
