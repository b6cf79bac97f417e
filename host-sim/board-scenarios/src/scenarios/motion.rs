//! Homing, enabling, the streamed path, a refused target and garbage on the link: the steps of
//! `host-sim teleop` (`teleop::ci`), with what only the emulator sees added: the plant's true
//! joints and pose, the switches and stops, the pins.

use kinematics_core::{forward, Branch, FkConfig, Pose, RsprGeometry};
use master_link::{RobotState, Warnings};
use nalgebra::{Vector3, Vector6};
use teleop::tracking::{deviation, rms_max};

use super::{master_settings, mm, Run, ScenarioError};

/// The tracking limit of `host-sim teleop` (its `--max-deviation-mm` default: the legs'
/// following-error window of the servo), m.
pub const MAX_DEVIATION_M: f64 = 1e-3;

/// The master's stream rate (`host-sim teleop`'s default), Hz.
pub const STREAM_RATE_HZ: f64 = 100.0;

fn joints_text(q: &[f64; 6]) -> String {
    format!(
        "legs {:.3} / {:.3} / {:.3} mm, links {:.3} / {:.3} / {:.3} deg",
        q[0] * 1e3,
        q[1] * 1e3,
        q[2] * 1e3,
        q[3].to_degrees(),
        q[4].to_degrees(),
        q[5].to_degrees()
    )
}

/// Homing (teleop's step), then: every leg reached its switch and every link its stop, the
/// park move ended at the central configuration, the board's joints agree with the plant's.
/// Whether the robot is homed.
pub fn home(run: &mut Run) -> Result<bool, ScenarioError> {
    run.rig.lock().truth = Some(Vec::new());
    let t0 = run.now_s();
    let homed = teleop::ci::home(&mut run.s, &mut run.ci, 90.0, &run.central_q)?;
    run.adopt_teleop_checks();
    let truth = run.rig.lock().truth.take().unwrap_or_default();
    let cfg = run.rig.lock().bench.last.q;
    let lowest: [f64; 6] = std::array::from_fn(|j| {
        truth
            .iter()
            .map(|(_, q)| q[j])
            .fold(f64::INFINITY, f64::min)
    });
    let mech = board_emulator::mechanics::MechanicsConfig::reference(None)?;
    let leg_switch_m = mech.layout.switch_below[0].unwrap_or_default();
    let link_stop = |j: usize| mech.layout.stop_below[j].unwrap_or_default();
    let reached: Vec<bool> = (0..6)
        .map(|j| {
            let l = lowest.get(j).copied().unwrap_or(f64::INFINITY);
            if j < 3 {
                l <= leg_switch_m
            } else {
                l <= link_stop(j) + 0.2f64.to_radians()
            }
        })
        .collect();
    let board = run.last_status().map(|s| s.joints.map(f64::from));
    let err: [f64; 6] =
        std::array::from_fn(|j| board.map_or(f64::INFINITY, |b| (b[j] - cfg[j]).abs()));
    let parked: [f64; 6] = std::array::from_fn(|j| (cfg[j] - run.central_q[j]).abs());
    // The board reads the load through the backlash (0.12 mm on the legs).
    let agree = err.iter().take(3).all(|e| *e < 0.3e-3) && err.iter().skip(3).all(|e| *e < 2e-4);
    let at_centre =
        parked.iter().take(3).all(|e| *e < 0.3e-3) && parked.iter().skip(3).all(|e| *e < 2e-3);
    let stops_below: Vec<f64> = (3..6)
        .map(|j| (run.central_q[j] - link_stop(j)).to_degrees())
        .collect();
    run.check(
        "homing: legs onto their switches, links against their stops, then the park move",
        homed && reached.iter().all(|r| *r) && agree && at_centre,
        format!(
            "in {:.2} s of virtual time; lowest true joints {} (switches at {:.1} mm, link stops {:.1} deg below central); parked at central within {:.3} mm / {:.4} deg (true joints); board vs plant: legs {:.3} mm, links {:.4} deg at most (the legs' backlash)",
            run.now_s() - t0,
            joints_text(&lowest),
            leg_switch_m * 1e3,
            stops_below.first().copied().unwrap_or_default(),
            parked.iter().take(3).fold(0.0, |a: f64, b| a.max(*b)) * 1e3,
            parked.iter().skip(3).fold(0.0, |a: f64, b| a.max(*b)).to_degrees(),
            err.iter().take(3).fold(0.0, |a: f64, b| a.max(*b)) * 1e3,
            err.iter().skip(3).fold(0.0, |a: f64, b| a.max(*b)).to_degrees(),
        ),
    );
    Ok(homed)
}

