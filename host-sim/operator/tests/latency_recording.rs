//! End-to-end latency on the board, the session recording and its
//! replay. A scripted operator moves the master at a constant 10 mm/s for 1.5 s, twice on
//! one board: with the classic tremor filter, then without. The latency is the lag along the path
//! (`masters::latency`): from the operator's command (the scaled master input, stamped
//! with the input sample's time) to the target sent, to the board's setpoint (as its
//! status arrives) and to the measured pose.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{master_at, wp, TestBoard, PRESENT};
use masters::recording::Recording;
use masters::script::ScriptedMaster;
use masters::{TeleopConfig, TremorSuppression};
use operator::teleoperation::{run, RunReport, TeleoperationSettings};
use std::sync::atomic::AtomicBool;

fn ramp(from_mm: f64, to_mm: f64) -> ScriptedMaster {
    ScriptedMaster::new(
        "ramp",
        vec![
            wp(0.0, master_at(from_mm, 0.0, 0.0, 0.0), PRESENT),
            wp(0.3, master_at(from_mm, 0.0, 0.0, 0.0), PRESENT),
            wp(1.8, master_at(to_mm, 0.0, 0.0, 0.0), PRESENT),
            wp(2.6, master_at(to_mm, 0.0, 0.0, 0.0), PRESENT),
        ],
    )
    .unwrap()
}

fn go(
    b: &mut operator::Board,
    master: &mut ScriptedMaster,
    teleop: TeleopConfig,
    record: Option<std::path::PathBuf>,
) -> RunReport {
    let settings = TeleoperationSettings {
        teleop,
        duration_s: Some(master.duration_s() + 0.2),
        record,
        ..TeleoperationSettings::default()
    };
    let r = run(b, master, &settings, &AtomicBool::new(false), &mut |_| {}).unwrap();
    eprint!("{}", r.summary());
    r
}

/// With the filter, the command reaches the target after the filter's group delay on top
/// of what it takes without it: a ramp through a filter of unit DC gain lags by its DC
/// group delay (60.0 ms; the medians' difference within 3 ms: the host's loop runs at the
/// 100 Hz stream and stamps each target when sent). Without the filter, the master-side
/// acceleration limit (none by default: v / (2 a) = 0) lags the ramp by at most v / (2 a)
/// plus one stream period; with that limit out of reach too, within one stream period
/// (10 ms). The
/// board's part (target to setpoint) is positive and, with the same host, the same with
/// and without the filter (medians within 20 ms). The recording read back gives the same
/// figures (within 1 µs: poses are stored in mm and degrees), and replay writes its five
/// plots.
#[test]
fn latency_measured_recorded_and_replayed() {
    let board = TestBoard::start();
    let mut b = board.enabled();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("session.mcap");
    let filtered = go(
        &mut b,
        &mut ramp(0.0, 15.0),
        TeleopConfig {
            tremor: Some(TremorSuppression::classic()),
            ..TeleopConfig::default()
        },
        Some(file.clone()),
    );
    let plain = go(
        &mut b,
        &mut ramp(15.0, 0.0),
        TeleopConfig {
            tremor: None,
            ..TeleopConfig::default()
        },
        None,
    );
    let fast = go(
        &mut b,
        &mut ramp(0.0, 15.0),
        TeleopConfig {
            tremor: None,
            limits: masters::limits::MotionLimits {
                linear_accel_m_s2: 100.0,
                ..Default::default()
            },
            ..TeleopConfig::default()
        },
        None,
    );
    // Done with the board: disabled now (common::EnabledBoard), not after the replay below,
    // which takes longer than the board waits for a heartbeat (500 ms, then
    // HeartbeatTimeout: a fault a board that outlives the test would keep).
    drop(b);
    let delay = filtered.filter_delay_s.unwrap();
    let f = filtered.latency;
    let p = plain.latency;
    let (fi, pi) = (f.input_to_target.unwrap(), p.input_to_target.unwrap());
    let (fb, pb) = (f.target_to_setpoint.unwrap(), p.target_to_setpoint.unwrap());
    eprintln!(
        "latency at 10 mm/s: filter delay {:.1} ms; master input -> target {:.1} ms (filter) / {:.1} ms (none); target -> setpoint {:.1} / {:.1} ms; input -> setpoint {:.1} / {:.1} ms; input -> measured {:.1} / {:.1} ms",
        delay * 1e3,
        fi.median_s * 1e3,
        pi.median_s * 1e3,
        fb.median_s * 1e3,
        pb.median_s * 1e3,
        f.input_to_setpoint.unwrap().median_s * 1e3,
        p.input_to_setpoint.unwrap().median_s * 1e3,
        f.input_to_measured.unwrap().median_s * 1e3,
        p.input_to_measured.unwrap().median_s * 1e3,
    );
    assert!((delay - 0.060).abs() < 5e-4, "filter delay {delay}");
    // The master-side acceleration limit (200 mm/s²) lags a 10 mm/s ramp by at most
    // v / (2 a) = 25 ms plus one stream period; out of reach (100 m/s²), the command
    // reaches the target within one period. The filter adds its group delay on top.
    let limits = masters::limits::MotionLimits::default();
    let accel_lag = 0.010 / (2.0 * limits.linear_accel_m_s2);
    let fa = fast.latency.input_to_target.unwrap();
    assert!(
        fa.median_s >= 0.0 && fa.median_s <= 0.010,
        "without filter and limit {fa}"
    );
    assert!(
        pi.median_s >= 0.0 && pi.median_s <= accel_lag + 0.010,
        "input -> target without the filter {pi} (limit's lag {accel_lag})"
    );
    assert!(
        (fi.median_s - pi.median_s - delay).abs() < 0.003,
        "input -> target {fi} against {pi} + the filter's {delay}"
    );
    assert!(fb.median_s > 0.0 && pb.median_s > 0.0);
    assert!((fb.median_s - pb.median_s).abs() < 0.020, "{fb} / {pb}");

    let rec = Recording::open(&file).unwrap();
    let read = rec.summary().latency;
    for (a, b) in [
        (read.input_to_target, f.input_to_target),
        (read.target_to_setpoint, f.target_to_setpoint),
        (read.input_to_setpoint, f.input_to_setpoint),
        (read.input_to_measured, f.input_to_measured),
    ] {
        let (a, b) = (a.unwrap(), b.unwrap());
        assert_eq!(a.samples, b.samples);
        assert!((a.median_s - b.median_s).abs() < 1e-6);
    }
    assert_eq!(rec.targets().count(), filtered.trace.targets.len());
    assert_eq!(rec.statuses().count(), filtered.trace.statuses.len());
    let out = dir.path().join("plots");
    let replay = operator::replay::replay(&file, &out).unwrap();
    eprint!("{}", replay.summary);
    let names: Vec<String> = replay
        .plots
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "input.png",
            "position.png",
            "orientation.png",
            "lag.png",
            "margins.png"
        ]
    );
    for p in &replay.plots {
        assert!(
            std::fs::metadata(p).unwrap().len() > 10_000,
            "{}",
            p.display()
        );
    }
}
