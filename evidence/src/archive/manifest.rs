//! `manifest.json`: its format (paths, sizes, SHA-256), reading and checking it, and writing it
//! for a local run folder.

use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Path as FsPath, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::ArchiveError;
use super::url::{check_relative_path, check_segment};

/// The manifest's name in every run folder.
pub const MANIFEST_FILE: &str = sadesim_crds::outcome::run_folder::MANIFEST;
/// `formatVersion` of the manifests this build writes and reads.
pub const MANIFEST_FORMAT_VERSION: u32 = 1;

/// Read buffer for local files (bytes).
pub(super) const READ_CHUNK_BYTES: usize = 1024 * 1024;

/// The checksums of one run folder: `manifest.json`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct Manifest {
    /// [`MANIFEST_FORMAT_VERSION`] when written; readers refuse versions they do not know.
    pub format_version: u32,
    /// Kubernetes namespace of the run (`default` for local runs unless the document says).
    pub namespace: String,
    /// The run's name (`metadata.name`).
    pub run: String,
    /// This execution of the run: the UTC start time of a local run, the object uid on
    /// Kubernetes.
    pub uid: String,
    /// Number of entries in `files`.
    pub file_count: usize,
    /// Sum of `files[].size`, bytes.
    pub total_bytes: u64,
    /// Every file of the run but the manifest itself, sorted by path.
    pub files: Vec<ManifestFile>,
    /// What the run could not write whole (from the folder's `incomplete.json`): present
    /// only when the recording stopped on a write error (the disk filled). The files listed
    /// in `files` match their checksums either way; this says which of them end early or
    /// were not closed, and which were never written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub incomplete: Option<Incomplete>,
}

/// `incomplete.json`: written into a run folder by the recorder when a file of the run
/// could not be written (the disk filled, an I/O error), and copied into the manifest.
pub const INCOMPLETE_FILE: &str = "incomplete.json";

/// What a run whose recording stopped on a write error holds, file by file.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct Incomplete {
    /// The error that stopped the recording, naming the file that could not be written
    /// (e.g. `recording.mcap: No space left on device (os error 28)`).
    pub reason: String,
    /// The files that are not whole, sorted by path.
    pub files: Vec<IncompleteFile>,
}

/// One file of an [`Incomplete`] run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct IncompleteFile {
    /// Relative to the run folder, `/`-separated.
    pub path: String,
    pub state: FileState,
    /// What it holds and why, in words.
    pub detail: String,
}

/// How a file of an [`Incomplete`] run falls short.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub enum FileState {
    /// Well-formed and closed (its readers open it normally), but it ends where the
    /// recording stopped, before the run's end.
    Truncated,
    /// Its end could not be written: it stops mid-record (`recording.mcap` without its
    /// summary and footer: readers need their recovery or streaming mode).
    NotFinalised,
    /// Not in the folder: it is written at the end of a run, and could not be.
    NotWritten,
}

impl FileState {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Truncated => "truncated",
            Self::NotFinalised => "notFinalised",
            Self::NotWritten => "notWritten",
        }
    }
}

impl std::fmt::Display for FileState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The folder's `incomplete.json`, if it has one.
///
/// # Errors
/// [`ArchiveError::ReadLocal`] when it exists but cannot be read or is not an
/// [`Incomplete`].
pub(crate) fn read_incomplete(dir: &FsPath) -> Result<Option<Incomplete>, ArchiveError> {
    let path = dir.join(INCOMPLETE_FILE);
    let read_err = |source| ArchiveError::ReadLocal { path: path.display().to_string(), source };
    let bytes = match std::fs::read(&path) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(read_err(e)),
    };
    let incomplete = serde_json::from_slice(&bytes).map_err(|e| read_err(std::io::Error::other(e)))?;
    Ok(Some(incomplete))
}

/// One file of a run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(rename_all = "camelCase")]
pub struct ManifestFile {
    /// Relative to the run folder, `/`-separated (e.g. `events.jsonl`, `ulog/drone-0.ulg`).
    pub path: String,
    /// Bytes.
    pub size: u64,
    /// SHA-256 of the content, 64 lowercase hex digits.
    pub sha256: String,
}

impl Manifest {
    /// A manifest for `files` (sorted here), with the counts filled in.
    pub fn new(namespace: &str, run: &str, uid: &str, mut files: Vec<ManifestFile>) -> Self {
        files.sort_by(|a, b| a.path.cmp(&b.path));
        Self {
            format_version: MANIFEST_FORMAT_VERSION,
            namespace: namespace.into(),
            run: run.into(),
            uid: uid.into(),
            file_count: files.len(),
            total_bytes: files.iter().map(|f| f.size).sum(),
            files,
            incomplete: None,
        }
    }

