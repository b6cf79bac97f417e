#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Recorded sessions: a session written with every kind of record reads back as the
//! same typed records (poses to 1e-12 after the mm/deg edge), the file is MCAP with the
//! documented channels, schemas and encodings, the summary's figures are right, and a
//! file cut short (a crash) reads up to its last whole chunk.

use masters::pose::{CartesianPose, Twist};
use masters::recording::{
    EventKind, EventRecord, InputRecord, Recording, RecordingWriter, SessionInfo, StatusRecord,
    TargetRecord, TOPIC_EVENT, TOPIC_INPUT, TOPIC_SERVO_CP, TOPIC_SESSION, TOPIC_STATUS,
};
use masters::teleop::{HoldReason, MotionScale, TeleopState};
use masters::workspace_cue::CueLevel;
use masters::MasterInput;
use std::collections::BTreeMap;
use std::path::Path;

fn pose(x_mm: f64, rz_deg: f64) -> CartesianPose {
    CartesianPose::from_mm_deg([x_mm, -1.0, 160.0, 2.0, 0.0, rz_deg]).unwrap()
}

fn close(a: &CartesianPose, b: &CartesianPose) -> bool {
    (a.position_m - b.position_m).norm() < 1e-12
        && masters::pose::angle_between(&a.orientation, &b.orientation) < 1e-12
}

fn session() -> SessionInfo {
    let mut settings = BTreeMap::new();
    settings.insert("scale".into(), "0.2/1".into());
    SessionInfo {
        start_unix_ns: 1_790_000_000_000_000_000,
        master: "spacenavd".into(),
        stream_rate_hz: 100.0,
        settings,
    }
}

/// Writes `seconds` of a session at 100 Hz (status at 50 Hz); the records written.
fn write_session(
    path: &Path,
    seconds: f64,
) -> (
    Vec<InputRecord>,
    Vec<TargetRecord>,
    Vec<StatusRecord>,
    Vec<EventRecord>,
) {
    let mut w = RecordingWriter::create(path, &session()).unwrap();
    let (mut ins, mut tgs, mut sts, mut evs) = (vec![], vec![], vec![], vec![]);
    let e = EventRecord::state(0.0, TeleopState::Holding(HoldReason::NoMaster));
    w.write_event(&e).unwrap();
    evs.push(e);
    let n = (seconds * 100.0) as usize;
    for k in 1..=n {
        let t = k as f64 * 0.01;
        let input = if k % 2 == 0 {
            MasterInput::Twist(Twist::from_array([0.001, 0.0, -0.002, 0.0, 0.01, 0.0]).unwrap())
        } else {
            MasterInput::Pose(pose(k as f64 * 0.1, 5.0))
        };
        let i = InputRecord {
            t_s: t,
            input,
            clutch: k % 7 == 0,
            operator_present: true,
            device_time_us: (k % 2 == 0).then_some(k as u64 * 10_000),
            deflection: (k % 2 == 0).then_some([1.0, 2.0, 3.0, 4.0, 5.0, -350.0]),
        };
        w.write_input(&i).unwrap();
        ins.push(i);
        if k == 1 {
            let e = EventRecord::state(t, TeleopState::Following);
            w.write_event(&e).unwrap();
            evs.push(e);
        }
        let tg = TargetRecord {
            t_s: t,
            timestamp_us: k as u64 * 10_000,
            pose: pose(k as f64 * 0.01, 0.0),
            limited: k % 5 == 0,
            input_t_s: (k % 3 == 0).then_some(t - 0.001),
            commanded: (k % 3 == 0).then(|| pose(k as f64 * 0.01 + 0.001, 0.0)),
        };
        w.write_target(&tg).unwrap();
        tgs.push(tg);
        if k % 2 == 0 {
            let s = StatusRecord {
                t_s: t,
                state: if k < 10 {
                    "Ready".into()
                } else {
                    "Enabled".into()
                },
                measured: Some(pose(k as f64 * 0.01 - 0.002, 0.0)),
                setpoint: (k % 4 == 0).then(|| pose(k as f64 * 0.01, 0.0)),
                nearest_margin: Some(0.9 - k as f64 * 0.001),
                faults: if k == 20 { 0x4 } else { 0 },
                margins: if k % 4 == 0 {
                    [("nearest".to_string(), 0.5), ("stroke".to_string(), 0.75)]
                        .into_iter()
                        .collect()
                } else {
                    Default::default()
                },
                stop: (k % 4 == 0).then(|| "None".to_string()),
            };
            w.write_status(&s).unwrap();
            sts.push(s);
        }
    }
    for e in [
        EventRecord::scale(seconds, MotionScale::new(0.2, 1.0).unwrap()),
        EventRecord::cue(seconds, CueLevel::Approaching),
        EventRecord {
            t_s: seconds,
            kind: EventKind::Note,
            detail: "end".into(),
        },
    ] {
        w.write_event(&e).unwrap();
        evs.push(e);
    }
    w.finish().unwrap();
    (ins, tgs, sts, evs)
}

fn same_input(a: &InputRecord, b: &InputRecord) -> bool {
    let inputs = match (&a.input, &b.input) {
        (MasterInput::Pose(p), MasterInput::Pose(q)) => close(p, q),
        (MasterInput::Twist(p), MasterInput::Twist(q)) => p
            .to_array()
            .iter()
            .zip(q.to_array())
            .all(|(x, y)| (x - y).abs() < 1e-15),
        _ => false,
    };
    inputs
        && a.t_s == b.t_s
        && a.clutch == b.clutch
        && a.operator_present == b.operator_present
        && a.device_time_us == b.device_time_us
        && a.deflection == b.deflection
}

