//! The master's side of the link: the writer with the master's session and sequence numbers
//! ([`Link`]) over a [`Medium`] that carries the bytes and keeps the clock. [`open`] gives the
//! host's medium, a Unix socket (QEMU's `-serial unix:PATH,server=on`) or a serial device,
//! timed by the host's clock, with a reader thread that decodes the board's frames
//! (`MasterDecoder`: COBS, CRC, tag, version, session, sequence; [`MasterRx`]) and hands
//! them over with their arrival time.
//!
//! **Sessions.** The board issues them: the master's `Hello` carries its nonce (fresh per
//! connection) and its clock; the board's `HelloReply` echoing that nonce carries the
//! session, which [`MasterRx`] opens on the receiving side and [`Link`] puts in every later
//! frame. A `HelloRefused` (another master owns the board, a replayed `Hello`) comes
//! outside any session.
//!
//! **Keys.** A link with a pre-shared key ([`open_with_key`], [`Link::with_key`]; the
//! command line's `--key-file PATH`, [`read_key_file`]) tags every frame it sends and drops
//! the board's frames without a valid tag. A board with a key drops every frame of a master
//! without one: its `Hello` goes unanswered. An emulated board stepped in lockstep brings its own medium, timed by its virtual
//! clock ([`Link::over`]).

use crate::error::TeleopError;
use master_link::{
    encode_with, BoardToMaster, FrameError, Header, LinkCounters, LinkKey, MasterDecoder,
    MasterToBoard, Seq, SeqCounter, MAX_FRAME_LEN, PROTOCOL_VERSION,
};
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::net::Shutdown;
use std::os::unix::fs::FileTypeExt;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::Command;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

/// One decoded board message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Received {
    /// Arrival, s since the link was opened.
    pub t_s: f64,
    /// The board's sequence number.
    pub seq: Seq,
    /// The message.
    pub msg: BoardToMaster,
}

/// What carries the link's bytes, and the clock the session runs on: the host's socket or
/// serial device ([`open`]), or an emulated board that advances its virtual time while the
/// session waits.
pub trait Medium: Send {
    /// Writes `bytes` towards the board.
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()>;
    /// The next board message, waiting at most `timeout` of this medium's clock; `Ok(None)`
    /// on timeout, `Err` once the link is closed.
    fn recv(&mut self, timeout: Duration) -> Result<Option<Received>, TeleopError>;
    /// The clock: seconds since the medium was opened.
    fn now_s(&self) -> f64;
    /// The counters of the board -> master direction (this side's decoder).
    fn counters(&self) -> LinkCounters;
}

/// What the reader thread reports.
enum FromReader {
    Message(Box<Received>),
    Closed(String),
}

/// The host's medium: a socket or a serial device, its reader thread, the host's clock.
struct HostMedium {
    writer: Box<dyn Write + Send>,
    rx: Receiver<FromReader>,
    t0: Instant,
    counters: Arc<Mutex<LinkCounters>>,
    closed: Option<String>,
    /// The socket, to shut down when the medium is dropped: its reader thread then reads
    /// the end of the stream and ends, and the board sees the connection close (it serves
    /// one master at a time). A serial device has no connection: its reader ends at the
    /// next bytes it reads, once nobody receives them.
    socket: Option<UnixStream>,
}

impl Drop for HostMedium {
    fn drop(&mut self) {
        if let Some(s) = &self.socket {
            let _ = s.shutdown(Shutdown::Both);
        }
    }
}

/// The master's receiving side: the decoder (with the link key, if any), which opens the
/// session of the board's `HelloReply` that echoes this master's nonce.
pub struct MasterRx {
    decoder: MasterDecoder,
    nonce: u32,
}

impl MasterRx {
    /// For the master with the nonce `nonce` and the link key `key`.
    pub fn new(nonce: u32, key: Option<LinkKey>) -> Self {
        MasterRx {
            decoder: MasterDecoder::with_key(key),
            nonce,
        }
    }
    /// Feeds one byte; a frame when it completes one. The master's own `HelloReply`
    /// opens its session (from its sequence number) before the next byte.
    pub fn push(&mut self, byte: u8) -> Option<Result<(Seq, BoardToMaster), FrameError>> {
        let r = self.decoder.push(byte)?;
        if let Ok((seq, BoardToMaster::HelloReply { session, nonce, .. })) = &r {
            if *nonce == self.nonce {
                self.decoder.open_session(*session, *seq);
            }
        }
        Some(r)
    }
    /// The decoder's counters.
    pub fn counters(&self) -> LinkCounters {
        *self.decoder.counters()
    }
}

