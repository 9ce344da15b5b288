//! Run archives: a run's output folder copied to object storage (or a local folder) with a
//! `manifest.json` of checksums, so that anyone can later check that the evidence is
//! complete and unchanged (DESIGN §6 `archive`, §8 "nothing is lost").
//!
//! An archive is a URL: `file:///abs/path`, `file://relative/path` (relative to the current
//! directory), `s3://bucket/prefix`, `gs://bucket/prefix` or `az://container/prefix`; the
//! CLI also takes a plain folder path. A run in it lives at
//! `<prefix>/<namespace>/<run>/<uid>/<relative path>`, and its `manifest.json` (written
//! LAST, so a run without one is an incomplete upload) lists every file with its size in
//! bytes and its SHA-256. Local runs (`sadesim run`) keep their `<out>/<run>/<UTC time>/`
//! folder and get a `manifest.json` too, so `verify` works on them as on uploads: every
//! command that reads a run takes the URL (or path) of the folder that holds the manifest.
//!
//! Object-store credentials come from the standard environment variables (`AWS_*`,
//! `GOOGLE_*`, `AZURE_*`, read by `object_store`'s `from_env` builders), including
//! `AWS_ENDPOINT_URL` and `AWS_ALLOW_HTTP=true` for a local S3-compatible server.
//!
//! The API is blocking: each [`Archive`] owns a single-threaded tokio runtime, so the CLI
//! and the local runner call it like any file operation.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{IsTerminal, Read};
use std::path::{Component, Path as FsPath, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use futures_util::{StreamExt, TryStreamExt};
use indicatif::{ProgressBar, ProgressStyle};
use object_store::path::{Path as ObjectPath, PathPart};
use object_store::{BackoffConfig, ObjectStore, ObjectStoreExt, PutPayload, RetryConfig, WriteMultipart};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

#[cfg(test)]
mod tests;

/// The manifest's name in every run folder.
pub const MANIFEST_FILE: &str = "manifest.json";
/// `formatVersion` of the manifests this build writes and reads.
pub const MANIFEST_FORMAT_VERSION: u32 = 1;
/// Files larger than this (bytes) are uploaded in parts; smaller ones in one request.
pub const MULTIPART_THRESHOLD_BYTES: u64 = 8 * 1024 * 1024;
/// Size of each part of a multipart upload (bytes; S3 needs at least 5 MiB but the last).
const PART_BYTES: usize = 8 * 1024 * 1024;
/// Parts of one file in flight at once.
const PARTS_IN_FLIGHT: usize = 4;
/// Files uploaded or checked at once: hides the per-request latency of object stores.
const FILES_IN_FLIGHT: usize = 8;
/// Read buffer for local files (bytes).
const READ_CHUNK_BYTES: usize = 1024 * 1024;

/// Why an archive operation failed. Every variant names the URL, file or object involved.
#[derive(Debug, thiserror::Error)]
pub enum ArchiveError {
    /// The archive URL cannot be used as written.
    #[error("archive URL {url:?}: {expected}")]
    BadUrl { url: String, expected: String },
    /// The store could not be set up (e.g. missing credentials or account name).
    #[error("archive {url}: cannot open it: {source}{hint}")]
    Open { url: String, hint: String, source: Box<object_store::Error> },
    /// The async runtime that drives the store could not start.
    #[error("archive: cannot start the I/O runtime: {0}")]
    Runtime(std::io::Error),
    /// `namespace`, `run` or `uid` of an upload is not a single path segment.
    #[error("{field} {value:?}: {expected}")]
    BadName { field: &'static str, value: String, expected: String },
    /// A local file or folder could not be read.
    #[error("failed to read {path}: {source}")]
    ReadLocal { path: String, source: std::io::Error },
    /// A local file or folder could not be written.
    #[error("failed to write {path}: {source}")]
    WriteLocal { path: String, source: std::io::Error },
    /// A local file's name cannot be an object name.
    #[error("{path}: {reason}")]
    BadFileName { path: String, reason: String },
    /// Uploading a file failed (after the store's retries): the archive is incomplete.
    #[error("failed to upload {file} to {url}: {source}")]
    Upload { file: String, url: String, source: Box<object_store::Error> },
    /// Reading an object failed.
    #[error("failed to read {url}: {source}")]
    Download { url: String, source: Box<object_store::Error> },
    /// Listing the archive failed.
    #[error("failed to list {url}: {source}")]
    List { url: String, source: Box<object_store::Error> },
    /// Nothing is stored at the URL.
    #[error("{url}: nothing there (no such folder, or no objects under this prefix)")]
    NotFound { url: String },
    /// The run has files but no `manifest.json`: its upload did not finish.
    #[error("{url}: incomplete run: no {MANIFEST_FILE} (written last, so the upload did not finish)")]
    Incomplete { url: String },
    /// `manifest.json` exists but cannot be used.
    #[error("{url}/{MANIFEST_FILE}: {reason}")]
    BadManifest { url: String, reason: String },
}

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
        Ok(manifest)
    }

    fn to_json(&self) -> Vec<u8> {
        let mut bytes = serde_json::to_vec_pretty(self).expect("a manifest always serialises");
        bytes.push(b'\n');
        bytes
    }
}

