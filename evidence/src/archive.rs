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

mod check;
mod error;
mod listing;
mod manifest;
mod store;
mod upload;
mod url;

#[cfg(test)]
pub(crate) mod tests;

pub use check::{Problem, VerifyReport, get, verify};
pub use error::ArchiveError;
pub use listing::{RunListing, list};
#[cfg(feature = "report")]
pub(crate) use manifest::read_incomplete;
pub use manifest::{
    FileState, INCOMPLETE_FILE, Incomplete, IncompleteFile, MANIFEST_FILE, MANIFEST_FORMAT_VERSION, Manifest,
    ManifestFile, write_manifest,
};
pub use store::{Archive, read_object};
pub use upload::{MULTIPART_THRESHOLD_BYTES, Uploaded};
pub use url::is_object_store;
