#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The firmware README prints the stop table: its copy must be the code's.

/// Property: the table between the README's `stop-table` markers is exactly what
/// `stops::write_table` writes from `stops::TABLE` (run with `RSPR_WRITE_README=1` to
/// rewrite it).
#[test]
fn the_readme_prints_the_stop_table_of_the_code() {
    let mut table = String::new();
    control::stops::write_table(&mut table).unwrap();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md");
    let readme = std::fs::read_to_string(path).unwrap();
    let (begin, end) = ("<!-- stop-table -->\n", "<!-- /stop-table -->");
    let a = readme.find(begin).expect("the README's stop-table marker") + begin.len();
    let b = readme[a..].find(end).expect("the README's end marker") + a;
    if std::env::var_os("RSPR_WRITE_README").is_some() {
        let new = format!("{}{}{}", &readme[..a], table, &readme[b..]);
        std::fs::write(path, new).unwrap();
        return;
    }
    assert_eq!(
        &readme[a..b],
        table,
        "firmware/README.md's stop table differs from stops::TABLE; rerun this test with RSPR_WRITE_README=1"
    );
}