/// A finished upload.
#[derive(Debug, Clone)]
pub struct Uploaded {
    /// URL of the run folder, `<archive>/<namespace>/<run>/<uid>`.
    pub url: String,
    pub manifest: Manifest,
}

/// One run found by [`Archive::list`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunListing {
    /// The run folder relative to the archive URL: `namespace/run/uid` for uploads,
    /// `run/<UTC time>` in a local runs folder, `.` when the URL is the run folder itself.
    pub path: String,
    /// Files in the folder, `manifest.json` not counted.
    pub files: usize,
    /// Their total size, bytes.
    pub bytes: u64,
    /// `manifest.json` is there (the upload finished).
    pub complete: bool,
}

/// Something [`Archive::verify`] or [`Archive::get`] found wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Problem {
    /// No `manifest.json`: the upload did not finish (nothing else can be checked).
    Incomplete,
    /// Listed in the manifest, not in the archive.
    Missing { path: String, expected_size: u64, expected_sha256: String },
    /// Content differs from the manifest.
    Mismatch { path: String, expected_size: u64, actual_size: u64, expected_sha256: String, actual_sha256: String },
    /// In the archive, not in the manifest.
    Extra { path: String, size: u64 },
}

impl Problem {
    /// The file concerned (`manifest.json` for [`Problem::Incomplete`]).
    pub fn path(&self) -> &str {
        match self {
            Self::Incomplete => MANIFEST_FILE,
            Self::Missing { path, .. } | Self::Mismatch { path, .. } | Self::Extra { path, .. } => path,
        }
    }
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Incomplete => {
                write!(f, "{MANIFEST_FILE}: missing: the run is incomplete (the manifest is written last)")
            }
            Self::Missing { path, expected_size, expected_sha256 } => {
                write!(f, "{path}: missing (the manifest lists {expected_size} bytes, sha256 {expected_sha256})")
            }
            Self::Mismatch { path, expected_size, actual_size, expected_sha256, actual_sha256 } => write!(
                f,
                "{path}: sha256 mismatch: expected {expected_sha256}, actual {actual_sha256} (size expected {expected_size}, actual {actual_size} bytes)"
            ),
            Self::Extra { path, size } => write!(f, "{path}: not in the manifest ({size} bytes)"),
        }
    }
}

/// What [`Archive::verify`] or [`Archive::get`] found.
#[derive(Debug, Clone)]
pub struct VerifyReport {
    /// URL of the run folder.
    pub url: String,
    /// `None` when the run has no manifest ([`Problem::Incomplete`]).
    pub manifest: Option<Manifest>,
    /// Files read and hashed.
    pub files_checked: usize,
    /// Bytes read and hashed.
    pub bytes_checked: u64,
    /// Sorted by path; empty when everything matches.
    pub problems: Vec<Problem>,
}

