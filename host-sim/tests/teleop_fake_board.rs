#![allow(clippy::unwrap_used, clippy::expect_used)]
//! `host-sim teleop` end to end.
//!
//! * `ci_scenario_against_a_fake_board`: the master's whole CI scenario (`--scenario ci
//!   --path line`) over a Unix socket against a small fake board in this process: the
//!   board side of the real link (`control::link::LinkRx` / `LinkTx`: COBS, CRC,
//!   version, sequence numbers, link counters), a toy state machine (homing takes 0.3 s,
//!   the heartbeat holds after 100 ms and faults after 500 ms), targets
//!   followed at once unless outside |x| <= 25 mm (acknowledged, then ignored: the robot
//!   holds). Every check must pass.
//!
//! The same master against the board's release image runs in `host-sim/board-scenarios`.

use control::link::{Answer, Inbound, LinkRx, LinkTx};
use master_link::MasterToBoard as Command;
use master_link::{
    BoardToMaster, FaultCause, FaultRecord, FirmwareVersion, ResetCause, ResetStatus, RobotState,
    StatusReport, StopStatus, Warnings, MAX_FRAME_LEN,
};
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::process::Command as Process;
use std::thread;
use std::time::{Duration, Instant};

/// The fake board's state.
struct Board {
    state: RobotState,
    homed: bool,
    homing_since: Option<Instant>,
    last_beat: Instant,
    position: [f32; 3],
    rotation: [f32; 3],
    /// Targets refused (StatusReport::targets_refused).
    refused: u32,
    /// Refusals of the "path check" not sent yet.
    refusals: Vec<master_link::RefusedTarget>,
    /// The latched fault.
    fault: FaultCause,
}

