//! The hand controllers `host-sim teleop --device` opens, behind the one [`Master`]
//! trait: `spacemouse` (through spacenavd when its socket is there, else evdev),
//! `spacenavd[:SOCKET]`, `evdev[:PATH]`, `udp:PORT` (or `udp:ADDR:PORT`), `keyboard`
//! (the terminal's keys, in raw mode; a process without a terminal is told so) and
//! `scripted:FILE` (a scripted operator from a file, no terminal needed).
//!
//! The script file ([`read_script`]): one waypoint per line, `#` starts a comment, fields
//! separated by spaces or commas:
//!
//! ```text
//! # t_s  x_mm y_mm z_mm  rx_deg ry_deg rz_deg  buttons...
//! 0.0    0 0 0  0 0 0  present
//! 2.0    5 0 0  0 0 0  present
//! 3.0    5 0 0  0 0 0  present clutch
//! 4.0    error the device failed
//! ```
//!
//! `t_s` is the time since the first poll, strictly increasing; the pose is the master's
//! (a position master: the teleoperation maps its motion, scaled, from where the operator
//! is present and the clutch released); the buttons `present` (operator present, the
//! dead-man held) and `clutch` (clutch pressed) hold from that waypoint on. Between
//! waypoints the pose moves linearly (position) and along the shortest arc (orientation)
//! (`masters::script::ScriptedMaster`); after the last it rests. A last line
//! `T error TEXT` makes the device report a read error with TEXT from T s on (counted in
//! the run's report; without samples the teleoperation holds).

use crate::error::OperatorError;
use masters::evdev::{DeviceMatch, EvdevMaster};
use masters::keyboard::{Key, KeyAction, KeyEvent, KeyOutcome, KeyboardConfig, KeyboardMaster};
use masters::rate::{RateMapping, RateMappingConfig};
use masters::script::{ScriptedMaster, Waypoint};
use masters::spacenav::{self, SpaceNavMaster, SpnavOptions};
use masters::udp::{GateConfig, UdpPoseMaster};
use masters::{CartesianPose, DeviceError, Master, MasterKind, MasterSample, OperatorButtons};
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::crossterm::terminal;
use std::io::IsTerminal;
use std::net::SocketAddr;
use std::path::Path;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Which device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceSpec {
    /// A SpaceMouse: spacenavd when its socket exists, else the first 3Dconnexion evdev
    /// device.
    SpaceMouse,
    /// spacenavd's socket (default: `$SPNAV_SOCKET` or `/var/run/spnav.sock`).
    Spacenavd(Option<PathBuf>),
    /// An evdev device (default: the first 3Dconnexion device).
    Evdev(Option<PathBuf>),
    /// The UDP pose master bound to this address.
    Udp(SocketAddr),
    /// The terminal's keyboard.
    Keyboard,
    /// A scripted operator read from this file.
    Scripted(PathBuf),
}

impl FromStr for DeviceSpec {
    type Err = OperatorError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || OperatorError::DeviceSpec(s.to_string());
        let (kind, arg) = match s.split_once(':') {
            Some((k, a)) => (k, Some(a)),
            None => (s, None),
        };
        Ok(match (kind, arg) {
            ("spacemouse", None) => DeviceSpec::SpaceMouse,
            ("spacenavd", a) => DeviceSpec::Spacenavd(a.map(PathBuf::from)),
            ("evdev", a) => DeviceSpec::Evdev(a.map(PathBuf::from)),
            ("keyboard", None) => DeviceSpec::Keyboard,
            ("scripted", Some(a)) if !a.is_empty() => DeviceSpec::Scripted(PathBuf::from(a)),
            ("udp", Some(a)) => {
                let addr = match a.parse::<u16>() {
                    Ok(port) => SocketAddr::from(([0, 0, 0, 0], port)),
                    Err(_) => a.parse().map_err(|_| bad())?,
                };
                DeviceSpec::Udp(addr)
            }
            _ => return Err(bad()),
        })
    }
}

/// Opens the device; the keyboard sets `quit` on `q` or Ctrl-C (raw mode: no signal).
pub fn open(spec: &DeviceSpec, quit: &Arc<AtomicBool>) -> Result<Box<dyn Master>, OperatorError> {
    Ok(match spec {
        DeviceSpec::SpaceMouse => {
            let socket = spacenav::socket_path();
            if socket.exists() {
                open(&DeviceSpec::Spacenavd(Some(socket)), quit)?
            } else {
                open(&DeviceSpec::Evdev(None), quit)?
            }
        }
        DeviceSpec::Spacenavd(path) => {
            let path = path.clone().unwrap_or_else(spacenav::socket_path);
            let mapping = RateMapping::new(RateMappingConfig::spacemouse_spacenavd())?;
            Box::new(SpaceNavMaster::connect(
                &path,
                &SpnavOptions::default(),
                mapping,
            )?)
        }
        DeviceSpec::Evdev(path) => {
            let mapping = RateMapping::new(RateMappingConfig::spacemouse_evdev())?;
            Box::new(match path {
                Some(p) => EvdevMaster::open(p, mapping)?,
                None => EvdevMaster::find(&DeviceMatch::Any3Dconnexion, mapping)?,
            })
        }
        DeviceSpec::Udp(addr) => Box::new(UdpPoseMaster::bind(*addr, None, GateConfig::default())?),
        DeviceSpec::Keyboard => {
            if !std::io::stdin().is_terminal() {
                return Err(OperatorError::NoTerminal("keyboard".into()));
            }
            Box::new(TerminalKeyboard::new(Arc::clone(quit))?)
        }
        DeviceSpec::Scripted(path) => Box::new(read_script(path)?),
    })
}

