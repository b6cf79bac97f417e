//! `host-sim console --connect <serial device | socket>`: the terminal console of a person
//! at the robot (ratatui), usable at 80x24 with its keys on screen.
//!
//! It shows, live from the board's status (every 20 ms): the state and the stop in force,
//! homed or not, the latched fault with its cause, joint and value, the last reset, the
//! measured pose and joints (`measured_cp`), the setpoint (`setpoint_cp`), the guard
//! margins, the link counters of both directions and the tick timing. Every command shows
//! the board's answer in the replies pane; a refusal says why in words.
//!
//! | key | command |
//! | --- | --- |
//! | `h` | Hello (sent at start too) |
//! | `o` | Home; when the robot is homed already, the console asks, and `y` sends `Home { rehome: true }` (the confirmation the firmware requires) |
//! | `e` | Enable (sent again while the board answers `Busy`: its brakes engage for ~100 ms after homing or a disable) |
//! | `d` | Disable |
//! | `c` | Clear fault |
//! | `s`, Space | Stop (`EmergencyStop`: a latched fault, the board stops) |
//! | `1`..`6` | select the joint to jog (l1 l2 l3 th1 th2 th3) |
//! | `+`/`→`, `-`/`←` | jog the selected joint: `Jog` every 20 ms for 0.3 s after the key (a held key repeats) |
//! | `[`, `]` | jog speed down, up |
//! | `k` | clutch engaged / released (engaged: the robot holds) |
//! | `p` | operator present / absent (the dead-man: absent, the robot holds) |
//! | `a` | acknowledge the board's last reset: the console names the cause and asks; `y` sends `AcknowledgeReset` (no front end acknowledges a reset by itself) |
//! | `t` | type a pose target: a line `x y z rx ry rz` (mm, and the rotation vector in deg, `CONVENTIONS.md`), Enter sends it as a `PoseTarget`, Esc cancels; a line that is not six numbers is refused on the spot, naming what is wrong |
//! | `q`, Esc | quit |
//!
//! A typed target goes through the board's supervisor like any other: the board answers it
//! (`Ack`, or refused with the guard, the value and the limit: "workspace z 177.0 mm >
//! 175.0 mm", "stroke leg 2 212.4 mm > 210.0 mm", "not homed: home the robot first"), and
//! a refusal of its path check after the `Ack` is shown too.
//!
//! Whatever ends the console (`q`, Ctrl-C, SIGINT, SIGTERM, an error), the robot is
//! disabled on the way out (`crate::shutdown`).

use crate::board::{refusal_text, request_name, Board, BoardEvent, HelloInfo, Outcome, Reply};
use crate::conversions::{measured_cp, setpoint_cp};
use crate::error::OperatorError;
use master_link::{LinkCounters, MasterToBoard, NackReason, RobotState, StatusReport, Warnings};
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::Rect;
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph};
use ratatui::Frame;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// How long one jog key press keeps the joint moving, s.
pub const JOG_PULSE_S: f64 = 0.3;
/// Period of the `Jog` messages of a jog stream, s (the board stops a jog 0.1 s after the
/// last one).
pub const JOG_PERIOD_S: f64 = 0.02;
/// Jog speeds: legs in mm/s and links in deg/s, the same step for both.
pub const JOG_SPEEDS: [f64; 5] = [0.2, 0.5, 1.0, 2.0, 5.0];
/// Replies kept on screen.
const REPLIES_SHOWN: usize = 6;

const JOINT_NAMES: [&str; 6] = ["l1", "l2", "l3", "th1", "th2", "th3"];

/// A command the console sends (what a key asks for). (Copy, one per key press: the
/// request's size, set by the calibrated geometry's message, is kept inline.)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Send this request.
    Send(MasterToBoard),
    /// Start or extend a jog stream of the selected joint in this direction (+1 / -1).
    Jog(f64),
    /// Send this pose target (`PoseTarget`, stamped with the link's clock).
    Target(masters::CartesianPose),
    /// Leave (the loop disables an enabled board first).
    Quit,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct JogStream {
    joint: usize,
    velocity: f32,
    until_s: f64,
    last_sent_s: f64,
    answered: bool,
}

/// The console's state: what the board said, the replies, the jog settings, a question
/// being asked. Pure: keys in, actions out; the loop does the I/O.
#[derive(Clone, Debug)]
pub struct Console {
    /// The board's name (socket or device).
    pub board_name: String,
    /// The latest status and its time.
    pub status: Option<(f64, StatusReport)>,
    /// The board's HelloReply.
    pub hello: Option<HelloInfo>,
    /// The master side's receive counters.
    pub host_counters: LinkCounters,
    /// The longest interval between two heartbeats this console sent, s.
    pub heartbeat_gap_max_s: f64,
    /// Replies, newest last: (time, text, refused).
    pub replies: VecDeque<(f64, String, bool)>,
    /// The joint jogged (0..6).
    pub joint: usize,
    /// Index into [`JOG_SPEEDS`].
    pub speed: usize,
    /// The last clutch and presence states sent.
    pub clutch: bool,
    /// Operator present (the board's default).
    pub present: bool,
    /// Waiting for `y` to re-home.
    pub confirm_rehome: bool,
    /// Waiting for `y` to acknowledge the reset of this cause.
    pub confirm_reset: Option<master_link::ResetCause>,
    /// The pose target being typed (`t` opened it).
    pub target_input: Option<String>,
    jog: Option<JogStream>,
    enable_retry_until: Option<f64>,
    enable_retry_at: Option<f64>,
}