/// Enable (teleop's step): the brakes stay applied while the drivers push against them in
/// the brake check (+q, then -q, 40 ms each), and open only after it.
pub fn enable(run: &mut Run) -> Result<(), ScenarioError> {
    let _ = run.take_pin_writes();
    let t0 = run.now_ns();
    teleop::ci::enable(&mut run.s, &mut run.ci)?;
    run.adopt_teleop_checks();
    let writes = run.take_pin_writes();
    let w = run.wiring.clone();
    let set = |pin: super::wiring::OutputPin, after: u64| {
        writes
            .iter()
            .find(|r| pin.written(r.address, r.value, true) && r.at.0 >= after)
            .map(|r| r.at.0)
    };
    // The driver enable high, then both brakes released.
    let enable_on = set(w.driver_enable, 0);
    let brakes_off = enable_on.and_then(|e| {
        set(w.brakes[0], e)
            .zip(set(w.brakes[1], e))
            .map(|(a, b)| a.max(b))
    });
    let pushed = enable_on.zip(brakes_off).map(|(e, b)| b.saturating_sub(e));
    // Two pushes (+q, -q), counted by the firmware in control ticks (1 ms): at least two
    // push times less a tick.
    let push_ns = control::brakes::BrakeCheckConfig::<f32>::default().push_us * 1_000;
    let ok = pushed.is_some_and(|p| p + 1_000_000 >= 2 * push_ns);
    run.check(
        "enable: the brakes stay applied through the brake check while the drivers push",
        ok,
        format!(
            "driver enable high ({}) {} after the request, brakes released ({}, {}) {} after the drivers came on (brake check 2 x {} ms, counted in 1 ms ticks)",
            w.driver_enable.name(true),
            enable_on.map_or("never".into(), |t| super::ms(t - t0)),
            w.brakes[0].name(true),
            w.brakes[1].name(true),
            pushed.map_or("never".into(), super::ms),
            push_ns / 1_000_000,
        ),
    );
    Ok(())
}

/// The tool (1.2 kg on 0.1 m) put on the platform while the robot holds at the centre: the
/// servo takes its weight (the sag is the legs' backlash at most), no fault.
pub fn attach_tool(run: &mut Run) -> Result<(), ScenarioError> {
    let since = run.s.statuses.len();
    run.rig.lock().truth = Some(Vec::new());
    run.act(board_emulator::bench::Action::Tool(Some(
        board_emulator::mechanics::Tool::THESIS,
    )));
    run.wait(0.5)?;
    let truth = run.rig.lock().truth.take().unwrap_or_default();
    let poses = true_poses(&truth, &run.centre);
    let sag = poses
        .iter()
        .map(|(_, p)| (p.t - run.centre.t).norm())
        .fold(0.0, f64::max);
    let end = poses
        .last()
        .map_or(f64::INFINITY, |(_, p)| (p.t - run.centre.t).norm());
    let left = run
        .rows_since(since)
        .into_iter()
        .find(|r| r.status.state != RobotState::Enabled || !r.status.faults.is_empty());
    run.check(
        "the tool put on while the robot holds: its weight taken, no fault",
        left.is_none() && sag < 0.25e-3,
        format!(
            "1.2 kg on 0.1 m; the true pose moved {} at most and ends {} from the centre over 0.5 s; {}",
            mm(sag),
            mm(end),
            match left {
                Some(r) => format!("LEFT Enabled: {:?} {:?}", r.status.state, r.status.fault.cause),
                None => "still Enabled, no fault".into(),
            }
        ),
    );
    Ok(())
}

/// The best-fitting delay between the master's targets and the board's setpoints: the
/// delay `d` (-50..300 ms, 0.1 ms steps; negative: the setpoint runs ahead, as a led one
/// can) that minimises the RMS distance between each status's
/// setpoint position and the streamed path at the status's arrival minus `d`; that RMS;
/// the RMS at no delay (the target error).
pub fn best_fitting_delay(
    sent: &[(f64, Pose<f64>)],
    setpoints: &[(f64, Vector3<f64>)],
) -> Option<(f64, f64, f64)> {
    let at = |t: f64| -> Option<Vector3<f64>> {
        let i = sent.partition_point(|(ts, _)| *ts <= t);
        let (ta, a) = sent.get(i.checked_sub(1)?)?;
        match sent.get(i) {
            Some((tb, b)) if tb > ta => Some(a.t + (b.t - a.t) * ((t - ta) / (tb - ta))),
            _ => Some(a.t),
        }
    };
    let rms = |d: f64| -> Option<f64> {
        let mut ss = 0.0;
        let mut n = 0usize;
        for (t, p) in setpoints {
            let target = at(t - d)?;
            ss += (p - target).norm_squared();
            n += 1;
        }
        (n > 0).then(|| (ss / n as f64).sqrt())
    };
    let mut best: Option<(f64, f64)> = None;
    for k in -500..=3000 {
        let d = f64::from(k) * 1e-4;
        if let Some(e) = rms(d) {
            if best.is_none_or(|(_, be)| e < be) {
                best = Some((d, e));
            }
        }
    }
    let (d, e) = best?;
    Some((d, e, rms(0.0)?))
}

