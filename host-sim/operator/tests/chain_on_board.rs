#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The teleoperation chain on a board served on a socket: `RSPR_BOARD_SOCKET` (the
//! emulated board running the release image, `against-emulator.sh`) or, without it, the
//! simulated board served in a thread (`common::TestBoard`). Ignored by `cargo test`
//! (it plays about 28 s of the board's time); run with `--ignored`.
//!
//! The synthetic operator (`masters::synthetic`: strokes, an arc, pauses; tremor drifting
//! over 8.0-11.7 Hz in this part of the session and 50-200 µm) is replayed through the
//! scripted master path (`chain/mod.rs`) into the host's own teleoperation loop
//! (`operator::teleoperation::run`: the 100 Hz stream, the buttons told to the board, the
//! mapping re-anchored at the board's setpoint while it holds). Everything runs in the
//! board's time: the board shares its clock beside its socket (the emulated board with
//! `--clock-lead-ms`, the simulated one of `common::TestBoard`; a board that does not
//! fails the test) and the master runs in lockstep with it (`Board::set_lockstep`,
//! `teleop::pacing`): the master's clock is the board's, a tick waits for the board's time
//! to reach it, and the board runs at most 2 ms beyond the master's last reading of its
//! clock, so that it never runs on while the master's host holds the master up. The
//! input's time is the board's time when the master sampled the hand, a setpoint's the
//! board's time when the master read its status: the figures do not move with the host's
//! load, and every run is judged. The loop's ticks are then 10 ms apart in the board's
//! time within the lead and the emulator's step (3 ms), which is checked too. The UDP and
//! SpaceMouse paths also wait on loopback sockets in the host's time each tick: they are
//! measured on the simulated board in lockstep (`chain_bench.rs`).
//!
//! The runs, on one board: the classic filter, then the canceller, over the first
//! `SESSION_S` of the session; after the canceller's session the hand stays still, its
//! tremor goes on for `TREMOR_ON_S` and stops at once, the hand stays still `STILL_S`
//! more, then the clutch scenario of `chain_bench.rs`.
//!
//! Checked on the canceller's run, the acceptance bounds as in `chain_bench.rs`: tremor
//! in the targets ≥ 20 dB down over 8-12 Hz (the DFT at the ticks' own times);
//! best-fitting delay of the targets behind the voluntary path ≤ 5 ms and RMS error
//! against it no worse than the classic filter's; input → setpoint median ≤ 15 ms and
//! 99th percentile ≤ 25 ms, in the board's time, on every run. And no step or jump:
//!
//! - **when the canceller starts** (the run engages with the tremor present): the first
//!   target is the board's setpoint the run started from; for 0.5 s the canceller,
//!   starting from zero weights, subtracts an estimate that grows towards the tremor, so
//!   the targets' deviation from the voluntary path stays within the tremor itself
//!   (`√2·A`: amplitude `A` on x, `0.8 A` on y, `0.6 A` on z) plus 2 µm, and no target
//!   moves further in one tick than the hand's own largest tick over that span;
//! - **when the tremor stops** (hand still): the canceller's output is the hand minus
//!   the estimate it still subtracts, a sinusoid of the tracked tremor's amplitude (at
//!   most `√2·A(t_stop)`). Its weights shrink as `w ← (I − 2μ1 x xᵀ) w + 2μ1 s x`: the
//!   matrix never lengthens `w` and on average over the phase shortens it by
//!   `1 − μ1 ≤ e^{−μ1}` per sample, and `s`, the high-pass's response to the tremor's
//!   end, decays at its slowest poles' rate `ζ ω_c` = 0.383 · 2π · 5 Hz = 12 /s, faster
//!   than the weights' `μ1 fs` = 10 /s. Two such decays in cascade stay under the
//!   critically damped `(1 + x) e^{−x}`, `x = μ1 fs (t − t_stop − 0.05 s)`: the setpoint
//!   stays within `√2·A(t_stop)·(1 + x)·e^{−x} + 2 µm` of where the hand means (0.05 s:
//!   the board's part of the lag; 2 µm: the residual before the stop and the f32
//!   setpoint);
//! - **when the clutch re-engages**: as in `chain_bench.rs`.