impl Console {
    /// A console for `board_name` with nothing received yet.
    pub fn new(board_name: &str) -> Self {
        Console {
            board_name: board_name.into(),
            status: None,
            hello: None,
            host_counters: LinkCounters::default(),
            heartbeat_gap_max_s: 0.0,
            replies: VecDeque::new(),
            joint: 0,
            speed: 2,
            clutch: false,
            present: false,
            confirm_rehome: false,
            confirm_reset: None,
            target_input: None,
            jog: None,
            enable_retry_until: None,
            enable_retry_at: None,
        }
    }

    fn homed(&self) -> Option<bool> {
        self.status
            .map(|(_, s)| !s.warnings.contains(Warnings::NOT_HOMED))
    }

    /// A line in the replies pane.
    pub fn note(&mut self, t_s: f64, text: String, refused: bool) {
        self.replies.push_back((t_s, text, refused));
        while self.replies.len() > 64 {
            self.replies.pop_front();
        }
    }

    /// What a key does.
    pub fn key(&mut self, code: KeyCode, modifiers: KeyModifiers, t_s: f64) -> Vec<Action> {
        if self.target_input.is_some() {
            return self.target_key(code, modifiers, t_s);
        }
        if let Some(cause) = self.confirm_reset.take() {
            if code == KeyCode::Char('y') {
                return vec![Action::Send(MasterToBoard::AcknowledgeReset)];
            }
            self.note(
                t_s,
                format!("{} reset not acknowledged", board_words::reset_cause(cause)),
                false,
            );
            return vec![];
        }
        if self.confirm_rehome {
            self.confirm_rehome = false;
            if code == KeyCode::Char('y') {
                return vec![Action::Send(MasterToBoard::Home { rehome: true })];
            }
            self.note(t_s, "re-homing cancelled".into(), false);
            return vec![];
        }
        if modifiers.contains(KeyModifiers::CONTROL) && code == KeyCode::Char('c') {
            return vec![Action::Quit];
        }
        let send = |m| vec![Action::Send(m)];
        match code {
            // (The board's link puts this connection's nonce and clock in.)
            KeyCode::Char('h') => send(MasterToBoard::Hello {
                protocol_version: master_link::PROTOCOL_VERSION,
                nonce: 0,
                clock_us: 0,
            }),
            KeyCode::Char('o') => {
                if self.homed() == Some(true) {
                    self.confirm_rehome = true;
                    vec![]
                } else {
                    send(MasterToBoard::Home { rehome: false })
                }
            }
            KeyCode::Char('e') => {
                self.enable_retry_until = Some(t_s + crate::board::ENABLE_BUSY_WINDOW_S);
                send(MasterToBoard::Enable)
            }
            KeyCode::Char('d') => send(MasterToBoard::Disable),
            KeyCode::Char('c') => send(MasterToBoard::ClearFault),
            KeyCode::Char('s' | ' ') => {
                self.jog = None;
                send(MasterToBoard::EmergencyStop)
            }
            KeyCode::Char(c @ '1'..='6') => {
                self.joint = usize::from(c as u8 - b'1');
                self.jog = None;
                vec![]
            }
            KeyCode::Char('+' | '=') | KeyCode::Right => vec![Action::Jog(1.0)],
            KeyCode::Char('-') | KeyCode::Left => vec![Action::Jog(-1.0)],
            KeyCode::Char('[') => {
                self.speed = self.speed.saturating_sub(1);
                vec![]
            }
            KeyCode::Char(']') => {
                self.speed = (self.speed + 1).min(JOG_SPEEDS.len() - 1);
                vec![]
            }
            KeyCode::Char('k') => send(MasterToBoard::Clutch {
                engaged: !self.clutch,
            }),
            KeyCode::Char('p') => send(MasterToBoard::OperatorPresent {
                present: !self.present,
            }),
            KeyCode::Char('a') => {
                let reset = self
                    .status
                    .map(|(_, s)| s.reset)
                    .or(self.hello.map(|h| h.reset));
                match reset {
                    Some(r) if !r.acknowledged => {
                        self.confirm_reset = Some(r.cause);
                        vec![]
                    }
                    _ => {
                        self.note(t_s, "no reset to acknowledge".into(), false);
                        vec![]
                    }
                }
            }
            KeyCode::Char('t') => {
                self.target_input = Some(String::new());
                vec![]
            }
            KeyCode::Char('q') | KeyCode::Esc => vec![Action::Quit],
            _ => vec![],
        }
    }

