#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The layers point one way (README, "Layout"): core; the firmware's libraries; `sim/`, the
//! simulated robot; the host's libraries; the front ends and the command line. Read from
//! every `Cargo.toml` under `firmware/` and `sim/`:
//!
//! * no crate there depends on a crate under `host-sim/`: not by a path dependency of any
//!   kind (normal, dev, build, target-specific), not through a workspace dependency, and
//!   no workspace there takes a member from `host-sim/`;
//! * no crate under `sim/` depends on a crate that has a `sim/` crate among its own
//!   dependencies of any kind (the control application's tests run on `sim/`, so `sim/`
//!   cannot run on the control application).

use std::collections::BTreeSet;
use std::path::{Component, Path, PathBuf};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// `path` with `.` and `..` folded away (the files need not exist).
fn normal(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            c => out.push(c),
        }
    }
    out
}

/// Every `Cargo.toml` under `dir`, build outputs left out.
fn manifests(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = entries.filter_map(|e| Some(e.ok()?.path())).collect();
    entries.sort();
    for p in entries {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if p.is_dir() {
            if name != "target" && !name.starts_with('.') {
                manifests(&p, out);
            }
        } else if name == "Cargo.toml" {
            out.push(p);
        }
    }
}

fn read(manifest: &Path) -> toml::Table {
    let text = std::fs::read_to_string(manifest).unwrap();
    text.parse()
        .unwrap_or_else(|e| panic!("{}: {e}", manifest.display()))
}

/// The manifest of the workspace `manifest` belongs to: its `package.workspace`, else the
/// nearest `Cargo.toml` with a `[workspace]` table at or above it.
fn workspace_of(manifest: &Path, table: &toml::Table) -> Option<PathBuf> {
    let dir = manifest.parent()?;
    if let Some(ws) = table
        .get("package")
        .and_then(|p| p.get("workspace"))
        .and_then(|w| w.as_str())
    {
        return Some(normal(&dir.join(ws).join("Cargo.toml")));
    }
    let mut at = Some(dir);
    while let Some(d) = at {
        let m = d.join("Cargo.toml");
        if m.exists() && read(&m).contains_key("workspace") {
            return Some(m);
        }
        at = d.parent();
    }
    None
}

/// A path dependency: the manifest and table that declare it, its name, the directory
/// it resolves to.
#[derive(Debug)]
struct PathDep {
    from: PathBuf,
    table: String,
    name: String,
    to: PathBuf,
}

/// The path dependencies a table of dependencies declares, `workspace = true` resolved
/// through the workspace's `[workspace.dependencies]`.
fn path_deps_of(
    manifest: &Path,
    table_name: &str,
    deps: &toml::Table,
    workspace: Option<&Path>,
    out: &mut Vec<PathDep>,
) {
    let dir = manifest.parent().unwrap();
    for (name, spec) in deps {
        let to = if let Some(path) = spec.get("path").and_then(|p| p.as_str()) {
            Some(normal(&dir.join(path)))
        } else if spec.get("workspace").and_then(|w| w.as_bool()) == Some(true) {
            workspace.and_then(|ws| {
                let t = read(ws);
                let path = t
                    .get("workspace")?
                    .get("dependencies")?
                    .get(name)?
                    .get("path")?
                    .as_str()?
                    .to_string();
                Some(normal(&ws.parent()?.join(path)))
            })
        } else {
            None
        };
        if let Some(to) = to {
            out.push(PathDep {
                from: manifest.to_path_buf(),
                table: table_name.to_string(),
                name: name.clone(),
                to,
            });
        }
    }
}

