#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The firmware README prints the stop table and the modes' transition table: its copies
//! must be the code's.

/// Checks (or, with `RSPR_WRITE_README=1`, rewrites) the README's text between the
/// markers `<!-- name -->` and `<!-- /name -->` against `table`.
fn check_copy(name: &str, table: &str, source: &str) {
    // One test at a time reads and rewrites the file.
    static FILE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _file = FILE.lock().unwrap();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md");
    let readme = std::fs::read_to_string(path).unwrap();
    let (begin, end) = (format!("<!-- {name} -->\n"), format!("<!-- /{name} -->"));
    let a = readme.find(&begin).expect("the README's begin marker") + begin.len();
    let b = readme[a..].find(&end).expect("the README's end marker") + a;
    if std::env::var_os("RSPR_WRITE_README").is_some() {
        let new = format!("{}{}{}", &readme[..a], table, &readme[b..]);
        std::fs::write(path, new).unwrap();
        return;
    }
    assert_eq!(
        &readme[a..b],
        table,
        "firmware/README.md's {name} differs from {source}; rerun this test with RSPR_WRITE_README=1"
    );
}

/// Property: the table between the README's `stop-table` markers is exactly what
/// `stops::write_table` writes from `stops::TABLE`.
#[test]
fn the_readme_prints_the_stop_table_of_the_code() {
    let mut table = String::new();
    control::stops::write_table(&mut table).unwrap();
    check_copy("stop-table", &table, "stops::TABLE");
}

/// Property: the table between the README's `mode-table` markers is exactly what
/// `modes::write_table` writes from `modes::next`.
#[test]
fn the_readme_prints_the_transition_table_of_the_code() {
    let mut table = String::new();
    control::modes::write_table(&mut table).unwrap();
    check_copy("mode-table", &table, "modes::next");
}

/// Property: the table between the README's `safety-requirements` markers is exactly what
/// `safety::write_table` writes from `safety::Requirement` with the bounds of the
/// reference robot's settings (SR-1 .. SR-7 written once).
#[test]
fn the_readme_prints_the_safety_requirements_of_the_code() {
    let robot = kinematics_core::RsprGeometry::<f64>::reference();
    let cfg =
        control::runtime::reference_config_for(&robot, kinematics_core::Branch::OUTER, None, None)
            .unwrap();
    let bounds = control::safety::Bounds::of(&cfg, &robot);
    let mut table = String::new();
    control::safety::write_table(&mut table, &bounds).unwrap();
    check_copy("safety-requirements", &table, "safety::Requirement");
}
