//! Browsing an archive of runs: a local runs folder (`sadesim run`'s output) or an object
//! store (`s3://`, `gs://`, `az://`) where the operator uploads runs. Blocking I/O: the
//! server calls it from `spawn_blocking`.
//!
//! An entry's id is its folder in the archive with `/` written `.` (`quickstart.20261206T151000Z`
//! locally, `default.chicago.<uid>` for uploads): run names, namespaces, stamps and uids hold
//! no dots.

use std::path::{Path, PathBuf};

use serde_json::Value;

use sadesim_crds::outcome::run_folder;
use sadesim_evidence::archive::{Archive, ArchiveError, MANIFEST_FILE, is_object_store};

use crate::local::verdict_word;
use crate::model::{ArchiveDetail, ArchiveEntry, EventLine, FileEntry, MAX_EVENTS, Verification, event_line};
use crate::time::stamp_to_rfc3339;

/// An archive the console reads.
#[derive(Debug, Clone)]
pub struct ArchiveBrowser {
    /// The archive's URL or folder.
    pub location: String,
    /// The folder, for a local archive.
    local: Option<PathBuf>,
}

/// Why a request on the archive failed: `NotFound` is the client's mistake (404), `Failed`
/// the archive's (502).
#[derive(Debug, thiserror::Error)]
pub enum BrowseError {
    #[error("{0}")]
    NotFound(String),
    #[error("{0}")]
    Failed(String),
}

impl From<ArchiveError> for BrowseError {
    fn from(e: ArchiveError) -> Self {
        match e {
            ArchiveError::NotFound { .. } => Self::NotFound(e.to_string()),
            other => Self::Failed(other.to_string()),
        }
    }
}

impl ArchiveBrowser {
    /// `location`: a folder (made if missing), `file://` URL or object-store URL.
    pub fn new(location: &str) -> Self {
        let local =
            (!is_object_store(location)).then(|| PathBuf::from(location.strip_prefix("file://").unwrap_or(location)));
        if let Some(dir) = &local {
            let _ = std::fs::create_dir_all(dir);
        }
        Self { location: location.to_string(), local }
    }

    fn open(&self) -> Result<Archive, BrowseError> {
        Ok(Archive::open(&self.location)?)
    }

    /// The folder of entry `id` in the archive, checked: segments of letters, digits, `-`
    /// and `_` only (nothing can point outside the archive).
    fn folder(id: &str) -> Result<String, BrowseError> {
        let ok = !id.is_empty()
            && id
                .split('.')
                .all(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_'));
        match ok {
            true => Ok(id.replace('.', "/")),
            false => Err(BrowseError::NotFound(format!("no run {id:?} in the archive"))),
        }
    }

    /// Every run in the archive, newest first.
    ///
    /// # Errors
    /// The archive cannot be listed.
    pub fn list(&self) -> Result<Vec<ArchiveEntry>, BrowseError> {
        let archive = self.open()?;
        let listings = match archive.list() {
            Ok(l) => l,
            Err(ArchiveError::NotFound { .. }) => Vec::new(),
            Err(e) => return Err(e.into()),
        };
        let mut entries: Vec<ArchiveEntry> = listings
            .into_iter()
            .filter(|l| l.path != "." && !l.path.starts_with('.'))
            .map(|l| self.entry(&archive, &l.path, l.complete))
            .collect();
        entries.sort_by(|a, b| b.date.cmp(&a.date).then_with(|| a.id.cmp(&b.id)));
        Ok(entries)
    }

    fn entry(&self, archive: &Archive, folder: &str, complete: bool) -> ArchiveEntry {
        let read_json = |file: &str| -> Option<Value> {
            let bytes = self.read(archive, folder, file, complete).ok()?;
            serde_json::from_slice(&bytes).ok()
        };
        let summary = read_json(run_folder::SUMMARY);
        let manifest = complete.then(|| read_json(MANIFEST_FILE)).flatten();
        let segments: Vec<&str> = folder.split('/').collect();
        let text =
            |v: &Option<Value>, k: &str| v.as_ref().and_then(|v| v.get(k)).and_then(Value::as_str).map(String::from);
        let last = segments.last().copied().unwrap_or_default();
        let date = stamp_to_rfc3339(last).or_else(|| self.modified(folder)).unwrap_or_default();
        ArchiveEntry {
            id: folder.replace('/', "."),
            scenario: text(&manifest, "run")
                .or_else(|| text(&summary, "run"))
                .unwrap_or_else(|| segments[segments.len().saturating_sub(2)].to_string()),
            namespace: text(&manifest, "namespace").unwrap_or_else(|| match segments.len() {
                3 => segments[0].to_string(),
                _ => "default".into(),
            }),
            date,
            verdict: summary
                .as_ref()
                .and_then(|s| s.pointer("/verdict/passed"))
                .and_then(Value::as_bool)
                .map(verdict_word),
            drones: summary.as_ref().and_then(|s| s.get("drones")).and_then(Value::as_u64).unwrap_or(0),
            duration_s: summary.as_ref().and_then(|s| s.get("simTimeS")).and_then(Value::as_f64),
            complete,
        }
    }

    /// The local folder's modification time, RFC 3339 (uploads are dated by their stamp).
    fn modified(&self, folder: &str) -> Option<String> {
        let dir = self.local.as_ref()?.join(folder);
        let t = std::fs::metadata(dir).ok()?.modified().ok()?;
        Some(crate::time::rfc3339(t))
    }

    /// One run's page: its entry, files and summary.
    ///
    /// # Errors
    /// No such run, or the archive cannot be read.
    pub fn detail(&self, id: &str) -> Result<ArchiveDetail, BrowseError> {
        let folder = Self::folder(id)?;
        let archive = self.open()?;
        let listing = archive
            .list()?
            .into_iter()
            .find(|l| l.path == folder)
            .ok_or_else(|| BrowseError::NotFound(format!("no run {id:?} in the archive")))?;
        let entry = self.entry(&archive, &folder, listing.complete);
        let files = self.files(&archive, &folder, listing.complete)?;
        let summary = self
            .read(&archive, &folder, run_folder::SUMMARY, listing.complete)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok());
        Ok(ArchiveDetail { entry, files, summary })
    }

