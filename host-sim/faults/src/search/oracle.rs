//! One oracle per safety requirement (`control::safety`), checked at every tick against
//! what can be measured: the plant's truth (the platform's position, the joints, hard-stop
//! contact), the board's outputs (driver enable, brakes), the status it reports (state,
//! stop in force, latched fault, setpoint) and its replies on the wire.

use std::fmt;

use control::safety::{Bounds, Requirement};
use control::stops::{reaction, StopCategory, StopEvent};
use master_link::{
    BoardToMaster, FaultCause, Faults, MasterToBoard, NackReason, RobotState, StopStatus,
};
use nalgebra::Vector3;
use simulation::board::BoardSim;

use super::inject::{Injection, Shows, Spec};
use super::{probe, Action, Cmd, Delivered};

/// A requirement that did not hold.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// The requirement.
    pub requirement: Requirement,
    /// When, µs of virtual time.
    pub t_us: u64,
    /// What was measured against what was allowed.
    pub what: String,
    /// The faults injected and not detected yet, and whether foreign frames reached the
    /// board in the case (what a known open hole is recognised by).
    pub context: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} at {:.3} s: {} [{}]",
            self.requirement.id(),
            self.t_us as f64 * 1e-6,
            self.what,
            self.context
        )
    }
}

/// A stop's strength: none 0, SS2 1, SS1 2, STO 3.
pub fn rank(stop: StopStatus) -> u8 {
    match stop {
        StopStatus::None => 0,
        StopStatus::SafeStop2Decelerating | StopStatus::SafeOperatingStop => 1,
        StopStatus::SafeStop1Decelerating
        | StopStatus::SafeStop1Braking
        | StopStatus::SafeStop1Done => 2,
        StopStatus::SafeTorqueOff => 3,
    }
}

fn category_rank(c: StopCategory) -> u8 {
    match c {
        StopCategory::Sto => 3,
        StopCategory::Ss1 => 2,
        StopCategory::Ss2 => 1,
    }
}

fn category_of(rank: u8) -> StopCategory {
    match rank {
        3 => StopCategory::Sto,
        2 => StopCategory::Ss1,
        _ => StopCategory::Ss2,
    }
}

/// Where a stop (or a reaction) began.
#[derive(Clone, Copy, Debug)]
struct Anchor {
    category: StopCategory,
    p: Vector3<f64>,
    /// The platform's distance from its setpoint then (SS1, SS2), m.
    lag: f64,
    t_us: u64,
    /// Already reported.
    reported: bool,
}

/// An injected fault the board has not detected yet.
#[derive(Clone, Debug)]
struct Pending {
    injection: Injection,
    spec: Spec,
    t_us: u64,
    homing: bool,
    shown_us: u64,
    first_show: Option<Vector3<f64>>,
}

/// What the last tick measured.
#[derive(Clone, Copy, Debug)]
struct Snap {
    state: RobotState,
    stop: StopStatus,
    faults: Faults,
    fault: FaultCause,
    drives: bool,
    at_stop: [bool; 6],
}

/// A fault latched and the stop it calls for (SR-7).
#[derive(Clone, Copy, Debug)]
struct Due {
    /// The stop's strength the stop table asks for.
    need: u8,
    cause: FaultCause,
    t_us: u64,
    /// A stop at least that strong was in force at a tick of the window.
    given: bool,
}

