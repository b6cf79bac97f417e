//! The external interrupt/event controller (EXTI, RM0090 rev 19 chapter 12) and the system
//! configuration controller's line routing (SYSCFG, chapter 9), which rigless 0.4 does not
//! model.
//!
//! | RM0090 rev 19 | what it says | here |
//! |---|---|---|
//! | 12.2.5, figure 42 | an edge on a line selected by `RTSR`/`FTSR` sets its pending bit; the interrupt request is the pending bit under `IMR` | [`Exti::edge`]; the line to the NVIC is `PR & IMR`, level, per vector |
//! | 12.3.1 `EXTI_IMR` | interrupt mask | masks the request, not the pending bit |
//! | 12.3.3, 12.3.4 `RTSR`, `FTSR` | rising / falling trigger selection, both may be set | both edges looked at |
//! | 12.3.5 `EXTI_SWIER` | writing 1 to a bit at 0 sets the pending bit when the line is unmasked in `IMR`; the bit is cleared by clearing the pending bit | as written |
//! | 12.3.6 `EXTI_PR` | `rc_w1`: set by hardware, cleared by writing 1 | the model keeps the pending bits and puts them back after every write |
//! | 12.2.5, table 61 (vectors) | lines 0..4 have a vector each (IRQ 6..10), 5..9 share `EXTI9_5` (23), 10..15 share `EXTI15_10` (40); line 21 is `TAMP_STAMP` (2) | [`vector_of`] |
//! | 9.2.3..9.2.6 `SYSCFG_EXTICR1..4` | `EXTIx[3:0]` picks the port of line x (0000 PA .. 1000 PI); bits 31:16 reserved | [`Syscfg`] stores the codes, [`Syscfg::port_of`] reads them |
//!
//! Not modelled: the event outputs (`EMR`, the core's event input: no firmware here waits for
//! an event), lines 16..22's internal sources (PVD, RTC, USB, Ethernet wake-ups) and an edge
//! made by the firmware's own output or a pull change on a routed pin (the board's inputs are
//! the only edges, `BoardMcu::set_pin`).

use rigless::device::{Device, DeviceContext, Level, RegisterFile};
use rigless::soc::stm32f427::generated::{exti, syscfg};

/// Lines 0..=22 of the STM32F405/F427.
pub const LINES: u32 = 23;
const LINE_MASK: u64 = (1 << LINES) - 1;

/// The NVIC line (IRQ number) each EXTI line raises, RM0090 rev 19 table 61, or `None` for
/// the lines whose internal source this crate does not model.
pub const fn vector_of(line: u32) -> Option<u16> {
    match line {
        0 => Some(6),
        1 => Some(7),
        2 => Some(8),
        3 => Some(9),
        4 => Some(10),
        5..=9 => Some(23),
        10..=15 => Some(40),
        21 => Some(2),
        _ => None,
    }
}

/// The EXTI.
#[derive(Debug, Default)]
pub struct Exti {
    pending: u64,
    swier: u64,
    /// The level last driven on each position of the instance's interrupt list.
    driven: Vec<Level>,
}

impl Exti {
    /// The controller out of reset.
    pub fn new() -> Self {
        Exti::default()
    }

    /// The pending bits (`EXTI_PR`).
    pub fn pending(&self) -> u64 {
        self.pending
    }

    /// An edge on `line` (rising when `rising`), at `context`'s instant: sets the pending bit
    /// when the line's trigger selection takes that edge, and raises the vector under `IMR`.
    pub fn edge(
        &mut self,
        line: u32,
        rising: bool,
        registers: &mut RegisterFile,
        context: &mut DeviceContext<'_>,
    ) {
        if line >= LINES {
            return;
        }
        let selected = if rising {
            registers.get(exti::Register::Rtsr)
        } else {
            registers.get(exti::Register::Ftsr)
        };
        if selected & (1 << line) != 0 {
            self.pending |= 1 << line;
        }
        self.settle(registers, context);
    }

