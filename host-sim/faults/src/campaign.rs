//! One cell of the campaign: a fault kind injected in a condition, against the whole board
//! application in simulation ([`simulation::board`]) driven over the wire protocol by the
//! in-process master ([`simulation::bench`]), with what the board noticed, when, how it
//! reacted and how far the platform moved afterwards.

use control::modes::ModeKind;
use control::stops::StopCategory;
use control::ToolLoad;
use master_link::{BoardToMaster, FaultCause, MasterToBoard, ResetCause, RobotState, StopStatus};
use nalgebra::Vector3;
use simulation::bench::{Bench, BenchError};
use simulation::board::{BoardSim, BoardSimConfig, BoardSimError};
use thiserror::Error;

use crate::kinds::{Detection, Expectation, FaultKind, Only, Reaction};

/// Why a cell could not be run (not a fault of the board: a failure of the set-up).
#[derive(Debug, Error)]
pub enum CampaignError {
    #[error("{kind} in {condition}: {source}")]
    Bench {
        kind: &'static str,
        condition: &'static str,
        source: BenchError,
    },
    #[error("{kind} in {condition}: {source}")]
    Board {
        kind: &'static str,
        condition: &'static str,
        source: BoardSimError,
    },
}

/// What the robot does when the fault strikes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Condition {
    /// Enabled, holding still (the master streams the same pose).
    Holding,
    /// Following a stream at 2.5 mm/s.
    Slow,
    /// Following a stream at 25 mm/s (the task's top speed).
    Fast,
    /// Holding still with the thesis's tool attached (1.2 kg on a 0.1 m lever).
    Tool,
    /// The kind's own phase (homing, enabling): the running conditions do not apply.
    Phase,
}

impl Condition {
    /// The running conditions, in the matrix's order.
    pub const RUNNING: [Condition; 4] = [
        Condition::Holding,
        Condition::Slow,
        Condition::Fast,
        Condition::Tool,
    ];

    /// The condition's name (the matrix's columns).
    pub const fn name(self) -> &'static str {
        match self {
            Condition::Holding => "holding",
            Condition::Slow => "slow",
            Condition::Fast => "fast",
            Condition::Tool => "tool",
            Condition::Phase => "phase",
        }
    }

    /// The condition of a name.
    pub fn from_name(name: &str) -> Option<Condition> {
        Condition::RUNNING
            .into_iter()
            .chain([Condition::Phase])
            .find(|c| c.name() == name)
    }

    /// The speed of the streamed motion, m/s.
    fn speed(self) -> f64 {
        match self {
            Condition::Slow => 0.0025,
            Condition::Fast => 0.025,
            _ => 0.0,
        }
    }
}

/// The result of one cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// The fault kind.
    pub kind: FaultKind,
    /// The condition.
    pub condition: Condition,
    /// The board noticed it.
    pub detected: bool,
    /// Time to notice, ms (from the injection, or from the probe move for a fault that
    /// only shows in motion).
    pub detect_ms: Option<f64>,
    /// The bound, ms.
    pub bound_ms: u64,
    /// What was noticed: the fault (cause, joint, value) or the refusal or the counters.
    pub noticed: String,
    /// The expected reaction.
    pub expected: Reaction,
    /// The reaction seen 30 ms after the detection (the stop in force).
    pub reaction: Reaction,
    /// The stop in force at the end of the cell.
    pub final_stop: StopStatus,
    /// How far the platform moved after the detection (largest displacement of o_p; into
    /// the wall for the wall), mm; when the board continues, the largest distance from the
    /// setpoint after the detection.
    pub moved_mm: f64,
    /// How far it was allowed to move, mm: 0.5 after an STO, the setpoint's own braking
    /// travel + 0.1 after an SS1/SS2, the tracking limit (1 mm from the setpoint) when
    /// it continues.
    pub allowed_mm: f64,
    /// The largest distance between the true platform and the setpoint from the injection
    /// to the end, mm (what the fault did before and after it was noticed).
    pub deviation_mm: f64,
    /// Every fault the board logged from the injection on (cause@time joint value).
    pub logged: String,
    /// The platform's speed at the injection, mm/s.
    pub speed_mm_s: f64,
    /// The verdict.
    pub pass: bool,
    /// Why it failed, if it did.
    pub why: String,
}

