#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The crate's modules build on each other without cycles: when a file uses a name from
//! another module (a `use` or a path `crate::…`, `super::…`, `self::…` in its code), that
//! module does not use a name from the first, directly or around a longer circle. Each
//! module can then be read knowing only the modules below it. The edges go to the module
//! a path names (a `mod.rs` that re-exports its children counts as using them, so the
//! children must not use its re-exports), and test modules count too.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::Path;

type Module = Vec<String>;

/// Every `.rs` file under `dir`, by the module it defines (`lib.rs` the root, `a/mod.rs`
/// and `a.rs` the module `a`).
fn sources(dir: &Path, prefix: &[String], out: &mut BTreeMap<Module, String>) {
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if path.is_dir() {
            let mut p = prefix.to_vec();
            p.push(name);
            sources(&path, &p, out);
        } else if let Some(stem) = name.strip_suffix(".rs") {
            let mut module = prefix.to_vec();
            if stem != "lib" && stem != "mod" {
                module.push(stem.to_string());
            }
            out.insert(module, fs::read_to_string(&path).unwrap());
        }
    }
}

/// The code without comments and string literals.
fn code_of(text: &str) -> String {
    let (b, mut out, mut i) = (text.as_bytes(), String::new(), 0);
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else {
            let c = text[i..].chars().next().unwrap();
            out.push(c);
            i += c.len_utf8();
        }
    }
    out
}

/// Inside inline modules (`mod tests { … }`), `super` is the file's own module: rewritten
/// to `self`.
fn inline_modules_resolved(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(at) = find_inline_mod(rest) {
        let (head, body) = rest.split_at(at);
        out.push_str(head);
        let mut depth = 0;
        let mut end = body.len();
        for (k, c) in body.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = k + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        out.push_str(&body[..end].replace("super::", "self::"));
        rest = &body[end..];
    }
    out.push_str(rest);
    out
}

/// Where the next `mod name {` starts.
fn find_inline_mod(code: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(k) = code[from..].find("mod ") {
        let at = from + k;
        let before = code[..at].chars().next_back();
        let after = code[at + 4..].trim_start();
        let name_len = after
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(after.len());
        let word_start = before.is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
        if word_start && name_len > 0 && after[name_len..].trim_start().starts_with('{') {
            return Some(at);
        }
        from = at + 4;
    }
    None
}

/// A `use` tree without its renames (`a as b` → `a`).
fn without_renames(tree: &str) -> String {
    let mut out = String::new();
    let mut words = tree.split_whitespace();
    while let Some(w) = words.next() {
        if w == "as" {
            // The new name, up to the punctuation after it.
            let renamed = words.next().unwrap_or("");
            out.push_str(renamed.trim_start_matches(|c: char| c.is_alphanumeric() || c == '_'));
        } else {
            out.push_str(w);
        }
    }
    out
}

