#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The crates that build their integration tests into one binary (`autotests = false` and
//! a `[[test]]` at `tests/main.rs`: one build and one link instead of one per file) declare
//! every file of their `tests/` as a module of `tests/main.rs`: a file left out would be
//! compiled by nobody and its tests would never run.

use std::path::{Path, PathBuf};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The workspace's members (the root manifest's `workspace.members`).
fn members() -> Vec<PathBuf> {
    let text = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let manifest: toml::Table = text.parse().unwrap();
    manifest["workspace"]["members"]
        .as_array()
        .expect("workspace.members is an array")
        .iter()
        .map(|m| root().join(m.as_str().expect("a member is a path")))
        .collect()
}

/// The `tests/` files of `dir` that `main` (the text of its `tests/main.rs`) does not
/// declare as modules: a line `mod NAME;` (or `pub mod NAME;`), or `#[path = "NAME.rs"]`
/// on the line before a `mod`; a commented-out line declares nothing.
fn undeclared(dir: &Path, main: &str) -> Vec<String> {
    let lines: Vec<&str> = main.lines().map(str::trim).collect();
    let declared = |stem: &str| {
        lines.iter().enumerate().any(|(i, l)| {
            let l = l.strip_prefix("pub ").unwrap_or(l);
            *l == format!("mod {stem};")
                || (*l == format!("#[path = \"{stem}.rs\"]")
                    && lines
                        .get(i + 1)
                        .is_some_and(|n| n.strip_prefix("pub ").unwrap_or(n).starts_with("mod ")))
        })
    };
    let mut missing = Vec::new();
    let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some(stem) = name.strip_suffix(".rs").filter(|s| *s != "main") {
            if !declared(stem) {
                missing.push(name);
            }
        }
    }
    missing.sort();
    missing
}

/// Property: in every member with `autotests = false`, the one test binary is
/// `tests/main.rs` and every other `tests/*.rs` is one of its modules.
#[test]
fn every_test_file_is_a_module_of_its_crates_test_binary() {
    let mut single = 0;
    for member in members() {
        let text = std::fs::read_to_string(member.join("Cargo.toml")).unwrap();
        let manifest: toml::Table = text.parse().unwrap();
        let autotests = manifest["package"]
            .get("autotests")
            .and_then(|v| v.as_bool())
            .unwrap_or(true);
        if autotests {
            continue;
        }
        single += 1;
        let tests = manifest
            .get("test")
            .and_then(|t| t.as_array())
            .map(|t| t.as_slice())
            .unwrap_or_default();
        assert!(
            tests
                .iter()
                .any(|t| t.get("path").and_then(|p| p.as_str()) == Some("tests/main.rs")),
            "{}: autotests = false without a [[test]] at tests/main.rs",
            member.display()
        );
        let main = std::fs::read_to_string(member.join("tests/main.rs")).unwrap();
        let missing = undeclared(&member.join("tests"), &main);
        assert!(
            missing.is_empty(),
            "{}: tests/{} not modules of tests/main.rs: their tests would never run",
            member.display(),
            missing.join(", tests/")
        );
    }
    // The seven crates of the layout (README): a check that found none checked nothing.
    assert!(single >= 7, "only {single} crates with one test binary");
}

/// The check finds a file left out (a `tests/` of its own).
#[test]
fn a_test_file_left_out_is_found() {
    let dir = std::env::temp_dir().join(format!("test-binaries-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for f in [
        "main.rs",
        "kept.rs",
        "forgotten.rs",
        "by_path.rs",
        "commented.rs",
    ] {
        std::fs::write(dir.join(f), "").unwrap();
    }
    let main = "mod kept;\n#[path = \"by_path.rs\"]\nmod renamed;\n// mod commented;\n";
    let missing = undeclared(&dir, main);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(missing, ["commented.rs", "forgotten.rs"]);
}