#[test]
fn round_trip_and_channels() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("session.mcap");
    let (ins, tgs, sts, evs) = write_session(&path, 3.0);
    let r = Recording::open(&path).unwrap();
    assert!(r.complete());
    assert_eq!(r.session, session());
    assert_eq!(r.inputs().count(), ins.len());
    for (a, b) in r.inputs().zip(&ins) {
        assert!(same_input(a, b), "{a:?}\n{b:?}");
    }
    assert_eq!(r.targets().count(), tgs.len());
    assert!(r.targets().zip(&tgs).all(|(a, b)| a.t_s == b.t_s
        && a.timestamp_us == b.timestamp_us
        && a.limited == b.limited
        && close(&a.pose, &b.pose)));
    assert_eq!(r.statuses().count(), sts.len());
    for (a, b) in r.statuses().zip(&sts) {
        assert_eq!(
            (a.t_s, &a.state, a.nearest_margin, a.faults),
            (b.t_s, &b.state, b.nearest_margin, b.faults)
        );
        assert!(close(
            a.measured.as_ref().unwrap(),
            b.measured.as_ref().unwrap()
        ));
        assert_eq!(a.setpoint.is_some(), b.setpoint.is_some());
    }
    assert_eq!(r.events().cloned().collect::<Vec<_>>(), evs);
    assert_eq!(evs[1].detail, "following");
    assert_eq!(evs[0].detail, "holding:no_master");

    // The MCAP summary lists the documented channels with their schemas and encodings.
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let mut seen: Vec<(String, String, String, String)> = summary
        .channels
        .values()
        .map(|c| {
            let s = c.schema.as_ref().unwrap();
            (
                c.topic.clone(),
                c.message_encoding.clone(),
                s.name.clone(),
                s.encoding.clone(),
            )
        })
        .collect();
    seen.sort();
    let want = [
        (TOPIC_SESSION, "rspr.masters.Session"),
        (TOPIC_INPUT, "rspr.masters.MasterInput"),
        (TOPIC_STATUS, "rspr.masters.RobotStatus"),
        (TOPIC_EVENT, "rspr.masters.TeleopEvent"),
        (TOPIC_SERVO_CP, "rspr.masters.ServoCp"),
    ];
    let mut want: Vec<_> = want
        .iter()
        .map(|(t, s)| {
            (
                t.to_string(),
                "json".to_string(),
                s.to_string(),
                "jsonschema".to_string(),
            )
        })
        .collect();
    want.sort();
    assert_eq!(seen, want);
    // Each schema is valid JSON.
    for c in summary.channels.values() {
        let s = c.schema.as_ref().unwrap();
        serde_json::from_slice::<serde_json::Value>(&s.data).unwrap();
    }
    // A message is JSON with the unit in its field names.
    let first_target = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .find(|m| m.channel.topic == TOPIC_SERVO_CP)
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&first_target.data).unwrap();
    assert!(
        (v["pose"]["x_mm"].as_f64().unwrap() - 0.01).abs() < 1e-12,
        "{v}"
    );
    assert_eq!(v["timestamp_us"], 10_000);
    assert_eq!(
        first_target.log_time,
        1_790_000_000_000_000_000 + 10_000_000
    );

    let s = r.summary();
    assert_eq!(
        (s.inputs, s.targets, s.statuses, s.events),
        (300, 300, 150, 5)
    );
    assert_eq!(s.limited_targets, 60);
    assert_eq!(s.engagements, 1);
    assert!((s.duration_s - 2.99).abs() < 1e-9);
    assert!(
        (s.target_path_m - 2.99e-3).abs() < 1e-9,
        "{}",
        s.target_path_m
    );
    assert!((s.max_target_speed_m_s - 1e-3).abs() < 1e-9);
    assert!((s.max_following_error_m.unwrap() - 2e-6).abs() < 1e-12);
    assert!((s.min_margin.unwrap() - 0.6).abs() < 1e-12);
    assert_eq!(s.faults_seen, 0x4);
    assert_eq!(s.states.get("Enabled"), Some(&146));
    let text = s.to_string();
    assert!(text.contains("300 targets (60 limited)"), "{text}");
}

/// A file cut short (here at 60 % of its bytes, as a crash would leave it) reads up to
/// its last whole chunk: some records, all equal to the first ones written, and
/// `complete()` false with the reason.
#[test]
fn file_cut_short_reads_up_to_its_last_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("session.mcap");
    let (_, tgs, _, _) = write_session(&path, 5.0);
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let r = Recording::open(&cut).unwrap();
    assert!(!r.complete());
    assert!(r.stopped_by().is_some());
    let n = r.targets().count();
    assert!(n >= 100 && n < tgs.len(), "{n} of {} targets", tgs.len());
    assert!(r
        .targets()
        .zip(&tgs)
        .all(|(a, b)| a.t_s == b.t_s && close(&a.pose, &b.pose)));
    assert!(!r.summary().complete);
}

#[test]
fn bad_times_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut w = RecordingWriter::create(&dir.path().join("x.mcap"), &session()).unwrap();
    let e = EventRecord {
        t_s: -1.0,
        kind: EventKind::Note,
        detail: String::new(),
    };
    assert!(matches!(
        w.write_event(&e),
        Err(masters::recording::RecordingError::Time(_))
    ));
    w.finish().unwrap();
}