impl VerifyReport {
    /// Every file matches the manifest, none is missing or extra.
    pub fn passed(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Where an archive URL points.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Location {
    /// An absolute, normalised local folder.
    Local(PathBuf),
    /// `scheme://bucket/prefix`; `prefix` without leading or trailing `/`, maybe empty.
    Cloud { scheme: &'static str, bucket: String, prefix: String },
}

const EXPECTED_URL: &str = "expected file:///absolute/folder, file://relative/folder, s3://bucket/prefix, gs://bucket/prefix, az://container/prefix or a folder path";

fn parse_location(url: &str) -> Result<Location, ArchiveError> {
    let bad = |expected: &str| ArchiveError::BadUrl { url: url.into(), expected: expected.into() };
    let Some((scheme, rest)) = url.split_once("://") else {
        if url.is_empty() {
            return Err(bad(EXPECTED_URL));
        }
        return local_location(url, FsPath::new(url));
    };
    match scheme {
        "file" if rest.is_empty() => Err(bad("file:// needs a folder, e.g. file://runs or file:///var/sadesim")),
        "file" => local_location(url, FsPath::new(rest)),
        "s3" | "gs" | "az" => {
            let scheme = match scheme {
                "s3" => "s3",
                "gs" => "gs",
                _ => "az",
            };
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            let what = if scheme == "az" { "container" } else { "bucket" };
            if bucket.is_empty() {
                return Err(bad(&format!("{scheme}:// needs a {what} name, e.g. {scheme}://my-{what}/runs")));
            }
            if !bucket.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b)) {
                return Err(bad(&format!("{what} name {bucket:?}: expected letters, digits, '-', '_' and '.' only")));
            }
            let prefix = prefix.trim_matches('/');
            if !prefix.is_empty() {
                check_relative_path(prefix).map_err(|e| bad(&format!("prefix {prefix:?}: {e}")))?;
            }
            Ok(Location::Cloud { scheme, bucket: bucket.into(), prefix: prefix.into() })
        }
        other => Err(bad(&format!("unsupported scheme {other:?}: {EXPECTED_URL}"))),
    }
}

/// `path` made absolute (relative to the current directory) with `.` and `..` resolved
/// lexically.
fn local_location(url: &str, path: &FsPath) -> Result<Location, ArchiveError> {
    let absolute = std::path::absolute(path).map_err(|e| ArchiveError::BadUrl {
        url: url.into(),
        expected: format!("a folder path relative to the current directory or absolute ({e})"),
    })?;
    let mut normal = PathBuf::new();
    for c in absolute.components() {
        match c {
            Component::ParentDir => {
                normal.pop();
            }
            Component::CurDir => {}
            other => normal.push(other),
        }
    }
    Ok(Location::Local(normal))
}

/// A relative object path: `/`-separated segments, none empty, `.` or `..`, and only
/// characters that object names keep as they are (so the manifest's paths are the keys).
fn check_relative_path(path: &str) -> Result<(), String> {
    if path.is_empty() {
        return Err("empty path".into());
    }
    if path.starts_with('/') {
        return Err("must be relative (no leading '/')".into());
    }
    for segment in path.split('/') {
        check_segment(segment)?;
    }
    Ok(())
}

/// `namespace`, `run` and `uid` each one path segment of the run's folder
/// `<namespace>/<run>/<uid>/`, or the error naming the field.
fn check_run_names(namespace: &str, run: &str, uid: &str) -> Result<(), ArchiveError> {
    for (field, value) in [("namespace", namespace), ("run", run), ("uid", uid)] {
        check_segment(value).map_err(|reason| ArchiveError::BadName {
            field,
            value: value.into(),
            expected: format!("expected one path segment: {reason}"),
        })?;
    }
    Ok(())
}

fn check_segment(segment: &str) -> Result<(), String> {
    if segment.is_empty() {
        return Err("empty path segment ('//' or a trailing '/')".into());
    }
    if segment == "." || segment == ".." {
        return Err(format!("segment {segment:?} is not allowed"));
    }
    if PathPart::parse(segment).is_err() || PathPart::from(segment).as_ref() != segment {
        return Err(format!(
            "segment {segment:?} holds characters object names do not keep: control characters or any of \\ {{ }} ^ % ` [ ] \" < > ~ # | * ?"
        ));
    }
    Ok(())
}

/// `base` followed by the (checked) `/`-separated `rel`; `rel` empty is `base`.
fn child_path(base: &ObjectPath, rel: &str) -> ObjectPath {
    rel.split('/').filter(|s| !s.is_empty()).fold(base.clone(), |p, s| p.join(s))
}

/// Lowercase hex.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// How the store retries failed requests (server errors, throttling, broken connections):
/// up to 10 times with exponential backoff from 0.1 s to 15 s, within 3 minutes of the
/// first attempt. Client errors (403, 404) are not retried.
fn retry_config() -> RetryConfig {
    RetryConfig {
        backoff: BackoffConfig {
            init_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(15),
            base: 2.0,
        },
        max_retries: 10,
        retry_timeout: Duration::from_secs(180),
    }
}

/// An archive root (or a run folder) opened for reading and writing.
#[derive(Debug)]
pub struct Archive {
    /// The URL as shown in messages: `file:///abs/folder` or `s3://bucket/prefix`, no
    /// trailing `/`.
    url: String,
    store: Arc<dyn ObjectStore>,
    /// The URL's folder inside `store`.
    prefix: ObjectPath,
    /// The folder of a local archive (existence is checked before reading).
    local: Option<PathBuf>,
    runtime: tokio::runtime::Runtime,
    /// Draw progress bars on stderr.
    progress: bool,
}

impl Archive {
    /// Opens an archive URL (see the module docs; a plain path is a local folder). Nothing
    /// is read or created yet, so this fails only on the URL and the store's configuration.
    ///
    /// # Errors
    /// [`ArchiveError::BadUrl`] naming the URL and what is expected; [`ArchiveError::Open`]
    /// when the store cannot be configured from the environment.
    pub fn open(url: &str) -> Result<Self, ArchiveError> {
        let location = parse_location(url)?;
        let (shown, store, prefix, local): (String, Arc<dyn ObjectStore>, ObjectPath, Option<PathBuf>) = match &location
        {
            Location::Local(folder) => {
                let prefix = ObjectPath::from_absolute_path(folder).map_err(|e| ArchiveError::BadUrl {
                    url: url.into(),
                    expected: format!("a folder whose name object paths can hold: {e}"),
                })?;
                let shown = format!("file://{}", folder.display());
                (shown, Arc::new(object_store::local::LocalFileSystem::new()), prefix, Some(folder.clone()))
            }
            Location::Cloud { scheme, bucket, prefix } => {
                let root = format!("{scheme}://{bucket}");
                let shown = if prefix.is_empty() { root.clone() } else { format!("{root}/{prefix}") };
                let open_err = |hint: &str| {
                    let shown = shown.clone();
                    let hint = hint.to_string();
                    move |source| ArchiveError::Open { url: shown, hint, source: Box::new(source) }
                };
                let store: Arc<dyn ObjectStore> = match *scheme {
                    "s3" => Arc::new(
                        object_store::aws::AmazonS3Builder::from_env()
                            .with_url(&root)
                            .with_retry(retry_config())
                            .build()
                            .map_err(open_err(
                                " (S3 reads AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_REGION, AWS_ENDPOINT_URL, AWS_ALLOW_HTTP)",
                            ))?,
                    ),
                    "gs" => Arc::new(
                        object_store::gcp::GoogleCloudStorageBuilder::from_env()
                            .with_url(&root)
                            .with_retry(retry_config())
                            .build()
                            .map_err(open_err(
                                " (GCS reads GOOGLE_SERVICE_ACCOUNT, GOOGLE_SERVICE_ACCOUNT_KEY or GOOGLE_APPLICATION_CREDENTIALS)",
                            ))?,
                    ),
                    _ => Arc::new(
                        object_store::azure::MicrosoftAzureBuilder::from_env()
                            .with_url(&root)
                            .with_retry(retry_config())
                            .build()
                            .map_err(open_err(
                                " (Azure reads AZURE_STORAGE_ACCOUNT_NAME and AZURE_STORAGE_ACCOUNT_KEY or another AZURE_* credential)",
                            ))?,
                    ),
                };
                let prefix = ObjectPath::parse(prefix).expect("prefix checked by parse_location");
                (shown, store, prefix, None)
            }
        };
        let runtime =
            tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(ArchiveError::Runtime)?;
        Ok(Self { url: shown, store, prefix, local, runtime, progress: std::io::stderr().is_terminal() })
    }

