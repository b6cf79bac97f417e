//! Shared helpers for the integration tests.
#![allow(dead_code)]

use master_link::*;
use proptest::array::uniform3;
use proptest::prelude::*;

/// Encodes one frame of session 0 into a `Vec`, using a `MAX_FRAME_LEN` buffer.
pub fn enc<M: WireMessage>(msg: &M, seq: Seq) -> Vec<u8> {
    enc_in(msg, 0, seq)
}

/// Encodes one frame of session `session` into a `Vec`.
pub fn enc_in<M: WireMessage>(msg: &M, session: u32, seq: Seq) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(msg, Header { session, seq }, &mut buf).expect("encode");
    buf[..n].to_vec()
}

/// Builds a frame by hand: raw = version | session 0 LE | seq LE | body | crc LE (the CRC
/// is computed over the first part unless `crc` is given), COBS + 0x00.
pub fn raw_frame(version: u8, seq: Seq, body: &[u8], crc: Option<u32>) -> Vec<u8> {
    let mut raw = vec![version];
    raw.extend_from_slice(&0u32.to_le_bytes());
    raw.extend_from_slice(&seq.to_le_bytes());
    raw.extend_from_slice(body);
    let crc = crc.unwrap_or_else(|| CRC32.checksum(&raw));
    raw.extend_from_slice(&crc.to_le_bytes());
    cobs_frame(&raw)
}

/// COBS-encodes arbitrary raw bytes and appends the delimiter.
pub fn cobs_frame(raw: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; cobs::max_encoded_len(raw.len()) + 1];
    let n = cobs::encode(raw, &mut out).expect("cobs");
    out.truncate(n);
    out.push(0);
    out
}

/// Postcard body of a message.
pub fn body<M: WireMessage>(msg: &M) -> Vec<u8> {
    let mut buf = [0u8; 512];
    postcard::to_slice(msg, &mut buf)
        .expect("postcard")
        .to_vec()
}

/// Feeds `bytes` one by one and collects every result.
pub fn decode_all<M: WireMessage, const N: usize>(
    dec: &mut FrameDecoder<M, N>,
    bytes: &[u8],
) -> Vec<Result<(Seq, M), FrameError>> {
    bytes.iter().filter_map(|b| dec.push(*b)).collect()
}

/// Variant index; the exhaustive match makes this file fail to compile when a
/// variant is added, so the "every variant" tests get updated.
pub fn master_variant(m: &MasterToBoard) -> usize {
    use MasterToBoard::*;
    match m {
        Hello { .. } => 0,
        Enable => 1,
        Disable => 2,
        Home { .. } => 3,
        PoseTarget { .. } => 4,
        Jog { .. } => 5,
        Clutch { .. } => 6,
        Heartbeat => 7,
        EmergencyStop => 8,
        ClearFault => 9,
        StatusRequest => 10,
        OperatorPresent { .. } => 11,
        AcknowledgeReset => 12,
        FaultLogRequest { .. } => 13,
        StoreGeometry(_) => 14,
        EventLogRequest { .. } => 15,
        Commission { .. } => 16,
    }
}
pub const MASTER_VARIANTS: usize = 17;

pub fn board_variant(m: &BoardToMaster) -> usize {
    use BoardToMaster::*;
    match m {
        HelloReply { .. } => 0,
        Ack { .. } => 1,
        Nack { .. } => 2,
        Status(_) => 3,
        FaultLog(_) => 4,
        GeometryStored { .. } => 5,
        GeometryRefused { .. } => 6,
        EventLog(_) => 7,
        HelloRefused { .. } => 8,
        TargetRefused(_) => 9,
        Commissioning(_) => 10,
    }
}
pub const BOARD_VARIANTS: usize = 11;

