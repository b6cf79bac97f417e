//! `host-sim identify`: one joint of a perturbed plant identified and tuned, its estimates
//! with their deviations beside the plant's values, the gains and the step response
//! predicted and measured; the errors name the flag that is wrong.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::{host_sim, ok};

/// Every estimate line carries its deviation and the plant's value, and the errors the
/// CLI prints against the plant stay within the acceptance's bounds (inertia and Coulomb
/// friction 10 %, torque constant 5 %, backlash 10 %).
#[test]
fn a_perturbed_leg_is_identified_and_tuned() {
    let out = ok(&["identify", "--joint", "l2", "--seed", "11"], "");
    for (label, bound) in [
        ("inertia (reflected)", 10.0),
        ("Coulomb friction", 10.0),
        ("torque const x gear", 5.0),
        ("backlash", 10.0),
    ] {
        let line = out
            .lines()
            .find(|l| l.trim_start().starts_with(label))
            .unwrap_or_else(|| panic!("no {label} line in\n{out}"));
        assert!(line.contains("+-") && line.contains("plant"), "{line}");
        let err: f64 = line
            .split("error ")
            .nth(1)
            .and_then(|r| r.split('%').next())
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("no error in {line}"));
        assert!(err.abs() <= bound, "{line}");
    }
    for want in [
        "kp ",
        "phase margin",
        "predicted",
        "measured",
        "breakaway duty",
    ] {
        assert!(out.contains(want), "no {want} in\n{out}");
    }
}

#[test]
fn bad_flags_are_named() {
    let bad = host_sim(&["identify", "--joint", "l9"], "");
    assert_ne!(bad.code, Some(0));
    let err = &bad.stderr;
    assert!(err.contains("unknown joint") && err.contains("l9"), "{err}");
    let bad = host_sim(&["identify", "--joint", "l1", "--travel-deg", "5"], "");
    assert_ne!(bad.code, Some(0));
    let err = &bad.stderr;
    assert!(err.contains("travel_deg"), "{err}");
    let bad = host_sim(
        &["identify", "--joint", "theta1", "--crossover-hz", "400"],
        "",
    );
    assert_ne!(bad.code, Some(0));
    let err = &bad.stderr;
    assert!(err.contains("crossover_hz"), "{err}");
}
