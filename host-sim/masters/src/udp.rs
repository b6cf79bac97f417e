//! A position master streaming its pose over UDP: a tracked stylus, or another lab's
//! master arm.
//!
//! # Datagram format, version 1
//!
//! One pose per datagram, 56 bytes, little-endian, no padding:
//!
//! | offset | size | type | field |
//! | --- | --- | --- | --- |
//! | 0 | 4 | bytes | magic `RSPM` (0x52 0x53 0x50 0x4D) |
//! | 4 | 1 | u8 | version = 1 |
//! | 5 | 1 | u8 | flags: bit 0 tracking valid; bits 1..7 reserved, 0 |
//! | 6 | 2 | u16 | length of the datagram in bytes = 56 |
//! | 8 | 4 | u32 | session: chosen at random when the sender starts |
//! | 12 | 4 | u32 | sequence number, +1 per datagram (wraps) |
//! | 16 | 8 | u64 | time stamp, µs, the sender's monotonic clock |
//! | 24 | 12 | 3 × f32 | position x, y, z, mm, in the sender's frame |
//! | 36 | 16 | 4 × f32 | orientation quaternion w, x, y, z (unit), sender's frame |
//! | 52 | 4 | u32 | buttons: bit 0 clutch, bit 1 operator present, bits 2..31 free |
//!
//! The receiver rejects, each with its own counter ([`RejectCounts`]):
//! - **malformed**: shorter or longer than 56 bytes, another magic, another version, a
//!   length field that is not the datagram's length, a reserved flag set, a non-finite
//!   number, a quaternion whose norm is off 1 by more than 10⁻³;
//! - **out of order**: a sequence number not after the last accepted one (serial-number
//!   arithmetic, so it wraps), with **duplicates** counted apart;
//! - **stale**: older than `max_age_s` on arrival. The two clocks are not synchronised,
//!   so the age is estimated: the offset `arrival − stamp` of each datagram is its
//!   one-way delay plus the clock offset; the smallest offset seen (allowed to creep up
//!   by `drift_allowance` s per s, so that a sender clock running slow is followed) stands
//!   for the delay-free offset, and the age is the excess over it.
//!
//! A new session number (the sender restarted) resets the order and the clock estimate,
//! but only once the current session has been silent for `session_switch_s` (default
//! 0.25 s): until then datagrams of another session are refused (**other session**), so
//! a late datagram of an earlier session, or a second sender, cannot take over a live
//! stream.
//! A datagram without the tracking-valid flag is accepted but reads as "operator
//! absent": the robot holds until tracking returns.

use crate::device::{DeviceError, Master, MasterInput, MasterKind, MasterSample, OperatorButtons};
use crate::pose::CartesianPose;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};
use thiserror::Error;

/// The magic bytes.
pub const MAGIC: [u8; 4] = *b"RSPM";
/// The version this code speaks.
pub const VERSION: u8 = 1;
/// Bytes of a version-1 datagram.
pub const DATAGRAM_BYTES: usize = 56;
/// Flag: the tracker sees the master.
pub const FLAG_TRACKING_VALID: u8 = 0x01;
/// Button bit: clutch.
pub const BUTTON_CLUTCH: u32 = 0x01;
/// Button bit: operator present.
pub const BUTTON_OPERATOR_PRESENT: u32 = 0x02;

/// One pose as sent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseDatagram {
    /// Flags (bit 0 tracking valid).
    pub flags: u8,
    /// Sender session.
    pub session: u32,
    /// Sequence number.
    pub sequence: u32,
    /// Sender time stamp, µs.
    pub timestamp_us: u64,
    /// Position, mm.
    pub position_mm: [f32; 3],
    /// Orientation quaternion `[w, x, y, z]`.
    pub orientation_wxyz: [f32; 4],
    /// Buttons (bit 0 clutch, bit 1 operator present).
    pub buttons: u32,
}

/// Why a datagram was refused.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum DatagramError {
    /// Not 56 bytes.
    #[error("datagram of {0} bytes, version 1 has 56")]
    WrongSize(usize),
    /// Another magic.
    #[error("magic {0:02x?} is not RSPM")]
    BadMagic([u8; 4]),
    /// Another version.
    #[error("version {0} (this receiver speaks 1)")]
    UnsupportedVersion(u8),
    /// The length field disagrees.
    #[error("length field {field} but {actual} bytes received")]
    LengthMismatch {
        /// The field.
        field: u16,
        /// The datagram's size.
        actual: usize,
    },
    /// A reserved flag is set.
    #[error("reserved flag bits {0:#04x} set")]
    ReservedFlags(u8),
    /// A number is not finite.
    #[error("field {0} is not finite")]
    NonFinite(&'static str),
    /// The quaternion is not unit.
    #[error("quaternion norm {0} is not 1 (tolerance 1e-3)")]
    NotUnitQuaternion(f32),
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        w.copy_from_slice(s);
    }
    u32::from_le_bytes(w)
}

