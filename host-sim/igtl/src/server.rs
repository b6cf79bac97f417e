//! The OpenIGTLink server: non-blocking TCP, several clients, driven by [`Server::poll`]
//! from the caller's loop (no threads of its own, so the robot needs no locking).
//!
//! Per client, each poll: reads what has arrived (up to a budget), decodes it, answers,
//! pushes the measured pose and the state when due, and writes what it can without
//! blocking. Each client is answered in the header version it last spoke (version 1 until
//! it has sent a message); replies carry the message id of the request.

use crate::content::{truncate_utf8, StatusContent, StringContent, STRING_MAX_LEN};
use crate::counters::Counters;
use crate::header::{is_valid_device_name, HeaderVersion};
use crate::message::{Body, DataType, Message, QueryKind};
use crate::pose::{
    pose_from_transform, position_from_pose, target_from_position, transform_from_pose, PoseError,
    Registration,
};
use crate::robot::{Robot, RobotState, TargetPose};
use crate::status::StatusCode;
use crate::stream::{DecoderLimits, Event, Malformed, MalformedKind, StreamDecoder, StreamError};
use crate::timestamp::Timestamp;
use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Settings of a [`Server`].
#[derive(Clone, Debug, PartialEq)]
pub struct ServerConfig {
    /// TRANSFORM, POSITION and QTRANS messages with this device name are targets.
    pub target_device: String,
    /// Device name of the measured pose (TRANSFORM, POSITION or QTRANS).
    pub pose_device: String,
    /// Device name of the STATUS messages that carry the robot's state.
    pub status_device: String,
    /// Device name of the STRING messages that carry the robot's state in words.
    pub state_text_device: String,
    /// Device name for which `GET_STRING` returns the counters as JSON.
    pub counters_device: String,
    /// Period of the measured-pose stream.
    pub pose_period: Duration,
    /// Push the pose (TRANSFORM) and the state to every client from its connection on;
    /// when false a client receives them after `STT_TRANS` or on `GET_` only.
    pub stream_on_connect: bool,
    /// Shortest interval between two state messages to one client.
    pub state_min_interval: Duration,
    /// Longest interval between two state messages to one client, even without change.
    pub state_keepalive: Duration,
    /// Answer every accepted target with a STATUS OK (refusals are always answered).
    pub acknowledge_targets: bool,
    /// The fixed client-frame → base-frame registration.
    pub registration: Registration,
    /// Most clients served at once; later ones get a STATUS "busy" and are closed.
    pub max_clients: usize,
    /// Decoder limits (maximum body size, CRC check).
    pub limits: DecoderLimits,
    /// Most bytes queued for a client that does not read; beyond, it is closed.
    pub max_output_backlog: usize,
    /// Queued bytes above which streamed poses are dropped rather than queued.
    pub stream_backlog: usize,
    /// Most bytes read from one client per poll.
    pub read_budget: usize,
    /// The client addresses served (empty: any); a connection from another address is
    /// closed at once ([`CloseReason::NotAllowed`]).
    pub allow: Vec<IpAddr>,
    /// A token every client must send before anything else: its first message must be a
    /// STRING to device [`TOKEN_DEVICE`] whose text is the token. Until then the client
    /// receives nothing; any other first message, or another text, closes the connection
    /// ([`CloseReason::BadToken`]). None: no token.
    pub token: Option<String>,
}

/// The device name of the STRING message that carries a client's token.
pub const TOKEN_DEVICE: &str = "Token";

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig {
            target_device: "Target".to_owned(),
            pose_device: "Robot".to_owned(),
            status_device: "RobotStatus".to_owned(),
            state_text_device: "RobotState".to_owned(),
            counters_device: "Counters".to_owned(),
            pose_period: Duration::from_millis(20),
            stream_on_connect: true,
            state_min_interval: Duration::from_millis(100),
            state_keepalive: Duration::from_secs(1),
            acknowledge_targets: false,
            registration: Registration::identity(),
            max_clients: 8,
            limits: DecoderLimits::default(),
            max_output_backlog: 1 << 20,
            stream_backlog: 64 << 10,
            read_budget: 256 << 10,
            allow: Vec::new(),
            token: None,
        }
    }
}

