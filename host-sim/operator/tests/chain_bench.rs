#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The whole teleoperation chain in the board's virtual time: the synthetic operator
//! (`masters::synthetic`: strokes, arcs, pauses, tremor drifting over 8-12 Hz and
//! 50-200 µm) replayed through each master path (`chain/mod.rs`) at the 100 Hz stream,
//!
//! - **scripted**: the hand's pose handed to the mapping as a position master's sample;
//! - **udp**: the hand's pose encoded as `PoseDatagram`s, sent over loopback UDP to a
//!   `UdpPoseMaster`, which judges and decodes them (f32 millimetres and quaternion);
//! - **spacemouse**: a SpaceMouse in rate mode through `SpaceNavMaster`, fed by the
//!   test's own spacenavd side on a Unix socket (protocol 1: the handshake, the client's
//!   name and the device queries answered first): each tick the operator deflects the cap
//!   (integer counts, through the inverse of the rate mapping's deadzone and expo) so that
//!   the integral the mapping forms follows the hand's path (the counts' rounding error
//!   carried into the next tick);
//!
//! through the teleoperation mapping (`masters::Teleop`), with the classic filter and with
//! the canceller, to the board application on the plant (`simulation::bench`, 1 kHz; the
//! board's statuses every 20 ms), all on one board, in lockstep: no figure depends on the
//! host's load.
//!
//! **The reference.** The robot follows the hand's motion since engagement: the mapping
//! captures the hand's pose at engagement, tremor included, so the voluntary path the
//! robot is to follow is the voluntary motion since engagement minus the tremor of that
//! instant (a constant offset of up to 200 µm for the whole engagement: against the
//! voluntary motion alone, a matched point lies that offset along the path, which at the
//! 1 mm/s where lags start being measured reads as up to 200 ms).
//!
//! **The stages** (lags along the path, `masters::latency`, a 0.15 s window: the strokes
//! come back over their own path): input → target (the targets as sent, stamped at their
//! input sample's time; the suppression's delay), target → setpoint (the board: its
//! admission, the supervisor's profile and lead), input → setpoint, setpoint → measured
//! (the servo and the plant).
//!
//! Checked on each path's canceller run, the acceptance bounds: tremor in the targets
//! ≥ 20 dB down over 8-12 Hz; best-fitting delay of the targets behind the voluntary path
//! ≤ 5 ms and their RMS error against it no worse than the classic filter's; input →
//! setpoint median ≤ 15 ms and 99th percentile ≤ 25 ms. Then the clutch through the
//! board: pressed while the hand moves on, released, no jump and the motion made while
//! clutched not applied.

mod chain;

use chain::{
    clutch_strokes, tremor_bound_m, tremor_stop_envelope_m, MasterPath, CLUTCH_AFTER_S,
    CLUTCH_FOLLOW_S, CLUTCH_HELD_S, FS, STILL_S, TREMOR_ON_S,
};
use master_link::{MasterToBoard, ResetCause, RobotState};
use masters::latency::{lags, LagConfig, Stamped};
use masters::synthetic::SyntheticOperator;
use masters::{
    CartesianPose, OperatorButtons, Teleop, TeleopConfig, TeleopOutput, TeleopState,
    TremorSuppression,
};
use nalgebra::Vector3;
use operator::conversions::{measured_cp, setpoint_cp};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};
use std::f64::consts::PI;

struct Run {
    /// Per tick of the session: (hand tremor − its value at engagement, target − the
    /// voluntary reference), m.
    residual: Vec<([f64; 3], [f64; 3])>,
    /// The targets relative to the engagement's robot pose, at the input times (s of the
    /// session), with the voluntary motion's value at engagement added back.
    targets: Vec<(f64, Vector3<f64>)>,
    /// The voluntary reference (absolute) and the targets, at their input times.
    reference: Vec<Stamped>,
    sent: Vec<Stamped>,
    /// The board's setpoints and measured poses as the statuses arrive.
    setpoints: Vec<Stamped>,
    measured: Vec<Stamped>,
    /// The clutch scenario: the board's setpoint at the last status before the release,
    /// the first target after it, the setpoints while clutched (after the stop), the
    /// final setpoint and where it should be.
    clutch: ClutchFigures,
    start: StartFigures,
    stop: StopFigures,
}

