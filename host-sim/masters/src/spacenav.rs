//! The SpaceMouse through the spacenavd daemon: its AF_UNIX socket protocol (the one
//! libspnav speaks), learnt from the daemon's and the library's public sources.
//!
//! # The protocol
//!
//! The daemon listens on a stream socket, `/var/run/spnav.sock` by default (libspnav also
//! honours the `SPNAV_SOCKET` environment variable; so does [`socket_path`]). Every word
//! is a 32-bit integer in the host's byte order (little-endian on every machine this
//! runs on).
//!
//! **Protocol 0** (the original): the daemon sends packets of 8 words:
//!
//! | word 0 | meaning | words 1..7 |
//! | --- | --- | --- |
//! | 0 | motion | x, y, z, rx, ry, rz, period (ms since the previous motion) |
//! | 1 | button press | button index (newer daemons: word 2 = 1) |
//! | 2 | button release | button index |
//! | 3 | device added/removed (protocol 1) | op (0 add, 1 remove), id, type, USB vendor, USB product |
//! | 4 | configuration changed (protocol 1) | setting, values |
//! | 5, 6 | raw axis / raw button (protocol 1, only when asked for) | |
//!
//! The client may send one float32, its sensitivity.
//!
//! **Protocol 1** (libspnav ≥ 1.0, spacenavd ≥ 1.0): right after connecting the client
//! sends the word `0x7faa5500 | version`. A float read of that word is a NaN, which an old
//! daemon ignores (or, older still, takes as its sensitivity; libspnav then sends 1.0).
//! A new daemon answers with one word, the same tag with the version it speaks. From then
//! on requests and responses are packets of 8 words too: `[0x7faa0000 | request, data0..6]`,
//! the response echoing the request word with its status in word 7 (negative: failure).
//! Events and responses share the stream; word 0 tells them apart (events 0..6, responses
//! carry the tag `0x7faa` in the high half).
//!
//! This client asks for protocol 1 and then for the number of axes and buttons, the USB
//! id and the device type (every daemon of protocol 1 answers them the same way). It does
//! not ask for the device name or path: spacenavd 1.1 answers those with a length and the
//! raw bytes after the packet, later versions with 24-byte chunks in packets, and the two
//! cannot be told apart reliably. With an old daemon (no answer within the handshake
//! timeout, or an event first) it stays on protocol 0.
//!
//! Debian's `spacenavd` 1.1 runs without any device: started with `-d` it binds
//! `run/spnav.sock` relative to its working directory, answers the handshake with version
//! 1, and fails device queries with status −1 (see `tests/spacenavd_daemon.rs`).

use crate::device::{DeviceError, Master, MasterInput, MasterKind, MasterSample};
use crate::rate::{Deflection, RateMapping};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The daemon's default socket.
pub const DEFAULT_SOCKET_PATH: &str = "/var/run/spnav.sock";
/// Bytes in a packet (8 words).
pub const PACKET_BYTES: usize = 32;
/// The tag of requests, responses and the protocol handshake (high half of word 0).
pub const REQ_TAG: i32 = 0x7faa_0000;
/// The protocol-change request (low half of the handshake word, version in the low byte).
pub const REQ_CHANGE_PROTO: i32 = 0x5500;
/// Device queries (protocol 1).
pub const REQ_DEV_NAXES: i32 = 0x2002;
/// Number of buttons.
pub const REQ_DEV_NBUTTONS: i32 = 0x2003;
/// USB vendor and product id.
pub const REQ_DEV_USBID: i32 = 0x2004;
/// The daemon's device-type enumeration.
pub const REQ_DEV_TYPE: i32 = 0x2005;
/// Set the client's name (no response from spacenavd 1.1).
pub const REQ_SET_NAME: i32 = 0x1000;
/// Device event op: added.
pub const DEV_ADD: i32 = 0;
/// Device event op: removed.
pub const DEV_REMOVE: i32 = 1;

const UEV_MOTION: i32 = 0;
const UEV_PRESS: i32 = 1;
const UEV_RELEASE: i32 = 2;
const UEV_DEV: i32 = 3;
const UEV_CFG: i32 = 4;
const UEV_RAWAXIS: i32 = 5;
const UEV_RAWBUTTON: i32 = 6;

