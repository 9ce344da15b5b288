//! The archive's error type: every variant names the URL, file or object involved.

use super::MANIFEST_FILE;

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
    /// A file does not match its manifest entry (damaged or partly written).
    #[error("{url}: does not match the manifest: expected {expected}, found {actual}")]
    Corrupt { url: String, expected: String, actual: String },
    /// `manifest.json` exists but cannot be used.
    #[error("{url}/{MANIFEST_FILE}: {reason}")]
    BadManifest { url: String, reason: String },
}
