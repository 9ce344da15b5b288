//! A file too big for one Kubernetes ConfigMap (1 MiB of data), stored as parts (issue 19,
//! "10 000 drones"): `plan.json` of a 10 000-drone run is about 4.6 MB.
//!
//! `<file>.part-000`, `<file>.part-001`, ... hold consecutive slices of the file's bytes,
//! cut at UTF-8 character boundaries, and `<file>.sha256` the SHA-256 of the whole file (lower
//! case hex). The operator puts each part in a ConfigMap of its own and mounts them all in
//! one folder (a projected volume); [`read`] joins them and checks the digest, so a part
//! missing, stale (a ConfigMap of another generation) or cut short is an error naming it.
//! A file that fits one ConfigMap stays whole and is read as is.

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
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: neither the file nor its first part {first} exists")]
    Missing { path: String, first: String },
    #[error(
        "{path}: its {parts} part(s) join to SHA-256 {found}, but {digest} says {expected}: a part is missing or from another version of the run"
    )]
    Digest { path: String, parts: usize, found: String, digest: String, expected: String },
}

fn read_file(path: &Path) -> Result<Vec<u8>, PartsError> {
    std::fs::read(path).map_err(|source| PartsError::Io { path: path.display().to_string(), source })
}

/// The bytes of `path`: the file itself when it exists, otherwise its parts joined in
/// order and checked against its digest file.
///
/// # Errors
/// Neither the file nor its parts, an unreadable part or digest, or a digest mismatch.
pub fn read(path: &Path) -> Result<Vec<u8>, PartsError> {
    if path.exists() {
        return read_file(path);
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let sibling = |file: String| -> PathBuf { path.with_file_name(file) };
    let first = sibling(part_name(&name, 0));
    if !first.exists() {
        return Err(PartsError::Missing { path: path.display().to_string(), first: first.display().to_string() });
    }
    let mut bytes = Vec::new();
    let mut parts = 0;
    while sibling(part_name(&name, parts)).exists() {
        bytes.extend(read_file(&sibling(part_name(&name, parts)))?);
        parts += 1;
    }
    let digest = sibling(digest_name(&name));
    let expected = String::from_utf8_lossy(&read_file(&digest)?).trim().to_string();
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
    use super::*;

    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("sadesim-parts-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn write_parts(dir: &Path, text: &str, part_bytes: usize) -> usize {
        let parts = split(text, part_bytes);
        for (i, part) in parts.iter().enumerate() {
            std::fs::write(dir.join(part_name("plan.json", i)), part).unwrap();
        }
        std::fs::write(dir.join(digest_name("plan.json")), sha256_hex(text.as_bytes())).unwrap();
        parts.len()
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
        let dir = folder("read");
        let text = "x".repeat(2500) + "end";
        assert_eq!(write_parts(&dir, &text, 1000), 3);
        let path = dir.join("plan.json");
        assert_eq!(read(&path).unwrap(), text.as_bytes());
        // A part from another version of the file: the digest names the mismatch.
        std::fs::write(dir.join(part_name("plan.json", 1)), "y".repeat(1000)).unwrap();
        let e = read(&path).unwrap_err().to_string();
        assert!(e.contains("3 part(s)") && e.contains("plan.json.sha256"), "{e}");
        // The last part missing.
        write_parts(&dir, &text, 1000);
        std::fs::remove_file(dir.join(part_name("plan.json", 2))).unwrap();
        assert!(matches!(read(&path), Err(PartsError::Digest { parts: 2, .. })));
        // A whole file wins, parts or not.
        std::fs::write(&path, "whole").unwrap();
        assert_eq!(read(&path).unwrap(), b"whole");
        let e = read(&dir.join("fleet.json")).unwrap_err().to_string();
        assert!(e.contains("fleet.json.part-000"), "{e}");
        std::fs::remove_dir_all(dir).unwrap();
    }
}
