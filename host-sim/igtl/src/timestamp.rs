//! The header's 64-bit timestamp: seconds since 1970-01-01 UTC as unsigned 32.32 fixed
//! point (integer seconds in the high 32 bits, the fraction of a second in units of 2^-32 s
//! in the low 32 bits), 0 when unused (protocol page "Timestamp").

use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A header timestamp, kept as its wire value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Timestamp(pub u64);

const NANOS_PER_SECOND: u64 = 1_000_000_000;

impl Timestamp {
    /// The "unused" timestamp (0).
    pub const UNUSED: Timestamp = Timestamp(0);

    /// From whole seconds and the fraction in units of 2^-32 s.
    pub fn from_parts(seconds: u32, fraction: u32) -> Self {
        Timestamp((u64::from(seconds) << 32) | u64::from(fraction))
    }

    /// Whole seconds since the epoch.
    pub fn seconds(self) -> u32 {
        (self.0 >> 32) as u32
    }

    /// Fraction of a second, in units of 2^-32 s.
    pub fn fraction(self) -> u32 {
        (self.0 & 0xFFFF_FFFF) as u32
    }

    /// True for the "unused" value 0.
    pub fn is_unused(self) -> bool {
        self.0 == 0
    }

    /// From a duration since the epoch; `None` past the 32-bit seconds range (year 2106).
    /// The fraction is rounded down to the next 2^-32 s (0.23 ns), so that converting back
    /// with [`Timestamp::since_epoch`] returns the same nanoseconds.
    pub fn from_since_epoch(d: Duration) -> Option<Self> {
        let seconds = u32::try_from(d.as_secs()).ok()?;
        let fraction = (u64::from(d.subsec_nanos()) << 32) / NANOS_PER_SECOND;
        // subsec_nanos < 1e9, so fraction < 2^32.
        Some(Timestamp::from_parts(seconds, fraction as u32))
    }

    /// The duration since the epoch, the fraction rounded to the nearest nanosecond.
    pub fn since_epoch(self) -> Duration {
        let nanos = (u64::from(self.fraction()) * NANOS_PER_SECOND + (1 << 31)) >> 32;
        // fraction <= 2^32 - 1 rounds to at most 1e9 ns: carry into the seconds.
        Duration::from_secs(u64::from(self.seconds())) + Duration::from_nanos(nanos)
    }

    /// The current system time, or [`Timestamp::UNUSED`] when the clock is before 1970 or
    /// past 2106.
    pub fn now() -> Self {
        SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .ok()
            .and_then(Timestamp::from_since_epoch)
            .unwrap_or(Timestamp::UNUSED)
    }
}