    fn files(&self, archive: &Archive, folder: &str, complete: bool) -> Result<Vec<FileEntry>, BrowseError> {
        if complete {
            let bytes = archive
                .read_checked(folder, MANIFEST_FILE)
                .or_else(|_| self.read(archive, folder, MANIFEST_FILE, false))?;
            let manifest: Value =
                serde_json::from_slice(&bytes).map_err(|e| BrowseError::Failed(format!("{MANIFEST_FILE}: {e}")))?;
            let files = manifest.get("files").and_then(Value::as_array).cloned().unwrap_or_default();
            return Ok(files
                .iter()
                .filter_map(|f| {
                    Some(FileEntry { path: f.get("path")?.as_str()?.into(), size: f.get("size")?.as_u64()? })
                })
                .collect());
        }
        let Some(root) = &self.local else { return Ok(Vec::new()) };
        let mut out = Vec::new();
        walk(&root.join(folder), Path::new(""), &mut out);
        out.sort_by(|a, b| a.path.cmp(&b.path));
        Ok(out)
    }

    /// A file of a run: checked against its manifest when the run has one (an upload), read
    /// from the folder otherwise (a local run still flying or killed).
    fn read(&self, archive: &Archive, folder: &str, file: &str, complete: bool) -> Result<Vec<u8>, BrowseError> {
        if file.split('/').any(|s| s.is_empty() || s == "." || s == "..") {
            return Err(BrowseError::NotFound(format!("no file {file:?}")));
        }
        match (&self.local, complete) {
            (Some(root), _) => {
                let path = root.join(folder).join(file);
                std::fs::read(&path).map_err(|e| BrowseError::NotFound(format!("{}: {e}", path.display())))
            }
            (None, true) => Ok(archive.read_checked(folder, file)?),
            (None, false) => {
                Err(BrowseError::NotFound(format!("{folder}: the upload is incomplete (no {MANIFEST_FILE})")))
            }
        }
    }

    /// A file of run `id`.
    ///
    /// # Errors
    /// No such run or file, or a file that does not match the manifest.
    pub fn file(&self, id: &str, file: &str) -> Result<Vec<u8>, BrowseError> {
        let folder = Self::folder(id)?;
        let archive = self.open()?;
        let complete = self.local.is_none();
        self.read(&archive, &folder, file, complete)
    }

    /// Checks every file of run `id` against its manifest.
    ///
    /// # Errors
    /// No such run, or the archive cannot be read.
    pub fn verify(&self, id: &str) -> Result<Verification, BrowseError> {
        let folder = Self::folder(id)?;
        let report = self.open()?.verify(&folder)?;
        Ok(Verification {
            ok: report.passed(),
            checked: report.files_checked,
            problems: report.problems.iter().map(ToString::to_string).collect(),
        })
    }
}

fn walk(dir: &Path, rel: &Path, out: &mut Vec<FileEntry>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let (path, name) = (e.path(), rel.join(e.file_name()));
        match e.file_type() {
            Ok(t) if t.is_dir() => walk(&path, &name, out),
            Ok(_) => out.push(FileEntry {
                path: name.to_string_lossy().replace('\\', "/"),
                size: e.metadata().map(|m| m.len()).unwrap_or(0),
            }),
            Err(_) => {}
        }
    }
}

/// The drones' names in a run plan (`plan.json` as JSON; empty when it has none).
pub fn drone_names(plan: &Value) -> Vec<String> {
    plan.get("drones")
        .and_then(Value::as_array)
        .map(|ds| ds.iter().map(|d| d.get("name").and_then(Value::as_str).unwrap_or_default().to_string()).collect())
        .unwrap_or_default()
}

/// The newest [`MAX_EVENTS`] events of an `events.jsonl` still being written (a torn last
/// line is skipped).
pub fn tail_events(path: &Path, drone_names: &[String]) -> Vec<EventLine> {
    let Ok(text) = std::fs::read_to_string(path) else { return Vec::new() };
    let lines: Vec<&str> = text.lines().collect();
    let start = lines.len().saturating_sub(MAX_EVENTS);
    lines[start..].iter().filter_map(|l| event_line(l, drone_names)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_cannot_leave_the_archive() {
        assert_eq!(ArchiveBrowser::folder("quickstart.20261206T151000Z").unwrap(), "quickstart/20261206T151000Z");
        for bad in ["", "..", "a..b", "a/b", "a.%2e%2e", ".hidden"] {
            assert!(ArchiveBrowser::folder(bad).is_err(), "{bad}");
        }
    }
}