/// Every requirement's oracle.
pub struct Oracle {
    bounds: Bounds,
    period_us: u64,
    violations: Vec<Violation>,
    prev: Option<Snap>,
    episode: Option<(u8, Anchor)>,
    reaction: Option<Anchor>,
    /// A fault latched: the stop its table asks for, its cause, when, and whether a stop
    /// that strong has been in force at a tick since.
    due: Option<Due>,
    sto_latched: bool,
    /// The nonce of the master that owns the board, as the replies showed it.
    owns: Option<u32>,
    /// A welded safety relay was found (not repaired since).
    relay_found: bool,
    /// The brakes wore after the brake check that let the board enable (not repaired
    /// since): an STO's distance rests on brakes that hold what that check tested.
    brakes_worn: bool,
    pending: Vec<Pending>,
    /// The injected faults detected (or judged late) and not repaired: they are still
    /// there, and a fault latched again after a ClearFault may name any of them.
    standing: Vec<Pending>,
    explained: Vec<FaultCause>,
    /// Each joint's home position and its switch's travel (m, rad): where a switch
    /// closed before the references is plausible.
    home: [(f64, f64); 6],
    /// When the board last left `Homing` (µs): a link homing swept towards its hard stop
    /// coasts on for up to the brakes' engage time after a stop cut its torque.
    left_homing_us: Option<u64>,
    /// Where each joint last rested against a hard stop (m, rad), while it stays there.
    rest: [Option<f64>; 6],
    foreign: bool,
    cleared: bool,
}

/// The causes the case's own actions explain (not a fault's misnaming).
fn explained_by(a: &Action) -> &'static [FaultCause] {
    use FaultCause as C;
    match a {
        Action::Command(Cmd::EStop) => &[C::EmergencyStopMessage],
        Action::Silence(ms) if *ms >= 100 => &[C::HeartbeatTimeout],
        Action::Button(true) => &[C::EmergencyStopButton],
        Action::Push { depth_um, .. } if *depth_um > 0 => &[
            C::Overload,
            C::FollowingError,
            C::NoMotion,
            C::StandstillLost,
            C::GuardStop,
            C::HomingFailed,
            C::BrakeCheck,
        ],
        Action::Wall { .. } => &[
            C::Overload,
            C::FollowingError,
            C::NoMotion,
            C::StandstillLost,
            C::HomingFailed,
        ],
        Action::Tool(true) => &[C::StandstillLost, C::HomingFailed],
        // A foreign frame may cut the owner off (its heartbeats refused: SR-6's to
        // judge), and anyone's emergency stop is taken.
        Action::Foreign(_) => &[C::HeartbeatTimeout, C::EmergencyStopMessage],
        _ => &[],
    }
}

impl Oracle {
    /// The oracles of `board`'s settings.
    pub fn new(board: &BoardSim) -> Self {
        let cfg = &board.config().runtime;
        let robot = kinematics_core::RsprGeometry::<f64>::reference();
        Oracle {
            bounds: Bounds::of(cfg, &robot),
            period_us: u64::from(board.config().service.watchdog.period_us),
            violations: Vec::new(),
            prev: None,
            episode: None,
            reaction: None,
            due: None,
            sto_latched: false,
            owns: None,
            relay_found: false,
            brakes_worn: false,
            pending: Vec::new(),
            standing: Vec::new(),
            explained: Vec::new(),
            home: std::array::from_fn(|j| {
                cfg.homing
                    .joints
                    .get(j)
                    .map_or((f64::NAN, 0.0), |h| (h.home_position, h.switch_travel_max))
            }),
            left_homing_us: None,
            rest: [None; 6],
            foreign: false,
            cleared: false,
        }
    }

    /// The violations so far.
    pub fn violations(&self) -> &[Violation] {
        &self.violations
    }

    fn violate(&mut self, requirement: Requirement, t_us: u64, what: String) {
        let mut context: Vec<String> = self
            .pending
            .iter()
            .map(|p| format!("{:?}", p.injection))
            .collect();
        if self.foreign {
            context.push("foreign frames".into());
        }
        self.violations.push(Violation {
            requirement,
            t_us,
            what,
            context: context.join(", "),
        });
    }

