//! The keyboard as a rate master, for jogging without hardware: a pure mapping from key
//! events to a twist, fed by the caller (the host feeds it from crossterm), testable
//! without a terminal.
//!
//! | keys | action |
//! | --- | --- |
//! | `d` / `a`, → / ← | +x / −x |
//! | `w` / `s`, ↑ / ↓ | +y / −y |
//! | `r` / `f`, PageUp / PageDown | +z / −z |
//! | `i` / `k` | rotate +x / −x |
//! | `l` / `j` | rotate +y / −y |
//! | `u` / `o` | rotate +z / −z |
//! | `+` (or `=`) / `-` | speed step up / down |
//! | `c` | clutch on / off (toggle) |
//! | Space | operator present on / off (toggle: the keyboard's dead-man) |
//! | Esc | stop: operator absent, clutch off, every motion key released |
//!
//! Terminals report key presses and auto-repeats, and releases only with the keyboard
//! enhancement protocol (crossterm's `REPORT_EVENT_TYPES`). With releases reported
//! ([`ReleaseMode::Reported`]) a motion key acts while held. Without
//! ([`ReleaseMode::Timeout`]) it acts until `hold_s` after its last press or repeat; the
//! default 0.6 s bridges the terminal's initial auto-repeat delay (typically 0.25 to
//! 0.5 s), so the motion continues that long after the key is let go.

use crate::device::{DeviceError, Master, MasterInput, MasterKind, MasterSample, OperatorButtons};
use crate::pose::Twist;
use nalgebra::Vector3;
use thiserror::Error;

/// A key, as far as the mapping cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Key {
    /// A character key (letters are matched case-insensitively).
    Char(char),
    /// Arrow up.
    Up,
    /// Arrow down.
    Down,
    /// Arrow left.
    Left,
    /// Arrow right.
    Right,
    /// Page up.
    PageUp,
    /// Page down.
    PageDown,
    /// Escape.
    Esc,
}

/// What happened to the key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyAction {
    /// Pressed.
    Press,
    /// Auto-repeat while held.
    Repeat,
    /// Released.
    Release,
}

/// One key event with the master-clock time it was read, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyEvent {
    /// The key.
    pub key: Key,
    /// Press, repeat or release.
    pub action: KeyAction,
    /// When, s.
    pub t_s: f64,
}

/// How motion keys end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReleaseMode {
    /// The terminal reports releases.
    Reported,
    /// A key acts until `hold_s` after its last press or repeat.
    Timeout {
        /// Seconds.
        hold_s: f64,
    },
}

/// Keyboard settings.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyboardConfig {
    /// How motion keys end.
    pub release: ReleaseMode,
    /// Speed steps: (linear m/s, angular rad/s).
    pub speeds: Vec<(f64, f64)>,
    /// Step at start (index into `speeds`).
    pub initial_step: usize,
}

impl Default for KeyboardConfig {
    /// Steps 0.5, 1, 2, 5, 10 mm/s with 1, 2, 5, 10, 20 deg/s; start at 2 mm/s.
    fn default() -> Self {
        let d = |x: f64| x.to_radians();
        KeyboardConfig {
            release: ReleaseMode::Timeout { hold_s: 0.6 },
            speeds: vec![
                (0.0005, d(1.0)),
                (0.001, d(2.0)),
                (0.002, d(5.0)),
                (0.005, d(10.0)),
                (0.010, d(20.0)),
            ],
            initial_step: 2,
        }
    }
}

/// A keyboard setting that is not usable.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum KeyboardConfigError {
    /// No speed step.
    #[error("keyboard: no speed steps")]
    NoSpeeds,
    /// A step's speeds are not positive and finite.
    #[error("keyboard: speed step {step} ({linear_m_s} m/s, {angular_rad_s} rad/s) is not positive and finite")]
    BadSpeed {
        /// The step.
        step: usize,
        /// Its linear speed.
        linear_m_s: f64,
        /// Its angular speed.
        angular_rad_s: f64,
    },
    /// The initial step is not in the list.
    #[error("keyboard: initial step {step} but only {steps} steps")]
    InitialStep {
        /// The step.
        step: usize,
        /// How many there are.
        steps: usize,
    },
    /// The hold time is not positive and finite.
    #[error("keyboard: hold time {0} s is not positive and finite")]
    HoldTime(f64),
}

/// What a key event did (for the host's display).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KeyOutcome {
    /// A motion key changed state.
    Motion,
    /// New speed step (index, linear m/s, angular rad/s).
    Speed(usize, f64, f64),
    /// Clutch toggled to this.
    Clutch(bool),
    /// Operator presence toggled to this.
    OperatorPresent(bool),
    /// Esc: everything stopped.
    Stopped,
    /// The key means nothing here.
    Ignored,
}

