//! `host-sim igtl --connect <board> --listen <port>`: the OpenIGTLink server of the `igtl`
//! crate in front of a live board, for 3D Slicer (OpenIGTLinkIF), PLUS and tracked
//! instruments.
//!
//! - **Targets**: a TRANSFORM (or POSITION / QTRANS) to device `Target` is a pose of the
//!   platform frame {p} in the client frame (the robot base {0} unless a registration is
//!   set; millimetres on the wire). It becomes one `PoseTarget` to the board, through the
//!   board's supervisor like every other target (admission, path check, speed profile),
//!   and the bridge waits for the board's answer: a refusal goes back to the client as a
//!   STATUS with the reason's code and the board's reason in words. A position-only
//!   target (12-byte POSITION) keeps the setpoint's orientation. A target the path check
//!   refuses later (the straight path crosses a stop-level guard) is not answered by the
//!   board; the state text then says so (the supervisor's refusal counter grew).
//! - **Pose**: the measured pose (`measured_cp`) of the latest status, streamed as
//!   TRANSFORM to device `Robot` at the configured rate, and answered to `GET_TRANS`,
//!   `GET_POSITION`, `GET_QTRANS`.
//! - **State**: the board's state, stop and fault as STATUS (device `RobotStatus`) and
//!   STRING (device `RobotState`), answered to `GET_STATUS` / `GET_STRING`.
//! - Unknown and malformed messages are counted and answered as the `igtl` crate's README
//!   says; a client's bad input never closes another client or the bridge.

use crate::board::{refusal_text, Board, BoardEvent, Outcome};
use crate::conversions::{measured_cp, setpoint_cp};
use crate::error::OperatorError;
use igtl::{
    Condition, PoseSi, Refusal, RefusalReason, Robot, RobotState as IgtlState, Server,
    ServerConfig, TargetPose,
};
use kinematics_core::Pose;
use master_link::{FaultCause, NackReason, RobotState, StatusReport};
use masters::CartesianPose;
use nalgebra::{Rotation3, UnitQuaternion};
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The board as the OpenIGTLink server's robot.
pub struct BoardRobot<'a> {
    board: &'a mut Board,
    status: Option<StatusReport>,
    /// The supervisor's refusal counter when the last target was accepted.
    refused_at_accept: Option<u32>,
    /// Targets accepted and refused by the board.
    pub accepted: u64,
    /// Targets refused (at once, or later by the board's path check).
    pub refused: u64,
    /// The stamps of the newest targets the board accepted and the clients that sent them.
    senders: VecDeque<(u64, SocketAddr)>,
    /// Refusals of the board's path check not handed to the server yet.
    later: Vec<(SocketAddr, Refusal)>,
}

/// Accepted targets whose sender is remembered for a later refusal.
const SENDERS_KEPT: usize = 64;

impl<'a> BoardRobot<'a> {
    /// Around a board (brought up or not: the state tells the clients).
    pub fn new(board: &'a mut Board) -> Self {
        let status = board.status().map(|(_, s)| *s);
        BoardRobot {
            board,
            status,
            refused_at_accept: None,
            accepted: 0,
            refused: 0,
            senders: VecDeque::new(),
            later: Vec::new(),
        }
    }

    /// The board.
    pub fn board(&mut self) -> &mut Board {
        self.board
    }

    /// Receives from the board for at most `wait` (statuses, heartbeats, targets its path
    /// check refused: each becomes a refusal for the client that sent the target).
    pub fn poll_board(&mut self, wait: Duration) -> Result<(), OperatorError> {
        for e in self.board.poll(wait)? {
            match e {
                BoardEvent::Status(_, s) => self.status = Some(s),
                BoardEvent::TargetRefused(_, r) => self.refused_later(&r),
                BoardEvent::Reply(_) => {}
            }
        }
        Ok(())
    }

    /// A target the board's path check refused after its `Ack`, for its sender.
    fn refused_later(&mut self, r: &master_link::RefusedTarget) {
        let Some(&(_, peer)) = self
            .senders
            .iter()
            .find(|(stamp, _)| *stamp == r.timestamp_us)
        else {
            return;
        };
        self.refused += 1;
        let state = self.status.map(|s| s.state);
        self.later.push((
            peer,
            Refusal::new(
                refusal_reason(r.reason, state),
                format!(
                    "board refused the target after accepting it (path check): {}",
                    board_words::refusal(r)
                ),
            ),
        ));
    }