    /// The archive's URL as shown in messages (`file:///abs/folder`, `s3://bucket/prefix`).
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Progress bars on stderr for uploads, downloads and checks (default: when stderr is a
    /// terminal).
    pub fn set_progress(&mut self, on: bool) {
        self.progress = on && std::io::stderr().is_terminal();
    }

    /// The URL of `rel` under the archive (`rel` empty: the archive itself).
    fn url_of(&self, rel: &str) -> String {
        if rel.is_empty() { self.url.clone() } else { format!("{}/{rel}", self.url) }
    }

    fn bar(&self, total_bytes: u64, verb: &str) -> ProgressBar {
        if !self.progress {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new(total_bytes);
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix} {bar:30.cyan/blue} {bytes}/{total_bytes} {binary_bytes_per_sec} {msg}",
            )
            .expect("a valid template"),
        );
        bar.set_prefix(verb.to_string());
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    }

    /// Every object under `rel` (relative to the archive): path relative to `rel` -> size.
    fn list_objects(&self, rel: &str) -> Result<BTreeMap<String, u64>, ArchiveError> {
        let url = self.url_of(rel);
        if let Some(folder) = &self.local {
            let folder = folder.join(rel);
            if !folder.is_dir() {
                return Err(ArchiveError::NotFound { url });
            }
        }
        let base = child_path(&self.prefix, rel);
        let metas: Vec<object_store::ObjectMeta> = self
            .runtime
            .block_on(self.store.list(Some(&base)).try_collect())
            .map_err(|source| ArchiveError::List { url: url.clone(), source: Box::new(source) })?;
        let mut objects = BTreeMap::new();
        for meta in metas {
            let Some(parts) = meta.location.prefix_match(&base) else { continue };
            let rel: Vec<String> = parts.map(|p| p.as_ref().to_string()).collect();
            if !rel.is_empty() {
                objects.insert(rel.join("/"), meta.size);
            }
        }
        Ok(objects)
    }

