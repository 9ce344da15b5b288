use std::collections::BTreeMap;
use std::path::{Path as FsPath, PathBuf};

use sha2::{Digest, Sha256};

use super::manifest::hex;
use super::upload::PART_BYTES;
use super::url::{Location, parse_location};
use super::*;

/// A fresh, empty temporary folder for one test.
pub(crate) fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-archive-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// A run folder like `sadesim run` writes: a few files, one in a sub-folder.
fn make_run(dir: &FsPath) -> BTreeMap<String, Vec<u8>> {
    let files: BTreeMap<String, Vec<u8>> = [
        ("events.jsonl", b"{\"timeS\":0.0,\"event\":\"runStarted\"}\n".to_vec()),
        ("summary.json", b"{\"run\":\"quickstart\"}".to_vec()),
        ("empty.log", Vec::new()),
        ("ulog/drone-0.ulg", (0..5000u32).map(|i| (i * 7 % 251) as u8).collect()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    for (rel, bytes) in &files {
        let path = dir.join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }
    files
}

pub(crate) fn file_url(dir: &FsPath) -> String {
    format!("file://{}", dir.display())
}

#[test]
fn upload_list_verify_and_get_round_trip() {
    let root = temp("roundtrip");
    let local = root.join("local/quickstart/20261122T010058Z");
    let files = make_run(&local);
    let archive = Archive::open(&file_url(&root.join("archive"))).unwrap();
    let up = archive.upload_run(&local, "default", "quickstart", "20261122T010058Z").unwrap();
    assert_eq!(up.url, format!("file://{}/archive/default/quickstart/20261122T010058Z", root.display()));

    // Layout and manifest.
    let run_dir = root.join("archive/default/quickstart/20261122T010058Z");
    for (rel, bytes) in &files {
        assert_eq!(&std::fs::read(run_dir.join(rel)).unwrap(), bytes, "{rel}");
    }
    let manifest = Manifest::parse(&std::fs::read(run_dir.join(MANIFEST_FILE)).unwrap(), "test").unwrap();
    assert_eq!(manifest, up.manifest);
    assert_eq!(manifest.format_version, MANIFEST_FORMAT_VERSION);
    assert_eq!((manifest.namespace.as_str(), manifest.run.as_str()), ("default", "quickstart"));
    let listed: Vec<(&str, u64, &str)> =
        manifest.files.iter().map(|f| (f.path.as_str(), f.size, f.sha256.as_str())).collect();
    let expected: Vec<(String, u64, String)> =
        files.iter().map(|(k, v)| (k.clone(), v.len() as u64, sha256_hex(v))).collect();
    let expected: Vec<(&str, u64, &str)> = expected.iter().map(|(k, n, h)| (k.as_str(), *n, h.as_str())).collect();
    assert_eq!(listed, expected);
    assert_eq!(manifest.file_count, 4);
    assert_eq!(manifest.total_bytes, files.values().map(|v| v.len() as u64).sum::<u64>());

    // list
    let runs = archive.list().unwrap();
    assert_eq!(
        runs,
        vec![RunListing {
            path: "default/quickstart/20261122T010058Z".into(),
            files: 4,
            bytes: manifest.total_bytes,
            complete: true
        }]
    );

    // verify, through the archive and through the run folder's own URL and plain path.
    let report = archive.verify("default/quickstart/20261122T010058Z").unwrap();
    assert!(report.passed(), "{:?}", report.problems);
    assert_eq!((report.files_checked, report.bytes_checked), (4, manifest.total_bytes));
    assert!(verify(&up.url).unwrap().passed());
    assert!(verify(run_dir.to_str().unwrap()).unwrap().passed());

    // get
    let got = root.join("got");
    let report = get(&up.url, &got).unwrap();
    assert!(report.passed(), "{:?}", report.problems);
    for (rel, bytes) in &files {
        assert_eq!(&std::fs::read(got.join(rel)).unwrap(), bytes, "{rel}");
    }
    assert_eq!(std::fs::read(got.join(MANIFEST_FILE)).unwrap(), std::fs::read(run_dir.join(MANIFEST_FILE)).unwrap());
    // The downloaded folder verifies as a local run.
    assert!(verify(got.to_str().unwrap()).unwrap().passed());
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_flipped_byte_fails_verify_naming_the_file_and_both_checksums() {
    let root = temp("flip");
    let local = root.join("run");
    let files = make_run(&local);
    let up = Archive::open(&file_url(&root.join("archive"))).unwrap().upload_run(&local, "ns", "r", "u1").unwrap();
    let target = root.join("archive/ns/r/u1/ulog/drone-0.ulg");
    let mut bytes = std::fs::read(&target).unwrap();
    bytes[1234] ^= 0x01;
    std::fs::write(&target, &bytes).unwrap();

    let report = verify(&up.url).unwrap();
    assert!(!report.passed());
    let original = &files["ulog/drone-0.ulg"];
    assert_eq!(
        report.problems,
        vec![Problem::Mismatch {
            path: "ulog/drone-0.ulg".into(),
            expected_size: 5000,
            actual_size: 5000,
            expected_sha256: sha256_hex(original),
            actual_sha256: sha256_hex(&bytes),
        }]
    );
    let text = report.problems[0].to_string();
    assert!(text.starts_with("ulog/drone-0.ulg: sha256 mismatch: expected "), "{text}");
    assert!(text.contains(&sha256_hex(original)) && text.contains(&sha256_hex(&bytes)), "{text}");

    // get downloads it anyway (to look at) and reports the same problem.
    let report = get(&up.url, &root.join("got")).unwrap();
    assert_eq!(report.problems.len(), 1);
    assert_eq!(report.problems[0].path(), "ulog/drone-0.ulg");
    assert_eq!(std::fs::read(root.join("got/ulog/drone-0.ulg")).unwrap(), bytes);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn missing_and_extra_files_are_reported() {
    let root = temp("missing");
    let local = root.join("run");
    make_run(&local);
    let up = Archive::open(&file_url(&root.join("archive"))).unwrap().upload_run(&local, "ns", "r", "u1").unwrap();
    let run_dir = root.join("archive/ns/r/u1");
    std::fs::remove_file(run_dir.join("summary.json")).unwrap();
    std::fs::write(run_dir.join("ulog/drone-9.ulg"), b"not listed").unwrap();
    let report = verify(&up.url).unwrap();
    let paths: Vec<(&str, bool)> =
        report.problems.iter().map(|p| (p.path(), matches!(p, Problem::Missing { .. }))).collect();
    assert_eq!(paths, vec![("summary.json", true), ("ulog/drone-9.ulg", false)]);
    assert!(matches!(&report.problems[1], Problem::Extra { size: 10, .. }));
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_run_without_manifest_is_incomplete() {
    let root = temp("incomplete");
    let local = root.join("run");
    make_run(&local);
    let archive = Archive::open(&file_url(&root.join("archive"))).unwrap();
    let up = archive.upload_run(&local, "ns", "r", "u1").unwrap();
    archive.upload_run(&local, "ns", "r", "u2").unwrap();
    std::fs::remove_file(root.join("archive/ns/r/u1").join(MANIFEST_FILE)).unwrap();

    let runs = archive.list().unwrap();
    let status: Vec<(&str, usize, bool)> = runs.iter().map(|r| (r.path.as_str(), r.files, r.complete)).collect();
    assert_eq!(status, vec![("ns/r/u1", 4, false), ("ns/r/u2", 4, true)]);

    let report = verify(&up.url).unwrap();
    assert_eq!(report.problems, vec![Problem::Incomplete]);
    assert!(report.manifest.is_none());
    let err = get(&up.url, &root.join("got")).unwrap_err();
    assert!(matches!(err, ArchiveError::Incomplete { .. }), "{err}");
    assert!(err.to_string().contains("incomplete run: no manifest.json"), "{err}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn large_files_go_up_in_parts_and_round_trip() {
    let root = temp("multipart");
    let local = root.join("run");
    std::fs::create_dir_all(&local).unwrap();
    // Two full 8 MiB parts and a short last one.
    let big: Vec<u8> = (0..(2 * PART_BYTES + 12_345)).map(|i| (i % 253) as u8).collect();
    assert!(big.len() as u64 > MULTIPART_THRESHOLD_BYTES);
    std::fs::write(local.join("trajectory.csv"), &big).unwrap();
    let up = Archive::open(&file_url(&root.join("archive"))).unwrap().upload_run(&local, "ns", "r", "u").unwrap();
    assert_eq!(up.manifest.files[0].sha256, sha256_hex(&big));
    assert_eq!(up.manifest.files[0].size, big.len() as u64);
    assert_eq!(std::fs::read(root.join("archive/ns/r/u/trajectory.csv")).unwrap(), big);
    let report = get(&up.url, &root.join("got")).unwrap();
    assert!(report.passed(), "{:?}", report.problems);
    assert_eq!(std::fs::read(root.join("got/trajectory.csv")).unwrap(), big);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_failed_upload_is_an_error_naming_the_file_and_writes_no_manifest() {
    let root = temp("failed");
    let local = root.join("run");
    make_run(&local);
    // The archive's `ns` is a file, so no object can be created below it.
    std::fs::create_dir_all(root.join("archive")).unwrap();
    std::fs::write(root.join("archive/ns"), b"in the way").unwrap();
    let err = Archive::open(&file_url(&root.join("archive"))).unwrap().upload_run(&local, "ns", "r", "u").unwrap_err();
    let ArchiveError::Upload { file, url, .. } = &err else { panic!("expected an upload error, got {err}") };
    assert!(file.starts_with(local.to_str().unwrap()), "{file}");
    assert!(url.ends_with(file.strip_prefix(local.to_str().unwrap()).unwrap()), "{url} vs {file}");
    assert!(err.to_string().starts_with(&format!("failed to upload {}", local.display())), "{err}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn local_run_folders_get_a_manifest_that_verify_checks() {
    let root = temp("local");
    let run_dir = root.join("runs/quickstart/20261122T010058Z");
    let files = make_run(&run_dir);
    let manifest = write_manifest(&run_dir, "default", "quickstart", "20261122T010058Z").unwrap();
    assert_eq!(manifest.file_count, files.len());
    assert!(!run_dir.join(".manifest.json.tmp").exists());
    assert!(verify(run_dir.to_str().unwrap()).unwrap().passed());
    assert!(verify(&file_url(&run_dir)).unwrap().passed());
    // A second manifest does not list the first.
    let again = write_manifest(&run_dir, "default", "quickstart", "20261122T010058Z").unwrap();
    assert_eq!(again, manifest);

    // A local runs folder lists runs two deep; a run without manifest (killed) is incomplete.
    make_run(&root.join("runs/quickstart/20261122T020000Z"));
    let runs = list(root.join("runs").to_str().unwrap()).unwrap();
    let status: Vec<(&str, bool)> = runs.iter().map(|r| (r.path.as_str(), r.complete)).collect();
    assert_eq!(status, vec![("quickstart/20261122T010058Z", true), ("quickstart/20261122T020000Z", false)]);

    // Uploading a folder that already holds a manifest replaces it.
    let up = Archive::open(&file_url(&root.join("archive")))
        .unwrap()
        .upload_run(&run_dir, "default", "quickstart", "20261122T010058Z")
        .unwrap();
    assert_eq!(up.manifest, manifest);
    assert!(verify(&up.url).unwrap().passed());

    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_plain_folder_of_runs_reports_nothing_there_when_missing() {
    let root = temp("notfound");
    let missing = root.join("nope");
    let err = list(missing.to_str().unwrap()).unwrap_err();
    assert!(matches!(err, ArchiveError::NotFound { .. }), "{err}");
    assert!(err.to_string().contains("nope: nothing there"), "{err}");
    let err = verify(&file_url(&missing)).unwrap_err();
    assert!(matches!(err, ArchiveError::NotFound { .. }), "{err}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn urls_are_parsed_or_refused_with_what_is_expected() {
    let cwd = std::env::current_dir().unwrap();
    assert_eq!(parse_location("file://runs").unwrap(), Location::Local(cwd.join("runs")));
    assert_eq!(parse_location("runs/./a/../b").unwrap(), Location::Local(cwd.join("runs/b")));
    assert_eq!(parse_location("file:///var/sadesim/").unwrap(), Location::Local(PathBuf::from("/var/sadesim")));
    assert_eq!(
        parse_location("s3://my-bucket/sade/runs/").unwrap(),
        Location::Cloud { scheme: "s3", bucket: "my-bucket".into(), prefix: "sade/runs".into() }
    );
    assert_eq!(
        parse_location("az://evidence").unwrap(),
        Location::Cloud { scheme: "az", bucket: "evidence".into(), prefix: String::new() }
    );
    for (url, expected) in [
        ("", "expected file:///absolute/folder"),
        ("file://", "file:// needs a folder"),
        ("s3://", "s3:// needs a bucket name, e.g. s3://my-bucket/runs"),
        ("az:///x", "az:// needs a container name"),
        ("gs://b/a//c", "prefix \"a//c\": empty path segment"),
        ("s3://b/../x", "segment \"..\" is not allowed"),
        ("s3://bu cket/x", "bucket name \"bu cket\": expected letters"),
        ("ftp://host/x", "unsupported scheme \"ftp\": expected file:///absolute/folder"),
    ] {
        let err = Archive::open(url).unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, ArchiveError::BadUrl { .. }), "{url}: {text}");
        assert!(text.starts_with(&format!("archive URL {url:?}: ")), "{url}: {text}");
        assert!(text.contains(expected), "{url}: {text}");
    }
    // An S3 URL opens without touching the network (credentials are read at first use).
    let archive = Archive::open("s3://my-bucket/sade/runs").unwrap();
    assert_eq!(archive.url(), "s3://my-bucket/sade/runs");
    assert!(is_object_store("s3://b") && is_object_store("gs://b") && is_object_store("az://c"));
    assert!(!is_object_store("file://runs") && !is_object_store("runs"));
}

#[test]
fn names_and_files_that_cannot_be_objects_are_refused() {
    let root = temp("names");
    let local = root.join("run");
    make_run(&local);
    let archive = Archive::open(&file_url(&root.join("archive"))).unwrap();
    for (ns, run, uid, field) in [("a/b", "r", "u", "namespace"), ("ns", "..", "u", "run"), ("ns", "r", "", "uid")] {
        let err = archive.upload_run(&local, ns, run, uid).unwrap_err();
        assert!(matches!(&err, ArchiveError::BadName { field: f, .. } if *f == field), "{err}");
    }
    std::fs::write(local.join("a#b.txt"), b"x").unwrap();
    let err = archive.upload_run(&local, "ns", "r", "u").unwrap_err();
    assert!(matches!(err, ArchiveError::BadFileName { .. }), "{err}");
    assert!(err.to_string().contains("a#b.txt: cannot be archived"), "{err}");
    // Nothing was uploaded: the name check comes first.
    assert!(!root.join("archive/ns").exists());
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn manifests_with_unsafe_or_unknown_content_are_refused() {
    let entry = |path: &str, sha: &str| format!(r#"{{"path":{path:?},"size":1,"sha256":{sha:?}}}"#);
    let good = "a".repeat(64);
    let doc = |version: u32, files: &[String]| {
        format!(
            r#"{{"formatVersion":{version},"namespace":"n","run":"r","uid":"u","fileCount":{},"totalBytes":0,"files":[{}]}}"#,
            files.len(),
            files.join(",")
        )
    };
    assert!(Manifest::parse(doc(1, &[entry("a/b.txt", &good)]).as_bytes(), "x").is_ok());
    for (text, expected) in [
        (doc(2, &[]), "formatVersion 2: this sadesim reads formatVersion 1"),
        (doc(1, &[entry("../etc/passwd", &good)]), "files[0].path \"../etc/passwd\": segment \"..\" is not allowed"),
        (doc(1, &[entry("/abs", &good)]), "must be relative"),
        (doc(1, &[entry("a", &good), entry("a", &good)]), "files[1].path \"a\": listed twice"),
        (doc(1, &[entry("a", "ABC")]), "files[0].sha256 \"ABC\": expected 64 lowercase hex digits"),
        (doc(1, &[entry("manifest.json", &good)]), "does not list itself"),
        ("{}".into(), "not a manifest"),
    ] {
        let err = Manifest::parse(text.as_bytes(), "s3://b/run").unwrap_err().to_string();
        assert!(err.starts_with("s3://b/run/manifest.json: "), "{err}");
        assert!(err.contains(expected), "{err}");
    }
}

#[test]
fn put_file_writes_one_object_outside_any_run_folder_and_refuses_unsafe_paths() {
    let root = temp("put-file");
    let archive = Archive::open(&file_url(&root)).unwrap();
    let url = archive.put_file("team-a/wind/sweep.json", b"{}\n".to_vec()).unwrap();
    assert_eq!(url, format!("file://{}/team-a/wind/sweep.json", root.display()));
    assert_eq!(std::fs::read(root.join("team-a/wind/sweep.json")).unwrap(), b"{}\n");
    assert!(!root.join("team-a/wind").join(MANIFEST_FILE).exists(), "no manifest is written");
    // Written again: replaced.
    archive.put_file("team-a/wind/sweep.json", b"[]".to_vec()).unwrap();
    assert_eq!(std::fs::read(root.join("team-a/wind/sweep.json")).unwrap(), b"[]");
    for bad in ["", "/abs", "../up", "a//b"] {
        let err = archive.put_file(bad, Vec::new()).unwrap_err();
        assert!(matches!(err, ArchiveError::BadName { field: "path", .. }), "{bad:?}: {err}");
    }
    std::fs::remove_dir_all(&root).unwrap();
}
