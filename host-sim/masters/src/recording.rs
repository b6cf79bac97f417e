//! Recorded teleoperation sessions: every run writes the master's input samples, the
//! targets sent and the board's status reports, time-stamped, to one MCAP file.
//!
//! # Format
//!
//! [MCAP](https://mcap.dev) (the Foxglove/ROS 2 container), zstd-compressed chunks,
//! chunks closed at least every second of session time (a crash loses at most that),
//! summary and indexes at the end. Every message is one JSON object (message encoding
//! `json`, schema encoding `jsonschema`), in the units of the project's edges
//! (millimetres and degrees, with the unit in the field name; poses as
//! `x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg`, (rx, ry, rz) the rotation vector). Every
//! message has `t_s`, the master clock in seconds; its MCAP log time is the session's
//! wall-clock start plus `t_s`.
//!
//! | topic | schema | one message per |
//! | --- | --- | --- |
//! | `/session` | `rspr.masters.Session` | session (first message): `start_unix_ns`, `master`, `stream_rate_hz`, `settings` (text map) |
//! | `/master/input` | `rspr.masters.MasterInput` | master sample: `twist` {`vx_mm_s`..`wz_deg_s`} or `pose` (master `measured_cp`), `clutch`, `operator_present`, `device_time_us`?, `deflection`? (device counts) |
//! | `/teleop/servo_cp` | `rspr.masters.ServoCp` | target sent: `timestamp_us` (the stamp sent to the board), `pose`, `limited` |
//! | `/robot/status` | `rspr.masters.RobotStatus` | board status: `state`, `measured_cp`?, `setpoint_cp`?, `nearest_margin`?, `faults` |
//! | `/teleop/event` | `rspr.masters.TeleopEvent` | change: `kind` (`state`, `scale`, `cue`, `note`), `detail` |
//!
//! The session is also written as MCAP metadata named `session` for tools that list it.
//! [`Recording::open`] reads a file back into typed records; a file cut short (a crash)
//! reads up to its last whole chunk and says so ([`Recording::complete`]).

use crate::device::{MasterInput, MasterSample};
use crate::latency::{LagConfig, LatencyFigures, Stamped};
use crate::pose::{CartesianPose, NonFinite, Twist};
use mcap::records::{MessageHeader, Metadata};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Topic of the session message.
pub const TOPIC_SESSION: &str = "/session";
/// Topic of master samples.
pub const TOPIC_INPUT: &str = "/master/input";
/// Topic of targets sent.
pub const TOPIC_SERVO_CP: &str = "/teleop/servo_cp";
/// Topic of board statuses.
pub const TOPIC_STATUS: &str = "/robot/status";
/// Topic of teleoperation events.
pub const TOPIC_EVENT: &str = "/teleop/event";

/// What went wrong with a recording.
#[derive(Debug, Error)]
pub enum RecordingError {
    /// File I/O.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP layer.
    #[error("{path}: MCAP: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The error.
        #[source]
        source: mcap::McapError,
    },
    /// A message that does not decode.
    #[error("{path}: message {index} on {topic}: {detail}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Index of the message in the file.
        index: usize,
        /// What was wrong.
        detail: String,
    },
    /// A time that cannot be recorded.
    #[error("record time {0} s is not finite and non-negative")]
    Time(f64),
    /// A record with non-finite numbers.
    #[error("record at {t_s} s on {topic}: {source}")]
    NonFinite {
        /// Its time.
        t_s: f64,
        /// The topic.
        topic: &'static str,
        /// Which component.
        #[source]
        source: NonFinite,
    },
    /// No session message.
    #[error("{0}: no /session message: not a session recording of `host-sim teleop --device` (a scene of `host-sim sim` or `view --record` opens in Foxglove)")]
    NoSession(PathBuf),
}

/// The session's description.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionInfo {
    /// Wall-clock time of `t_s = 0`, ns since the Unix epoch.
    pub start_unix_ns: u64,
    /// The master device.
    pub master: String,
    /// Target stream rate, Hz.
    pub stream_rate_hz: f64,
    /// Settings as text (scale, filter, limits, mapping...).
    pub settings: BTreeMap<String, String>,
}