mod chain;
mod common;

use chain::{
    clutch_strokes, tremor_bound_m, tremor_stop_envelope_m, MasterPath, CLUTCH_AFTER_S,
    CLUTCH_FOLLOW_S, CLUTCH_HELD_S, FS, STILL_S, TREMOR_ON_S,
};
use common::{TestBoard, PRESENT};
use masters::latency::{lags, LagConfig, Stamped};
use masters::pose::rotate;
use masters::recording::EventKind;
use masters::synthetic::SyntheticOperator;
use masters::{
    CartesianPose, DeviceError, Master, MasterKind, MasterSample, OperatorButtons, TeleopConfig,
    TremorSuppression,
};
use nalgebra::Vector3;
use operator::conversions::setpoint_cp;
use operator::teleoperation::{run, RunReport, TeleoperationSettings};
use std::f64::consts::PI;
use std::sync::atomic::AtomicBool;

/// The part of the session the scripted runs play, s: it ends in a pause (11.4-11.9 s),
/// and its tremor's frequency drifts over 8.0-11.7 Hz.
const SESSION_S: f64 = 11.6;

/// What the hand does.
#[derive(Clone)]
struct Scenario {
    op: SyntheticOperator,
    /// The session's part played; the voluntary motion stays at its end after, s.
    session_s: f64,
    /// The tremor stop and the clutch scenario after the session.
    tail: bool,
}

impl Scenario {
    fn duration_s(&self) -> f64 {
        if self.tail {
            self.session_s
                + TREMOR_ON_S
                + STILL_S
                + CLUTCH_FOLLOW_S
                + CLUTCH_HELD_S
                + CLUTCH_AFTER_S
        } else {
            self.session_s
        }
    }

    /// When the tremor stops, s of the session (never without the tail).
    fn tremor_stop_s(&self) -> f64 {
        if self.tail {
            self.session_s + TREMOR_ON_S
        } else {
            f64::INFINITY
        }
    }

    /// Seconds into the clutch scenario at `ts` (negative before it).
    fn clutch_t(&self, ts: f64) -> f64 {
        ts - self.session_s - TREMOR_ON_S - STILL_S
    }

    /// The voluntary position (with the clutch scenario's strokes) and rotation, the
    /// tremor's position and rotation, and the buttons, at `ts` s of the session.
    #[allow(clippy::type_complexity)]
    fn at(
        &self,
        ts: f64,
    ) -> (
        Vector3<f64>,
        Vector3<f64>,
        Vector3<f64>,
        Vector3<f64>,
        OperatorButtons,
    ) {
        let (vp, vr) = self.op.voluntary(ts.min(self.session_s));
        let (tp, tr) = if ts < self.tremor_stop_s() {
            self.op.tremor(ts)
        } else {
            ([0.0; 3], [0.0; 3])
        };
        let after = self.clutch_t(ts);
        let extra = if self.tail && after > 0.0 {
            clutch_strokes(after)
        } else {
            Vector3::zeros()
        };
        let clutch =
            self.tail && after > CLUTCH_FOLLOW_S && after <= CLUTCH_FOLLOW_S + CLUTCH_HELD_S;
        (
            Vector3::from(vp) + extra,
            Vector3::from(vr),
            Vector3::from(tp),
            Vector3::from(tr),
            OperatorButtons { clutch, ..PRESENT },
        )
    }
}

/// The synthetic operator as a master: the hand at the board's time since the first poll,
/// through `path`.
struct Operator {
    scenario: Scenario,
    path: MasterPath,
    /// The board's time at the first poll: the session's zero.
    t0: Option<f64>,
}

impl Master for Operator {
    fn name(&self) -> &str {
        self.path.name()
    }
    fn kind(&self) -> MasterKind {
        match self.path {
            MasterPath::SpaceMouse { .. } => MasterKind::Rate,
            _ => MasterKind::Position,
        }
    }
    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        let t0 = *self.t0.get_or_insert(now_s);
        let (vp, vr, tp, tr, buttons) = self.scenario.at(now_s - t0);
        let hand = CartesianPose {
            position_m: vp + tp,
            orientation: rotate(&CartesianPose::identity().orientation, &(vr + tr)),
        };
        Ok(Some(self.path.sample(now_s, &hand, buttons)))
    }
}