    fn settle(&mut self, registers: &mut RegisterFile, context: &mut DeviceContext<'_>) {
        registers.set(exti::Register::Pr, self.pending);
        let requests = self.pending & registers.get(exti::Register::Imr) & LINE_MASK;
        let table = rigless::soc::stm32f427::generated::EXTI.interrupts;
        if self.driven.len() != table.len() {
            self.driven = vec![Level::Low; table.len()];
        }
        for (position, irq) in table.iter().enumerate() {
            let high =
                (0..LINES).any(|line| requests & (1 << line) != 0 && vector_of(line) == Some(*irq));
            let level = Level::from(high);
            if self.driven.get(position) != Some(&level) {
                if let Some(d) = self.driven.get_mut(position) {
                    *d = level;
                }
                context.interrupt(position, level);
            }
        }
    }
}

impl Device for Exti {
    type Register = exti::Register;

    fn read(
        &mut self,
        register: exti::Register,
        _registers: &mut RegisterFile,
        _context: &mut DeviceContext<'_>,
    ) -> Option<u64> {
        (register == exti::Register::Pr).then_some(self.pending)
    }

    fn peek(
        &self,
        register: exti::Register,
        _registers: &RegisterFile,
        _now: rigless::time::VirtualNanos,
    ) -> Option<u64> {
        (register == exti::Register::Pr).then_some(self.pending)
    }

    fn write(
        &mut self,
        register: exti::Register,
        value: u64,
        registers: &mut RegisterFile,
        context: &mut DeviceContext<'_>,
    ) {
        match register {
            exti::Register::Pr => {
                // rc_w1: a written 1 clears, a 0 leaves; SWIER's bit goes with its pending bit.
                self.pending &= !value;
                self.swier &= !value;
                registers.set(exti::Register::Swier, self.swier);
            }
            exti::Register::Swier => {
                // A 1 written to a bit at 0 sets the pending bit of an unmasked line; the bit
                // reads 1 until the pending bit is cleared, and a written 0 leaves it.
                let rising = value & !self.swier & LINE_MASK;
                self.swier |= value & LINE_MASK;
                self.pending |= rising & registers.get(exti::Register::Imr);
                registers.set(exti::Register::Swier, self.swier);
            }
            _ => {
                let masked = registers.get(register) & LINE_MASK;
                registers.set(register, masked);
            }
        }
        self.settle(registers, context);
    }

    fn reset(&mut self) {
        self.pending = 0;
        self.swier = 0;
        self.driven.clear();
    }
}

/// SYSCFG: the `EXTICRx` routing (and the rest of its registers as storage).
#[derive(Debug, Default)]
pub struct Syscfg;

impl Syscfg {
    /// The port code (0 = A, 1 = B, ...) routed to EXTI line `line` (0..=15) by
    /// `SYSCFG_EXTICR((line / 4) + 1)` field `line % 4`.
    pub fn port_of(line: u32, registers: &RegisterFile) -> Option<u8> {
        let register = match line / 4 {
            0 => syscfg::Register::Exticr1,
            1 => syscfg::Register::Exticr2,
            2 => syscfg::Register::Exticr3,
            3 => syscfg::Register::Exticr4,
            _ => return None,
        };
        let shift = (line % 4) * 4;
        u8::try_from((registers.get(register) >> shift) & 0xF).ok()
    }
}

impl Device for Syscfg {
    type Register = syscfg::Register;

    fn write(
        &mut self,
        register: syscfg::Register,
        _value: u64,
        registers: &mut RegisterFile,
        _context: &mut DeviceContext<'_>,
    ) {
        if matches!(
            register,
            syscfg::Register::Exticr1
                | syscfg::Register::Exticr2
                | syscfg::Register::Exticr3
                | syscfg::Register::Exticr4
        ) {
            // 9.2.3..9.2.6: bits 31:16 are reserved.
            let kept = registers.get(register) & 0xFFFF;
            registers.set(register, kept);
        }
    }
}