/// Errors of setting the server up (a client's errors only close that client).
#[derive(Debug, Error)]
pub enum ServerError {
    /// The address cannot be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: String,
        /// The error.
        source: std::io::Error,
    },
    /// A setting that cannot work.
    #[error("bad server setting: {0}")]
    Config(String),
    /// An outgoing connection failed.
    #[error("cannot connect to {addr}: {source}")]
    Connect {
        /// The address.
        addr: SocketAddr,
        /// The error.
        source: std::io::Error,
    },
}

/// Why a connection was closed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CloseReason {
    /// The client closed it.
    PeerClosed,
    /// A read or write failed.
    Io(String),
    /// The client did not read: this many bytes were queued.
    Backlog(usize),
    /// The server already had `max_clients` clients.
    ServerFull,
    /// The client's address is not in the allow-list.
    NotAllowed(IpAddr),
    /// A token is required and the client's first message was not it (what came instead).
    BadToken(String),
}

/// What one [`Server::poll`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PollReport {
    /// Clients connected.
    pub accepted: Vec<SocketAddr>,
    /// Clients disconnected, with the reason.
    pub closed: Vec<(SocketAddr, CloseReason)>,
    /// Targets the robot took.
    pub targets_accepted: u32,
    /// Targets the robot refused.
    pub targets_refused: u32,
    /// Accepting a connection failed (e.g. out of file descriptors); accepting is tried
    /// again at the next poll.
    pub accept_error: Option<String>,
}

/// What an answer goes back to: the request's version, device name and message id.
struct Request<'a> {
    version: HeaderVersion,
    device_name: &'a str,
    message_id: u32,
}

struct Client {
    stream: TcpStream,
    peer: SocketAddr,
    decoder: StreamDecoder,
    discarded_seen: u64,
    out: Vec<u8>,
    version: HeaderVersion,
    stream_transform: bool,
    stream_position: Option<DataType>,
    next_pose_at: Instant,
    push_state: bool,
    last_state: Option<(RobotState, Instant)>,
    /// The header of the last target it sent that was taken (version, device name,
    /// message id): a later refusal of it is answered as that target's STATUS.
    last_target: Option<(HeaderVersion, String, u32)>,
    close: Option<CloseReason>,
    /// The token was sent (or none is required).
    authenticated: bool,
}

/// The OpenIGTLink server.
pub struct Server {
    listener: TcpListener,
    local_addr: SocketAddr,
    config: ServerConfig,
    clients: Vec<Client>,
    counters: Counters,
}

impl Server {
    /// Listens on `addr` with the default settings.
    pub fn bind(addr: impl ToSocketAddrs + std::fmt::Debug) -> Result<Self, ServerError> {
        Server::bind_with(addr, ServerConfig::default())
    }

    /// Listens on `addr` with `config`.
    pub fn bind_with(
        addr: impl ToSocketAddrs + std::fmt::Debug,
        config: ServerConfig,
    ) -> Result<Self, ServerError> {
        for (what, name) in [
            ("target_device", &config.target_device),
            ("pose_device", &config.pose_device),
            ("status_device", &config.status_device),
            ("state_text_device", &config.state_text_device),
            ("counters_device", &config.counters_device),
        ] {
            if name.is_empty() || !is_valid_device_name(name) {
                return Err(ServerError::Config(format!(
                    "{what} {name:?} is not 1 to 20 bytes of text without control characters"
                )));
            }
        }
        if config.pose_period.is_zero() {
            return Err(ServerError::Config("pose_period is zero".to_owned()));
        }
        if config.max_clients == 0 || config.read_budget == 0 {
            return Err(ServerError::Config(
                "max_clients and read_budget must be positive".to_owned(),
            ));
        }
        let addr_text = format!("{addr:?}");
        let bind_err = |source| ServerError::Bind {
            addr: addr_text.clone(),
            source,
        };
        let listener = TcpListener::bind(addr).map_err(bind_err)?;
        listener.set_nonblocking(true).map_err(bind_err)?;
        let local_addr = listener.local_addr().map_err(bind_err)?;
        Ok(Server {
            listener,
            local_addr,
            config,
            clients: Vec::new(),
            counters: Counters::default(),
        })
    }

