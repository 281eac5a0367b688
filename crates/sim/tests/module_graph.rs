//! The crate's modules form no cycle at any level of its folders: in every folder (the crate root
//! included), the files and subfolders it holds depend on one another without a cycle. A
//! subfolder counts as one node (all its files together), so the top-level folders form a
//! layered graph, and so do the files inside each folder; a folder's `mod.rs` (the root's
//! `lib.rs`) is a node beside its files, so a file that reaches a sibling through the folder's
//! re-exports depends on the `mod.rs` that re-exports it.
//!
//! A file depends on a module when its code (outside comments and its tests) names it by path:
//! `crate::a::b`, `super::b`, `self::b` (groups `crate::{a, b::c}` included), or a child module
//! in a `use` of a `mod.rs`. A cycle is what let records, packing and the runner reach into each
//! other before the crate was cut into one concept per module.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Source files by path relative to `src/` (`physics/world.rs`), with their text.
type Files = BTreeMap<String, String>;

/// A module path: `["physics", "world"]`; the crate root is empty.
type Module = Vec<String>;

/// The module a file defines: `a/b.rs` → `[a, b]`, `a/mod.rs` → `[a]`, `lib.rs` → `[]`.
fn module_of(path: &str) -> Module {
    let mut parts: Vec<String> = path
        .trim_end_matches(".rs")
        .split('/')
        .map(str::to_string)
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// Every module the files define, folders included.
fn modules(files: &Files) -> BTreeSet<Module> {
    let mut out = BTreeSet::new();
    for path in files.keys() {
        let module = module_of(path);
        for n in 0..=module.len() {
            out.insert(module[..n].to_vec());
        }
    }
    out
}

/// The paths of a use tree starting at `text` (`a::b::{c, d::e}`, `a::b`), each as segments.
fn use_tree(text: &str) -> (Vec<Vec<String>>, usize) {
    let bytes = text.as_bytes();
    let mut i = 0;
    let mut prefix = Vec::new();
    loop {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if i < bytes.len() && bytes[i] == b'{' {
            let mut paths = Vec::new();
            i += 1;
            loop {
                while i < bytes.len() && (bytes[i].is_ascii_whitespace() || bytes[i] == b',') {
                    i += 1;
                }
                if i >= bytes.len() || bytes[i] == b'}' {
                    break;
                }
                let (inner, used) = use_tree(&text[i..]);
                if used == 0 {
                    break;
                }
                i += used;
                paths.extend(inner.into_iter().map(|p| [prefix.clone(), p].concat()));
            }
            return (paths, i + 1);
        }
        let start = i;
        while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
            i += 1;
        }
        if i == start {
            return (vec![prefix], i);
        }
        prefix.push(text[start..i].to_string());
        if text[i..].starts_with("::") {
            i += 2;
        } else {
            return (vec![prefix], i);
        }
    }
}

/// The modules the code of the file at `path` names.
fn references(path: &str, text: &str, modules: &BTreeSet<Module>) -> BTreeSet<Module> {
    let own = module_of(path);
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let code: String = code
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut paths = Vec::new();
    for (at, _) in code.match_indices(|c: char| c.is_ascii_lowercase()) {
        let before = code[..at].chars().next_back();
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
            continue;
        }
        let rest = &code[at..];
        if ["crate::", "super::", "self::"]
            .iter()
            .any(|p| rest.starts_with(p))
        {
            paths.extend(use_tree(rest).0);
        } else if let Some(tree) = rest.strip_prefix("use ") {
            // `use child::…` in a module with children: relative to it.
            paths.extend(
                use_tree(tree)
                    .0
                    .into_iter()
                    .filter(|p| {
                        p.first().is_some_and(|f| {
                            modules.contains(&[own.clone(), vec![f.clone()]].concat())
                        })
                    })
                    .map(|p| [vec!["self".to_string()], p].concat()),
            );
        }
    }
    let mut out = BTreeSet::new();
    for path in paths {
        let mut base = own.clone();
        let mut segments = path.iter().peekable();
        match segments.peek().map(|s| s.as_str()) {
            Some("crate") => base.clear(),
            Some("self") => {}
            Some("super") => {}
            _ => continue,
        }
        if path[0] != "super" {
            segments.next();
        }
        while segments.peek().is_some_and(|s| *s == "super") {
            segments.next();
            base.pop();
        }
        for s in segments {
            let deeper = [base.clone(), vec![s.clone()]].concat();
            if !modules.contains(&deeper) {
                break;
            }
            base = deeper;
        }
        if base != own {
            out.insert(base);
        }
    }
    out
}

/// Per folder (`""` for the crate root, else `a/b`): its nodes (`x.rs`, `sub/`, `mod.rs` or
/// `lib.rs`) and which depends on which.
fn folder_graphs(files: &Files) -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let modules = modules(files);
    let is_folder = |m: &Module| {
        files
            .keys()
            .any(|p| p.starts_with(&format!("{}/", m.join("/"))))
    };
    // The node of module `m` in folder `d`, when `m` is `d` itself or inside it.
    let node = |d: &Module, m: &Module| -> Option<String> {
        if m.len() < d.len() || m[..d.len()] != d[..] {
            return None;
        }
        if m.len() == d.len() {
            return Some(if d.is_empty() { "lib.rs" } else { "mod.rs" }.to_string());
        }
        let child = m[..=d.len()].to_vec();
        let name = &child[d.len()];
        Some(match is_folder(&child) {
            true => format!("{name}/"),
            false => format!("{name}.rs"),
        })
    };
    let mut out: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for folder in modules.iter().filter(|m| m.is_empty() || is_folder(m)) {
        let graph = out.entry(folder.join("/")).or_default();
        for (path, text) in files {
            let own = module_of(path);
            // A folder's own mod.rs is its `mod.rs` node; a file `d/x.rs` is `x.rs`, even when a
            // folder `d/x/` beside it holds x's children.
            let from = if path.ends_with("mod.rs") || path == "lib.rs" {
                node(folder, &own)
            } else if own.len() == folder.len() + 1 && own[..folder.len()] == folder[..] {
                Some(format!("{}.rs", own[folder.len()]))
            } else {
                node(folder, &own)
            };
            let Some(from) = from else { continue };
            let deps = graph.entry(from.clone()).or_default();
            for r in references(path, text, &modules) {
                if let Some(to) = node(folder, &r).filter(|to| *to != from) {
                    deps.insert(to);
                }
            }
        }
    }
    out
}