    /// The case is about to carry out `a`.
    pub fn note(&mut self, a: &Action, board: &BoardSim) {
        for c in explained_by(a) {
            if !self.explained.contains(c) {
                self.explained.push(*c);
            }
        }
        match a {
            Action::Fault(i) => {
                // A switch forced to a new reading is no longer forced to the old one: the
                // earlier injection on that switch is gone (it never showed if no tick ran).
                if let Injection::SwitchClosed(j) | Injection::SwitchDead(j) = *i {
                    let same_switch = |pd: &Pending| matches!(pd.injection, Injection::SwitchClosed(k) | Injection::SwitchDead(k) if k % 6 == j % 6);
                    self.pending.retain(|pd| !same_switch(pd));
                    self.standing.retain(|pd| !same_switch(pd));
                }
                let homing = probe::state(board) == RobotState::Homing;
                self.pending.push(Pending {
                    injection: *i,
                    spec: i.spec(),
                    t_us: board.now_us(),
                    homing,
                    shown_us: 0,
                    first_show: None,
                });
                if *i == Injection::RelayWelded {
                    self.explained.push(FaultCause::EmergencyStopButton);
                }
                self.brakes_worn |= *i == Injection::BrakesWorn;
            }
            // A repaired fault may still be latched after it (a jump counted, a driver's
            // latch): its causes stay explained.
            Action::Repair => {
                self.relay_found = false;
                self.brakes_worn = false;
                for pd in self.pending.drain(..).chain(self.standing.drain(..)) {
                    for c in pd.spec.causes.iter().chain(pd.spec.homing_causes) {
                        if !self.explained.contains(c) {
                            self.explained.push(*c);
                        }
                    }
                }
            }
            Action::Foreign(_) => self.foreign = true,
            _ => {}
        }
    }

    /// The board failed to step (the plant's true pose was lost: the robot went where its
    /// kinematics do not reach).
    pub fn broken(&mut self, board: &BoardSim, why: &str) {
        self.violate(
            Requirement::Range,
            board.now_us(),
            format!("the plant could not be stepped: {why}"),
        );
    }

    /// One tick: `delivered` the frames the board took before it, `replies` what it sent.
    pub fn tick(&mut self, board: &BoardSim, delivered: &[Delivered], replies: &[BoardToMaster]) {
        let now = board.now_us();
        let st = probe::status(board);
        let (p, _speed) = probe::platform(board);
        let drives = probe::drives_on(board);
        let snap = Snap {
            state: st.state,
            stop: st.stop,
            faults: st.faults,
            fault: st.fault.cause,
            drives,
            at_stop: probe::at_hard_stop(board),
        };
        let sp = Vector3::new(
            f64::from(st.setpoint_position_m[0]),
            f64::from(st.setpoint_position_m[1]),
            f64::from(st.setpoint_position_m[2]),
        );
        let lag = if sp.iter().all(|x| x.is_finite()) {
            (p - sp).norm()
        } else {
            0.0
        };
        let (q, _) = probe::joints(board);
        self.range(now, &snap, &q);
        self.authority(now, &snap, delivered, replies);
        self.torque(now, board, &snap, delivered, replies);
        self.not_weakened(now, &snap, board);
        self.distance(now, &snap, p, lag);
        self.reaction(now, &snap, p, lag);
        self.detection(now, board, &snap, p, st.fault.joint);
        self.prev = Some(snap);
    }

    /// SR-1: a leg never meets its end stop; a link meets its hard stop only while homing,
    /// or coasting on within the brakes' engage time after a stop ended a homing: its sweep
    /// went towards that stop, which the homing meets anyway (under power, at the sweep's
    /// speed; the coast only slows).
    ///
    /// A joint arrives at a hard stop when it touches it after it had moved off it: the
    /// plant's contact flag of a joint resting against its stop (where homing put a link)
    /// comes and goes with the push of its drive, and the joint has not moved.
    fn range(&mut self, now: u64, s: &Snap, q: &[f64; 6]) {
        let before = self.prev.map_or([false; 6], |p| p.at_stop);
        if self
            .prev
            .is_some_and(|p| p.state == RobotState::Homing && s.state != RobotState::Homing)
        {
            self.left_homing_us = Some(now);
        }
        let engage_us = (self.bounds.brake_engage_s * 1e6) as u64;
        let homing_coast = s.state == RobotState::Homing
            || (!s.drives
                && self
                    .left_homing_us
                    .is_some_and(|t| now.saturating_sub(t) <= engage_us));
        for (j, (now_at, was_at)) in s.at_stop.iter().zip(before).enumerate() {
            // Within a hundredth of an encoder count (legs 1.5 µm a count, links 87 µrad):
            // it has not moved off the stop.
            let still = if j < 3 { 1.5e-8 } else { 8.7e-7 };
            let rested = self.rest[j].is_some_and(|r| (q[j] - r).abs() <= still);
            if *now_at {
                if !rested {
                    self.rest[j] = Some(q[j]);
                }
            } else if !rested {
                self.rest[j] = None;
            }
            let arrived = *now_at && !was_at && !rested;
            if arrived && (j < 3 || !homing_coast) {
                self.violate(
                    Requirement::Range,
                    now,
                    format!(
                        "joint {j} met its hard stop in {:?} (stop {:?})",
                        s.state, s.stop
                    ),
                );
            }
        }
    }