    /// The address listened on (with the port chosen when 0 was asked).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The settings.
    pub fn config(&self) -> &ServerConfig {
        &self.config
    }

    /// The counters.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Clients connected.
    pub fn client_count(&self) -> usize {
        self.clients.len()
    }

    /// Connects to a client that listens (3D Slicer's OpenIGTLinkIF in server mode) and
    /// serves it like an accepted one. Blocks up to `timeout` for the connection; no
    /// reconnection: a closed connection is reported by [`Server::poll`] and can be made
    /// again by calling this again.
    pub fn connect_to(&mut self, addr: SocketAddr, timeout: Duration) -> Result<(), ServerError> {
        let connect_err = |source| ServerError::Connect { addr, source };
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(connect_err)?;
        stream.set_nonblocking(true).map_err(connect_err)?;
        stream.set_nodelay(true).map_err(connect_err)?;
        self.counters.connections_accepted += 1;
        self.add_client(stream, addr);
        Ok(())
    }

    fn add_client(&mut self, stream: TcpStream, peer: SocketAddr) {
        let authenticated = self.config.token.is_none();
        let stream_on_connect = self.config.stream_on_connect && authenticated;
        self.clients.push(Client {
            stream,
            peer,
            decoder: StreamDecoder::new(self.config.limits),
            discarded_seen: 0,
            out: Vec::new(),
            version: HeaderVersion::V1,
            stream_transform: stream_on_connect,
            stream_position: None,
            next_pose_at: Instant::now(),
            push_state: stream_on_connect,
            last_state: None,
            last_target: None,
            close: None,
            authenticated,
        });
    }

    /// Serves: accepts, reads, answers, streams and writes, without blocking. Problems of
    /// single connections close those connections and are reported, never returned.
    pub fn poll<R: Robot + ?Sized>(&mut self, robot: &mut R) -> PollReport {
        let mut report = PollReport::default();
        self.accept(&mut report);
        let now = Instant::now();
        let state = robot.state();
        let mut clients = std::mem::take(&mut self.clients);
        for client in &mut clients {
            self.read_and_answer(client, robot, &mut report);
        }
        // Targets taken before and refused since: a STATUS each, to the client that sent
        // it, as the answer to its last target taken.
        for (peer, refusal) in robot.take_later_refusals() {
            report.targets_refused += 1;
            if let Some(client) = clients.iter_mut().find(|c| c.peer == peer) {
                let (version, device, id) =
                    client
                        .last_target
                        .clone()
                        .unwrap_or((client.version, String::new(), 0));
                let to = Request {
                    version,
                    device_name: &device,
                    message_id: id,
                };
                self.send_status(
                    client,
                    &to,
                    refusal.reason.status_code(),
                    refusal.reason.error_name(),
                    &refusal.detail,
                );
            }
        }
        for client in &mut clients {
            if client.close.is_none() {
                self.push_due(client, robot, &state, now);
            }
            if client.close.is_none() {
                flush(client, self.config.max_output_backlog);
            }
        }
        clients.retain_mut(|c| match c.close.take() {
            Some(reason) => {
                self.counters.connections_closed += 1;
                report.closed.push((c.peer, reason));
                false
            }
            None => true,
        });
        self.clients = clients;
        report
    }

