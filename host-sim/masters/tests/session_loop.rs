#![allow(clippy::unwrap_used, clippy::expect_used)]
//! A whole teleoperation session the way `host-sim teleop` will run one, against a
//! simulated board (setpoint = last target, measured pose lagging it): a scripted
//! keyboard (operator present, jog +x at 10 mm/s, clutch, index the master back while
//! clutched, change the scale to 1:2, release the clutch, jog +y, operator absent),
//! the mapping at 100 Hz, the edge cue from a margin that shrinks towards x = 20 mm,
//! everything recorded to MCAP and read back.
//!
//! Checked: the robot moved 1.8 s × 10 mm/s in x minus nothing (the filter delays but
//! does not shorten) and 0.8 s × 10 mm/s × 0.5 in y; it did not move while clutched or
//! absent; re-engaging did not jump; no target exceeded the master-side limits; the
//! recording holds the same targets and the state, scale and cue events in order.

use masters::keyboard::{Key, KeyAction, KeyEvent, KeyboardConfig, KeyboardMaster, ReleaseMode};
use masters::recording::{
    EventKind, EventRecord, InputRecord, Recording, RecordingWriter, SessionInfo, StatusRecord,
    TargetRecord,
};
use masters::{
    CartesianPose, CueLevel, EdgeCue, EdgeCueConfig, Master, MotionLimits, MotionScale, Teleop,
    TeleopConfig, TeleopOutput,
};
use std::collections::BTreeMap;

fn key(key: Key, action: KeyAction, t_s: f64) -> KeyEvent {
    KeyEvent { key, action, t_s }
}