/// The socket: `$SPNAV_SOCKET` if set, else [`DEFAULT_SOCKET_PATH`].
pub fn socket_path() -> PathBuf {
    std::env::var_os("SPNAV_SOCKET")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(DEFAULT_SOCKET_PATH))
}

/// An event from the daemon.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpnavEvent {
    /// The cap's deflection (device counts, after the daemon's sensitivity).
    Motion {
        /// `[x, y, z, rx, ry, rz]`.
        axes: [i32; 6],
        /// Milliseconds since the previous motion event.
        period_ms: i32,
    },
    /// A button pressed or released.
    Button {
        /// Button index.
        index: i32,
        /// Pressed (true) or released.
        pressed: bool,
    },
    /// A device added or removed (protocol 1).
    Device {
        /// [`DEV_ADD`] or [`DEV_REMOVE`].
        op: i32,
        /// The daemon's device id.
        id: i32,
        /// The daemon's device type.
        device_type: i32,
        /// USB vendor id.
        usb_vendor: i32,
        /// USB product id.
        usb_product: i32,
    },
    /// Configuration changed (protocol 1).
    Config {
        /// Words 1..7.
        data: [i32; 7],
    },
    /// A raw axis or button report (protocol 1, only on request).
    Raw {
        /// True for a raw button, false for a raw axis.
        button: bool,
        /// Words 1..7.
        data: [i32; 7],
    },
}

/// One packet of 8 words as the daemon sends it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpnavPacket {
    /// An event.
    Event(SpnavEvent),
    /// A response to a request (protocol 1).
    Response {
        /// The request (word 0 without the tag).
        request: i32,
        /// Words 1..7; word 7 (`data[6]`) is the status.
        data: [i32; 7],
    },
    /// Word 0 is neither an event type nor a tagged response.
    Unknown {
        /// Word 0.
        word0: i32,
    },
}

/// The 8 words of a packet.
pub fn packet_words(bytes: &[u8; PACKET_BYTES]) -> [i32; 8] {
    let mut w = [0i32; 8];
    for (word, chunk) in w.iter_mut().zip(bytes.chunks_exact(4)) {
        let mut b = [0u8; 4];
        b.copy_from_slice(chunk);
        *word = i32::from_ne_bytes(b);
    }
    w
}

/// Decodes one packet.
pub fn decode_packet(bytes: &[u8; PACKET_BYTES]) -> SpnavPacket {
    let w = packet_words(bytes);
    let [w0, w1, w2, w3, w4, w5, w6, w7] = w;
    let rest = [w1, w2, w3, w4, w5, w6, w7];
    if w0 & !0xffff == REQ_TAG {
        return SpnavPacket::Response {
            request: w0 & 0xffff,
            data: rest,
        };
    }
    let ev = match w0 {
        UEV_MOTION => SpnavEvent::Motion {
            axes: [w1, w2, w3, w4, w5, w6],
            period_ms: w7,
        },
        UEV_PRESS | UEV_RELEASE => SpnavEvent::Button {
            index: w1,
            pressed: w0 == UEV_PRESS,
        },
        UEV_DEV => SpnavEvent::Device {
            op: w1,
            id: w2,
            device_type: w3,
            usb_vendor: w4,
            usb_product: w5,
        },
        UEV_CFG => SpnavEvent::Config { data: rest },
        UEV_RAWAXIS | UEV_RAWBUTTON => SpnavEvent::Raw {
            button: w0 == UEV_RAWBUTTON,
            data: rest,
        },
        _ => return SpnavPacket::Unknown { word0: w0 },
    };
    SpnavPacket::Event(ev)
}

/// Cuts the daemon's byte stream into packets (reads may split or join them).
#[derive(Clone, Debug, Default)]
pub struct PacketReader {
    buf: Vec<u8>,
}

impl PacketReader {
    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next whole packet, if one is buffered.
    pub fn next_packet(&mut self) -> Option<SpnavPacket> {
        let head = self.buf.get(..PACKET_BYTES)?;
        let mut p = [0u8; PACKET_BYTES];
        p.copy_from_slice(head);
        self.buf.drain(..PACKET_BYTES);
        Some(decode_packet(&p))
    }

    /// Bytes of an incomplete packet still buffered.
    pub fn pending_bytes(&self) -> usize {
        self.buf.len()
    }
}

