//! The node in front of a live board: the board's state published, the ROS 2 commands sent
//! to it, every refusal reported back with its reason.
//!
//! - **Rates.** The board sends a status every 20 ms; the bridge asks for one
//!   (`StatusRequest`) whenever [`STATUS_PERIOD_S`] has passed on the board's clock without
//!   one: `measured_cp`, `measured_js`, `setpoint_cp`, `setpoint_js`, `/joint_states`
//!   and `/tf` are published once per status, at 100 Hz or more (measured by `ros2-board.sh` on the
//!   simulated board: 127 Hz, the median interval 9.8 ms, the longest 20 ms when a
//!   request's answer and a periodic status coincide; each
//!   message a new status, none repeated). Their stamps are the board's clock (the
//!   front ends' paced clock, `teleop::pacing`) anchored to the host's clock at the first
//!   status: when the board measured, not when the host got round to it. `operating_state` is published when it changes
//!   and every [`SLOW_PERIOD_S`], the diagnostics every [`SLOW_PERIOD_S`] and when the
//!   board's state changes.
//! - **`/joint_states` and `/tf`**: every joint of the robot description at the measured
//!   joints (the forward kinematics of the status's encoders, then the description's
//!   joint states at that pose, [`convert::measured_joint_states`]): the actuated ones
//!   equal `measured_js`, the passive ones (spherical joints, pins) are computed; `/tf` is
//!   every joint's transform from its parent link to its child, so the frames from `base`
//!   to `platform` need no `robot_state_publisher`. A status whose joints have no forward
//!   kinematics (joints that no pose has) gets neither; the reason is logged when it
//!   changes, and the summary counts such statuses.
//! - **`servo_cp`**: the newest pose received becomes one target to the board, through the
//!   board's supervisor like every target (admission, path check, speed profile); older
//!   ones still queued are dropped (a servo stream wants its latest). The bridge waits for
//!   the board's answer; a refusal is published on `refusal` (`std_msgs/String`) as
//!   `servo_cp refused: <the board's reason in words>`, e.g. `servo_cp refused: workspace
//!   z 250.0 mm > 175.0 mm`, and so is a target the board's path check refuses after
//!   accepting it.
//! - **`servo_jp`** (`sensor_msgs/JointState`, the six actuated joints by name, in any
//!   order, SI): the forward kinematics of the joints (from the measured pose, on the
//!   description's branch) becomes the pose target, sent as `servo_cp`'s is; only the
//!   newest is taken. A message with a wrong count of names or positions, a name that is
//!   not an actuated joint, a value that is not finite, or joints with no forward
//!   kinematics is refused on `refusal` as `servo_jp refused: <what is wrong>`; the board's
//!   refusals of the pose as `servo_jp refused: <the board's reason>`.
//! - While the robot is paused (`state_command pause`: the board holds under SS2), the
//!   board refuses every target; the refusal says so: `... refused: not allowed in this
//!   state (the robot is paused: state_command resume)`.
//! - **`state_command`** (`crtk_msgs/StringStamped`): CRTK's words as the board's requests
//!   ([`crate::crtk`]); a refusal is published as `state_command <word> refused: <reason>`.
//!
//! Refusal words are those of `board_words`, the same as the console's and the
//! OpenIGTLink bridge's.

use crate::convert::{self, target_of, target_of_joints};
use crate::crtk::{operating_state, MetaState, Operating, StateCommand};
use crate::messages::{Header, JointState, OperatingState, StdString, StringStamped, Time};
use crate::node::RosNode;
use kinematics_core::{Mechanism, Pose};
use master_link::{MasterToBoard, NackReason, RobotState, StatusReport};
use masters::CartesianPose;
use operator::board::{Board, BoardError, BoardEvent, Outcome};
use operator::conversions::measured_cp;
use robot_description::Description;
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
    /// `servo_jp` targets accepted by the board.
    pub joint_targets_accepted: u64,
    /// `servo_jp` targets refused (by the bridge or by the board).
    pub joint_targets_refused: u64,
    /// `servo_jp` messages dropped for a newer one.
    pub joint_targets_superseded: u64,
    /// Statuses whose measured joints had no forward kinematics: no `/joint_states` and
    /// `/tf` for them.
    pub unposed: u64,
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