    /// Uploads the local run folder `local_dir` to `<archive>/<namespace>/<run>/<uid>/`:
    /// every file (sub-folders too; a `manifest.json` at its top is replaced), files over
    /// [`MULTIPART_THRESHOLD_BYTES`] in parts, then `manifest.json` last. Objects already
    /// there with the same names are overwritten.
    ///
    /// # Errors
    /// [`ArchiveError::BadName`] for a `namespace`, `run` or `uid` that is not one path
    /// segment; [`ArchiveError::ReadLocal`]/[`ArchiveError::BadFileName`] naming the local
    /// file; [`ArchiveError::Upload`] naming the first file whose upload failed after the
    /// store's retries (no manifest is written then: the run stays incomplete).
    pub fn upload_run(
        &self,
        local_dir: &FsPath,
        namespace: &str,
        run: &str,
        uid: &str,
    ) -> Result<Uploaded, ArchiveError> {
        check_run_names(namespace, run, uid)?;
        let files = scan_local(local_dir)?;
        let rel = format!("{namespace}/{run}/{uid}");
        let folder = child_path(&self.prefix, &rel);
        let url = self.url_of(&rel);
        let bar = self.bar(files.iter().map(|f| f.size).sum(), "uploading");
        let uploads = futures_util::stream::iter(files.iter().map(|f| self.upload_file(f, &folder, &url, &bar)))
            .buffer_unordered(FILES_IN_FLIGHT)
            .try_collect::<Vec<ManifestFile>>();
        let entries = self.runtime.block_on(uploads);
        bar.finish_and_clear();
        let manifest = Manifest::new(namespace, run, uid, entries?);
        let location = folder.clone().join(MANIFEST_FILE);
        self.runtime.block_on(self.store.put(&location, PutPayload::from(manifest.to_json()))).map_err(|source| {
            ArchiveError::Upload {
                file: MANIFEST_FILE.into(),
                url: format!("{url}/{MANIFEST_FILE}"),
                source: Box::new(source),
            }
        })?;
        Ok(Uploaded { url, manifest })
    }

    /// Adds files the operator owns under `owned_prefix` (e.g. `logs/`) to the run folder
    /// `<archive>/<namespace>/<run>/<uid>/` and rewrites its `manifest.json`: the entries
    /// already there outside `owned_prefix` (the coordinator's own upload) are kept, and
    /// every object under `owned_prefix` (earlier additions too) is hashed as stored.
    /// `files` are `(path relative to the run folder, content)`, each under `owned_prefix`.
    ///
    /// # Caveats
    /// A role that uploads its own `manifest.json` afterwards replaces this one; call this
    /// again after it has finished.
    ///
    /// # Errors
    /// [`ArchiveError::BadName`] for a name that is not one segment or a path outside
    /// `owned_prefix`; [`ArchiveError::Upload`], [`ArchiveError::List`],
    /// [`ArchiveError::Download`] naming the object; [`ArchiveError::BadManifest`] when the
    /// existing manifest cannot be read.
    pub fn add_files(
        &self,
        namespace: &str,
        run: &str,
        uid: &str,
        owned_prefix: &str,
        files: &[(String, Vec<u8>)],
    ) -> Result<Manifest, ArchiveError> {
        check_run_names(namespace, run, uid)?;
        let rel = format!("{namespace}/{run}/{uid}");
        let folder = child_path(&self.prefix, &rel);
        let url = self.url_of(&rel);
        for (path, bytes) in files {
            if !path.starts_with(owned_prefix) || check_relative_path(path).is_err() {
                return Err(ArchiveError::BadName {
                    field: "path",
                    value: path.clone(),
                    expected: format!("expected a relative path under {owned_prefix}"),
                });
            }
            let location = child_path(&folder, path);
            self.runtime.block_on(self.store.put(&location, PutPayload::from(bytes.clone()))).map_err(|source| {
                ArchiveError::Upload { file: path.clone(), url: format!("{url}/{path}"), source: Box::new(source) }
            })?;
        }
        let manifest_url = format!("{url}/{MANIFEST_FILE}");
        let existing =
            self.runtime.block_on(async { self.store.get(&folder.clone().join(MANIFEST_FILE)).await?.bytes().await });
        let mut entries = match existing {
            Ok(bytes) => Manifest::parse(&bytes, &url)?.files,
            Err(object_store::Error::NotFound { .. }) => Vec::new(),
            Err(source) => return Err(ArchiveError::Download { url: manifest_url, source: Box::new(source) }),
        };
        entries.retain(|f| !f.path.starts_with(owned_prefix));
        let owned = child_path(&folder, owned_prefix);
        let metas: Vec<object_store::ObjectMeta> =
            self.runtime.block_on(self.store.list(Some(&owned)).try_collect()).map_err(|source| {
                ArchiveError::List { url: format!("{url}/{owned_prefix}"), source: Box::new(source) }
            })?;
        for meta in metas {
            let Some(parts) = meta.location.prefix_match(&folder) else { continue };
            let path = parts.map(|p| p.as_ref().to_string()).collect::<Vec<_>>().join("/");
            let bytes = self
                .runtime
                .block_on(async { self.store.get(&meta.location).await?.bytes().await })
                .map_err(|source| ArchiveError::Download { url: format!("{url}/{path}"), source: Box::new(source) })?;
            entries.push(ManifestFile { path, size: bytes.len() as u64, sha256: hex(&Sha256::digest(&bytes)) });
        }
        let manifest = Manifest::new(namespace, run, uid, entries);
        self.runtime
            .block_on(self.store.put(&folder.clone().join(MANIFEST_FILE), PutPayload::from(manifest.to_json())))
            .map_err(|source| ArchiveError::Upload {
                file: MANIFEST_FILE.into(),
                url: manifest_url,
                source: Box::new(source),
            })?;
        Ok(manifest)
    }