/// Counters of what the client received.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SpnavCounters {
    /// Motion events.
    pub motion: u64,
    /// Button events.
    pub buttons: u64,
    /// Device, configuration and raw events.
    pub other_events: u64,
    /// Responses nobody waited for.
    pub stray_responses: u64,
    /// Packets whose word 0 is unknown (skipped).
    pub unknown_packets: u64,
    /// Button events with an index outside 0..32 (skipped).
    pub bad_button_index: u64,
    /// Polls whose deflection saturated an axis (beyond the mapping's full scale).
    pub saturated_samples: u64,
}

/// How to connect.
#[derive(Clone, Debug)]
pub struct SpnavOptions {
    /// Ask for protocol 1 (and the device queries).
    pub handshake: bool,
    /// How long to wait for the daemon's answer to the handshake (libspnav: 300 ms).
    pub handshake_timeout: Duration,
    /// How long to wait for a response to a request (libspnav: 400 ms).
    pub request_timeout: Duration,
    /// The client name sent with protocol 1 (at most 24 bytes are sent).
    pub client_name: String,
}

impl Default for SpnavOptions {
    fn default() -> Self {
        SpnavOptions {
            handshake: true,
            handshake_timeout: Duration::from_millis(300),
            request_timeout: Duration::from_millis(400),
            client_name: "rspr-masters".into(),
        }
    }
}

/// The device the daemon serves, as protocol 1 reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpnavDeviceInfo {
    /// Number of axes.
    pub axes: i32,
    /// Number of buttons.
    pub buttons: i32,
    /// USB vendor and product id, when the daemon knows them.
    pub usb_id: Option<(u16, u16)>,
    /// The daemon's device type (e.g. 0x206 Space Navigator), when known.
    pub device_type: Option<i32>,
}

/// A connection to spacenavd.
pub struct SpnavClient {
    stream: UnixStream,
    path: PathBuf,
    reader: PacketReader,
    queued: VecDeque<SpnavEvent>,
    protocol: u8,
    device: Option<SpnavDeviceInfo>,
    counters: SpnavCounters,
}

const DEVICE: &str = "spacenavd";

impl SpnavClient {
    /// Connects to the daemon at `path`, negotiates the protocol and (protocol 1) asks for
    /// the device; the stream is then non-blocking.
    pub fn connect(path: &Path, options: &SpnavOptions) -> Result<Self, DeviceError> {
        let io = |operation, source| DeviceError::Io {
            device: DEVICE.into(),
            operation,
            path: path.to_path_buf(),
            source,
        };
        let stream = UnixStream::connect(path).map_err(|e| io("connect", e))?;
        let mut c = SpnavClient {
            stream,
            path: path.to_path_buf(),
            reader: PacketReader::default(),
            queued: VecDeque::new(),
            protocol: 0,
            device: None,
            counters: SpnavCounters::default(),
        };
        if options.handshake {
            c.handshake(options)?;
        }
        if c.protocol >= 1 {
            c.send_name(&options.client_name)?;
            c.device = c.query_device(options.request_timeout)?;
        }
        c.stream
            .set_nonblocking(true)
            .map_err(|e| io("set non-blocking", e))?;
        Ok(c)
    }

    fn io_err(&self, operation: &'static str, source: std::io::Error) -> DeviceError {
        DeviceError::Io {
            device: DEVICE.into(),
            operation,
            path: self.path.clone(),
            source,
        }
    }

    fn write_all(&mut self, bytes: &[u8]) -> Result<(), DeviceError> {
        let r = self.stream.write_all(bytes);
        r.map_err(|e| self.io_err("write", e))
    }