#[test]
fn scripted_keyboard_session() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("session.mcap");
    let mut keyboard = KeyboardMaster::new(KeyboardConfig {
        release: ReleaseMode::Reported,
        initial_step: 4, // 10 mm/s
        ..KeyboardConfig::default()
    })
    .unwrap();
    let mut teleop = Teleop::new(TeleopConfig::default()).unwrap();
    let mut cue = EdgeCue::new(EdgeCueConfig::default()).unwrap();
    let start = CartesianPose::from_position_rotation_vector([0.0, 0.0, 0.16], [0.0; 3]).unwrap();
    let mut rec = RecordingWriter::create(
        &path,
        &SessionInfo {
            start_unix_ns: 0,
            master: keyboard.name().into(),
            stream_rate_hz: 100.0,
            settings: BTreeMap::new(),
        },
    )
    .unwrap();
    teleop.start(0.0, start).unwrap();
    let script = [
        (10, Key::Char(' '), KeyAction::Press),
        (20, Key::Char('d'), KeyAction::Press),
        (200, Key::Char('d'), KeyAction::Release),
        (220, Key::Char('c'), KeyAction::Press),
        (230, Key::Char('a'), KeyAction::Press),
        (300, Key::Char('a'), KeyAction::Release),
        (310, Key::Char('c'), KeyAction::Press),
        (320, Key::Char('w'), KeyAction::Press),
        (400, Key::Char('w'), KeyAction::Release),
        (450, Key::Char(' '), KeyAction::Press),
    ];
    let limits = MotionLimits::default();
    let mut state = teleop.state();
    let mut targets: Vec<(f64, CartesianPose)> = Vec::new();
    let mut last_before_clutch = None;
    let mut first_after_clutch = None;
    let mut held_ticks_moved = 0;
    let mut setpoint = start;
    let mut measured = start;
    for k in 1..=500u32 {
        let t = f64::from(k) * 0.01;
        for (at, kk, a) in script.iter().filter(|(at, _, _)| *at == k) {
            keyboard.handle(&key(*kk, *a, f64::from(*at) * 0.01));
        }
        if k == 305 {
            // indexing done: change the scale while clutched
            teleop
                .set_scale(MotionScale::new(0.5, 0.5).unwrap())
                .unwrap();
            rec.write_event(&EventRecord::scale(t, teleop.config().scale))
                .unwrap();
        }
        let sample = keyboard.poll(t).unwrap().unwrap();
        rec.write_input(&InputRecord::from(&sample)).unwrap();
        let out = teleop.step(t, Some(&sample)).unwrap();
        if teleop.state() != state {
            state = teleop.state();
            rec.write_event(&EventRecord::state(t, state)).unwrap();
        }
        match out {
            TeleopOutput::ServoCp { pose, limited } => {
                if (220..310).contains(&k) {
                    panic!("followed while clutched at tick {k}");
                }
                if k > 310 && first_after_clutch.is_none() {
                    first_after_clutch = Some(pose);
                }
                if k < 220 {
                    last_before_clutch = Some(pose);
                }
                rec.write_target(&TargetRecord {
                    t_s: t,
                    timestamp_us: u64::from(k) * 10_000,
                    pose,
                    limited,
                    input_t_s: Some(t),
                    commanded: None,
                })
                .unwrap();
                targets.push((t, pose));
                setpoint = pose;
            }
            TeleopOutput::Hold(_) => {
                if teleop.held_pose() != setpoint {
                    held_ticks_moved += 1;
                }
            }
        }
        // the simulated board: measured pose 20 % of the way to the setpoint each tick
        measured.position_m += (setpoint.position_m - measured.position_m) * 0.2;
        if k % 2 == 0 {
            let margin = (1.0 - measured.position_m.x.abs() / 0.020).clamp(0.0, 1.0);
            let before = cue.level();
            let level = cue.update(margin).unwrap();
            if level != before {
                rec.write_event(&EventRecord::cue(t, level)).unwrap();
            }
            rec.write_status(&StatusRecord {
                t_s: t,
                state: "Enabled".into(),
                measured: Some(measured),
                setpoint: Some(setpoint),
                nearest_margin: Some(margin),
                faults: 0,
                margins: Default::default(),
                stop: None,
            })
            .unwrap();
        }
    }
    rec.finish().unwrap();

    // Zero jump on re-engaging, nothing moved while holding.
    assert_eq!(first_after_clutch, last_before_clutch);
    assert_eq!(held_ticks_moved, 0);
    let end = targets.last().unwrap().1;
    let dx_mm = (end.position_m.x - start.position_m.x) * 1e3;
    let dy_mm = (end.position_m.y - start.position_m.y) * 1e3;
    // +x for 1.8 s at 10 mm/s; the -x jog while clutched moved nothing
    assert!((dx_mm - 18.0).abs() < 0.05, "x moved {dx_mm} mm");
    // +y for 0.8 s at 10 mm/s, scaled 1:2 (the filter's tail is cut by the release at 4.5 s)
    assert!((dy_mm - 4.0).abs() < 0.1, "y moved {dy_mm} mm");
    // Limits on every pair of consecutive targets in a following stretch.
    for w in targets.windows(2) {
        let [(ta, a), (tb, b)] = w else { continue };
        if tb - ta < 0.015 {
            let v = (b.position_m - a.position_m).norm() / (tb - ta);
            assert!(
                v <= limits.linear_speed_m_s * (1.0 + 1e-9),
                "{v} m/s at {tb}"
            );
        }
    }

    let r = Recording::open(&path).unwrap();
    assert!(r.complete());
    assert_eq!(r.targets().count(), targets.len());
    for (a, (t, p)) in r.targets().zip(&targets) {
        assert_eq!(a.t_s, *t);
        assert!((a.pose.position_m - p.position_m).norm() < 1e-12);
    }
    let states: Vec<&str> = r
        .events()
        .filter(|e| e.kind == EventKind::State)
        .map(|e| e.detail.as_str())
        .collect();
    assert_eq!(
        states,
        [
            "holding:operator_absent",
            "following",
            "holding:clutched",
            "following",
            "holding:operator_absent"
        ]
    );
    let cues: Vec<&str> = r
        .events()
        .filter(|e| e.kind == EventKind::Cue)
        .map(|e| e.detail.as_str())
        .collect();
    assert_eq!(
        cues,
        [CueLevel::Approaching.as_str()],
        "x passed 15 mm (margin 0.25)"
    );
    assert_eq!(r.events().filter(|e| e.kind == EventKind::Scale).count(), 1);
    let s = r.summary();
    assert_eq!(s.engagements, 2);
    assert!(s.max_target_speed_m_s <= limits.linear_speed_m_s * (1.0 + 1e-9));
    assert_eq!((s.inputs, s.statuses), (500, 250));
}