/// The canceller's start: the first target's distance from the setpoint the mapping held
/// at; over the first 0.5 s the largest tick of the targets and of the hand, and the
/// targets' largest deviation from the voluntary path beyond the tremor's size, m.
#[derive(Default)]
struct StartFigures {
    first_from_setpoint_m: f64,
    largest_tick_m: f64,
    hand_tick_m: f64,
    beyond_bound_m: f64,
}

/// The tremor's stop (hand still): the setpoint's largest distance from the still
/// reference, its largest excess over the envelope, the statuses seen, m.
#[derive(Default)]
struct StopFigures {
    largest_m: f64,
    beyond_envelope_m: f64,
    statuses: usize,
}

#[derive(Default)]
struct ClutchFigures {
    held_setpoint: Vector3<f64>,
    first_target: Vector3<f64>,
    spread_while_held_m: f64,
    end_error_m: f64,
    engagements: u64,
}

fn run(
    b: &mut Bench,
    op: &SyntheticOperator,
    path: &mut MasterPath,
    tremor: TremorSuppression,
) -> Run {
    let status = *b.master.last_status().unwrap();
    let start = setpoint_cp(&status).unwrap();
    let mut teleop = Teleop::new(TeleopConfig {
        tremor: Some(tremor),
        ..TeleopConfig::default()
    })
    .unwrap();
    let t0 = b.now_us() as f64 * 1e-6;
    teleop.start(t0, start).unwrap();
    let origin = CartesianPose::identity();
    let present = OperatorButtons {
        clutch: false,
        operator_present: true,
    };
    let first_status = b.master.statuses.len();
    let mut out = Run {
        residual: Vec::new(),
        targets: Vec::new(),
        reference: Vec::new(),
        sent: Vec::new(),
        setpoints: Vec::new(),
        measured: Vec::new(),
        clutch: ClutchFigures::default(),
        start: StartFigures::default(),
        stop: StopFigures::default(),
    };
    let n = (op.duration_s() * FS).round() as usize;
    let q = ((TREMOR_ON_S + STILL_S) * FS).round() as usize;
    let m = ((CLUTCH_FOLLOW_S + CLUTCH_HELD_S + CLUTCH_AFTER_S) * FS).round() as usize;
    // The tremor stops at `stop_s` of the session; (board time, still reference) then.
    let stop_s = op.duration_s() + TREMOR_ON_S;
    let mut stopped: Option<(f64, Vector3<f64>)> = None;
    let mut prev: Option<(Vector3<f64>, Vector3<f64>)> = None;
    let mut held = start;
    // The engagement: (voluntary position, tremor, robot position) at it.
    let mut anchor: Option<[Vector3<f64>; 3]> = None;
    let mut engagements = teleop.stats().engagements;
    let mut clutch_sent = false;
    let mut statuses_seen = b.master.statuses.len();
    let mut held_spread: Vec<Vector3<f64>> = Vec::new();
    for k in 1..=n + q + m {
        b.run_ms(10).unwrap();
        let t = b.now_us() as f64 * 1e-6;
        let ts = k as f64 / FS;
        // Past the session and the tremor's stop: the clutch scenario.
        let after = ts - stop_s - STILL_S;
        let extra = if k > n + q {
            clutch_strokes(after)
        } else {
            Vector3::zeros()
        };
        let clutched =
            k > n + q && after > CLUTCH_FOLLOW_S && after <= CLUTCH_FOLLOW_S + CLUTCH_HELD_S;
        let buttons = OperatorButtons {
            clutch: clutched,
            ..present
        };
        // While the mapping holds, it re-anchors at the board's setpoint (as
        // `operator::teleoperation` does).
        for r in &b.master.statuses[statuses_seen..] {
            if matches!(teleop.state(), TeleopState::Holding(_))
                && r.status.state == RobotState::Enabled
            {
                let p = setpoint_cp(&r.status).unwrap();
                teleop.resync(p).unwrap();
                held = p;
                if clutched && after > CLUTCH_FOLLOW_S + 0.3 {
                    held_spread.push(p.position_m);
                }
                out.clutch.held_setpoint = p.position_m;
            }
        }
        statuses_seen = b.master.statuses.len();
        let tremor_on = ts < stop_s;
        let mut hand = if tremor_on {
            op.hand(&origin, ts)
        } else {
            op.voluntary_pose(&origin, ts)
        };
        hand.position_m += extra;
        let sample = path.sample(t, &hand, buttons);
        if clutch_sent != buttons.clutch {
            b.send(&MasterToBoard::Clutch {
                engaged: buttons.clutch,
            });
            clutch_sent = buttons.clutch;
        }
        let output = teleop.step(t, Some(&sample)).unwrap();
        let (v, _) = op.voluntary(ts);
        let (tr, _) = if tremor_on {
            op.tremor(ts)
        } else {
            ([0.0; 3], [0.0; 3])
        };
        let (v, tr) = (Vector3::from(v) + extra, Vector3::from(tr));
        if teleop.stats().engagements != engagements {
            engagements = teleop.stats().engagements;
            anchor = Some([v, tr, teleop.held_pose().position_m]);
        }
        let TeleopOutput::ServoCp { pose, .. } = output else {
            assert!(clutched, "holding at {ts} s: {output:?}");
            continue;
        };
        let rv = pose.rotation_vector_rad();
        b.send(&MasterToBoard::PoseTarget {
            timestamp_us: b.now_us(),
            position_m: pose.position_m.map(|x| x as f32).into(),
            rotation_vector_rad: [rv.x as f32, rv.y as f32, rv.z as f32],
        });
        let [v0, tr0, robot0] = anchor.unwrap();
        // The voluntary path the robot is to follow since this engagement.
        let reference = robot0 + v - v0 - tr0;
        if ts < 0.5 {
            // The canceller's start.
            let st = &mut out.start;
            match prev {
                // Before its first engagement the mapping holds at the board's setpoint
                // (the start, or a status since, as it re-anchors while holding).
                None => st.first_from_setpoint_m = (pose.position_m - held.position_m).norm(),
                Some((p, h)) => {
                    st.largest_tick_m = st.largest_tick_m.max((pose.position_m - p).norm());
                    st.hand_tick_m = st.hand_tick_m.max((hand.position_m - h).norm());
                }
            }
            prev = Some((pose.position_m, hand.position_m));
            let beyond = (pose.position_m - reference).norm() - tremor_bound_m(ts);
            st.beyond_bound_m = st.beyond_bound_m.max(beyond);
        }
        if !tremor_on && stopped.is_none() {
            stopped = Some((t, reference));
        }
        if k <= n {
            let off = pose.position_m - reference;
            out.residual
                .push(((tr - tr0).into(), [off.x, off.y, off.z]));
            out.targets.push((ts, pose.position_m - robot0 + v0 + tr0));
        } else if out.clutch.engagements == 0 && engagements >= 2 {
            out.clutch.first_target = pose.position_m;
            out.clutch.engagements = engagements;
        }
        out.reference.push((t, reference));
        out.sent.push((t, pose.position_m));
        if k == n + q + m {
            // The end of the clutch scenario: the robot settles where the reference is.
            b.run_ms(500).unwrap();
            let last = setpoint_cp(b.master.last_status().unwrap()).unwrap();
            out.clutch.end_error_m = (last.position_m - reference).norm();
        }
    }
    let lo = held_spread
        .iter()
        .fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = held_spread
        .iter()
        .fold(Vector3::repeat(-f64::INFINITY), |a, p| a.sup(p));
    out.clutch.spread_while_held_m = (hi - lo).norm();
    // The tremor's stop: the statuses while the hand is still after it.
    let (t_stop, still) = stopped.unwrap();
    let bound = tremor_bound_m(stop_s);
    for r in &b.master.statuses[first_status..] {
        let t = r.t_us as f64 * 1e-6;
        if t >= t_stop && t < t_stop + STILL_S {
            let d = (setpoint_cp(&r.status).unwrap().position_m - still).norm();
            let s = &mut out.stop;
            s.largest_m = s.largest_m.max(d);
            s.beyond_envelope_m = s
                .beyond_envelope_m
                .max(d - tremor_stop_envelope_m(bound, t - t_stop));
            s.statuses += 1;
        }
    }
    for r in &b.master.statuses[first_status..] {
        let t = r.t_us as f64 * 1e-6;
        if let Some(p) = setpoint_cp(&r.status) {
            out.setpoints.push((t, p.position_m));
        }
        if let Some(p) = measured_cp(&r.status) {
            out.measured.push((t, p.position_m));
        }
    }
    out
}

