//! The board's clock shared with its master beside the link, for an emulated board whose
//! host stalls it: a file of [`LEN`] bytes next to the board's Unix socket (its path with
//! [`SUFFIX`]). The board writes its own time at [`BOARD_US`]; a master that runs in
//! lockstep with it writes back, at [`MASTER_US`], the board time it last read. Each is a
//! little-endian `u64` of microseconds since the board's boot (0: nothing written yet).
//!
//! The board (`board-emulator serve --clock-lead-ms`) then runs at most its lead beyond the
//! master's last reading, and the master's clock is the board's own (`teleop::pacing`):
//! neither runs ahead of the other whatever their host does, so what the master measures
//! is the board's time. A real board has no such file; its master's clock is paced by its
//! statuses.
//!
//! A reader takes a value only when two reads in a row agree (a write races a read).

/// Appended to the socket's path: the shared clock's file.
pub const SUFFIX: &str = ".clock";
/// The file's length, bytes.
pub const LEN: u64 = 16;
/// Where the board writes its time, µs since boot.
pub const BOARD_US: u64 = 0;
/// Where the master writes the board time it last read, µs since the board's boot.
pub const MASTER_US: u64 = 8;

/// A value as stored.
pub const fn encode(us: u64) -> [u8; 8] {
    us.to_le_bytes()
}

/// A value as read back.
pub const fn decode(bytes: [u8; 8]) -> u64 {
    u64::from_le_bytes(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two slots do not overlap and fit the file (checked when compiled); values
    /// round-trip.
    #[test]
    fn slots_fit_and_values_round_trip() {
        const { assert!(BOARD_US + 8 <= MASTER_US && MASTER_US + 8 <= LEN) };
        for v in [0u64, 1, 20_000, u64::MAX] {
            assert_eq!(decode(encode(v)), v);
        }
    }
}