/// The six motion axes with a direction.
fn motion_of(key: Key) -> Option<(usize, f64)> {
    let k = match key {
        Key::Char(c) => c.to_ascii_lowercase(),
        Key::Right => 'd',
        Key::Left => 'a',
        Key::Up => 'w',
        Key::Down => 's',
        Key::PageUp => 'r',
        Key::PageDown => 'f',
        Key::Esc => return None,
    };
    Some(match k {
        'd' => (0, 1.0),
        'a' => (0, -1.0),
        'w' => (1, 1.0),
        's' => (1, -1.0),
        'r' => (2, 1.0),
        'f' => (2, -1.0),
        'i' => (3, 1.0),
        'k' => (3, -1.0),
        'l' => (4, 1.0),
        'j' => (4, -1.0),
        'u' => (5, 1.0),
        'o' => (5, -1.0),
        _ => return None,
    })
}

/// The keyboard master.
#[derive(Clone, Debug)]
pub struct KeyboardMaster {
    config: KeyboardConfig,
    step: usize,
    /// Per axis and direction (index 2·axis + (dir < 0)): the time the key was last seen
    /// pressed, or None when released.
    held: [Option<f64>; 12],
    clutch: bool,
    present: bool,
}

impl KeyboardMaster {
    /// A keyboard with nothing held, clutch off, operator absent; checks the settings.
    pub fn new(config: KeyboardConfig) -> Result<Self, KeyboardConfigError> {
        if config.speeds.is_empty() {
            return Err(KeyboardConfigError::NoSpeeds);
        }
        if let Some((step, &(v, w))) = config
            .speeds
            .iter()
            .enumerate()
            .find(|(_, (v, w))| !(v.is_finite() && w.is_finite() && *v > 0.0 && *w > 0.0))
        {
            return Err(KeyboardConfigError::BadSpeed {
                step,
                linear_m_s: v,
                angular_rad_s: w,
            });
        }
        if config.initial_step >= config.speeds.len() {
            return Err(KeyboardConfigError::InitialStep {
                step: config.initial_step,
                steps: config.speeds.len(),
            });
        }
        if let ReleaseMode::Timeout { hold_s } = config.release {
            if !(hold_s.is_finite() && hold_s > 0.0) {
                return Err(KeyboardConfigError::HoldTime(hold_s));
            }
        }
        Ok(KeyboardMaster {
            step: config.initial_step,
            config,
            held: [None; 12],
            clutch: false,
            present: false,
        })
    }

    /// Applies one key event.
    pub fn handle(&mut self, ev: &KeyEvent) -> KeyOutcome {
        if let Some((axis, dir)) = motion_of(ev.key) {
            let slot = 2 * axis + usize::from(dir < 0.0);
            self.held[slot] = match ev.action {
                KeyAction::Press | KeyAction::Repeat => Some(ev.t_s),
                KeyAction::Release => None,
            };
            return KeyOutcome::Motion;
        }
        if ev.action == KeyAction::Release {
            return KeyOutcome::Ignored;
        }
        match ev.key {
            Key::Esc => {
                self.held = [None; 12];
                self.clutch = false;
                self.present = false;
                KeyOutcome::Stopped
            }
            Key::Char('+' | '=') | Key::Char('-') => {
                if ev.key == Key::Char('-') {
                    self.step = self.step.saturating_sub(1);
                } else if self.step + 1 < self.config.speeds.len() {
                    self.step += 1;
                }
                let (v, w) = self.speed();
                KeyOutcome::Speed(self.step, v, w)
            }
            Key::Char(c) if c.eq_ignore_ascii_case(&'c') && ev.action == KeyAction::Press => {
                self.clutch = !self.clutch;
                KeyOutcome::Clutch(self.clutch)
            }
            Key::Char(' ') if ev.action == KeyAction::Press => {
                self.present = !self.present;
                KeyOutcome::OperatorPresent(self.present)
            }
            _ => KeyOutcome::Ignored,
        }
    }

    /// Current speed step (linear m/s, angular rad/s).
    pub fn speed(&self) -> (f64, f64) {
        self.config
            .speeds
            .get(self.step)
            .copied()
            .unwrap_or((0.0, 0.0))
    }

    /// The twist at `now_s`.
    pub fn twist(&self, now_s: f64) -> Twist {
        let (v, w) = self.speed();
        let mut g = [0.0f64; 6];
        for (slot, seen) in self.held.iter().enumerate() {
            let active = match (seen, self.config.release) {
                (None, _) => false,
                (Some(_), ReleaseMode::Reported) => true,
                (Some(t), ReleaseMode::Timeout { hold_s }) => now_s - t <= hold_s,
            };
            if active {
                g[slot / 2] += if slot % 2 == 0 { 1.0 } else { -1.0 };
            }
        }
        Twist {
            linear_m_s: Vector3::new(g[0], g[1], g[2]) * v,
            angular_rad_s: Vector3::new(g[3], g[4], g[5]) * w,
        }
    }

    /// Clutch and presence.
    pub fn buttons(&self) -> OperatorButtons {
        OperatorButtons {
            clutch: self.clutch,
            operator_present: self.present,
        }
    }
}

impl Master for KeyboardMaster {
    fn name(&self) -> &str {
        "keyboard"
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Rate
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        Ok(Some(MasterSample {
            t_s: now_s,
            input: MasterInput::Twist(self.twist(now_s)),
            buttons: self.buttons(),
            device_time_us: None,
            deflection: None,
        }))
    }
}
