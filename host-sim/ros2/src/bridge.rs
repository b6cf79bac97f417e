//! The node in front of a live board: the board's state published, the ROS 2 commands sent
//! to it, every refusal reported back with its reason.
//!
//! - **Rates.** The board sends a status every 20 ms; the bridge asks for one
//!   (`StatusRequest`) whenever [`STATUS_PERIOD_S`] has passed on the board's clock without
//!   one: `measured_cp`, `measured_js`, `setpoint_cp`, `setpoint_js` and `/tf` are
//!   published once per status, at 100 Hz or more (measured by `ros2-board.sh` on the
//!   simulated board: 127 Hz, the median interval 9.8 ms, the longest 20 ms when a
//!   request's answer and a periodic status coincide; each
//!   message a new status, none repeated). Their stamps are the board's clock (the
//!   front ends' paced clock, `teleop::pacing`) anchored to the host's clock at the first
//!   status: when the board measured, not when the host got round to it. `operating_state` is published when it changes
//!   and every [`SLOW_PERIOD_S`], the diagnostics every [`SLOW_PERIOD_S`] and when the
//!   board's state changes.
//! - **`servo_cp`**: the newest pose received becomes one target to the board, through the
//!   board's supervisor like every target (admission, path check, speed profile); older
//!   ones still queued are dropped (a servo stream wants its latest). The bridge waits for
//!   the board's answer; a refusal is published on `refusal` (`std_msgs/String`) as
//!   `servo_cp refused: <the board's reason in words>`, e.g. `servo_cp refused: workspace
//!   z 250.0 mm > 175.0 mm`, and so is a target the board's path check refuses after
//!   accepting it.
//! - **`state_command`** (`crtk_msgs/StringStamped`): CRTK's words as the board's requests
//!   ([`crate::crtk`]); a refusal is published as `state_command <word> refused: <reason>`.
//!
//! Refusal words are those of `board_words`, the same as the console's and the
//! OpenIGTLink bridge's.

use crate::convert::{self, target_of};
use crate::crtk::{operating_state, Operating, StateCommand};
use crate::messages::{Header, OperatingState, StdString, StringStamped, Time};
use crate::node::RosNode;
use kinematics_core::Mechanism;
use master_link::{MasterToBoard, NackReason, RobotState, StatusReport};
use operator::board::{Board, BoardError, BoardEvent, Outcome};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use thiserror::Error;

/// The interval after a status at which the bridge asks for the next, s (board clock):
/// 9 ms, so that with the request's round trip (about 0.5 ms on a socket) and the loop's
/// 1 ms poll the statuses come at 100 Hz or more (10 ms gave 97-98 Hz: an answer that
/// crosses a periodic status leaves a 20 ms gap).
pub const STATUS_PERIOD_S: f64 = 0.009;
/// The period of the slow topics (`operating_state` when unchanged, diagnostics), s.
pub const SLOW_PERIOD_S: f64 = 0.1;

/// Why the bridge stopped.
#[derive(Debug, Error)]
pub enum BridgeError {
    #[error(transparent)]
    Board(#[from] BoardError),
    #[error("publishing {topic}: {error}")]
    Publish { topic: &'static str, error: String },
}

/// What the bridge did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counters {
    /// Statuses received and published as `measured_cp` / `measured_js`.
    pub statuses: u64,
    /// The board-clock time between the first and the last of them, s.
    pub span_s: f64,
    /// `servo_cp` targets accepted by the board.
    pub targets_accepted: u64,
    /// `servo_cp` targets refused (by the bridge, at once by the board, or later by its
    /// path check).
    pub targets_refused: u64,
    /// `servo_cp` messages dropped for a newer one.
    pub targets_superseded: u64,
    /// `state_command`s carried out.
    pub commands_done: u64,
    /// `state_command`s refused.
    pub commands_refused: u64,
}

impl Counters {
    /// The rate of the pose and joint topics, Hz.
    pub fn rate_hz(&self) -> f64 {
        if self.statuses < 2 || self.span_s <= 0.0 {
            return 0.0;
        }
        (self.statuses - 1) as f64 / self.span_s
    }
}

/// The bridge between `board` and `node`; `robot` is the geometry the board runs (for
/// `setpoint_js`).
pub struct Bridge<'a, M: Mechanism<f64> + ?Sized> {
    board: &'a mut Board,
    node: &'a RosNode,
    robot: &'a M,
    counters: Counters,
    first_status_s: Option<f64>,
    last_status_s: f64,
    last_request_s: f64,
    last_state: Option<(Operating, RobotState)>,
    last_slow_s: f64,
    /// The host's clock and the board's at the first status.
    anchor: Option<(Time, f64)>,
}