    /// Reads what arrives before `deadline` into `buf` (blocking with a timeout); the
    /// number of bytes, 0 on timeout.
    fn read_until(&mut self, buf: &mut [u8], deadline: Instant) -> Result<usize, DeviceError> {
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(0);
            }
            let r = self.stream.set_read_timeout(Some(left));
            r.map_err(|e| self.io_err("set timeout", e))?;
            match self.stream.read(buf) {
                Ok(0) => {
                    return Err(DeviceError::Disconnected {
                        device: DEVICE.into(),
                        detail: "the daemon closed the socket".into(),
                    })
                }
                Ok(n) => return Ok(n),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    return Ok(0)
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(self.io_err("read", e)),
            }
        }
    }

    fn handshake(&mut self, options: &SpnavOptions) -> Result<(), DeviceError> {
        let want = REQ_TAG | REQ_CHANGE_PROTO | 1;
        self.write_all(&want.to_ne_bytes())?;
        let deadline = Instant::now() + options.handshake_timeout;
        let mut got = Vec::new();
        while got.len() < 4 {
            let mut b = [0u8; 4];
            let need = 4 - got.len();
            let n = self.read_until(b.get_mut(..need).unwrap_or_default(), deadline)?;
            if n == 0 {
                break;
            }
            got.extend_from_slice(b.get(..n).unwrap_or_default());
        }
        let mut word = [0u8; 4];
        if got.len() == 4 {
            word.copy_from_slice(&got);
        }
        let reply = i32::from_ne_bytes(word);
        if got.len() == 4 && reply & !0xff == REQ_TAG | REQ_CHANGE_PROTO {
            self.protocol = (reply & 0xff) as u8;
        } else {
            // An old daemon: whatever arrived is the start of an event packet. It may have
            // taken the handshake word as its sensitivity: set it back to 1.0.
            self.reader.push(&got);
            self.protocol = 0;
            self.write_all(&1.0f32.to_ne_bytes())?;
        }
        Ok(())
    }

    fn send_name(&mut self, name: &str) -> Result<(), DeviceError> {
        // Up to 24 bytes in words 1..6, the length in word 7 (no response expected).
        let bytes = name.as_bytes();
        let n = bytes.len().min(24);
        let mut p = [0u8; PACKET_BYTES];
        p[..4].copy_from_slice(&(REQ_TAG | REQ_SET_NAME).to_ne_bytes());
        if let (Some(dst), Some(srcb)) = (p.get_mut(4..4 + n), bytes.get(..n)) {
            dst.copy_from_slice(srcb);
        }
        p[28..].copy_from_slice(&(n as i32).to_ne_bytes());
        self.write_all(&p)
    }

    /// Sends request `request` with `data` and waits for its response; events arriving
    /// meanwhile are queued. `Ok(None)` when the daemon answers with a failure status.
    pub fn request(
        &mut self,
        request: i32,
        data: [i32; 7],
        timeout: Duration,
    ) -> Result<Option<[i32; 7]>, DeviceError> {
        if self.protocol < 1 {
            return Err(DeviceError::Protocol {
                device: DEVICE.into(),
                detail: format!("request {request:#x} needs protocol 1, the daemon speaks 0"),
            });
        }
        let mut p = [0u8; PACKET_BYTES];
        for (chunk, w) in p
            .chunks_exact_mut(4)
            .zip(std::iter::once(REQ_TAG | request).chain(data))
        {
            chunk.copy_from_slice(&w.to_ne_bytes());
        }
        self.write_all(&p)?;
        let deadline = Instant::now() + timeout;
        loop {
            while let Some(packet) = self.reader.next_packet() {
                match packet {
                    SpnavPacket::Response { request: r, data } if r == request => {
                        return Ok((data[6] >= 0).then_some(data));
                    }
                    other => self.absorb(other),
                }
            }
            let mut buf = [0u8; 256];
            let n = self.read_until(&mut buf, deadline)?;
            if n == 0 {
                return Err(DeviceError::Protocol {
                    device: DEVICE.into(),
                    detail: format!("no response to request {request:#x} within {timeout:?}"),
                });
            }
            self.reader.push(buf.get(..n).unwrap_or_default());
        }
    }

    fn query_device(&mut self, timeout: Duration) -> Result<Option<SpnavDeviceInfo>, DeviceError> {
        let Some(axes) = self.request(REQ_DEV_NAXES, [0; 7], timeout)? else {
            return Ok(None);
        };
        let buttons = self.request(REQ_DEV_NBUTTONS, [0; 7], timeout)?;
        let usb = self.request(REQ_DEV_USBID, [0; 7], timeout)?;
        let device_type = self.request(REQ_DEV_TYPE, [0; 7], timeout)?;
        Ok(Some(SpnavDeviceInfo {
            axes: axes[0],
            buttons: buttons.map_or(0, |b| b[0]),
            usb_id: usb.map(|u| (u[0] as u16, u[1] as u16)),
            device_type: device_type.map(|t| t[0]),
        }))
    }

    fn absorb(&mut self, packet: SpnavPacket) {
        match packet {
            SpnavPacket::Event(e) => self.queued.push_back(e),
            SpnavPacket::Response { .. } => self.counters.stray_responses += 1,
            SpnavPacket::Unknown { .. } => self.counters.unknown_packets += 1,
        }
    }

    /// The negotiated protocol version.
    pub fn protocol(&self) -> u8 {
        self.protocol
    }

    /// The device (protocol 1 and a device present at connection).
    pub fn device(&self) -> Option<SpnavDeviceInfo> {
        self.device
    }

    /// What was received.
    pub fn counters(&self) -> SpnavCounters {
        self.counters
    }

    /// Reads everything available without blocking and appends the events to `out`.
    pub fn poll_events(&mut self, out: &mut Vec<SpnavEvent>) -> Result<(), DeviceError> {
        let mut buf = [0u8; 1024];
        loop {
            match self.stream.read(&mut buf) {
                Ok(0) => {
                    return Err(DeviceError::Disconnected {
                        device: DEVICE.into(),
                        detail: "the daemon closed the socket".into(),
                    })
                }
                Ok(n) => self.reader.push(buf.get(..n).unwrap_or_default()),
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(self.io_err("read", e)),
            }
        }
        while let Some(p) = self.reader.next_packet() {
            self.absorb(p);
        }
        for e in self.queued.drain(..) {
            match e {
                SpnavEvent::Motion { .. } => self.counters.motion += 1,
                SpnavEvent::Button { .. } => self.counters.buttons += 1,
                _ => self.counters.other_events += 1,
            }
            out.push(e);
        }
        Ok(())
    }
}