/// A `use` tree expanded into its paths (`a::{b, c::{d, e}}` → `a::b`, `a::c::d`, …).
fn expand(tree: &str) -> Vec<String> {
    let tree = without_renames(tree);
    let Some(open) = tree.find('{') else {
        return vec![tree];
    };
    let (prefix, inner) = (&tree[..open], &tree[open + 1..tree.len() - 1]);
    let mut parts = vec![];
    let (mut depth, mut start) = (0, 0);
    for (k, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(expand)
        .map(|p| match p.as_str() {
            "self" => prefix.trim_end_matches("::").to_string(),
            _ => format!("{prefix}{p}"),
        })
        .collect()
}

/// The paths a file's code names: its `use` trees and the `crate::`, `super::` and
/// `self::` paths in its code.
fn paths_of(code: &str) -> Vec<String> {
    let mut paths = vec![];
    let mut rest = String::new();
    let mut text = code;
    while let Some(k) = text.find("use ") {
        let word_start = text[..k]
            .chars()
            .next_back()
            .is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
        rest.push_str(&text[..k]);
        let end = text[k..].find(';').map_or(text.len(), |e| k + e);
        if word_start {
            paths.extend(expand(&text[k + 4..end]));
            text = &text[end..];
        } else {
            rest.push_str("use ");
            text = &text[k + 4..];
        }
    }
    rest.push_str(text);
    let b = rest.as_bytes();
    for root in ["crate::", "super::", "self::"] {
        let mut from = 0;
        while let Some(k) = rest[from..].find(root) {
            let at = from + k;
            let before = if at > 0 { b[at - 1] } else { b' ' };
            from = at + root.len();
            if before.is_ascii_alphanumeric() || before == b'_' || before == b':' {
                continue;
            }
            let len = rest[at..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(rest.len() - at);
            paths.push(rest[at..at + len].trim_end_matches(':').to_string());
        }
    }
    paths
}

/// The module a path used in `module` names: its longest prefix that is a module of the
/// crate (None for other crates).
fn target(module: &Module, path: &str, modules: &BTreeMap<Module, String>) -> Option<Module> {
    let segs: Vec<&str> = path.split("::").collect();
    let mut abs: Module = match segs.first()? {
        &"crate" => vec![],
        &"self" => module.clone(),
        &"super" => module.clone(),
        first => {
            let mut child = module.clone();
            child.push((*first).to_string());
            if !modules.contains_key(&child) {
                return None;
            }
            module.clone()
        }
    };
    let mut rest = &segs[..];
    if matches!(segs[0], "crate" | "self") {
        rest = &segs[1..];
    }
    while rest.first() == Some(&"super") {
        abs.pop();
        rest = &rest[1..];
    }
    abs.extend(rest.iter().map(|s| s.to_string()));
    while !modules.contains_key(&abs) {
        abs.pop()?;
    }
    Some(abs)
}

type Edges = BTreeMap<Module, BTreeMap<Module, String>>;

/// The crate's import graph: for each module, the modules it uses, with a path naming
/// each.
fn import_graph(modules: &BTreeMap<Module, String>) -> Edges {
    let mut edges = Edges::new();
    for (module, text) in modules {
        let code = inline_modules_resolved(&code_of(text));
        for path in paths_of(&code) {
            if let Some(t) = target(module, &path, modules) {
                if &t != module {
                    let uses = edges.entry(module.clone()).or_default();
                    uses.entry(t).or_insert(path);
                }
            }
        }
    }
    edges
}

/// A cycle of the graph (its modules, the first repeated at the end), found by a
/// depth-first search as an edge back to a module on the search's path.
fn find_cycle(edges: &Edges) -> Option<Vec<Module>> {
    let next = |m: &Module| -> Vec<Module> {
        edges
            .get(m)
            .map(|e| e.keys().cloned().collect())
            .unwrap_or_default()
    };
    let mut done = BTreeSet::new();
    for start in edges.keys() {
        if done.contains(start) {
            continue;
        }
        let mut path = vec![start.clone()];
        let mut pending = vec![next(start)];
        while let Some(todo) = pending.last_mut() {
            let Some(n) = todo.pop() else {
                done.extend(path.pop());
                pending.pop();
                continue;
            };
            if let Some(at) = path.iter().position(|m| *m == n) {
                let mut circle = path[at..].to_vec();
                circle.push(n);
                return Some(circle);
            }
            if !done.contains(&n) {
                pending.push(next(&n));
                path.push(n);
            }
        }
    }
    None
}

#[test]
fn no_module_uses_one_that_uses_it_back() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut modules = BTreeMap::new();
    sources(&src, &[], &mut modules);
    let edges = import_graph(&modules);
    // The parser sees the imports: most modules use others.
    assert!(edges.len() > 20, "modules with imports: {}", edges.len());
    if let Some(circle) = find_cycle(&edges) {
        let name = |m: &Module| {
            if m.is_empty() {
                "lib".to_string()
            } else {
                m.join("::")
            }
        };
        let steps: Vec<String> = circle
            .windows(2)
            .map(|w| format!("{} uses {}", name(&w[0]), edges[&w[0]][&w[1]]))
            .collect();
        panic!("an import cycle: {}", steps.join(", "));
    }
}

#[test]
fn a_cycle_is_found_around_any_circle() {
    let m = |s: &str| vec![s.to_string()];
    let mut edges = Edges::new();
    for (a, b) in [("a", "b"), ("b", "c"), ("a", "c"), ("d", "a")] {
        edges.entry(m(a)).or_default().insert(m(b), String::new());
    }
    assert_eq!(find_cycle(&edges), None);
    edges
        .entry(m("c"))
        .or_default()
        .insert(m("d"), String::new());
    let circle = find_cycle(&edges).unwrap();
    assert_eq!(circle.first(), circle.last());
    assert!(circle.len() >= 4, "{circle:?}");
}

#[test]
fn the_parser_sees_use_trees_paths_and_test_modules() {
    let code = code_of(
        "use crate::a::{b, c::{d as e, self}}; // use crate::z;\n\
         fn f() { let s = \"crate::y\"; super::g::h(); }\n\
         mod tests { use super::*; }",
    );
    let code = inline_modules_resolved(&code);
    let paths = paths_of(&code);
    assert!(paths.contains(&"crate::a::b".to_string()), "{paths:?}");
    assert!(paths.contains(&"crate::a::c::d".to_string()), "{paths:?}");
    assert!(paths.contains(&"crate::a::c".to_string()), "{paths:?}");
    assert!(paths.contains(&"super::g::h".to_string()), "{paths:?}");
    assert!(paths.contains(&"self::*".to_string()), "{paths:?}");
    assert!(
        !paths.iter().any(|p| p.contains('z') || p.contains('y')),
        "{paths:?}"
    );
    let mut modules = BTreeMap::new();
    for m in [
        vec![],
        vec!["a".to_string()],
        vec!["a".to_string(), "c".to_string()],
    ] {
        modules.insert(m, String::new());
    }
    let a = vec!["a".to_string()];
    assert_eq!(
        target(&a, "crate::a::c::d", &modules),
        Some(vec!["a".into(), "c".into()])
    );
    assert_eq!(target(&a, "super::x", &modules), Some(vec![]));
    assert_eq!(
        target(&a, "c::d", &modules),
        Some(vec!["a".into(), "c".into()])
    );
    assert_eq!(target(&a, "nalgebra::Vector3", &modules), None);
}