fn le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(le_u32(b, at).to_le_bytes())
}

impl PoseDatagram {
    /// Encodes (little-endian, 56 bytes).
    pub fn encode(&self) -> [u8; DATAGRAM_BYTES] {
        let mut b = [0u8; DATAGRAM_BYTES];
        b[0..4].copy_from_slice(&MAGIC);
        b[4] = VERSION;
        b[5] = self.flags;
        b[6..8].copy_from_slice(&(DATAGRAM_BYTES as u16).to_le_bytes());
        b[8..12].copy_from_slice(&self.session.to_le_bytes());
        b[12..16].copy_from_slice(&self.sequence.to_le_bytes());
        b[16..24].copy_from_slice(&self.timestamp_us.to_le_bytes());
        for (i, v) in self.position_mm.iter().enumerate() {
            b[24 + 4 * i..28 + 4 * i].copy_from_slice(&v.to_le_bytes());
        }
        for (i, v) in self.orientation_wxyz.iter().enumerate() {
            b[36 + 4 * i..40 + 4 * i].copy_from_slice(&v.to_le_bytes());
        }
        b[52..56].copy_from_slice(&self.buttons.to_le_bytes());
        b
    }

    /// Decodes and checks the format (not order or age).
    pub fn decode(b: &[u8]) -> Result<Self, DatagramError> {
        if b.len() != DATAGRAM_BYTES {
            // Look at magic and version first when there are enough bytes: a future,
            // longer version is reported as such.
            if b.len() >= 8 {
                let mut m = [0u8; 4];
                m.copy_from_slice(&b[0..4]);
                if m != MAGIC {
                    return Err(DatagramError::BadMagic(m));
                }
                if b[4] != VERSION {
                    return Err(DatagramError::UnsupportedVersion(b[4]));
                }
            }
            return Err(DatagramError::WrongSize(b.len()));
        }
        let mut m = [0u8; 4];
        m.copy_from_slice(&b[0..4]);
        if m != MAGIC {
            return Err(DatagramError::BadMagic(m));
        }
        if b[4] != VERSION {
            return Err(DatagramError::UnsupportedVersion(b[4]));
        }
        let flags = b[5];
        let length = u16::from_le_bytes([b[6], b[7]]);
        if usize::from(length) != b.len() {
            return Err(DatagramError::LengthMismatch {
                field: length,
                actual: b.len(),
            });
        }
        if flags & !FLAG_TRACKING_VALID != 0 {
            return Err(DatagramError::ReservedFlags(flags & !FLAG_TRACKING_VALID));
        }
        let mut ts = [0u8; 8];
        ts.copy_from_slice(&b[16..24]);
        let position_mm = [le_f32(b, 24), le_f32(b, 28), le_f32(b, 32)];
        let orientation_wxyz = [le_f32(b, 36), le_f32(b, 40), le_f32(b, 44), le_f32(b, 48)];
        if position_mm.iter().any(|v| !v.is_finite()) {
            return Err(DatagramError::NonFinite("position_mm"));
        }
        if orientation_wxyz.iter().any(|v| !v.is_finite()) {
            return Err(DatagramError::NonFinite("orientation"));
        }
        let norm = orientation_wxyz.iter().map(|v| v * v).sum::<f32>().sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(DatagramError::NotUnitQuaternion(norm));
        }
        Ok(PoseDatagram {
            flags,
            session: le_u32(b, 8),
            sequence: le_u32(b, 12),
            timestamp_us: u64::from_le_bytes(ts),
            position_mm,
            orientation_wxyz,
            buttons: le_u32(b, 52),
        })
    }

    /// The pose (SI; quaternion renormalised in f64).
    pub fn pose(&self) -> CartesianPose {
        let [x, y, z] = self.position_mm.map(|v| f64::from(v) * 1e-3);
        let [w, i, j, k] = self.orientation_wxyz.map(f64::from);
        CartesianPose {
            position_m: Vector3::new(x, y, z),
            orientation: UnitQuaternion::new_normalize(Quaternion::new(w, i, j, k)),
        }
    }

    /// Clutch and presence (presence also needs tracking).
    pub fn operator_buttons(&self) -> OperatorButtons {
        OperatorButtons {
            clutch: self.buttons & BUTTON_CLUTCH != 0,
            operator_present: self.buttons & BUTTON_OPERATOR_PRESENT != 0
                && self.flags & FLAG_TRACKING_VALID != 0,
        }
    }
}

