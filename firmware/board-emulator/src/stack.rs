//! The image's stack, measured by painting: before the first instruction the bench fills
//! the stack's region (from the image's `_stack_end`, the end of `.bss` and `.uninit`, up
//! to `_stack_start`, the top of SRAM, where cortex-m-rt starts the main stack) with
//! [`PAINT`]; the core's pushes and frames overwrite it from the top down. The lowest word
//! that no longer holds the paint is the stack's low-water mark (`Action::MeasureStack`,
//! [`crate::bench::Bench::stack_use`]): the deepest the stack has been in the run so far,
//! in thread mode and every interrupt stacked on it (one main stack: the image uses no
//! process stack).
//!
//! The mark is where the deepest write landed: a frame that reserves words and never
//! writes them is not seen, so the mark under-reads a path of large frames. The image
//! before its tick service moved out of the control task's poll frame died at the end of
//! the park move with its stack in `.bss`, yet its mark read 75 744 B: its 27 KB
//! transition frames stepped over painted words and past the floor. Only a stack whose
//! writes reach the floor word reads as an overflow.

use crate::image::{Firmware, ImageError};

/// The paint: a word the firmware is unlikely to push (not a RAM or flash address, not a
/// small integer, not a float it computes).
pub const PAINT: u32 = 0xC5AC_5AC5;

/// The stack depth the board image may use, bytes: 88 KiB. The region the image leaves for
/// the stack is SRAM (128 KiB) less `.data`, `.bss` and `.uninit` (29.5 KiB in the release
/// image; `build-and-size.sh` holds `.data` + `.bss` to 32 KiB): 100 892 B, 98.5 KiB. The
/// budget keeps 10.5 KiB of it unused, for a path the scenarios do not take. The scenarios
/// measure 81 528 B (the deepest is the boot: the runtime and its tick service built in
/// the control task's first poll, under the thread mode's frames).
pub const STACK_BUDGET: u64 = 88 * 1024;

/// The stack's region in the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackRegion {
    /// Its lowest address (`_stack_end`): below it lie `.uninit`, `.bss` and `.data`.
    pub floor: u64,
    /// One past its highest address (`_stack_start`): the initial stack pointer.
    pub top: u64,
}

impl StackRegion {
    /// The region of `firmware` (its `_stack_end` and `_stack_start`, cortex-m-rt's link
    /// script's symbols).
    pub fn of(firmware: &Firmware) -> Result<Self, ImageError> {
        let floor = firmware.symbol("_stack_end")?;
        let top = firmware.symbol("_stack_start")?;
        Ok(StackRegion {
            floor: floor.min(top).next_multiple_of(4),
            top: top & !3,
        })
    }

    /// Bytes between the floor and the top.
    pub fn room(&self) -> u64 {
        self.top.saturating_sub(self.floor)
    }

    /// The paint covering the region, as little-endian bytes from [`StackRegion::floor`].
    pub fn paint(&self) -> Vec<u8> {
        let words = usize::try_from(self.room() / 4).unwrap_or(0);
        PAINT.to_le_bytes().repeat(words)
    }

    /// The lowest address at or above the floor whose word no longer holds the paint (the
    /// top when every word does), reading each word with `read` (`None`: unreadable, taken
    /// as overwritten).
    pub fn low_water(&self, mut read: impl FnMut(u64) -> Option<u32>) -> u64 {
        let mut at = self.floor;
        while at < self.top {
            if read(at) != Some(PAINT) {
                return at;
            }
            at += 4;
        }
        self.top
    }
}

/// The stack's use so far in a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackUse {
    /// The region.
    pub region: StackRegion,
    /// The low-water mark: the lowest word written ([`StackRegion::low_water`]).
    pub lowest: u64,
}

impl StackUse {
    /// The deepest the stack has been, bytes from the top.
    pub fn depth(&self) -> u64 {
        self.region.top.saturating_sub(self.lowest)
    }

    /// The stack ran through its whole region (its floor word was written): past `.bss`.
    pub fn overflowed(&self) -> bool {
        self.lowest <= self.region.floor
    }
}

impl std::fmt::Display for StackUse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "deepest {} B (low-water mark {:#010x}) of the {} B between {:#010x} and {:#010x}{}",
            self.depth(),
            self.lowest,
            self.region.room(),
            self.region.floor,
            self.region.top,
            if self.overflowed() {
                ": the stack ran through its floor into .bss"
            } else {
                ""
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const REGION: StackRegion = StackRegion {
        floor: 0x2000_75DC,
        top: 0x2002_0000,
    };

    proptest! {
        #![proptest_config(proptest_config::cases(64))]
        /// Painted memory with the words from `depth` bytes below the top overwritten
        /// (any value but the paint): the low-water mark is that word, whatever was
        /// written, and a write at the floor reads as an overflow.
        #[test]
        fn the_low_water_mark_is_the_lowest_word_written(
            words in 0u64..(REGION.room() / 4),
            value in any::<u32>().prop_filter("not the paint", |v| *v != PAINT),
        ) {
            let lowest = REGION.top - 4 * words;
            let read = |a: u64| Some(if a >= lowest { value } else { PAINT });
            let got = REGION.low_water(read);
            prop_assert_eq!(got, if words == 0 { REGION.top } else { lowest });
            let used = StackUse { region: REGION, lowest: got };
            prop_assert_eq!(used.depth(), 4 * words);
            prop_assert_eq!(used.overflowed(), got <= REGION.floor);
        }
    }

    /// The paint covers the region word for word.
    #[test]
    fn the_paint_covers_the_region() {
        let p = REGION.paint();
        assert_eq!(p.len() as u64, REGION.room());
        assert!(p.chunks(4).all(|w| w == PAINT.to_le_bytes()));
    }
}
