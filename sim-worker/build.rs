//! Embeds the live view's JavaScript library, three.js (npm `three`, pinned in
//! `web/package.json` and `web/package-lock.json`), into the binary: the renderer serves it
//! itself, so a browser needs no CDN and a cluster no internet (issue 18).
//!
//! Where the files come from, first found wins:
//! 1. `web/node_modules/three` at the pinned version (a developer's `npm ci --prefix web`,
//!    or `tests/install-tools.sh`);
//! 2. `npm ci` of the same lock file into `OUT_DIR` (needs npm and the npm registry, once
//!    per fresh target directory; npm's cache serves it afterwards).
//!
//! Without either (no npm on the build machine) the build still succeeds, without the cfg
//! `sadesim_three`: `rendering.enabled` is then refused with a "not supported: this build
//! has no three.js" error naming what to install, never a page that cannot draw.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The files the page imports: (path under `/vendor/three/`, path in the npm package).
const FILES: &[(&str, &str)] = &[
    ("three.module.js", "build/three.module.js"),
    ("three.core.js", "build/three.core.js"),
    ("addons/controls/OrbitControls.js", "examples/jsm/controls/OrbitControls.js"),
    ("addons/loaders/GLTFLoader.js", "examples/jsm/loaders/GLTFLoader.js"),
    ("addons/utils/BufferGeometryUtils.js", "examples/jsm/utils/BufferGeometryUtils.js"),
    ("addons/utils/SkeletonUtils.js", "examples/jsm/utils/SkeletonUtils.js"),
    ("LICENSE", "LICENSE"),
];

fn main() {
    println!("cargo::rustc-check-cfg=cfg(sadesim_three)");
    println!("cargo::rerun-if-changed=web/package.json");
    println!("cargo::rerun-if-changed=web/package-lock.json");
    println!("cargo::rerun-if-changed=web/node_modules/three/package.json");
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let web = manifest.join("web");
    let wanted = pinned_version(&web.join("package.json"));
    let three = [web.join("node_modules/three"), out.join("web/node_modules/three")]
        .into_iter()
        .find(|dir| installed_version(dir).as_deref() == Some(wanted.as_str()))
        .or_else(|| npm_ci(&web, &out.join("web"), &wanted));
    let mut table = String::from("/// Files of npm `three` served under `/vendor/three/`: (path, bytes).\n");
    table.push_str("pub static THREE_FILES: &[(&str, &[u8])] = &[\n");
    match three {
        Some(dir) => {
            println!("cargo::rustc-cfg=sadesim_three");
            for (served, source) in FILES {
                let path = dir.join(source);
                assert!(path.is_file(), "npm three@{wanted} has no {source}");
                table.push_str(&format!("    ({served:?}, include_bytes!({:?})),\n", path.display().to_string()));
            }
        }
        None => println!(
            "cargo::warning=three.js (npm three@{wanted}) is not installed and npm ci failed: this build's live view is off (rendering.enabled is refused). Run `npm ci --prefix sim-worker/web` and rebuild."
        ),
    }
    table.push_str("];\n");
    table.push_str(&format!("/// The npm `three` version embedded.\npub const THREE_VERSION: &str = {wanted:?};\n"));
    std::fs::write(out.join("three_files.rs"), table).expect("OUT_DIR is writable");
}

/// `dependencies.three` of `web/package.json` (an exact version).
fn pinned_version(package_json: &Path) -> String {
    let text = std::fs::read_to_string(package_json).expect("sim-worker/web/package.json exists");
    let after = text.split("\"three\"").nth(1).expect("web/package.json depends on three");
    after.split('"').nth(1).expect("three's version is a string").to_string()
}

/// The `version` of an installed npm package folder.
fn installed_version(dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join("package.json")).ok()?;
    let after = text.split("\"version\"").nth(1)?;
    Some(after.split('"').nth(1)?.to_string())
}

/// `npm ci` of `web`'s lock file into `into`; the package folder when it worked.
fn npm_ci(web: &Path, into: &Path, wanted: &str) -> Option<PathBuf> {
    std::fs::create_dir_all(into).ok()?;
    for file in ["package.json", "package-lock.json"] {
        std::fs::copy(web.join(file), into.join(file)).ok()?;
    }
    let status = Command::new("npm")
        .args(["ci", "--silent", "--no-audit", "--no-fund", "--ignore-scripts"])
        .current_dir(into)
        .status()
        .ok()?;
    let dir = into.join("node_modules/three");
    (status.success() && installed_version(&dir).as_deref() == Some(wanted)).then_some(dir)
}
