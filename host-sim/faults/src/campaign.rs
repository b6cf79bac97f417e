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
use control::safety::Requirement;

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
    /// Homing: 1.5 s after `Home` (the first leg searching its switch); the kinds of the
    /// homing (a dead home switch) from its start.
    Homing,
    /// The brake check at the enable: 20 ms after `Enable`; worn brakes from before it.
    BrakeCheck,
    /// A safe operating stop (the clutch engaged) with the tool attached and a push of
    /// 10 N along +x (a wall pressing 0.1 mm into the platform).
    HeldTool,
    /// 20 ms into the SS1 of a `Disable` from 25 mm/s.
    DuringSs1,
    /// 20 ms into the SS2 of the clutch engaged at 25 mm/s.
    DuringSs2,
    /// The first tick enabled (the brakes just released).
    AfterEnable,
    /// Following at 2.5 mm/s, the kind and its partner ([`partner`]) at the same instant.
    Double,
}

impl Condition {
    /// The running conditions, in the matrix's order.
    pub const RUNNING: [Condition; 4] = [
        Condition::Holding,
        Condition::Slow,
        Condition::Fast,
        Condition::Tool,
    ];

    /// Every condition, in the matrix's order.
    pub const ALL: [Condition; 11] = [
        Condition::Holding,
        Condition::Slow,
        Condition::Fast,
        Condition::Tool,
        Condition::Homing,
        Condition::BrakeCheck,
        Condition::HeldTool,
        Condition::DuringSs1,
        Condition::DuringSs2,
        Condition::AfterEnable,
        Condition::Double,
    ];

    /// The condition's name (the matrix's columns).
    pub const fn name(self) -> &'static str {
        match self {
            Condition::Holding => "holding",
            Condition::Slow => "slow",
            Condition::Fast => "fast",
            Condition::Tool => "tool",
            Condition::Homing => "homing",
            Condition::BrakeCheck => "brake-check",
            Condition::HeldTool => "held-tool-push",
            Condition::DuringSs1 => "during-ss1",
            Condition::DuringSs2 => "during-ss2",
            Condition::AfterEnable => "after-enable",
            Condition::Double => "double",
        }
    }

    /// The condition of a name.
    pub fn from_name(name: &str) -> Option<Condition> {
        Condition::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The speed of the streamed motion, m/s.
    fn speed(self) -> f64 {
        match self {
            Condition::Slow | Condition::Double => 0.0025,
            Condition::Fast | Condition::DuringSs1 | Condition::DuringSs2 => 0.025,
            _ => 0.0,
        }
    }

    /// The stop the condition itself has in force when the fault strikes (0: none, SS2 1,
    /// SS1 2): a fault's stop may only add to it.
    fn own_stop(self) -> u8 {
        match self {
            Condition::HeldTool | Condition::DuringSs2 => 1,
            Condition::DuringSs1 => 2,
            _ => 0,
        }
    }

    /// The requirements a cell of `kind` in this condition checks: the travel (SR-1),
    /// the detection and its naming (SR-5), the reaction and the distance after it
    /// (SR-7); with a stop in force, its distance and strength (SR-2, SR-3); frames that
    /// are not the master's, its authority (SR-6).
    pub fn requirements(self, kind: FaultKind) -> Vec<Requirement> {
        use Requirement as R;
        let mut r = vec![R::Range, R::Detection];
        if matches!(kind, FaultKind::ReplayedFrames | FaultKind::GarbageBurst) {
            r.push(R::Authority);
        } else {
            r.push(R::Reaction);
        }
        if self.own_stop() > 0 {
            r.extend([R::StopDistance, R::StopNotWeakened]);
        }
        r.sort_by_key(|x| x.id());
        r
    }
}

/// The partner of `kind` in the double-fault column: the next kind of the list that is a
/// fault of the robot or the board (not of the link, the targets, a phase or a wall), on
/// its own joint.
pub fn partner(kind: FaultKind) -> FaultKind {
    let all = FaultKind::ALL;
    let i = all.iter().position(|k| *k == kind).unwrap_or(0);
    (1..all.len())
        .map(|d| all[(i + d) % all.len()])
        .find(|k| k.is_physical())
        .unwrap_or(FaultKind::EncoderJump)
}

