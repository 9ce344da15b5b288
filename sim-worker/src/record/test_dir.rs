//! A temporary folder for the recorders' tests, removed when dropped.

use std::path::PathBuf;

/// `<tmp>/sadesim-record-<pid>-<name>/`, emptied on creation and removed on drop; `name`
/// must be unique among the tests of this crate that run at the same time.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("sadesim-record-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