    /// Uploads one file, hashing what it sends: the manifest describes the bytes uploaded.
    async fn upload_file(
        &self,
        file: &LocalFile,
        folder: &ObjectPath,
        folder_url: &str,
        bar: &ProgressBar,
    ) -> Result<ManifestFile, ArchiveError> {
        let location = child_path(folder, &file.rel);
        let err = |source| ArchiveError::Upload {
            file: file.path.display().to_string(),
            url: format!("{folder_url}/{}", file.rel),
            source: Box::new(source),
        };
        let read_err = |source| ArchiveError::ReadLocal { path: file.path.display().to_string(), source };
        let mut reader = std::fs::File::open(&file.path).map_err(read_err)?;
        let mut hasher = Sha256::new();
        let mut size = 0u64;
        if file.size <= MULTIPART_THRESHOLD_BYTES {
            let mut bytes = Vec::with_capacity(file.size as usize);
            reader.read_to_end(&mut bytes).map_err(read_err)?;
            hasher.update(&bytes);
            size = bytes.len() as u64;
            self.store.put(&location, PutPayload::from(bytes)).await.map_err(err)?;
            bar.inc(size);
        } else {
            bar.set_message(file.rel.clone());
            let upload = self.store.put_multipart(&location).await.map_err(err)?;
            let mut writer = WriteMultipart::new_with_chunk_size(upload, PART_BYTES);
            let mut buf = vec![0u8; READ_CHUNK_BYTES];
            loop {
                let n = match reader.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => n,
                    Err(e) => {
                        let _ = writer.abort().await;
                        return Err(read_err(e));
                    }
                };
                if let Err(e) = writer.wait_for_capacity(PARTS_IN_FLIGHT).await {
                    let _ = writer.abort().await;
                    return Err(err(e));
                }
                hasher.update(&buf[..n]);
                writer.write(&buf[..n]);
                size += n as u64;
                bar.inc(n as u64);
            }
            writer.finish().await.map_err(err)?;
        }
        Ok(ManifestFile { path: file.rel.clone(), size, sha256: hex(&hasher.finalize()) })
    }

    /// The runs under the archive: folders holding a `manifest.json` (complete), and
    /// objects outside any such folder grouped by their first three segments
    /// (`namespace/run/uid`; two, `run/<UTC time>`, when every complete run found is two
    /// deep, as in a local runs folder) as incomplete runs. Sorted by path.
    ///
    /// # Errors
    /// [`ArchiveError::NotFound`] for a local folder that does not exist;
    /// [`ArchiveError::List`] when the store cannot be listed.
    pub fn list(&self) -> Result<Vec<RunListing>, ArchiveError> {
        let objects = self.list_objects("")?;
        let split = |p: &str| -> Vec<String> { p.split('/').map(String::from).collect() };
        let complete: BTreeSet<Vec<String>> = objects
            .keys()
            .map(|k| split(k))
            .filter(|parts| parts.last().is_some_and(|l| l == MANIFEST_FILE))
            .map(|mut parts| {
                parts.pop();
                parts
            })
            .collect();
        let depth = if !complete.is_empty() && complete.iter().all(|c| c.len() == 2) { 2 } else { 3 };
        let mut runs: BTreeMap<Vec<String>, RunListing> = BTreeMap::new();
        for (key, size) in &objects {
            let parts = split(key);
            // The deepest run folder with a manifest that holds this object.
            let owner = (0..parts.len()).rev().map(|n| parts[..n].to_vec()).find(|p| complete.contains(p));
            let folder = owner.clone().unwrap_or_else(|| parts[..depth.min(parts.len() - 1)].to_vec());
            let entry = runs.entry(folder.clone()).or_insert_with(|| RunListing {
                path: if folder.is_empty() { ".".into() } else { folder.join("/") },
                files: 0,
                bytes: 0,
                complete: owner.is_some(),
            });
            if !(owner.is_some() && parts.len() == folder.len() + 1 && parts[folder.len()] == MANIFEST_FILE) {
                entry.files += 1;
                entry.bytes += size;
            }
        }
        Ok(runs.into_values().collect())
    }

    /// Checks the run folder `run` (relative to the archive URL, `""` for the URL itself):
    /// re-reads every file the manifest lists and compares size and SHA-256, and lists files
    /// that are missing or not in the manifest.
    ///
    /// # Errors
    /// Only when the check cannot be made: nothing at the URL, a listing or read failure,
    /// an unreadable manifest. A run without manifest is a [`Problem::Incomplete`].
    pub fn verify(&self, run: &str) -> Result<VerifyReport, ArchiveError> {
        self.check(run, None)
    }

    /// Downloads the run folder `run` (as in [`Archive::verify`]) into `dir` (created if
    /// needed; files there are overwritten), checking every file against the manifest as it
    /// arrives, then writes `manifest.json`. A file that does not match is still written (to
    /// be looked at) and reported; files not in the manifest are reported, not downloaded.
    ///
    /// # Errors
    /// As [`Archive::verify`], plus [`ArchiveError::Incomplete`] for a run without manifest
    /// and [`ArchiveError::WriteLocal`] naming a file that cannot be written.
    pub fn get(&self, run: &str, dir: &FsPath) -> Result<VerifyReport, ArchiveError> {
        self.check(run, Some(dir))
    }

    fn check(&self, run: &str, dir: Option<&FsPath>) -> Result<VerifyReport, ArchiveError> {
        let run = run.trim_matches('/');
        let url = self.url_of(run);
        if !run.is_empty() {
            check_relative_path(run)
                .map_err(|e| ArchiveError::BadUrl { url: url.clone(), expected: format!("run folder {run:?}: {e}") })?;
        }
        let objects = self.list_objects(run)?;
        if objects.is_empty() {
            return Err(ArchiveError::NotFound { url });
        }
        let folder = child_path(&self.prefix, run);
        if !objects.contains_key(MANIFEST_FILE) {
            if dir.is_some() {
                return Err(ArchiveError::Incomplete { url });
            }
            return Ok(VerifyReport {
                url,
                manifest: None,
                files_checked: 0,
                bytes_checked: 0,
                problems: vec![Problem::Incomplete],
            });
        }
        let manifest_url = format!("{url}/{MANIFEST_FILE}");
        let manifest_bytes = self
            .runtime
            .block_on(async { self.store.get(&folder.clone().join(MANIFEST_FILE)).await?.bytes().await })
            .map_err(|source| ArchiveError::Download { url: manifest_url, source: Box::new(source) })?;
        let manifest = Manifest::parse(&manifest_bytes, &url)?;
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir)
                .map_err(|source| ArchiveError::WriteLocal { path: dir.display().to_string(), source })?;
        }
        let bar = self.bar(manifest.total_bytes, if dir.is_some() { "downloading" } else { "verifying" });
        let mut problems = Vec::new();
        let mut present = Vec::new();
        for f in &manifest.files {
            if objects.contains_key(&f.path) {
                present.push(f);
            } else {
                problems.push(Problem::Missing {
                    path: f.path.clone(),
                    expected_size: f.size,
                    expected_sha256: f.sha256.clone(),
                });
            }
        }
        let checks = futures_util::stream::iter(present.iter().map(|f| self.check_file(f, &folder, &url, dir, &bar)))
            .buffer_unordered(FILES_IN_FLIGHT)
            .try_collect::<Vec<(u64, Option<Problem>)>>();
        let checked = self.runtime.block_on(checks);
        bar.finish_and_clear();
        let checked = checked?;
        let listed: BTreeSet<&str> = manifest.files.iter().map(|f| f.path.as_str()).collect();
        for (path, size) in &objects {
            if path != MANIFEST_FILE && !listed.contains(path.as_str()) {
                problems.push(Problem::Extra { path: path.clone(), size: *size });
            }
        }
        if let Some(dir) = dir {
            let path = dir.join(MANIFEST_FILE);
            std::fs::write(&path, &manifest_bytes)
                .map_err(|source| ArchiveError::WriteLocal { path: path.display().to_string(), source })?;
        }
        let bytes_checked = checked.iter().map(|(n, _)| n).sum();
        problems.extend(checked.into_iter().filter_map(|(_, p)| p));
        problems.sort_by(|a, b| a.path().cmp(b.path()));
        Ok(VerifyReport { url, files_checked: present.len(), bytes_checked, problems, manifest: Some(manifest) })
    }

    /// Reads one object, hashing it (and writing it under `dir` when given): bytes read and
    /// the mismatch, if any.
    async fn check_file(
        &self,
        f: &ManifestFile,
        folder: &ObjectPath,
        folder_url: &str,
        dir: Option<&FsPath>,
        bar: &ProgressBar,
    ) -> Result<(u64, Option<Problem>), ArchiveError> {
        use std::io::Write;
        let url = format!("{folder_url}/{}", f.path);
        let download_err = |source| ArchiveError::Download { url: url.clone(), source: Box::new(source) };
        let mut out = match dir {
            Some(dir) => {
                let path = f.path.split('/').fold(dir.to_path_buf(), |p, s| p.join(s));
                let write_err = |source| ArchiveError::WriteLocal { path: path.display().to_string(), source };
                if let Some(parent) = path.parent() {
                    std::fs::create_dir_all(parent).map_err(write_err)?;
                }
                Some((std::io::BufWriter::new(std::fs::File::create(&path).map_err(write_err)?), path))
            }
            None => None,
        };
        let mut stream = self.store.get(&child_path(folder, &f.path)).await.map_err(download_err)?.into_stream();
        let mut hasher = Sha256::new();
        let mut size = 0u64;
        while let Some(chunk) = stream.next().await {
            let chunk = chunk.map_err(download_err)?;
            hasher.update(&chunk);
            if let Some((w, path)) = &mut out {
                w.write_all(&chunk)
                    .map_err(|source| ArchiveError::WriteLocal { path: path.display().to_string(), source })?;
            }
            size += chunk.len() as u64;
            bar.inc(chunk.len() as u64);
        }
        if let Some((w, path)) = &mut out {
            w.flush().map_err(|source| ArchiveError::WriteLocal { path: path.display().to_string(), source })?;
        }
        let sha256 = hex(&hasher.finalize());
        let problem = (size != f.size || sha256 != f.sha256).then(|| Problem::Mismatch {
            path: f.path.clone(),
            expected_size: f.size,
            actual_size: size,
            expected_sha256: f.sha256.clone(),
            actual_sha256: sha256,
        });
        Ok((size, problem))
    }
}