/// One run's trace, in the session's time.
struct Played {
    scenario: Scenario,
    report: RunReport,
    /// The board's time at the session's zero, s.
    t0: f64,
    /// The board's setpoint the run started from.
    start: Vector3<f64>,
}

/// Waits, in the board's time, until five statuses in a row carry the same setpoint
/// (within 1 nm); fails after 2 s of the board's time with the setpoint still moving.
fn settle(board: &mut operator::Board) {
    let t0 = board.now_s();
    let end = t0 + 2.0;
    let mut seen = board.statuses_received();
    let (mut last, mut same, mut moved) = (None::<Vector3<f64>>, 0, 0.0f64);
    while board.now_s() < end {
        let next = board.now_s() + 0.01;
        board.poll_until(next).unwrap();
        if board.statuses_received() == seen {
            continue;
        }
        seen = board.statuses_received();
        let p = setpoint_cp(&board.status().unwrap().1).unwrap().position_m;
        match last {
            Some(l) if (p - l).norm() <= 1e-9 => same += 1,
            Some(l) => {
                moved = (p - l).norm();
                same = 0;
            }
            None => {}
        }
        if same >= 4 {
            eprintln!(
                "at rest after {:.3} s of the board's time (the last step before: {:.2} µm)",
                board.now_s() - t0,
                moved * 1e6
            );
            return;
        }
        last = Some(p);
    }
    panic!("the board's setpoint still moving after 2 s of its time (last step {moved} m)");
}

