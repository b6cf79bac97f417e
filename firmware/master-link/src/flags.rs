//! Fault and warning bit sets (`u32` newtypes with named bits).
//!
//! Bits are part of the wire format: never renumber a bit, only add new ones.
//! Unknown bits (from a newer firmware) are preserved, never rejected.

use core::fmt;
use core::ops::{BitAnd, BitAndAssign, BitOr, BitOrAssign};
use serde::{Deserialize, Serialize};

macro_rules! bit_flags {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$fmeta:meta])* const $flag:ident = $bit:literal; )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[serde(transparent)]
        pub struct $name(pub u32);

        impl $name {
            $( $(#[$fmeta])* pub const $flag: Self = Self(1 << $bit); )*

            /// No bit set.
            pub const NONE: Self = Self(0);
            /// Every named bit.
            pub const ALL: Self = Self(0 $( | (1 << $bit) )*);
            /// Name of each defined bit (used by `Debug`).
            pub const NAMED: &'static [(&'static str, Self)] = &[ $( (stringify!($flag), Self::$flag), )* ];

            /// Wraps raw bits (unknown bits are kept).
            pub const fn from_bits_retain(bits: u32) -> Self { Self(bits) }
            /// Raw bits.
            pub const fn bits(self) -> u32 { self.0 }
            /// `true` when no bit is set.
            pub const fn is_empty(self) -> bool { self.0 == 0 }
            /// `true` when every bit of `other` is set in `self`.
            pub const fn contains(self, other: Self) -> bool { self.0 & other.0 == other.0 }
            /// `true` when `self` and `other` share at least one bit.
            pub const fn intersects(self, other: Self) -> bool { self.0 & other.0 != 0 }
            /// Union of both sets.
            pub const fn union(self, other: Self) -> Self { Self(self.0 | other.0) }
            /// Bits set that have no name in this protocol version.
            pub const fn unknown(self) -> Self { Self(self.0 & !Self::ALL.0) }
            /// Sets the bits of `other`.
            pub fn insert(&mut self, other: Self) { self.0 |= other.0; }
            /// Clears the bits of `other`.
            pub fn remove(&mut self, other: Self) { self.0 &= !other.0; }
            /// Sets or clears the bits of `other`.
            pub fn set(&mut self, other: Self, on: bool) {
                if on { self.insert(other) } else { self.remove(other) }
            }
        }

        impl BitOr for $name {
            type Output = Self;
            fn bitor(self, rhs: Self) -> Self { Self(self.0 | rhs.0) }
        }
        impl BitOrAssign for $name {
            fn bitor_assign(&mut self, rhs: Self) { self.0 |= rhs.0; }
        }
        impl BitAnd for $name {
            type Output = Self;
            fn bitand(self, rhs: Self) -> Self { Self(self.0 & rhs.0) }
        }
        impl BitAndAssign for $name {
            fn bitand_assign(&mut self, rhs: Self) { self.0 &= rhs.0; }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}(", stringify!($name))?;
                let mut first = true;
                for (name, flag) in Self::NAMED {
                    if self.contains(*flag) {
                        if !first { f.write_str(" | ")?; }
                        f.write_str(name)?;
                        first = false;
                    }
                }
                let unknown = self.unknown().0;
                if unknown != 0 {
                    if !first { f.write_str(" | ")?; }
                    write!(f, "{unknown:#x}")?;
                    first = false;
                }
                if first { f.write_str("NONE")?; }
                f.write_str(")")
            }
        }
    };
}

bit_flags! {
    /// Latched fault conditions (`StatusReport::faults`). Any fault forces the
    /// `Fault` state; they are cleared by `ClearFault` once the cause is gone.
    pub struct Faults {
        /// Emergency stop requested (message or hardware input).
        const EMERGENCY_STOP = 0;
        /// Master heartbeat not received in time while enabled.
        const HEARTBEAT_TIMEOUT = 1;
        /// A joint hit a hard (software or mechanical) limit.
        const JOINT_LIMIT = 2;
        /// Position tracking (following) error too large.
        const FOLLOWING_ERROR = 3;
        /// Motor over-current.
        const OVERCURRENT = 4;
        /// Encoder signal lost or implausible.
        const ENCODER = 5;
        /// Motor driver reported an error.
        const DRIVER = 6;
        /// Homing sequence failed or timed out.
        const HOMING_FAILED = 7;
        /// Configuration became singular (margin below the fault threshold).
        const SINGULARITY = 8;
        /// Inverse kinematics had no solution for an accepted target.
        const KINEMATICS = 9;
        /// Forward kinematics did not converge.
        const FORWARD_KINEMATICS = 10;
        /// Supply voltage out of range.
        const SUPPLY_VOLTAGE = 11;
        /// Over-temperature.
        const OVER_TEMPERATURE = 12;
        /// Watchdog reset or control-loop overrun.
        const WATCHDOG = 13;
        /// Internal firmware error (should not happen).
        const INTERNAL = 14;
        /// The e-stop button and the safety relay's feedback disagree.
        const SAFETY_RELAY = 15;
        /// Standstill monitoring failed during a safe operating stop.
        const STANDSTILL = 16;
        /// The holding brakes failed their check.
        const BRAKE = 17;
        /// A motor circuit is open (current commanded, none flows) or draws far more than
        /// its model (a shorted winding).
        const MOTOR = 18;
    }
}

bit_flags! {
    /// Non-latched warning conditions (`StatusReport::warnings`), recomputed
    /// every control cycle.
    pub struct Warnings {
        /// Serial singularity margin below the warning threshold.
        const NEAR_SERIAL_SINGULARITY = 0;
        /// Parallel singularity margin below the warning threshold.
        const NEAR_PARALLEL_SINGULARITY = 1;
        /// A joint is close to its limit.
        const NEAR_JOINT_LIMIT = 2;
        // Bit 3 is reserved, never to be reused: the board does not clamp a target to
        // the workspace (the supervisor refuses a target outside its limits).
        /// Commanded velocity was limited.
        const VELOCITY_LIMITED = 4;
        /// Following, and no target (pose or jog) accepted for longer than the
        /// supervisor's staleness age (`SupervisorConfig::stale_after_us`, 100 ms): the
        /// robot holds the last one.
        const TARGET_STALE = 5;
        /// Heartbeat late (but not yet timed out).
        const HEARTBEAT_LATE = 6;
        /// Link errors (bad frames) observed recently.
        const LINK_ERRORS = 7;
        /// Not homed yet.
        const NOT_HOMED = 8;
        /// Control loop is close to its time budget.
        const CYCLE_OVERRUN = 9;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;

    /// Flag helpers: insert/remove/contains and a readable `Debug` output.
    #[test]
    fn flags_ops_and_debug() {
        let mut f = Faults::NONE;
        assert!(f.is_empty());
        f.insert(Faults::EMERGENCY_STOP | Faults::ENCODER);
        assert!(f.contains(Faults::ENCODER));
        assert!(f.intersects(Faults::ENCODER | Faults::DRIVER));
        f.remove(Faults::ENCODER);
        assert_eq!(f, Faults::EMERGENCY_STOP);
        f.set(Faults::from_bits_retain(1 << 31), true);
        assert_eq!(format!("{f:?}"), "Faults(EMERGENCY_STOP | 0x80000000)");
        assert_eq!(format!("{:?}", Warnings::NONE), "Warnings(NONE)");
        assert_eq!(Faults::ALL.unknown(), Faults::NONE);
    }
}
