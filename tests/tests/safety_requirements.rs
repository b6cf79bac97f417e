#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The safety requirements' citations (`control::safety`): every requirement is checked by
//! the search and at least one other named test, each cited test exists, and each cites
//! the requirement's identifier back in its documentation.

use std::path::Path;

use control::safety::Requirement;

/// The documentation and attributes right above `fn name` in `source` (up to the previous
/// item's end), if the function exists.
fn doc_of<'a>(source: &'a str, name: &str) -> Option<&'a str> {
    let at = source.find(&format!("fn {name}("))?;
    let before = &source[..at];
    let start = before
        .rfind("\n}\n")
        .or_else(|| before.rfind(";\n"))
        .or_else(|| before.rfind("{\n"))
        .map_or(0, |i| i + 2);
    Some(&before[start..])
}

/// Property: for every requirement, every test it cites exists (file and function) and
/// names the requirement's identifier in its documentation; the search checks every
/// requirement, and at least one other named test does too.
#[test]
fn every_requirement_is_checked_by_the_tests_it_cites() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for r in Requirement::ALL {
        let cited = r.checked_by();
        assert!(
            cited
                .iter()
                .any(|c| c.starts_with("host-sim/faults/tests/search.rs::")),
            "{}: the search must check it",
            r.id()
        );
        assert!(
            cited.len() >= 2,
            "{}: a named test besides the search",
            r.id()
        );
        for c in cited {
            let (file, name) = c.split_once("::").expect("path::test");
            let source = std::fs::read_to_string(root.join(file))
                .unwrap_or_else(|e| panic!("{}: {file}: {e}", r.id()));
            let doc = doc_of(&source, name)
                .unwrap_or_else(|| panic!("{}: no test `{name}` in {file}", r.id()));
            assert!(
                doc.contains("#[test]") || doc.contains("proptest"),
                "{}: `{name}` in {file} is not a test",
                r.id()
            );
            assert!(
                doc.contains(r.id()),
                "{}: `{name}` in {file} does not cite it in its documentation",
                r.id()
            );
        }
    }
}

/// Property: every fault cause guards at least one requirement (the fault log cites it),
/// and the identifiers are SR-1 .. SR-7 in order, each statement written once.
#[test]
fn every_fault_cause_guards_a_requirement() {
    for c in master_link::FaultCause::ALL {
        assert!(
            !control::safety::guards(c).is_empty(),
            "{c:?} guards no requirement"
        );
    }
    for (i, r) in Requirement::ALL.iter().enumerate() {
        assert_eq!(r.id(), format!("SR-{}", i + 1));
        assert_eq!(Requirement::of_id(r.id()), Some(*r));
    }
}