    fn current_orientation(&self) -> Option<UnitQuaternion<f64>> {
        let s = self.status.as_ref()?;
        setpoint_cp(s)
            .or_else(|| measured_cp(s))
            .map(|p| p.orientation)
    }
}

/// The OpenIGTLink refusal for a board's refusal in state `state`.
pub fn refusal_reason(reason: NackReason, state: Option<RobotState>) -> RefusalReason {
    match reason {
        NackReason::OutOfWorkspace
        | NackReason::JointLimit
        | NackReason::NearSingularity
        | NackReason::VelocityLimit => RefusalReason::Unreachable,
        NackReason::NotHomed | NackReason::NotConnected | NackReason::ResetNotAcknowledged => {
            RefusalReason::NotReady
        }
        NackReason::InvalidState => match state {
            Some(RobotState::Ready | RobotState::Disabled) => RefusalReason::Disabled,
            Some(RobotState::Boot | RobotState::Homing | RobotState::Enabling) => {
                RefusalReason::NotReady
            }
            Some(RobotState::Fault) => RefusalReason::SafetyStop,
            _ => RefusalReason::Busy,
        },
        NackReason::Faulted | NackReason::FaultStillActive | NackReason::SafetyRelayMismatch => {
            RefusalReason::SafetyStop
        }
        NackReason::BrakeCheckFailed => RefusalReason::HardwareFailure,
        NackReason::Busy
        | NackReason::OperatorAbsent
        | NackReason::ClutchDisengaged
        | NackReason::NotOwner => RefusalReason::Busy,
        NackReason::UnsupportedVersion
        | NackReason::InvalidJoint
        | NackReason::InvalidValue
        | NackReason::StaleTarget
        | NackReason::TargetFromFuture
        | NackReason::ReplayedHello
        | NackReason::AlreadyHomed => RefusalReason::Other,
    }
}

impl Robot for BoardRobot<'_> {
    fn submit_target(&mut self, target: &TargetPose) -> Result<(), Refusal> {
        let orientation = match target.r {
            Some(r) => UnitQuaternion::from_rotation_matrix(&r),
            None => self.current_orientation().ok_or_else(|| {
                Refusal::new(
                    RefusalReason::NotReady,
                    "a position-only target needs the robot's orientation: no status yet",
                )
            })?,
        };
        let pose = CartesianPose {
            position_m: target.t,
            orientation,
        };
        let (outcome, stamp_us) = self
            .board
            .request_target_stamped(&pose)
            .map_err(|e| Refusal::new(RefusalReason::HardwareFailure, e.to_string()))?;
        // Statuses that came while waiting.
        if let Some((_, s)) = self.board.status() {
            self.status = Some(*s);
        }
        match outcome {
            Outcome::Ack => {
                self.accepted += 1;
                self.refused_at_accept = self.status.map(|s| s.targets_refused);
                // The board's path check may refuse it later: its answer goes to this
                // client.
                if self.senders.len() >= SENDERS_KEPT {
                    self.senders.pop_front();
                }
                self.senders.push_back((stamp_us, target.peer));
                Ok(())
            }
            Outcome::Refused(reason) => {
                self.refused += 1;
                let state = self.status.map(|s| s.state);
                Err(Refusal::new(
                    refusal_reason(reason, state),
                    format!("board refused the target: {}", refusal_text(reason)),
                ))
            }
            Outcome::TargetRefused(r) => {
                self.refused += 1;
                let state = self.status.map(|s| s.state);
                Err(Refusal::new(
                    refusal_reason(r.reason, state),
                    format!("board refused the target: {}", board_words::refusal(&r)),
                ))
            }
            _ => {
                self.refused += 1;
                Err(Refusal::new(
                    RefusalReason::Other,
                    "the board did not answer the target",
                ))
            }
        }
    }

    fn measured_pose(&self) -> Option<PoseSi> {
        let p = measured_cp(self.status.as_ref()?)?;
        Some(Pose {
            t: p.position_m,
            r: Rotation3::from(p.orientation),
        })
    }

    fn take_later_refusals(&mut self) -> Vec<(SocketAddr, Refusal)> {
        std::mem::take(&mut self.later)
    }

    fn state(&self) -> IgtlState {
        let Some(s) = self.status else {
            return IgtlState {
                condition: Condition::NotReady,
                detail: "no status from the board yet".into(),
            };
        };
        state_of(&s, self.refused_at_accept)
    }
}

