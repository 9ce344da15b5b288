//! A file too big for one Kubernetes ConfigMap (1 MiB of data), stored as parts: `plan.json`
//! of a 10 000-drone run is about 4.6 MB.
//!
//! `<file>.part-000`, `<file>.part-001`, ... hold consecutive slices of the file's bytes,
//! cut at UTF-8 character boundaries, and `<file>.sha256` the SHA-256 of the whole file (lower
//! case hex). The operator puts each part in a ConfigMap of its own and mounts them all in
//! one folder (a projected volume); [`join`] joins them and checks the digest, so a part
//! missing, stale (a ConfigMap of another generation) or cut short is an error naming it.
//! A file that fits one ConfigMap stays whole and is read as is. Pure: the caller reads the
//! files (`sim_worker::roles::read_parts` from a folder).

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// Bytes of one part: under the 1 MiB ConfigMap limit with room for the object's metadata.
pub const PART_BYTES: usize = 900 * 1024;

/// Name of part `index` of `file` (e.g. `plan.json.part-003`).
pub fn part_name(file: &str, index: usize) -> String {
    format!("{file}.part-{index:03}")
}

/// Name of the digest file of `file` (`plan.json.sha256`).
pub fn digest_name(file: &str) -> String {
    format!("{file}.sha256")
}

/// SHA-256 of `bytes`, lower-case hex: the digests of plan parts, of a world's input files
/// (extract, DEM) and of the asset inputs in asset cache keys.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// `text` cut into slices of at most `part_bytes` bytes, at character boundaries (the
/// ConfigMap's `data` holds UTF-8 strings). `part_bytes` must be at least 4.
pub fn split(text: &str, part_bytes: usize) -> Vec<&str> {
    assert!(part_bytes >= 4, "a part holds at least one character");
    let mut parts = Vec::new();
    let mut rest = text;
    while !rest.is_empty() {
        let mut end = rest.len().min(part_bytes);
        while !rest.is_char_boundary(end) {
            end -= 1;
        }
        let (part, tail) = rest.split_at(end);
        parts.push(part);
        rest = tail;
    }
    parts
}

/// Why a file could not be read whole.
#[derive(Debug, thiserror::Error)]
pub enum PartsError {
    /// A file or part exists but could not be read (the reader's I/O error).
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: neither the file nor its first part {first} exists")]
    Missing { path: String, first: String },
    #[error("{path}: its parts are there but not their digest {digest}")]
    NoDigest { path: String, digest: String },
    #[error(
        "{path}: its {parts} part(s) join to SHA-256 {found}, but {digest} says {expected}: a part is missing or from another version of the run"
    )]
    Digest { path: String, parts: usize, found: String, digest: String, expected: String },
}

/// The bytes of the file `path`: the file itself when `fetch` has it, otherwise its parts
/// beside it joined in order and checked against its digest file. `fetch(path)` gives a
/// file's bytes, `None` when there is no such file (the caller does the reading: a folder,
/// a ConfigMap's data).
///
/// # Errors
/// Neither the file nor its first part, the digest missing or not matching, or what
/// `fetch` returns.
pub fn join(
    path: &Path,
    mut fetch: impl FnMut(&Path) -> Result<Option<Vec<u8>>, PartsError>,
) -> Result<Vec<u8>, PartsError> {
    if let Some(bytes) = fetch(path)? {
        return Ok(bytes);
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let sibling = |file: String| -> PathBuf { path.with_file_name(file) };
    let first = sibling(part_name(&name, 0));
    let Some(mut bytes) = fetch(&first)? else {
        return Err(PartsError::Missing { path: path.display().to_string(), first: first.display().to_string() });
    };
    let mut parts = 1;
    while let Some(part) = fetch(&sibling(part_name(&name, parts)))? {
        bytes.extend(part);
        parts += 1;
    }
    let digest = sibling(digest_name(&name));
    let Some(text) = fetch(&digest)? else {
        return Err(PartsError::NoDigest { path: path.display().to_string(), digest: digest.display().to_string() });
    };
    let expected = String::from_utf8_lossy(&text).trim().to_string();
    let found = sha256_hex(&bytes);
    if found != expected {
        return Err(PartsError::Digest {
            path: path.display().to_string(),
            parts,
            found,
            digest: digest.display().to_string(),
            expected,
        });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    /// Files by path, as a folder or a ConfigMap's data holds them.
    type Files = BTreeMap<PathBuf, Vec<u8>>;

    fn write_parts(files: &mut Files, text: &str, part_bytes: usize) -> usize {
        let parts = split(text, part_bytes);
        for (i, part) in parts.iter().enumerate() {
            files.insert(PathBuf::from(format!("run/{}", part_name("plan.json", i))), part.as_bytes().to_vec());
        }
        files.insert(PathBuf::from(format!("run/{}", digest_name("plan.json"))), sha256_hex(text.as_bytes()).into());
        parts.len()
    }

    fn read(files: &Files, path: &str) -> Result<Vec<u8>, PartsError> {
        join(Path::new(path), |p| Ok(files.get(p).cloned()))
    }

    #[test]
    fn parts_cut_at_character_boundaries_and_join_back() {
        let text = "{\"name\":\"drône-ü-€\"}".repeat(50);
        for part_bytes in [4, 5, 7, 64, 10_000] {
            let parts = split(&text, part_bytes);
            assert!(parts.iter().all(|p| p.len() <= part_bytes && !p.is_empty()));
            assert_eq!(parts.concat(), text, "{part_bytes}");
        }
        assert!(split("", 8).is_empty());
    }

    #[test]
    fn a_file_in_parts_reads_as_the_whole_and_a_bad_part_is_named() {
        let mut files = Files::new();
        let text = "x".repeat(2500) + "end";
        assert_eq!(write_parts(&mut files, &text, 1000), 3);
        assert_eq!(read(&files, "run/plan.json").unwrap(), text.as_bytes());
        // A part from another version of the file: the digest names the mismatch.
        files.insert(PathBuf::from(format!("run/{}", part_name("plan.json", 1))), vec![b'y'; 1000]);
        let e = read(&files, "run/plan.json").unwrap_err().to_string();
        assert!(e.contains("3 part(s)") && e.contains("run/plan.json.sha256"), "{e}");
        // The last part missing.
        write_parts(&mut files, &text, 1000);
        files.remove(&PathBuf::from(format!("run/{}", part_name("plan.json", 2))));
        assert!(matches!(read(&files, "run/plan.json"), Err(PartsError::Digest { parts: 2, .. })));
        // The digest missing.
        files.remove(&PathBuf::from(format!("run/{}", digest_name("plan.json"))));
        let e = read(&files, "run/plan.json").unwrap_err().to_string();
        assert!(e.contains("run/plan.json.sha256"), "{e}");
        // A whole file wins, parts or not.
        files.insert(PathBuf::from("run/plan.json"), b"whole".to_vec());
        assert_eq!(read(&files, "run/plan.json").unwrap(), b"whole");
        let e = read(&files, "run/fleet.json").unwrap_err().to_string();
        assert!(e.contains("fleet.json.part-000"), "{e}");
        // The reader's errors pass through.
        let e = join(Path::new("run/plan.json"), |p| {
            Err(PartsError::Io { path: p.display().to_string(), source: std::io::ErrorKind::PermissionDenied.into() })
        });
        assert!(matches!(e, Err(PartsError::Io { .. })));
    }
}