/// A master sample as recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputRecord {
    /// Master clock, s.
    pub t_s: f64,
    /// Twist (rate masters) or pose (position masters).
    pub input: MasterInput,
    /// Clutch pressed.
    pub clutch: bool,
    /// Operator present.
    pub operator_present: bool,
    /// Device time stamp, µs.
    pub device_time_us: Option<u64>,
    /// Raw deflection, device counts.
    pub deflection: Option<[f64; 6]>,
}

impl From<&MasterSample> for InputRecord {
    fn from(s: &MasterSample) -> Self {
        InputRecord {
            t_s: s.t_s,
            input: s.input,
            clutch: s.buttons.clutch,
            operator_present: s.buttons.operator_present,
            device_time_us: s.device_time_us,
            deflection: s.deflection,
        }
    }
}

/// A target sent to the board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TargetRecord {
    /// Master clock when sent, s.
    pub t_s: f64,
    /// The time stamp sent with it, µs.
    pub timestamp_us: u64,
    /// The target (`servo_cp`).
    pub pose: CartesianPose,
    /// A master-side limit acted on it.
    pub limited: bool,
    /// The master clock of the newest master sample this target reflects, s (for the
    /// latency from the master's input).
    pub input_t_s: Option<f64>,
    /// The master's scaled motion applied to the robot before the tremor filter and the
    /// limits (what the operator commanded), for the latency figures.
    pub commanded: Option<CartesianPose>,
}

/// A board status, kept generic (no dependency on the board's protocol crate).
#[derive(Clone, Debug, PartialEq)]
pub struct StatusRecord {
    /// Master clock at arrival, s.
    pub t_s: f64,
    /// The board's state, as text.
    pub state: String,
    /// Measured pose (`measured_cp`).
    pub measured: Option<CartesianPose>,
    /// The supervisor's setpoint (`setpoint_cp`), when known.
    pub setpoint: Option<CartesianPose>,
    /// Nearest guard margin in [0, 1], when known.
    pub nearest_margin: Option<f64>,
    /// Fault bits.
    pub faults: u32,
    /// Every guard margin the board reports, by name (`nearest`, `serial`, `parallel`,
    /// `stroke`, `tilt`, `collision`, `workspace`), each in [0, 1]; only finite values.
    pub margins: BTreeMap<String, f64>,
    /// The stop in force, as text (`None` when none), when known.
    pub stop: Option<String>,
}

/// What kind of event.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// Teleoperation state change (`following`, `holding:clutched`, ...).
    State,
    /// Motion scale change (`translation=0.2 rotation=1`).
    Scale,
    /// Workspace cue change (`none`, `approaching`, `at_edge`).
    Cue,
    /// Free text.
    Note,
}

/// A teleoperation event.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventRecord {
    /// Master clock, s.
    pub t_s: f64,
    /// Kind.
    pub kind: EventKind,
    /// Detail.
    pub detail: String,
}

impl EventRecord {
    /// A state change.
    pub fn state(t_s: f64, state: crate::teleop::TeleopState) -> Self {
        let detail = match state {
            crate::teleop::TeleopState::Following => "following".to_string(),
            crate::teleop::TeleopState::Holding(r) => format!("holding:{}", r.as_str()),
        };
        EventRecord {
            t_s,
            kind: EventKind::State,
            detail,
        }
    }

    /// A scale change.
    pub fn scale(t_s: f64, s: crate::teleop::MotionScale) -> Self {
        EventRecord {
            t_s,
            kind: EventKind::Scale,
            detail: format!("translation={} rotation={}", s.translation, s.rotation),
        }
    }

    /// A cue change.
    pub fn cue(t_s: f64, level: crate::workspace_cue::CueLevel) -> Self {
        EventRecord {
            t_s,
            kind: EventKind::Cue,
            detail: level.as_str().into(),
        }
    }
}

// ---- JSON forms (mm, deg) ----

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct PoseJson {
    x_mm: f64,
    y_mm: f64,
    z_mm: f64,
    rx_deg: f64,
    ry_deg: f64,
    rz_deg: f64,
}

