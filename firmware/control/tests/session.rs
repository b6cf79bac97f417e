#![allow(clippy::unwrap_used)]
//! The master session's idea of who a `Hello` comes from (`control::session`): the owner
//! reconnecting, a replay, or another master.
//!
//! The property: a `Hello` whose clock is not newer than the last clock its nonce sent
//! while it owned the board is a replay, whether that nonce owns the board now or is one
//! of the last [`FORMER_OWNERS`] owners another master displaced; a newer one is taken
//! (the owner reconnecting, or a former owner coming back as another master); a nonce
//! never seen is another master.

use control::heartbeat::HeartbeatConfig;
use control::session::{HelloFrom, MasterSession, FORMER_OWNERS};
use control::targets::TargetClockConfig;
use proptest::prelude::*;

fn session() -> MasterSession {
    MasterSession::new(HeartbeatConfig::default(), TargetClockConfig::default(), 0)
}

/// The example the search found: master 1 owns the board, master 2 takes over while the
/// robot is disabled, master 1's recorded `Hello` is replayed. Refused; a fresh `Hello` of
/// master 1 (a newer clock) is another master's, as any new connection's.
#[test]
fn a_former_owners_replayed_hello_does_not_take_the_board_back() {
    let mut s = session();
    s.take_over(1, 5_000, 0);
    s.take_over(2, 100, 1_000);
    assert_eq!(s.hello_from(1, 5_000), HelloFrom::Replay);
    assert_eq!(s.hello_from(1, 4_000), HelloFrom::Replay);
    assert_eq!(s.hello_from(1, 5_001), HelloFrom::Other);
    assert_eq!(s.hello_from(2, 100), HelloFrom::Replay);
    assert_eq!(s.hello_from(2, 101), HelloFrom::Owner);
    assert_eq!(s.hello_from(3, 0), HelloFrom::Other);
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Owners 1..=n take the board in turn (each with its own clock); then every one of
    /// the last FORMER_OWNERS displaced owners' Hellos at or before its clock is a replay,
    /// a newer one is taken, and the current owner's rules are unchanged.
    #[test]
    fn every_recent_former_owner_is_held_to_its_clock(
        clocks in proptest::collection::vec(1u64..1_000_000, 2..20),
        back in 0u64..1_000,
    ) {
        let mut s = session();
        let n = clocks.len();
        for (i, c) in clocks.iter().enumerate() {
            s.take_over(i as u32 + 1, *c, i as u64 * 1_000);
        }
        let owner = n as u32;
        let last = clocks[n - 1];
        prop_assert_eq!(s.hello_from(owner, last.saturating_sub(back)), HelloFrom::Replay);
        prop_assert_eq!(s.hello_from(owner, last + 1 + back), HelloFrom::Owner);
        // The displaced owners, newest first.
        for k in 1..n.min(FORMER_OWNERS + 1) {
            let nonce = (n - k) as u32;
            let clock = clocks[n - k - 1];
            prop_assert_eq!(
                s.hello_from(nonce, clock.saturating_sub(back)),
                HelloFrom::Replay,
                "former owner {} at or before its clock {}", nonce, clock
            );
            prop_assert_eq!(s.hello_from(nonce, clock + 1 + back), HelloFrom::Other);
        }
        prop_assert_eq!(s.hello_from(n as u32 + 1, 0), HelloFrom::Other);
    }

    /// A former owner that takes the board again is the owner, not a former one: its
    /// reconnect with a newer clock is taken as the owner's, and the master it displaced
    /// is now held to its own clock.
    #[test]
    fn a_former_owner_back_in_charge_is_the_owner(c1 in 1u64..1_000, c2 in 1u64..1_000, d in 1u64..1_000) {
        let mut s = session();
        s.take_over(1, c1, 0);
        s.take_over(2, c2, 1_000);
        s.take_over(1, c1 + d, 2_000);
        prop_assert_eq!(s.hello_from(1, c1 + d + 1), HelloFrom::Owner);
        prop_assert_eq!(s.hello_from(1, c1 + d), HelloFrom::Replay);
        prop_assert_eq!(s.hello_from(2, c2), HelloFrom::Replay);
        prop_assert_eq!(s.hello_from(2, c2 + 1), HelloFrom::Other);
    }
}
