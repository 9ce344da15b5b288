//! The end of a run, the one sequence every run goes through, whatever its outcome: the
//! report (`report.html` and its plots), then `manifest.json` (so the manifest lists the
//! report), then the upload of the folder when it is to go to an archive. The local runner
//! (`sadesim run`) and the coordinator role (`sim-worker coordinator --finish-run`, the
//! coordinator pod on Kubernetes) both call [`finish_run`], so a run folder holds the same
//! files on a laptop and on a cluster (DESIGN §8: nothing is lost).
//!
//! A report failure never costs the run its evidence: the message goes to
//! `report-error.txt` in the folder and the manifest and upload still happen. A run whose
//! recording stopped on a write error (`incomplete.json`: the disk filled) gets no report:
//! what room there is goes to the manifest, which says what is incomplete.

use std::path::Path;

use sadesim_crds::outcome::run_folder;

use crate::archive::{Archive, ArchiveError, Uploaded, write_manifest};

/// Which run a folder holds, as its archive names it: `<archive>/<namespace>/<run>/<uid>/`.
#[derive(Debug, Clone, Copy)]
pub struct RunAddress<'a> {
    pub namespace: &'a str,
    pub run: &'a str,
    /// The run's uid on Kubernetes; the folder's UTC start time for local runs.
    pub uid: &'a str,
}

/// What [`finish_run`] did.
#[derive(Debug)]
pub struct Finished {
    /// Why `report.html` could not be written (also in `report-error.txt`); `None` when it
    /// was.
    pub report_error: Option<crate::report::ReportError>,
    /// The upload (`None` when there was nothing to upload to), or why the manifest or the
    /// upload failed. The local folder keeps every file either way.
    pub archived: Result<Option<Uploaded>, ArchiveError>,
}

/// Finishes the run folder `run_dir`: writes the report (its map drawn over `world`, the
/// run's; `None` draws it without buildings; a failure is recorded in `report-error.txt`),
/// writes `manifest.json`, then, with `upload_to` (an archive URL: object store or
/// `file://`), uploads the folder to `<upload_to>/<namespace>/<run>/<uid>/`, manifest last.
/// `progress` shows a progress bar for the upload.
///
/// Without `upload_to` the folder itself is the archive (a local run whose `spec.archive`
/// is a folder, or no archive at all).
pub fn finish_run(
    run_dir: &Path,
    address: RunAddress<'_>,
    upload_to: Option<&str>,
    progress: bool,
    world: Option<&sadesim_world::World>,
) -> Finished {
    let report_error = match crate::archive::read_incomplete(run_dir) {
        Ok(Some(incomplete)) => Some(crate::report::ReportError::RecordingIncomplete { reason: incomplete.reason }),
        _ => crate::report::write_report_in(run_dir, world).err(),
    };
    if let Some(e) = &report_error {
        // Best effort: the folder may be unwritable, and the message is returned anyway.
        let _ = std::fs::write(run_dir.join(run_folder::REPORT_ERROR), format!("{e}\n"));
    }
    let archived = archive(run_dir, address, upload_to, progress);
    Finished { report_error, archived }
}

