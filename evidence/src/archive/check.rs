//! Verifying and downloading a run: every file re-read and compared with the manifest, and
//! the problems found (missing, mismatched, extra files, no manifest).

use std::collections::BTreeSet;
use std::path::Path as FsPath;

use futures_util::{StreamExt, TryStreamExt};
use indicatif::ProgressBar;
use object_store::ObjectStoreExt;
use object_store::path::Path as ObjectPath;
use sha2::{Digest, Sha256};

use super::manifest::hex;
use super::store::FILES_IN_FLIGHT;
use super::url::{check_relative_path, child_path};
use super::{Archive, ArchiveError, FileState, MANIFEST_FILE, Manifest, ManifestFile};

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
    /// The manifest says the run's recording stopped on a write error (the disk filled) and
    /// this file is not whole (`manifest.incomplete`): its bytes may match, the run is still
    /// incomplete.
    Unfinished { path: String, state: FileState, detail: String },
    /// The manifest says the run's recording stopped on a write error: the error, naming
    /// the file that could not be written (`manifest.incomplete.reason`).
    Stopped { reason: String },
}

impl Problem {
    /// The file concerned (`manifest.json` for [`Problem::Incomplete`]).
    pub fn path(&self) -> &str {
        match self {
            Self::Incomplete => MANIFEST_FILE,
            Self::Missing { path, .. }
            | Self::Mismatch { path, .. }
            | Self::Extra { path, .. }
            | Self::Unfinished { path, .. } => path,
            Self::Stopped { .. } => super::INCOMPLETE_FILE,
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
            Self::Unfinished { path, state, detail } => write!(f, "{path}: incomplete ({state}): {detail}"),
            Self::Stopped { reason } => {
                write!(f, "the run's recording stopped on a write error: {reason} (the manifest's `incomplete`)")
            }
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

impl Archive {
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

    /// One file of the folder `run` (as in [`Archive::verify`]), read whole and checked
    /// against the folder's manifest: what a role loads before trusting it (the world
    /// bundle's `world.bin`), without re-reading the folder's other files.
    ///
    /// # Errors
    /// [`ArchiveError::Incomplete`] without a manifest, [`ArchiveError::BadManifest`] when
    /// it does not list `file`, [`ArchiveError::Corrupt`] when the bytes do not match it,
    /// [`ArchiveError::Download`] naming the object that cannot be read.
    pub fn read_checked(&self, run: &str, file: &str) -> Result<Vec<u8>, ArchiveError> {
        let run = run.trim_matches('/');
        let url = self.url_of(run);
        let folder = child_path(&self.prefix, run);
        let get = |name: &str| {
            let object_url = format!("{url}/{name}");
            self.runtime.block_on(async { self.store.get(&child_path(&folder, name)).await?.bytes().await }).map_err(
                |source| match source {
                    object_store::Error::NotFound { .. } if name == MANIFEST_FILE => {
                        ArchiveError::Incomplete { url: url.clone() }
                    }
                    source => ArchiveError::Download { url: object_url, source: Box::new(source) },
                },
            )
        };
        let manifest = Manifest::parse(&get(MANIFEST_FILE)?, &url)?;
        let entry = manifest
            .files
            .iter()
            .find(|f| f.path == file)
            .ok_or_else(|| ArchiveError::BadManifest { url: url.clone(), reason: format!("lists no {file}") })?;
        let bytes = get(file)?;
        let sha256 = hex(&Sha256::digest(&bytes));
        if bytes.len() as u64 != entry.size || sha256 != entry.sha256 {
            return Err(ArchiveError::Corrupt {
                url: format!("{url}/{file}"),
                expected: format!("{} bytes, sha256 {}", entry.size, entry.sha256),
                actual: format!("{} bytes, sha256 {sha256}", bytes.len()),
            });
        }
        Ok(bytes.to_vec())
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
        // A run whose recording stopped on a write error: said file by file, whatever the
        // checksums say (they match what was written).
        for f in manifest.incomplete.iter().flat_map(|i| &i.files) {
            problems.push(Problem::Unfinished { path: f.path.clone(), state: f.state, detail: f.detail.clone() });
        }
        problems.sort_by(|a, b| a.path().cmp(b.path()));
        // Why the files listed after it are not whole, first.
        if let Some(incomplete) = &manifest.incomplete {
            problems.insert(0, Problem::Stopped { reason: incomplete.reason.clone() });
        }
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