    /// SR-6: no frame but the owner's fresh ones is taken; a `Hello` is answered only
    /// when a master sent it fresh, and takes the board from its owner only while the
    /// robot is disabled (torque off); every fresh frame of the owner is answered (a
    /// foreign frame does not lock it out), and its targets, stamped in order, are never
    /// stale (a foreign stamp did not become its clock).
    fn authority(
        &mut self,
        now: u64,
        s: &Snap,
        delivered: &[Delivered],
        replies: &[BoardToMaster],
    ) {
        // Disabled as the tick that took the Hello left it (an emergency stop taken in the
        // same tick before it disables the robot).
        let disabled = !s.drives
            && matches!(
                s.state,
                RobotState::Boot | RobotState::Disabled | RobotState::Ready | RobotState::Fault
            );
        let state = s.state;
        for r in replies {
            match r {
                BoardToMaster::HelloReply { nonce, .. } => {
                    let asked = delivered.iter().any(|d| {
                        d.from == Some(*nonce) && matches!(d.message, MasterToBoard::Hello { .. })
                    });
                    if !asked {
                        self.violate(
                            Requirement::Authority,
                            now,
                            format!("a replayed Hello opened a session (nonce {nonce:#x})"),
                        );
                    } else if self.owns.is_some_and(|o| o != *nonce) && !disabled {
                        self.violate(
                            Requirement::Authority,
                            now,
                            format!(
                                "a second master's Hello took the board from its owner in {state:?}"
                            ),
                        );
                    }
                    self.owns = Some(*nonce);
                }
                BoardToMaster::Ack { seq } => {
                    let fresh = delivered.iter().any(|d| d.owner && d.seq == *seq);
                    let foreign = delivered
                        .iter()
                        .find(|d| !d.owner && d.seq == *seq && moves(&d.message));
                    if let (false, Some(d)) = (fresh, foreign) {
                        self.violate(
                            Requirement::Authority,
                            now,
                            format!("a foreign frame was taken: {:?} (seq {seq})", d.message),
                        );
                    }
                }
                BoardToMaster::Nack {
                    seq,
                    reason: NackReason::StaleTarget,
                }
                | BoardToMaster::TargetRefused(master_link::RefusedTarget {
                    reply_to: Some(seq),
                    reason: NackReason::StaleTarget,
                    ..
                }) => {
                    let own_target = delivered.iter().any(|d| {
                        d.owner
                            && d.seq == *seq
                            && matches!(d.message, MasterToBoard::PoseTarget { .. })
                    });
                    if own_target {
                        self.violate(
                            Requirement::Authority,
                            now,
                            format!("the owner's target (seq {seq}) was refused as stale: a foreign stamp became its clock"),
                        );
                    }
                }
                _ => {}
            }
        }
        // Every fresh frame of the owner is answered in its tick (but the frames a master
        // sends after its own Hello in the same tick, still in its old session).
        for (i, d) in delivered.iter().enumerate() {
            let after_hello = delivered[..i]
                .iter()
                .any(|e| e.from == d.from && matches!(e.message, MasterToBoard::Hello { .. }));
            if !d.owner || after_hello || matches!(d.message, MasterToBoard::Hello { .. }) {
                continue;
            }
            let answered = replies.iter().any(|r| match r {
                BoardToMaster::Ack { seq }
                | BoardToMaster::Nack { seq, .. }
                | BoardToMaster::GeometryStored { seq, .. }
                | BoardToMaster::GeometryRefused { seq, .. } => *seq == d.seq,
                BoardToMaster::TargetRefused(t) => t.reply_to == Some(d.seq),
                BoardToMaster::Status(_) => d.message == MasterToBoard::StatusRequest,
                BoardToMaster::FaultLog(_) | BoardToMaster::EventLog(_) => true,
                _ => false,
            });
            if !answered {
                self.violate(
                    Requirement::Authority,
                    now,
                    format!(
                        "the owner's {:?} (seq {}) was not answered: the owner is locked out",
                        d.message, d.seq
                    ),
                );
            }
        }
    }

