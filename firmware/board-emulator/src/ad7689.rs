//! The second position channel's converter: an AD7689 (16 bits, 8 channels) on the board
//! with the channel, a `rigless` SPI peer behind its `CNV` pin (the board's SPI3 and PD0,
//! `crate::position_channel`).
//!
//! What the board's driver (`firmware/cortex-m/board/src/ad7689.rs`) relies on, as the data
//! sheet gives it (the constants and the configuration word are
//! `board_profile::position_channel::ad7689`, the one owner both sides read):
//!
//! * `CNV` rising starts a conversion of the input the configuration selects: the input
//!   is sampled at that instant; `CNV` low after `tCONV` selects the converter, and the
//!   16-bit frame clocked then answers that conversion's result (read after conversion).
//!   A frame clocked before `tCONV` has passed answers 0 and is counted
//!   ([`Ad7689::early_reads`]); conversions closer than `tCYC` are counted too
//!   ([`Ad7689::fast_starts`]).
//! * The first 14 bits clocked in (`DIN`) are the configuration when their overwrite bit is
//!   set; they apply from the conversion after the next (a two-deep pipeline). With the
//!   sequencer on (`SEQ` = 0b10 or 0b11) that conversion converts IN0 and the following
//!   ones IN1 .. `INx` in turn, then IN0 again; with it off, each converts `INx`.
//! * Until a configuration has applied the part's is undefined: its conversions answer 0
//!   and are counted ([`Ad7689::unconfigured`]).
//!
//! The inputs are the plant's readings (`plant::PositionSensor`: resolution, noise, offset
//! and faults, as the host's simulated board sees them), already the converter's 16-bit
//! codes of the potentiometers' ratiometric fraction, refreshed every plant step.
//! Not modelled: the temperature sensor, the read-back of the configuration (`RB` = 0),
//! the busy indicator, read during conversion, the bipolar and differential modes.

use board_profile::position_channel::ad7689;
use rigless::chip::spi::Peer;
use rigless::chip::Timeline;
use rigless::snapshot::Store;

/// A conversion under way or done.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Conversion {
    /// Its start (`CNV` rising), ns.
    started_ns: u64,
    /// The input converted.
    channel: u8,
    /// Its result (`None`: the part was not configured).
    value: Option<u16>,
}

/// One AD7689.
#[derive(Debug, Clone, Default)]
pub struct Ad7689 {
    /// The code each input stands at, IN0..IN7.
    inputs: [u16; 8],
    /// The configuration in force (`None` until the first applies).
    active: Option<u16>,
    /// Written by the last frame, applies at the next conversion but one.
    written: Option<u16>,
    /// Moves to `active` at the next conversion.
    armed: Option<u16>,
    /// The sequencer's next input.
    next_channel: u8,
    /// The last conversion.
    conversion: Option<Conversion>,
    /// The inputs converted, in order (the last [`KEPT`]).
    converted: Vec<u8>,
    early_reads: u32,
    fast_starts: u32,
    unconfigured: u32,
}

/// How many converted inputs [`Ad7689::converted`] keeps.
const KEPT: usize = 64;

impl Ad7689 {
    /// A converter just powered (its configuration undefined, its inputs at 0).
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the codes of IN0.. (the rest keep theirs).
    pub fn set_inputs(&mut self, codes: &[u16]) {
        for (i, c) in self.inputs.iter_mut().zip(codes) {
            *i = *c;
        }
    }

    /// The configuration in force.
    pub fn configuration(&self) -> Option<u16> {
        self.active
    }

    /// The inputs the last conversions converted, oldest first.
    pub fn converted(&self) -> &[u8] {
        &self.converted
    }

    /// Frames read before their conversion ended.
    pub fn early_reads(&self) -> u32 {
        self.early_reads
    }

    /// Conversions started sooner than `tCYC` after the one before.
    pub fn fast_starts(&self) -> u32 {
        self.fast_starts
    }

    /// Conversions while the configuration was undefined.
    pub fn unconfigured(&self) -> u32 {
        self.unconfigured
    }

    /// `CNV` rising at `now_ns`: the next conversion.
    fn start(&mut self, now_ns: u64) {
        if let Some(prev) = self.conversion {
            if now_ns.saturating_sub(prev.started_ns) < u64::from(ad7689::T_CYC_NS) {
                self.fast_starts += 1;
            }
        }
        if let Some(cfg) = self.armed.take() {
            self.active = Some(cfg);
            self.next_channel = 0;
        }
        self.armed = self.written.take();
        let Some(cfg) = self.active else {
            self.unconfigured += 1;
            self.conversion = Some(Conversion {
                started_ns: now_ns,
                channel: 0,
                value: None,
            });
            return;
        };
        let last = ((cfg >> 7) & 0b111) as u8;
        let sequencer = (cfg >> 1) & 0b11 >= 0b10;
        let channel = if sequencer { self.next_channel } else { last };
        if sequencer {
            self.next_channel = if channel >= last { 0 } else { channel + 1 };
        }
        let value = self.inputs.get(usize::from(channel)).copied();
        self.conversion = Some(Conversion {
            started_ns: now_ns,
            channel,
            value,
        });
        if self.converted.len() == KEPT {
            self.converted.remove(0);
        }
        self.converted.push(channel);
    }
}