fn archive(
    run_dir: &Path,
    address: RunAddress<'_>,
    upload_to: Option<&str>,
    progress: bool,
) -> Result<Option<Uploaded>, ArchiveError> {
    let RunAddress { namespace, run, uid } = address;
    write_manifest(run_dir, namespace, run, uid)?;
    let Some(url) = upload_to else { return Ok(None) };
    let mut archive = Archive::open(url)?;
    archive.set_progress(progress);
    archive.upload_run(run_dir, namespace, run, uid).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::archive::tests::{file_url, temp};
    use crate::archive::verify;

    /// A run folder `<temp>/<name>/run` holding an empty `events.jsonl` and no `plan.json`;
    /// returns (temp root, run folder).
    fn unreportable_run(name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
        let root = temp(&format!("finish-{name}"));
        let run_dir = root.join("run");
        std::fs::create_dir_all(&run_dir).unwrap();
        std::fs::write(run_dir.join(run_folder::EVENTS), "").unwrap();
        (root, run_dir)
    }

    const ADDRESS: RunAddress<'static> = RunAddress { namespace: "default", run: "quickstart", uid: "u-1" };

    /// A folder without `plan.json` cannot be reported on: the reason is kept in the folder,
    /// and the manifest (which lists `report-error.txt`) and the upload still happen.
    #[test]
    fn a_report_failure_is_recorded_and_the_folder_is_still_archived() {
        let (root, run_dir) = unreportable_run("report-error");
        let archive_url = file_url(&root.join("archive"));

        let done = finish_run(&run_dir, ADDRESS, Some(&archive_url), false, None);

        let error = done.report_error.expect("no plan.json: no report").to_string();
        assert!(error.contains(run_folder::PLAN), "{error}");
        let recorded = std::fs::read_to_string(run_dir.join(run_folder::REPORT_ERROR)).unwrap();
        assert_eq!(recorded.trim_end(), error);
        assert!(!run_dir.join(run_folder::REPORT).exists());
        let uploaded = done.archived.expect("archived").expect("uploaded");
        assert_eq!(uploaded.url, format!("{archive_url}/default/quickstart/u-1"));
        let listed: Vec<&str> = uploaded.manifest.files.iter().map(|f| f.path.as_str()).collect();
        assert_eq!(listed, vec![run_folder::EVENTS, run_folder::REPORT_ERROR]);
        assert!(verify(&uploaded.url).unwrap().passed());
        // The local folder is verifiable too.
        assert!(verify(run_dir.to_str().unwrap()).unwrap().passed());
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// A run whose recording stopped on a write error (`incomplete.json`): no report is
    /// attempted, the manifest carries what is incomplete, and verify reports it file by
    /// file, after the reason, rather than passing or failing on checksums.
    #[test]
    fn an_incomplete_recording_is_in_the_manifest_and_fails_verify_saying_so() {
        use crate::archive::{FileState, INCOMPLETE_FILE, Incomplete, IncompleteFile, Problem};
        let (root, run_dir) = unreportable_run("incomplete");
        std::fs::write(run_dir.join("recording.mcap"), b"an MCAP cut short").unwrap();
        let incomplete = Incomplete {
            reason: "recording.mcap: No space left on device (os error 28)".into(),
            files: vec![
                IncompleteFile {
                    path: "recording.mcap".into(),
                    state: FileState::Truncated,
                    detail: "it ends at 50.00 s of simulated time, where the recording stopped".into(),
                },
                IncompleteFile {
                    path: run_folder::SUMMARY.into(),
                    state: FileState::NotWritten,
                    detail: "it could not be written (No space left on device (os error 28))".into(),
                },
            ],
        };
        std::fs::write(run_dir.join(INCOMPLETE_FILE), serde_json::to_vec(&incomplete).unwrap()).unwrap();

        let done = finish_run(&run_dir, ADDRESS, None, false, None);

        let error = done.report_error.expect("no report").to_string();
        assert!(error.starts_with("not attempted: the recording is incomplete (recording.mcap: No space"), "{error}");
        assert!(!run_dir.join(run_folder::REPORT).exists());
        let manifest: crate::archive::Manifest =
            serde_json::from_slice(&std::fs::read(run_dir.join(run_folder::MANIFEST)).unwrap()).unwrap();
        assert_eq!(manifest.incomplete.as_ref(), Some(&incomplete));
        let report = verify(run_dir.to_str().unwrap()).unwrap();
        assert!(!report.passed());
        assert_eq!(report.problems[0], Problem::Stopped { reason: incomplete.reason.clone() });
        let lines: Vec<String> = report.problems.iter().map(ToString::to_string).collect();
        assert_eq!(
            lines[1..],
            [
                "recording.mcap: incomplete (truncated): it ends at 50.00 s of simulated time, where the recording stopped",
                "summary.json: incomplete (notWritten): it could not be written (No space left on device (os error 28))",
            ]
        );
        assert!(!lines.iter().any(|l| l.contains("sha256")), "the bytes match: {lines:?}");
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// Without an upload target the folder is the archive: a manifest, no upload.
    #[test]
    fn without_an_archive_the_folder_gets_its_manifest_only() {
        let (root, run_dir) = unreportable_run("local");
        let done = finish_run(&run_dir, ADDRESS, None, false, None);
        assert!(done.archived.expect("manifest written").is_none());
        assert!(verify(run_dir.to_str().unwrap()).unwrap().passed());
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// An archive that cannot be opened is an error naming it; the local folder still has
    /// its manifest.
    #[test]
    fn an_archive_that_cannot_be_opened_is_named() {
        let (root, run_dir) = unreportable_run("bad-url");
        let done = finish_run(&run_dir, ADDRESS, Some("ftp://nowhere/runs"), false, None);
        let err = done.archived.expect_err("ftp is not an archive");
        assert!(err.to_string().contains("ftp://nowhere/runs"), "{err}");
        assert!(verify(run_dir.to_str().unwrap()).unwrap().passed());
        std::fs::remove_dir_all(&root).unwrap();
    }
}