    /// Reads and checks a manifest; `url` (of the run folder) names it in errors. Paths must
    /// be relative and free of `.`/`..` segments, so `get` never writes outside its folder.
    ///
    /// # Errors
    /// [`ArchiveError::BadManifest`] naming the first problem.
    pub fn parse(bytes: &[u8], url: &str) -> Result<Self, ArchiveError> {
        let bad = |reason: String| ArchiveError::BadManifest { url: url.into(), reason };
        let manifest: Self = serde_json::from_slice(bytes).map_err(|e| bad(format!("not a manifest: {e}")))?;
        if manifest.format_version != MANIFEST_FORMAT_VERSION {
            return Err(bad(format!(
                "formatVersion {}: this sadesim reads formatVersion {MANIFEST_FORMAT_VERSION}",
                manifest.format_version
            )));
        }
        let mut seen = BTreeSet::new();
        for (i, f) in manifest.files.iter().enumerate() {
            let at = format!("files[{i}]");
            check_relative_path(&f.path).map_err(|e| bad(format!("{at}.path {:?}: {e}", f.path)))?;
            if f.path == MANIFEST_FILE {
                return Err(bad(format!("{at}.path: the manifest does not list itself")));
            }
            if !seen.insert(f.path.as_str()) {
                return Err(bad(format!("{at}.path {:?}: listed twice", f.path)));
            }
            if f.sha256.len() != 64 || !f.sha256.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)) {
                return Err(bad(format!("{at}.sha256 {:?}: expected 64 lowercase hex digits", f.sha256)));
            }
        }
        for (i, f) in manifest.incomplete.iter().flat_map(|i| &i.files).enumerate() {
            check_relative_path(&f.path).map_err(|e| bad(format!("incomplete.files[{i}].path {:?}: {e}", f.path)))?;
        }
        Ok(manifest)
    }

    pub(super) fn to_json(&self) -> Vec<u8> {
        let mut bytes = serde_json::to_vec_pretty(self).expect("a manifest always serialises");
        bytes.push(b'\n');
        bytes
    }
}

/// Lowercase hex.
pub(super) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A file of a local run folder.
#[derive(Debug, Clone)]
pub(super) struct LocalFile {
    /// `/`-separated, relative to the run folder.
    pub(super) rel: String,
    pub(super) path: PathBuf,
    /// Bytes when scanned.
    pub(super) size: u64,
}

/// Every regular file under `dir` (symbolic links followed), sorted by relative path,
/// except a `manifest.json` at the top (it is rewritten).
pub(super) fn scan_local(dir: &FsPath) -> Result<Vec<LocalFile>, ArchiveError> {
    let read_err = |path: &FsPath| {
        let path = path.display().to_string();
        move |source| ArchiveError::ReadLocal { path, source }
    };
    if !std::fs::metadata(dir).map_err(read_err(dir))?.is_dir() {
        return Err(ArchiveError::ReadLocal {
            path: dir.display().to_string(),
            source: std::io::Error::other("not a folder"),
        });
    }
    let mut files = Vec::new();
    let mut pending = vec![(dir.to_path_buf(), String::new())];
    while let Some((folder, rel)) = pending.pop() {
        for entry in std::fs::read_dir(&folder).map_err(read_err(&folder))? {
            let entry = entry.map_err(read_err(&folder))?;
            let path = entry.path();
            let Some(name) = entry.file_name().to_str().map(String::from) else {
                return Err(ArchiveError::BadFileName {
                    path: path.display().to_string(),
                    reason: "name is not UTF-8: archives need UTF-8 object names".into(),
                });
            };
            check_segment(&name).map_err(|reason| ArchiveError::BadFileName {
                path: path.display().to_string(),
                reason: format!("cannot be archived: {reason}"),
            })?;
            let child = if rel.is_empty() { name } else { format!("{rel}/{name}") };
            let meta = std::fs::metadata(&path).map_err(read_err(&path))?;
            if meta.is_dir() {
                pending.push((path, child));
            } else if meta.is_file() && child != MANIFEST_FILE {
                files.push(LocalFile { rel: child, path, size: meta.len() });
            }
        }
    }
    files.sort_by(|a, b| a.rel.cmp(&b.rel));
    Ok(files)
}

/// SHA-256 (hex) and size of a local file.
fn hash_local(path: &FsPath) -> Result<(String, u64), ArchiveError> {
    let read_err = |source| ArchiveError::ReadLocal { path: path.display().to_string(), source };
    let mut file = std::fs::File::open(path).map_err(read_err)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; READ_CHUNK_BYTES];
    let mut size = 0u64;
    loop {
        let n = file.read(&mut buf).map_err(read_err)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        size += n as u64;
    }
    Ok((hex(&hasher.finalize()), size))
}

/// Writes `manifest.json` into the local run folder `dir` (every file under it, hashed
/// now), through a temporary file and a rename so a reader never sees half a manifest.
///
/// # Errors
/// [`ArchiveError::ReadLocal`]/[`ArchiveError::BadFileName`] naming a file;
/// [`ArchiveError::WriteLocal`] when the manifest cannot be written.
pub fn write_manifest(dir: &FsPath, namespace: &str, run: &str, uid: &str) -> Result<Manifest, ArchiveError> {
    let files = scan_local(dir)?
        .into_iter()
        .map(|f| {
            let (sha256, size) = hash_local(&f.path)?;
            Ok(ManifestFile { path: f.rel, size, sha256 })
        })
        .collect::<Result<Vec<_>, ArchiveError>>()?;
    let mut manifest = Manifest::new(namespace, run, uid, files);
    manifest.incomplete = read_incomplete(dir)?;
    let path = dir.join(MANIFEST_FILE);
    let tmp = dir.join(format!(".{MANIFEST_FILE}.tmp"));
    let write_err = |source| ArchiveError::WriteLocal { path: path.display().to_string(), source };
    if let Err(e) = std::fs::write(&tmp, manifest.to_json()) {
        // A full disk leaves no half-written temporary file behind.
        let _ = std::fs::remove_file(&tmp);
        return Err(write_err(e));
    }
    std::fs::rename(&tmp, &path).map_err(write_err)?;
    Ok(manifest)
}
