//! `faults`: the fault-injection campaign. Every fault kind ([`FaultKind`], 21 of them:
//! encoders, motors, drivers, supply, currents, the link, the e-stop chain, deadlines,
//! bad targets, switches, jams, a wall, homing and brakes) in every condition
//! ([`Condition`]: holding, moving at 2.5 and at 25 mm/s, holding with the tool), each
//! against the whole board application in simulation, driven over the wire protocol.
//!
//! For each cell ([`Cell`]): whether the board noticed, how long it took against the
//! kind's bound, the reaction it took against the stop table's, and how far the platform
//! moved afterwards against the stops issue's bounds (0.5 mm after an STO with brakes;
//! after an SS1 or SS2, 0.1 mm beyond the supervisor's own braking travel; when the board
//! keeps going, within 1 mm of the setpoint). A fault that only shows while a joint moves
//! (a stuck encoder, an open motor, a jam) is probed in the holding conditions by a small
//! move 100 ms after the injection, and timed from the probe.
//!
//! [`run`] runs the cells, [`report`] prints the matrix and writes it as CSV and PNG.
//! [`search`] is the search for counterexamples to the safety requirements
//! (`control::safety`): random sequences of commands, frames and faults, every
//! requirement's oracle at every tick.

pub mod campaign;
pub mod kinds;
pub mod report;
pub mod search;

pub use campaign::{cells, run_cell, CampaignError, Cell, Condition};
pub use kinds::{Detection, Expectation, FaultKind, Only, Reaction};

/// Runs the cells of `kinds` x `conditions` on up to `threads` threads, in the matrix's
/// order; `progress` is told each finished cell.
pub fn run(
    kinds: &[FaultKind],
    conditions: &[Condition],
    threads: usize,
    progress: &(dyn Fn(&Cell) + Sync),
) -> Result<Vec<Cell>, CampaignError> {
    let todo = cells(kinds, conditions);
    let threads = threads.clamp(1, 8);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: std::sync::Mutex<Vec<Option<Result<Cell, CampaignError>>>> =
        std::sync::Mutex::new((0..todo.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some((k, c)) = todo.get(i) else { break };
                let r = run_cell(*k, *c);
                if let Ok(cell) = &r {
                    progress(cell);
                }
                if let Ok(mut all) = results.lock() {
                    if let Some(slot) = all.get_mut(i) {
                        *slot = Some(r);
                    }
                }
            });
        }
    });
    let all = results.into_inner().unwrap_or_default();
    all.into_iter().flatten().collect()
}