/// Every geometry refusal.
pub const ALL_GEOMETRY_REFUSALS: [GeometryRefusal; 11] = [
    GeometryRefusal::Crc,
    GeometryRefusal::Layout { found: u8::MAX },
    GeometryRefusal::Version,
    GeometryRefusal::NonFinite { index: 51 },
    GeometryRefusal::Nominal { index: 3 },
    GeometryRefusal::OutOfTolerance { index: 17 },
    GeometryRefusal::NotAssemblable,
    GeometryRefusal::CentralPose,
    GeometryRefusal::InvalidState,
    GeometryRefusal::Flash,
    GeometryRefusal::Unsupported,
];

/// A geometry record with maximal varints (the largest master message).
pub fn max_geometry() -> GeometryRecord {
    GeometryRecord {
        layout: GEOMETRY_LAYOUT,
        version: u32::MAX,
        nominal: [0.02, 0.09, 0.05, 0.16],
        chains: [[-1.5e-3; GEOMETRY_CHAIN_VALUES]; 3],
        crc: 0,
    }
    .sealed()
}

pub const ALL_NACK_REASONS: [NackReason; 23] = [
    NackReason::UnsupportedVersion,
    NackReason::NotConnected,
    NackReason::InvalidState,
    NackReason::NotHomed,
    NackReason::Faulted,
    NackReason::FaultStillActive,
    NackReason::InvalidJoint,
    NackReason::InvalidValue,
    NackReason::OutOfWorkspace,
    NackReason::JointLimit,
    NackReason::NearSingularity,
    NackReason::VelocityLimit,
    NackReason::StaleTarget,
    NackReason::ClutchDisengaged,
    NackReason::Busy,
    NackReason::AlreadyHomed,
    NackReason::ResetNotAcknowledged,
    NackReason::SafetyRelayMismatch,
    NackReason::BrakeCheckFailed,
    NackReason::OperatorAbsent,
    NackReason::NotOwner,
    NackReason::TargetFromFuture,
    NackReason::ReplayedHello,
];

pub const ALL_STATES: [RobotState; 8] = [
    RobotState::Boot,
    RobotState::Disabled,
    RobotState::Homing,
    RobotState::Ready,
    RobotState::Enabled,
    RobotState::Fault,
    RobotState::Enabling,
    RobotState::Commissioning,
];

/// Status with every varint at its maximum: the largest board message.
pub fn max_status() -> StatusReport {
    StatusReport {
        state: RobotState::Fault,
        position_m: [0.1, -0.2, 0.3],
        rotation_vector_rad: [1.0, -2.0, 3.0],
        joints: [0.01, 0.02, 0.03, 0.4, 0.5, 0.6],
        warnings: Warnings::from_bits_retain(u32::MAX),
        faults: Faults::from_bits_retain(u32::MAX),
        serial_singularity_margin: 0.25,
        parallel_singularity_margin: 0.75,
        link: LinkCounters {
            frames_ok: u32::MAX,
            bad_checksum: u32::MAX,
            malformed: u32::MAX,
            oversized: u32::MAX,
            wrong_version: u32::MAX,
            out_of_order: u32::MAX,
            dropped: u32::MAX,
            wrong_session: u32::MAX,
            bad_tag: u32::MAX,
        },
        tick_jitter_max_us: u32::MAX,
        tick_exec_max_us: u32::MAX,
        targets_refused: u32::MAX,
        stop: StopStatus::SafeStop1Decelerating,
        fault: FaultRecord {
            cause: FaultCause::EncoderDead,
            joint: 5,
            value: -1.5e-3,
            time_ms: u32::MAX,
        },
        reset: ResetStatus {
            cause: ResetCause::Watchdog,
            acknowledged: false,
        },
        setpoint_position_m: [0.1, -0.2, 0.3],
        setpoint_rotation_vector_rad: [1.0, -2.0, 3.0],
        margins: GuardMargins {
            nearest: 0.1,
            serial: 0.2,
            parallel: 0.3,
            stroke: 0.4,
            tilt: 0.5,
            collision: 0.6,
            workspace: 0.7,
        },
        currents_a: [1.0, -2.0, 3.0, -4.0, 5.0, -6.0],
        supply_v: 24.0,
        fault_log_len: u16::MAX,
        missed_ticks: u32::MAX,
        owner_changes: u16::MAX,
        position_channel: true,
    }
}