    /// A key while a pose target is being typed: characters, Backspace, Enter (checks the
    /// line and sends it, or notes what is wrong and keeps it open), Esc (cancels);
    /// Ctrl-C still quits.
    fn target_key(&mut self, code: KeyCode, modifiers: KeyModifiers, t_s: f64) -> Vec<Action> {
        if modifiers.contains(KeyModifiers::CONTROL) && code == KeyCode::Char('c') {
            return vec![Action::Quit];
        }
        let Some(line) = self.target_input.as_mut() else {
            return vec![];
        };
        match code {
            KeyCode::Char(c) if line.chars().count() < TARGET_INPUT_MAX => line.push(c),
            KeyCode::Backspace => {
                line.pop();
            }
            KeyCode::Esc => {
                self.target_input = None;
                self.note(t_s, "target cancelled".into(), false);
            }
            KeyCode::Enter => match parse_target(line) {
                Ok(mm_deg) => match masters::CartesianPose::from_mm_deg(mm_deg) {
                    Ok(pose) => {
                        self.target_input = None;
                        self.note(t_s, format!("Target {} sent", mm_deg_text(&mm_deg)), false);
                        return vec![Action::Target(pose)];
                    }
                    Err(_) => self.note(t_s, "target: a number is not finite".into(), true),
                },
                Err(e) => self.note(t_s, format!("target not sent: {e}"), true),
            },
            _ => {}
        }
        vec![]
    }

    /// The jog velocity of the selected joint in direction `dir`: m/s or rad/s.
    fn jog_velocity(&self, dir: f64) -> f32 {
        let v = JOG_SPEEDS.get(self.speed).copied().unwrap_or(1.0) * dir;
        (if self.joint < 3 {
            v * 1e-3
        } else {
            v.to_radians()
        }) as f32
    }

    /// Starts or extends the jog stream.
    fn start_jog(&mut self, dir: f64, t_s: f64) {
        let velocity = self.jog_velocity(dir);
        match &mut self.jog {
            Some(j) if j.joint == self.joint && j.velocity == velocity => {
                j.until_s = t_s + JOG_PULSE_S;
            }
            _ => {
                self.jog = Some(JogStream {
                    joint: self.joint,
                    velocity,
                    until_s: t_s + JOG_PULSE_S,
                    last_sent_s: f64::NEG_INFINITY,
                    answered: false,
                });
            }
        }
    }

    /// The jog message due at `t_s`, if any.
    fn jog_due(&mut self, t_s: f64) -> Option<MasterToBoard> {
        let j = self.jog.as_mut()?;
        if t_s > j.until_s {
            self.jog = None;
            return None;
        }
        if t_s - j.last_sent_s < JOG_PERIOD_S {
            return None;
        }
        j.last_sent_s = t_s;
        Some(MasterToBoard::Jog {
            joint: j.joint as u8,
            velocity: j.velocity,
        })
    }

    /// Takes what the board sent.
    pub fn board_event(&mut self, e: &BoardEvent) -> Option<MasterToBoard> {
        match e {
            BoardEvent::Status(t, s) => {
                self.status = Some((*t, *s));
                None
            }
            BoardEvent::Reply(r) => self.reply(r),
            BoardEvent::TargetRefused(t, r) => {
                self.note(
                    *t,
                    format!("Target REFUSED (path): {}", board_words::refusal(r)),
                    true,
                );
                None
            }
        }
    }

    /// A reply: noted (a jog stream's first answer and its refusals only); an Enable
    /// refused with `Busy` is sent again 50 ms later within its window (the returned
    /// request is due then: the loop sends it when `enable_due` says so).
    fn reply(&mut self, r: &Reply) -> Option<MasterToBoard> {
        let name = request_name(&r.request);
        match (r.request, r.outcome) {
            (MasterToBoard::Heartbeat, _) => return None,
            (MasterToBoard::PoseTarget { .. }, o) => {
                self.outcome_note(r.t_s, "Target", o);
                return None;
            }
            (MasterToBoard::Jog { joint, velocity }, o) => {
                let first = self.jog.as_mut().is_none_or(|j| !j.answered);
                if let Some(j) = self.jog.as_mut() {
                    j.answered = true;
                }
                let refused = matches!(o, Outcome::Refused(_) | Outcome::TargetRefused(_));
                if refused {
                    self.jog = None;
                }
                if first || refused {
                    let j = usize::from(joint);
                    let unit = if j < 3 {
                        ("mm/s", 1e3)
                    } else {
                        ("deg/s", 57.295_779_513_082_32)
                    };
                    let what = format!(
                        "Jog {} {:+.1} {}",
                        JOINT_NAMES.get(j).copied().unwrap_or("?"),
                        f64::from(velocity) * unit.1,
                        unit.0
                    );
                    self.outcome_note(r.t_s, &what, o);
                }
                return None;
            }
            (MasterToBoard::Enable, Outcome::Refused(NackReason::Busy))
                if self.enable_retry_until.is_some_and(|u| r.t_s < u) =>
            {
                self.note(
                    r.t_s,
                    "Enable -> Busy (brakes engaging): sending again".into(),
                    false,
                );
                self.enable_retry_at = Some(r.t_s + 0.05);
                return None;
            }
            (MasterToBoard::Enable, _) => self.enable_retry_until = None,
            (MasterToBoard::Clutch { engaged }, Outcome::Ack) => self.clutch = engaged,
            (MasterToBoard::OperatorPresent { present }, Outcome::Ack) => self.present = present,
            (MasterToBoard::Home { rehome: false }, Outcome::Refused(NackReason::AlreadyHomed)) => {
                self.confirm_rehome = true;
            }
            // No session yet (a board still booting): say Hello again until it answers.
            (MasterToBoard::Hello { .. }, Outcome::NoReply) if self.hello.is_none() => {
                self.outcome_note(r.t_s, "Hello", r.outcome);
                self.note(r.t_s, "no session yet: saying Hello again".into(), false);
                return Some(r.request);
            }
            _ => {}
        }
        self.outcome_note(r.t_s, name, r.outcome);
        None
    }