/// The runs under an archive URL (see [`Archive::list`]).
///
/// # Errors
/// See [`Archive::open`] and [`Archive::list`].
pub fn list(url: &str) -> Result<Vec<RunListing>, ArchiveError> {
    Archive::open(url)?.list()
}

/// Verifies the run folder at `location` (`URL/NS/RUN/UID`, or a local run folder).
///
/// # Errors
/// See [`Archive::open`] and [`Archive::verify`].
pub fn verify(location: &str) -> Result<VerifyReport, ArchiveError> {
    Archive::open(location)?.verify("")
}

/// Downloads and verifies the run folder at `location` into `dir`.
///
/// # Errors
/// See [`Archive::open`] and [`Archive::get`].
pub fn get(location: &str, dir: &FsPath) -> Result<VerifyReport, ArchiveError> {
    Archive::open(location)?.get("", dir)
}

/// A file of a local run folder.
#[derive(Debug, Clone)]
struct LocalFile {
    /// `/`-separated, relative to the run folder.
    rel: String,
    path: PathBuf,
    /// Bytes when scanned.
    size: u64,
}

/// Every regular file under `dir` (symbolic links followed), sorted by relative path,
/// except a `manifest.json` at the top (it is rewritten).
fn scan_local(dir: &FsPath) -> Result<Vec<LocalFile>, ArchiveError> {
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
    let manifest = Manifest::new(namespace, run, uid, files);
    let path = dir.join(MANIFEST_FILE);
    let tmp = dir.join(format!(".{MANIFEST_FILE}.tmp"));
    let write_err = |source| ArchiveError::WriteLocal { path: path.display().to_string(), source };
    std::fs::write(&tmp, manifest.to_json()).map_err(write_err)?;
    std::fs::rename(&tmp, &path).map_err(write_err)?;
    Ok(manifest)
}

/// `url` is an object store (`s3://`, `gs://`, `az://`) rather than a local folder.
pub fn is_object_store(url: &str) -> bool {
    matches!(url.split_once("://"), Some(("s3" | "gs" | "az", _)))
}

/// The end of `sadesim run`, whatever the run's outcome: `manifest.json` into the local run
/// folder `out_dir`, then, when `archive_url` is an object store, the folder uploaded to
/// `<archive_url>/<namespace>/<run>/<uid>/` with `uid` the folder's name (its UTC start
/// time). Returns the upload, `None` for local archives (the folder is the archive).
///
/// # Errors
/// See [`write_manifest`], [`Archive::open`] and [`Archive::upload_run`].
pub fn archive_run_folder(
    out_dir: &FsPath,
    archive_url: Option<&str>,
    namespace: &str,
    run: &str,
    progress: bool,
) -> Result<Option<Uploaded>, ArchiveError> {
    let uid = out_dir.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
    write_manifest(out_dir, namespace, run, &uid)?;
    match archive_url {
        Some(url) if is_object_store(url) => {
            let mut archive = Archive::open(url)?;
            archive.set_progress(progress);
            archive.upload_run(out_dir, namespace, run, &uid).map(Some)
        }
        _ => Ok(None),
    }
}