/// A cycle through `start`, if there is one.
fn cycle_from(graph: &BTreeMap<String, BTreeSet<String>>, start: &str) -> Option<Vec<String>> {
    let mut stack = vec![vec![start.to_string()]];
    let mut seen = BTreeSet::new();
    while let Some(path) = stack.pop() {
        let last = path.last().unwrap();
        for next in graph.get(last).into_iter().flatten() {
            if next == start {
                let mut cycle = path.clone();
                cycle.push(next.clone());
                return Some(cycle);
            }
            if seen.insert(next.clone()) {
                let mut longer = path.clone();
                longer.push(next.clone());
                stack.push(longer);
            }
        }
    }
    None
}

/// Every folder's first cycle, as `folder: a → b → a`.
fn cycles(files: &Files) -> Vec<String> {
    let mut out = Vec::new();
    for (folder, graph) in folder_graphs(files) {
        if let Some(cycle) = graph.keys().find_map(|n| cycle_from(&graph, n)) {
            out.push(format!("{}/: {}", folder, cycle.join(" → ")));
        }
    }
    out
}

/// The crate's source files.
fn crate_files() -> Files {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Files::new();
    let mut stack = vec![src.clone()];
    while let Some(path) = stack.pop() {
        if path.is_dir() {
            stack.extend(std::fs::read_dir(&path).unwrap().map(|e| e.unwrap().path()));
        } else if path.extension().is_some_and(|e| e == "rs") {
            let relative = path
                .strip_prefix(&src)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            files.insert(relative, std::fs::read_to_string(&path).unwrap());
        }
    }
    files
}

#[test]
fn modules_form_no_cycle() {
    let files = crate_files();
    let graphs = folder_graphs(&files);
    let root = &graphs[""];
    assert!(root.len() > 5, "read only {} top-level nodes", root.len());
    assert!(
        root["run/"].contains("tasks/") && graphs["run"]["runner.rs"].contains("results.rs"),
        "the reader misses `use crate::…`"
    );
    let cycles = cycles(&files);
    assert!(cycles.is_empty(), "module cycles:\n{}", cycles.join("\n"));
}

fn planted(files: &[(&str, &str)]) -> Files {
    files
        .iter()
        .map(|(p, t)| (p.to_string(), t.to_string()))
        .collect()
}

#[test]
fn a_cycle_between_two_files_of_a_folder_is_found() {
    let files = planted(&[
        ("lib.rs", "pub mod a;"),
        ("a/mod.rs", "pub mod x;\npub mod y;"),
        ("a/x.rs", "use super::y::Y;\npub struct X;"),
        ("a/y.rs", "pub fn f() -> crate::a::x::X { todo!() }"),
    ]);
    assert_eq!(cycles(&files), ["a/: x.rs → y.rs → x.rs"]);
}

#[test]
fn a_cycle_between_folders_is_found() {
    let files = planted(&[
        ("lib.rs", "pub mod p;\npub mod r;"),
        ("p/mod.rs", "pub mod q;"),
        ("p/q.rs", "use crate::{r::s::S, p};"),
        ("r/mod.rs", "pub mod s;"),
        ("r/s.rs", "pub struct S;\npub fn f() { crate::p::q::g() }"),
    ]);
    assert_eq!(cycles(&files), ["/: p/ → r/ → p/"]);
}

#[test]
fn a_file_reaching_a_sibling_through_the_folders_re_exports_is_a_cycle() {
    let files = planted(&[
        ("lib.rs", "pub mod a;"),
        ("a/mod.rs", "mod x;\nmod y;\npub use x::X;\npub use y::Y;"),
        ("a/x.rs", "pub struct X;"),
        ("a/y.rs", "use crate::a::X;\npub struct Y;"),
    ]);
    assert_eq!(cycles(&files), ["a/: mod.rs → y.rs → mod.rs"]);
}

#[test]
fn comments_tests_and_layers_are_no_cycle() {
    let files = planted(&[
        ("lib.rs", "pub mod a;\npub mod b;\npub use a::x::X;"),
        ("a/mod.rs", "pub mod x;\npub mod y;"),
        (
            "a/x.rs",
            "//! See [`crate::a::y`].\npub struct X;\n#[cfg(test)]\nmod tests { use crate::a::y::Y; }",
        ),
        ("a/y.rs", "use super::x::X;\npub struct Y(X);"),
        ("b/mod.rs", "use crate::a::{x::X, y::Y};"),
    ]);
    assert_eq!(cycles(&files), Vec::<String>::new());
    let graphs = folder_graphs(&files);
    assert_eq!(graphs[""]["b/"], BTreeSet::from(["a/".to_string()]));
    assert_eq!(graphs["a"]["y.rs"], BTreeSet::from(["x.rs".to_string()]));
    assert_eq!(graphs[""]["lib.rs"], BTreeSet::from(["a/".to_string()]));
}