impl From<&CartesianPose> for PoseJson {
    fn from(p: &CartesianPose) -> Self {
        let [x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg] = p.to_mm_deg();
        PoseJson {
            x_mm,
            y_mm,
            z_mm,
            rx_deg,
            ry_deg,
            rz_deg,
        }
    }
}

impl PoseJson {
    fn pose(&self) -> Result<CartesianPose, NonFinite> {
        CartesianPose::from_mm_deg([
            self.x_mm,
            self.y_mm,
            self.z_mm,
            self.rx_deg,
            self.ry_deg,
            self.rz_deg,
        ])
    }
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct TwistJson {
    vx_mm_s: f64,
    vy_mm_s: f64,
    vz_mm_s: f64,
    wx_deg_s: f64,
    wy_deg_s: f64,
    wz_deg_s: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct InputJson {
    t_s: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    twist: Option<TwistJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pose: Option<PoseJson>,
    clutch: bool,
    operator_present: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    device_time_us: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    deflection: Option<[f64; 6]>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct ServoCpJson {
    t_s: f64,
    timestamp_us: u64,
    pose: PoseJson,
    limited: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    input_t_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    commanded: Option<PoseJson>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct StatusJson {
    t_s: f64,
    state: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    measured_cp: Option<PoseJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    setpoint_cp: Option<PoseJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    nearest_margin: Option<f64>,
    faults: u32,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    margins: BTreeMap<String, f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    stop: Option<String>,
}

const POSE_SCHEMA: &str = r#"{"type":"object","properties":{"x_mm":{"type":"number"},"y_mm":{"type":"number"},"z_mm":{"type":"number"},"rx_deg":{"type":"number"},"ry_deg":{"type":"number"},"rz_deg":{"type":"number"}},"required":["x_mm","y_mm","z_mm","rx_deg","ry_deg","rz_deg"]}"#;

fn schema_of(topic: &str) -> (&'static str, String) {
    let obj = |props: &str, required: &str| {
        format!(r#"{{"type":"object","properties":{{{props}}},"required":[{required}]}}"#)
    };
    match topic {
        TOPIC_SESSION => (
            "rspr.masters.Session",
            obj(
                r#""start_unix_ns":{"type":"integer"},"master":{"type":"string"},"stream_rate_hz":{"type":"number"},"settings":{"type":"object","additionalProperties":{"type":"string"}}"#,
                r#""start_unix_ns","master","stream_rate_hz","settings""#,
            ),
        ),
        TOPIC_INPUT => (
            "rspr.masters.MasterInput",
            obj(
                &format!(
                    r#""t_s":{{"type":"number"}},"twist":{{"type":"object","properties":{{"vx_mm_s":{{"type":"number"}},"vy_mm_s":{{"type":"number"}},"vz_mm_s":{{"type":"number"}},"wx_deg_s":{{"type":"number"}},"wy_deg_s":{{"type":"number"}},"wz_deg_s":{{"type":"number"}}}}}},"pose":{POSE_SCHEMA},"clutch":{{"type":"boolean"}},"operator_present":{{"type":"boolean"}},"device_time_us":{{"type":"integer"}},"deflection":{{"type":"array","items":{{"type":"number"}},"minItems":6,"maxItems":6}}"#
                ),
                r#""t_s","clutch","operator_present""#,
            ),
        ),
        TOPIC_SERVO_CP => (
            "rspr.masters.ServoCp",
            obj(
                &format!(
                    r#""t_s":{{"type":"number"}},"timestamp_us":{{"type":"integer"}},"pose":{POSE_SCHEMA},"limited":{{"type":"boolean"}},"input_t_s":{{"type":"number"}},"commanded":{POSE_SCHEMA}"#
                ),
                r#""t_s","timestamp_us","pose","limited""#,
            ),
        ),
        TOPIC_STATUS => (
            "rspr.masters.RobotStatus",
            obj(
                &format!(
                    r#""t_s":{{"type":"number"}},"state":{{"type":"string"}},"measured_cp":{POSE_SCHEMA},"setpoint_cp":{POSE_SCHEMA},"nearest_margin":{{"type":"number"}},"faults":{{"type":"integer"}},"margins":{{"type":"object","additionalProperties":{{"type":"number"}}}},"stop":{{"type":"string"}}"#
                ),
                r#""t_s","state","faults""#,
            ),
        ),
        _ => (
            "rspr.masters.TeleopEvent",
            obj(
                r#""t_s":{"type":"number"},"kind":{"type":"string","enum":["state","scale","cue","note"]},"detail":{"type":"string"}"#,
                r#""t_s","kind","detail""#,
            ),
        ),
    }
}

const TOPICS: [&str; 5] = [
    TOPIC_SESSION,
    TOPIC_INPUT,
    TOPIC_SERVO_CP,
    TOPIC_STATUS,
    TOPIC_EVENT,
];

/// Writes one session's MCAP file.
pub struct RecordingWriter {
    writer: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    channels: [u16; 5],
    sequence: u32,
    start_unix_ns: u64,
    last_flush_s: f64,
    flush_period_s: f64,
    messages: u64,
}

impl RecordingWriter {
    /// Creates `path` and writes the session.
    pub fn create(path: &Path, session: &SessionInfo) -> Result<Self, RecordingError> {
        let file = File::create(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mcap_err = |source| RecordingError::Mcap {
            path: path.to_path_buf(),
            source,
        };
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_threads(0)
            .chunk_size(Some(256 * 1024))
            .create(BufWriter::new(file))
            .map_err(mcap_err)?;
        let mut channels = [0u16; 5];
        for (slot, topic) in channels.iter_mut().zip(TOPICS) {
            let (name, schema) = schema_of(topic);
            let sid = writer
                .add_schema(name, "jsonschema", schema.as_bytes())
                .map_err(mcap_err)?;
            *slot = writer
                .add_channel(sid, topic, "json", &BTreeMap::new())
                .map_err(mcap_err)?;
        }
        let mut meta = session.settings.clone();
        meta.insert("master".into(), session.master.clone());
        meta.insert("stream_rate_hz".into(), session.stream_rate_hz.to_string());
        meta.insert("start_unix_ns".into(), session.start_unix_ns.to_string());
        writer
            .write_metadata(&Metadata {
                name: "session".into(),
                metadata: meta,
            })
            .map_err(mcap_err)?;
        let mut w = RecordingWriter {
            writer,
            path: path.to_path_buf(),
            channels,
            sequence: 0,
            start_unix_ns: session.start_unix_ns,
            last_flush_s: 0.0,
            flush_period_s: 1.0,
            messages: 0,
        };
        w.write_json(0, 0.0, session)?;
        Ok(w)
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    fn write_json<T: Serialize>(
        &mut self,
        channel: usize,
        t_s: f64,
        value: &T,
    ) -> Result<(), RecordingError> {
        if !(t_s.is_finite() && t_s >= 0.0) {
            return Err(RecordingError::Time(t_s));
        }
        let data = serde_json::to_vec(value).map_err(|e| RecordingError::Decode {
            path: self.path.clone(),
            topic: TOPICS.get(channel).copied().unwrap_or("?").into(),
            index: self.messages as usize,
            detail: format!("encode: {e}"),
        })?;
        let log_time = self.start_unix_ns.saturating_add((t_s * 1e9) as u64);
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id: self.channels.get(channel).copied().unwrap_or(0),
            sequence: self.sequence,
            log_time,
            publish_time: log_time,
        };
        let path = self.path.clone();
        let mcap_err = |source| RecordingError::Mcap { path, source };
        self.writer
            .write_to_known_channel(&header, &data)
            .map_err(mcap_err)?;
        self.messages += 1;
        if t_s - self.last_flush_s >= self.flush_period_s {
            self.last_flush_s = t_s;
            let path = self.path.clone();
            self.writer
                .flush()
                .map_err(|source| RecordingError::Mcap { path, source })?;
        }
        Ok(())
    }

    /// Records a master sample.
    pub fn write_input(&mut self, r: &InputRecord) -> Result<(), RecordingError> {
        let (twist, pose) = match &r.input {
            MasterInput::Twist(t) => {
                let nf = |source| RecordingError::NonFinite {
                    t_s: r.t_s,
                    topic: TOPIC_INPUT,
                    source,
                };
                Twist::from_array(t.to_array()).map_err(nf)?;
                let [vx, vy, vz, wx, wy, wz] = t.to_array();
                (
                    Some(TwistJson {
                        vx_mm_s: vx * 1e3,
                        vy_mm_s: vy * 1e3,
                        vz_mm_s: vz * 1e3,
                        wx_deg_s: wx.to_degrees(),
                        wy_deg_s: wy.to_degrees(),
                        wz_deg_s: wz.to_degrees(),
                    }),
                    None,
                )
            }
            MasterInput::Pose(p) => (None, Some(PoseJson::from(p))),
        };
        let j = InputJson {
            t_s: r.t_s,
            twist,
            pose,
            clutch: r.clutch,
            operator_present: r.operator_present,
            device_time_us: r.device_time_us,
            deflection: r.deflection,
        };
        self.write_json(1, r.t_s, &j)
    }

    /// Records a target sent.
    pub fn write_target(&mut self, r: &TargetRecord) -> Result<(), RecordingError> {
        let j = ServoCpJson {
            t_s: r.t_s,
            timestamp_us: r.timestamp_us,
            pose: PoseJson::from(&r.pose),
            limited: r.limited,
            input_t_s: r.input_t_s,
            commanded: r.commanded.as_ref().map(PoseJson::from),
        };
        self.write_json(2, r.t_s, &j)
    }

    /// Records a board status.
    pub fn write_status(&mut self, r: &StatusRecord) -> Result<(), RecordingError> {
        let j = StatusJson {
            t_s: r.t_s,
            state: r.state.clone(),
            measured_cp: r.measured.as_ref().map(PoseJson::from),
            setpoint_cp: r.setpoint.as_ref().map(PoseJson::from),
            nearest_margin: r.nearest_margin,
            faults: r.faults,
            margins: r
                .margins
                .iter()
                .filter(|(_, v)| v.is_finite())
                .map(|(k, v)| (k.clone(), *v))
                .collect(),
            stop: r.stop.clone(),
        };
        self.write_json(3, r.t_s, &j)
    }

    /// Records an event.
    pub fn write_event(&mut self, r: &EventRecord) -> Result<(), RecordingError> {
        self.write_json(4, r.t_s, r)
    }

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<PathBuf, RecordingError> {
        let path = self.path.clone();
        self.writer
            .finish()
            .map_err(|source| RecordingError::Mcap {
                path: path.clone(),
                source,
            })?;
        Ok(path)
    }
}

/// A recording read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The file.
    pub path: PathBuf,
    /// The session.
    pub session: SessionInfo,
    inputs: Vec<InputRecord>,
    targets: Vec<TargetRecord>,
    statuses: Vec<StatusRecord>,
    events: Vec<EventRecord>,
    complete: bool,
    stopped_by: Option<String>,
    unknown_topics: u64,
}

/// A message's JSON.
fn decode<T: serde::de::DeserializeOwned>(data: &[u8]) -> Result<T, String> {
    serde_json::from_slice(data).map_err(|e| e.to_string())
}

impl InputJson {
    /// The sample: a twist (SI from mm/s and deg/s) or a pose, exactly one of them.
    fn record(self) -> Result<InputRecord, String> {
        let input = match (self.twist, self.pose) {
            (Some(t), None) => MasterInput::Twist(
                Twist::from_array([
                    t.vx_mm_s * 1e-3,
                    t.vy_mm_s * 1e-3,
                    t.vz_mm_s * 1e-3,
                    t.wx_deg_s.to_radians(),
                    t.wy_deg_s.to_radians(),
                    t.wz_deg_s.to_radians(),
                ])
                .map_err(|e| e.to_string())?,
            ),
            (None, Some(p)) => MasterInput::Pose(p.pose().map_err(|e| e.to_string())?),
            _ => return Err("needs exactly one of twist and pose".into()),
        };
        Ok(InputRecord {
            t_s: self.t_s,
            input,
            clutch: self.clutch,
            operator_present: self.operator_present,
            device_time_us: self.device_time_us,
            deflection: self.deflection,
        })
    }
}

impl ServoCpJson {
    /// The target sent.
    fn record(self) -> Result<TargetRecord, String> {
        Ok(TargetRecord {
            t_s: self.t_s,
            timestamp_us: self.timestamp_us,
            pose: self.pose.pose().map_err(|e| e.to_string())?,
            limited: self.limited,
            input_t_s: self.input_t_s,
            commanded: self
                .commanded
                .map(|p| p.pose())
                .transpose()
                .map_err(|e| e.to_string())?,
        })
    }
}

impl StatusJson {
    /// The board's status.
    fn record(self) -> Result<StatusRecord, String> {
        let pose = |p: Option<PoseJson>| p.map(|p| p.pose()).transpose().map_err(|e| e.to_string());
        Ok(StatusRecord {
            t_s: self.t_s,
            state: self.state,
            measured: pose(self.measured_cp)?,
            setpoint: pose(self.setpoint_cp)?,
            nearest_margin: self.nearest_margin,
            faults: self.faults,
            margins: self.margins,
            stop: self.stop,
        })
    }
}

fn decode_err(path: &Path, topic: &str, index: usize, detail: impl fmt::Display) -> RecordingError {
    RecordingError::Decode {
        path: path.to_path_buf(),
        topic: topic.into(),
        index,
        detail: detail.to_string(),
    }
}

impl Recording {
    /// Reads `path`. A file cut short reads up to its last whole chunk
    /// ([`Recording::complete`] is then false); a message that does not decode is an
    /// error.
    pub fn open(path: &Path) -> Result<Self, RecordingError> {
        let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let stream = mcap::MessageStream::new(&bytes).map_err(|source| RecordingError::Mcap {
            path: path.to_path_buf(),
            source,
        })?;
        let mut session = None;
        let mut rec = Recording {
            path: path.to_path_buf(),
            session: SessionInfo {
                start_unix_ns: 0,
                master: String::new(),
                stream_rate_hz: 0.0,
                settings: BTreeMap::new(),
            },
            inputs: Vec::new(),
            targets: Vec::new(),
            statuses: Vec::new(),
            events: Vec::new(),
            complete: true,
            stopped_by: None,
            unknown_topics: 0,
        };
        for (index, m) in stream.enumerate() {
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    rec.complete = false;
                    rec.stopped_by = Some(e.to_string());
                    break;
                }
            };
            let topic = m.channel.topic.as_str();
            if let Some(s) = rec
                .take(topic, &m.data)
                .map_err(|e| decode_err(path, topic, index, e))?
            {
                session = Some(s);
            }
        }
        rec.session = session.ok_or_else(|| RecordingError::NoSession(path.to_path_buf()))?;
        Ok(rec)
    }

    /// Takes one message of `topic`; the session record, when it is one. The error says
    /// why the message does not decode.
    fn take(&mut self, topic: &str, data: &[u8]) -> Result<Option<SessionInfo>, String> {
        match topic {
            TOPIC_SESSION => return Ok(Some(decode(data)?)),
            TOPIC_INPUT => self.inputs.push(decode::<InputJson>(data)?.record()?),
            TOPIC_SERVO_CP => self.targets.push(decode::<ServoCpJson>(data)?.record()?),
            TOPIC_STATUS => self.statuses.push(decode::<StatusJson>(data)?.record()?),
            TOPIC_EVENT => self.events.push(decode(data)?),
            _ => self.unknown_topics += 1,
        }
        Ok(None)
    }

    /// Master samples, in file order.
    pub fn inputs(&self) -> impl Iterator<Item = &InputRecord> {
        self.inputs.iter()
    }

    /// Targets sent.
    pub fn targets(&self) -> impl Iterator<Item = &TargetRecord> {
        self.targets.iter()
    }

    /// Board statuses.
    pub fn statuses(&self) -> impl Iterator<Item = &StatusRecord> {
        self.statuses.iter()
    }

    /// Events.
    pub fn events(&self) -> impl Iterator<Item = &EventRecord> {
        self.events.iter()
    }

    /// The file ended properly (summary and footer read).
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// Why reading stopped early, for a file cut short.
    pub fn stopped_by(&self) -> Option<&str> {
        self.stopped_by.as_deref()
    }

    /// Messages on topics this reader does not know.
    pub fn unknown_topics(&self) -> u64 {
        self.unknown_topics
    }

    /// The time series `host-sim replay` plots, in mm and degrees.
    pub fn series(&self) -> Series {
        let mut out = Series::default();
        for r in &self.inputs {
            match &r.input {
                MasterInput::Pose(p) => out.input_pose.push((r.t_s, p.to_mm_deg())),
                MasterInput::Twist(t) => {
                    let [vx, vy, vz, wx, wy, wz] = t.to_array();
                    out.input_twist.push((
                        r.t_s,
                        [
                            vx * 1e3,
                            vy * 1e3,
                            vz * 1e3,
                            wx.to_degrees(),
                            wy.to_degrees(),
                            wz.to_degrees(),
                        ],
                    ));
                }
            }
        }
        out.target = self
            .targets
            .iter()
            .map(|r| (r.t_s, r.pose.to_mm_deg()))
            .collect();
        for s in &self.statuses {
            if let Some(p) = &s.setpoint {
                out.setpoint.push((s.t_s, p.to_mm_deg()));
            }
            if let Some(p) = &s.measured {
                out.measured.push((s.t_s, p.to_mm_deg()));
            }
        }
        out
    }

    /// The figures `host-sim replay` prints.
    pub fn summary(&self) -> RecordingSummary {
        let times = self
            .inputs
            .iter()
            .map(|r| r.t_s)
            .chain(self.targets.iter().map(|r| r.t_s))
            .chain(self.statuses.iter().map(|r| r.t_s));
        let (t0, t1) = times.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
            (a.min(t), b.max(t))
        });
        let mut path_m = 0.0;
        let mut max_speed_m_s: f64 = 0.0;
        for w in self.targets.windows(2) {
            if let [a, b] = w {
                let d = (b.pose.position_m - a.pose.position_m).norm();
                path_m += d;
                let dt = b.t_s - a.t_s;
                if dt > 0.0 {
                    max_speed_m_s = max_speed_m_s.max(d / dt);
                }
            }
        }
        let mut max_following_error_m: Option<f64> = None;
        for s in &self.statuses {
            if let (Some(m), Some(sp)) = (&s.measured, &s.setpoint) {
                let e = (m.position_m - sp.position_m).norm();
                max_following_error_m = Some(max_following_error_m.map_or(e, |x| x.max(e)));
            }
        }
        let mut states: BTreeMap<String, usize> = BTreeMap::new();
        for s in &self.statuses {
            *states.entry(s.state.clone()).or_default() += 1;
        }
        RecordingSummary {
            master: self.session.master.clone(),
            duration_s: if t1 >= t0 { t1 - t0 } else { 0.0 },
            inputs: self.inputs.len(),
            targets: self.targets.len(),
            limited_targets: self.targets.iter().filter(|t| t.limited).count(),
            statuses: self.statuses.len(),
            events: self.events.len(),
            engagements: self
                .events
                .iter()
                .filter(|e| e.kind == EventKind::State && e.detail == "following")
                .count(),
            target_path_m: path_m,
            max_target_speed_m_s: max_speed_m_s,
            max_following_error_m,
            min_margin: self
                .statuses
                .iter()
                .filter_map(|s| s.nearest_margin)
                .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.min(x)))),
            faults_seen: self.statuses.iter().fold(0, |f, s| f | s.faults),
            states,
            complete: self.complete,
            latency: self.latency(&LagConfig::default()),
        }
    }

    /// The latency figures of the run (see [`crate::latency`]): from what the operator
    /// commanded (stamped with the input sample's time) to the targets sent, the board's
    /// setpoint and the measured pose.
    pub fn latency(&self, cfg: &LagConfig) -> LatencyFigures {
        latency_of(&self.targets, &self.statuses, cfg)
    }
}