/// Reads a link key file: 64 hexadecimal digits (32 bytes). The error never shows the
/// file's content.
pub fn read_key_file(path: &Path) -> Result<LinkKey, TeleopError> {
    let text = std::fs::read_to_string(path).map_err(|source| TeleopError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    LinkKey::from_hex(&text).map_err(|_| TeleopError::KeyFile(path.to_path_buf()))
}

/// An open link to the board.
pub struct Link {
    medium: Box<dyn Medium>,
    seq: SeqCounter,
    /// This connection's nonce (sent in `Hello`).
    nonce: u32,
    /// The session the board issued (its `HelloReply`; 0 before one): every frame carries
    /// it.
    session: u32,
    key: Option<LinkKey>,
    /// Frames and bytes written.
    pub frames_sent: u64,
    pub bytes_sent: u64,
}

/// Opens `path`: a Unix socket (retried until `timeout`: the emulator may still be
/// starting) or a serial device (set to raw mode at `baud` with `stty`).
pub fn open(path: &Path, baud: u32, timeout: Duration) -> Result<Link, TeleopError> {
    open_with_key(path, baud, timeout, None)
}

/// [`open`] with the link key `key` (None: frames without tags, a board on a desk).
pub fn open_with_key(
    path: &Path,
    baud: u32,
    timeout: Duration,
    key: Option<LinkKey>,
) -> Result<Link, TeleopError> {
    let open_error = |source| TeleopError::Open {
        path: path.to_path_buf(),
        source,
    };
    let start = Instant::now();
    let is_socket = loop {
        match std::fs::metadata(path) {
            Ok(m) => break m.file_type().is_socket(),
            Err(e) if start.elapsed() >= timeout => {
                return Err(open_error(e));
            }
            Err(_) => thread::sleep(Duration::from_millis(100)),
        }
    };
    let mut socket = None;
    let (reader, writer): (Box<dyn Read + Send>, Box<dyn Write + Send>) = if is_socket {
        let stream = loop {
            match UnixStream::connect(path) {
                Ok(s) => break s,
                Err(source) if start.elapsed() >= timeout => {
                    return Err(TeleopError::Connect {
                        path: path.to_path_buf(),
                        source,
                    });
                }
                Err(_) => thread::sleep(Duration::from_millis(100)),
            }
        };
        let r = stream.try_clone().map_err(open_error)?;
        socket = Some(stream.try_clone().map_err(open_error)?);
        (Box::new(r), Box::new(stream))
    } else {
        let status = Command::new("stty")
            .arg("-F")
            .arg(path)
            .args(["raw", "-echo", &baud.to_string()])
            .status();
        if !status.is_ok_and(|s| s.success()) {
            eprintln!(
                "warning: could not set {} to raw mode at {baud} baud with stty",
                path.display()
            );
        }
        let f: File = OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .map_err(open_error)?;
        let r = f.try_clone().map_err(open_error)?;
        (Box::new(r), Box::new(f))
    };
    let nonce = session_nonce();
    Ok(Link::over(
        Box::new(HostMedium::start(
            reader,
            writer,
            socket,
            MasterRx::new(nonce, key.clone()),
        )),
        nonce,
    )
    .with_key(key))
}

impl HostMedium {
    fn start(
        mut reader: Box<dyn Read + Send>,
        writer: Box<dyn Write + Send>,
        socket: Option<UnixStream>,
        mut decoder: MasterRx,
    ) -> Self {
        let (tx, rx) = mpsc::channel();
        let t0 = Instant::now();
        let counters = Arc::new(Mutex::new(LinkCounters::default()));
        let shared = Arc::clone(&counters);
        thread::spawn(move || {
            let mut buf = [0u8; 4096];
            loop {
                let n = match reader.read(&mut buf) {
                    Ok(0) => {
                        let _ = tx.send(FromReader::Closed("end of stream".into()));
                        return;
                    }
                    Ok(n) => n,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        let _ = tx.send(FromReader::Closed(e.to_string()));
                        return;
                    }
                };
                let t_s = t0.elapsed().as_secs_f64();
                for b in buf.iter().take(n) {
                    if let Some(Ok((seq, msg))) = decoder.push(*b) {
                        if tx
                            .send(FromReader::Message(Box::new(Received { t_s, seq, msg })))
                            .is_err()
                        {
                            // The medium was dropped: nobody reads any more.
                            return;
                        }
                    }
                }
                if let Ok(mut c) = shared.lock() {
                    *c = decoder.counters();
                }
            }
        });
        HostMedium {
            writer,
            rx,
            t0,
            counters,
            closed: None,
            socket,
        }
    }
}

impl Medium for HostMedium {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.writer
            .write_all(bytes)
            .and_then(|()| self.writer.flush())
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<Received>, TeleopError> {
        if let Some(why) = &self.closed {
            return Err(TeleopError::Closed(why.clone()));
        }
        match self.rx.recv_timeout(timeout) {
            Ok(FromReader::Message(m)) => Ok(Some(*m)),
            Ok(FromReader::Closed(why)) => {
                self.closed = Some(why.clone());
                Err(TeleopError::Closed(why))
            }
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(TeleopError::ReaderStopped),
        }
    }

    fn now_s(&self) -> f64 {
        self.t0.elapsed().as_secs_f64()
    }

    fn counters(&self) -> LinkCounters {
        self.counters.lock().map(|c| *c).unwrap_or_default()
    }
}

