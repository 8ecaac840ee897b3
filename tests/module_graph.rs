//! No import circles: no module of `src/` imports one that imports it back,
//! directly or around a loop (ARCHITECTURE.md's rule, pinned).
//!
//! Reads every `use` of `crate::…`, `super::…` and `self::…` (and paths
//! written out in code) outside the files' test modules, follows `pub use`
//! re-exports to the module that defines an item, and looks for a cycle.
//! A module importing from its own ancestors (a folder's `mod.rs`) or
//! declaring and re-exporting its children is structure, not an edge.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

type Module = Vec<String>;

/// Every `.rs` file under `dir` with its module path (`crate` first).
fn modules(dir: &Path, prefix: &[String], out: &mut BTreeMap<Module, String>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if path.is_dir() {
            let mut next = prefix.to_vec();
            next.push(name);
            modules(&path, &next, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let mut module = prefix.to_vec();
            if !matches!(name.as_str(), "mod" | "lib" | "main") {
                module.push(name);
            }
            out.insert(module, code_of(&std::fs::read_to_string(&path).unwrap()));
        }
    }
}

/// The file's code without comments and without its `#[cfg(test)]`
/// test module (by convention the file's end).
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(end) => &text[..end],
        None => text,
    };
    text.lines()
        .map(|line| line.split_once("//").map_or(line, |(code, _)| code))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The full paths a `use` tree names (`a::{b, c::{d, self}}` → `a::b`,
/// `a::c::d`, `a::c`); renames and globs are dropped to their path.
fn expand(tree: &str, prefix: &str, out: &mut Vec<String>) {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        let path = tree
            .split(" as ")
            .next()
            .unwrap()
            .trim()
            .trim_end_matches("::*");
        let path = path.trim_end_matches("::self");
        if path == "self" {
            out.push(prefix.trim_end_matches("::").to_string());
        } else if !path.is_empty() {
            out.push(format!("{prefix}{path}"));
        }
        return;
    };
    let head = format!("{prefix}{}", &tree[..open]);
    let inner = &tree[open + 1..tree.rfind('}').unwrap()];
    let (mut depth, mut start) = (0, 0);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                expand(&inner[start..i], &head, out);
                start = i + 1;
            }
            _ => {}
        }
    }
    expand(&inner[start..], &head, out);
}

/// `(path, re-exported)` of every `use` in `code`: the last `use ` of
/// each statement that starts a word, `pub` or `pub(crate)` before it.
fn uses(code: &str) -> Vec<(String, bool)> {
    let mut found = Vec::new();
    for statement in code.split(';') {
        let at = statement.rmatch_indices("use ").map(|(i, _)| i).find(|&i| {
            statement[..i]
                .chars()
                .next_back()
                .is_none_or(char::is_whitespace)
        });
        let Some(at) = at else {
            continue;
        };
        let before = statement[..at].trim_end();
        let public = before.ends_with("pub") || before.ends_with("pub(crate)");
        let mut paths = Vec::new();
        expand(&statement[at + 4..], "", &mut paths);
        found.extend(paths.into_iter().map(|p| (p, public)));
    }
    found
}

/// `path` as seen from `module`, made absolute (`crate::…`), or None for
/// another crate's.
fn absolute(path: &str, module: &Module, all: &BTreeMap<Module, String>) -> Option<Module> {
    let mut parts: Vec<String> = path.split("::").map(|s| s.trim().to_string()).collect();
    let mut base = module.clone();
    match parts[0].as_str() {
        "crate" => return Some(parts),
        "self" => {
            parts.remove(0);
        }
        "super" => {
            while parts.first().is_some_and(|p| p == "super") {
                parts.remove(0);
                base.pop();
            }
        }
        first => {
            let mut child = module.clone();
            child.push(first.to_string());
            if !all.contains_key(&child) {
                return None;
            }
        }
    }
    base.extend(parts);
    Some(base)
}

/// The module that defines what `path` names, through re-exports.
fn defining_module(
    path: &Module,
    all: &BTreeMap<Module, String>,
    reexports: &BTreeMap<Module, Module>,
    depth: usize,
) -> Module {
    for k in (1..=path.len()).rev() {
        let prefix = path[..k].to_vec();
        if all.contains_key(&prefix) {
            return prefix;
        }
        if depth < 8 {
            if let Some(target) = reexports.get(&prefix) {
                let mut rest = target.clone();
                rest.extend_from_slice(&path[k..]);
                return defining_module(&rest, all, reexports, depth + 1);
            }
        }
    }
    vec!["crate".to_string()]
}

#[test]
fn no_module_imports_one_that_imports_it_back() {
    let mut all = BTreeMap::new();
    modules(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
        &["crate".to_string()],
        &mut all,
    );
    assert!(
        all.len() > 50,
        "the sources were found: {} files",
        all.len()
    );
    let mut reexports = BTreeMap::new();
    let mut imports: BTreeMap<Module, Vec<Module>> = BTreeMap::new();
    for (module, code) in &all {
        let mut paths: Vec<(String, bool)> = uses(code);
        // Paths written out in code: `crate::a::b::f(…)`.
        for (i, _) in code.match_indices("crate::") {
            let before = code[..i].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let path: String = code[i..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            paths.push((path.trim_end_matches(':').to_string(), false));
        }
        for (path, public) in paths {
            let Some(target) = absolute(&path, module, &all) else {
                continue;
            };
            if public {
                let name = target.last().unwrap().clone();
                let mut alias = module.clone();
                alias.push(name);
                if alias != target {
                    reexports.insert(alias, target.clone());
                }
            }
            imports.entry(module.clone()).or_default().push(target);
        }
    }
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, targets) in &imports {
        for target in targets {
            let to = defining_module(target, &all, &reexports, 0);
            let related = to.starts_with(module) || module.starts_with(&to);
            if !related {
                edges.entry(module.clone()).or_default().insert(to);
            }
        }
    }
    // A path back from each edge's end to its start is a circle.
    let name = |m: &Module| m.join("::");
    let mut circles = Vec::new();
    for (from, targets) in &edges {
        for to in targets {
            let mut seen = BTreeSet::new();
            let mut stack = vec![vec![to.clone()]];
            while let Some(route) = stack.pop() {
                let last = route.last().unwrap();
                if last == from {
                    let mut names: Vec<String> = vec![name(from)];
                    names.extend(route.iter().map(name));
                    circles.push(names.join(" → "));
                    break;
                }
                for next in edges.get(last).into_iter().flatten() {
                    if seen.insert(next.clone()) {
                        let mut longer = route.clone();
                        longer.push(next.clone());
                        stack.push(longer);
                    }
                }
            }
        }
    }
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
    let edge_count: usize = edges.values().map(BTreeSet::len).sum();
    assert!(
        edge_count > 100,
        "the imports were read: {edge_count} edges"
    );
}