/// Applies daemon events to a device state; true when the device was removed (the state
/// is then released: no deflection, no button).
pub fn apply_event(
    state: &mut Deflection,
    event: &SpnavEvent,
    counters: &mut SpnavCounters,
) -> bool {
    match *event {
        SpnavEvent::Motion { axes, .. } => {
            state.axes = axes.map(f64::from);
            false
        }
        SpnavEvent::Button { index, pressed } => {
            match u32::try_from(index).ok().and_then(|i| 1u32.checked_shl(i)) {
                Some(bit) if pressed => state.buttons |= bit,
                Some(bit) => state.buttons &= !bit,
                None => counters.bad_button_index += 1,
            }
            false
        }
        SpnavEvent::Device { op, .. } if op == DEV_REMOVE => {
            *state = Deflection::default();
            true
        }
        _ => false,
    }
}

/// A SpaceMouse read through spacenavd, as a rate [`Master`].
pub struct SpaceNavMaster {
    client: SpnavClient,
    mapping: RateMapping,
    state: Deflection,
    events: Vec<SpnavEvent>,
    counters: SpnavCounters,
}

impl SpaceNavMaster {
    /// Connects to the daemon at `path` (see [`socket_path`]).
    pub fn connect(
        path: &Path,
        options: &SpnavOptions,
        mapping: RateMapping,
    ) -> Result<Self, DeviceError> {
        Ok(Self::new(SpnavClient::connect(path, options)?, mapping))
    }

    /// Over an open client.
    pub fn new(client: SpnavClient, mapping: RateMapping) -> Self {
        SpaceNavMaster {
            client,
            mapping,
            state: Deflection::default(),
            events: Vec::new(),
            counters: SpnavCounters::default(),
        }
    }

    /// The client (protocol, device, counters).
    pub fn client(&self) -> &SpnavClient {
        &self.client
    }

    /// The client's counters, with bad button indices and saturated samples.
    pub fn counters(&self) -> SpnavCounters {
        let mut c = self.client.counters();
        c.bad_button_index = self.counters.bad_button_index;
        c.saturated_samples = self.counters.saturated_samples;
        c
    }
}

impl Master for SpaceNavMaster {
    fn name(&self) -> &str {
        DEVICE
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Rate
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        self.events.clear();
        let r = self.client.poll_events(&mut self.events);
        if r.is_err() {
            self.state = Deflection::default();
            self.mapping.release_all();
        }
        r?;
        for e in &self.events {
            if apply_event(&mut self.state, e, &mut self.counters) {
                self.mapping.release_all();
            }
        }
        let (twist, stats) = self.mapping.twist(&self.state);
        if stats.saturated_axes > 0 {
            self.counters.saturated_samples += 1;
        }
        let buttons = self.mapping.buttons(self.state.buttons);
        Ok(Some(MasterSample {
            t_s: now_s,
            input: MasterInput::Twist(twist),
            buttons,
            device_time_us: None,
            deflection: Some(self.state.axes),
        }))
    }
}