/// Milliseconds the cell runs after the injection (or after the probe starts).
const AFTER_MS: u64 = 900;
/// Milliseconds the stream runs before the injection: slow, 0.6 s (2.2 mm/s); fast, one
/// period of the sinusoid (1.51 s) plus the supervisor's lag: the platform at its peak
/// speed, 25 mm/s.
fn before_ms(condition: Condition) -> u64 {
    match condition {
        Condition::Fast => 1_580,
        _ => 600,
    }
}
/// The probe move of a fault that only shows in motion: starts 100 ms after the
/// injection, +x at 2.5 mm/s.
const PROBE_DELAY_MS: u64 = 100;
const PROBE_SPEED: f64 = 0.0025;

/// The master's stream: a sinusoid along x about the park pose, amplitude 6 mm (fast) or
/// 3 mm (slow), peak speed the condition's; a probe move along +x from its start.
#[derive(Clone, Copy, Debug)]
struct Stream {
    centre: Vector3<f64>,
    speed: f64,
    amplitude: f64,
    t0_us: u64,
    probe_from_us: Option<u64>,
    /// The probe is a step of this many metres (else a drift).
    probe_step_m: Option<f64>,
}

impl Stream {
    fn position(&self, t_us: u64) -> Vector3<f64> {
        let t = t_us.saturating_sub(self.t0_us) as f64 * 1e-6;
        let mut p = self.centre;
        if self.speed > 0.0 {
            let w = self.speed / self.amplitude;
            p.x += self.amplitude * (w * t).sin();
        }
        if let Some(from) = self.probe_from_us {
            match self.probe_step_m {
                Some(step) if t_us >= from => p.x += step,
                Some(_) => {}
                None => p.x += PROBE_SPEED * t_us.saturating_sub(from) as f64 * 1e-6,
            }
        }
        p
    }
}

fn category_of(stop: StopStatus) -> Reaction {
    match stop {
        StopStatus::None => Reaction::Continue,
        StopStatus::SafeTorqueOff => Reaction::Stop(StopCategory::Sto),
        StopStatus::SafeStop1Decelerating
        | StopStatus::SafeStop1Braking
        | StopStatus::SafeStop1Done => Reaction::Stop(StopCategory::Ss1),
        StopStatus::SafeStop2Decelerating | StopStatus::SafeOperatingStop => {
            Reaction::Stop(StopCategory::Ss2)
        }
    }
}

/// The setpoint's position (the supervisor's), if the controller runs.
fn setpoint(b: &Bench) -> Option<Vector3<f64>> {
    b.board
        .runtime()
        .controller()
        .map(|c| c.supervisor().setpoint().t)
}

/// Runs one cell.
pub fn run_cell(kind: FaultKind, condition: Condition) -> Result<Cell, CampaignError> {
    let ctx = |source| CampaignError::Bench {
        kind: kind.name(),
        condition: condition.name(),
        source,
    };
    let cfg = BoardSimConfig::reference(None).map_err(|source| CampaignError::Board {
        kind: kind.name(),
        condition: condition.name(),
        source,
    })?;
    let board =
        BoardSim::new(cfg, ResetCause::PowerOn, None).map_err(|source| CampaignError::Board {
            kind: kind.name(),
            condition: condition.name(),
            source,
        })?;
    let mut b = Bench::new(board, 0xC0FF_EE00);
    let exp = kind.expectation();
    match exp.only {
        Some(only) => phase_cell(kind, &mut b, only).map_err(ctx),
        None => running_cell(kind, condition, &mut b).map_err(ctx),
    }
}

/// What the detector has seen so far.
struct Detector {
    /// The frame whose reply tells the detection.
    seq: Option<u16>,
    detection: Detection,
    log_len: usize,
    rejected: u32,
    frames_ok: u32,
}

impl Detector {
    fn new(b: &Bench, detection: Detection, seq: Option<u16>) -> Self {
        let c = b.board.link_rx().counters();
        Detector {
            detection,
            seq,
            log_len: b.board.runtime().fault_log().len(),
            rejected: c.rejected(),
            frames_ok: c.frames_ok,
        }
    }