/// Energy over [lo, hi] Hz of a 100 Hz record (DFT bins).
fn band_energy(x: &[f64], lo: f64, hi: f64) -> f64 {
    let n = x.len();
    let df = FS / n as f64;
    ((lo / df).ceil() as usize..=(hi / df).floor() as usize)
        .map(|k| {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, v) in x.iter().enumerate() {
                let ph = 2.0 * PI * (k * i) as f64 / n as f64;
                re += v * ph.cos();
                im -= v * ph.sin();
            }
            re * re + im * im
        })
        .sum()
}

fn attenuation_db(r: &Run) -> f64 {
    let (mut res, mut tre) = (0.0, 0.0);
    for c in 0..3 {
        let t: Vec<f64> = r.residual.iter().map(|(t, _)| t[c]).collect();
        let o: Vec<f64> = r.residual.iter().map(|(_, o)| o[c]).collect();
        tre += band_energy(&t, 8.0, 12.0);
        res += band_energy(&o, 8.0, 12.0);
    }
    10.0 * (res / tre).log10()
}

/// Best-fitting delay of the targets behind the voluntary path (0.1 ms grid), and the
/// RMS error at zero delay, m.
fn delay_and_rms(op: &SyntheticOperator, r: &Run) -> (f64, f64) {
    let rms = |tau: f64| {
        let s: f64 = r
            .targets
            .iter()
            .map(|(ts, p)| (p - Vector3::from(op.voluntary(ts - tau).0)).norm_squared())
            .sum();
        (s / r.targets.len() as f64).sqrt()
    };
    let mut best = (0.0, f64::INFINITY);
    for i in -200..=1200 {
        let tau = f64::from(i) * 1e-4;
        let e = rms(tau);
        if e < best.1 {
            best = (tau, e);
        }
    }
    (best.0, rms(0.0))
}

