//! The SpaceMouse read directly from the Linux input subsystem (`/dev/input/event*`).
//!
//! # The event format
//!
//! A read returns whole `struct input_event`s, laid out by a 64-bit kernel as 24 bytes
//! in the host's byte order (little-endian here):
//!
//! | offset | size | field |
//! | --- | --- | --- |
//! | 0 | 8 | `time.tv_sec` (i64) |
//! | 8 | 8 | `time.tv_usec` (i64) |
//! | 16 | 2 | `type` (u16) |
//! | 18 | 2 | `code` (u16) |
//! | 20 | 4 | `value` (i32) |
//!
//! A SpaceMouse reports its six axes as `EV_REL` (older kernels and devices) or `EV_ABS`
//! (codes 0..5 = x, y, z, rx, ry, rz), its buttons as `EV_KEY` `BTN_0`, `BTN_1`, ...
//! (0x100 + i; value 1 pressed, 0 released, 2 autorepeat), and closes each report with
//! `EV_SYN SYN_REPORT`. The decoder applies a report only at its `SYN_REPORT` (EV_SYN
//! framing); an `EV_SYN SYN_DROPPED` (the kernel's buffer overflowed) discards events up
//! to and including the next `SYN_REPORT` and, since the device state can then only be
//! known again through ioctls this crate does not issue, releases the state (no
//! deflection, no button: the robot holds) until new reports arrive.
//!
//! As spacenavd does, each axis keeps its last reported value: the kernel does not
//! forward an unchanged `EV_ABS` value nor a zero `EV_REL` value, so an axis absent from
//! a report has not changed (for `EV_REL` devices, a cap released to the centre may end
//! on a small last value; the rate mapping's deadzone absorbs it).
//!
//! The device is found by name, by USB vendor/product, or as any 3Dconnexion device,
//! through sysfs (`/sys/class/input/event*/device/{name,id/vendor,id/product}`), so no
//! ioctl is needed; or it is given as a path.

use crate::device::{DeviceError, Master, MasterInput, MasterKind, MasterSample};
use crate::rate::{Deflection, RateMapping};
use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Read};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

/// Bytes of one `struct input_event` on a 64-bit kernel.
pub const INPUT_EVENT_BYTES: usize = 24;
/// Event types.
pub const EV_SYN: u16 = 0x00;
/// Keys and buttons.
pub const EV_KEY: u16 = 0x01;
/// Relative axes.
pub const EV_REL: u16 = 0x02;
/// Absolute axes.
pub const EV_ABS: u16 = 0x03;
/// Miscellaneous (scan codes): ignored.
pub const EV_MSC: u16 = 0x04;
/// LEDs: ignored.
pub const EV_LED: u16 = 0x11;
/// End of a report.
pub const SYN_REPORT: u16 = 0;
/// The kernel dropped events.
pub const SYN_DROPPED: u16 = 3;
/// First numbered button (`BTN_MISC` range 0x100..=0x10f: `BTN_0`..`BTN_9` and the
/// six after them); other key codes are not this device's buttons.
pub const BTN_0: u16 = 0x100;
/// USB vendor ids of 3Dconnexion devices (Logitech's, then 3Dconnexion's own).
pub const VENDORS_3DCONNEXION: [u16; 2] = [0x046d, 0x256f];

/// One `struct input_event`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InputEvent {
    /// Seconds of the kernel's time stamp.
    pub sec: i64,
    /// Microseconds of the kernel's time stamp.
    pub usec: i64,
    /// Event type.
    pub kind: u16,
    /// Event code.
    pub code: u16,
    /// Value.
    pub value: i32,
}

impl InputEvent {
    /// Decodes the 24 bytes of one event (host byte order).
    pub fn from_bytes(b: &[u8; INPUT_EVENT_BYTES]) -> Self {
        let mut i8b = [0u8; 8];
        let mut i4b = [0u8; 4];
        let mut i2b = [0u8; 2];
        i8b.copy_from_slice(&b[0..8]);
        let sec = i64::from_ne_bytes(i8b);
        i8b.copy_from_slice(&b[8..16]);
        let usec = i64::from_ne_bytes(i8b);
        i2b.copy_from_slice(&b[16..18]);
        let kind = u16::from_ne_bytes(i2b);
        i2b.copy_from_slice(&b[18..20]);
        let code = u16::from_ne_bytes(i2b);
        i4b.copy_from_slice(&b[20..24]);
        let value = i32::from_ne_bytes(i4b);
        InputEvent {
            sec,
            usec,
            kind,
            code,
            value,
        }
    }

    /// The 24 bytes (host byte order).
    pub fn to_bytes(&self) -> [u8; INPUT_EVENT_BYTES] {
        let mut b = [0u8; INPUT_EVENT_BYTES];
        b[0..8].copy_from_slice(&self.sec.to_ne_bytes());
        b[8..16].copy_from_slice(&self.usec.to_ne_bytes());
        b[16..18].copy_from_slice(&self.kind.to_ne_bytes());
        b[18..20].copy_from_slice(&self.code.to_ne_bytes());
        b[20..24].copy_from_slice(&self.value.to_ne_bytes());
        b
    }

