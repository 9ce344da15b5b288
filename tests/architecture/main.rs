//! The architecture map stays true to the code: the crate graph drawn in
//! `docs/architecture.md` is the workspace's (read with `cargo metadata`), and every crate's
//! `lib.rs` doc names each module the crate declares; the pure crates do no I/O
//! ([`layering`]).

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::Command;

use serde_json::Value;

mod layering;

/// The workspace root (this crate is `tests/`).
const WORKSPACE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
/// The page that draws the crate graph, from the workspace root.
const DOC: &str = "docs/architecture.md";
/// The info string of the fenced block that holds the graph.
const GRAPH_INFO: &str = "text crate-graph";

/// A workspace member as `cargo metadata` describes it.
#[derive(Debug)]
struct Member {
    name: String,
    /// Workspace members it depends on as a normal dependency (not dev, not build).
    internal_deps: BTreeSet<String>,
    /// Its library target's root file (`lib.rs`), when it has one.
    lib: Option<PathBuf>,
}

fn members() -> Vec<Member> {
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--no-deps", "--offline"])
        .current_dir(WORKSPACE)
        .output()
        .expect("cargo runs");
    assert!(out.status.success(), "cargo metadata failed: {}", String::from_utf8_lossy(&out.stderr));
    let metadata: Value = serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON");
    let ids: BTreeSet<&str> =
        metadata["workspace_members"].as_array().expect("workspace_members").iter().filter_map(Value::as_str).collect();
    let packages: Vec<&Value> = metadata["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .filter(|p| p["id"].as_str().is_some_and(|id| ids.contains(id)))
        .collect();
    let names: BTreeSet<&str> = packages.iter().filter_map(|p| p["name"].as_str()).collect();
    let members: Vec<Member> = packages
        .iter()
        .map(|p| {
            let internal_deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .filter(|d| d["kind"].is_null())
                .filter_map(|d| d["name"].as_str())
                .filter(|name| names.contains(name))
                .map(str::to_string)
                .collect();
            let lib = p["targets"]
                .as_array()
                .expect("targets")
                .iter()
                .find(|t| {
                    t["kind"].as_array().is_some_and(|kinds| {
                        kinds.iter().any(|k| matches!(k.as_str(), Some("lib" | "rlib" | "dylib" | "proc-macro")))
                    })
                })
                .and_then(|t| t["src_path"].as_str())
                .map(PathBuf::from);
            Member { name: p["name"].as_str().expect("name").to_string(), internal_deps, lib }
        })
        .collect();
    assert!(members.len() >= 2, "cargo metadata listed the workspace: {members:?}");
    members
}

/// A member's line in the graph: `crate -> dep-a, dep-b` (sorted), or `crate -> (none)`.
fn graph_line(member: &Member) -> String {
    let deps: Vec<&str> = member.internal_deps.iter().map(String::as_str).collect();
    match deps.is_empty() {
        true => format!("{} -> (none)", member.name),
        false => format!("{} -> {}", member.name, deps.join(", ")),
    }
}

/// The non-empty lines of the one fenced block whose info string is [`GRAPH_INFO`].
fn graph_block(markdown: &str) -> Result<Vec<String>, String> {
    let mut blocks = Vec::new();
    let mut lines = markdown.lines();
    while let Some(line) = lines.next() {
        let Some(info) = line.trim_start().strip_prefix("```") else { continue };
        if info.trim() != GRAPH_INFO {
            // Skip over any other fenced block, so that its lines are never read as fences.
            for inner in lines.by_ref() {
                if inner.trim() == "```" {
                    break;
                }
            }
            continue;
        }
        let mut block = Vec::new();
        let mut closed = false;
        for inner in lines.by_ref() {
            if inner.trim() == "```" {
                closed = true;
                break;
            }
            if !inner.trim().is_empty() {
                block.push(inner.trim().to_string());
            }
        }
        if !closed {
            return Err(format!("the ```{GRAPH_INFO} block is never closed"));
        }
        blocks.push(block);
    }
    match blocks.len() {
        1 => Ok(blocks.pop().expect("one block")),
        0 => Err(format!("no fenced block with the info string `{GRAPH_INFO}`")),
        n => Err(format!("{n} fenced blocks with the info string `{GRAPH_INFO}`; keep one")),
    }
}

#[test]
fn the_crate_graph_in_the_architecture_doc_is_the_workspaces() {
    let members = members();
    let expected: Vec<String> = members.iter().map(graph_line).collect();
    let path = format!("{WORKSPACE}/{DOC}");
    let doc = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let documented = graph_block(&doc).unwrap_or_else(|e| panic!("{DOC}: {e}"));

    let want: BTreeSet<&str> = expected.iter().map(String::as_str).collect();
    let have: BTreeSet<&str> = documented.iter().map(String::as_str).collect();
    let missing: Vec<&str> = want.difference(&have).copied().collect();
    let extra: Vec<&str> = have.difference(&want).copied().collect();
    let repeated = documented.len() != have.len();
    if missing.is_empty() && extra.is_empty() && !repeated {
        return;
    }
    let list = |lines: &[&str]| match lines.is_empty() {
        true => "  (none)\n".to_string(),
        false => lines.iter().map(|l| format!("  {l}\n")).collect(),
    };
    panic!(
        "{DOC}: the ```{GRAPH_INFO} block is not the workspace's crate graph (`cargo metadata --format-version 1 \
         --no-deps --offline`).\nmissing lines (a crate or a dependency left out):\n{}stale or extra lines:\n{}{}\
         To regenerate, write one line per workspace member, `crate -> ` and its workspace-internal normal \
         dependencies sorted and comma-separated (`(none)` without any); in any order, for example:\n\
         ```{GRAPH_INFO}\n{}```\nThen update the prose around it (what each crate owns) to match.",
        list(&missing),
        list(&extra),
        if repeated { "some lines appear twice\n" } else { "" },
        expected.iter().map(|l| format!("{l}\n")).collect::<String>(),
    );
}

/// A top-level module declaration of a crate root.
#[derive(Debug, PartialEq)]
struct ModuleDecl {
    name: String,
    /// Compiled only for the crate's own unit tests (`#[cfg(test)]`).
    test_only: bool,
    /// `mod x { ... }` rather than `mod x;`.
    inline: bool,
}

impl ModuleDecl {
    /// The crate's own unit tests: compiled only for them, or an inline `mod tests { ... }`.
    fn is_unit_tests(&self) -> bool {
        self.test_only || (self.inline && self.name == "tests")
    }
}

/// The modules a crate root declares at its top level: `mod x;`, `pub mod x;`,
/// `pub(crate) mod x;` and the like, with the attributes above them, and inline
/// `mod x { ... }` blocks.
///
/// The workspace is formatted by rustfmt, so a top-level item starts at column 0 and
/// anything nested is indented: a line is read as a top-level declaration only when it
/// starts at column 0.
fn module_decls(source: &str) -> Vec<ModuleDecl> {
    let mut decls = Vec::new();
    let mut attributes: Vec<String> = Vec::new();
    let mut open_attribute: Option<(String, i32)> = None;
    for line in source.lines() {
        if let Some((mut text, mut depth)) = open_attribute.take() {
            text.push_str(line.trim());
            depth += bracket_balance(line);
            match depth > 0 {
                true => open_attribute = Some((text, depth)),
                false => attributes.push(text),
            }
            continue;
        }
        if line.starts_with("#[") {
            let depth = bracket_balance(line);
            match depth > 0 {
                true => open_attribute = Some((line.trim().to_string(), depth)),
                false => attributes.push(line.trim().to_string()),
            }
            continue;
        }
        if line.starts_with("///") || line.starts_with("//!") || line.starts_with("//") {
            continue;
        }
        let item = match line.strip_prefix("pub") {
            Some(rest) if rest.starts_with('(') => rest.find(')').map(|end| rest[end + 1..].trim_start()),
            Some(rest) if rest.starts_with(' ') => Some(rest.trim_start()),
            Some(_) => None,
            None => Some(line),
        };
        if let Some(rest) = item.and_then(|item| item.strip_prefix("mod ")) {
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            let after = rest[name.len()..].trim_start();
            let test_only = attributes.iter().any(|a| a.replace(' ', "") == "#[cfg(test)]");
            decls.push(ModuleDecl { name, test_only, inline: after.starts_with('{') });
        }
        attributes.clear();
    }
    decls
}

/// `[` minus `]` on a line.
fn bracket_balance(line: &str) -> i32 {
    line.chars().map(|c| i32::from(c == '[') - i32::from(c == ']')).sum()
}

/// The crate's own documentation: the `//!` lines of its root.
fn crate_doc(source: &str) -> String {
    source.lines().filter_map(|l| l.trim_start().strip_prefix("//!")).map(|l| format!("{l}\n")).collect::<String>()
}

/// Modules that must be named in the crate doc: all but the unit tests' own modules
/// (`#[cfg(test)] mod tests;`, inline `mod tests { ... }`).
fn documented_modules(source: &str) -> Vec<String> {
    module_decls(source).into_iter().filter(|m| !m.is_unit_tests()).map(|m| m.name).collect()
}

#[test]
fn every_lib_rs_doc_names_each_of_its_modules() {
    let members = members();
    let mut problems = Vec::new();
    let mut checked = 0;
    for member in &members {
        let Some(lib) = &member.lib else { continue };
        let source = std::fs::read_to_string(lib).unwrap_or_else(|e| panic!("cannot read {}: {e}", lib.display()));
        let doc = crate_doc(&source);
        let missing: Vec<String> =
            documented_modules(&source).into_iter().filter(|m| !doc.contains(&format!("`{m}`"))).collect();
        checked += 1;
        if !missing.is_empty() {
            problems.push(format!(
                "{} ({}): module(s) {} not named in the crate doc",
                member.name,
                lib.display(),
                missing.iter().map(|m| format!("`{m}`")).collect::<Vec<_>>().join(", ")
            ));
        }
    }
    assert!(checked >= 2, "no library target found: {members:?}");
    assert!(
        problems.is_empty(),
        "every crate's lib.rs `//!` doc lists its modules, each as `name` in backticks with a line on what it \
         owns:\n{}",
        problems.join("\n")
    );
}

#[test]
fn module_declarations_are_read_as_rustc_sees_them() {
    let source = "//! A crate with `a`.\n\
                  \n\
                  pub mod a;\n\
                  mod b;\n\
                  pub(crate) mod c;\n\
                  #[cfg(feature = \"report\")]\n\
                  pub mod d;\n\
                  #[cfg(any(\n    test,\n    feature = \"fixtures\"\n))]\n\
                  pub mod e;\n\
                  #[cfg(test)]\n\
                  mod fuzz;\n\
                  pub use a::Thing;\n\
                  fn module() {}\n\
                  \n\
                  #[cfg(test)]\n\
                  mod tests {\n    mod nested;\n    use super::*;\n}\n";
    assert_eq!(documented_modules(source), ["a", "b", "c", "d", "e"]);
    let decls = module_decls(source);
    assert!(decls.iter().any(|m| m.name == "fuzz" && m.test_only && !m.inline), "{decls:?}");
    assert!(decls.iter().any(|m| m.name == "tests" && m.test_only && m.inline), "{decls:?}");
    assert!(crate_doc(source).contains("`a`"));
}

#[test]
fn the_graph_block_is_found_among_other_fenced_blocks() {
    let doc =
        "# Title\n\n```text\nnot -> this\n```\n\n```text crate-graph\na -> (none)\n\nb -> a\n```\n\n```\nplain\n```\n";
    assert_eq!(graph_block(doc).unwrap(), ["a -> (none)", "b -> a"]);
    assert!(graph_block("```text\na -> b\n```\n").is_err(), "no graph block");
    assert!(graph_block("```text crate-graph\na -> b\n").is_err(), "an unclosed block");
    let two = "```text crate-graph\na -> (none)\n```\n```text crate-graph\na -> (none)\n```\n";
    assert!(graph_block(two).is_err(), "two graph blocks");
}