    /// SR-4: the drives on only where the mode allows torque, the brakes released only
    /// with them, never after an STO until the owner's fresh Enable or Home.
    fn torque(
        &mut self,
        now: u64,
        board: &BoardSim,
        s: &Snap,
        delivered: &[Delivered],
        replies: &[BoardToMaster],
    ) {
        // An Enable or a Home the board took (a foreign one is SR-6's to judge).
        let fresh_start = replies.iter().any(|r| match r {
            BoardToMaster::Ack { seq } => delivered.iter().any(|d| {
                d.seq == *seq
                    && matches!(
                        d.message,
                        MasterToBoard::Enable | MasterToBoard::Home { .. }
                    )
            }),
            _ => false,
        });
        if fresh_start {
            self.sto_latched = false;
        }
        self.cleared = fresh_start
            || replies.iter().any(|r| match r {
                BoardToMaster::Ack { seq } => delivered
                    .iter()
                    .any(|d| d.seq == *seq && d.message == MasterToBoard::ClearFault),
                _ => false,
            });
        if s.stop == StopStatus::SafeTorqueOff {
            self.sto_latched = true;
        }
        let allowed = matches!(
            s.state,
            RobotState::Homing
                | RobotState::Enabling
                | RobotState::Enabled
                | RobotState::Commissioning
        ) || matches!(
            s.stop,
            StopStatus::SafeStop1Decelerating
                | StopStatus::SafeStop1Braking
                | StopStatus::SafeStop2Decelerating
                | StopStatus::SafeOperatingStop
        );
        // A deadline missed is found after the tick's outputs (the third overrun, measured
        // at the tick's end): its STO reaches the outputs at the next tick, or the
        // watchdog's reset within 10 ms if none comes (reported, not a hole of the mode
        // table: `TickService::finish`).
        let deadline_now = s.faults.intersects(FaultCause::DeadlineMissed.bit())
            && !self
                .prev
                .is_some_and(|p| p.faults.intersects(FaultCause::DeadlineMissed.bit()));
        let allowed = allowed || deadline_now;
        if s.drives && !allowed {
            self.violate(
                Requirement::Torque,
                now,
                format!("drives on in {:?} (stop {:?})", s.state, s.stop),
            );
        }
        if s.drives && self.sto_latched && !deadline_now {
            self.violate(
                Requirement::Torque,
                now,
                format!(
                    "drives on after an STO without a fresh Enable or Home ({:?})",
                    s.state
                ),
            );
        }
        // A welded safety relay, once found: the button can no longer cut the drives'
        // supply, so no command brings the torque back until it is repaired.
        let welded_found = s.faults.intersects(FaultCause::SafetyRelayMismatch.bit())
            || self
                .prev
                .is_some_and(|p| p.fault == FaultCause::SafetyRelayMismatch);
        if welded_found {
            self.relay_found = true;
        }
        let welded = self
            .pending
            .iter()
            .any(|p| p.injection == Injection::RelayWelded);
        if s.drives && welded && self.relay_found {
            self.violate(
                Requirement::Torque,
                now,
                format!(
                    "drives on in {:?} with the welded safety relay found",
                    s.state
                ),
            );
        }
        // The geometry is replaced only with the drives off and no stop running (as the
        // tick that took it left them: an emergency stop taken before it stops them).
        let running = s.drives
            || !matches!(
                s.stop,
                StopStatus::None | StopStatus::SafeTorqueOff | StopStatus::SafeStop1Done
            );
        if running
            && replies
                .iter()
                .any(|r| matches!(r, BoardToMaster::GeometryStored { .. }))
        {
            self.violate(
                Requirement::StopNotWeakened,
                now,
                format!(
                    "the geometry was replaced during {:?} in {:?}",
                    s.stop, s.state
                ),
            );
        }
        if probe::brakes_released(board) && !s.drives {
            self.violate(
                Requirement::Torque,
                now,
                "brakes released without the drives".into(),
            );
        }
    }