/// Every path dependency a manifest declares (normal, dev, build, target-specific, the
/// workspace's), and its workspace's members as dependencies of the kind "member".
fn path_deps(manifest: &Path) -> Vec<PathDep> {
    let t = read(manifest);
    let ws = workspace_of(manifest, &t);
    let mut out = Vec::new();
    let kinds = ["dependencies", "dev-dependencies", "build-dependencies"];
    for kind in kinds {
        if let Some(d) = t.get(kind).and_then(|d| d.as_table()) {
            path_deps_of(manifest, kind, d, ws.as_deref(), &mut out);
        }
    }
    if let Some(targets) = t.get("target").and_then(|x| x.as_table()) {
        for (cfg, tt) in targets {
            for kind in kinds {
                if let Some(d) = tt.get(kind).and_then(|d| d.as_table()) {
                    let name = format!("target.{cfg}.{kind}");
                    path_deps_of(manifest, &name, d, ws.as_deref(), &mut out);
                }
            }
        }
    }
    if let Some(w) = t.get("workspace").and_then(|w| w.as_table()) {
        if let Some(d) = w.get("dependencies").and_then(|d| d.as_table()) {
            path_deps_of(manifest, "workspace.dependencies", d, None, &mut out);
        }
        let dir = manifest.parent().unwrap();
        for m in w
            .get("members")
            .and_then(|m| m.as_array())
            .into_iter()
            .flatten()
        {
            if let Some(m) = m.as_str() {
                out.push(PathDep {
                    from: manifest.to_path_buf(),
                    table: "workspace.members".to_string(),
                    name: m.to_string(),
                    to: normal(&dir.join(m)),
                });
            }
        }
    }
    if let Some(ws) = t
        .get("package")
        .and_then(|p| p.get("workspace"))
        .and_then(|w| w.as_str())
    {
        out.push(PathDep {
            from: manifest.to_path_buf(),
            table: "package.workspace".to_string(),
            name: ws.to_string(),
            to: normal(&manifest.parent().unwrap().join(ws)),
        });
    }
    out
}

fn relative(p: &Path) -> String {
    p.strip_prefix(root()).unwrap_or(p).display().to_string()
}

fn manifests_under(dirs: &[&str]) -> Vec<PathBuf> {
    let mut all = Vec::new();
    for d in dirs {
        manifests(&root().join(d), &mut all);
    }
    all
}

/// Property: no manifest under `firmware/` or `sim/` reaches into `host-sim/`, by any kind
/// of path dependency or workspace membership.
#[test]
fn firmware_and_sim_depend_on_nothing_under_host_sim() {
    let host = root().join("host-sim");
    let all = manifests_under(&["firmware", "sim"]);
    assert!(
        all.len() >= 8,
        "found only {} manifests under firmware/ and sim/",
        all.len()
    );
    let wrong: Vec<String> = all
        .iter()
        .flat_map(|m| path_deps(m))
        .filter(|d| d.to.starts_with(&host))
        .map(|d| {
            format!(
                "{} [{}] {} -> {}",
                relative(&d.from),
                d.table,
                d.name,
                relative(&d.to)
            )
        })
        .collect();
    assert!(
        wrong.is_empty(),
        "dependencies pointing up into host-sim/:\n{}",
        wrong.join("\n")
    );
}

/// Property: no crate under `sim/` depends on a crate that depends (by any kind of
/// dependency, tests included) on a crate under `sim/`: the control application's tests
/// run on the plant-backed board, so that board cannot be built on the control
/// application.
#[test]
fn sim_depends_on_no_crate_that_tests_on_sim() {
    let sim = root().join("sim");
    let sim_crates: BTreeSet<PathBuf> = manifests_under(&["sim"])
        .iter()
        .filter_map(|m| m.parent().map(Path::to_path_buf))
        .collect();
    let mut wrong = Vec::new();
    for m in manifests_under(&["sim"]) {
        for d in path_deps(&m) {
            if d.to.starts_with(&sim) || d.table.starts_with("workspace") {
                continue;
            }
            let theirs = path_deps(&d.to.join("Cargo.toml"));
            for back in theirs.iter().filter(|b| sim_crates.contains(&b.to)) {
                wrong.push(format!(
                    "{} -> {} ({}), which [{}] depends on {}",
                    relative(&m),
                    d.name,
                    relative(&d.to),
                    back.table,
                    relative(&back.to)
                ));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "cycles through sim/:\n{}",
        wrong.join("\n")
    );
}
