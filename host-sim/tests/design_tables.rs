//! `host-sim ranges` on a geometry file reproduces row 1 of thesis Table 8.3 (the whole
//! table, its transcription and the explained differences: host-sim/design/tests/tables.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{ok, Table};
use std::path::PathBuf;

/// True when `x` rounds to the printed value `printed` at `decimals` decimals.
fn prints_as(x: f64, printed: f64, decimals: i32) -> bool {
    (x - printed).abs() <= 0.5 * 10f64.powi(-decimals) + 1e-9
}

/// The CLI's `ranges --csv` on a geometry file gives the per-chain rows from which row 1 of
/// the table follows: alpha3 min -73 deg (rotated) and alpha1 max 50 deg (rotated).
#[test]
fn ranges_cli_reproduces_row_1_from_a_geometry_file() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("design-tables");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("table-8-3-row-1.toml");
    std::fs::write(
        &file,
        "robot = \"usr\"\ne_mm = 20.0\nrp_mm = 20.0\nl1_mm = 60.0\nl2_mm = 80.0\nhc_mm = 60.0\n",
    )
    .unwrap();
    let f = file.to_str().unwrap();
    let t = Table::parse(&ok(
        &["--geometry", f, "ranges", "--grid", "5,5,3", "--csv"],
        "",
    ));
    let find = |q: &str, o: &str| {
        (0..t.rows.len())
            .find(|&i| t.text(i, "quantity") == q && t.text(i, "orientation") == o)
            .unwrap()
    };
    assert!(prints_as(
        t.num(find("alpha3_deg", "rotated"), "min"),
        -73.0,
        0
    ));
    assert!(prints_as(
        t.num(find("alpha1_deg", "rotated"), "max"),
        50.0,
        0
    ));
    let table = ok(&["--geometry", f, "ranges", "--grid", "5,5,3"], "");
    assert!(
        table.contains("the columns of thesis Tables 8.2/8.3"),
        "{table}"
    );
}