/// Median and 99th percentile, s (NaN when nothing was matched).
fn median_p99(mut v: Vec<f64>) -> (f64, f64, usize) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN, 0);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.99), v.len())
}

struct Figures {
    att_db: f64,
    delay_s: f64,
    rms_m: f64,
    input_setpoint: (f64, f64, usize),
}

fn figures(op: &SyntheticOperator, path: &str, name: &str, r: &Run) -> Figures {
    let att_db = attenuation_db(r);
    let (delay_s, rms_m) = delay_and_rms(op, r);
    let cfg = LagConfig {
        window_s: 0.15,
        ..LagConfig::default()
    };
    let stage =
        |reference: &[Stamped], follower: &[Stamped]| median_p99(lags(reference, follower, &cfg));
    let input_target = stage(&r.reference, &r.sent);
    let target_setpoint = stage(&r.sent, &r.setpoints);
    let input_setpoint = stage(&r.reference, &r.setpoints);
    let setpoint_measured = stage(&r.setpoints, &r.measured);
    let ms = |(m, p, n): (f64, f64, usize)| format!("{:.1}/{:.1} ms ({n})", m * 1e3, p * 1e3);
    eprintln!(
        "{path:>10} {name:<14} tremor {att_db:6.1} dB; delay {:5.1} ms; RMS {:6.1} µm; median/p99: input->target {}, target->setpoint {}, input->setpoint {}, setpoint->measured {}",
        delay_s * 1e3,
        rms_m * 1e6,
        ms(input_target),
        ms(target_setpoint),
        ms(input_setpoint),
        ms(setpoint_measured),
    );
    Figures {
        att_db,
        delay_s,
        rms_m,
        input_setpoint,
    }
}

fn bench() -> Bench {
    let cfg = BoardSimConfig::reference(None).unwrap();
    let mut b = Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        0x7e30,
    );
    b.bring_up().unwrap();
    b.run_ms(100).unwrap();
    b
}