/// The OpenIGTLink state of a board status; `refused_at_accept` is the supervisor's
/// refusal counter when the last target was accepted.
pub fn state_of(s: &StatusReport, refused_at_accept: Option<u32>) -> IgtlState {
    let (condition, detail) = match s.state {
        RobotState::Boot => (Condition::NotReady, "booting".to_string()),
        RobotState::Homing => (Condition::NotReady, "homing".to_string()),
        RobotState::Enabling => (Condition::NotReady, "enabling (brake check)".to_string()),
        RobotState::Commissioning => (Condition::NotReady, "commissioning".to_string()),
        RobotState::Disabled => (
            Condition::Disabled,
            "drives off, not homed: home it".to_string(),
        ),
        RobotState::Ready => (
            Condition::Disabled,
            "homed, drives off: enable it".to_string(),
        ),
        RobotState::Fault => {
            let f = s.fault;
            let hardware = !matches!(
                f.cause,
                FaultCause::EmergencyStopButton
                    | FaultCause::EmergencyStopMessage
                    | FaultCause::HeartbeatTimeout
                    | FaultCause::Singularity
                    | FaultCause::GuardStop
            );
            (
                if hardware {
                    Condition::HardwareFailure
                } else {
                    Condition::SafetyStop
                },
                format!(
                    "fault: {}{}",
                    board_words::fault(&f).unwrap_or_else(|| "not reported".to_string()),
                    board_words::stop(s.state, s.stop)
                        .map_or(String::new(), |stop| format!("; {stop}"))
                ),
            )
        }
        RobotState::Enabled => {
            let moving = match (measured_cp(s), setpoint_cp(s)) {
                (Some(m), Some(sp)) => (m.position_m - sp.position_m).norm() > 2e-5,
                _ => false,
            };
            let later = refused_at_accept
                .map(|r| s.targets_refused.wrapping_sub(r))
                .filter(|n| *n > 0);
            let mut detail = if let Some(stop) = board_words::stop(s.state, s.stop) {
                stop.to_string()
            } else if moving {
                "moving".to_string()
            } else {
                "holding".to_string()
            };
            if let Some(n) = later {
                detail.push_str(&format!(
                    "; {n} target(s) refused by the supervisor's path check since the last accepted"
                ));
            }
            (
                if moving {
                    Condition::Moving
                } else {
                    Condition::Ready
                },
                detail,
            )
        }
    };
    IgtlState { condition, detail }
}

/// Serves OpenIGTLink on `server` for the board in `robot` until `stop`: the board is
/// polled every `tick`, the server after it; `report` hears connections and refusals.
pub fn serve(
    server: &mut Server,
    robot: &mut BoardRobot<'_>,
    stop: &AtomicBool,
    tick: Duration,
    report: &mut dyn FnMut(&str),
) -> Result<(), OperatorError> {
    while !stop.load(Ordering::Relaxed) {
        robot.poll_board(tick)?;
        let r = server.poll(robot);
        for a in &r.accepted {
            report(&format!("client {a} connected"));
        }
        for (a, why) in &r.closed {
            match why {
                igtl::server::CloseReason::NotAllowed(ip) => report(&format!(
                    "client {a} refused: {ip} is not in the allow-list (--allow)"
                )),
                igtl::server::CloseReason::BadToken(what) => report(&format!(
                    "client {a} refused: no valid token (--token-file): it sent {what}"
                )),
                igtl::server::CloseReason::PeerClosed => {
                    report(&format!("client {a} closed the connection"))
                }
                igtl::server::CloseReason::Io(e) => {
                    report(&format!("client {a} closed: read or write failed: {e}"))
                }
                igtl::server::CloseReason::Backlog(n) => report(&format!(
                    "client {a} closed: it did not read ({n} bytes queued)"
                )),
                igtl::server::CloseReason::ServerFull => {
                    report(&format!("client {a} refused: the server is full"))
                }
            }
        }
        if let Some(e) = &r.accept_error {
            report(&format!("accept: {e}"));
        }
    }
    Ok(())
}

/// The server settings of the bridge: pose stream at `rate_hz`, the registration.
pub fn server_config(rate_hz: f64, registration: igtl::Registration) -> ServerConfig {
    ServerConfig {
        pose_period: Duration::from_secs_f64(1.0 / rate_hz),
        registration,
        ..ServerConfig::default()
    }
}
