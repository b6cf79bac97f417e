//! The hand controllers `host-sim teleop --device` opens, behind the one [`Master`]
//! trait: `spacemouse` (through spacenavd when its socket is there, else evdev),
//! `spacenavd[:SOCKET]`, `evdev[:PATH]`, `udp:PORT` (or `udp:ADDR:PORT`) and `keyboard`
//! (the terminal's keys, in raw mode).

use crate::error::OperatorError;
use masters::evdev::{DeviceMatch, EvdevMaster};
use masters::keyboard::{Key, KeyAction, KeyEvent, KeyOutcome, KeyboardConfig, KeyboardMaster};
use masters::rate::{RateMapping, RateMappingConfig};
use masters::spacenav::{self, SpaceNavMaster, SpnavOptions};
use masters::udp::{GateConfig, UdpPoseMaster};
use masters::{DeviceError, Master, MasterKind, MasterSample};
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::crossterm::terminal;
use std::net::SocketAddr;
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
        DeviceSpec::Keyboard => Box::new(TerminalKeyboard::new(Arc::clone(quit))?),
    })
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
