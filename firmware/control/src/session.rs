//! The master session: what the master in charge says about itself and its operator, as
//! the board keeps it between commands. Who owns the board (the nonce of the `Hello` it
//! accepted last, with the master's clock), the clutch pedal and the dead-man (sent by the
//! master), the heartbeat's timing and the clock of its targets; from them, the holds
//! ([`Hold`]) that keep an enabled robot still.
//!
//! **One owner.** A `Hello` with the owner's nonce is the owner reconnecting: a fresh
//! session, its holds kept (unless its clock is not newer than the owner's last: a
//! recording replayed, refused). The last [`FORMER_OWNERS`] owners that another master
//! displaced are kept with their latest clock too: a `Hello` of one of them that is not
//! newer than what it last sent is a replay as well, so that a recording of a former
//! owner cannot take the board back from the master that took over. A `Hello` with
//! another nonce is another master
//! ([`HelloFrom::Other`]): the runtime's table ([`crate::modes::next`]) lets it take over
//! only while the robot is disabled, and then it starts with the clutch released and the
//! operator absent, so that it must say `OperatorPresent { present: true }` before an
//! `Enable` is taken. Every change of owner is counted and kept ([`OwnerChange`]): the hook
//! for the board's event log.

use master_link::NackReason;

use crate::heartbeat::{HeartbeatConfig, HeartbeatLevel, HeartbeatMonitor};
use crate::modes::{Event, Hold};
use crate::targets::{TargetClock, TargetClockConfig};

/// Who a `Hello` comes from, as the session sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HelloFrom {
    /// The owner (its nonce) with a clock newer than its last: a reconnect.
    Owner,
    /// The owner's nonce with a clock not newer than the owner's last: a replay.
    Replay,
    /// Another master (or the first, while nobody owns the board).
    Other,
}

/// A change of the board's owner (the event the board's log records).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OwnerChange {
    /// The previous owner's nonce (None: nobody owned the board).
    pub from: Option<u32>,
    /// The new owner's nonce.
    pub to: u32,
    /// Board time of the change, µs.
    pub at_us: u64,
}

/// The master that owns the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Owner {
    /// Its `Hello`'s nonce.
    pub nonce: u32,
    /// The latest master clock it sent (its `Hello`'s, or a later target's stamp), µs.
    pub clock_us: u64,
}

/// How many displaced owners the session remembers (nonce and latest clock), to refuse
/// their `Hello`s replayed. A master's nonce is fresh per connection, so that only a
/// replay repeats one; the oldest is forgotten first.
pub const FORMER_OWNERS: usize = 8;

/// The master session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MasterSession {
    heartbeat: HeartbeatMonitor,
    targets: TargetClock,
    /// The holds the master's conditions call for ([`Hold::after`]).
    hold: Hold,
    owner: Option<Owner>,
    /// Owners another master displaced, newest first, with the latest clock each sent.
    former: [Option<Owner>; FORMER_OWNERS],
    owner_changes: u16,
    last_change: Option<OwnerChange>,
}

impl MasterSession {
    /// No master yet: clutch released, operator present (a master without a dead-man never
    /// sends `OperatorPresent`), the heartbeat armed at `now_us`.
    pub const fn new(heartbeat: HeartbeatConfig, targets: TargetClockConfig, now_us: u64) -> Self {
        MasterSession {
            heartbeat: HeartbeatMonitor::new(heartbeat, now_us),
            targets: TargetClock::new(targets),
            hold: Hold {
                clutch: false,
                operator_absent: false,
                heartbeat: false,
            },
            owner: None,
            former: [None; FORMER_OWNERS],
            owner_changes: 0,
            last_change: None,
        }
    }

    /// Who a `Hello` with `nonce`, sent at the master's `clock_us`, comes from.
    pub fn hello_from(&self, nonce: u32, clock_us: u64) -> HelloFrom {
        match self.owner {
            Some(o) if o.nonce == nonce && clock_us > self.owner_clock_us(o) => HelloFrom::Owner,
            Some(o) if o.nonce == nonce => HelloFrom::Replay,
            _ if self
                .former
                .iter()
                .flatten()
                .any(|f| f.nonce == nonce && clock_us <= f.clock_us) =>
            {
                HelloFrom::Replay
            }
            _ => HelloFrom::Other,
        }
    }

    /// The owner's latest clock: its `Hello`'s or its latest target's.
    fn owner_clock_us(&self, o: Owner) -> u64 {
        self.targets
            .last_master_us()
            .map_or(o.clock_us, |t| t.max(o.clock_us))
    }

