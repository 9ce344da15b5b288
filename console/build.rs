//! Embeds the console's page and its map library into the binary, so `sadesim console`
//! (and the console pod) serves everything itself: no CDN, no internet.
//!
//! - The page: every `.html`, `.js`, `.css` and `.svg` file directly in `web/`.
//! - MapLibre GL JS (npm `maplibre-gl`, pinned in `web/package.json` and
//!   `web/package-lock.json`), from, first found wins: `web/node_modules/maplibre-gl` at the
//!   pinned version (`npm ci --prefix console/web`, or `tests/install-tools.sh`), or `npm ci`
//!   of the same lock file into `OUT_DIR`. Without either the build succeeds without the
//!   cfg `sadesim_maplibre`, and `sadesim console` refuses to start with a "not supported"
//!   error naming what to install.

use std::path::PathBuf;

#[path = "../sim-worker/build_npm.rs"]
mod npm;

/// The map library's files served under `/vendor/maplibre/`: (served name, path in the
/// npm package).
const MAPLIBRE_FILES: &[(&str, &str)] = &[
    ("maplibre-gl.js", "dist/maplibre-gl.js"),
    ("maplibre-gl.css", "dist/maplibre-gl.css"),
    ("LICENSE.txt", "LICENSE.txt"),
];

fn main() {
    println!("cargo::rustc-check-cfg=cfg(sadesim_maplibre)");
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let web = manifest.join("web");
    println!("cargo::rerun-if-changed=web");
    println!("cargo::rerun-if-changed=web/node_modules/maplibre-gl/package.json");

    let mut table = String::from("/// The page's files served at `/<name>`: (name, bytes).\n");
    table.push_str("pub static PAGE_FILES: &[(&str, &[u8])] = &[\n");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&web)
        .expect("console/web exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension().is_some_and(|x| ["html", "js", "css", "svg"].contains(&x.to_str().unwrap_or("")))
        })
        .collect();
    names.sort();
    for path in &names {
        println!("cargo::rerun-if-changed={}", path.display());
        let name = path.file_name().and_then(|n| n.to_str()).expect("UTF-8 file names");
        table.push_str(&format!("    ({name:?}, include_bytes!({:?})),\n", path.display().to_string()));
    }
    table.push_str("];\n");

    println!("cargo::rerun-if-changed=../sim-worker/build_npm.rs");
    let wanted = npm::pinned_version(&web.join("package.json"), "maplibre-gl");
    let maplibre = wanted.as_deref().and_then(|wanted| npm::find_or_install(&web, &out, "maplibre-gl", wanted));
    table.push_str("/// Files of npm `maplibre-gl` served under `/vendor/maplibre/`: (name, bytes).\n");
    table.push_str("pub static MAPLIBRE_FILES: &[(&str, &[u8])] = &[\n");
    match maplibre {
        Some(dir) => {
            println!("cargo::rustc-cfg=sadesim_maplibre");
            for (served, source) in MAPLIBRE_FILES {
                let path = dir.join(source);
                assert!(path.is_file(), "npm maplibre-gl has no {source}");
                table.push_str(&format!("    ({served:?}, include_bytes!({:?})),\n", path.display().to_string()));
            }
        }
        None => println!(
            "cargo::warning=MapLibre GL JS (npm maplibre-gl) is not installed and npm ci failed: `sadesim console` is off in this build. Run `npm ci --prefix console/web` and rebuild."
        ),
    }
    table.push_str("];\n");
    table.push_str(&format!(
        "/// The npm `maplibre-gl` version pinned.\npub const MAPLIBRE_VERSION: &str = {:?};\n",
        wanted.unwrap_or_default()
    ));
    std::fs::write(out.join("console_files.rs"), table).expect("OUT_DIR is writable");
}