fn play(
    board: &mut operator::Board,
    scenario: &Scenario,
    path: MasterPath,
    tremor: TremorSuppression,
) -> Played {
    let mut master = Operator {
        scenario: scenario.clone(),
        path,
        t0: None,
    };
    let settings = TeleoperationSettings {
        teleop: TeleopConfig {
            tremor: Some(tremor),
            ..TeleopConfig::default()
        },
        duration_s: Some(scenario.duration_s() + if scenario.tail { 0.5 } else { 0.05 }),
        ..TeleoperationSettings::default()
    };
    // Each run starts from a robot at rest, as an operator's session does: after the run
    // before it, the board's setpoint may still be on its way to the last target, and a
    // mapping anchored at a moving setpoint anchors at the one its latest status carried.
    settle(board);
    // The setpoint the run starts from (`run` starts the mapping at the latest status's).
    let start = setpoint_cp(&board.status().unwrap().1).unwrap().position_m;
    let report = run(
        board,
        &mut master,
        &settings,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .unwrap();
    // A target the host held up beyond the board's staleness limit (50 ms behind the
    // fastest delay) is refused as stale: the board doing its job on a loaded host, which
    // the board's time cannot absorb (it waits for a master at most 50 ms). A few are
    // counted and reported; any other refusal, or more than 1 % of the targets, fails.
    let stale = report
        .targets_refused
        .get(board_words::reason(master_link::NackReason::StaleTarget))
        .copied()
        .unwrap_or(0);
    let others: u64 = report.targets_refused.values().sum::<u64>() - stale;
    eprintln!(
        "{}: {} targets sent, {stale} refused as stale",
        master.name(),
        report.targets_sent
    );
    assert!(
        others == 0 && stale * 100 <= report.targets_sent && report.device_errors == 0,
        "{}: targets refused {:?} of {}, device errors {}",
        master.name(),
        report.targets_refused,
        report.targets_sent,
        report.device_errors
    );
    Played {
        scenario: scenario.clone(),
        report,
        t0: master.t0.unwrap(),
        start,
    }
}

/// A target with its session time, the reference (the voluntary path since its
/// engagement, anchored as the mapping anchors: `robot0 + v − v0 − tr0`), and its
/// engagement's number (1 the first).
struct Target {
    ts: f64,
    t_sent: f64,
    t_input: f64,
    pose: Vector3<f64>,
    reference: Vector3<f64>,
    /// `pose − robot0 + v0 + tr0`: the target as the hand's voluntary motion.
    as_voluntary: Vector3<f64>,
    tremor: Vector3<f64>,
    tremor0: Vector3<f64>,
    engagement: usize,
}

fn targets(p: &Played) -> Vec<Target> {
    let engaged: Vec<f64> = p
        .report
        .trace
        .events
        .iter()
        .filter(|e| e.kind == EventKind::State && e.detail == "following")
        .map(|e| e.t_s)
        .collect();
    let mut out = Vec::new();
    let mut anchor: Option<(Vector3<f64>, Vector3<f64>, Vector3<f64>)> = None;
    let mut engagement = 0;
    for r in &p.report.trace.targets {
        let t_input = r.input_t_s.unwrap();
        let ts = t_input - p.t0;
        let (v, _, tr, _, _) = p.scenario.at(ts);
        if engaged.get(engagement).is_some_and(|&t| t <= t_input) {
            engagement += 1;
            anchor = Some((r.pose.position_m, v, tr));
        }
        let (robot0, v0, tr0) = anchor.expect("a target before the first engagement");
        out.push(Target {
            ts,
            t_sent: r.t_s,
            t_input,
            pose: r.pose.position_m,
            reference: robot0 + v - v0 - tr0,
            as_voluntary: r.pose.position_m - robot0 + v0 + tr0,
            tremor: tr,
            tremor0: tr0,
            engagement,
        });
    }
    out
}

fn setpoints(p: &Played) -> Vec<Stamped> {
    p.report
        .trace
        .reports
        .iter()
        .filter_map(|(t, s)| setpoint_cp(s).map(|c| (*t, c.position_m)))
        .collect()
}

/// Energy over [lo, hi] Hz of samples `x` at times `t` (s): the DFT at the samples' own
/// times (the ticks of the paced loop are 10 ms apart in the board's time only nearly).
fn band_energy(t: &[f64], x: &[f64], lo: f64, hi: f64) -> f64 {
    let span = t.len() as f64 / FS;
    ((lo * span).ceil() as usize..=(hi * span).floor() as usize)
        .map(|k| {
            let f = k as f64 / span;
            let (mut re, mut im) = (0.0, 0.0);
            for (ti, v) in t.iter().zip(x) {
                let ph = 2.0 * PI * f * ti;
                re += v * ph.cos();
                im -= v * ph.sin();
            }
            re * re + im * im
        })
        .sum()
}

/// Median and 99th percentile, s, and the count (NaN when nothing was matched).
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
    /// RMS error at zero delay over the session's first `until_s`, m.
    rms_m: f64,
    input_setpoint: (f64, f64, usize),
    /// The narrowest and the widest interval between two ticks, s.
    tick_span: (f64, f64),
}

