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

use std::path::PathBuf;

#[path = "build_npm.rs"]
mod npm;

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
    println!("cargo::rerun-if-changed=build_npm.rs");
    let wanted = npm::pinned_version(&web.join("package.json"), "three").expect("web/package.json pins three");
    let three = npm::find_or_install(&web, &out, "three", &wanted);
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