/// The largest fault-log page.
pub fn max_fault_log() -> FaultLogPage {
    let entry = FaultLogEntry {
        record: FaultRecord {
            cause: FaultCause::Internal,
            joint: NO_JOINT,
            value: f32::MAX,
            time_ms: u32::MAX,
        },
        stop: StopStatus::SafeOperatingStop,
        count: u16::MAX,
    };
    FaultLogPage {
        len: u16::MAX,
        total: u32::MAX,
        first: u16::MAX,
        count: FAULT_LOG_PAGE as u8,
        entries: [entry; FAULT_LOG_PAGE],
    }
}

/// Every kind of event, with maximal values.
pub fn max_event_kinds() -> Vec<EventKind> {
    let mut v = vec![
        EventKind::Fault {
            cause: FaultCause::Internal,
            joint: NO_JOINT,
            value: f32::MAX,
            stop: StopStatus::SafeOperatingStop,
        },
        EventKind::Reset {
            cause: ResetCause::LowPower,
        },
        EventKind::Master { id: u32::MAX },
        EventKind::GeometryStored { version: u32::MAX },
        EventKind::RelayTest { pending: true },
        EventKind::Lost { count: u32::MAX },
    ];
    v.extend(StopReason::ALL.iter().map(|&reason| EventKind::Stop {
        reason,
        stop: StopStatus::SafeStop1Decelerating,
    }));
    v
}

/// The largest event-log page: every entry the largest event (a fault) with maximal
/// varints.
pub fn max_event_log() -> EventLogPage {
    let entry = EventEntry {
        seq: u32::MAX,
        boot: u16::MAX,
        time_ms: u32::MAX,
        event: max_event_kinds()[0],
        count: u16::MAX,
        relay_test_pending: true,
    };
    EventLogPage {
        len: u16::MAX,
        total: u32::MAX,
        first: u16::MAX,
        count: EVENT_LOG_PAGE as u8,
        lost: u32::MAX,
        entries: [entry; EVENT_LOG_PAGE],
    }
}

/// One sample of every master -> board variant (with maximal varints).
pub fn master_samples() -> Vec<MasterToBoard> {
    vec![
        MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION,
            nonce: u32::MAX,
            clock_us: u64::MAX,
        },
        MasterToBoard::Enable,
        MasterToBoard::Disable,
        MasterToBoard::Home { rehome: false },
        MasterToBoard::Home { rehome: true },
        MasterToBoard::PoseTarget {
            timestamp_us: u64::MAX,
            position_m: [0.01, -0.02, 0.15],
            rotation_vector_rad: [0.1, 0.0, -2.5],
        },
        MasterToBoard::Jog {
            joint: 5,
            velocity: -0.5,
        },
        MasterToBoard::Clutch { engaged: true },
        MasterToBoard::Clutch { engaged: false },
        MasterToBoard::Heartbeat,
        MasterToBoard::EmergencyStop,
        MasterToBoard::ClearFault,
        MasterToBoard::StatusRequest,
        MasterToBoard::OperatorPresent { present: true },
        MasterToBoard::AcknowledgeReset,
        MasterToBoard::FaultLogRequest { first: u16::MAX },
        MasterToBoard::StoreGeometry(max_geometry()),
        MasterToBoard::EventLogRequest { first: u16::MAX },
        MasterToBoard::Commission {
            joint: 5,
            confirm: true,
        },
    ]
}