    /// The time stamp in µs, when it is a valid time (non-negative, usec < 10⁶).
    pub fn time_us(&self) -> Option<u64> {
        if self.sec < 0 || !(0..1_000_000).contains(&self.usec) {
            return None;
        }
        u64::try_from(self.sec)
            .ok()?
            .checked_mul(1_000_000)?
            .checked_add(u64::try_from(self.usec).ok()?)
    }
}

/// What the decoder saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EvdevCounters {
    /// Events decoded.
    pub events: u64,
    /// Reports applied (`SYN_REPORT`).
    pub reports: u64,
    /// `SYN_DROPPED` seen.
    pub dropped: u64,
    /// Events discarded after a `SYN_DROPPED`.
    pub discarded: u64,
    /// Axis or button codes this device mapping does not use (skipped).
    pub unused_codes: u64,
    /// Events of other types (`EV_MSC`, `EV_LED`, ...; skipped).
    pub other_types: u64,
    /// Malformed events: key values other than 0, 1, 2, invalid time stamps (skipped).
    pub malformed: u64,
}

/// A report's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Report {
    /// The device state after the report.
    pub state: Deflection,
    /// The kernel's time stamp of the `SYN_REPORT`, µs.
    pub time_us: Option<u64>,
}

/// The EV_SYN-framed decoder: events in, device states out.
#[derive(Clone, Debug, Default)]
pub struct EvdevDecoder {
    state: Deflection,
    pending: Deflection,
    dropping: bool,
    bytes: Vec<u8>,
    counters: EvdevCounters,
}

impl EvdevDecoder {
    /// A decoder with the device at rest.
    pub fn new() -> Self {
        Self::default()
    }

    /// The counters.
    pub fn counters(&self) -> EvdevCounters {
        self.counters
    }

    /// The state after the last applied report.
    pub fn state(&self) -> Deflection {
        self.state
    }

    /// Feeds one event; the report when it closes one.
    pub fn push(&mut self, ev: &InputEvent) -> Option<Report> {
        self.counters.events += 1;
        if ev.kind == EV_SYN && ev.code == SYN_DROPPED {
            self.counters.dropped += 1;
            self.dropping = true;
            self.state = Deflection::default();
            self.pending = self.state;
            return None;
        }
        if self.dropping {
            self.counters.discarded += 1;
            if ev.kind == EV_SYN && ev.code == SYN_REPORT {
                self.dropping = false;
            }
            return None;
        }
        match ev.kind {
            EV_SYN if ev.code == SYN_REPORT => {
                let time_us = ev.time_us();
                if time_us.is_none() {
                    self.counters.malformed += 1;
                }
                self.state = self.pending;
                self.counters.reports += 1;
                return Some(Report {
                    state: self.state,
                    time_us,
                });
            }
            EV_SYN => self.counters.other_types += 1,
            EV_REL | EV_ABS => match self.pending.axes.get_mut(usize::from(ev.code)) {
                Some(a) => *a = f64::from(ev.value),
                None => self.counters.unused_codes += 1,
            },
            EV_KEY => {
                let bit = ev
                    .code
                    .checked_sub(BTN_0)
                    .filter(|i| *i < 16)
                    .map(|i| 1u32 << i);
                match (bit, ev.value) {
                    (None, _) => self.counters.unused_codes += 1,
                    (Some(b), 1 | 2) => self.pending.buttons |= b,
                    (Some(b), 0) => self.pending.buttons &= !b,
                    (Some(_), _) => self.counters.malformed += 1,
                }
            }
            _ => self.counters.other_types += 1,
        }
        None
    }

    /// Feeds raw bytes (whole events or pieces of them); the reports they close.
    pub fn push_bytes(&mut self, bytes: &[u8], reports: &mut Vec<Report>) {
        self.bytes.extend_from_slice(bytes);
        let whole = self.bytes.len() / INPUT_EVENT_BYTES * INPUT_EVENT_BYTES;
        let chunk: Vec<u8> = self.bytes.drain(..whole).collect();
        for c in chunk.chunks_exact(INPUT_EVENT_BYTES) {
            let mut b = [0u8; INPUT_EVENT_BYTES];
            b.copy_from_slice(c);
            if let Some(r) = self.push(&InputEvent::from_bytes(&b)) {
                reports.push(r);
            }
        }
    }

    /// Forgets the device state (device lost).
    pub fn release(&mut self) {
        self.state = Deflection::default();
        self.pending = self.state;
        self.bytes.clear();
    }
}

/// An input device as sysfs describes it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputDeviceInfo {
    /// `/dev/input/eventN`.
    pub path: PathBuf,
    /// The kernel's name ("3Dconnexion SpaceNavigator").
    pub name: String,
    /// USB (or bus) vendor id.
    pub vendor: u16,
    /// Product id.
    pub product: u16,
}

/// Which device to take.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceMatch {
    /// Any device of a 3Dconnexion vendor id.
    Any3Dconnexion,
    /// Name contains this text (case-insensitive).
    NameContains(String),
    /// This vendor and product id.
    UsbId(u16, u16),
}