impl Link {
    /// A link over `medium` with the nonce `nonce` (a fresh value per connection; an
    /// emulated run that must repeat itself bit for bit passes a fixed one), without a key.
    pub fn over(medium: Box<dyn Medium>, nonce: u32) -> Self {
        Link {
            medium,
            seq: SeqCounter::new(0),
            nonce,
            session: 0,
            key: None,
            frames_sent: 0,
            bytes_sent: 0,
        }
    }

    /// The link with the key `key` for the frames it sends (the medium's decoder must
    /// have it too).
    pub fn with_key(mut self, key: Option<LinkKey>) -> Self {
        self.key = key;
        self
    }

    /// This connection's nonce.
    pub fn nonce(&self) -> u32 {
        self.nonce
    }

    /// This master's `Hello`, sent at its clock `clock_us`.
    pub fn hello_message(&self, clock_us: u64) -> MasterToBoard {
        MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION,
            nonce: self.nonce,
            clock_us,
        }
    }

    /// Seconds since the link was opened (the master's clock: the medium's).
    pub fn now_s(&self) -> f64 {
        self.medium.now_s()
    }

    /// Microseconds since the link was opened (target timestamps).
    pub fn now_us(&self) -> u64 {
        (self.medium.now_s() * 1e6) as u64
    }

    /// The session the board issued (0 before its `HelloReply`).
    pub fn session(&self) -> u32 {
        self.session
    }

    /// Sends `msg` as the next frame; returns its sequence number.
    pub fn send(&mut self, msg: &MasterToBoard) -> Result<Seq, TeleopError> {
        let seq = self.seq.next();
        let mut buf = [0u8; MAX_FRAME_LEN];
        let header = Header {
            session: self.session,
            seq,
        };
        let n = encode_with(msg, header, self.key.as_ref(), &mut buf)
            .map_err(|e| encode_error(msg, e))?;
        self.write_raw(buf.get(..n).unwrap_or_default())?;
        self.frames_sent += 1;
        Ok(seq)
    }

    /// Sends `msg` with sequence number `seq` without advancing the counter (a replay).
    pub fn send_with_seq(&mut self, msg: &MasterToBoard, seq: Seq) -> Result<(), TeleopError> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let header = Header {
            session: self.session,
            seq,
        };
        let n = encode_with(msg, header, self.key.as_ref(), &mut buf)
            .map_err(|e| encode_error(msg, e))?;
        self.write_raw(buf.get(..n).unwrap_or_default())
    }

    /// The sequence number the next frame gets.
    pub fn next_seq(&self) -> Seq {
        self.seq.peek()
    }

    /// Writes bytes as they are (garbage tests).
    pub fn write_raw(&mut self, bytes: &[u8]) -> Result<(), TeleopError> {
        self.medium.write_all(bytes).map_err(TeleopError::Write)?;
        self.bytes_sent += bytes.len() as u64;
        Ok(())
    }

    /// The next board message, waiting at most `timeout`; `Ok(None)` on timeout, `Err`
    /// once the link is closed.
    pub fn recv(&mut self, timeout: Duration) -> Result<Option<Received>, TeleopError> {
        let r = self.medium.recv(timeout)?;
        if let Some(Received {
            msg: BoardToMaster::HelloReply { session, nonce, .. },
            ..
        }) = &r
        {
            if *nonce == self.nonce {
                self.session = *session;
            }
        }
        Ok(r)
    }

    /// The counters of the board -> master direction (this side's decoder).
    pub fn counters(&self) -> LinkCounters {
        self.medium.counters()
    }
}

/// A fresh session nonce: the clock's nanoseconds mixed with the process id (distinct per
/// connection; not a secret).
fn session_nonce() -> u32 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let x = (nanos as u64) ^ (u64::from(std::process::id()) << 32);
    // splitmix64's finaliser.
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) as u32).max(1)
}

/// A message that cannot be encoded, with its debug text.
pub(crate) fn encode_error(msg: &MasterToBoard, e: impl std::fmt::Debug) -> TeleopError {
    TeleopError::Encode {
        message: format!("{msg:?}"),
        reason: format!("{e:?}"),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use std::os::unix::net::UnixListener;

    /// A dropped link closes its connection: the board's side reads the end of the stream
    /// within 2 s (its reader thread does not keep the socket open), so the board, which
    /// serves one master at a time, can take the next one.
    #[test]
    fn a_dropped_link_closes_its_socket() {
        let dir = std::env::temp_dir().join(format!("rspr-link-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("board.sock");
        let _ = std::fs::remove_file(&path);
        let listener = UnixListener::bind(&path).unwrap();
        let link = open(&path, 1_000_000, Duration::from_secs(2)).unwrap();
        let (mut board, _) = listener.accept().unwrap();
        board
            .set_read_timeout(Some(Duration::from_secs(2)))
            .unwrap();
        drop(link);
        let mut buf = [0u8; 64];
        let n = board.read(&mut buf);
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(
            n.map_err(|e| e.kind()),
            Ok(0),
            "the board's side must read the end of the stream"
        );
    }
}