/// The session part's figures; the RMS error over its first `rms_until_s`.
fn figures(p: &Played, what: &str, rms_until_s: f64) -> Figures {
    let all = targets(p);
    let session: Vec<&Target> = all
        .iter()
        .filter(|t| t.engagement == 1 && t.ts < p.scenario.session_s)
        .collect();
    let times: Vec<f64> = session.iter().map(|t| t.ts).collect();
    let (mut tre, mut res) = (0.0, 0.0);
    for c in 0..3 {
        let tr: Vec<f64> = session.iter().map(|t| t.tremor[c] - t.tremor0[c]).collect();
        let off: Vec<f64> = session.iter().map(|t| t.pose[c] - t.reference[c]).collect();
        tre += band_energy(&times, &tr, 8.0, 12.0);
        res += band_energy(&times, &off, 8.0, 12.0);
    }
    let att_db = 10.0 * (res / tre).log10();
    let op = &p.scenario.op;
    let rms = |tau: f64, until: f64| {
        let (s, n) = session
            .iter()
            .filter(|t| t.ts < until)
            .fold((0.0, 0usize), |(s, n), t| {
                let v = Vector3::from(op.voluntary(t.ts - tau).0);
                (s + (t.as_voluntary - v).norm_squared(), n + 1)
            });
        (s / n as f64).sqrt()
    };
    let mut best = (0.0, f64::INFINITY);
    for i in -200..=1200 {
        let tau = f64::from(i) * 1e-4;
        let e = rms(tau, f64::INFINITY);
        if e < best.1 {
            best = (tau, e);
        }
    }
    let cfg = LagConfig {
        window_s: 0.15,
        ..LagConfig::default()
    };
    let reference: Vec<Stamped> = all.iter().map(|t| (t.t_input, t.reference)).collect();
    let sent: Vec<Stamped> = all.iter().map(|t| (t.t_sent, t.pose)).collect();
    let sp = setpoints(p);
    let stage = |r: &[Stamped], f: &[Stamped]| median_p99(lags(r, f, &cfg));
    let (input_target, target_setpoint, input_setpoint) = (
        stage(&reference, &sent),
        stage(&sent, &sp),
        stage(&reference, &sp),
    );
    let ms = |(m, q, n): (f64, f64, usize)| format!("{:.1}/{:.1} ms ({n})", m * 1e3, q * 1e3);
    // How regular the loop's ticks were in the board's time.
    let gaps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let off = gaps
        .iter()
        .filter(|g| (**g - 1.0 / FS).abs() > 0.002)
        .count();
    let widest = gaps.iter().fold(0.0f64, |a, g| a.max(*g));
    let narrowest = gaps.iter().fold(f64::INFINITY, |a, g| a.min(*g));
    let f = Figures {
        att_db,
        delay_s: best.0,
        rms_m: rms(0.0, rms_until_s),
        input_setpoint,
        tick_span: (narrowest, widest),
    };
    eprintln!(
        "{what:<28} tremor {att_db:6.1} dB; delay {:5.1} ms; RMS {:6.1} µm (first {rms_until_s} s); median/p99: input->target {}, target->setpoint {}, input->setpoint {}",
        f.delay_s * 1e3,
        f.rms_m * 1e6,
        ms(input_target),
        ms(target_setpoint),
        ms(input_setpoint),
    );
    // The row of the README's table of the emulated board.
    eprintln!(
        "| {what} | {att_db:.1} dB | {:.1} ms | {:.1} µm | {:.1} / {:.1} ms |",
        f.delay_s * 1e3,
        f.rms_m * 1e6,
        f.input_setpoint.0 * 1e3,
        f.input_setpoint.1 * 1e3
    );
    eprintln!(
        "{what:<28} ticks: {off} of {} more than 2 ms off the period, {:.1} to {:.1} ms apart",
        gaps.len(),
        narrowest * 1e3,
        widest * 1e3
    );
    f
}

/// Records a failed check (all checks run, then the test fails with every failure).
macro_rules! ensure {
    ($fails:expr, $cond:expr, $($msg:tt)+) => {
        if $cond {
        } else {
            $fails.push(format!($($msg)+));
        }
    };
}

/// How far a tick may come off the stream's period in the board's time in lockstep, s:
/// the board's lead over the master's last reading (2 ms) and its step (1 ms).
const TICK_SLACK_S: f64 = 0.003;

/// The acceptance bounds on a canceller run against the classic filter's RMS error.
fn check_acceptance(
    what: &str,
    f: &Figures,
    classic_rms_m: f64,
    min_lags: usize,
    fails: &mut Vec<String>,
) {
    // In lockstep the loop keeps its period in the board's time: a tick is sent when the
    // board's clock reaches it, and the board runs at most 2 ms beyond the master's last
    // reading, read at least every 0.5 ms while the master waits, plus its 1 ms step.
    let (narrowest, widest) = f.tick_span;
    ensure!(
        fails,
        narrowest >= 1.0 / FS - TICK_SLACK_S && widest <= 1.0 / FS + TICK_SLACK_S,
        "{what}: ticks {narrowest} to {widest} s apart in the board's time, beyond the lockstep's {TICK_SLACK_S} s"
    );
    ensure!(
        fails,
        f.att_db <= -20.0,
        "{what}: attenuation {} dB",
        f.att_db
    );
    ensure!(
        fails,
        f.delay_s.abs() <= 0.005,
        "{what}: delay {} s",
        f.delay_s
    );
    ensure!(
        fails,
        f.rms_m <= classic_rms_m,
        "{what}: RMS {} m against the classic filter's {classic_rms_m} m",
        f.rms_m
    );
    let (med, p99, n) = f.input_setpoint;
    ensure!(fails, n >= min_lags, "{what}: only {n} lags matched");
    ensure!(
        fails,
        med <= 0.015,
        "{what}: input -> setpoint median {med} s"
    );
    ensure!(fails, p99 <= 0.025, "{what}: input -> setpoint p99 {p99} s");
}