    /// SR-3: the stop's strength never drops while it is in force, but by completing
    /// (torque off and brakes applied in Ready or Disabled) or a hold ending (enabled).
    fn not_weakened(&mut self, now: u64, s: &Snap, board: &BoardSim) {
        // (`self.cleared`: a ClearFault taken in this tick, set by `torque`.)
        let Some(prev) = self.prev else { return };
        let (was, is) = (rank(prev.stop), rank(s.stop));
        if is >= was {
            return;
        }
        let idle = matches!(s.state, RobotState::Ready | RobotState::Disabled);
        let completed = is == 0 && idle && !s.drives && !probe::brakes_released(board);
        let hold_ended = prev.state == RobotState::Enabled && s.state == RobotState::Enabled;
        // A stop that had done its work (torque off, brakes applied) ended by a ClearFault,
        // an Enable or a Home the board took in this tick: whatever followed it in the
        // same tick is a fresh command.
        let done = matches!(
            prev.stop,
            StopStatus::SafeTorqueOff | StopStatus::SafeStop1Done
        ) && !prev.drives;
        let cleared = done && self.cleared;
        if !completed && !hold_ended && !cleared {
            self.violate(
                Requirement::StopNotWeakened,
                now,
                format!(
                    "the stop {:?} in {:?} became {:?} in {:?} (drives {})",
                    prev.stop, prev.state, s.stop, s.state, s.drives
                ),
            );
        }
    }

    fn anchor(&self, category: StopCategory, p: Vector3<f64>, lag: f64, now: u64) -> Anchor {
        Anchor {
            category,
            p,
            lag: if category == StopCategory::Sto {
                0.0
            } else {
                lag
            },
            t_us: now,
            reported: false,
        }
    }

    /// SR-2's distance of the stop anchored at `a`. An STO's (`v t_e`) is the coast until
    /// the brakes bite, and rests on brakes that hold what the brake check of the last
    /// enable tested: brakes worn since hold less and let the load slip on (0.76 mm
    /// against 0.751 mm with the tool and a push, holding a fifth). No stop of the board
    /// can keep that distance (an STO takes the torque away), so it is not judged while
    /// they are worn; the next enable's brake check finds them (SR-5, `BrakeCheck`).
    fn allowed(&self, a: &Anchor) -> f64 {
        if a.category == StopCategory::Sto && self.brakes_worn {
            return f64::INFINITY;
        }
        // A micrometre for the plant's numerics.
        self.bounds.stop_distance_m(a.category) + a.lag + 1e-6
    }

    /// SR-2: from where a stop began (or last grew stronger), at most its distance.
    fn distance(&mut self, now: u64, s: &Snap, p: Vector3<f64>, lag: f64) {
        let r = rank(s.stop);
        if r == 0 {
            self.episode = None;
            return;
        }
        let renew = self.episode.is_none_or(|(er, _)| r > er);
        if renew {
            self.episode = Some((r, self.anchor(category_of(r), p, lag, now)));
        }
        if let Some((er, a)) = self.episode {
            let d = (p - a.p).norm();
            let allowed = self.allowed(&a);
            if d > allowed && !a.reported {
                self.violate(
                    Requirement::StopDistance,
                    now,
                    format!(
                        "{:?} since {:.3} s: moved {:.3} mm > {:.3} mm (lag {:.3} mm at the start)",
                        a.category,
                        a.t_us as f64 * 1e-6,
                        d * 1e3,
                        allowed * 1e3,
                        a.lag * 1e3
                    ),
                );
                self.episode = Some((
                    er,
                    Anchor {
                        reported: true,
                        ..a
                    },
                ));
            }
        }
    }