/// One sample of every board -> master variant, every Nack reason and
/// every robot state.
pub fn board_samples() -> Vec<BoardToMaster> {
    let mut v = vec![
        BoardToMaster::HelloReply {
            firmware_version: FirmwareVersion {
                major: 1,
                minor: 2,
                patch: 255,
            },
            protocol_version: PROTOCOL_VERSION,
            session: u32::MAX,
            nonce: u32::MAX,
            reset: ResetStatus {
                cause: ResetCause::BrownOut,
                acknowledged: false,
            },
            geometry_version: u32::MAX,
        },
        BoardToMaster::HelloRefused {
            seq: u16::MAX,
            nonce: u32::MAX,
            reason: NackReason::NotOwner,
        },
        BoardToMaster::Ack { seq: u16::MAX },
        BoardToMaster::GeometryStored {
            seq: u16::MAX,
            version: u32::MAX,
        },
        BoardToMaster::Status(max_status()),
        BoardToMaster::Status(StatusReport::default()),
        BoardToMaster::FaultLog(max_fault_log()),
        BoardToMaster::FaultLog(FaultLogPage::default()),
        BoardToMaster::EventLog(max_event_log()),
        BoardToMaster::EventLog(EventLogPage::default()),
    ];
    v.extend(max_event_kinds().into_iter().map(|event| {
        let mut page = max_event_log();
        page.entries = [EventEntry {
            event,
            ..page.entries[0]
        }; EVENT_LOG_PAGE];
        BoardToMaster::EventLog(page)
    }));
    v.extend(ALL_NACK_REASONS.iter().map(|&reason| BoardToMaster::Nack {
        seq: 0x1234,
        reason,
    }));
    // A refused target at submission (the reply) and one of the path check, with a
    // measured breach at its largest (u64::MAX stamp) and without one.
    v.push(BoardToMaster::TargetRefused(master_link::RefusedTarget {
        reply_to: Some(u16::MAX),
        timestamp_us: u64::MAX,
        reason: NackReason::OutOfWorkspace,
        breach: master_link::Breach {
            guard: master_link::GuardId::Workspace,
            subject: 2,
            value: 0.177,
            limit: 0.175,
        },
    }));
    // A commissioning record with every field set (finite: the round trip compares).
    v.push(BoardToMaster::Commissioning(CommissionRecord {
        joint: 5,
        done: true,
        reference: true,
        findings: CommissionFindings(u16::MAX),
        moved_encoder: 255,
        encoder_motion: -1.5e-3,
        reference_motion: f32::MAX,
        scale: 1.1,
        current_offset_a: -0.02,
        current_a: 3.5,
        applied_motion: 6e-6,
        peak_travel: 0.5,
        breakaway_duty: 0.069,
        switch: 3,
        switch_position: 0.143,
    }));
    v.push(BoardToMaster::TargetRefused(master_link::RefusedTarget {
        reply_to: None,
        timestamp_us: 12,
        reason: NackReason::NotHomed,
        breach: master_link::Breach::NONE,
    }));
    v.extend(
        ALL_GEOMETRY_REFUSALS
            .iter()
            .map(|&reason| BoardToMaster::GeometryRefused { seq: 7, reason }),
    );
    v.extend(ALL_STATES.iter().map(|&state| {
        BoardToMaster::Status(StatusReport {
            state,
            faults: Faults::EMERGENCY_STOP | Faults::ENCODER,
            warnings: Warnings::NEAR_PARALLEL_SINGULARITY,
            ..StatusReport::default()
        })
    }));
    v
}

// ---- proptest strategies (any f32 bit pattern, NaN included) ----

pub fn arb_f3() -> impl Strategy<Value = [f32; 3]> {
    uniform3(any::<f32>())
}