fn published<E: std::fmt::Debug>(topic: &'static str, r: Result<(), E>) -> Result<(), BridgeError> {
    r.map_err(|e| BridgeError::Publish {
        topic,
        error: format!("{e:?}"),
    })
}

impl<'a, M: Mechanism<f64> + ?Sized> Bridge<'a, M> {
    /// Around a board (brought up or only greeted: the state tells the ROS side).
    pub fn new(board: &'a mut Board, node: &'a RosNode, robot: &'a M) -> Self {
        Bridge {
            board,
            node,
            robot,
            counters: Counters::default(),
            first_status_s: None,
            last_status_s: f64::NEG_INFINITY,
            last_request_s: f64::NEG_INFINITY,
            last_state: None,
            last_slow_s: f64::NEG_INFINITY,
            anchor: None,
        }
    }

    /// What it did so far.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Runs until `stop` is set; `log` hears the commands, targets refused and
    /// errors of the ROS side.
    pub fn run(&mut self, stop: &AtomicBool, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        while !stop.load(Ordering::Relaxed) {
            self.step(Duration::from_millis(1), log)?;
        }
        Ok(())
    }

    /// One round: receive from the board for at most `wait`, publish, ask for a status
    /// when one is due, take the commands.
    pub fn step(&mut self, wait: Duration, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        let events = self.board.poll(wait)?;
        self.handle(events, log)?;
        let now = self.board.now_s();
        if now - self.last_status_s >= STATUS_PERIOD_S
            && now - self.last_request_s >= STATUS_PERIOD_S
        {
            self.board.request_status()?;
            self.last_request_s = now;
        }
        self.servo_cp(log)?;
        self.state_commands(log)?;
        Ok(())
    }

    fn handle(
        &mut self,
        events: Vec<BoardEvent>,
        log: &mut dyn FnMut(&str),
    ) -> Result<(), BridgeError> {
        for e in events {
            match e {
                BoardEvent::Status(t, s) => self.publish_status(t, &s)?,
                BoardEvent::TargetRefused(_, r) => {
                    self.counters.targets_refused += 1;
                    self.refuse(
                        &format!(
                            "servo_cp refused by the board's path check after it was accepted: {}",
                            board_words::refusal(&r)
                        ),
                        log,
                    )?;
                }
                BoardEvent::Reply(_) => {}
            }
        }
        Ok(())
    }