impl DeviceMatch {
    /// True when `d` matches.
    pub fn matches(&self, d: &InputDeviceInfo) -> bool {
        match self {
            DeviceMatch::Any3Dconnexion => VENDORS_3DCONNEXION.contains(&d.vendor),
            DeviceMatch::NameContains(s) => d.name.to_lowercase().contains(&s.to_lowercase()),
            DeviceMatch::UsbId(v, p) => d.vendor == *v && d.product == *p,
        }
    }
}

fn read_trimmed(p: &Path) -> Option<String> {
    std::fs::read_to_string(p)
        .ok()
        .map(|s| s.trim().to_string())
}

/// The event devices sysfs lists under `sysfs_input` (normally `/sys/class/input`),
/// with their node under `dev_input` (normally `/dev/input`), sorted by path.
pub fn list_devices(sysfs_input: &Path, dev_input: &Path) -> Vec<InputDeviceInfo> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(sysfs_input) else {
        return out;
    };
    for e in entries.flatten() {
        let file_name = e.file_name();
        let Some(node) = file_name.to_str() else {
            continue;
        };
        if !node.starts_with("event") {
            continue;
        }
        let dev = e.path().join("device");
        let hex = |f: &str| {
            read_trimmed(&dev.join("id").join(f)).and_then(|s| u16::from_str_radix(&s, 16).ok())
        };
        let (Some(name), Some(vendor), Some(product)) = (
            read_trimmed(&dev.join("name")),
            hex("vendor"),
            hex("product"),
        ) else {
            continue;
        };
        out.push(InputDeviceInfo {
            path: dev_input.join(node),
            name,
            vendor,
            product,
        });
    }
    out.sort_by(|a, b| a.path.cmp(&b.path));
    out
}

/// The first device that matches.
pub fn find_device(
    wanted: &DeviceMatch,
    sysfs_input: &Path,
    dev_input: &Path,
) -> Result<InputDeviceInfo, DeviceError> {
    list_devices(sysfs_input, dev_input)
        .into_iter()
        .find(|d| wanted.matches(d))
        .ok_or_else(|| DeviceError::NotFound {
            wanted: format!("{wanted:?}"),
            searched: sysfs_input.display().to_string(),
        })
}

/// A SpaceMouse read from its event device, as a rate [`Master`].
pub struct EvdevMaster {
    file: File,
    path: PathBuf,
    name: String,
    decoder: EvdevDecoder,
    mapping: RateMapping,
    reports: Vec<Report>,
    last_time_us: Option<u64>,
    saturated_samples: u64,
}

impl EvdevMaster {
    /// Opens `path` (non-blocking, read-only).
    pub fn open(path: &Path, mapping: RateMapping) -> Result<Self, DeviceError> {
        let file = OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .map_err(|source| DeviceError::Io {
                device: "evdev".into(),
                operation: "open",
                path: path.to_path_buf(),
                source,
            })?;
        Ok(EvdevMaster {
            file,
            path: path.to_path_buf(),
            name: format!("evdev:{}", path.display()),
            decoder: EvdevDecoder::new(),
            mapping,
            reports: Vec::new(),
            last_time_us: None,
            saturated_samples: 0,
        })
    }

    /// Finds the device (see [`find_device`]) in `/sys/class/input` and opens it.
    pub fn find(wanted: &DeviceMatch, mapping: RateMapping) -> Result<Self, DeviceError> {
        let d = find_device(
            wanted,
            Path::new("/sys/class/input"),
            Path::new("/dev/input"),
        )?;
        Self::open(&d.path, mapping)
    }

    /// The decoder's counters.
    pub fn counters(&self) -> EvdevCounters {
        self.decoder.counters()
    }

    /// Polls whose deflection saturated an axis (beyond the mapping's full scale).
    pub fn saturated_samples(&self) -> u64 {
        self.saturated_samples
    }
}

impl Master for EvdevMaster {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Rate
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        let mut buf = [0u8; INPUT_EVENT_BYTES * 64];
        loop {
            match self.file.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    self.reports.clear();
                    self.decoder
                        .push_bytes(buf.get(..n).unwrap_or_default(), &mut self.reports);
                    if let Some(t) = self.reports.iter().rev().find_map(|r| r.time_us) {
                        self.last_time_us = Some(t);
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(source) => {
                    // ENODEV when unplugged: release everything (the robot holds).
                    self.decoder.release();
                    self.mapping.release_all();
                    return Err(DeviceError::Io {
                        device: self.name.clone(),
                        operation: "read",
                        path: self.path.clone(),
                        source,
                    });
                }
            }
        }
        let state = self.decoder.state();
        let (twist, stats) = self.mapping.twist(&state);
        if stats.saturated_axes > 0 {
            self.saturated_samples += 1;
        }
        let buttons = self.mapping.buttons(state.buttons);
        Ok(Some(MasterSample {
            t_s: now_s,
            input: MasterInput::Twist(twist),
            buttons,
            device_time_us: self.last_time_us,
            deflection: Some(state.axes),
        }))
    }
}