    fn outcome_note(&mut self, t_s: f64, what: &str, o: Outcome) {
        let (text, refused) = match o {
            Outcome::Ack => (format!("{what} -> Ack"), false),
            Outcome::Refused(reason) => (format!("{what} REFUSED: {}", refusal_text(reason)), true),
            Outcome::TargetRefused(r) => (
                format!("{what} REFUSED: {}", board_words::refusal(&r)),
                true,
            ),
            Outcome::HelloReply(h) => {
                self.hello = Some(h);
                // A session starts with the clutch released and the operator absent
                // (command authority): the person presses the dead-man (p) to enable.
                self.clutch = false;
                self.present = false;
                (
                    format!(
                        "{what} -> firmware {}.{}.{}, protocol {}, reset {}{}",
                        h.firmware.major,
                        h.firmware.minor,
                        h.firmware.patch,
                        h.protocol_version,
                        board_words::reset_cause(h.reset.cause),
                        if h.reset.acknowledged {
                            ""
                        } else {
                            " (acknowledge: a)"
                        }
                    ),
                    false,
                )
            }
            Outcome::FaultLog(p) => (format!("{what} -> {} entries", p.len), false),
            Outcome::EventLog(p) => (format!("{what} -> {} entries", p.len), false),
            Outcome::GeometryStored(v) => (format!("{what} -> stored, version {v}"), false),
            Outcome::GeometryRefused(reason) => (
                format!("{what} REFUSED: {}", geometry_refusal_text(reason)),
                true,
            ),
            Outcome::NoReply => (format!("{what} -> no answer"), true),
        };
        self.note(t_s, text, refused);
    }

    /// An Enable due again (after `Busy`).
    fn enable_due(&mut self, t_s: f64) -> bool {
        if self.enable_retry_at.is_some_and(|at| t_s >= at) {
            self.enable_retry_at = None;
            return true;
        }
        false
    }

    /// Draws the console into `area` (80x24 and larger).
    pub fn draw(&self, frame: &mut Frame, area: Rect) {
        let title = match self.hello {
            Some(h) => format!(
                " RSPR console  {}  fw {}.{}.{} protocol {} ",
                self.board_name,
                h.firmware.major,
                h.firmware.minor,
                h.firmware.patch,
                h.protocol_version
            ),
            None => format!(" RSPR console  {}  (no HelloReply yet) ", self.board_name),
        };
        let block = Block::bordered().title(title);
        let inner = block.inner(area);
        frame.render_widget(block, area);
        let lines = self.lines(usize::from(inner.height));
        frame.render_widget(Paragraph::new(lines), inner);
    }