/// No step when the canceller starts: the first target is the setpoint the run started
/// from; for 0.5 s the targets stay within the tremor's bound of the voluntary path and
/// move no further in one tick than the hand's largest tick.
fn check_start(what: &str, p: &Played, fails: &mut Vec<String>) {
    let all = targets(p);
    // The setpoint the mapping held at: the run's start, or the last status before the
    // first tick (it re-anchors while holding).
    let start = p
        .report
        .trace
        .reports
        .iter()
        .rev()
        .find(|(t, _)| *t <= all.first().unwrap().t_input)
        .and_then(|(_, r)| setpoint_cp(r))
        .map_or(p.start, |c| c.position_m);
    let first = all.first().unwrap();
    ensure!(
        fails,
        (first.pose - start).norm() <= 1e-9,
        "{what}: the first target {} m from the setpoint",
        (first.pose - start).norm()
    );
    let early: Vec<&Target> = all.iter().filter(|t| t.ts < 0.5).collect();
    let (mut dev, mut step, mut hand_step) = (0.0f64, 0.0f64, 0.0f64);
    for w in early.windows(2) {
        let hand = |t: &Target| {
            let (v, _, tr, _, _) = p.scenario.at(t.ts);
            v + tr
        };
        hand_step = hand_step.max((hand(w[1]) - hand(w[0])).norm());
        step = step.max((w[1].pose - w[0].pose).norm());
    }
    for t in &early {
        let excess = (t.pose - t.reference).norm() - tremor_bound_m(t.ts);
        dev = dev.max(excess);
    }
    eprintln!(
        "{what:<28} start: first target {:.2e} m from the setpoint; largest tick {:.1} µm (the hand's {:.1} µm); deviation beyond the tremor's bound {:.1} µm",
        (first.pose - start).norm(),
        step * 1e6,
        hand_step * 1e6,
        dev * 1e6
    );
    ensure!(
        fails,
        step <= hand_step,
        "{what}: a tick of {step} m at the start, the hand's {hand_step} m"
    );
    ensure!(
        fails,
        dev <= 2e-6,
        "{what}: {dev} m beyond the tremor's bound at the start"
    );
}

/// No jump when the tremor stops (hand still): the setpoint within the decaying bound.
fn check_tremor_stop(p: &Played, fails: &mut Vec<String>) {
    let all = targets(p);
    let s = &p.scenario;
    let t_stop = p.t0 + s.tremor_stop_s();
    let t_end = p.t0 + s.tremor_stop_s() + STILL_S;
    // The reference is still: the last target's reference before the stop.
    let reference = all
        .iter()
        .rev()
        .find(|t| t.ts >= s.session_s && t.t_input < t_stop)
        .unwrap()
        .reference;
    let a = tremor_bound_m(s.tremor_stop_s());
    let (mut worst, mut largest, mut last) = (f64::NEG_INFINITY, 0.0f64, 0.0);
    let mut n = 0;
    for (t, sp) in setpoints(p)
        .iter()
        .filter(|(t, _)| *t >= t_stop && *t < t_end)
    {
        let dev = (sp - reference).norm();
        let bound = tremor_stop_envelope_m(a, t - t_stop);
        worst = worst.max(dev - bound);
        largest = largest.max(dev);
        last = dev;
        n += 1;
    }
    eprintln!(
        "tremor stops (A {:.1} µm, bound {:.1} µm): the setpoint at most {:.1} µm from the still reference, {:.2} µm at the end ({n} statuses); closest to the bound {:.1} µm",
        a / 2f64.sqrt() * 1e6,
        a * 1e6,
        largest * 1e6,
        last * 1e6,
        -worst * 1e6,
    );
    ensure!(fails, n >= 40, "only {n} statuses after the tremor stopped");
    ensure!(
        fails,
        worst <= 0.0,
        "the setpoint {worst} m beyond the bound after the tremor stopped"
    );
}