/// The laparoscope path (teleop's step and its tracking check), then: the lag of the
/// setpoint behind the master's targets, and the plant's true pose against the path.
pub fn path(run: &mut Run) -> Result<(), ScenarioError> {
    let (laparoscope, limits) = master_settings()?;
    let (traj, passes) = teleop::trajectory(run.options.path, &run.centre, &laparoscope, &limits);
    let first_target = run.s.targets.len();
    let since = run.s.statuses.len();
    run.rig.lock().truth = Some(Vec::new());
    teleop::ci::stream(
        &mut run.s,
        &mut run.ci,
        &traj,
        &passes,
        STREAM_RATE_HZ,
        MAX_DEVIATION_M,
    )?;
    run.adopt_teleop_checks();
    let truth = run.rig.lock().truth.take().unwrap_or_default();
    let sent = run
        .s
        .targets
        .get(first_target..)
        .unwrap_or_default()
        .to_vec();
    let (t_first, t_last) = (
        sent.first().map_or(0.0, |(t, _)| *t),
        sent.last().map_or(0.0, |(t, _)| *t),
    );
    // The setpoints while the stream ran, from 0.3 s after its first target (every delay
    // tried then has targets behind it; the path starts with a hold) to 0.3 s after its
    // last.
    let setpoints: Vec<(f64, Vector3<f64>)> = run
        .rows_since(since)
        .iter()
        .filter(|r| r.t_s >= t_first + 0.3 && r.t_s <= t_last + 0.3)
        .filter(|r| r.status.state == RobotState::Enabled)
        .map(|r| {
            let [x, y, z] = r.status.setpoint_position_m.map(f64::from);
            (r.t_s, Vector3::new(x, y, z))
        })
        .filter(|(_, p)| p.iter().all(|c| c.is_finite()))
        .collect();
    let lag = best_fitting_delay(&sent, &setpoints);
    // The true tip against the streamed path, every millisecond.
    let true_dev: Vec<f64> = true_poses(&truth, &run.centre)
        .iter()
        .filter_map(|(t, p)| deviation(&sent, *t, 0.25, p).map(|d| d.position_m))
        .collect();
    let (t_rms, t_max) = rms_max(&true_dev);
    let pass_count = passes.len();
    run.check(
        "the setpoint's lag behind the master's targets (best-fitting delay), the true pose on the path",
        lag.is_some() && !true_dev.is_empty() && t_max <= MAX_DEVIATION_M,
        format!(
            "{} targets, {} statuses; {}; plant's true tip (load-side joints) from the streamed path: RMS {} max {} ({} samples, limit {}); {pass_count} pass(es) of {:?}",
            sent.len(),
            setpoints.len(),
            lag.map_or("no lag measured".to_string(), |(d, e, e0)| format!(
                "best-fitting delay of the setpoint behind the targets {:.1} ms (RMS {} at that delay; target error at no delay RMS {}; the status's transport, up to a tick and a frame at 1 Mbaud, about 2.5 ms, is included)",
                d * 1e3,
                mm(e),
                mm(e0)
            )),
            mm(t_rms),
            mm(t_max),
            true_dev.len(),
            mm(MAX_DEVIATION_M),
            run.options.path,
        ),
    );
    Ok(())
}

/// The true platform poses of `truth` (FK of the load-side joints), with their instants.
fn true_poses(truth: &[(f64, [f64; 6])], start: &Pose<f64>) -> Vec<(f64, Pose<f64>)> {
    let g = RsprGeometry::<f64>::reference();
    let mut guess = *start;
    let mut out = Vec::with_capacity(truth.len());
    for (t, q) in truth {
        let qv = Vector6::from_row_slice(q);
        if let Ok(fk) = forward(&g, &qv, Branch::OUTER, &guess, &FkConfig::default()) {
            guess = fk.pose;
            out.push((*t, fk.pose));
        }
    }
    out
}