    /// SR-7: a fault latched gets at least the stop table's stop within a tick, and the
    /// platform moves at most that stop's distance after it.
    ///
    /// The stop is given when it is in force at any tick from the one that shows the
    /// fault latched to the first one more than a period after it: a stop that did its
    /// work in that window (an STO: torque off, brakes applied) may be ended by the
    /// owner's `ClearFault` before the window closes; what follows it is a fresh command's
    /// (SR-3 judges the stop's end, SR-4 the torque after it).
    fn reaction(&mut self, now: u64, s: &Snap, p: Vector3<f64>, lag: f64) {
        let prev_faults = self.prev.map_or(Faults::NONE, |p| p.faults);
        if let Some(mut due) = self.due {
            due.given |= rank(s.stop) >= due.need;
            self.due = Some(due);
            if now > due.t_us + self.period_us {
                if !due.given {
                    self.violate(
                        Requirement::Reaction,
                        now,
                        format!(
                            "{:?} latched, the stop in force is {:?} (the table's: {:?})",
                            due.cause,
                            s.stop,
                            category_of(due.need)
                        ),
                    );
                }
                self.due = None;
            }
        }
        // Each new bit calls for the weakest stop of the causes it groups; the new bits
        // together for the strongest of those.
        let need = FaultCause::ALL
            .into_iter()
            .filter(|c| s.faults.intersects(c.bit()) && !prev_faults.intersects(c.bit()))
            .map(|c| {
                let weakest = FaultCause::ALL
                    .into_iter()
                    .filter(|x| x.bit() == c.bit())
                    .map(|x| category_rank(reaction(StopEvent::Fault(x)).category))
                    .min()
                    .unwrap_or(3);
                (weakest, c)
            })
            .max_by_key(|(r, _)| *r);
        if let Some((need, cause)) = need {
            self.due = Some(Due {
                need,
                cause,
                t_us: now,
                given: rank(s.stop) >= need,
            });
            if self
                .reaction
                .is_none_or(|a| category_rank(a.category) < need)
            {
                self.reaction = Some(self.anchor(category_of(need), p, lag, now));
            }
        }
        if rank(s.stop) == 0 {
            self.reaction = None;
        }
        if let Some(a) = self.reaction {
            let d = (p - a.p).norm();
            let allowed = self.allowed(&a);
            if d > allowed && !a.reported {
                self.violate(
                    Requirement::Reaction,
                    now,
                    format!(
                        "after a fault latched at {:.3} s ({:?}): moved {:.3} mm > {:.3} mm",
                        a.t_us as f64 * 1e-6,
                        a.category,
                        d * 1e3,
                        allowed * 1e3
                    ),
                );
                self.reaction = Some(Anchor {
                    reported: true,
                    ..a
                });
            }
        }
    }