impl Store for Ad7689 {}

impl Peer for Ad7689 {
    /// `CNV` low: the result may be clocked out.
    fn select(&mut self, _context: &mut Timeline<'_, '_>) {}

    /// `CNV` high: a conversion starts.
    fn deselect(&mut self, context: &mut Timeline<'_, '_>) {
        self.start(context.now().0);
    }

    fn transfer(&mut self, mosi: u32, bits: u8, context: &mut Timeline<'_, '_>) -> u32 {
        let frame = if bits >= 16 {
            (mosi >> (bits - 16)) as u16
        } else {
            (mosi << (16 - bits)) as u16
        };
        let cfg = ad7689::cfg_of(frame);
        if cfg & ad7689::CFG_OVERWRITE != 0 {
            self.written = Some(cfg);
        }
        let now = context.now().0;
        let answer = match self.conversion {
            Some(c) if now.saturating_sub(c.started_ns) >= u64::from(ad7689::T_CONV_NS) => {
                c.value.unwrap_or(0)
            }
            Some(_) => {
                self.early_reads += 1;
                0
            }
            None => 0,
        };
        if bits >= 16 {
            u32::from(answer) << (bits - 16)
        } else {
            u32::from(answer >> (16 - bits))
        }
    }
}

#[cfg(test)]
#[allow(clippy::expect_used)]
mod tests {
    use super::*;

    fn read(adc: &mut Ad7689, at: u64, din: u16) -> (u8, u16) {
        adc.start(at);
        let c = adc.conversion.expect("a conversion");
        let now = at + u64::from(ad7689::T_CONV_NS);
        // The transfer's own logic, at `now`.
        let cfg = ad7689::cfg_of(din);
        if cfg & ad7689::CFG_OVERWRITE != 0 {
            adc.written = Some(cfg);
        }
        assert!(now >= c.started_ns);
        (c.channel, c.value.unwrap_or(0))
    }

    /// The configuration applies from the conversion after the next, then the sequencer
    /// converts IN0..IN5 in turn, and again after every rewrite at the fifth read (the
    /// board's driver's pattern); before it applies, nothing is converted.
    #[test]
    fn the_sequencer_follows_the_pipelined_configuration() {
        let mut adc = Ad7689::new();
        adc.set_inputs(&[10, 11, 12, 13, 14, 15, 16, 17]);
        let mut t = 0;
        let mut step = |adc: &mut Ad7689, din| {
            t += u64::from(ad7689::T_CYC_NS);
            read(adc, t, din)
        };
        assert_eq!(step(&mut adc, ad7689::frame(ad7689::CFG)).1, 0);
        assert_eq!(step(&mut adc, 0).1, 0);
        assert_eq!(adc.unconfigured(), 2);
        for _tick in 0..3 {
            let got: Vec<(u8, u16)> = (0..6)
                .map(|k| {
                    step(
                        &mut adc,
                        if k == 4 {
                            ad7689::frame(ad7689::CFG)
                        } else {
                            0
                        },
                    )
                })
                .collect();
            assert_eq!(
                got,
                (0..6u8).map(|c| (c, 10 + u16::from(c))).collect::<Vec<_>>()
            );
        }
        assert_eq!(adc.configuration(), Some(ad7689::CFG));
        assert_eq!(adc.fast_starts(), 0);
    }

    /// An extra conversion (a lost tick's half) shifts the sequence for one tick only: the
    /// rewrite at the fifth read restarts it at IN0.
    #[test]
    fn a_rewrite_realigns_the_sequence() {
        let mut adc = Ad7689::new();
        adc.set_inputs(&[0, 1, 2, 3, 4, 5, 6, 7]);
        let mut t = 0;
        let mut step = |adc: &mut Ad7689, din| {
            t += u64::from(ad7689::T_CYC_NS);
            read(adc, t, din).0
        };
        step(&mut adc, ad7689::frame(ad7689::CFG));
        step(&mut adc, 0);
        step(&mut adc, 0); // IN0, an extra conversion
        let shifted: Vec<u8> = (0..6)
            .map(|k| {
                step(
                    &mut adc,
                    if k == 4 {
                        ad7689::frame(ad7689::CFG)
                    } else {
                        0
                    },
                )
            })
            .collect();
        assert_eq!(shifted, vec![1, 2, 3, 4, 5, 0]);
        let next: Vec<u8> = (0..6)
            .map(|k| {
                step(
                    &mut adc,
                    if k == 4 {
                        ad7689::frame(ad7689::CFG)
                    } else {
                        0
                    },
                )
            })
            .collect();
        assert_eq!(next, vec![0, 1, 2, 3, 4, 5]);
    }
}