pub fn arb_master() -> impl Strategy<Value = MasterToBoard> {
    prop_oneof![
        (any::<u8>(), any::<u32>(), any::<u64>()).prop_map(|(v, nonce, clock_us)| {
            MasterToBoard::Hello {
                protocol_version: v,
                nonce,
                clock_us,
            }
        }),
        Just(MasterToBoard::Enable),
        Just(MasterToBoard::Disable),
        any::<bool>().prop_map(|rehome| MasterToBoard::Home { rehome }),
        (any::<u64>(), arb_f3(), arb_f3()).prop_map(|(t, p, r)| MasterToBoard::PoseTarget {
            timestamp_us: t,
            position_m: p,
            rotation_vector_rad: r
        }),
        (any::<u8>(), any::<f32>())
            .prop_map(|(joint, velocity)| MasterToBoard::Jog { joint, velocity }),
        any::<bool>().prop_map(|engaged| MasterToBoard::Clutch { engaged }),
        Just(MasterToBoard::Heartbeat),
        Just(MasterToBoard::EmergencyStop),
        Just(MasterToBoard::ClearFault),
        Just(MasterToBoard::StatusRequest),
        any::<bool>().prop_map(|present| MasterToBoard::OperatorPresent { present }),
        Just(MasterToBoard::AcknowledgeReset),
        any::<u16>().prop_map(|first| MasterToBoard::FaultLogRequest { first }),
        (
            any::<u8>(),
            any::<u32>(),
            proptest::array::uniform4(any::<f32>()),
            proptest::array::uniform16(any::<f32>()),
            any::<u32>()
        )
            .prop_map(|(layout, version, nominal, chain, crc)| {
                MasterToBoard::StoreGeometry(GeometryRecord {
                    layout,
                    version,
                    nominal,
                    chains: [chain; 3],
                    crc,
                })
            }),
        any::<u16>().prop_map(|first| MasterToBoard::EventLogRequest { first }),
        (any::<u8>(), any::<bool>())
            .prop_map(|(joint, confirm)| MasterToBoard::Commission { joint, confirm }),
    ]
}

pub fn arb_counters() -> impl Strategy<Value = LinkCounters> {
    proptest::array::uniform9(any::<u32>()).prop_map(|c| LinkCounters {
        frames_ok: c[0],
        bad_checksum: c[1],
        malformed: c[2],
        oversized: c[3],
        wrong_version: c[4],
        out_of_order: c[5],
        dropped: c[6],
        wrong_session: c[7],
        bad_tag: c[8],
    })
}

pub fn arb_status() -> impl Strategy<Value = StatusReport> {
    (
        proptest::sample::select(ALL_STATES.to_vec()),
        arb_f3(),
        arb_f3(),
        proptest::array::uniform6(any::<f32>()),
        any::<u32>(),
        any::<u32>(),
        any::<f32>(),
        any::<f32>(),
        (arb_counters(), any::<u32>(), any::<u32>(), any::<u32>()),
    )
        .prop_map(
            |(state, p, r, joints, w, f, sm, pm, (link, tj, te, tr))| StatusReport {
                state,
                position_m: p,
                rotation_vector_rad: r,
                joints,
                warnings: Warnings::from_bits_retain(w),
                faults: Faults::from_bits_retain(f),
                serial_singularity_margin: sm,
                parallel_singularity_margin: pm,
                link,
                tick_jitter_max_us: tj,
                tick_exec_max_us: te,
                targets_refused: tr,
                ..max_status()
            },
        )
}

pub fn arb_board() -> impl Strategy<Value = BoardToMaster> {
    prop_oneof![
        (any::<[u8; 3]>(), any::<u8>(), any::<u32>()).prop_map(|(v, p, session)| {
            BoardToMaster::HelloReply {
                firmware_version: FirmwareVersion {
                    major: v[0],
                    minor: v[1],
                    patch: v[2],
                },
                protocol_version: p,
                session,
                nonce: session.rotate_left(3),
                reset: ResetStatus::default(),
                geometry_version: session.rotate_left(7),
            }
        }),
        (any::<u16>(), any::<u32>())
            .prop_map(|(seq, version)| BoardToMaster::GeometryStored { seq, version }),
        (
            any::<u16>(),
            proptest::sample::select(ALL_GEOMETRY_REFUSALS.to_vec())
        )
            .prop_map(|(seq, reason)| BoardToMaster::GeometryRefused { seq, reason }),
        any::<u16>().prop_map(|seq| BoardToMaster::Ack { seq }),
        (
            any::<u16>(),
            proptest::sample::select(ALL_NACK_REASONS.to_vec())
        )
            .prop_map(|(seq, reason)| BoardToMaster::Nack { seq, reason }),
        arb_status().prop_map(BoardToMaster::Status),
        Just(BoardToMaster::FaultLog(max_fault_log())),
        Just(BoardToMaster::EventLog(max_event_log())),
    ]
}