    fn accept(&mut self, report: &mut PollReport) {
        loop {
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    if !self.config.allow.is_empty() && !self.config.allow.contains(&peer.ip()) {
                        self.counters.connections_refused += 1;
                        report
                            .closed
                            .push((peer, CloseReason::NotAllowed(peer.ip())));
                        drop(stream);
                        continue;
                    }
                    if self.clients.len() >= self.config.max_clients {
                        self.refuse_connection(stream);
                        continue;
                    }
                    if let Err(e) = stream
                        .set_nonblocking(true)
                        .and_then(|()| stream.set_nodelay(true))
                    {
                        self.counters.connections_accepted += 1;
                        self.counters.connections_closed += 1;
                        report.accepted.push(peer);
                        report.closed.push((peer, CloseReason::Io(e.to_string())));
                        continue;
                    }
                    self.counters.connections_accepted += 1;
                    report.accepted.push(peer);
                    self.add_client(stream, peer);
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => return,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::ConnectionAborted
                            | ErrorKind::ConnectionReset
                            | ErrorKind::Interrupted
                    ) =>
                {
                    continue
                }
                Err(e) => {
                    report.accept_error = Some(format!("accepting on {}: {e}", self.local_addr));
                    return;
                }
            }
        }
    }

    /// Tells a client beyond `max_clients` why it is dropped (best effort) and drops it.
    fn refuse_connection(&mut self, mut stream: TcpStream) {
        self.counters.connections_refused += 1;
        let msg = Message {
            timestamp: Timestamp::now(),
            ..Message::new(
                &self.config.status_device,
                Body::Status(StatusContent {
                    code: StatusCode::Busy.wire(),
                    subcode: 0,
                    error_name: "Busy".to_owned(),
                    message: format!(
                        "server full: {} clients already connected",
                        self.config.max_clients
                    ),
                }),
            )
        };
        if let Ok(bytes) = msg.encode() {
            if stream.set_nonblocking(true).is_ok() && stream.write(&bytes).is_ok() {
                self.counters.count_sent("STATUS");
            }
        }
    }

    fn read_and_answer<R: Robot + ?Sized>(
        &mut self,
        client: &mut Client,
        robot: &mut R,
        report: &mut PollReport,
    ) {
        let mut budget = self.config.read_budget;
        let mut chunk = [0u8; 16 * 1024];
        while budget > 0 && client.close.is_none() {
            let want = chunk.len().min(budget);
            match client.stream.read(&mut chunk[..want]) {
                Ok(0) => {
                    if let Some(m) = client.decoder.finish() {
                        self.counters.count_malformed(m.kind());
                    }
                    client.close = Some(CloseReason::PeerClosed);
                }
                Ok(n) => {
                    budget -= n;
                    client.decoder.push(&chunk[..n]);
                    while let Some(event) = client.decoder.next_event() {
                        if !client.authenticated {
                            self.authenticate(client, event);
                            continue;
                        }
                        match event {
                            Event::Message(m) => self.handle_message(client, m, robot, report),
                            Event::Malformed(m) => self.handle_malformed(client, &m),
                        }
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => {
                    // A reset cuts a message as an orderly close does.
                    if let Some(m) = client.decoder.finish() {
                        self.counters.count_malformed(m.kind());
                    }
                    client.close = Some(CloseReason::Io(e.to_string()));
                }
            }
        }
        let discarded = client.decoder.discarded_bytes();
        self.counters.discarded_bytes += discarded - client.discarded_seen;
        client.discarded_seen = discarded;
    }

    /// A client's first message, when a token is required: the token (then the client is
    /// served as from its connection), or the connection is closed.
    fn authenticate(&mut self, client: &mut Client, event: Event) {
        if client.close.is_some() {
            return;
        }
        let Some(token) = &self.config.token else {
            client.authenticated = true;
            return;
        };
        let refusal = match &event {
            Event::Message(m) => {
                self.counters.count_received(&m.type_name());
                match &m.body {
                    Body::String(text) if m.device_name == TOKEN_DEVICE => {
                        if same_bytes(&text.bytes, token.as_bytes()) {
                            None
                        } else {
                            Some("a wrong token".to_owned())
                        }
                    }
                    _ => Some(format!(
                        "{} to device {:?} before the token (a STRING to device {TOKEN_DEVICE:?})",
                        m.type_name(),
                        m.device_name
                    )),
                }
            }
            Event::Malformed(m) => {
                self.counters.count_malformed(m.kind());
                Some(format!(
                    "a malformed message ({:?}) before the token",
                    m.kind()
                ))
            }
        };
        match refusal {
            None => {
                client.authenticated = true;
                client.stream_transform = self.config.stream_on_connect;
                client.push_state = self.config.stream_on_connect;
            }
            Some(why) => {
                self.counters.connections_refused += 1;
                client.close = Some(CloseReason::BadToken(why));
            }
        }
    }

    fn is_target(&self, type_name: &str, device_name: &str) -> bool {
        matches!(type_name, "TRANSFORM" | "POSITION" | "QTRANS")
            && device_name == self.config.target_device
    }

    fn handle_malformed(&mut self, client: &mut Client, m: &Malformed) {
        self.counters.count_malformed(m.kind());
        // Answer only messages that ask for something (targets and queries); everything
        // else is dropped silently, as the reference library does.
        let Some(header) = &m.header else { return };
        let is_query = ["GET_", "STT_", "STP_"]
            .iter()
            .any(|p| header.type_name.starts_with(p));
        if !self.is_target(&header.type_name, &header.device_name) && !is_query {
            return;
        }
        let (code, name) = match &m.error {
            StreamError::Decode(crate::message::DecodeError::Crc { .. }) => {
                (StatusCode::ChecksumError, "ChecksumError")
            }
            StreamError::Oversized { .. } => (StatusCode::Overflow, "Oversized"),
            _ => (StatusCode::IllegalInstruction, "Malformed"),
        };
        let detail = format!(
            "{} from {:?} dropped: {}",
            header.type_name, header.device_name, m.error
        );
        let to = Request {
            version: header.version,
            device_name: &header.device_name,
            message_id: 0,
        };
        self.send_status(client, &to, code, name, &detail);
    }

    fn send_status(
        &mut self,
        client: &mut Client,
        to: &Request<'_>,
        code: StatusCode,
        error_name: &str,
        detail: &str,
    ) {
        let body = Body::Status(StatusContent {
            code: code.wire(),
            subcode: 0,
            error_name: error_name.to_owned(),
            message: truncate_utf8(detail, STRING_MAX_LEN).to_owned(),
        });
        self.send(client, to.version, to.message_id, to.device_name, body);
    }

    fn send(
        &mut self,
        client: &mut Client,
        version: HeaderVersion,
        message_id: u32,
        device_name: &str,
        body: Body,
    ) {
        let message = Message {
            version,
            device_name: device_name.to_owned(),
            timestamp: Timestamp::now(),
            message_id: if version == HeaderVersion::V2 {
                message_id
            } else {
                0
            },
            metadata: Vec::new(),
            body,
        };
        match message.encode() {
            Ok(bytes) => {
                self.counters.count_sent(&message.type_name());
                client.out.extend_from_slice(&bytes);
            }
            // Names come from validated settings or decoded headers and texts are cut to
            // size, so this does not happen; it is counted rather than hidden.
            Err(_) => self.counters.send_failures += 1,
        }
    }

    fn handle_message<R: Robot + ?Sized>(
        &mut self,
        client: &mut Client,
        m: Message,
        robot: &mut R,
        report: &mut PollReport,
    ) {
        let type_name = m.type_name();
        self.counters.count_received(&type_name);
        client.version = m.version;
        match &m.body {
            Body::Transform(t) if self.is_target(&type_name, &m.device_name) => {
                let target = pose_from_transform(t).map(|p| {
                    let p = self.config.registration.pose_to_base(&p);
                    (p.t, Some(p.r))
                });
                self.submit(client, &m, target, robot, report);
            }
            Body::Position(p) | Body::QTrans(p) if self.is_target(&type_name, &m.device_name) => {
                let target = target_from_position(p).map(|(t, r)| {
                    let reg = &self.config.registration;
                    (reg.point_to_base(&t), r.map(|r| reg.rotation_to_base(&r)))
                });
                self.submit(client, &m, target, robot, report);
            }
            Body::Query { kind, suffix, .. } => {
                self.answer_query(client, &m, *kind, suffix, robot);
            }
            Body::Other { .. } => self.counters.count_malformed(MalformedKind::UnknownType),
            // Poses for other devices, STATUS, STRING, null bodies and RTS_ answers: counted
            // and otherwise ignored.
            _ => {}
        }
    }

    fn submit<R: Robot + ?Sized>(
        &mut self,
        client: &mut Client,
        m: &Message,
        target: Result<(nalgebra::Vector3<f64>, Option<nalgebra::Rotation3<f64>>), PoseError>,
        robot: &mut R,
        report: &mut PollReport,
    ) {
        let to = Request {
            version: m.version,
            device_name: &m.device_name,
            message_id: m.message_id,
        };
        let (t, r) = match target {
            Ok(x) => x,
            Err(e) => {
                self.counters.count_malformed(MalformedKind::InvalidPose);
                let detail = format!("target not a pose, dropped: {e}");
                self.send_status(
                    client,
                    &to,
                    StatusCode::IllegalInstruction,
                    "InvalidPose",
                    &detail,
                );
                return;
            }
        };
        let target = TargetPose {
            t,
            r,
            timestamp: m.timestamp,
            peer: client.peer,
        };
        match robot.submit_target(&target) {
            Ok(()) => {
                self.counters.targets_accepted += 1;
                report.targets_accepted += 1;
                client.last_target = Some((m.version, m.device_name.clone(), m.message_id));
                if self.config.acknowledge_targets {
                    self.send_status(client, &to, StatusCode::Ok, "OK", "target accepted");
                }
            }
            Err(refusal) => {
                self.counters.targets_refused += 1;
                report.targets_refused += 1;
                self.send_status(
                    client,
                    &to,
                    refusal.reason.status_code(),
                    refusal.reason.error_name(),
                    &refusal.detail,
                );
            }
        }
    }

    fn answer_query<R: Robot + ?Sized>(
        &mut self,
        client: &mut Client,
        m: &Message,
        kind: QueryKind,
        suffix: &str,
        robot: &mut R,
    ) {
        let data = DataType::from_query_suffix(suffix);
        let device = m.device_name.as_str();
        match kind {
            QueryKind::Get => {
                let (name, body) = self.get_reply(device, data, suffix, robot);
                self.send(client, m.version, m.message_id, &name, body);
            }
            QueryKind::Start | QueryKind::Stop => {
                let start = kind == QueryKind::Start;
                let ok = self.stream_request(client, device, data, start);
                let body = Body::Rts {
                    suffix: suffix.to_owned(),
                    status: if ok { 0 } else { 1 },
                };
                self.send(client, m.version, m.message_id, device, body);
            }
        }
    }

    /// The answer to GET_`suffix` of `device` (empty: this server's device of that
    /// type): the device answering and the data, or no data (an empty body).
    fn get_reply<R: Robot + ?Sized>(
        &self,
        device: &str,
        data: Option<DataType>,
        suffix: &str,
        robot: &mut R,
    ) -> (String, Body) {
        match data {
            Some(d @ (DataType::Transform | DataType::Position | DataType::QTrans)) => {
                if device.is_empty() || device == self.config.pose_device {
                    let body = match robot.measured_pose() {
                        Some(p) => self.pose_body(d, &p),
                        None => Body::Null(d),
                    };
                    (self.config.pose_device.clone(), body)
                } else {
                    (device.to_owned(), Body::Null(d))
                }
            }
            Some(DataType::Status) => {
                if device.is_empty() || device == self.config.status_device {
                    (
                        self.config.status_device.clone(),
                        state_status(&robot.state()),
                    )
                } else {
                    (device.to_owned(), Body::Null(DataType::Status))
                }
            }
            Some(DataType::String) => {
                if device.is_empty() || device == self.config.state_text_device {
                    (
                        self.config.state_text_device.clone(),
                        state_string(&robot.state()),
                    )
                } else if device == self.config.counters_device {
                    let json = self.counters.to_json();
                    (device.to_owned(), Body::String(StringContent::text(&json)))
                } else {
                    (device.to_owned(), Body::Null(DataType::String))
                }
            }
            // A data type not handled here: "no data available" is a message of
            // that type with an empty body (protocol page "Query").
            None => (
                device.to_owned(),
                Body::Other {
                    type_name: suffix.to_owned(),
                    content: Vec::new(),
                },
            ),
        }
    }

    /// Starts (`start`) or stops the client's stream of `data` from `device`; whether
    /// this server streams that (the pose device's transform or position).
    fn stream_request(
        &self,
        client: &mut Client,
        device: &str,
        data: Option<DataType>,
        start: bool,
    ) -> bool {
        let ours = device.is_empty() || device == self.config.pose_device;
        let ok = match data {
            Some(DataType::Transform) if ours => {
                client.stream_transform = start;
                true
            }
            Some(d @ (DataType::Position | DataType::QTrans)) if ours => {
                client.stream_position = start.then_some(d);
                true
            }
            _ => false,
        };
        if ok && start {
            client.next_pose_at = Instant::now();
        }
        ok
    }

    fn pose_body(&self, data: DataType, pose_base: &crate::pose::PoseSi) -> Body {
        let pose = self.config.registration.pose_to_client(pose_base);
        match data {
            DataType::Position => Body::Position(position_from_pose(&pose)),
            DataType::QTrans => Body::QTrans(position_from_pose(&pose)),
            _ => Body::Transform(transform_from_pose(&pose)),
        }
    }

    fn push_due<R: Robot + ?Sized>(
        &mut self,
        client: &mut Client,
        robot: &R,
        state: &RobotState,
        now: Instant,
    ) {
        let streaming = client.stream_transform || client.stream_position.is_some();
        if streaming && now >= client.next_pose_at {
            let period = self.config.pose_period;
            client.next_pose_at += period;
            if client.next_pose_at <= now {
                // Fell behind (a slow loop): restart the schedule rather than burst.
                client.next_pose_at = now + period;
            }
            if client.out.len() > self.config.stream_backlog {
                self.counters.stream_dropped += 1;
            } else if let Some(p) = robot.measured_pose() {
                let version = client.version;
                let device = self.config.pose_device.clone();
                if client.stream_transform {
                    let body = self.pose_body(DataType::Transform, &p);
                    self.send(client, version, 0, &device, body);
                }
                if let Some(d) = client.stream_position {
                    let body = self.pose_body(d, &p);
                    self.send(client, version, 0, &device, body);
                }
            }
        }
        let due = client.push_state
            && match &client.last_state {
                None => true,
                Some((last, at)) => {
                    let since = now.saturating_duration_since(*at);
                    (last != state && since >= self.config.state_min_interval)
                        || since >= self.config.state_keepalive
                }
            };
        if due {
            let version = client.version;
            let status_device = self.config.status_device.clone();
            let text_device = self.config.state_text_device.clone();
            self.send(client, version, 0, &status_device, state_status(state));
            self.send(client, version, 0, &text_device, state_string(state));
            client.last_state = Some((state.clone(), now));
        }
    }
}

fn state_status(state: &RobotState) -> Body {
    Body::Status(StatusContent {
        code: state.condition.status_code().wire(),
        subcode: 0,
        error_name: state.condition.name().to_owned(),
        message: truncate_utf8(&state.detail, STRING_MAX_LEN).to_owned(),
    })
}

fn state_string(state: &RobotState) -> Body {
    let text = state.text();
    Body::String(StringContent::text(truncate_utf8(&text, STRING_MAX_LEN)))
}

/// Writes what the socket takes now; closes a client whose backlog is too large.
fn flush(client: &mut Client, max_backlog: usize) {
    let mut written = 0;
    while written < client.out.len() {
        match client.stream.write(&client.out[written..]) {
            Ok(0) => {
                client.close = Some(CloseReason::Io("write returned 0".to_owned()));
                break;
            }
            Ok(n) => written += n,
            Err(e) if e.kind() == ErrorKind::WouldBlock => break,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) => {
                client.close = Some(CloseReason::Io(e.to_string()));
                break;
            }
        }
    }
    client.out.drain(..written);
    if client.close.is_none() && client.out.len() > max_backlog {
        client.close = Some(CloseReason::Backlog(client.out.len()));
    }
}

/// Whether two byte strings are equal, in a time that does not depend on where they differ.
fn same_bytes(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}
