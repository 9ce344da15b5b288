//! The layers hold: the pure crates (the engine among them) build no file system, process,
//! thread or socket code (their own unit tests aside) and depend on no I/O crate; what a
//! run reads and writes goes through the crates at the edges (`sources`, `evidence`,
//! `sim-worker`, the CLI, the operator), which hand the pure crates bytes and values. The
//! operator links no engine crate, so its image stays small and its reviewers read no
//! physics.

use std::path::{Path, PathBuf};

use super::{WORKSPACE, members, module_decls};

/// The crates with no I/O: the contracts, the world, satellite navigation, the wind field,
/// the planner and the simulation engine.
const PURE_CRATES: &[&str] =
    &["sadesim-crds", "sadesim-world", "sadesim-gnss", "sadesim-wind", "sadesim-planner", "sadesim-engine"];

/// Uses of the standard library's I/O that a pure crate must not make.
const FORBIDDEN_STD: &[&str] = &[
    "std::fs",
    "std::process",
    "std::thread",
    "std::net::TcpStream",
    "std::net::TcpListener",
    "std::net::UdpSocket",
    "std::io::stdin",
    "std::io::stdout",
    "std::env::var",
];

/// Crates that do I/O (runtimes, networking, object stores, the Kubernetes client,
/// processes) a pure crate must not depend on. (`crds` uses `kube`'s derive only; the
/// engine uses `mavlink`'s messages and framing only, see
/// [`mavlink_is_built_without_its_connections`].)
const IO_CRATES: &[&str] = &[
    "tokio",
    "object_store",
    "reqwest",
    "hyper",
    "axum",
    "mio",
    "socket2",
    "kube-client",
    "kube-runtime",
    "ctrlc",
    "nix",
    "wgpu",
];

/// The source files a crate builds, outside its unit tests: from the root, every `mod x;`
/// that is not `#[cfg(test)]`.
fn built_files(root: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut queue = vec![root.to_path_buf()];
    while let Some(file) = queue.pop() {
        let source = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("cannot read {}: {e}", file.display()));
        let stem = file.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
        let dir = match stem {
            "lib" | "main" | "mod" => file.parent().unwrap().to_path_buf(),
            _ => file.with_extension(""),
        };
        for decl in module_decls(&source).into_iter().filter(|m| !m.inline && !m.test_only) {
            let flat = dir.join(format!("{}.rs", decl.name));
            let nested = dir.join(&decl.name).join("mod.rs");
            let found = [flat, nested].into_iter().find(|p| p.exists());
            queue.push(found.unwrap_or_else(|| panic!("{}: `mod {};` has no file", file.display(), decl.name)));
        }
        files.push(file);
    }
    files.sort();
    files
}

/// The lines of `source` that the crate builds: comments and top-level `#[cfg(test)]`
/// inline modules left out.
fn built_lines(source: &str) -> Vec<(usize, &str)> {
    let mut lines = Vec::new();
    let mut test_attribute = false;
    let mut in_test_module = false;
    for (i, line) in source.lines().enumerate() {
        if in_test_module {
            in_test_module = line != "}";
            continue;
        }
        if line == "#[cfg(test)]" {
            test_attribute = true;
            continue;
        }
        let opens_module = line.contains("mod ") && line.ends_with('{');
        if std::mem::take(&mut test_attribute) && opens_module {
            in_test_module = true;
            continue;
        }
        if !line.trim_start().starts_with("//") {
            lines.push((i + 1, line));
        }
    }
    lines
}

/// The forbidden uses on the built lines of `source`, as `line: text`.
fn forbidden_uses(source: &str) -> Vec<String> {
    let grouped = |line: &str| {
        // `use std::{fs, ...}` and the like.
        line.contains("std::{")
            && ["fs", "process", "thread", "net"]
                .iter()
                .any(|m| line.split(|c: char| !c.is_alphanumeric() && c != '_').any(|word| word == *m))
    };
    built_lines(source)
        .into_iter()
        .filter(|(_, line)| FORBIDDEN_STD.iter().any(|p| line.contains(p)) || grouped(line))
        .map(|(n, line)| format!("{n}: {}", line.trim()))
        .collect()
}

#[test]
fn pure_crates_build_no_file_process_thread_or_socket_code() {
    let members = members();
    let mut problems = Vec::new();
    let mut files = 0;
    let workspace = Path::new(WORKSPACE).canonicalize().expect("the workspace exists");
    for name in PURE_CRATES {
        let member = members.iter().find(|m| m.name == *name).unwrap_or_else(|| panic!("{name} is not a member"));
        let root = member.lib.as_ref().unwrap_or_else(|| panic!("{name} has no library"));
        for file in built_files(root) {
            let source = std::fs::read_to_string(&file).unwrap();
            files += 1;
            for use_ in forbidden_uses(&source) {
                problems.push(format!(
                    "{} ({}): {use_}",
                    name,
                    file.strip_prefix(&workspace).unwrap_or(&file).display()
                ));
            }
        }
    }
    assert!(files > 40, "the pure crates' files were found: {files}");
    assert!(
        problems.is_empty(),
        "pure crates take bytes and values, never files, processes, threads, sockets or the environment; \
         move the I/O to the edge (sources, evidence, sim-worker's roles, the CLI) and pass what it reads:\n{}",
        problems.join("\n")
    );
}

