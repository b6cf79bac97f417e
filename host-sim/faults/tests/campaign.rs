#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The whole campaign: every cell must pass (detected, within its bound, with the stop
//! table's reaction, the platform within the stops issue's bounds afterwards).

use faults::{report, Condition, FaultKind};

/// Property: every fault kind in every condition is detected within its bound, gets the
/// stop its cause calls for, and the platform moves no further than allowed (SR-1, SR-2,
/// SR-5, SR-7: each cell names the requirements it checks).
#[test]
fn every_cell_of_the_campaign_passes() {
    let t0 = std::time::Instant::now();
    let cells = faults::run(&FaultKind::ALL, &Condition::RUNNING, 2, &|_| {}).unwrap();
    let text = report::matrix_text(&cells);
    println!("{text}");
    println!(
        "campaign: {} cells in {:.1} s",
        cells.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(cells.len() >= 15 * 4);
    assert!(cells.iter().all(|c| c.pass), "{text}");
}
