//! Archive URLs: parsing `file://`, `s3://`, `gs://`, `az://` URLs and plain folder paths into a
//! location, and the checks that keep object paths and run names to plain path segments.

use std::path::{Component, Path as FsPath, PathBuf};

use object_store::path::{Path as ObjectPath, PathPart};

use super::ArchiveError;

/// Where an archive URL points.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Location {
    /// An absolute, normalised local folder.
    Local(PathBuf),
    /// `scheme://bucket/prefix`; `prefix` without leading or trailing `/`, maybe empty.
    Cloud { scheme: &'static str, bucket: String, prefix: String },
}

const EXPECTED_URL: &str = "expected file:///absolute/folder, file://relative/folder, s3://bucket/prefix, gs://bucket/prefix, az://container/prefix or a folder path";

pub(super) fn parse_location(url: &str) -> Result<Location, ArchiveError> {
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
pub(super) fn check_relative_path(path: &str) -> Result<(), String> {
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
pub(super) fn check_run_names(namespace: &str, run: &str, uid: &str) -> Result<(), ArchiveError> {
    for (field, value) in [("namespace", namespace), ("run", run), ("uid", uid)] {
        check_segment(value).map_err(|reason| ArchiveError::BadName {
            field,
            value: value.into(),
            expected: format!("expected one path segment: {reason}"),
        })?;
    }
    Ok(())
}

pub(super) fn check_segment(segment: &str) -> Result<(), String> {
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
pub(super) fn child_path(base: &ObjectPath, rel: &str) -> ObjectPath {
    rel.split('/').filter(|s| !s.is_empty()).fold(base.clone(), |p, s| p.join(s))
}

/// `url` is an object store (`s3://`, `gs://`, `az://`) rather than a local folder.
pub fn is_object_store(url: &str) -> bool {
    matches!(url.split_once("://"), Some(("s3" | "gs" | "az", _)))
}
