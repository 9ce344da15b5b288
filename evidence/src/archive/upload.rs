//! Uploads: a local run folder to `<archive>/<namespace>/<run>/<uid>/` (multipart for large
//! files, manifest last), files added to an uploaded run (the end of a run is
//! `crate::finish`), and single files written outside run folders (a sweep's report).

use std::io::Read;
use std::path::Path as FsPath;

use futures_util::{StreamExt, TryStreamExt};
use indicatif::ProgressBar;
use object_store::path::Path as ObjectPath;
use object_store::{ObjectStoreExt, PutPayload, WriteMultipart};
use sha2::{Digest, Sha256};

use super::manifest::{LocalFile, READ_CHUNK_BYTES, hex, read_incomplete, scan_local};
use super::store::FILES_IN_FLIGHT;
use super::url::{check_relative_path, check_run_names, child_path};
use super::{Archive, ArchiveError, MANIFEST_FILE, Manifest, ManifestFile};

/// Files larger than this (bytes) are uploaded in parts; smaller ones in one request.
pub const MULTIPART_THRESHOLD_BYTES: u64 = 8 * 1024 * 1024;
/// Size of each part of a multipart upload (bytes; S3 needs at least 5 MiB but the last).
pub(super) const PART_BYTES: usize = 8 * 1024 * 1024;
/// Parts of one file in flight at once.
const PARTS_IN_FLIGHT: usize = 4;

/// A finished upload.
#[derive(Debug, Clone)]
pub struct Uploaded {
    /// URL of the run folder, `<archive>/<namespace>/<run>/<uid>`.
    pub url: String,
    pub manifest: Manifest,
}

impl Archive {
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
        let mut manifest = Manifest::new(namespace, run, uid, entries?);
        manifest.incomplete = read_incomplete(local_dir)?;
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

    /// Writes `bytes` as the object `path` (relative to the archive URL, e.g.
    /// `team-a/wind/sweep.json`), replacing any object there; returns the object's URL. For
    /// files outside a run folder (a sweep's report): no manifest is written or changed.
    ///
    /// # Errors
    /// [`ArchiveError::BadName`] for a `path` that is not a relative object path;
    /// [`ArchiveError::Upload`] naming the object when the write fails after the store's
    /// retries.
    pub fn put_file(&self, path: &str, bytes: Vec<u8>) -> Result<String, ArchiveError> {
        check_relative_path(path).map_err(|reason| ArchiveError::BadName {
            field: "path",
            value: path.into(),
            expected: format!("expected a relative object path: {reason}"),
        })?;
        let url = self.url_of(path);
        let location = child_path(&self.prefix, path);
        self.runtime
            .block_on(self.store.put(&location, PutPayload::from(bytes)))
            .map_err(|source| ArchiveError::Upload { file: path.into(), url: url.clone(), source: Box::new(source) })?;
        Ok(url)
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
}
