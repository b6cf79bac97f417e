//! The master session: what the master in charge says about itself and its operator, as
//! the board keeps it between commands. The clutch pedal and the dead-man (sent by the
//! master), the heartbeat's timing and the clock of its targets; from them, the holds
//! ([`Hold`]) that keep an enabled robot still.

use master_link::NackReason;

use crate::heartbeat::{HeartbeatConfig, HeartbeatLevel, HeartbeatMonitor};
use crate::modes::{Event, Hold};
use crate::targets::{TargetClock, TargetClockConfig};

/// The master session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MasterSession {
    heartbeat: HeartbeatMonitor,
    targets: TargetClock,
    /// The holds the master's conditions call for ([`Hold::after`]).
    hold: Hold,
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
        }
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
