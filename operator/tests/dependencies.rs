//! The operator links no simulation engine: its normal dependency tree (what the
//! `sadesim-operator` binary and image contain) has no physics, MAVLink or HTTP server
//! framework crate. Checked with `cargo tree` on the real lock file.

use std::process::Command;

/// Crates that belong to the engine's roles, never to the controller: the engine itself,
/// MAVLink, the HTTP servers, the report's and the cameras' renderers.
const ENGINE_CRATES: &[&str] = &["sim-worker", "sadesim-render", "mavlink", "axum", "resvg", "wgpu"];

/// Every crate of [`ENGINE_CRATES`] is one the workspace uses (in Cargo.lock): a crate
/// dropped from the workspace would make the check below pass by saying nothing.
#[test]
fn every_forbidden_crate_is_in_the_workspace() {
    let lock = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.lock")).expect("Cargo.lock");
    let missing: Vec<&&str> = ENGINE_CRATES.iter().filter(|c| !lock.contains(&format!("\nname = \"{c}\"\n"))).collect();
    assert!(missing.is_empty(), "not in Cargo.lock any more: {missing:?}; list the crates the engine uses now");
}

#[test]
fn the_operator_dependency_tree_has_no_engine_crate() {
    let out = Command::new(env!("CARGO"))
        .args(["tree", "--offline", "--locked", "-p", "sadesim-operator", "-e", "normal", "--prefix", "none"])
        .args(["--format", "{p}"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree failed: {}", String::from_utf8_lossy(&out.stderr));
    let tree = String::from_utf8(out.stdout).unwrap();
    let names: Vec<&str> = tree.lines().filter_map(|l| l.split_whitespace().next()).collect();
    assert!(names.contains(&"kube"), "the tree was read: {tree}");
    let found: Vec<&&str> = ENGINE_CRATES.iter().filter(|c| names.contains(c)).collect();
    assert!(
        found.is_empty(),
        "the operator depends on {found:?}; `cargo tree -p sadesim-operator -i <crate>` shows why"
    );
}
