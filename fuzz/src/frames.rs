//! One sample of every message of both directions, and their frames: the seed corpus and
//! the dictionary that get the fuzzers past COBS and the CRC at once.

use master_link::{
    encode_with, BoardToMaster, EventEntry, EventKind, EventLogPage, FaultCause, FaultLogEntry,
    FaultLogPage, FaultRecord, FirmwareVersion, Header, LinkKey, MasterToBoard, NackReason,
    ResetCause, ResetStatus, RobotState, StatusReport, StopStatus, WireMessage, EVENT_LOG_PAGE,
    FAULT_LOG_PAGE, MAX_FRAME_LEN, PROTOCOL_VERSION,
};

/// The session of the samples' master.
pub const SESSION: u32 = 0x5e55_1011;

/// Every master message, once (Hello first: it opens the session).
pub fn master_messages() -> Vec<MasterToBoard> {
    vec![
        MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION,
            nonce: SESSION,
            clock_us: 1_000,
        },
        MasterToBoard::Enable,
        MasterToBoard::Disable,
        MasterToBoard::Home { rehome: false },
        MasterToBoard::Home { rehome: true },
        MasterToBoard::PoseTarget {
            timestamp_us: 1_000_000,
            position_m: [0.0, 0.0, 0.16],
            rotation_vector_rad: [0.0, 0.0, 0.0],
        },
        MasterToBoard::Jog {
            joint: 0,
            velocity: 0.001,
        },
        MasterToBoard::Clutch { engaged: true },
        MasterToBoard::Clutch { engaged: false },
        MasterToBoard::Heartbeat,
        MasterToBoard::EmergencyStop,
        MasterToBoard::ClearFault,
        MasterToBoard::StatusRequest,
        MasterToBoard::OperatorPresent { present: false },
        MasterToBoard::OperatorPresent { present: true },
        MasterToBoard::AcknowledgeReset,
        MasterToBoard::FaultLogRequest { first: 0 },
    ]
}

/// Every board message, once (a full status, a full fault-log page and a full event-log
/// page: the longest frames).
pub fn board_messages() -> Vec<BoardToMaster> {
    let record = FaultRecord {
        cause: FaultCause::FollowingError,
        joint: 2,
        value: 1.5e-3,
        time_ms: 12_345,
    };
    let status = StatusReport {
        state: RobotState::Fault,
        position_m: [0.001, -0.002, 0.16],
        rotation_vector_rad: [0.01, 0.02, -0.03],
        joints: [0.17, 0.171, 0.169, 0.1, 0.2, 0.3],
        stop: StopStatus::SafeStop1Braking,
        fault: record,
        reset: ResetStatus {
            cause: ResetCause::Watchdog,
            acknowledged: false,
        },
        currents_a: [f32::NAN, 1.0, -1.0, 0.5, 0.25, f32::INFINITY],
        supply_v: 24.0,
        fault_log_len: 3,
        missed_ticks: u32::MAX,
        ..StatusReport::default()
    };
    let entry = FaultLogEntry {
        record,
        stop: StopStatus::SafeTorqueOff,
        count: 7,
    };
    vec![
        BoardToMaster::HelloReply {
            firmware_version: FirmwareVersion {
                major: 0,
                minor: 1,
                patch: 0,
            },
            protocol_version: PROTOCOL_VERSION,
            session: SESSION,
            nonce: SESSION,
            reset: ResetStatus::default(),
            geometry_version: 3,
        },
        BoardToMaster::HelloRefused {
            seq: 4,
            nonce: SESSION,
            reason: NackReason::NotOwner,
        },
        BoardToMaster::GeometryStored { seq: 5, version: 3 },
        BoardToMaster::GeometryRefused {
            seq: 6,
            reason: master_link::GeometryRefusal::OutOfTolerance { index: 17 },
        },
        BoardToMaster::Ack { seq: 7 },
        BoardToMaster::Nack {
            seq: 8,
            reason: NackReason::OutOfWorkspace,
        },
        BoardToMaster::Status(status),
        BoardToMaster::FaultLog(FaultLogPage {
            len: 40,
            total: 41,
            first: 0,
            count: FAULT_LOG_PAGE as u8,
            entries: [entry; FAULT_LOG_PAGE],
        }),
        BoardToMaster::EventLog(EventLogPage {
            len: 32,
            total: 90,
            first: 8,
            count: EVENT_LOG_PAGE as u8,
            lost: 0,
            entries: [EventEntry {
                seq: 60,
                boot: 4,
                time_ms: 12_345,
                event: EventKind::Fault {
                    cause: record.cause,
                    joint: record.joint,
                    value: record.value,
                    stop: StopStatus::SafeTorqueOff,
                },
                count: 2,
                relay_test_pending: false,
            }; EVENT_LOG_PAGE],
        }),
    ]
}

/// The frame of `msg` with `header` (delimiter included).
pub fn frame<M: WireMessage>(msg: &M, header: Header) -> Vec<u8> {
    frame_keyed(msg, header, None)
}

/// The frame of `msg` with `header`, tagged with `key` if any (delimiter included).
pub fn frame_keyed<M: WireMessage>(msg: &M, header: Header, key: Option<&LinkKey>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    match encode_with(msg, header, key, &mut buf) {
        Ok(n) => buf.get(..n).map(<[u8]>::to_vec).unwrap_or_default(),
        Err(e) => panic!("a sample message does not encode: {e:?}"),
    }
}

/// The frames of `msgs` in one session, sequence numbers from `first_seq` up.
pub fn stream<M: WireMessage>(msgs: &[M], first_seq: u16) -> Vec<u8> {
    stream_keyed(msgs, first_seq, None)
}

/// [`stream`], tagged with `key` if any.
pub fn stream_keyed<M: WireMessage>(msgs: &[M], first_seq: u16, key: Option<&LinkKey>) -> Vec<u8> {
    let mut out = Vec::new();
    for (i, m) in msgs.iter().enumerate() {
        let seq = first_seq.wrapping_add(u16::try_from(i).unwrap_or(u16::MAX));
        out.extend(frame_keyed(
            m,
            Header {
                session: SESSION,
                seq,
            },
            key,
        ));
    }
    out
}

/// libFuzzer dictionary entries (at most 64 bytes each: libFuzzer's limit): the delimiter,
/// the header's version byte, and every master frame short enough.
pub fn dictionary() -> Vec<Vec<u8>> {
    let mut entries = vec![vec![0u8], vec![PROTOCOL_VERSION]];
    for (i, m) in master_messages().iter().enumerate() {
        let f = frame(
            m,
            Header {
                session: SESSION,
                seq: u16::try_from(i).unwrap_or(0),
            },
        );
        if f.len() <= 64 {
            entries.push(f);
        }
    }
    entries
}

/// A dictionary entry in libFuzzer's syntax (`"..."` with `\xNN` escapes).
pub fn dictionary_line(name: &str, bytes: &[u8]) -> String {
    let mut s = format!("{name}=\"");
    for b in bytes {
        s.push_str(&format!("\\x{b:02X}"));
    }
    s.push('"');
    s
}
