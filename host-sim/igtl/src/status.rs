//! The status codes of the STATUS message (protocol page "Status", list updated
//! 7/6/2013; `IGTL_STATUS_*` in the reference library's `igtl_status.h`).

/// A STATUS code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum StatusCode {
    /// 0: invalid packet (0 is not used).
    Invalid,
    /// 1: OK (default status).
    Ok,
    /// 2: unknown error.
    UnknownError,
    /// 3: panic mode (emergency).
    PanicMode,
    /// 4: not found (file, configuration, device ...).
    NotFound,
    /// 5: access denied.
    AccessDenied,
    /// 6: busy.
    Busy,
    /// 7: time out / connection lost.
    TimeOut,
    /// 8: overflow / can't be reached.
    Overflow,
    /// 9: checksum error.
    ChecksumError,
    /// 10: configuration error.
    ConfigurationError,
    /// 11: not enough resource (memory, storage ...).
    ResourceError,
    /// 12: illegal/unknown instruction (or feature not implemented / unknown command).
    IllegalInstruction,
    /// 13: device not ready (starting up).
    NotReady,
    /// 14: manual mode (device does not accept commands).
    ManualMode,
    /// 15: device disabled.
    Disabled,
    /// 16: device not present.
    NotPresent,
    /// 17: device version not known.
    UnknownVersion,
    /// 18: hardware failure.
    HardwareFailure,
    /// 19: exiting / shut down in progress.
    ShutDown,
}

impl StatusCode {
    /// Every code, in wire order (index = code).
    pub const ALL: [StatusCode; 20] = [
        StatusCode::Invalid,
        StatusCode::Ok,
        StatusCode::UnknownError,
        StatusCode::PanicMode,
        StatusCode::NotFound,
        StatusCode::AccessDenied,
        StatusCode::Busy,
        StatusCode::TimeOut,
        StatusCode::Overflow,
        StatusCode::ChecksumError,
        StatusCode::ConfigurationError,
        StatusCode::ResourceError,
        StatusCode::IllegalInstruction,
        StatusCode::NotReady,
        StatusCode::ManualMode,
        StatusCode::Disabled,
        StatusCode::NotPresent,
        StatusCode::UnknownVersion,
        StatusCode::HardwareFailure,
        StatusCode::ShutDown,
    ];

    /// The wire value.
    pub fn wire(self) -> u16 {
        self as u16
    }

    /// The code for a wire value, `None` beyond 19.
    pub fn from_wire(v: u16) -> Option<Self> {
        StatusCode::ALL.get(usize::from(v)).copied()
    }
}