/// The latency figures of a run from its targets (their commanded poses and input times)
/// and statuses (see [`crate::latency`]).
pub fn latency_of(
    targets: &[TargetRecord],
    statuses: &[StatusRecord],
    cfg: &LagConfig,
) -> LatencyFigures {
    let commanded: Vec<Stamped> = targets
        .iter()
        .filter_map(|r| Some((r.input_t_s?, r.commanded?.position_m)))
        .collect();
    let sent: Vec<Stamped> = targets.iter().map(|r| (r.t_s, r.pose.position_m)).collect();
    let setpoints: Vec<Stamped> = statuses
        .iter()
        .filter_map(|r| Some((r.t_s, r.setpoint?.position_m)))
        .collect();
    let measured: Vec<Stamped> = statuses
        .iter()
        .filter_map(|r| Some((r.t_s, r.measured?.position_m)))
        .collect();
    LatencyFigures::measure(&commanded, &sent, &setpoints, &measured, cfg)
}

/// Time series for plotting: `(t_s, [x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg])`, the
/// rate masters' input as `(t_s, [vx_mm_s, vy_mm_s, vz_mm_s, wx_deg_s, wy_deg_s, wz_deg_s])`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Position masters' pose (master `measured_cp`, tracker frame).
    pub input_pose: Vec<(f64, [f64; 6])>,
    /// Rate masters' twist ({0}).
    pub input_twist: Vec<(f64, [f64; 6])>,
    /// Targets sent (`servo_cp`).
    pub target: Vec<(f64, [f64; 6])>,
    /// The board's setpoint (`setpoint_cp`), when recorded.
    pub setpoint: Vec<(f64, [f64; 6])>,
    /// The measured pose (`measured_cp`).
    pub measured: Vec<(f64, [f64; 6])>,
}