/// Each master path, the classic filter then the canceller, on one board.
#[test]
fn each_master_path_through_the_simulated_board() {
    let mut b = bench();
    let op = SyntheticOperator::surgical();
    for make in [
        (|| MasterPath::Scripted) as fn() -> MasterPath,
        MasterPath::udp,
        MasterPath::spacemouse,
    ] {
        let mut path = make();
        let name = path.name();
        let classic = run(&mut b, &op, &mut path, TremorSuppression::classic());
        let classic = figures(&op, name, "classic filter", &classic);
        let r = run(
            &mut b,
            &op,
            &mut path,
            TremorSuppression::Canceller(Default::default()),
        );
        let new = figures(&op, name, "canceller", &r);
        let c = &r.clutch;
        eprintln!(
            "{name:>10} clutch: re-engaged {:.3} µm from the held setpoint; setpoint spread while held {:.3} µm; settled {:.1} µm from the reference ({} engagements)",
            (c.first_target - c.held_setpoint).norm() * 1e6,
            c.spread_while_held_m * 1e6,
            c.end_error_m * 1e6,
            c.engagements,
        );
        let (st, sp) = (&r.start, &r.stop);
        eprintln!(
            "{name:>10} start: first target {:.2e} m from the setpoint; largest tick {:.1} µm (the hand's {:.1} µm); beyond the tremor's size {:.1} µm. Tremor stops: the setpoint at most {:.1} µm from the still reference (the tremor's size {:.1} µm), beyond the envelope {:.2} µm ({} statuses)",
            st.first_from_setpoint_m,
            st.largest_tick_m * 1e6,
            st.hand_tick_m * 1e6,
            st.beyond_bound_m * 1e6,
            sp.largest_m * 1e6,
            tremor_bound_m(op.duration_s() + TREMOR_ON_S) * 1e6,
            sp.beyond_envelope_m * 1e6,
            sp.statuses,
        );
        // No step when the canceller starts: the first target is the setpoint the run
        // started from (f64 of its f32 report, sent back as f32: exact); while the
        // estimate grows from zero the targets stay within the tremor's size of the
        // voluntary path and no tick moves further than the hand's largest.
        assert!(
            st.first_from_setpoint_m <= 1e-9,
            "{name}: the first target {} m from the setpoint",
            st.first_from_setpoint_m
        );
        assert!(
            st.largest_tick_m <= st.hand_tick_m,
            "{name}: a tick of {} m at the start, the hand's largest {} m",
            st.largest_tick_m,
            st.hand_tick_m
        );
        assert!(
            st.beyond_bound_m <= 2e-6,
            "{name}: {} m beyond the tremor's size at the start",
            st.beyond_bound_m
        );
        // No jump when the tremor stops: the setpoint within the envelope of the
        // estimate's fading (chain/mod.rs), for the position masters. The SpaceMouse's
        // pose is the integral of the twists it commands, which meets the hand's jump
        // where the tremor ends at once only through its counts (printed, not checked).
        assert!(
            sp.statuses >= 50,
            "{name}: {} statuses after the stop",
            sp.statuses
        );
        assert!(
            name == "spacemouse" || sp.beyond_envelope_m <= 0.0,
            "{name}: the setpoint {} m beyond the envelope after the tremor stopped",
            sp.beyond_envelope_m
        );
        assert!(new.att_db <= -20.0, "{name}: attenuation {} dB", new.att_db);
        assert!(
            new.delay_s.abs() <= 0.005,
            "{name}: delay {} s",
            new.delay_s
        );
        assert!(
            new.rms_m <= classic.rms_m,
            "{name}: RMS {} vs the classic filter's {}",
            new.rms_m,
            classic.rms_m
        );
        let (med, p99, samples) = new.input_setpoint;
        assert!(samples >= 300, "{name}: only {samples} lags matched");
        assert!(med <= 0.015, "{name}: input -> setpoint median {med} s");
        assert!(p99 <= 0.025, "{name}: input -> setpoint p99 {p99} s");
        // The clutch: the first target after re-engaging is the board's held setpoint
        // (bit for bit in f64 of its f32 report: the f32 target rounds the same); the
        // board held still (within its f32 report and the servo's settling) while the
        // hand made its 4 mm stroke; and the robot ends where the hand's motion since
        // re-engaging puts it (the 4 mm not applied), within the canceller's residual
        // and the board's f32 setpoint.
        assert_eq!(c.engagements, 2, "{name}: one re-engagement");
        assert!(
            (c.first_target - c.held_setpoint).norm() <= 1e-9,
            "{name}: a jump of {} m on re-engaging",
            (c.first_target - c.held_setpoint).norm()
        );
        assert!(
            c.spread_while_held_m <= 1e-6,
            "{name}: the setpoint moved {} m while clutched",
            c.spread_while_held_m
        );
        assert!(
            c.end_error_m <= 50e-6,
            "{name}: ended {} m from the reference",
            c.end_error_m
        );
    }
}
