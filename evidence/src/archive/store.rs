//! [`Archive`]: an archive URL opened on its object store (or local folder), with the runtime
//! that drives it, progress bars, and listing the objects under a folder.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use futures_util::TryStreamExt;
use indicatif::{ProgressBar, ProgressStyle};
use object_store::path::Path as ObjectPath;
use object_store::{BackoffConfig, ObjectStore, ObjectStoreExt, RetryConfig};

use super::ArchiveError;
use super::url::{Location, child_path, parse_location};

/// Files uploaded or checked at once: hides the per-request latency of object stores.
pub(super) const FILES_IN_FLIGHT: usize = 8;

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
    pub(super) url: String,
    pub(super) store: Arc<dyn ObjectStore>,
    /// The URL's folder inside `store`.
    pub(super) prefix: ObjectPath,
    /// The folder of a local archive (existence is checked before reading).
    pub(super) local: Option<PathBuf>,
    pub(super) runtime: tokio::runtime::Runtime,
    /// Draw progress bars on stderr.
    pub(super) progress: bool,
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
    pub(super) fn url_of(&self, rel: &str) -> String {
        if rel.is_empty() { self.url.clone() } else { format!("{}/{rel}", self.url) }
    }

    pub(super) fn bar(&self, total_bytes: u64, verb: &str) -> ProgressBar {
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
    pub(super) fn list_objects(&self, rel: &str) -> Result<BTreeMap<String, u64>, ArchiveError> {
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
}

/// The bytes of the one object at `url` (`s3://bucket/path/file`, `gs://...`, `az://...`),
/// read whole: a world's map or DEM kept in object storage. Credentials come from the
/// environment as for archives.
///
/// # Errors
/// [`ArchiveError::BadUrl`] when `url` is not an object-store URL of a file,
/// [`ArchiveError::Open`] when the store cannot be configured, [`ArchiveError::NotFound`]
/// when nothing is there, [`ArchiveError::Download`] when the read fails.
pub fn read_object(url: &str) -> Result<Vec<u8>, ArchiveError> {
    let bad = |expected: &str| ArchiveError::BadUrl { url: url.into(), expected: expected.into() };
    if !super::is_object_store(url) {
        return Err(bad("an object-store URL of a file: s3://bucket/path/file, gs://... or az://..."));
    }
    let (folder, name) =
        url.trim_end_matches('/').rsplit_once('/').ok_or_else(|| bad("a file name after the bucket"))?;
    if !folder.contains("://") || folder.ends_with(':') || folder.ends_with("://") {
        return Err(bad("a file name after the bucket, e.g. s3://maps/helsinki.osm.pbf"));
    }
    super::url::check_segment(name).map_err(|e| bad(&e))?;
    let archive = Archive::open(folder)?;
    let path = super::url::child_path(&archive.prefix, name);
    archive.runtime.block_on(async { archive.store.get(&path).await?.bytes().await }).map(|b| b.to_vec()).map_err(
        |source| match source {
            object_store::Error::NotFound { .. } => ArchiveError::NotFound { url: url.into() },
            source => ArchiveError::Download { url: url.into(), source: Box::new(source) },
        },
    )
}