/// Refused datagrams by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RejectCounts {
    /// Wrong size.
    pub wrong_size: u64,
    /// Wrong magic.
    pub bad_magic: u64,
    /// Other version.
    pub unsupported_version: u64,
    /// Length field mismatch.
    pub length_mismatch: u64,
    /// Reserved flags set.
    pub reserved_flags: u64,
    /// Non-finite numbers.
    pub non_finite: u64,
    /// Quaternion not unit.
    pub not_unit_quaternion: u64,
    /// Sequence not after the last accepted.
    pub out_of_order: u64,
    /// Same sequence as the last accepted.
    pub duplicate: u64,
    /// Too old on arrival.
    pub stale: u64,
    /// From another sender than the configured one.
    pub wrong_peer: u64,
    /// Of another session while the current one is live.
    pub other_session: u64,
}

impl RejectCounts {
    /// Every rejection.
    pub fn total(&self) -> u64 {
        self.wrong_size
            + self.bad_magic
            + self.unsupported_version
            + self.length_mismatch
            + self.reserved_flags
            + self.non_finite
            + self.not_unit_quaternion
            + self.out_of_order
            + self.duplicate
            + self.stale
            + self.wrong_peer
            + self.other_session
    }

    fn count(&mut self, e: &DatagramError) {
        match e {
            DatagramError::WrongSize(_) => self.wrong_size += 1,
            DatagramError::BadMagic(_) => self.bad_magic += 1,
            DatagramError::UnsupportedVersion(_) => self.unsupported_version += 1,
            DatagramError::LengthMismatch { .. } => self.length_mismatch += 1,
            DatagramError::ReservedFlags(_) => self.reserved_flags += 1,
            DatagramError::NonFinite(_) => self.non_finite += 1,
            DatagramError::NotUnitQuaternion(_) => self.not_unit_quaternion += 1,
        }
    }
}

/// The receiver's verdict on one datagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Verdict {
    /// Accepted.
    Accepted(PoseDatagram),
    /// Malformed.
    Malformed(DatagramError),
    /// Sequence not after the last accepted.
    OutOfOrder {
        /// Its sequence.
        sequence: u32,
        /// The last accepted.
        last: u32,
    },
    /// The last accepted again.
    Duplicate(u32),
    /// Too old.
    Stale {
        /// Estimated age, s.
        age_s: f64,
    },
    /// Another session while the current one is live.
    OtherSession {
        /// Its session.
        session: u32,
        /// The current one.
        current: u32,
    },
}

/// Acceptance settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GateConfig {
    /// Oldest accepted datagram, s.
    pub max_age_s: f64,
    /// How fast the delay-free offset may creep up, s per s (sender clock drift).
    pub drift_allowance: f64,
    /// How long the current session must be silent before another is taken, s.
    pub session_switch_s: f64,
}

impl Default for GateConfig {
    fn default() -> Self {
        GateConfig {
            max_age_s: 0.05,
            drift_allowance: 200e-6,
            session_switch_s: 0.25,
        }
    }
}

/// Order, duplicates and age: the receiver's state.
#[derive(Clone, Debug)]
pub struct DatagramGate {
    config: GateConfig,
    session: Option<u32>,
    last_sequence: u32,
    last_accepted_s: f64,
    /// (smallest offset arrival − stamp, s; arrival of the datagram that set it, s)
    min_offset: Option<(f64, f64)>,
    counts: RejectCounts,
    accepted: u64,
    sessions: u64,
}

impl DatagramGate {
    /// A gate that has seen nothing.
    pub fn new(config: GateConfig) -> Self {
        DatagramGate {
            config,
            session: None,
            last_sequence: 0,
            last_accepted_s: f64::NEG_INFINITY,
            min_offset: None,
            counts: RejectCounts::default(),
            accepted: 0,
            sessions: 0,
        }
    }

    /// Rejections so far.
    pub fn counts(&self) -> RejectCounts {
        self.counts
    }

    /// Accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Sender sessions seen.
    pub fn sessions(&self) -> u64 {
        self.sessions
    }