/// The clutch through the board, as in `chain_bench.rs`.
fn check_clutch(p: &Played, fails: &mut Vec<String>) {
    let all = targets(p);
    let s = &p.scenario;
    let clutch_t = |t_board: f64| s.clutch_t(t_board - p.t0);
    let reports = &p.report.trace.reports;
    let second = all
        .iter()
        .find(|t| t.engagement == 2)
        .expect("no re-engagement");
    ensure!(
        fails,
        all.iter().all(|t| t.engagement <= 2),
        "more than one re-engagement"
    );
    // The setpoint the mapping held at: the last status before the re-engaging tick.
    let held = reports
        .iter()
        .rev()
        .find(|(t, _)| *t <= second.t_input)
        .and_then(|(_, r)| setpoint_cp(r))
        .unwrap()
        .position_m;
    let during: Vec<Vector3<f64>> = reports
        .iter()
        .filter(|(t, _)| {
            let c = clutch_t(*t);
            c > CLUTCH_FOLLOW_S + 0.3 && c <= CLUTCH_FOLLOW_S + CLUTCH_HELD_S
        })
        .filter_map(|(_, r)| setpoint_cp(r).map(|c| c.position_m))
        .collect();
    let lo = during
        .iter()
        .fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = during
        .iter()
        .fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
    let spread = (hi - lo).norm();
    let last_ref = all.last().unwrap().reference;
    let end = setpoint_cp(&reports.last().unwrap().1).unwrap().position_m;
    let end_error = (end - last_ref).norm();
    eprintln!(
        "clutch: re-engaged {:.3} µm from the held setpoint; setpoint spread while held {:.3} µm ({} statuses); settled {:.1} µm from the reference",
        (second.pose - held).norm() * 1e6,
        spread * 1e6,
        during.len(),
        end_error * 1e6
    );
    ensure!(
        fails,
        (second.pose - held).norm() <= 1e-9,
        "a jump on re-engaging"
    );
    ensure!(
        fails,
        during.len() >= 20,
        "only {} statuses while held",
        during.len()
    );
    ensure!(
        fails,
        spread <= 1e-6,
        "the setpoint moved {spread} m while clutched"
    );
    ensure!(
        fails,
        end_error <= 50e-6,
        "ended {end_error} m from the reference"
    );
}

/// The chain on the board at `RSPR_BOARD_SOCKET` (or a simulated one): each master path
/// with the canceller against the classic filter, the canceller's start, the tremor's
/// stop and the clutch.
#[test]
#[ignore = "about 28 s of the board's time: run by against-emulator.sh, or with --ignored"]
fn chain_on_the_served_board() {
    let board = TestBoard::start();
    let mut b = board.enabled();
    assert!(
        b.on_board_time(),
        "the board at {} does not share its clock (board-emulator serve --clock-lead-ms): the figures would be the host's time, not the board's",
        board.socket.display()
    );
    let op = SyntheticOperator::surgical();
    let plain = Scenario {
        op: op.clone(),
        session_s: SESSION_S,
        tail: false,
    };
    let classic = play(
        &mut b,
        &plain,
        MasterPath::Scripted,
        TremorSuppression::classic(),
    );
    let canceller = TremorSuppression::Canceller(Default::default());
    let with_tail = Scenario {
        tail: true,
        ..plain.clone()
    };
    let new = play(&mut b, &with_tail, MasterPath::Scripted, canceller);
    drop(b);

    let fc = figures(&classic, "scripted, classic filter", SESSION_S);
    let mut fails = Vec::new();
    let f = figures(&new, "scripted, canceller", SESSION_S);
    check_acceptance("scripted", &f, fc.rms_m, 300, &mut fails);
    check_start("scripted", &new, &mut fails);
    check_tremor_stop(&new, &mut fails);
    check_clutch(&new, &mut fails);
    assert!(fails.is_empty(), "failed:\n{}", fails.join("\n"));
}
