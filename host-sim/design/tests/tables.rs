//! `ranges` against the printed rows of thesis Table 8.3 (the first 20 of the 95 admissible
//! USR robots; the command on row 1: host-sim/tests/design_tables.rs). Table 8.2 (the 22
//! admissible RSPR robots) is not reproduced: the thesis text in shared/seed names it but
//! prints none of its rows, so there is nothing to compare.
//!
//! Transcription. The seed's Table 8.3 is an OCR of a right-to-left page; its header reads
//! `T_r max | T_r min | T_n max | T_n min | e | rp | hc | l1 | l2 || alpha min, max, span ||
//! beta ... || gamma ... || delta ...`, and its data rows run left to right as e, rp, hc, l1,
//! l2 (cm), alpha, beta, gamma, delta (min, max, span; deg), T_n min, max, T_r min, max
//! (N m). The column order of (hc, l1, l2) is confirmed by delta at the central pose:
//! |e_i - p_i| = hc when e = rp, and the law of cosines gives delta = 48.2 deg for row 1,
//! inside its printed 34..70 (with hc and l1 swapped it would be 83.6 deg). T_n is the
//! torque about the yaw axis z0 (our t_alpha_i), T_r the torque about the pitch axis (our
//! t_beta_i). OCR debris removed by hand: stray `|`, `1|` and `11` prefixes (e.g. `1144` ->
//! 44, `$11-28$` -> -28), doubled digits (`188` -> 88, `180` -> 80, `18` -> 8 in the l2
//! column, `135` -> 35), and in two rows a lost leading digit re-derived from the printed span
//! (row 11 gamma `17, 87, 180` -> 7, 87, 80; row 19 beta `115, 54, 50` -> 5, 54, 50 and gamma
//! `116, 85, 79` -> 6, 85, 79); row 1's T_r min `. 72` -> -0.72.
//!
//! What the table is. Every printed number of the 20 rows (320 values) is reproduced at its
//! printed precision (deg to 1, N m to 0.01) by the ranges of the **rotated** orientation
//! alone (+20 deg about [1,1,0]), each quantity over the three chains, on a 10 mm grid of the
//! 40 x 40 x 20 mm box (5 x 5 x 3 points, corners included), wrench [7,7,7 N, 0.7,0.7,0.7
//! N m] with components in {0}, branch 0 (the larger gamma, CONVENTIONS.md).
//!
//! The explained differences:
//! - CONVENTIONS.md defines the task as both orientations (parallel and rotated), and
//!   `ranges`' `task` column (and `synth`) use that union. Its angle columns still match the
//!   table (their extremes all lie in the rotated orientation), but 15 of the 80 torque
//!   values do not: there the parallel orientation needs more torque than the rotated one
//!   (e.g. row 7, T_r max 1.49 N m at (20, 0, 90) mm parallel against the printed 1.40). The
//!   thesis's torque columns therefore cover the rotated orientation only; CONVENTIONS.md
//!   wins, so the task column keeps the union, and this test checks the table against the
//!   `rotated` column and states the union's difference.
//! - The grid: the thesis sampled the box every 10 mm. A finer grid finds slightly wider
//!   ranges (9 x 9 x 5: 11 of the 320 values move by one printed unit, all outwards).
//! - Wrench components in {p} instead of {0} would match none of the 80 torques.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::ranges::{evaluate, Ranges};
use kinematics_core::{Branch, Robot, UsrGeometry};
use robot_config::task_box::TaskBox;

/// One printed row: e, rp, hc, l1, l2 (cm); alpha, beta, gamma, delta min, max, span (deg);
/// T_n min, max; T_r min, max (N m).
type Row = ([f64; 5], [[f64; 3]; 4], [f64; 4]);