/// A recording's figures.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingSummary {
    /// The master.
    pub master: String,
    /// From the first to the last record, s.
    pub duration_s: f64,
    /// Master samples.
    pub inputs: usize,
    /// Targets sent.
    pub targets: usize,
    /// Of which limited.
    pub limited_targets: usize,
    /// Statuses.
    pub statuses: usize,
    /// Events.
    pub events: usize,
    /// State events `following` (engagements).
    pub engagements: usize,
    /// Length of the target path, m.
    pub target_path_m: f64,
    /// Largest speed between consecutive targets, m/s.
    pub max_target_speed_m_s: f64,
    /// Largest distance between measured pose and setpoint, m (when both are recorded).
    pub max_following_error_m: Option<f64>,
    /// Smallest nearest-guard margin.
    pub min_margin: Option<f64>,
    /// Every fault bit seen.
    pub faults_seen: u32,
    /// Statuses per board state.
    pub states: BTreeMap<String, usize>,
    /// The file ended properly.
    pub complete: bool,
    /// The latency figures.
    pub latency: LatencyFigures,
}

impl fmt::Display for RecordingSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "master: {}", self.master)?;
        writeln!(
            f,
            "duration {:.2} s; {} master samples, {} targets ({} limited), {} statuses, {} events, {} engagements{}",
            self.duration_s,
            self.inputs,
            self.targets,
            self.limited_targets,
            self.statuses,
            self.events,
            self.engagements,
            if self.complete { "" } else { " (file cut short)" }
        )?;
        writeln!(
            f,
            "target path {:.3} mm, fastest {:.3} mm/s",
            self.target_path_m * 1e3,
            self.max_target_speed_m_s * 1e3
        )?;
        if let Some(e) = self.max_following_error_m {
            writeln!(f, "largest measured-to-setpoint distance {:.4} mm", e * 1e3)?;
        }
        if let Some(m) = self.min_margin {
            writeln!(f, "smallest guard margin {m:.3}")?;
        }
        let states: Vec<String> = self
            .states
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        writeln!(
            f,
            "board states: {}; faults seen {:#x}",
            states.join(", "),
            self.faults_seen
        )?;
        writeln!(f, "latency (lag along the path while moving):")?;
        write!(f, "{}", self.latency)
    }
}
