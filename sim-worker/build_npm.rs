//! npm packages embedded by build scripts (sim-worker's three.js, the console's MapLibre):
//! the pinned version, found installed or fetched with `npm ci` of the lock file. Shared by
//! `sim-worker/build.rs` and `console/build.rs` (`#[path]` module).

use std::path::{Path, PathBuf};
use std::process::Command;

/// `dependencies[package]` of a `package.json` (an exact version).
pub fn pinned_version(package_json: &Path, package: &str) -> Option<String> {
    let text = std::fs::read_to_string(package_json).ok()?;
    let after = text.split(&format!("\"{package}\"")).nth(1)?;
    Some(after.split('"').nth(1)?.to_string())
}

/// The `version` of an installed npm package folder.
pub fn installed_version(dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join("package.json")).ok()?;
    let after = text.split("\"version\"").nth(1)?;
    Some(after.split('"').nth(1)?.to_string())
}

/// The folder of `package` at version `wanted`: `<web>/node_modules/<package>` when that
/// is the version installed (a developer's or `tests/install-tools.sh`'s `npm ci`), else
/// `npm ci` of `web`'s lock file into `<out>/web` (needs npm and the registry once per fresh
/// target directory). `None` when neither works.
pub fn find_or_install(web: &Path, out: &Path, package: &str, wanted: &str) -> Option<PathBuf> {
    let local = web.join("node_modules").join(package);
    if installed_version(&local).as_deref() == Some(wanted) {
        return Some(local);
    }
    let into = out.join("web");
    let fetched = into.join("node_modules").join(package);
    if installed_version(&fetched).as_deref() == Some(wanted) {
        return Some(fetched);
    }
    std::fs::create_dir_all(&into).ok()?;
    for file in ["package.json", "package-lock.json"] {
        std::fs::copy(web.join(file), into.join(file)).ok()?;
    }
    let status = Command::new("npm")
        .args(["ci", "--silent", "--no-audit", "--no-fund", "--ignore-scripts"])
        .current_dir(&into)
        .status()
        .ok()?;
    (status.success() && installed_version(&fetched).as_deref() == Some(wanted)).then_some(fetched)
}
