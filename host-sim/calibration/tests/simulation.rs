#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The calibration proved in simulation, on fixed seeds: a true robot perturbed by ±0.5 mm,
//! ±0.5 deg and ±20 counts, a tracker with 0.1 mm and 0.05 deg of noise, 60 planned poses;
//! on 300 other poses of the task box the calibrated model is within 0.05 mm RMS and
//! 0.15 mm at most, and within reach of the limit the noise allows.

use calibration::identify::Loss;
use calibration::simulate::{run, Outcome, Scenario};

fn mm(m: f64) -> f64 {
    m * 1e3
}

fn print(name: &str, o: &Outcome) {
    println!(
        "{name}: before {:.4} mm RMS, {:.4} max, {:.4} deg RMS; after {:.4} mm RMS, {:.4} max, {:.5} deg RMS; \
         noise limit {:.4} mm RMS, {:.4} max; determined {} of {}; O1 plan {:.3} vs random {:.3}",
        mm(o.before.position_rms_m),
        mm(o.before.position_max_m),
        o.before.rotation_rms_rad.to_degrees(),
        mm(o.after.position_rms_m),
        mm(o.after.position_max_m),
        o.after.rotation_rms_rad.to_degrees(),
        mm(o.limit.position_rms_m),
        mm(o.limit.position_max_m),
        o.identification.identifiability.determined,
        o.identification.identifiability.singular_values.len(),
        o.plan_index.0,
        o.plan_index.1,
    );
}

/// The target on the default scenario (full-pose tracker), with the calibration
/// doing most of the work (the error before is many times the target) and landing within
/// twice the noise limit (the limit is an expectation; one realisation scatters about it).
#[test]
fn calibration_meets_the_target_on_unseen_poses() {
    let o = run(&Scenario::default()).unwrap();
    print("full pose", &o);
    assert!(
        o.before.position_rms_m > 4.0 * 0.05e-3,
        "the perturbation matters"
    );
    assert!(
        o.after.position_rms_m <= 0.05e-3,
        "RMS {:.4} mm",
        mm(o.after.position_rms_m)
    );
    assert!(
        o.after.position_max_m <= 0.15e-3,
        "max {:.4} mm",
        mm(o.after.position_max_m)
    );
    assert!(o.after.position_rms_m <= 2.0 * o.limit.position_rms_m);
    // The plan is better conditioned than as many random poses.
    assert!(o.plan_index.0 > o.plan_index.1);
}

/// Without noise the identification recovers the true robot's behaviour to far below the
/// tracker's resolution: the model and the solver are complete (every pose-relevant
/// deviation is determined, the rest does not matter).
#[test]
fn without_noise_the_error_vanishes() {
    let o = run(&Scenario {
        noise_scale: 0.0,
        ..Scenario::default()
    })
    .unwrap();
    print("noise-free", &o);
    // Half an encoder count of settling is all that is left: 0.005 deg on a 90 mm link
    // moves a spherical joint by 4 µm.
    assert!(
        o.after.position_max_m <= 0.01e-3,
        "max {:.5} mm",
        mm(o.after.position_max_m)
    );
}

/// Position-only measurements (a laser tracker) meet the target too, with the marker's
/// lever making the orientation observable.
#[test]
fn position_only_meets_the_target() {
    let o = run(&Scenario {
        position_only: true,
        seed: 23,
        ..Scenario::default()
    })
    .unwrap();
    print("position only", &o);
    assert!(
        o.after.position_rms_m <= 0.05e-3,
        "RMS {:.4} mm",
        mm(o.after.position_rms_m)
    );
    assert!(
        o.after.position_max_m <= 0.15e-3,
        "max {:.4} mm",
        mm(o.after.position_max_m)
    );
}

/// Gross outliers (3 rows off by 7 mm and 2 deg): plain least squares is dragged off, the
/// Cauchy loss is not (a trial step to a geometry that cannot assemble a measured
/// configuration is rejected, not fatal).
#[test]
fn a_robust_loss_rejects_outliers() {
    let base = Scenario {
        outliers: 3,
        seed: 29,
        ..Scenario::default()
    };
    let plain = run(&base).unwrap();
    print("outliers, squared", &plain);
    let robust = run(&Scenario {
        loss: Loss::Cauchy(3.0),
        ..base
    })
    .unwrap();
    print("outliers, Cauchy", &robust);
    // The robust fit lands within twice the noise limit (the outliers' remaining pull; on
    // seeds 1 to 5 it is at or below the limit, on this one 1.47 times it), the plain one
    // several times further.
    assert!(
        robust.after.position_rms_m <= 2.0 * robust.limit.position_rms_m,
        "robust {:.4} mm vs noise limit {:.4} mm",
        mm(robust.after.position_rms_m),
        mm(robust.limit.position_rms_m)
    );
    assert!(plain.after.position_rms_m > 4.0 * robust.after.position_rms_m);
}

/// Tracker outliers up to 100 mm (one row, and three rows, moved by 100 mm and turned by
/// 2 deg, a thousand noise deviations): the Cauchy fit stays within twice the noise limit
/// on unseen poses, as it does without them. The rows are weighed by their residuals from
/// the first pass on, against a scale that follows the bulk of the rows; a first pass at
/// equal weights lets the outlier drag the fit (on seed 29, to 1.05 mm RMS).
#[test]
fn a_robust_loss_rejects_outliers_of_a_hundred_millimetres() {
    for seed in [19, 29] {
        for outliers in [1, 3] {
            let o = run(&Scenario {
                outliers,
                outlier_m: 0.1,
                seed,
                loss: Loss::Cauchy(3.0),
                ..Scenario::default()
            })
            .unwrap();
            print(
                &format!("seed {seed}, {outliers} rows 100 mm off, Cauchy"),
                &o,
            );
            assert!(
                o.after.position_rms_m <= 2.0 * o.limit.position_rms_m,
                "seed {seed}, {outliers} outliers: {:.4} mm vs noise limit {:.4} mm",
                mm(o.after.position_rms_m),
                mm(o.limit.position_rms_m)
            );
        }
    }
}