    /// The stamp of a status that arrived at `t_s` on the board's clock: the host's clock
    /// at the first status, plus the board's time since (so that the stamps are the
    /// board's, 20 ms apart for its periodic statuses, whatever the host's load).
    fn stamp(&mut self, t_s: f64) -> Time {
        let (wall0, t0) = *self.anchor.get_or_insert((Time::now(), t_s));
        let ns = i64::from(wall0.sec) * 1_000_000_000
            + i64::from(wall0.nanosec)
            + ((t_s - t0) * 1e9).round() as i64;
        Time {
            sec: i32::try_from(ns.div_euclid(1_000_000_000)).unwrap_or(i32::MAX),
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }

    fn publish_status(&mut self, t_s: f64, s: &StatusReport) -> Result<(), BridgeError> {
        let stamp = self.stamp(t_s);
        let n = self.node;
        self.counters.statuses += 1;
        let first = *self.first_status_s.get_or_insert(t_s);
        self.counters.span_s = t_s - first;
        self.last_status_s = self.last_status_s.max(t_s);
        if let Some(m) = convert::measured_cp_msg(s, stamp) {
            published("measured_cp", n.measured_cp.publish(m))?;
        }
        published(
            "measured_js",
            n.measured_js.publish(convert::measured_js_msg(s, stamp)),
        )?;
        if let Some(m) = convert::setpoint_cp_msg(s, stamp) {
            published("setpoint_cp", n.setpoint_cp.publish(m))?;
        }
        if let Some(m) = convert::setpoint_js_msg(self.robot, s, stamp) {
            published("setpoint_js", n.setpoint_js.publish(m))?;
        }
        if let Some(m) = convert::tf_msg(s, stamp) {
            published("/tf", n.tf.publish(m))?;
        }
        let o = operating_state(s);
        let changed = self.last_state != Some((o, s.state));
        if changed || t_s - self.last_slow_s >= SLOW_PERIOD_S {
            self.last_slow_s = t_s;
            self.last_state = Some((o, s.state));
            published(
                "operating_state",
                n.operating_state.publish(OperatingState {
                    header: Header {
                        stamp,
                        frame_id: String::new(),
                    },
                    state: o.state.as_str().to_string(),
                    is_homed: o.is_homed,
                    is_busy: o.is_busy,
                }),
            )?;
            published(
                "diagnostics",
                n.diagnostics.publish(convert::diagnostics_msg(s, stamp)),
            )?;
        }
        Ok(())
    }

    fn refuse(&mut self, text: &str, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        log(text);
        published(
            "refusal",
            self.node.refusal.publish(StdString {
                data: text.to_string(),
            }),
        )
    }

    fn servo_cp(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        let mut newest = None;
        loop {
            match self.node.servo_cp.take() {
                Ok(Some((m, _))) => {
                    if newest.replace(m).is_some() {
                        self.counters.targets_superseded += 1;
                    }
                }
                Ok(None) => break,
                // A sample that could not be read (a peer leaving, a foreign type): not
                // a command.
                Err(e) => {
                    log(&format!("servo_cp: a sample could not be read: {e:?}"));
                    break;
                }
            }
        }
        let Some(msg) = newest else {
            return Ok(());
        };
        let pose = match target_of(&msg) {
            Ok(p) => p,
            Err(e) => {
                self.counters.targets_refused += 1;
                return self.refuse(&format!("servo_cp refused: {e}"), log);
            }
        };
        let outcome = self.board.request_target(&pose)?;
        let why = match outcome {
            Outcome::Ack => {
                self.counters.targets_accepted += 1;
                return Ok(());
            }
            Outcome::Refused(reason) => board_words::reason(reason).to_string(),
            Outcome::TargetRefused(r) => board_words::refusal(&r),
            _ => "the board did not answer the target".to_string(),
        };
        self.counters.targets_refused += 1;
        self.refuse(&format!("servo_cp refused: {why}"), log)
    }

    fn state_commands(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        loop {
            let msg: StringStamped = match self.node.state_command.take() {
                Ok(Some((m, _))) => m,
                Ok(None) => return Ok(()),
                Err(e) => {
                    log(&format!("state_command: a sample could not be read: {e:?}"));
                    return Ok(());
                }
            };
            self.state_command(&msg.string, log)?;
        }
    }

    /// Carries out one `state_command`; a refusal is published with its reason.
    pub fn state_command(
        &mut self,
        word: &str,
        log: &mut dyn FnMut(&str),
    ) -> Result<(), BridgeError> {
        let command: StateCommand = match word.parse() {
            Ok(c) => c,
            Err(e) => {
                self.counters.commands_refused += 1;
                return self.refuse(&format!("state_command refused: {e}"), log);
            }
        };
        let request = match command.request() {
            Ok(r) => r,
            Err(why) => {
                self.counters.commands_refused += 1;
                return self.refuse(&format!("state_command {command} refused: {why}"), log);
            }
        };
        let outcome = match request {
            MasterToBoard::Enable => self.board.enable()?,
            r => self.board.request(r)?,
        };
        match outcome {
            Outcome::Ack => {}
            // CRTK's `home` on a homed robot: nothing to do.
            Outcome::Refused(NackReason::AlreadyHomed) if command == StateCommand::Home => {
                log("state_command home: already homed");
            }
            Outcome::Refused(reason) => {
                self.counters.commands_refused += 1;
                return self.refuse(
                    &format!(
                        "state_command {command} refused: {}",
                        board_words::reason(reason)
                    ),
                    log,
                );
            }
            _ => {
                self.counters.commands_refused += 1;
                return self.refuse(
                    &format!("state_command {command}: the board did not answer"),
                    log,
                );
            }
        }
        self.counters.commands_done += 1;
        log(&format!("state_command {command}: done"));
        Ok(())
    }
}
