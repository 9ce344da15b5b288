//! Listing the runs of an archive: complete ones (with a manifest) and incomplete uploads.

use std::collections::{BTreeMap, BTreeSet};

use super::{Archive, ArchiveError, MANIFEST_FILE};

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

impl Archive {
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
}

/// The runs under an archive URL (see [`Archive::list`]).
///
/// # Errors
/// See [`Archive::open`] and [`Archive::list`].
pub fn list(url: &str) -> Result<Vec<RunListing>, ArchiveError> {
    Archive::open(url)?.list()
}
