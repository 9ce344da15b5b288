//! What the tests of local runs with a pilot share: a scratch folder laid out as a user's
//! (the scenario's folder, where a pilot's relative paths resolve, and the output root),
//! and the options of `sadesim run` on it.

use std::path::{Path, PathBuf};

use sadesim::runner::RunOptions;

/// A fresh folder `sadesim-<what>-<pid>-<name>` under the temporary folder, holding the
/// scenario's folder (`scenario/`) and, once a run wrote it, the output (`out/`).
pub fn scratch(what: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sadesim-{what}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("scenario")).unwrap();
    dir
}

/// `sadesim run --no-mavlink` of `root/scenario/run.yaml` into `root/out`, in threads or
/// in worker processes (this workspace's debug `sim-worker`).
pub fn options(root: &Path, processes: bool) -> RunOptions {
    RunOptions {
        out_root: Some(root.join("out")),
        processes,
        worker: Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/debug/sim-worker")),
        scenario: Some(root.join("scenario/run.yaml")),
        mavlink: false,
        ..RunOptions::default()
    }
}
