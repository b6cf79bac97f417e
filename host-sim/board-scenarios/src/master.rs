//! The master: the code of `host-sim teleop` (the `teleop` crate's [`Session`] on a
//! [`Link`]) over the emulated board's USART3, paced by virtual time.
//!
//! [`Rig`] holds the bench and the master's end of the wire (its frame decoder and every
//! message it decoded); [`BenchMedium`] is the [`Medium`] teleop's link runs on: its bytes go
//! onto USART3's RX line at the port's baud, its clock is the board's virtual time, and while
//! the session waits for a message the medium runs the board (in steps of at most
//! [`STEP_NS`]) until one arrives or the wait is over. The session's own clock pacing is off
//! (`Session::paced = false`): its clock already is the board's.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use master_link::{BoardToMaster, LinkCounters};
use rigless::time::VirtualNanos;
use teleop::link::{Link, MasterRx, Medium, Received};
use teleop::session::Session;
use teleop::TeleopError;

use board_emulator::bench::{Bench, BenchError, NANOS_PER_SECOND};

/// The longest stretch the medium runs the board without looking for a message, ns.
pub const STEP_NS: u64 = 1_000_000;

/// The master's nonce in the emulated runs: fixed, so that two runs are the same run.
pub const SESSION_NONCE: u32 = 0x5253_5052;

/// The bench and the master's end of the wire.
pub struct Rig {
    /// The bench.
    pub bench: Bench,
    decoder: MasterRx,
    inbox: VecDeque<Received>,
    /// Every message the master decoded, with its arrival (virtual s).
    pub messages: Vec<Received>,
    /// The true joints (load side) after every step of the medium while recording: (s, q).
    pub truth: Option<Vec<(f64, [f64; 6])>>,
}

impl std::fmt::Debug for Rig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rig")
            .field("bench", &self.bench)
            .field("messages", &self.messages.len())
            .finish()
    }
}

impl Rig {
    /// The master's end of the wire on `bench`.
    pub fn new(bench: Bench) -> Self {
        Rig {
            bench,
            decoder: MasterRx::new(SESSION_NONCE, None),
            inbox: VecDeque::new(),
            messages: Vec::new(),
            truth: None,
        }
    }

    /// Decodes what the board sent since the last call.
    fn decode(&mut self) {
        for (t, byte) in std::mem::take(&mut self.bench.received) {
            if let Some(Ok((seq, msg))) = self.decoder.push(byte) {
                let r = Received {
                    t_s: t.0 as f64 / NANOS_PER_SECOND as f64,
                    seq,
                    msg,
                };
                self.messages.push(r);
                self.inbox.push_back(r);
            }
        }
    }

    /// Runs the board to `until` in steps of at most [`STEP_NS`], stopping early once a
    /// message has arrived (when `early`).
    pub fn run_until(&mut self, until: VirtualNanos, early: bool) -> Result<(), BenchError> {
        loop {
            let now = self.bench.now().0;
            if now >= until.0 || (early && !self.inbox.is_empty()) {
                return Ok(());
            }
            self.bench
                .run_until(VirtualNanos(until.0.min(now + STEP_NS)))?;
            self.decode();
            if let Some(t) = self.truth.as_mut() {
                t.push((self.bench.now_s(), self.bench.last.q));
            }
        }
    }

    /// The board -> master counters of the master's decoder.
    pub fn counters(&self) -> LinkCounters {
        self.decoder.counters()
    }

    /// The last `HelloReply` received, with its arrival.
    pub fn last_hello(&self) -> Option<(f64, BoardToMaster)> {
        self.messages
            .iter()
            .rev()
            .find(|r| matches!(r.msg, BoardToMaster::HelloReply { .. }))
            .map(|r| (r.t_s, r.msg))
    }
}

/// The rig, shared by the session's medium and the scenarios.
#[derive(Debug, Clone)]
pub struct SharedRig(Arc<Mutex<Rig>>);

impl SharedRig {
    /// Shares `rig`.
    pub fn new(rig: Rig) -> Self {
        SharedRig(Arc::new(Mutex::new(rig)))
    }

    /// The rig (a poisoned lock still gives it: the run is single-threaded on this side).
    pub fn lock(&self) -> MutexGuard<'_, Rig> {
        match self.0.lock() {
            Ok(g) => g,
            Err(poisoned) => poisoned.into_inner(),
        }
    }

    /// A teleop session on this rig: link over [`BenchMedium`] with the fixed nonce, the
    /// session's clock pacing off.
    pub fn session(&self) -> Session {
        let link = Link::over(Box::new(BenchMedium { rig: self.clone() }), SESSION_NONCE);
        let mut s = Session::new(link);
        s.paced = false;
        s
    }
}

/// Teleop's medium on the emulated board.
#[derive(Debug)]
pub struct BenchMedium {
    rig: SharedRig,
}

fn closed(e: BenchError) -> TeleopError {
    TeleopError::Closed(e.to_string())
}

impl Medium for BenchMedium {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.rig
            .lock()
            .bench
            .act(board_emulator::bench::Action::Send(bytes.to_vec()));
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<Received>, TeleopError> {
        let mut rig = self.rig.lock();
        if let Some(r) = rig.inbox.pop_front() {
            return Ok(Some(r));
        }
        // At least a microsecond on, whole microseconds: a wait always advances the clock.
        let now = rig.bench.now().0;
        let wait = u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX);
        let until = now.saturating_add(wait.max(1_000)).div_ceil(1_000) * 1_000;
        rig.run_until(VirtualNanos(until), true).map_err(closed)?;
        Ok(rig.inbox.pop_front())
    }

    fn now_s(&self) -> f64 {
        self.rig.lock().bench.now_s()
    }

    fn counters(&self) -> LinkCounters {
        self.rig.lock().counters()
    }
}