/// The bridge between `board` and `node`; `description` is that of the geometry the
/// board runs (for `setpoint_js`, `/joint_states`, `/tf` and `servo_jp`).
pub struct Bridge<'a> {
    board: &'a mut Board,
    node: &'a RosNode,
    description: &'a Description,
    counters: Counters,
    first_status_s: Option<f64>,
    last_status_s: f64,
    last_request_s: f64,
    last_state: Option<(Operating, RobotState)>,
    last_slow_s: f64,
    /// The host's clock and the board's at the first status.
    anchor: Option<(Time, f64)>,
    /// The pose of the last measured joints (their forward kinematics).
    pose: Option<Pose<f64>>,
    /// The last reason a status could not be posed (logged when it changes).
    unposed_reason: Option<String>,
    /// The last refusal logged, and how many times it came again since.
    last_refusal: Option<String>,
    refusal_repeats: u64,
}

fn published<E: std::fmt::Debug>(topic: &'static str, r: Result<(), E>) -> Result<(), BridgeError> {
    r.map_err(|e| BridgeError::Publish {
        topic,
        error: format!("{e:?}"),
    })
}

impl<'a> Bridge<'a> {
    /// Around a board (brought up or only greeted: the state tells the ROS side).
    pub fn new(board: &'a mut Board, node: &'a RosNode, description: &'a Description) -> Self {
        Bridge {
            board,
            node,
            description,
            counters: Counters::default(),
            first_status_s: None,
            last_status_s: f64::NEG_INFINITY,
            last_request_s: f64::NEG_INFINITY,
            last_state: None,
            last_slow_s: f64::NEG_INFINITY,
            anchor: None,
            pose: None,
            unposed_reason: None,
            last_refusal: None,
            refusal_repeats: 0,
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
        self.servo_jp(log)?;
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
                BoardEvent::Status(t, s) => self.publish_status(t, &s, log)?,
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

    fn publish_status(
        &mut self,
        t_s: f64,
        s: &StatusReport,
        log: &mut dyn FnMut(&str),
    ) -> Result<(), BridgeError> {
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
        if let Some(m) = convert::setpoint_js_msg(self.description.robot(), s, stamp) {
            published("setpoint_js", n.setpoint_js.publish(m))?;
        }
        self.publish_joint_states(s, stamp, log)?;
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

    /// `/joint_states` and `/tf` at the measured joints of `s`.
    fn publish_joint_states(
        &mut self,
        s: &StatusReport,
        stamp: Time,
        log: &mut dyn FnMut(&str),
    ) -> Result<(), BridgeError> {
        let d = self.description;
        let guess = measured_cp(s)
            .map(|p| convert::kinematic_pose(&p))
            .or(self.pose)
            .unwrap_or_else(|| Pose::central(d.robot().hc()));
        let q = s.joints.map(f64::from);
        let states = match convert::measured_joint_states(d, q, &guess) {
            Ok((pose, states)) => {
                self.pose = Some(pose);
                self.unposed_reason = None;
                states
            }
            Err(e) => {
                self.counters.unposed += 1;
                let why = e.to_string();
                if self.unposed_reason.as_deref() != Some(why.as_str()) {
                    log(&format!("/joint_states and /tf not published: {why}"));
                    self.unposed_reason = Some(why);
                }
                return Ok(());
            }
        };
        let n = self.node;
        published(
            "/joint_states",
            n.joint_states
                .publish(convert::joint_states_msg(&states, stamp)),
        )?;
        match convert::tf_msg(d, &states, stamp) {
            Some(m) => published("/tf", n.tf.publish(m)),
            None => {
                self.counters.unposed += 1;
                log("/tf not published: a joint of the description has no value");
                Ok(())
            }
        }
    }

    /// Publishes a refusal on `refusal`, every one of them; the log hears a refusal
    /// repeated back to back (a servo stream while paused) once, and how many times it
    /// came when another follows.
    fn refuse(&mut self, text: &str, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        if self.last_refusal.as_deref() == Some(text) {
            self.refusal_repeats += 1;
        } else {
            if self.refusal_repeats > 0 {
                log(&format!(
                    "(the refusal before repeated {} more times)",
                    self.refusal_repeats
                ));
            }
            self.refusal_repeats = 0;
            self.last_refusal = Some(text.to_string());
            log(text);
        }
        published(
            "refusal",
            self.node.refusal.publish(StdString {
                data: text.to_string(),
            }),
        )
    }

    /// The newest sample of `subscription`, counting the older ones dropped.
    fn newest<T: serde::de::DeserializeOwned + 'static>(
        subscription: &ros2_client::dds::Subscription<T>,
        topic: &str,
        superseded: &mut u64,
        log: &mut dyn FnMut(&str),
    ) -> Option<T> {
        let mut newest = None;
        loop {
            match subscription.take() {
                Ok(Some((m, _))) => {
                    if newest.replace(m).is_some() {
                        *superseded += 1;
                    }
                }
                Ok(None) => break,
                // A sample that could not be read (a peer leaving, a foreign type): not
                // a command.
                Err(e) => {
                    log(&format!("{topic}: a sample could not be read: {e:?}"));
                    break;
                }
            }
        }
        newest
    }

    fn servo_cp(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        let Some(msg) = Self::newest(
            &self.node.servo_cp,
            "servo_cp",
            &mut self.counters.targets_superseded,
            log,
        ) else {
            return Ok(());
        };
        let accepted = match target_of(&msg) {
            Ok(pose) => self.send_target("servo_cp", &pose, log)?,
            Err(e) => {
                self.refuse(&format!("servo_cp refused: {e}"), log)?;
                false
            }
        };
        if accepted {
            self.counters.targets_accepted += 1;
        } else {
            self.counters.targets_refused += 1;
        }
        Ok(())
    }

    fn servo_jp(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), BridgeError> {
        let Some(msg): Option<JointState> = Self::newest(
            &self.node.servo_jp,
            "servo_jp",
            &mut self.counters.joint_targets_superseded,
            log,
        ) else {
            return Ok(());
        };
        let d = self.description;
        let guess = self.pose.unwrap_or_else(|| Pose::central(d.robot().hc()));
        let accepted = match target_of_joints(d.robot(), d.branch(), &msg, &guess) {
            Ok(pose) => self.send_target("servo_jp", &pose, log)?,
            Err(e) => {
                self.refuse(&format!("servo_jp refused: {e}"), log)?;
                false
            }
        };
        if accepted {
            self.counters.joint_targets_accepted += 1;
        } else {
            self.counters.joint_targets_refused += 1;
        }
        Ok(())
    }

    /// Sends a target of `topic` to the board and waits for its answer: whether it was
    /// accepted; a refusal is published with the board's reason.
    fn send_target(
        &mut self,
        topic: &str,
        pose: &CartesianPose,
        log: &mut dyn FnMut(&str),
    ) -> Result<bool, BridgeError> {
        let outcome = self.board.request_target(pose)?;
        let paused = matches!(self.last_state, Some((o, _)) if o.state == MetaState::Paused);
        let why = match outcome {
            Outcome::Ack => return Ok(true),
            Outcome::Refused(NackReason::InvalidState) if paused => format!(
                "{} (the robot is paused: state_command resume)",
                board_words::reason(NackReason::InvalidState)
            ),
            Outcome::Refused(reason) => board_words::reason(reason).to_string(),
            Outcome::TargetRefused(r) => board_words::refusal(&r),
            _ => "the board did not answer the target".to_string(),
        };
        self.refuse(&format!("{topic} refused: {why}"), log)?;
        Ok(false)
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