/// Whether `kind` applies in `condition` (else the cell is n/a): a kind of its own phase
/// only there; targets only while following; the link's kinds while enabled; a wall only
/// in motion.
pub fn applies(kind: FaultKind, condition: Condition) -> bool {
    use Condition as C;
    use FaultKind as K;
    match kind.expectation().only {
        Some(Only::Homing) => return condition == C::Homing,
        Some(Only::Enabling) => return condition == C::BrakeCheck,
        None => {}
    }
    let following = matches!(
        condition,
        C::Holding | C::Slow | C::Fast | C::Tool | C::AfterEnable | C::Double
    );
    match kind {
        K::NanTarget | K::UnreachableTarget => following,
        K::LinkLoss | K::GarbageBurst | K::ReplayedFrames => following || condition == C::HeldTool,
        K::WallContact => matches!(
            condition,
            C::Holding | C::Slow | C::Fast | C::Tool | C::Double
        ),
        _ => true,
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
    /// How far the platform moved from when the fault showed (the injection, or the
    /// probe's start) to its detection, mm (SR-5).
    pub before_mm: f64,
    /// How far it may: the tip speed for the kind's bound, mm.
    pub before_allowed_mm: f64,
    /// The requirements the cell checks (`SR-1 SR-5 SR-7`).
    pub requirements: String,
    /// The verdict.
    pub pass: bool,
    /// Why it failed, if it did.
    pub why: String,
}

/// Milliseconds the cell runs after the injection (or after the probe starts).
const AFTER_MS: u64 = 900;

/// A setpoint moved by more than this from where it stood asks its joints to move, m
/// (a micrometre: far below any motion a fault that needs motion is timed from, far
/// above the rounding of a setpoint held still).
const ASKED_M: f64 = 1e-6;
/// Milliseconds the stream runs before the injection: slow, 0.6 s (2.2 mm/s); fast, one
/// period of the sinusoid (1.51 s) plus the supervisor's lag: the platform at its peak
/// speed, 25 mm/s.
fn before_ms(condition: Condition) -> u64 {
    match condition {
        Condition::Fast | Condition::DuringSs1 | Condition::DuringSs2 => 1_580,
        Condition::AfterEnable => 0,
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
        None if Condition::RUNNING.contains(&condition) => {
            running_cell(kind, condition, &mut b).map_err(ctx)
        }
        None => staged_cell(kind, condition, &mut b).map_err(ctx),
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
                    // A target refused at submission: its reply names the guard.
                    BoardToMaster::TargetRefused(r) if reasons.contains(&r.reason) => Some(
                        format!("TargetRefused {:?} ({:?})", r.reason, r.breach.guard),
                    ),
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
    fn tick(&mut self, b: &Bench, det: &Detector, det2: Option<&Detector>, exp: &Expectation) {
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
            if let Some(what) = det.check(b).or_else(|| det2.and_then(|d| d.check(b))) {
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
        let t_ref = self.shown_from(kind, t_inj, t_ref);
        self.detected
            .as_ref()
            .map(|(t, _)| t.saturating_sub(t_ref) as f64 * 1e-3)
    }

    /// When the fault showed, as [`Watch::detect_ms`] times it, µs.
    fn shown_from(&self, kind: FaultKind, t_inj: u64, t_ref: u64) -> u64 {
        let t_ref = if kind == FaultKind::WallContact {
            self.overload_from.unwrap_or(t_ref)
        } else if let Some(t) = self.shows_at {
            t
        } else {
            t_ref
        };
        // Noticed before the probe started: timed from the injection.
        match &self.detected {
            Some((t, _)) if *t < t_ref => t_inj,
            _ => t_ref,
        }
    }
}

/// A cell in one of the running conditions.
fn running_cell(kind: FaultKind, condition: Condition, b: &mut Bench) -> Result<Cell, BenchError> {
    let exp = kind.expectation();
    let mut stream = lead_in(condition, &exp, b)?;
    // The detector's baseline before the injection: a frame may be counted as it arrives.
    let mut det = Detector::new(b, exp.detection, None);
    let pair = (condition == Condition::Double).then(|| partner(kind));
    let det2 = pair.map(|k| Detector::new(b, k.expectation().detection, None));
    let t_inj = b.now_us();
    det.seq = kind.inject(b);
    if let Some(k) = pair {
        k.inject(b);
    }
    let expected = match pair {
        Some(k) => reaction_of_rank(rank_of(exp.reaction).max(rank_of(k.expectation().reaction))),
        None => exp.reaction,
    };
    let speed_at_injection = b.board.truth().velocity.norm();
    // A fault that only shows while its joint works is probed by a small move in the
    // conditions where the joint may not work at all (holding, or moving slowly).
    let holding = matches!(
        condition,
        Condition::Holding
            | Condition::Tool
            | Condition::Slow
            | Condition::AfterEnable
            | Condition::Double
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
    let mut track = vec![(b.now_us(), b.board.truth().pose.t)];
    let mut contacts = Contacts::new(b);
    while b.now_us() < end {
        if k.is_multiple_of(10) {
            send_target(b, &stream);
        }
        k += 1;
        b.tick()?;
        track.push((b.now_us(), b.board.truth().pose.t));
        contacts.check(b);
        watch.tick(b, &det, det2.as_ref(), &exp);
    }
    let t_from = watch.shown_from(kind, t_inj, t_ref);
    let before = watch
        .detected
        .as_ref()
        .map_or(0.0, |(t, _)| travel_between(&track, t_from, *t));
    let allowed = match expected {
        Reaction::Stop(StopCategory::Sto) => 0.5,
        Reaction::Stop(_) => watch.sp_travel * 1e3 + 0.1,
        Reaction::Continue => 1.0,
    };
    let mut extra = contacts.found;
    let mut accepted = accepted_causes(kind);
    if let Some(k) = pair {
        accepted.extend(accepted_causes(k));
    }
    extra.extend(misnamed(b, det.log_len, &accepted));
    let shown = if expected == Reaction::Continue {
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
        before_mm: before * 1e3,
        expected,
        at_least: pair.is_some(),
        may_not_show: false,
        extra,
        bound_ms: pair.map_or(exp.bound_ms, |k| exp.bound_ms.max(k.expectation().bound_ms)),
        judge_time: true,
    }))
}

/// The causes that name `kind` as the first fault logged after it (SR-5), or none where
/// it is noticed otherwise (a refusal, the link's counters, a hold).
fn accepted_causes(kind: FaultKind) -> Vec<FaultCause> {
    let mut c = match kind.expectation().detection {
        Detection::Cause(causes, _) => causes.to_vec(),
        _ => Vec::new(),
    };
    // The button itself is the first thing the board sees of a welded relay.
    if matches!(kind, FaultKind::RelayWelded | FaultKind::EStop) {
        c.push(FaultCause::EmergencyStopButton);
    }
    c
}

/// SR-5: the first fault logged after the baseline `log_len`, if it is none of
/// `accepted` (nothing to judge when `accepted` is empty).
fn misnamed(b: &Bench, log_len: usize, accepted: &[FaultCause]) -> Option<String> {
    let first = b.board.runtime().fault_log().get(log_len)?.record;
    (!accepted.is_empty() && !accepted.contains(&first.cause)).then(|| {
        format!(
            "SR-5: the first fault logged is {:?} on joint {}",
            first.cause, first.joint
        )
    })
}

/// The largest distance of the platform from where it stood at `from_us`, until `to_us`
/// (the motion before a detection), m.
fn travel_between(track: &[(u64, Vector3<f64>)], from_us: u64, to_us: u64) -> f64 {
    let Some(p0) = track.iter().find(|(t, _)| *t >= from_us).map(|(_, p)| *p) else {
        return 0.0;
    };
    track
        .iter()
        .filter(|(t, _)| *t >= from_us && *t <= to_us)
        .map(|(_, p)| (p - p0).norm())
        .fold(0.0, f64::max)
}

/// SR-1 along a cell: a joint arriving at a hard stop (a leg's end stop ever, a link's
/// stop outside homing).
struct Contacts {
    at: [bool; 6],
    found: Vec<String>,
}

impl Contacts {
    fn new(b: &Bench) -> Self {
        Contacts {
            at: crate::search::probe::at_hard_stop(&b.board),
            found: Vec::new(),
        }
    }
    fn check(&mut self, b: &Bench) {
        let now = crate::search::probe::at_hard_stop(&b.board);
        let homing = b.board.runtime().state() == RobotState::Homing;
        for (j, (n, was)) in now.iter().zip(self.at).enumerate() {
            if *n && !was && (j < 3 || !homing) && self.found.is_empty() {
                self.found.push(format!(
                    "SR-1: joint {j} met its hard stop at {:.3} s",
                    b.now_us() as f64 * 1e-6
                ));
            }
        }
        self.at = now;
    }
}

/// A cell of a kind with its own phase (homing, enabling).
fn phase_cell(kind: FaultKind, b: &mut Bench, only: Only) -> Result<Cell, BenchError> {
    let condition = match only {
        Only::Homing => Condition::Homing,
        Only::Enabling => Condition::BrakeCheck,
    };
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
    let mut contacts = Contacts::new(b);
    let mut track = vec![(b.now_us(), b.board.truth().pose.t)];
    while b.now_us() < end {
        b.tick()?;
        let now = b.now_us();
        contacts.check(b);
        track.push((now, b.board.truth().pose.t));
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
    // Homing moves at its own speeds, not the supervisor's: the motion before the
    // detection is judged by SR-1 (the hard stops) there.
    let before = match (&detected, only) {
        (Some((t, _)), Only::Enabling) => travel_between(&track, t_inj, *t),
        _ => 0.0,
    };
    Ok(verdict(Verdict {
        kind,
        condition,
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
        before_mm: before * 1e3,
        expected: exp.reaction,
        at_least: false,
        may_not_show: false,
        extra: contacts.found,
        bound_ms: exp.bound_ms,
        judge_time: true,
    }))
}

/// A cell in a condition with its own set-up (homing, the brake check, a held stop with
/// the tool and a push, during an SS1 or an SS2): the fault injected once the condition
/// stands, judged like a running cell, the reaction as at least the stronger of the
/// kind's and the condition's own stop (SR-7); with a stop in force, the platform within
/// its distance (SR-2) and the stop never weakened (SR-3). A fault that needs motion may
/// not show where the robot stands still: not detected then passes, the motion judged.
fn staged_cell(kind: FaultKind, condition: Condition, b: &mut Bench) -> Result<Cell, BenchError> {
    let exp = kind.expectation();
    let hello = b.hello_msg();
    let bounds = safety_bounds();
    // The stop the condition puts in force: where and when it began, the lag then.
    let mut own_stop: Option<(Vector3<f64>, f64)> = None;
    match condition {
        Condition::Homing => {
            b.request(&hello, 100)?;
            b.command(&MasterToBoard::Home { rehome: false })?;
            b.run_ms(1_500)?;
        }
        Condition::BrakeCheck => {
            b.request(&hello, 100)?;
            b.command(&MasterToBoard::Home { rehome: false })?;
            b.run_until("homed", 120_000, |s| {
                s.runtime().state() != RobotState::Homing
            })?;
            b.run_ms(100)?;
            b.command(&MasterToBoard::OperatorPresent { present: true })?;
            b.send(&MasterToBoard::Enable);
            b.run_ms(20)?;
        }
        Condition::HeldTool => {
            b.bring_up()?;
            b.board.set_tool(Some(ToolLoad::thesis()));
            b.run_ms(300)?;
            b.command(&MasterToBoard::Clutch { engaged: true })?;
            b.run_ms(300)?;
            let p = b.board.truth().pose.t;
            own_stop = Some((p, lag(b)));
            // A wall 0.1 mm past o_p on the -x side: 10 N along +x.
            b.board.set_wall(Some(simulation::board::Wall {
                point: p + Vector3::new(0.0001, 0.0, 0.0),
                normal: Vector3::new(1.0, 0.0, 0.0),
                stiffness_n_per_m: 1e5,
                damping_n_s_per_m: 200.0,
            }));
            b.run_ms(100)?;
        }
        Condition::DuringSs1 | Condition::DuringSs2 => {
            b.bring_up()?;
            let centre = setpoint(b).unwrap_or_else(|| b.board.truth().pose.t);
            let stream = Stream {
                centre,
                speed: condition.speed(),
                amplitude: 0.006,
                t0_us: b.now_us(),
                probe_from_us: None,
                probe_step_m: None,
            };
            for k in 0..before_ms(condition) {
                if k % 10 == 0 {
                    let t = b.now_us();
                    let p = stream.position(t);
                    b.send(&MasterToBoard::PoseTarget {
                        timestamp_us: t,
                        position_m: [p.x as f32, p.y as f32, p.z as f32],
                        rotation_vector_rad: [0.0; 3],
                    });
                }
                b.tick()?;
            }
            own_stop = Some((b.board.truth().pose.t, lag(b)));
            b.send(&if condition == Condition::DuringSs1 {
                MasterToBoard::Disable
            } else {
                MasterToBoard::Clutch { engaged: true }
            });
            b.run_ms(20)?;
        }
        _ => return running_cell(kind, condition, b),
    }
    let mut det = Detector::new(b, exp.detection, None);
    let homing_det = (condition == Condition::Homing)
        .then(|| Detector::new(b, Detection::Cause(&[FaultCause::HomingFailed], None), None));
    let t_inj = b.now_us();
    det.seq = kind.inject(b);
    let speed_at_injection = b.board.truth().velocity.norm();
    let expected = reaction_of_rank(rank_of(exp.reaction).max(condition.own_stop()));
    let mut detected: Option<(u64, String)> = None;
    let mut at_detect: Option<(Vector3<f64>, Vector3<f64>)> = None;
    let mut reaction = Reaction::Continue;
    let (mut moved, mut sp_travel, mut deviation, mut during) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut last_sp = setpoint(b);
    let mut contacts = Contacts::new(b);
    let mut track = vec![(t_inj, b.board.truth().pose.t)];
    let mut weakened: Option<String> = None;
    let mut rank_before = stop_rank(b.board.runtime().status().stop);
    // While homing, a fault is in time if it is found before the homing (and its park
    // move) ends: the cell runs until then.
    let homing = condition == Condition::Homing;
    let mut end = t_inj + (exp.bound_ms + AFTER_MS) * 1000;
    // A fault that needs motion shows from the first tick its joint moves under power at
    // three times the back-EMF check's floor (the search's threshold).
    let mut shows_at: Option<u64> = (!exp.needs_motion).then_some(t_inj);
    // The first tick the setpoint moved from where it stood at the injection: from then on
    // the joint is asked to move, and a fault that needs motion (a seized load, which
    // never moves itself) can show.
    let sp_inj = setpoint(b);
    let mut asked_at: Option<u64> = None;
    loop {
        let now = b.now_us();
        let in_homing = b.board.runtime().state() == RobotState::Homing;
        if homing && in_homing && now < t_inj + 30_000_000 {
            end = end.max(now + AFTER_MS * 1000);
        }
        if now >= end {
            break;
        }
        b.tick()?;
        let now = b.now_us();
        let p = b.board.truth().pose.t;
        if shows_at.is_none() {
            if let Some(j) = kind.joint() {
                let threshold = if j < 3 { 4.3e-3 } else { 0.25 };
                let v = b.board.hw.plant.joint_velocities()[j].abs();
                if v >= threshold && crate::search::probe::powered(&b.board) {
                    shows_at = Some(now);
                }
            }
        }
        track.push((now, p));
        contacts.check(b);
        if let Some(sp) = setpoint(b) {
            last_sp = Some(sp);
            if asked_at.is_none() && sp_inj.is_none_or(|s0| (sp - s0).norm() > ASKED_M) {
                asked_at = Some(now);
            }
        }
        let st = b.board.runtime().status();
        let r = stop_rank(st.stop);
        let done =
            matches!(st.state, RobotState::Ready | RobotState::Disabled) && !b.board.hw.enabled;
        if r < rank_before && !done && weakened.is_none() && condition.own_stop() > 0 {
            weakened = Some(format!(
                "SR-3: the stop weakened to {:?} in {:?} at {:.3} s",
                st.stop,
                st.state,
                now as f64 * 1e-6
            ));
        }
        rank_before = r;
        if let Some((p0, _)) = own_stop {
            during = during.max((p - p0).norm());
        }
        if detected.is_none() {
            let seen = det
                .check(b)
                .or_else(|| homing_det.as_ref().and_then(|d| d.check(b)));
            if let Some(what) = seen {
                detected = Some((now, what));
                at_detect = Some((p, last_sp.unwrap_or(p)));
            }
        }
        if let (Some((t_det, _)), Some((p0, sp0))) = (&detected, &at_detect) {
            moved = moved.max((p - p0).norm());
            let sp = last_sp.unwrap_or(*sp0);
            sp_travel = sp_travel.max((sp - sp0).norm());
            deviation = deviation.max((p - sp).norm());
            if now == *t_det + 30_000 {
                reaction = category_of(b.board.runtime().status().stop);
            }
        }
    }
    // Timed from when it showed (detected before it showed: from the injection). A fault
    // that needs motion, found where its joint never moved and the setpoint never asked
    // it to (a load seized while a held stop keeps the platform still), could not show:
    // found or not, its time is not judged (as a fault that needs motion and was not
    // found there passes); what it was named and the reaction are.
    let t_ref = match (&detected, shows_at) {
        (Some((t, _)), Some(s)) if *t >= s => s,
        _ => t_inj,
    };
    let never_shown = match &detected {
        Some((t, _)) => {
            exp.needs_motion && shows_at.is_none_or(|s| s > *t) && asked_at.is_none_or(|a| a > *t)
        }
        None => false,
    };
    let detect_ms = detected
        .as_ref()
        .map(|(t, _)| t.saturating_sub(t_ref) as f64 * 1e-3);
    let allowed = match expected {
        Reaction::Stop(StopCategory::Sto) => 0.5,
        Reaction::Stop(_) => sp_travel * 1e3 + 0.1,
        Reaction::Continue => 1.0,
    };
    let mut extra = contacts.found;
    extra.extend(weakened);
    // A fault that showed must be found (one that never could, passes: nothing moved it).
    if detected.is_none() && exp.needs_motion && shows_at.is_some() {
        extra.push("not detected after it showed".into());
    }
    let mut accepted = accepted_causes(kind);
    if condition == Condition::Homing && !accepted.is_empty() {
        accepted.push(FaultCause::HomingFailed);
    }
    extra.extend(misnamed(b, det.log_len, &accepted));
    // SR-2: from where the condition's stop began, its distance (and an STO's on top if a
    // fault's STO replaced it).
    if let Some((_, lag0)) = own_stop {
        let category = if condition == Condition::DuringSs1 {
            StopCategory::Ss1
        } else {
            StopCategory::Ss2
        };
        let bound =
            bounds.stop_distance_m(category) + lag0 + bounds.stop_distance_m(StopCategory::Sto);
        if during > bound {
            extra.push(format!(
                "SR-2: {:.3} mm during the stop > {:.3} mm",
                during * 1e3,
                bound * 1e3
            ));
        }
    }
    // Homing moves at its own speeds: SR-1 judges the motion before the detection there.
    let before = match (&detected, condition) {
        (Some((t, _)), c) if c != Condition::Homing => travel_between(&track, t_ref, *t),
        _ => 0.0,
    };
    Ok(verdict(Verdict {
        kind,
        condition,
        detected,
        detect_ms,
        reaction,
        final_stop: b.board.runtime().status().stop,
        shown_mm: moved * 1e3,
        allowed_mm: allowed,
        still_enabled: b.board.runtime().state() == RobotState::Enabled,
        deviation_mm: deviation * 1e3,
        logged: det.logged(b),
        speed_mm_s: speed_at_injection * 1e3,
        before_mm: before * 1e3,
        expected,
        at_least: true,
        may_not_show: exp.needs_motion,
        extra,
        bound_ms: exp.bound_ms,
        judge_time: !homing && !never_shown,
    }))
}

/// The platform's distance from its setpoint now, m (0 without a controller).
fn lag(b: &Bench) -> f64 {
    setpoint(b).map_or(0.0, |sp| (b.board.truth().pose.t - sp).norm())
}

/// A stop's strength: none 0, SS2 1, SS1 2, STO 3.
fn stop_rank(stop: StopStatus) -> u8 {
    rank_of(category_of(stop))
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
    /// The platform's motion from when the fault showed to its detection, mm.
    before_mm: f64,
    /// The reaction expected (the kind's, or the stronger of a pair, or the condition's
    /// own stop).
    expected: Reaction,
    /// The reaction is judged as at least the expected one (a stop in force, a pair).
    at_least: bool,
    /// Not detected passes: the fault could not show (it needs motion, and the condition
    /// has none or stops it).
    may_not_show: bool,
    /// Other failures found along the cell (SR-1's hard stops, SR-3's weakened stop, a
    /// misnamed first fault).
    extra: Vec<String>,
    /// The detection's bound, ms (the kind's; the larger of a pair's).
    bound_ms: u64,
    /// The time is judged against it (else: detected before the homing ended is in time).
    judge_time: bool,
}

fn rank_of(r: Reaction) -> u8 {
    match r {
        Reaction::Continue => 0,
        Reaction::Stop(StopCategory::Ss2) => 1,
        Reaction::Stop(StopCategory::Ss1) => 2,
        Reaction::Stop(StopCategory::Sto) => 3,
    }
}

fn reaction_of_rank(r: u8) -> Reaction {
    match r {
        0 => Reaction::Continue,
        1 => Reaction::Stop(StopCategory::Ss2),
        2 => Reaction::Stop(StopCategory::Ss1),
        _ => Reaction::Stop(StopCategory::Sto),
    }
}

fn verdict(v: Verdict) -> Cell {
    let bounds = safety_bounds();
    let before_allowed_mm = bounds.before_detection_m(v.bound_ms as f64 * 1e-3) * 1e3;
    let mut why = Vec::new();
    if v.detected.is_none() && !v.may_not_show {
        why.push("not detected".to_string());
    }
    if let (Some(ms), true) = (v.detect_ms, v.judge_time) {
        if ms > v.bound_ms as f64 {
            why.push(format!("late: {ms:.0} ms > {} ms", v.bound_ms));
        }
    }
    let reaction_ok = if v.at_least {
        rank_of(v.reaction) >= rank_of(v.expected)
    } else {
        v.reaction == v.expected
    };
    if v.detected.is_some() && !reaction_ok {
        why.push(format!(
            "reaction {} instead of {}{}",
            v.reaction.name(),
            if v.at_least { "at least " } else { "" },
            v.expected.name()
        ));
    }
    if v.expected == Reaction::Continue && v.detected.is_some() && !v.still_enabled {
        why.push("left Enabled".into());
    }
    // (A NaN figure fails too.)
    let within = |x: f64, bound: f64| {
        x.partial_cmp(&bound) != Some(std::cmp::Ordering::Greater) && !x.is_nan()
    };
    if !within(v.shown_mm, v.allowed_mm) {
        why.push(format!(
            "moved {:.3} mm > {:.3} mm",
            v.shown_mm, v.allowed_mm
        ));
    }
    if !within(v.before_mm, before_allowed_mm) {
        why.push(format!(
            "moved {:.3} mm before the detection > {:.3} mm",
            v.before_mm, before_allowed_mm
        ));
    }
    why.extend(v.extra);
    let requirements: Vec<&str> = v
        .condition
        .requirements(v.kind)
        .iter()
        .map(|r| r.id())
        .collect();
    Cell {
        kind: v.kind,
        condition: v.condition,
        detected: v.detected.is_some(),
        detect_ms: v.detect_ms,
        bound_ms: v.bound_ms,
        noticed: v.detected.map(|(_, w)| w).unwrap_or_else(|| {
            if v.may_not_show {
                "not shown (no motion)".into()
            } else {
                String::new()
            }
        }),
        expected: v.expected,
        reaction: v.reaction,
        final_stop: v.final_stop,
        moved_mm: v.shown_mm,
        allowed_mm: v.allowed_mm,
        deviation_mm: v.deviation_mm,
        logged: v.logged,
        speed_mm_s: v.speed_mm_s,
        before_mm: v.before_mm,
        before_allowed_mm,
        requirements: requirements.join(" "),
        pass: why.is_empty(),
        why: why.join("; "),
    }
}

/// The requirements' bounds of the reference board.
fn safety_bounds() -> control::safety::Bounds {
    let robot = kinematics_core::RsprGeometry::<f64>::reference();
    match control::runtime::reference_config_for(&robot, kinematics_core::Branch::OUTER, None, None)
    {
        Ok(cfg) => control::safety::Bounds::of(&cfg, &robot),
        // (The reference robot's central pose has its inverse kinematics.)
        Err(_) => control::safety::Bounds {
            tip_speed_m_s: f64::NAN,
            tip_accel_m_s2: f64::NAN,
            period_s: f64::NAN,
            brake_engage_s: f64::NAN,
            decel_timeout_s: f64::NAN,
            standstill: [f64::NAN; 6],
            standstill_platform_m: f64::NAN,
            heartbeat_s: [f64::NAN; 2],
            channel_agree: [f64::NAN; 6],
        },
    }
}

/// The cells of `kinds` x `conditions` that apply ([`applies`]).
pub fn cells(kinds: &[FaultKind], conditions: &[Condition]) -> Vec<(FaultKind, Condition)> {
    let mut out = Vec::new();
    for k in kinds {
        for c in conditions {
            if applies(*k, *c) {
                out.push((*k, *c));
            }
        }
    }
    out
}

/// `FaultCause` is re-exported for the matrix's readers.
pub type Cause = FaultCause;