    /// The console's lines for a pane `height` rows high.
    pub fn lines(&self, height: usize) -> Vec<Line<'static>> {
        let mut out: Vec<Line<'static>> = match &self.status {
            None => {
                let mut waiting = vec![Line::from("no status from the board yet (h: hello)")];
                waiting.extend((0..9).map(|_| Line::from("")));
                waiting
            }
            Some((_, s)) => self.status_lines(s),
        };
        out.push(self.jog_line());
        out.push(Line::styled("-- replies (newest last)", bold()));
        let keys_rows = 3;
        let room = height
            .saturating_sub(out.len() + keys_rows)
            .min(REPLIES_SHOWN.max(1));
        out.extend(self.reply_lines(room));
        out.extend(self.key_lines());
        out
    }

    /// The status's ten lines: state, fault, reset, poses, joints, margins, link, tick.
    fn status_lines(&self, s: &StatusReport) -> Vec<Line<'static>> {
        vec![
            self.state_line(s),
            fault_line(s),
            Line::from(format!(
                "Reset    {}{}  supply {:.1} V  fault log {} entries",
                board_words::reset_cause(s.reset.cause),
                if s.reset.acknowledged {
                    " (acknowledged)"
                } else {
                    " NOT ACKNOWLEDGED (a)"
                },
                s.supply_v,
                s.fault_log_len
            )),
            Line::from(format!("Measured {}", pose_text(measured_cp(s)))),
            Line::from(format!("Setpoint {}", pose_text(setpoint_cp(s)))),
            joints_line(s),
            margins_line(s),
            board_link_line(s),
            self.host_link_line(s),
            Line::from(format!(
                "Tick     jitter max {} us  exec max {} us  missed {}  refused targets {}",
                s.tick_jitter_max_us, s.tick_exec_max_us, s.missed_ticks, s.targets_refused
            )),
        ]
    }

    /// The state, the stop, homed, and the clutch and presence as last acknowledged.
    fn state_line(&self, s: &StatusReport) -> Line<'static> {
        let homed = if s.warnings.contains(Warnings::NOT_HOMED) {
            "no"
        } else {
            "yes"
        };
        let state_style = match s.state {
            RobotState::Fault => red(),
            RobotState::Enabled => bold().fg(Color::Green),
            _ => bold(),
        };
        Line::from(vec![
            Span::raw("State "),
            Span::styled(
                format!("{:<9}", board_words::state_label(s.state)),
                state_style,
            ),
            Span::raw(format!(
                " Stop {:<25} Homed {homed:<3} Clutch {} Op {}",
                board_words::stop(s.state, s.stop).unwrap_or(""),
                if self.clutch { "on " } else { "off" },
                if self.present { "present" } else { "ABSENT" }
            )),
        ])
    }

    /// The master side's receive counters, its longest heartbeat gap and the workspace
    /// margin.
    fn host_link_line(&self, s: &StatusReport) -> Line<'static> {
        let h = self.host_counters;
        Line::from(format!(
            "         host rx ok {} rejected {} lost {}  beat gap {:.0} ms  workspace {} left",
            h.frames_ok,
            h.rejected(),
            h.dropped,
            self.heartbeat_gap_max_s * 1e3,
            margin_text(s.margins.workspace)
        ))
    }

    /// The joint jogged, the speed, and whether a jog stream runs.
    fn jog_line(&self) -> Line<'static> {
        let speed = JOG_SPEEDS.get(self.speed).copied().unwrap_or(1.0);
        let jogging = match &self.jog {
            Some(_) => "  JOGGING",
            None => "",
        };
        Line::from(format!(
            "Jog      joint {} (1-6)  speed {speed} mm/s | deg/s ([ ]){jogging}",
            JOINT_NAMES.get(self.joint).copied().unwrap_or("?")
        ))
    }

    /// The newest replies in `room` rows, oldest first, blank rows above when fewer;
    /// refusals in red, each cut to 78 characters.
    fn reply_lines(&self, room: usize) -> Vec<Line<'static>> {
        let shown: Vec<&(f64, String, bool)> = self.replies.iter().rev().take(room).collect();
        let mut out: Vec<Line<'static>> = (shown.len()..room).map(|_| Line::from("")).collect();
        for (t, text, refused) in shown.into_iter().rev() {
            let style = if *refused { red() } else { Style::default() };
            let mut l = format!("{t:7.2} {text}");
            if l.chars().count() > 78 {
                l = l.chars().take(77).collect::<String>() + "~";
            }
            out.push(Line::styled(l, style));
        }
        out
    }

    /// The keys, or the re-homing question being asked.
    fn key_lines(&self) -> [Line<'static>; 3] {
        let heading = if let Some(cause) = self.confirm_reset {
            Line::styled(
                format!(
                    "Acknowledge the board's {} reset? y = yes, other = no",
                    board_words::reset_cause(cause)
                ),
                red(),
            )
        } else if let Some(line) = &self.target_input {
            Line::styled(format!("Target x y z [mm] rx ry rz [deg]: {line}_"), bold())
        } else if self.confirm_rehome {
            Line::styled(
                "Robot is homed. Re-home (every joint to its switch)? y = yes, other = no",
                red(),
            )
        } else {
            Line::styled("-- keys", bold())
        };
        [
            heading,
            Line::from("h hello o home e enable d disable c clear fault s/SPACE stop q quit"),
            Line::from(if self.target_input.is_some() {
                "Enter send the target  Esc cancel  Backspace erase"
            } else {
                "1-6 joint +/- jog [ ] speed k clutch p dead-man a ack reset t target"
            }),
        ]
    }
}

/// The longest pose target line, characters.
const TARGET_INPUT_MAX: usize = 60;

/// Why a typed pose target is not one.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TargetInputError {
    /// Not six fields.
    #[error("{found} number(s), need 6: x y z [mm] rx ry rz [deg]")]
    Count {
        /// How many fields the line has.
        found: usize,
    },
    /// A field that is not a finite number.
    #[error("{field} is {text:?}, not a number")]
    NotANumber {
        /// The field's name and unit ("z mm").
        field: &'static str,
        /// What was typed.
        text: String,
    },
}

/// The fields of a pose target, with their units.
const TARGET_FIELDS: [&str; 6] = ["x mm", "y mm", "z mm", "rx deg", "ry deg", "rz deg"];