/// A target outside the workspace refused while the robot holds (teleop's step and
/// checks), and garbage on the link counted and ignored (teleop's); without the tool (see
/// README.md, "Figures": with it, the legs' loads rest on the lower flank of their backlash
/// and the board image, which declares no payload, compensates by the direction of motion).
///
/// Teleop's second check of the refusal step, "follows again" (a 1 mm step and back, each
/// reached within 0.05 mm), judges the board's measured pose: the forward kinematics of the
/// encoders, which sit on the motors. The emulator adds the plant's true pose (load side)
/// to its figures.
pub fn refuse_and_garbage(run: &mut Run) -> Result<(), ScenarioError> {
    let centre = run.centre;
    run.rig.lock().truth = Some(Vec::new());
    teleop::ci::refuse(&mut run.s, &mut run.ci, &centre)?;
    let refuse_checks = std::mem::take(&mut run.ci.list);
    let t_refused = run.now_s();
    let n = run.s.targets.len();
    let steps: Vec<(f64, Pose<f64>)> = run
        .s
        .targets
        .get(n.saturating_sub(2)..)
        .unwrap_or_default()
        .to_vec();
    // Garbage while the robot holds; the true pose settles meanwhile (about 1 s).
    teleop::ci::garbage(&mut run.s, &mut run.ci)?;
    let garbage_checks = std::mem::take(&mut run.ci.list);
    let truth = run.rig.lock().truth.take().unwrap_or_default();
    let poses = true_poses(&truth, &centre);
    for c in refuse_checks {
        if !c.name.starts_with("follows again") {
            run.check(&format!("teleop: {}", c.name), c.ok, c.figures);
            continue;
        }
        let truth_figures = match steps.as_slice() {
            [(t_near, near), (t_back, back)] => {
                let reached = poses
                    .iter()
                    .filter(|(t, _)| t >= t_near && t < t_back)
                    .map(|(_, p)| (p.t - near.t).norm())
                    .fold(f64::INFINITY, f64::min);
                let settled = poses
                    .last()
                    .map_or(f64::INFINITY, |(_, p)| (p.t - back.t).norm());
                let q_end = truth.last().map_or([f64::NAN; 6], |(_, q)| *q);
                let off: [f64; 6] = std::array::from_fn(|j| q_end[j] - run.central_q[j]);
                format!(
                    "the plant's true pose came within {} of the step and, settled {:.2} s later, rests {} from the centre (true joints minus central: {})",
                    mm(reached),
                    poses.last().map_or(0.0, |(t, _)| t - t_refused),
                    mm(settled),
                    joints_text(&off),
                )
            }
            _ => "the step's targets not found".into(),
        };
        run.check(
            &format!("teleop: {}", c.name),
            c.ok,
            format!("{}; {truth_figures}", c.figures),
        );
    }
    run.ci.list = garbage_checks;
    run.adopt_teleop_checks();
    let still = run.last_status().is_some_and(|s| {
        s.state == RobotState::Enabled && !s.warnings.contains(Warnings::NOT_HOMED)
    });
    if !still {
        run.check(
            "still enabled after the refusal and the garbage",
            false,
            format!(
                "last status {:?}",
                run.last_status().map(|s| (s.state, s.fault))
            ),
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(proptest_config::cases(32))]

        /// A setpoint that is the streamed path delayed by `d` (-40..250 ms; negative: ahead)
        /// gives back `d`
        /// within the search's 0.1 ms step and an RMS at that delay far below the path's
        /// motion, at any speed of the stream (0.5..25 mm/s, a circle of 10 mm).
        #[test]
        fn the_best_fitting_delay_of_a_delayed_path_is_its_delay(
            d in -0.04f64..0.25,
            speed_mm_s in 0.5f64..25.0,
        ) {
            let r = 0.010;
            let w = speed_mm_s * 1e-3 / r;
            let at = |t: f64| Vector3::new(r * (w * t).cos(), r * (w * t).sin(), 0.16);
            let sent: Vec<(f64, Pose<f64>)> = (0..600)
                .map(|k| {
                    let t = f64::from(k) * 0.01;
                    (t, Pose { t: at(t), r: nalgebra::Rotation3::identity() })
                })
                .collect();
            let setpoints: Vec<(f64, Vector3<f64>)> = (30..290)
                .map(|k| {
                    let t = f64::from(k) * 0.02 + 0.0007;
                    (t, at(t - d))
                })
                .collect();
            let (found, rms, _) = best_fitting_delay(&sent, &setpoints)
                .ok_or_else(|| TestCaseError::fail("no delay"))?;
            prop_assert!((found - d).abs() <= 0.6e-4, "found {found} for {d}");
            // Chord error of the 10 ms polyline plus the 0.1 ms grid.
            let chord = r * (w * 0.01).powi(2) / 8.0 + speed_mm_s * 1e-3 * 0.6e-4;
            prop_assert!(rms <= chord, "rms {rms} bound {chord}");
        }
    }
}