#[rustfmt::skip]
const TABLE_8_3: [Row; 20] = [
    ([2.0, 2.0, 6.0, 6.0, 8.0], [[-73.0, 50.0, 123.0], [-32.0, 44.0, 75.0], [2.0, 87.0, 85.0], [34.0, 70.0, 36.0]], [-0.41, 0.75, -0.72, 0.87]),
    ([2.0, 2.0, 7.0, 6.0, 7.0], [[-57.0, 41.0, 98.0], [-7.0, 58.0, 65.0], [4.0, 89.0, 85.0], [49.0, 89.0, 40.0]], [-0.58, 0.85, -1.01, 1.02]),
    ([2.0, 2.0, 7.0, 6.0, 8.0], [[-59.0, 43.0, 102.0], [-19.0, 48.0, 68.0], [3.0, 83.0, 79.0], [44.0, 80.0, 37.0]], [-0.41, 0.74, -0.81, 0.91]),
    ([2.0, 2.0, 8.0, 6.0, 7.0], [[-65.0, 46.0, 112.0], [3.0, 63.0, 60.0], [0.0, 83.0, 82.0], [60.0, 102.0, 42.0]], [-0.50, 0.79, -1.05, 1.02]),
    ([2.0, 2.0, 8.0, 6.0, 8.0], [[-64.0, 41.0, 106.0], [-8.0, 54.0, 62.0], [1.0, 78.0, 77.0], [53.0, 91.0, 38.0]], [-0.39, 0.71, -0.89, 0.94]),
    ([2.0, 2.0, 8.0, 7.0, 8.0], [[-48.0, 35.0, 83.0], [-2.0, 54.0, 56.0], [8.0, 87.0, 79.0], [51.0, 84.0, 33.0]], [-0.63, 0.90, -1.08, 1.08]),
    ([2.0, 2.0, 9.0, 7.0, 6.0], [[-63.0, 52.0, 115.0], [24.0, 76.0, 51.0], [1.0, 89.0, 88.0], [70.0, 116.0, 46.0]], [-0.76, 1.00, -1.90, 1.40]),
    ([2.0, 2.0, 9.0, 7.0, 7.0], [[-57.0, 43.0, 100.0], [15.0, 67.0, 52.0], [4.0, 85.0, 81.0], [65.0, 104.0, 39.0]], [-0.65, 0.91, -1.43, 1.23]),
    ([2.0, 2.0, 9.0, 7.0, 8.0], [[-54.0, 38.0, 92.0], [6.0, 59.0, 52.0], [5.0, 82.0, 76.0], [60.0, 95.0, 35.0]], [-0.54, 0.84, -1.11, 1.08]),
    ([2.0, 2.0, 10.0, 7.0, 8.0], [[-62.0, 43.0, 106.0], [14.0, 64.0, 50.0], [1.0, 76.0, 75.0], [69.0, 106.0, 38.0]], [-0.46, 0.77, -1.15, 1.08]),
    ([2.0, 2.0, 10.0, 8.0, 7.0], [[-52.0, 42.0, 94.0], [25.0, 70.0, 45.0], [7.0, 87.0, 80.0], [69.0, 106.0, 38.0]], [-0.79, 1.04, -1.95, 1.47]),
    ([2.0, 2.0, 10.0, 8.0, 8.0], [[-49.0, 36.0, 85.0], [17.0, 62.0, 45.0], [9.0, 84.0, 75.0], [64.0, 97.0, 33.0]], [-0.69, 0.95, -1.47, 1.29]),
    ([2.0, 2.0, 11.0, 8.0, 7.0], [[-63.0, 49.0, 112.0], [30.0, 75.0, 45.0], [1.0, 80.0, 79.0], [78.0, 120.0, 42.0]], [-0.60, 0.91, -1.66, 1.37]),
    ([2.0, 2.0, 11.0, 8.0, 8.0], [[-56.0, 41.0, 98.0], [23.0, 67.0, 44.0], [4.0, 78.0, 74.0], [73.0, 109.0, 36.0]], [-0.56, 0.86, -1.38, 1.25]),
    ([2.0, 3.0, 6.0, 7.0, 8.0], [[-46.0, 39.0, 85.0], [-28.0, 41.0, 69.0], [4.0, 89.0, 85.0], [32.0, 71.0, 39.0]], [-0.49, 0.82, -0.71, 0.88]),
    ([2.0, 3.0, 7.0, 7.0, 8.0], [[-46.0, 35.0, 81.0], [-17.0, 45.0, 62.0], [3.0, 85.0, 81.0], [41.0, 80.0, 40.0]], [-0.48, 0.81, -0.79, 0.91]),
    ([2.0, 3.0, 8.0, 7.0, 7.0], [[-48.0, 37.0, 85.0], [2.0, 57.0, 56.0], [1.0, 87.0, 86.0], [53.0, 99.0, 46.0]], [-0.59, 0.87, -1.05, 1.02]),
    ([2.0, 3.0, 8.0, 7.0, 8.0], [[-49.0, 34.0, 83.0], [-8.0, 49.0, 57.0], [1.0, 81.0, 79.0], [49.0, 90.0, 41.0]], [-0.46, 0.78, -0.86, 0.92]),
    ([2.0, 3.0, 9.0, 8.0, 8.0], [[-43.0, 32.0, 74.0], [5.0, 54.0, 50.0], [6.0, 85.0, 79.0], [54.0, 93.0, 39.0]], [-0.63, 0.91, -1.09, 1.08]),
    ([2.0, 3.0, 10.0, 8.0, 8.0], [[-47.0, 35.0, 82.0], [11.0, 58.0, 47.0], [2.0, 80.0, 78.0], [62.0, 103.0, 41.0]], [-0.53, 0.84, -1.12, 1.07]),
];

const ANGLES: [&str; 4] = ["alpha_deg", "beta_deg", "gamma_deg", "delta_deg"];
const THESIS_WRENCH: [f64; 6] = [7.0, 7.0, 7.0, 0.7, 0.7, 0.7];