/// A typed pose target: six numbers separated by spaces or commas, x y z in mm and the
/// rotation vector rx ry rz in deg (`CONVENTIONS.md`, Pose and twist).
pub fn parse_target(line: &str) -> Result<[f64; 6], TargetInputError> {
    let fields: Vec<&str> = line
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|f| !f.is_empty())
        .collect();
    if fields.len() != 6 {
        return Err(TargetInputError::Count {
            found: fields.len(),
        });
    }
    let mut v = [0.0; 6];
    for ((x, text), field) in v.iter_mut().zip(&fields).zip(TARGET_FIELDS) {
        *x = text
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| TargetInputError::NotANumber {
                field,
                text: (*text).to_string(),
            })?;
    }
    Ok(v)
}

/// A pose in mm and deg, compact: "x 0.0 y 0.0 z 177.0 mm r 0.0 0.0 0.0 deg".
fn mm_deg_text(v: &[f64; 6]) -> String {
    format!(
        "x {:.1} y {:.1} z {:.1} mm r {:.1} {:.1} {:.1} deg",
        v[0], v[1], v[2], v[3], v[4], v[5]
    )
}

fn bold() -> Style {
    Style::default().add_modifier(Modifier::BOLD)
}

fn red() -> Style {
    Style::default().fg(Color::Red).add_modifier(Modifier::BOLD)
}

/// The latched fault: cause, joint, value and time (red), or none.
fn fault_line(s: &StatusReport) -> Line<'static> {
    let f = s.fault;
    let none = f.cause == master_link::FaultCause::None;
    let fault = match board_words::fault(&f) {
        None => "none".to_string(),
        Some(words) => format!("{words} ({})", board_words::board_time(f.time_ms)),
    };
    Line::from(vec![
        Span::raw("Fault    "),
        Span::styled(fault, if none { Style::default() } else { red() }),
    ])
}

/// A pose in mm and deg, or `--`.
fn pose_text(p: Option<masters::CartesianPose>) -> String {
    match p {
        Some(p) => {
            let a = p.to_mm_deg();
            format!(
                "x {:7.3} y {:7.3} z {:7.3} mm  rx {:6.2} ry {:6.2} rz {:6.2} deg",
                a[0], a[1], a[2], a[3], a[4], a[5]
            )
        }
        None => "--".to_string(),
    }
}

/// The measured joints, mm and deg.
fn joints_line(s: &StatusReport) -> Line<'static> {
    let q = s.joints;
    Line::from(format!(
        "Joints   l1-l3 {:7.3} {:7.3} {:7.3} mm  th1-th3 {:7.2} {:7.2} {:7.2} deg",
        f64::from(q[0]) * 1e3,
        f64::from(q[1]) * 1e3,
        f64::from(q[2]) * 1e3,
        f64::from(q[3]).to_degrees(),
        f64::from(q[4]).to_degrees(),
        f64::from(q[5]).to_degrees()
    ))
}

/// A guard margin as the share of its range left, %, or `--` when not finite.
fn margin_text(x: f32) -> String {
    if x.is_finite() {
        format!("{:.0} %", x * 100.0)
    } else {
        "--".into()
    }
}

/// The guard margins.
fn margins_line(s: &StatusReport) -> Line<'static> {
    let m = s.margins;
    Line::from(format!(
        "Margins  nearest {}",
        board_words::nearest_margin_short(&m)
    ))
}

/// The board's receive counters.
fn board_link_line(s: &StatusReport) -> Line<'static> {
    let c = s.link;
    Line::from(format!(
        "Link     board rx ok {} crc {} bad {} ver {} order {} sess {} lost {}",
        c.frames_ok,
        c.bad_checksum,
        c.malformed,
        c.wrong_version,
        c.out_of_order,
        c.wrong_session,
        c.dropped
    ))
}

/// Runs the console on the terminal until `q`: the board polled every 5 ms, the screen
/// drawn every 50 ms by a thread of its own (a copy of the console's state handed over),
/// so that a terminal slow to take the output (a remote session, a loaded machine) never
/// holds up the link's loop: the heartbeats, the keys, the jog stream. The Link line
/// shows the loop's longest interval between two heartbeats (`beat gap`; the board holds
/// after 100 ms without one).
/// `stop` (SIGINT, SIGTERM) ends it like `q`.
pub fn run(board: &mut Board, stop: &AtomicBool) -> Result<(), OperatorError> {
    let mut terminal = ratatui::try_init().map_err(OperatorError::Terminal)?;
    let result = std::thread::scope(|scope| {
        let (screen, frames) = std::sync::mpsc::sync_channel::<Console>(1);
        let terminal = &mut terminal;
        let drawer = scope.spawn(move || -> Result<(), OperatorError> {
            for c in frames {
                terminal
                    .draw(|f| c.draw(f, f.area()))
                    .map_err(OperatorError::Terminal)?;
            }
            Ok(())
        });
        let looped = event_loop(board, &screen, stop);
        drop(screen);
        let drawn = drawer.join().unwrap_or(Err(OperatorError::DrawerPanicked));
        looped.and(drawn)
    });
    ratatui::restore();
    result
}

