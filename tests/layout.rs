//! The source layout `docs/architecture.md` promises, checked on the source itself:
//!
//! - the crate's top-level modules depend on each other one way (no cycle);
//! - within a module, files depend one way too, except that a `mod.rs` declares and
//!   re-exports its children (children may use their parent's types);
//! - in `src/plugin/`, no file imports from `plugin/mod.rs` either: it only declares the
//!   files, re-exports the public API and configures the schedule;
//! - no file in `src/plugin/` or `src/bin/` is over 900 lines, and no function in
//!   `src/plugin/` over 120.
//!
//! Paths are read from `use` trees and from `crate::`, `super::` and `self::` paths in code
//! (not comments); unit tests (`#[cfg(test)] mod tests`, `tests.rs`) may use anything.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 900;
const MAX_FN_LINES: usize = 120;

/// Every `.rs` file under `src/`, by its path relative to `src/`.
fn sources() -> BTreeMap<PathBuf, String> {
    fn walk(dir: &Path, root: &Path, out: &mut BTreeMap<PathBuf, String>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .expect("src/ is readable")
            .map(|e| e.expect("a directory entry").path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                walk(&path, root, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).expect("a readable source file");
                let rel = path.strip_prefix(root).expect("under src/").to_path_buf();
                out.insert(rel, text);
            }
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = BTreeMap::new();
    walk(&root, &root, &mut out);
    out
}

/// A file's module path (`plugin/select.rs` is `["plugin", "select"]`, `plugin/mod.rs` and
/// `lib.rs` their directory's); `None` for binaries.
fn module_of(rel: &Path) -> Option<Vec<String>> {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    if parts.first().is_some_and(|p| p == "bin") {
        return None;
    }
    if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
        parts.pop();
    }
    Some(parts)
}

/// The code of a file without comments and without its unit tests.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(at) => &text[..at],
        None => text,
    };
    text.lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The paths a file names: the leaves of its `use` trees (as written, segment by segment)
/// and the `crate::`/`super::`/`self::` paths elsewhere in its code.
fn named_paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(at) = find_use(rest) {
        let tail = &rest[at..];
        let end = tail.find(';').unwrap_or(tail.len());
        expand_use(tail[..end].trim(), &mut Vec::new(), &mut out);
        rest = &tail[end..];
    }
    let bytes = code.as_bytes();
    for start in ["crate::", "super::", "self::"] {
        for (at, _) in code.match_indices(start) {
            let boundary = at == 0
                || !(bytes[at - 1].is_ascii_alphanumeric()
                    || bytes[at - 1] == b'_'
                    || bytes[at - 1] == b':');
            if !boundary {
                continue;
            }
            let path: String = code[at..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            out.push(
                path.split("::")
                    .filter(|s| !s.is_empty())
                    .map(str::to_owned)
                    .collect(),
            );
        }
    }
    out
}

/// Where the next `use` item starts (after the keyword), if any.
fn find_use(code: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(at) = code[from..].find("use ") {
        let at = from + at;
        let before = code[..at].trim_end_matches([' ', '\t']);
        let starts_item = before.is_empty()
            || before.ends_with('\n')
            || before.ends_with(')')
            || before.ends_with("pub");
        if starts_item {
            return Some(at + 4);
        }
        from = at + 4;
    }
    None
}

/// The leaves of one `use` tree.
fn expand_use(tree: &str, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    let tree = tree.trim();
    if let Some(open) = tree.find('{') {
        let head: Vec<String> = tree[..open]
            .split("::")
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_owned)
            .collect();
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let depth = prefix.len();
        prefix.extend(head);
        let mut level = 0;
        let mut item = String::new();
        for c in inner.chars().chain(std::iter::once(',')) {
            match c {
                '{' => level += 1,
                '}' => level -= 1,
                _ => {}
            }
            if c == ',' && level == 0 {
                if !item.trim().is_empty() {
                    expand_use(&item, prefix, out);
                }
                item.clear();
            } else {
                item.push(c);
            }
        }
        prefix.truncate(depth);
        return;
    }
    let leaf = tree.split(" as ").next().unwrap_or(tree);
    let mut path = prefix.clone();
    path.extend(
        leaf.split("::")
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_owned),
    );
    out.push(path);
}