/// A scripted operator from a file (format: the module documentation), failing at the
/// time of its `error` line if it has one.
pub struct ScriptFile {
    script: ScriptedMaster,
    fail: Option<(f64, String)>,
}

impl Master for ScriptFile {
    fn name(&self) -> &str {
        self.script.name()
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Position
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        let sample = self.script.poll(now_s)?;
        if let Some((at_s, text)) = &self.fail {
            if self.script.elapsed_s(now_s) >= *at_s {
                return Err(DeviceError::Disconnected {
                    device: self.script.name().to_string(),
                    detail: text.clone(),
                });
            }
        }
        Ok(sample)
    }
}

/// Reads a script file (format: the module documentation).
pub fn read_script(path: &Path) -> Result<ScriptFile, OperatorError> {
    let text = std::fs::read_to_string(path).map_err(|source| OperatorError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |line: usize, reason: String| OperatorError::Script {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut waypoints = Vec::new();
    let mut fail = None;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or_default();
        let fields: Vec<&str> = content
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        let Some((first, rest)) = fields.split_first() else {
            continue;
        };
        if fail.is_some() {
            return Err(bad(line, "nothing may follow the error line".into()));
        }
        let at_s: f64 = first
            .parse()
            .map_err(|_| bad(line, format!("time `{first}` is not a number")))?;
        if rest.first() == Some(&"error") {
            fail = Some((at_s, rest.get(1..).unwrap_or_default().join(" ")));
            continue;
        }
        let mut v = [0.0; 6];
        for (k, x) in v.iter_mut().enumerate() {
            let f = rest
                .get(k)
                .ok_or_else(|| bad(line, "expected t_s, x y z (mm), rx ry rz (deg)".into()))?;
            *x = f
                .parse()
                .map_err(|_| bad(line, format!("`{f}` is not a number")))?;
        }
        let mut buttons = OperatorButtons::default();
        for b in rest.get(6..).unwrap_or_default() {
            match *b {
                "present" => buttons.operator_present = true,
                "clutch" => buttons.clutch = true,
                other => {
                    return Err(bad(
                        line,
                        format!("button `{other}`: expected present or clutch"),
                    ))
                }
            }
        }
        let pose = CartesianPose::from_mm_deg(v)
            .map_err(|_| bad(line, "a pose value is not finite".into()))?;
        waypoints.push(Waypoint {
            at_s,
            pose,
            buttons,
        });
    }
    let name = format!("scripted:{}", path.display());
    let script = ScriptedMaster::new(name, waypoints).map_err(|e| bad(0, format!("{e}")))?;
    Ok(ScriptFile { script, fail })
}

/// The keyboard master fed from the terminal (raw mode while it lives). Keys: see
/// `masters::keyboard`; `c` clutch, Space operator present, Esc stops everything.
pub struct TerminalKeyboard {
    keys: KeyboardMaster,
    last: Option<KeyOutcome>,
    quit: Arc<AtomicBool>,
}

impl TerminalKeyboard {
    /// Puts the terminal in raw mode; `q` and Ctrl-C set `quit`.
    pub fn new(quit: Arc<AtomicBool>) -> Result<Self, OperatorError> {
        let keys = KeyboardMaster::new(KeyboardConfig::default())?;
        terminal::enable_raw_mode().map_err(OperatorError::Terminal)?;
        Ok(TerminalKeyboard {
            keys,
            last: None,
            quit,
        })
    }

    /// What the last key did.
    pub fn last_outcome(&self) -> Option<KeyOutcome> {
        self.last
    }
}

impl Drop for TerminalKeyboard {
    fn drop(&mut self) {
        let _ = terminal::disable_raw_mode();
    }
}

/// A terminal key as the keyboard mapping knows it.
pub fn mapped_key(code: KeyCode) -> Option<Key> {
    Some(match code {
        KeyCode::Char(c) => Key::Char(c),
        KeyCode::Up => Key::Up,
        KeyCode::Down => Key::Down,
        KeyCode::Left => Key::Left,
        KeyCode::Right => Key::Right,
        KeyCode::PageUp => Key::PageUp,
        KeyCode::PageDown => Key::PageDown,
        KeyCode::Esc => Key::Esc,
        _ => return None,
    })
}

impl Master for TerminalKeyboard {
    fn name(&self) -> &str {
        "keyboard"
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Rate
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        let io = |source| DeviceError::Io {
            device: "keyboard".into(),
            operation: "read",
            path: "terminal".into(),
            source,
        };
        while event::poll(Duration::ZERO).map_err(io)? {
            if let Event::Key(k) = event::read().map_err(io)? {
                if k.code == KeyCode::Char('q')
                    || (k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL))
                {
                    self.quit.store(true, Ordering::Relaxed);
                    continue;
                }
                let action = match k.kind {
                    KeyEventKind::Press => KeyAction::Press,
                    KeyEventKind::Repeat => KeyAction::Repeat,
                    KeyEventKind::Release => KeyAction::Release,
                };
                if let Some(key) = mapped_key(k.code) {
                    self.last = Some(self.keys.handle(&KeyEvent {
                        key,
                        action,
                        t_s: now_s,
                    }));
                }
            }
        }
        self.keys.poll(now_s)
    }
}