/// The link's loop: polls the board, reads the keys, hands a copy of the console's state
/// to `screen` every 50 ms (skipped while the drawing thread is still busy). Ends on `q`,
/// or when the drawing thread has stopped (its error is the run's).
fn event_loop(
    board: &mut Board,
    screen: &std::sync::mpsc::SyncSender<Console>,
    stop: &AtomicBool,
) -> Result<(), OperatorError> {
    let mut c = Console::new(board.name());
    board.send_hello()?;
    let mut last_draw = f64::NEG_INFINITY;
    while !stop.load(Ordering::Relaxed) {
        let now = board.now_s();
        for e in board.poll(Duration::from_millis(5))? {
            if let Some(m) = c.board_event(&e) {
                board.send(m)?;
            }
        }
        c.host_counters = board.link().counters();
        c.heartbeat_gap_max_s = board.heartbeat_gap_max_s();
        if c.enable_due(now) {
            board.send(MasterToBoard::Enable)?;
        }
        if let Some(m) = c.jog_due(now) {
            board.send(m)?;
        }
        while event::poll(Duration::ZERO).map_err(OperatorError::Terminal)? {
            let Event::Key(k) = event::read().map_err(OperatorError::Terminal)? else {
                continue;
            };
            if k.kind == KeyEventKind::Release {
                continue;
            }
            for a in c.key(k.code, k.modifiers, now) {
                match a {
                    Action::Send(MasterToBoard::Hello { .. }) => {
                        board.send_hello()?;
                    }
                    Action::Send(m) => {
                        board.send(m)?;
                    }
                    Action::Target(pose) => {
                        board.send_target(&pose)?;
                    }
                    Action::Jog(dir) => {
                        c.start_jog(dir, now);
                        if let Some(m) = c.jog_due(now) {
                            board.send(m)?;
                        }
                    }
                    // (The way out disables: crate::shutdown.)
                    Action::Quit => return Ok(()),
                }
            }
        }
        if now - last_draw >= 0.05 {
            last_draw = now;
            match screen.try_send(c.clone()) {
                Ok(()) | Err(std::sync::mpsc::TrySendError::Full(_)) => {}
                // The drawing thread stopped: its error ends the run.
                Err(std::sync::mpsc::TrySendError::Disconnected(_)) => return Ok(()),
            }
        }
    }
    Ok(())
}