    /// Every fault logged since the detector's baseline, as text.
    fn logged(&self, b: &Bench) -> String {
        let log = b.board.runtime().fault_log();
        (self.log_len..log.len())
            .filter_map(|i| log.get(i))
            .map(|e| {
                format!(
                    "{:?}@{}ms j{} {}",
                    e.record.cause, e.record.time_ms, e.record.joint, e.record.value
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The joint of the newest logged fault, if it names one.
    fn joint_of_last(&self, b: &Bench) -> Option<usize> {
        let r = b.board.runtime().fault_log().newest()?.record;
        (r.joint != master_link::NO_JOINT).then_some(usize::from(r.joint))
    }

    /// What is noticed now, if anything.
    fn check(&self, b: &Bench) -> Option<String> {
        match self.detection {
            Detection::Cause(causes, joint) => {
                let log = b.board.runtime().fault_log();
                (self.log_len..log.len()).find_map(|i| {
                    let e = log.get(i)?;
                    let r = e.record;
                    let joint_ok = joint.is_none_or(|j| j == r.joint);
                    (causes.contains(&r.cause) && joint_ok)
                        .then(|| format!("{:?} joint {} value {}", r.cause, r.joint, r.value))
                })
            }
            Detection::Nack(reasons) => {
                let (_, reply) = b.master.replies.get(&self.seq?)?;
                match reply {
                    BoardToMaster::Nack { reason, .. } if reasons.contains(reason) => {
                        Some(format!("Nack {reason:?}"))
                    }
                    _ => None,
                }
            }
            Detection::Counted => {
                let c = b.board.link_rx().counters();
                (c.rejected() > self.rejected).then(|| {
                    format!(
                        "counted: rejected +{} (malformed +{}, bad checksum +{}, out of order +{}), frames ok +{}",
                        c.rejected() - self.rejected,
                        c.malformed,
                        c.bad_checksum,
                        c.out_of_order,
                        c.frames_ok - self.frames_ok
                    )
                })
            }
            Detection::HeartbeatHold => {
                let rt = b.board.runtime();
                let hold = (rt.mode().kind() == ModeKind::Holding && rt.session().hold().heartbeat)
                    || rt.state() == RobotState::Fault;
                hold.then(|| "heartbeat late: hold".to_string())
            }
        }
    }
}

/// The master's target at the bench's time, from `stream`.
fn send_target(b: &mut Bench, stream: &Stream) {
    let t = b.now_us();
    let p = stream.position(t);
    b.send(&MasterToBoard::PoseTarget {
        timestamp_us: t,
        position_m: [p.x as f32, p.y as f32, p.z as f32],
        rotation_vector_rad: [0.0; 3],
    });
}

/// Brings the board up in `condition` (the tool attached for [`Condition::Tool`]) and
/// streams until the injection is due; the stream, to go on with.
fn lead_in(condition: Condition, exp: &Expectation, b: &mut Bench) -> Result<Stream, BenchError> {
    b.bring_up()?;
    if condition == Condition::Tool {
        b.board.set_tool(Some(ToolLoad::thesis()));
        b.run_ms(300)?;
    }
    let centre = setpoint(b).unwrap_or_else(|| b.board.truth().pose.t);
    let amplitude = if condition == Condition::Fast {
        0.006
    } else {
        0.003
    };
    let stream = Stream {
        centre,
        speed: condition.speed(),
        amplitude,
        t0_us: b.now_us(),
        probe_from_us: None,
        probe_step_m: exp.probe_step_mm.map(|mm| mm * 1e-3),
    };
    for k in 0..before_ms(condition) {
        if k % 10 == 0 {
            send_target(b, &stream);
        }
        b.tick()?;
    }
    Ok(stream)
}

/// What a running cell sees tick by tick after the injection.
struct Watch {
    /// When the detector noticed the fault, and what.
    detected: Option<(u64, String)>,
    /// The wall: when each joint's current last came up to 90 % of its peak and stayed.
    at_limit_from: [Option<u64>; 6],
    /// That time for the joint of the fault detected.
    overload_from: Option<u64>,
    /// When the fault showed in its joint's current ([`Expectation::shows_at_current`]).
    shows_at: Option<u64>,
    /// The largest distance of the platform from the setpoint since the injection, m.
    after_injection: f64,
    /// The platform's position and the setpoint at the detection.
    at_detect: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The stop in force 30 ms after the detection.
    reaction: Reaction,
    /// Since the detection, m: the platform's largest displacement (into the wall, against
    /// the wall), the setpoint's travel, the largest distance between the two.
    moved: f64,
    sp_travel: f64,
    deviation: f64,
    /// The setpoint while the controller runs, the last one after.
    last_sp: Option<Vector3<f64>>,
}

impl Watch {
    fn new(b: &Bench) -> Self {
        Watch {
            detected: None,
            at_limit_from: [None; 6],
            overload_from: None,
            shows_at: None,
            after_injection: 0.0,
            at_detect: None,
            reaction: Reaction::Continue,
            moved: 0.0,
            sp_travel: 0.0,
            deviation: 0.0,
            last_sp: setpoint(b),
        }
    }

    /// Takes in the tick that just ran.
    fn tick(&mut self, b: &Bench, det: &Detector, exp: &Expectation) {
        let now = b.now_us();
        if let Some(sp) = setpoint(b) {
            self.last_sp = Some(sp);
        }
        self.currents(b, exp, now);
        if let Some(sp) = self.last_sp {
            self.after_injection = self
                .after_injection
                .max((b.board.truth().pose.t - sp).norm());
        }
        if self.detected.is_none() {
            if let Some(what) = det.check(b) {
                self.detected = Some((now, what));
                let p = b.board.truth().pose.t;
                self.at_detect = Some((p, self.last_sp.unwrap_or(p)));
                if let Some(j) = det.joint_of_last(b) {
                    self.overload_from = self.at_limit_from.get(j).copied().flatten();
                }
            }
        }
        self.after_detection(b, now);
    }

    /// The joints' currents: which sit at their limit since when, and when the fault
    /// showed in its joint's.
    fn currents(&mut self, b: &Bench, exp: &Expectation, now: u64) {
        let rt = b.board.runtime();
        let currents = rt.inputs().currents;
        for (j, from) in self.at_limit_from.iter_mut().enumerate() {
            let at = currents[j].abs() >= 0.9 * rt.monitors().current.peak_current(j);
            *from = match (*from, at) {
                (None, true) => Some(now),
                (f, true) => f,
                (_, false) => None,
            };
        }
        if let (None, Some((j, frac))) = (self.shows_at, exp.shows_at_current) {
            if currents[j].abs() > frac * rt.monitors().current.peak_current(j) {
                self.shows_at = Some(now);
            }
        }
    }

    /// Once detected: how far the platform and the setpoint went, and the stop in force
    /// 30 ms after.
    fn after_detection(&mut self, b: &Bench, now: u64) {
        let (Some((t_det, _)), Some((p0, sp0))) = (&self.detected, &self.at_detect) else {
            return;
        };
        let p = b.board.truth().pose.t;
        // Against the wall, what counts is the motion further into it (the wall's own
        // spring pushes the platform back out once the torque is off).
        let d = match b.board.config().wall {
            Some(w) => (p - p0).dot(&-w.normal).max(0.0),
            None => (p - p0).norm(),
        };
        self.moved = self.moved.max(d);
        let sp = self.last_sp.unwrap_or(*sp0);
        self.sp_travel = self.sp_travel.max((sp - sp0).norm());
        self.deviation = self.deviation.max((p - sp).norm());
        if now == *t_det + 30_000 {
            self.reaction = category_of(b.board.runtime().status().stop);
        }
    }

    /// The time to detect, ms: from when the fault showed (the wall: the sustained
    /// overload of the tripping joint; a latent fault: its current), else from `t_ref`
    /// (the probe's start or the injection), or from the injection `t_inj` when noticed
    /// before that.
    fn detect_ms(&self, kind: FaultKind, t_inj: u64, t_ref: u64) -> Option<f64> {
        let t_ref = if kind == FaultKind::WallContact {
            self.overload_from.unwrap_or(t_ref)
        } else if let Some(t) = self.shows_at {
            t
        } else {
            t_ref
        };
        // Noticed before the probe started: timed from the injection.
        let t_ref = match &self.detected {
            Some((t, _)) if *t < t_ref => t_inj,
            _ => t_ref,
        };
        self.detected
            .as_ref()
            .map(|(t, _)| t.saturating_sub(t_ref) as f64 * 1e-3)
    }
}

/// A cell in one of the running conditions.
fn running_cell(kind: FaultKind, condition: Condition, b: &mut Bench) -> Result<Cell, BenchError> {
    let exp = kind.expectation();
    let mut stream = lead_in(condition, &exp, b)?;
    // The detector's baseline before the injection: a frame may be counted as it arrives.
    let mut det = Detector::new(b, exp.detection, None);
    let t_inj = b.now_us();
    det.seq = kind.inject(b);
    let speed_at_injection = b.board.truth().velocity.norm();
    // A fault that only shows while its joint works is probed by a small move in the
    // conditions where the joint may not work at all (holding, or moving slowly).
    let holding = matches!(
        condition,
        Condition::Holding | Condition::Tool | Condition::Slow
    );
    let t_ref = if exp.needs_motion && holding {
        stream.probe_from_us = Some(t_inj + PROBE_DELAY_MS * 1000);
        t_inj + PROBE_DELAY_MS * 1000
    } else {
        t_inj
    };
    let mut watch = Watch::new(b);
    let end = t_ref + AFTER_MS * 1000;
    let mut k = 0u64;
    while b.now_us() < end {
        if k.is_multiple_of(10) {
            send_target(b, &stream);
        }
        k += 1;
        b.tick()?;
        watch.tick(b, &det, &exp);
    }
    let allowed = match exp.reaction {
        Reaction::Stop(StopCategory::Sto) => 0.5,
        Reaction::Stop(_) => watch.sp_travel * 1e3 + 0.1,
        Reaction::Continue => 1.0,
    };
    let shown = if exp.reaction == Reaction::Continue {
        watch.deviation * 1e3
    } else {
        watch.moved * 1e3
    };
    Ok(verdict(Verdict {
        kind,
        condition,
        detect_ms: watch.detect_ms(kind, t_inj, t_ref),
        detected: watch.detected,
        reaction: watch.reaction,
        final_stop: b.board.runtime().status().stop,
        shown_mm: shown,
        allowed_mm: allowed,
        still_enabled: b.board.runtime().state() == RobotState::Enabled,
        deviation_mm: watch.after_injection * 1e3,
        logged: det.logged(b),
        speed_mm_s: speed_at_injection * 1e3,
    }))
}

/// A cell of a kind with its own phase (homing, enabling).
fn phase_cell(kind: FaultKind, b: &mut Bench, only: Only) -> Result<Cell, BenchError> {
    let exp = kind.expectation();
    let hello = b.hello_msg();
    b.request(&hello, 100)?;
    let t_inj;
    let det;
    match only {
        Only::Homing => {
            kind.inject(b);
            t_inj = b.now_us();
            det = Detector::new(b, exp.detection, None);
            b.command(&MasterToBoard::Home { rehome: false })?;
        }
        Only::Enabling => {
            b.command(&MasterToBoard::Home { rehome: false })?;
            b.run_until("homed", 120_000, |s| {
                s.runtime().state() != RobotState::Homing
            })?;
            b.run_ms(100)?;
            for j in 0..6 {
                let _ = b
                    .board
                    .hw
                    .plant
                    .inject(j, plant::Fault::BrakeWorn { holding_ratio: 0.0 });
            }
            t_inj = b.now_us();
            det = Detector::new(b, exp.detection, None);
            b.command(&MasterToBoard::OperatorPresent { present: true })?;
            b.command(&MasterToBoard::Enable)?;
        }
    }
    let mut detected = None;
    let mut at_detect = None;
    let mut reaction = Reaction::Continue;
    let mut moved = 0.0f64;
    let end = t_inj + (exp.bound_ms + AFTER_MS) * 1000;
    while b.now_us() < end {
        b.tick()?;
        let now = b.now_us();
        if detected.is_none() {
            if let Some(what) = det.check(b) {
                detected = Some((now, what));
                at_detect = Some(b.board.truth().pose.t);
            }
        }
        if let (Some((t_det, _)), Some(p0)) = (&detected, &at_detect) {
            moved = moved.max((b.board.truth().pose.t - p0).norm());
            if now == *t_det + 30_000 {
                reaction = category_of(b.board.runtime().status().stop);
            }
        }
    }
    let detect_ms = detected
        .as_ref()
        .map(|(t, _): &(u64, String)| t.saturating_sub(t_inj) as f64 * 1e-3);
    let allowed = match exp.reaction {
        Reaction::Stop(StopCategory::Sto) => 0.5,
        _ => 0.1,
    };
    Ok(verdict(Verdict {
        kind,
        condition: Condition::Phase,
        detected,
        detect_ms,
        reaction,
        final_stop: b.board.runtime().status().stop,
        shown_mm: moved * 1e3,
        allowed_mm: allowed,
        still_enabled: false,
        deviation_mm: moved * 1e3,
        logged: det.logged(b),
        speed_mm_s: 0.0,
    }))
}

struct Verdict {
    kind: FaultKind,
    condition: Condition,
    detected: Option<(u64, String)>,
    detect_ms: Option<f64>,
    reaction: Reaction,
    final_stop: StopStatus,
    shown_mm: f64,
    allowed_mm: f64,
    still_enabled: bool,
    deviation_mm: f64,
    logged: String,
    speed_mm_s: f64,
}

fn verdict(v: Verdict) -> Cell {
    let exp = v.kind.expectation();
    let mut why = Vec::new();
    if v.detected.is_none() {
        why.push("not detected".to_string());
    }
    if let Some(ms) = v.detect_ms {
        if ms > exp.bound_ms as f64 {
            why.push(format!("late: {ms:.0} ms > {} ms", exp.bound_ms));
        }
    }
    if v.detected.is_some() && v.reaction != exp.reaction {
        why.push(format!(
            "reaction {} instead of {}",
            v.reaction.name(),
            exp.reaction.name()
        ));
    }
    if exp.reaction == Reaction::Continue && v.detected.is_some() && !v.still_enabled {
        why.push("left Enabled".into());
    }
    // (A NaN figure fails too.)
    if v.shown_mm.partial_cmp(&v.allowed_mm) != Some(std::cmp::Ordering::Less)
        && v.shown_mm != v.allowed_mm
    {
        why.push(format!(
            "moved {:.3} mm > {:.3} mm",
            v.shown_mm, v.allowed_mm
        ));
    }
    Cell {
        kind: v.kind,
        condition: v.condition,
        detected: v.detected.is_some(),
        detect_ms: v.detect_ms,
        bound_ms: exp.bound_ms,
        noticed: v.detected.map(|(_, w)| w).unwrap_or_default(),
        expected: exp.reaction,
        reaction: v.reaction,
        final_stop: v.final_stop,
        moved_mm: v.shown_mm,
        allowed_mm: v.allowed_mm,
        deviation_mm: v.deviation_mm,
        logged: v.logged,
        speed_mm_s: v.speed_mm_s,
        pass: why.is_empty(),
        why: why.join("; "),
    }
}

/// The cells of `kinds` x `conditions` (a kind with its own phase runs once, in it).
pub fn cells(kinds: &[FaultKind], conditions: &[Condition]) -> Vec<(FaultKind, Condition)> {
    let mut out = Vec::new();
    for k in kinds {
        if k.expectation().only.is_some() {
            if conditions.contains(&Condition::Phase)
                || conditions.len() == Condition::RUNNING.len()
            {
                out.push((*k, Condition::Phase));
            }
        } else {
            for c in conditions {
                if *c != Condition::Phase {
                    out.push((*k, *c));
                }
            }
        }
    }
    out
}

/// `FaultCause` is re-exported for the matrix's readers.
pub type Cause = FaultCause;