    /// SR-5: each injected fault is latched under one of its causes within its time of
    /// showing; the first fault latched after it names it (or something else the case
    /// did); before it, the platform moves at most the tip speed times that time.
    fn detection(&mut self, now: u64, board: &BoardSim, s: &Snap, p: Vector3<f64>, joint: u8) {
        let homing_now = s.state == RobotState::Homing;
        let entered =
            self.prev.is_some_and(|pr| pr.fault == FaultCause::None) && s.fault != FaultCause::None;
        if entered && !self.pending.is_empty() {
            let c = s.fault;
            let named = self.pending.iter().chain(self.standing.iter()).any(|pd| {
                let on_joint = pd.spec.joint.is_none_or(|j| j == joint);
                let homing = pd.homing || homing_now;
                (pd.spec.causes.contains(&c) || (homing && pd.spec.homing_causes.contains(&c)))
                    && on_joint
            });
            if !named && !self.explained.contains(&c) {
                let what: Vec<String> = self
                    .pending
                    .iter()
                    .map(|pd| format!("{:?}", pd.injection))
                    .collect();
                self.violate(
                    Requirement::Detection,
                    now,
                    format!(
                        "the first fault latched after {} is {c:?} on joint {joint}",
                        what.join(" + ")
                    ),
                );
            }
        }
        let (q, qdot) = probe::joints(board);
        let homed = probe::homed(board);
        let currents = probe::current_fraction(board);
        let button = probe::button(board);
        let relay_open = probe::relay_open(board);
        let powered = probe::powered(board);
        let duty = probe::duties(board);
        let supervised = s.state == RobotState::Enabled;
        let period = self.period_us;
        let speed_bound = self.bounds.tip_speed_m_s;
        let mut found = Vec::new();
        // A fault on a joint whose motor leads are open too cannot show through the motor
        // (a stuck bridge, a short): its time is not judged.
        let open_joints: Vec<Option<u8>> = self
            .pending
            .iter()
            .filter(|pd| matches!(pd.injection, Injection::MotorOpen(_)))
            .map(|pd| pd.injection.joint())
            .collect();
        let mut gone = Vec::new();
        self.pending.retain_mut(|pd| {
            let masked = !matches!(pd.injection, Injection::MotorOpen(_))
                && pd.injection.joint().is_some()
                && open_joints.contains(&pd.injection.joint());
            pd.homing |= homing_now;
            let homing = pd.homing;
            let detected = pd
                .spec
                .detected_by
                .iter()
                .chain(if homing { pd.spec.homing_causes } else { &[] })
                .any(|c| s.faults.intersects(c.bit()));
            if detected {
                gone.push(pd.clone());
                return false;
            }
            let shows = !masked
                && match pd.spec.shows {
                    Shows::Always => true,
                    Shows::Torque => powered,
                    Shows::Moving(j, v) => powered && qdot[j].abs() >= v,
                    Shows::Current(j, f) => powered && currents[j] >= f,
                    Shows::Driven(j) => powered && duty[j] != 0.0,
                    Shows::NotHoming => !homing_now,
                    Shows::SwitchImplausible(j) => {
                        let (home, travel) = self.home[j];
                        !homing_now && (homed || (q[j] - home).abs() > travel)
                    }
                    Shows::Enabling => s.state == RobotState::Enabling,
                    Shows::RelayDisagrees => button != relay_open,
                    Shows::Unjudged => false,
                };
            if shows {
                pd.shown_us += period;
            } else if pd.spec.shows.restarts() {
                pd.shown_us = 0;
            }
            // The motion before the detection is judged under the supervisor's speed
            // limit (homing moves at its own speeds, SR-1 judges it), over each stretch
            // the fault shows without a break.
            pd.first_show = match (shows && supervised, pd.first_show) {
                (true, None) => Some(p),
                (true, kept) => kept,
                (false, _) => None,
            };
            let bound_us = pd.spec.bound_ms * 1000;
            if pd.spec.shows != Shows::Unjudged && pd.shown_us > bound_us {
                found.push(format!(
                    "{:?} (injected at {:.3} s) not detected after showing for {} ms (bound {} ms)",
                    pd.injection,
                    pd.t_us as f64 * 1e-6,
                    pd.shown_us / 1000,
                    pd.spec.bound_ms
                ));
                gone.push(pd.clone());
                return false;
            }
            if let Some(p0) = pd.first_show {
                let allowed = speed_bound * bound_us as f64 * 1e-6 + 1e-6;
                let d = (p - p0).norm();
                if d > allowed {
                    found.push(format!(
                        "{:?}: moved {:.3} mm before its detection > {:.3} mm",
                        pd.injection,
                        d * 1e3,
                        allowed * 1e3
                    ));
                    gone.push(pd.clone());
                    return false;
                }
            }
            true
        });
        self.standing.extend(gone);
        for f in found {
            self.violate(Requirement::Detection, now, f);
        }
    }
}

/// A message that could start or resume motion, or keep it going.
fn moves(m: &MasterToBoard) -> bool {
    !matches!(
        m,
        MasterToBoard::EmergencyStop
            | MasterToBoard::Disable
            | MasterToBoard::StatusRequest
            | MasterToBoard::FaultLogRequest { .. }
            | MasterToBoard::Clutch { engaged: true }
            | MasterToBoard::OperatorPresent { present: false }
    )
}