/// Why the board refused a geometry, in words.
fn geometry_refusal_text(r: master_link::GeometryRefusal) -> String {
    use master_link::GeometryRefusal as G;
    match r {
        G::Crc => "its checksum does not match".into(),
        G::Layout { found } => format!("record layout {found} is not one this board reads"),
        G::Version => "version 0 is reserved".into(),
        G::NonFinite { index } => format!("value {index} is not finite"),
        G::Nominal { index } => format!("nominal value {index} is not this robot's"),
        G::OutOfTolerance { index } => format!("value {index} is too far from the nominal"),
        G::NotAssemblable => "the geometry cannot be assembled".into(),
        G::CentralPose => "no inverse kinematics at the central pose".into(),
        G::InvalidState => "the drives are on: disable first".into(),
        G::Flash => "writing the flash failed".into(),
        G::Unsupported => "this board cannot store a geometry".into(),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use ratatui::backend::TestBackend;
    use ratatui::Terminal;

    /// At 80x24 every line fits (no line longer than the 78 columns inside the border)
    /// and the keys are on screen.
    #[test]
    fn fits_80x24_with_the_keys() {
        let mut c = Console::new("/tmp/board.sock");
        let mut s = StatusReport {
            state: RobotState::Fault,
            ..StatusReport::default()
        };
        s.fault.cause = master_link::FaultCause::FollowingError;
        s.fault.joint = 3;
        s.fault.value = -0.0123;
        s.link.frames_ok = 123_456_789;
        c.status = Some((1.0, s));
        for k in 0..10 {
            c.note(
                f64::from(k),
                "Jog th1 +1.0 deg/s REFUSED (ResetNotAcknowledged): acknowledge the board's last reset first".into(),
                true,
            );
        }
        for l in c.lines(22) {
            assert!(l.width() <= 78, "too wide ({}): {l}", l.width());
        }
        let mut t = Terminal::new(TestBackend::new(80, 24)).unwrap();
        t.draw(|f| c.draw(f, f.area())).unwrap();
        let screen: String = t
            .backend()
            .buffer()
            .content()
            .chunks(80)
            .map(|row| row.iter().map(|cell| cell.symbol()).collect::<String>() + "\n")
            .collect();
        assert!(
            screen.contains("following error on link 1: error -0.70 deg"),
            "{screen}"
        );
        assert!(screen.contains("s/SPACE stop"), "{screen}");
        assert!(screen.contains("k clutch p dead-man"), "{screen}");
    }

    /// `t` opens the target line; what is typed (a `q` too) goes into it; Enter sends six
    /// numbers as a pose target in mm and deg, and refuses anything else naming what is
    /// wrong, keeping the line open; Esc cancels.
    #[test]
    fn a_typed_target_is_checked_then_sent() {
        let mut c = Console::new("b");
        let typed = |c: &mut Console, text: &str| {
            for ch in text.chars() {
                assert!(c.key(KeyCode::Char(ch), KeyModifiers::NONE, 0.0).is_empty());
            }
        };
        assert!(c
            .key(KeyCode::Char('t'), KeyModifiers::NONE, 0.0)
            .is_empty());
        typed(&mut c, "0 0 q");
        assert_eq!(c.target_input.as_deref(), Some("0 0 q"));
        assert!(c.key(KeyCode::Enter, KeyModifiers::NONE, 0.0).is_empty());
        assert_eq!(
            c.replies.back().unwrap().1,
            "target not sent: 3 number(s), need 6: x y z [mm] rx ry rz [deg]"
        );
        typed(&mut c, " 0 0 0");
        assert!(c.key(KeyCode::Enter, KeyModifiers::NONE, 0.0).is_empty());
        assert_eq!(
            c.replies.back().unwrap().1,
            "target not sent: z mm is \"q\", not a number"
        );
        // "0 0 q 0 0 0" back to "0 0 ".
        for _ in 0..7 {
            c.key(KeyCode::Backspace, KeyModifiers::NONE, 0.0);
        }
        typed(&mut c, "177,1.5 -2 3");
        let a = c.key(KeyCode::Enter, KeyModifiers::NONE, 0.0);
        let [Action::Target(p)] = a.as_slice() else {
            panic!("{a:?}");
        };
        let v = p.to_mm_deg();
        for (x, want) in v.iter().zip([0.0, 0.0, 177.0, 1.5, -2.0, 3.0]) {
            assert!((x - want).abs() < 1e-9, "{v:?}");
        }
        assert!(c.target_input.is_none());
        // Esc cancels without sending; then keys are commands again.
        c.key(KeyCode::Char('t'), KeyModifiers::NONE, 0.0);
        assert!(c.key(KeyCode::Esc, KeyModifiers::NONE, 0.0).is_empty());
        assert_eq!(
            c.key(KeyCode::Char('q'), KeyModifiers::NONE, 0.0),
            vec![Action::Quit]
        );
        assert!(parse_target("0 0 160 0 0 inf").is_err());
    }

    /// The board's answers to a typed target: a refusal at once and one of the path check
    /// after the Ack, each with the guard, the value and the limit, on a line that fits.
    #[test]
    fn target_refusals_name_guard_value_and_limit() {
        let mut c = Console::new("b");
        let request = MasterToBoard::PoseTarget {
            timestamp_us: 1,
            position_m: [0.0, 0.0, 0.4],
            rotation_vector_rad: [0.0; 3],
        };
        let breach = |guard, subject, value, limit| master_link::RefusedTarget {
            reply_to: Some(3),
            timestamp_us: 1,
            reason: NackReason::OutOfWorkspace,
            breach: master_link::Breach {
                guard,
                subject,
                value,
                limit,
            },
        };
        c.board_event(&BoardEvent::Reply(Reply {
            request,
            seq: 3,
            sent_s: 1.0,
            t_s: 1.0,
            outcome: Outcome::TargetRefused(breach(master_link::GuardId::Workspace, 2, 0.4, 0.175)),
        }));
        let later = master_link::RefusedTarget {
            reply_to: None,
            ..breach(
                master_link::GuardId::Tilt,
                0,
                31.2f32.to_radians(),
                30f32.to_radians(),
            )
        };
        c.board_event(&BoardEvent::TargetRefused(2.0, later));
        let texts: Vec<&str> = c.replies.iter().map(|r| r.1.as_str()).collect();
        assert_eq!(
            texts,
            [
                "Target REFUSED: workspace z 400.0 mm > 175.0 mm",
                "Target REFUSED (path): tilt spherical joint 1 31.2 deg > 30.0 deg"
            ]
        );
        for l in c.reply_lines(2) {
            assert!(l.width() <= 78 && !l.to_string().ends_with('~'), "{l}");
        }
    }

    /// Re-homing a homed robot asks first; `y` sends `Home { rehome: true }`, another key
    /// cancels.
    #[test]
    fn rehome_needs_the_confirmation() {
        let mut c = Console::new("b");
        c.status = Some((0.0, StatusReport::default()));
        assert!(c
            .key(KeyCode::Char('o'), KeyModifiers::NONE, 0.0)
            .is_empty());
        assert!(c.confirm_rehome);
        assert_eq!(
            c.key(KeyCode::Char('y'), KeyModifiers::NONE, 0.1),
            vec![Action::Send(MasterToBoard::Home { rehome: true })]
        );
        c.key(KeyCode::Char('o'), KeyModifiers::NONE, 0.2);
        assert!(c
            .key(KeyCode::Char('n'), KeyModifiers::NONE, 0.3)
            .is_empty());
        assert!(!c.confirm_rehome);
        let s = StatusReport {
            warnings: Warnings::NOT_HOMED,
            ..StatusReport::default()
        };
        c.status = Some((0.0, s));
        assert_eq!(
            c.key(KeyCode::Char('o'), KeyModifiers::NONE, 0.4),
            vec![Action::Send(MasterToBoard::Home { rehome: false })]
        );
    }
}