/// The robot of a row (e, rp, hc, l1, l2 in cm).
fn robot(dims_cm: [f64; 5]) -> Robot<f64> {
    let [e, rp, hc, l1, l2] = dims_cm.map(|x| x / 100.0);
    Robot::Usr(UsrGeometry::new(e, rp, l1, l2, hc).unwrap())
}

/// The ranges of a row over the thesis's box on the 10 mm grid.
fn ranges_of(dims_cm: [f64; 5]) -> Ranges {
    let r = evaluate(
        &robot(dims_cm),
        &TaskBox::thesis([5, 5, 3]),
        THESIS_WRENCH,
        Branch::OUTER,
        1e-6,
    )
    .unwrap();
    assert!(r.failures.is_empty(), "{dims_cm:?}: {:?}", r.failures);
    r
}

/// True when `x` rounds to the printed value `printed` at `decimals` decimals.
fn prints_as(x: f64, printed: f64, decimals: i32) -> bool {
    (x - printed).abs() <= 0.5 * 10f64.powi(-decimals) + 1e-9
}

/// Our values of a row at an orientation in the table's order: the 12 angles (min, max,
/// span of alpha, beta, gamma, delta), then T_n min, max, T_r min, max.
fn our_row(r: &Ranges, orientation: &str) -> ([f64; 12], [f64; 4]) {
    let cols = r.table_columns(orientation);
    let get = |n: &str| cols.iter().find(|c| c.quantity == n).unwrap();
    let mut angles = [0.0; 12];
    for (k, n) in ANGLES.iter().enumerate() {
        let c = get(n);
        angles[3 * k..3 * k + 3].copy_from_slice(&[c.min, c.max, c.span()]);
    }
    let (tn, tr) = (get("t_alpha_nm"), get("t_beta_nm"));
    (angles, [tn.min, tn.max, tr.min, tr.max])
}

/// The printed values of a row in the same order.
fn printed_row(row: &Row) -> ([f64; 12], [f64; 4]) {
    let mut angles = [0.0; 12];
    for (k, a) in row.1.iter().enumerate() {
        angles[3 * k..3 * k + 3].copy_from_slice(a);
    }
    (angles, row.2)
}

/// Every printed value of the 20 rows of Table 8.3 (alpha, beta, gamma, delta min/max/span
/// to 1 deg, T_n and T_r min/max to 0.01 N m) equals, at its printed precision, `ranges` at
/// the rotated task orientation on the thesis's 10 mm grid, each quantity over the chains.
#[test]
fn table_8_3_rows_match_the_rotated_orientation_at_printed_precision() {
    let mut misses = Vec::new();
    for (i, row) in TABLE_8_3.iter().enumerate() {
        let r = ranges_of(row.0);
        let (ours_a, ours_t) = our_row(&r, "rotated");
        let (printed_a, printed_t) = printed_row(row);
        for (k, (&x, &p)) in ours_a.iter().zip(&printed_a).enumerate() {
            if !prints_as(x, p, 0) {
                misses.push(format!("row {} angle column {k}: {x:.2} vs {p}", i + 1));
            }
        }
        for (k, (&x, &p)) in ours_t.iter().zip(&printed_t).enumerate() {
            if !prints_as(x, p, 2) {
                misses.push(format!("row {} torque column {k}: {x:.4} vs {p}", i + 1));
            }
        }
    }
    assert!(misses.is_empty(), "{misses:#?}");
}

/// Over the task of CONVENTIONS.md (both orientations) the angle columns still match the
/// table at printed precision, while the torque ranges only widen: each contains the printed
/// range (to printed precision), and exactly 15 of the 80 torque values differ, every one of
/// them where the parallel orientation needs more torque than the rotated one.
#[test]
fn table_8_3_over_both_orientations_differs_only_in_parallel_torques() {
    let mut torque_differences = 0;
    for (i, row) in TABLE_8_3.iter().enumerate() {
        let r = ranges_of(row.0);
        let (task_a, task_t) = our_row(&r, "task");
        let (_, rotated_t) = our_row(&r, "rotated");
        let (printed_a, printed_t) = printed_row(row);
        for (k, (&x, &p)) in task_a.iter().zip(&printed_a).enumerate() {
            assert!(prints_as(x, p, 0), "row {} angle {k}: {x} vs {p}", i + 1);
        }
        for k in 0..4 {
            let (x, p) = (task_t[k], printed_t[k]);
            // Minima (k even) can only fall, maxima only rise.
            let outward = if k % 2 == 0 {
                x <= p + 0.005
            } else {
                x >= p - 0.005
            };
            assert!(outward, "row {} torque {k}: {x} vs {p}", i + 1);
            if !prints_as(x, p, 2) {
                torque_differences += 1;
                assert_ne!(x, rotated_t[k], "row {} torque {k}", i + 1);
            }
        }
    }
    assert_eq!(torque_differences, 15);
}