/// The names of the crates in the normal dependency trees of `packages` (`cargo tree` on
/// the real lock file).
fn dependency_tree(packages: &[&str]) -> Vec<String> {
    let out = std::process::Command::new(env!("CARGO"))
        .args(["tree", "--offline", "--locked", "-e", "normal", "--prefix", "none", "--format", "{p}"])
        .args(packages.iter().flat_map(|c| ["-p", c]))
        .current_dir(WORKSPACE)
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree failed: {}", String::from_utf8_lossy(&out.stderr));
    let tree = String::from_utf8(out.stdout).unwrap();
    let names: Vec<String> = tree.lines().filter_map(|l| l.split_whitespace().next()).map(str::to_string).collect();
    assert!(names.iter().any(|n| n == "serde"), "the tree was read: {tree}");
    names
}

#[test]
fn pure_crates_depend_on_no_io_crate() {
    let names = dependency_tree(PURE_CRATES);
    let found: Vec<&&str> = IO_CRATES.iter().filter(|c| names.iter().any(|n| n == *c)).collect();
    assert!(found.is_empty(), "a pure crate depends on {found:?}; `cargo tree -i <crate>` shows which");
}

/// The `mavlink` crate the engine depends on is its message set and framing only: none of
/// its connection features (TCP, UDP, serial, async runtimes) is enabled anywhere in the
/// workspace, so the engine cannot open a MAVLink connection; the sockets are
/// `sim-worker`'s.
#[test]
fn mavlink_is_built_without_its_connections() {
    let out = std::process::Command::new(env!("CARGO"))
        .args(["tree", "--offline", "--locked", "-e", "normal", "--prefix", "none", "--format", "{p} [{f}]"])
        .args(["-p", "sadesim-engine", "-i", "mavlink"])
        .current_dir(WORKSPACE)
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree failed: {}", String::from_utf8_lossy(&out.stderr));
    let tree = String::from_utf8(out.stdout).unwrap();
    let line = tree.lines().find(|l| l.starts_with("mavlink ")).unwrap_or_else(|| panic!("no mavlink in {tree}"));
    let features = &line[line.find('[').unwrap() + 1..line.rfind(']').unwrap()];
    assert!(features.contains("std"), "the features were read: {line}");
    let connections: Vec<&str> = features
        .split(',')
        .filter(|f| ["tcp", "udp", "direct-serial", "tokio-1", "embedded", "embedded-hal-02"].contains(f))
        .collect();
    assert!(connections.is_empty(), "mavlink is built with connection features {connections:?}: {line}");
}

/// Crates of the engine and its roles, never of the controller: the engine itself, MAVLink, the
/// HTTP servers, the report's and the cameras' renderers.
const ENGINE_CRATES: &[&str] = &["sadesim-engine", "sim-worker", "sadesim-render", "mavlink", "axum", "resvg", "wgpu"];

/// The operator links no simulation engine: its normal dependency tree (what the
/// `sadesim-operator` binary and image contain) has no physics, MAVLink or HTTP server
/// framework crate.
#[test]
fn the_operator_dependency_tree_has_no_engine_crate() {
    let names = dependency_tree(&["sadesim-operator"]);
    assert!(names.iter().any(|n| n == "kube"), "the operator's tree was read: {names:?}");
    let found: Vec<&&str> = ENGINE_CRATES.iter().filter(|c| names.iter().any(|n| n == *c)).collect();
    assert!(
        found.is_empty(),
        "the operator depends on {found:?}; `cargo tree -p sadesim-operator -i <crate>` shows why"
    );
}

/// Every crate the checks above forbid is one the workspace uses (in Cargo.lock): a crate
/// dropped from the workspace would make a check pass by saying nothing.
#[test]
fn every_forbidden_crate_is_in_the_workspace() {
    let lock = std::fs::read_to_string(format!("{WORKSPACE}/Cargo.lock")).expect("Cargo.lock");
    let missing: Vec<&&str> =
        ENGINE_CRATES.iter().chain(IO_CRATES).filter(|c| !lock.contains(&format!("\nname = \"{c}\"\n"))).collect();
    assert!(missing.is_empty(), "not in Cargo.lock any more: {missing:?}; list the crates used now");
}

#[test]
fn the_scan_sees_io_and_skips_tests_and_comments() {
    let source = "//! Pure.\n\
                  use std::{collections::BTreeMap, fs};\n\
                  // std::fs in a comment is fine.\n\
                  fn read() { std::process::exit(1) }\n\
                  fn ip(s: &str) -> std::net::IpAddr { s.parse().unwrap() }\n\
                  #[cfg(test)]\n\
                  mod tests {\n    fn t() { std::fs::write(\"x\", \"y\").unwrap(); }\n}\n\
                  fn after() { std::thread::spawn(|| ()); }\n";
    assert_eq!(
        forbidden_uses(source),
        [
            "2: use std::{collections::BTreeMap, fs};",
            "4: fn read() { std::process::exit(1) }",
            "10: fn after() { std::thread::spawn(|| ()); }"
        ]
    );
}