/// The file a path named in the file of module `here` resolves to: the longest prefix of
/// the absolute path that is a module of the crate.
fn resolve(
    path: &[String],
    here: &[String],
    modules: &BTreeMap<Vec<String>, PathBuf>,
) -> Option<PathBuf> {
    let mut absolute: Vec<String> = Vec::new();
    let mut rest = path;
    match path.first().map(String::as_str) {
        Some("crate") => rest = &path[1..],
        Some("self" | "super") => {
            absolute = here.to_vec();
            while let Some(first) = rest.first() {
                match first.as_str() {
                    "self" => {}
                    "super" => {
                        absolute.pop();
                    }
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        // A child module named directly (`pub use asset::MultiresMesh;` in a `mod.rs`, or
        // in a file with a folder of its own).
        Some(first) => {
            let mut child = here.to_vec();
            child.push(first.to_owned());
            if !modules.contains_key(&child) {
                return None;
            }
            absolute = here.to_vec();
        }
        None => return None,
    }
    absolute.extend(rest.iter().cloned());
    (1..=absolute.len())
        .rev()
        .find_map(|n| modules.get(&absolute[..n]).cloned())
}

/// The file-level import graph (`tests.rs` files left out): file -> files it names.
fn graph(sources: &BTreeMap<PathBuf, String>) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let modules: BTreeMap<Vec<String>, PathBuf> = sources
        .keys()
        .filter_map(|rel| module_of(rel).map(|m| (m, rel.clone())))
        .collect();
    let mut edges: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for (rel, text) in sources {
        let Some(here) = module_of(rel) else { continue };
        if rel.file_name().is_some_and(|n| n == "tests.rs") {
            continue;
        }
        let targets = edges.entry(rel.clone()).or_default();
        for path in named_paths(&code_of(text)) {
            if let Some(target) = resolve(&path, &here, &modules)
                && &target != rel
                && target != Path::new("lib.rs")
            {
                targets.insert(target);
            }
        }
    }
    edges
}

/// A cycle of `edges`, if there is one.
fn find_cycle(edges: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Option<Vec<PathBuf>> {
    fn visit(
        node: &PathBuf,
        edges: &BTreeMap<PathBuf, BTreeSet<PathBuf>>,
        state: &mut BTreeMap<PathBuf, u8>,
        stack: &mut Vec<PathBuf>,
    ) -> Option<Vec<PathBuf>> {
        state.insert(node.clone(), 1);
        stack.push(node.clone());
        for next in edges.get(node).into_iter().flatten() {
            match state.get(next).copied().unwrap_or(0) {
                0 => {
                    if let Some(cycle) = visit(next, edges, state, stack) {
                        return Some(cycle);
                    }
                }
                1 => {
                    let from = stack.iter().position(|n| n == next).unwrap_or(0);
                    return Some(stack[from..].to_vec());
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(node.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in edges.keys() {
        if state.get(node).copied().unwrap_or(0) == 0
            && let Some(cycle) = visit(node, edges, &mut state, &mut Vec::new())
        {
            return Some(cycle);
        }
    }
    None
}

#[test]
fn top_level_modules_depend_one_way() {
    let sources = sources();
    let mut top: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for (from, targets) in graph(&sources) {
        let Some(a) = module_of(&from).and_then(|m| m.first().cloned()) else {
            continue;
        };
        for target in targets {
            let Some(b) = module_of(&target).and_then(|m| m.first().cloned()) else {
                continue;
            };
            if a != b {
                top.entry(PathBuf::from(&a))
                    .or_default()
                    .insert(PathBuf::from(b));
            }
        }
    }
    assert!(
        find_cycle(&top).is_none(),
        "top-level modules in a cycle: {:?}",
        find_cycle(&top)
    );
}

#[test]
fn files_depend_one_way_but_for_re_exports() {
    let sources = sources();
    let mut edges = graph(&sources);
    // A `mod.rs` declares and re-exports its own children.
    for (from, targets) in &mut edges {
        if from.file_name().is_some_and(|n| n == "mod.rs") {
            let dir = from.parent().unwrap_or(Path::new("")).to_path_buf();
            targets.retain(|t| !t.starts_with(&dir));
        }
    }
    assert!(
        find_cycle(&edges).is_none(),
        "files in a cycle: {:?}",
        find_cycle(&edges)
    );
}

#[test]
fn plugin_files_never_import_from_the_plugin_root() {
    let sources = sources();
    let plugin = |p: &Path| p.starts_with("plugin");
    let mut edges = graph(&sources);
    edges.retain(|from, _| plugin(from));
    for targets in edges.values_mut() {
        targets.retain(|t| plugin(t));
    }
    assert!(
        find_cycle(&edges).is_none(),
        "plugin files in a cycle: {:?}",
        find_cycle(&edges)
    );
}

#[test]
fn plugin_and_cli_files_and_functions_stay_short() {
    let mut long = Vec::new();
    for (rel, text) in sources() {
        if !(rel.starts_with("plugin") || rel.starts_with("bin")) {
            continue;
        }
        let lines: Vec<&str> = text.lines().collect();
        if lines.len() > MAX_FILE_LINES {
            long.push(format!("{}: {} lines", rel.display(), lines.len()));
        }
        if !rel.starts_with("plugin") {
            continue;
        }
        for (name, length) in function_lengths(&lines) {
            if length > MAX_FN_LINES {
                long.push(format!("{}: fn {name} is {length} lines", rel.display()));
            }
        }
    }
    assert!(
        long.is_empty(),
        "over the limits ({MAX_FILE_LINES} lines a file, {MAX_FN_LINES} a function): {long:#?}"
    );
}

/// Every function with a body and its length in lines, from its `fn` line to the closing
/// brace at the same indentation (the code is `rustfmt`ed).
fn function_lengths(lines: &[&str]) -> Vec<(String, usize)> {
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let Some(at) = trimmed.find("fn ") else {
            continue;
        };
        let head = &trimmed[..at];
        let is_fn = head
            .split_whitespace()
            .all(|w| w.starts_with("pub") || ["const", "async", "unsafe", "extern"].contains(&w));
        if !is_fn || trimmed.starts_with("//") || trimmed.trim_end().ends_with('}') {
            continue; // not a function, or one on a single line
        }
        let name: String = trimmed[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let indent = &line[..line.len() - trimmed.len()];
        // The signature ends at the first line ending in `{` (a body) or `;` (none).
        let Some(open) = (i..lines.len()).find(|&j| {
            let l = lines[j].trim_end();
            l.ends_with('{') || l.ends_with(';')
        }) else {
            continue;
        };
        if lines[open].trim_end().ends_with(';') {
            continue;
        }
        let close = (open..lines.len())
            .find(|&j| lines[j].starts_with(indent) && lines[j][indent.len()..].starts_with('}'));
        if let Some(close) = close {
            out.push((name, close - i + 1));
        }
    }
    out
}