impl Board {
    fn command(&mut self, c: &Command, now: Instant) -> Result<(), master_link::NackReason> {
        use master_link::NackReason as N;
        match *c {
            Command::Heartbeat => {
                self.last_beat = now;
                Ok(())
            }
            Command::Home { .. } => {
                self.state = RobotState::Homing;
                self.homing_since = Some(now);
                self.last_beat = now;
                Ok(())
            }
            Command::Enable if self.state == RobotState::Fault => Err(N::Faulted),
            Command::Enable if self.homed => {
                self.state = RobotState::Enabled;
                self.last_beat = now;
                Ok(())
            }
            Command::Enable => Err(N::NotHomed),
            Command::Disable => {
                if self.state == RobotState::Enabled {
                    self.state = RobotState::Ready;
                }
                Ok(())
            }
            Command::ClearFault => {
                if self.state == RobotState::Fault {
                    self.state = RobotState::Ready;
                    self.fault = FaultCause::None;
                }
                Ok(())
            }
            Command::PoseTarget {
                timestamp_us,
                position_m,
                rotation_vector_rad,
            } => {
                if self.state != RobotState::Enabled || self.late(now) {
                    return Err(N::InvalidState);
                }
                // Outside the task box: accepted, then refused by the "path check".
                if position_m[0].abs() <= 0.025 {
                    self.position = position_m;
                    self.rotation = rotation_vector_rad;
                } else {
                    self.refused += 1;
                    // As the firmware: the path check's refusal names the guard, the
                    // value and the limit (the face of the box with its margin, 25 mm).
                    self.refusals.push(master_link::RefusedTarget {
                        reply_to: None,
                        timestamp_us,
                        reason: N::OutOfWorkspace,
                        breach: master_link::Breach {
                            guard: master_link::GuardId::Workspace,
                            subject: 0,
                            value: position_m[0],
                            limit: 0.025f32.copysign(position_m[0]),
                        },
                    });
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn late(&self, now: Instant) -> bool {
        now.duration_since(self.last_beat) > Duration::from_millis(100)
    }

    fn tick(&mut self, now: Instant) {
        if let Some(t) = self.homing_since {
            if now.duration_since(t) > Duration::from_millis(300) {
                self.homing_since = None;
                self.homed = true;
                self.state = RobotState::Ready;
                self.position = [0.0, 0.0, 0.16];
            }
        }
        if self.state == RobotState::Enabled
            && now.duration_since(self.last_beat) > Duration::from_millis(500)
        {
            // The heartbeat lost: a fault, stopped as SS1 (brakes, torque off).
            self.state = RobotState::Fault;
            self.fault = FaultCause::HeartbeatTimeout;
        }
    }

    fn status(&self, now: Instant) -> StatusReport {
        let mut warnings = Warnings::NONE;
        warnings.set(Warnings::NOT_HOMED, !self.homed);
        warnings.set(
            Warnings::HEARTBEAT_LATE,
            self.state == RobotState::Enabled && self.late(now),
        );
        let stop = if self.state == RobotState::Fault {
            StopStatus::SafeStop1Done
        } else {
            StopStatus::None
        };
        StatusReport {
            state: self.state,
            position_m: self.position,
            rotation_vector_rad: self.rotation,
            warnings,
            targets_refused: self.refused,
            stop,
            fault: FaultRecord {
                cause: self.fault,
                ..FaultRecord::NONE
            },
            ..Default::default()
        }
    }
}

/// Serves one master on `stream` until it disconnects.
fn fake_board(mut stream: UnixStream) {
    let version = FirmwareVersion {
        major: 9,
        minor: 8,
        patch: 7,
    };
    let mut rx = LinkRx::new();
    let mut tx = LinkTx::new();
    let start = Instant::now();
    let mut board = Board {
        state: RobotState::Disabled,
        homed: false,
        homing_since: None,
        last_beat: start,
        position: [0.0, 0.0, 0.15],
        rotation: [0.0; 3],
        refused: 0,
        refusals: Vec::new(),
        fault: FaultCause::None,
    };
    let _ = stream.set_read_timeout(Some(Duration::from_millis(2)));
    let mut next_status = start;
    let mut buf = [0u8; 1024];
    let mut frame = [0u8; MAX_FRAME_LEN];
    loop {
        let now = Instant::now();
        let mut out: Vec<BoardToMaster> = Vec::new();
        match stream.read(&mut buf) {
            Ok(0) => return,
            Ok(n) => {
                let mut opened = None;
                rx.feed(&buf[..n], |inbound| match inbound {
                    Inbound::Reply(r) => out.push(r),
                    Inbound::Request(req) => {
                        let result = match req.message {
                            Command::Hello { nonce, .. } => Ok(Answer::Hello {
                                nonce,
                                // A power-on reset needs no acknowledgement.
                                reset: ResetStatus {
                                    cause: ResetCause::PowerOn,
                                    acknowledged: true,
                                },
                                geometry_version: 0,
                            }),
                            Command::StatusRequest => Ok(Answer::Status),
                            c => board.command(&c, now).map(|()| Answer::Ack),
                        };
                        let reply = req.reply(result, &board.status(now), version);
                        if let Some(session) = control::link::opened_session(&reply) {
                            opened = Some((session, req.seq));
                        }
                        out.push(reply);
                    }
                    Inbound::Geometry { seq, .. } => out.push(BoardToMaster::GeometryRefused {
                        seq,
                        reason: master_link::GeometryRefusal::Unsupported,
                    }),
                });
                if let Some((session, seq)) = opened {
                    rx.open_session(session, seq);
                }
            }
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => return,
        }
        board.tick(now);
        out.extend(board.refusals.drain(..).map(BoardToMaster::TargetRefused));
        if !rx.connected() {
            next_status = now;
        } else if now >= next_status {
            // Every 20 ms exactly, as the firmware's ticker (the master's clock counts them).
            next_status += Duration::from_millis(20);
            let mut s = board.status(now);
            s.link = rx.counters();
            s.warnings.set(Warnings::LINK_ERRORS, s.link.rejected() > 0);
            out.push(BoardToMaster::Status(s));
        }
        for m in out {
            let Ok(n) = tx.encode(&m, &mut frame) else {
                continue;
            };
            if stream.write_all(&frame[..n]).is_err() {
                return;
            }
        }
    }
}

#[test]
fn ci_scenario_against_a_fake_board() {
    let dir = std::env::temp_dir().join(format!("teleop-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sock = dir.join("board.sock");
    let _ = std::fs::remove_file(&sock);
    let listener = UnixListener::bind(&sock).unwrap();
    let board = thread::spawn(move || {
        if let Ok((stream, _)) = listener.accept() {
            fake_board(stream);
        }
    });
    let out = Process::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "teleop",
            "--scenario",
            "ci",
            "--path",
            "line",
            "--home-timeout-s",
            "5",
        ])
        .arg("--connect")
        .arg(&sock)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "teleop failed:\n{stdout}\n{stderr}");
    for check in [
        "check hello: ok",
        "check homes: ok",
        "check follows the path within the tracking limits: ok",
        "check a target outside the workspace is refused and the robot holds: ok",
        "check garbage on the link is counted and ignored: ok",
        "check when the heartbeat stops the firmware holds, then stops with brakes: ok",
        "check disables: ok",
    ] {
        assert!(stdout.contains(check), "missing `{check}` in:\n{stdout}");
    }
    assert!(stdout.contains("firmware 9.8.7"), "{stdout}");
    let csv = std::fs::read_to_string(dir.join("out").join("status.csv")).unwrap();
    assert!(
        csv.lines().count() > 100,
        "telemetry rows: {}",
        csv.lines().count()
    );
    let _ = board.join();
    let _ = std::fs::remove_dir_all(&dir);
}