    /// The owner's `Hello` was accepted at `now_us` (a reconnect): a fresh session on the
    /// master's clock `clock_us`, the holds kept.
    pub fn reconnect(&mut self, clock_us: u64, now_us: u64) {
        if let Some(o) = &mut self.owner {
            o.clock_us = clock_us;
        }
        self.targets.start_session(clock_us, now_us);
    }

    /// Another master's `Hello` was accepted at `now_us` (the robot is disabled): it owns
    /// the board, with the clutch released and the operator absent; the change is counted
    /// and kept.
    pub fn take_over(&mut self, nonce: u32, clock_us: u64, now_us: u64) {
        let from = self.owner.map(|o| o.nonce);
        if let Some(o) = self.owner {
            self.remember_former(Owner {
                nonce: o.nonce,
                clock_us: self.owner_clock_us(o),
            });
        }
        // A former owner taking the board again is the owner now, not a former one.
        for f in &mut self.former {
            if f.is_some_and(|f| f.nonce == nonce) {
                *f = None;
            }
        }
        self.owner = Some(Owner { nonce, clock_us });
        self.hold = Hold {
            clutch: false,
            operator_absent: true,
            heartbeat: false,
        };
        self.targets.start_session(clock_us, now_us);
        if from.is_some() {
            self.owner_changes = self.owner_changes.wrapping_add(1);
        }
        self.last_change = Some(OwnerChange {
            from,
            to: nonce,
            at_us: now_us,
        });
    }

    /// Keeps a displaced owner, newest first (the oldest forgotten; an entry of the same
    /// nonce replaced).
    fn remember_former(&mut self, o: Owner) {
        let at = self
            .former
            .iter()
            .position(|f| f.is_none_or(|f| f.nonce == o.nonce))
            .unwrap_or(FORMER_OWNERS - 1);
        // The newer entries move down by one over the slot taken; `o` goes first.
        if let Some(newer) = self.former.get_mut(..=at) {
            newer.rotate_right(1);
            if let Some(first) = newer.first_mut() {
                *first = Some(o);
            }
        }
    }

    /// The master that owns the board, if any.
    pub fn owner(&self) -> Option<Owner> {
        self.owner
    }
    /// Times another master took over from an owner since boot (wrapping).
    pub fn owner_changes(&self) -> u16 {
        self.owner_changes
    }
    /// The last change of owner (the first owner's `Hello` included), for the event log.
    pub fn last_owner_change(&self) -> Option<OwnerChange> {
        self.last_change
    }

    /// Notes what `event` says of the master's conditions (`enabled`: the robot is
    /// enabled, where a late heartbeat holds): see [`Hold::after`].
    pub fn note(&mut self, event: Event, enabled: bool) {
        self.hold = self.hold.after(event, enabled);
    }

    /// A heartbeat arrived: the event it ends (a late or lost heartbeat), if any.
    pub fn beat(&mut self, now_us: u64) -> Option<Event> {
        self.heartbeat.beat(now_us)
    }
    /// The heartbeat's escalation at `now_us`, once each.
    pub fn poll(&mut self, now_us: u64) -> Option<Event> {
        self.heartbeat.poll(now_us)
    }
    /// The master just spoke (homing or enabling starts): the heartbeat timing restarts.
    pub fn rearm(&mut self, now_us: u64) {
        self.heartbeat.rearm(now_us);
    }
    /// Enabling starts: the heartbeat timing and the target clock restart.
    pub fn restart(&mut self, now_us: u64) {
        self.heartbeat.rearm(now_us);
        self.targets.reset();
    }

    /// The holds in force now.
    pub fn hold(&self) -> Hold {
        self.hold
    }
    /// The clutch is engaged.
    pub fn clutch_engaged(&self) -> bool {
        self.hold.clutch
    }
    /// The operator is present.
    pub fn operator_present(&self) -> bool {
        !self.hold.operator_absent
    }
    /// The heartbeat monitor.
    pub fn heartbeat(&self) -> &HeartbeatMonitor {
        &self.heartbeat
    }
    /// The heartbeat is later than the hold time at `now_us`.
    pub fn heartbeat_is_late(&self, now_us: u64) -> bool {
        self.heartbeat.is_late(now_us)
    }
    /// The heartbeat's level at the last poll or beat.
    pub fn heartbeat_level(&self) -> HeartbeatLevel {
        self.heartbeat.level()
    }

    /// A master target stamped `master_us` received at `now_us`: its time on the board's
    /// clock, or why it is refused (out of order, too old).
    pub fn accept_target(&mut self, master_us: u64, now_us: u64) -> Result<u64, NackReason> {
        self.targets.accept(master_us, now_us)
    }
    /// A board-side target (a jog) at `now_us`: its stamp.
    pub fn board_stamp(&mut self, now_us: u64) -> u64 {
        self.targets.board_stamp(now_us)
    }
}