    /// Judges the datagram `bytes` that arrived at `arrival_s` (receiver clock).
    pub fn judge(&mut self, bytes: &[u8], arrival_s: f64) -> Verdict {
        let d = match PoseDatagram::decode(bytes) {
            Ok(d) => d,
            Err(e) => {
                self.counts.count(&e);
                return Verdict::Malformed(e);
            }
        };
        if self.session != Some(d.session) {
            if let Some(current) = self.session {
                if arrival_s - self.last_accepted_s < self.config.session_switch_s {
                    self.counts.other_session += 1;
                    return Verdict::OtherSession {
                        session: d.session,
                        current,
                    };
                }
            }
            self.session = Some(d.session);
            self.sessions += 1;
            self.min_offset = None;
        } else {
            // Serial-number arithmetic: d is after last when 0 < d - last < 2^31.
            let ahead = d.sequence.wrapping_sub(self.last_sequence);
            if ahead == 0 {
                self.counts.duplicate += 1;
                return Verdict::Duplicate(d.sequence);
            }
            if ahead >= 1 << 31 {
                self.counts.out_of_order += 1;
                return Verdict::OutOfOrder {
                    sequence: d.sequence,
                    last: self.last_sequence,
                };
            }
        }
        let offset = arrival_s - d.timestamp_us as f64 * 1e-6;
        let base = match self.min_offset {
            Some((m, at)) => {
                (m + self.config.drift_allowance * (arrival_s - at).max(0.0)).min(offset)
            }
            None => offset,
        };
        let age_s = offset - base;
        if age_s > self.config.max_age_s {
            self.counts.stale += 1;
            return Verdict::Stale { age_s };
        }
        if self.min_offset.is_none() || base == offset {
            self.min_offset = Some((offset, arrival_s));
        }
        self.last_sequence = d.sequence;
        self.last_accepted_s = arrival_s;
        self.accepted += 1;
        Verdict::Accepted(d)
    }

    /// Counts a datagram from a sender other than the configured one.
    pub fn count_wrong_peer(&mut self) {
        self.counts.wrong_peer += 1;
    }
}

/// The UDP pose master.
pub struct UdpPoseMaster {
    socket: UdpSocket,
    name: String,
    peer: Option<SocketAddr>,
    gate: DatagramGate,
    latest: Option<PoseDatagram>,
}

impl UdpPoseMaster {
    /// Binds `local` (e.g. `127.0.0.1:47100`); only datagrams from `peer` are taken when
    /// it is given.
    pub fn bind(
        local: SocketAddr,
        peer: Option<SocketAddr>,
        gate: GateConfig,
    ) -> Result<Self, DeviceError> {
        let io = |operation, source| DeviceError::Io {
            device: "udp".into(),
            operation,
            path: local.to_string().into(),
            source,
        };
        let socket = UdpSocket::bind(local).map_err(|e| io("bind", e))?;
        socket
            .set_nonblocking(true)
            .map_err(|e| io("set non-blocking", e))?;
        let name = format!(
            "udp:{}",
            socket.local_addr().map_err(|e| io("local address", e))?
        );
        Ok(UdpPoseMaster {
            socket,
            name,
            peer,
            gate: DatagramGate::new(gate),
            latest: None,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.socket.local_addr().ok()
    }

    /// The gate (counters).
    pub fn gate(&self) -> &DatagramGate {
        &self.gate
    }

    /// The newest accepted datagram.
    pub fn latest(&self) -> Option<&PoseDatagram> {
        self.latest.as_ref()
    }
}

impl Master for UdpPoseMaster {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Position
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        let mut buf = [0u8; 2048];
        let mut newest = None;
        loop {
            match self.socket.recv_from(&mut buf) {
                Ok((n, from)) => {
                    if self.peer.is_some_and(|p| p != from) {
                        self.gate.count_wrong_peer();
                        continue;
                    }
                    if let Verdict::Accepted(d) =
                        self.gate.judge(buf.get(..n).unwrap_or_default(), now_s)
                    {
                        newest = Some(d);
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(source) => {
                    return Err(DeviceError::Io {
                        device: self.name.clone(),
                        operation: "receive",
                        path: self.name.clone().into(),
                        source,
                    })
                }
            }
        }
        let Some(d) = newest else {
            return Ok(None);
        };
        self.latest = Some(d);
        Ok(Some(MasterSample {
            t_s: now_s,
            input: MasterInput::Pose(d.pose()),
            buttons: d.operator_buttons(),
            device_time_us: Some(d.timestamp_us),
            deflection: None,
        }))
    }
}
