#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The search for counterexamples to the safety requirements (SR-1 .. SR-7,
//! `control::safety`): random sequences of the owning master's commands and streams, a
//! second master's and replayed or forged frames, injected faults (alone and two at
//! once, at any tick, in every mode), the e-stop button, the tool, walls and pushes, on
//! the whole board application against the plant, every requirement's oracle checked at
//! every tick (`faults::search`).
//!
//! CI runs `SEARCH_CASES` cases from the fixed seed of `tests/proptest-config`; a deeper
//! search: `RSPR_PROPTEST_FRESH=1 RSPR_PROPTEST_SCALE=20 cargo test --release -p faults
//! --test search` (fresh seeds, 20 times the cases; proptest records a failure in
//! `search.proptest-regressions`, which is committed and replayed by every later run).
//! Each counterexample found once is also written out below as a named case.

use control::safety::Requirement;
use faults::search::{run_case, Action, Cmd, Foreign, Injection, OpenHole, Start};
use proptest::prelude::*;

/// The cases CI runs: about 0.24 s each on one core of the CI machine (homing, the
/// enable, up to 24 actions and 600 ms after them in virtual time), 400 cases in about
/// a minute and a half.
const SEARCH_CASES: u32 = 400;

/// The holes known open on this branch, each closed by work in progress elsewhere: their
/// violations are counted and printed, and the case goes on. When the work lands, its
/// entry goes (the search then holds it to the requirement). `SEARCH_OPEN=SR-5,SR-2`
/// tolerates more requirements, to explore past a hole.
const OPEN: &[OpenHole] = &[
    OpenHole {
        requirements: &[
            Requirement::Detection,
            Requirement::StopDistance,
            Requirement::Reaction,
        ],
        involving: "EncoderLosesCounts",
        closed_by: "the second position channel: an encoder that loses one count in three is detected after 151 ms of showing against 150 ms (SR-5), and the joint runs faster and further than measured (SR-2, SR-7)",
    },
];

fn open() -> Vec<OpenHole> {
    let extra = std::env::var("SEARCH_OPEN").unwrap_or_default();
    let extra: &'static [Requirement] = Box::leak(
        extra
            .split(',')
            .filter_map(|id| Requirement::of_id(id.trim()))
            .collect::<Vec<_>>()
            .into_boxed_slice(),
    );
    let mut open = OPEN.to_vec();
    if !extra.is_empty() {
        open.push(OpenHole {
            requirements: extra,
            involving: "",
            closed_by: "SEARCH_OPEN",
        });
    }
    open
}

fn start() -> impl Strategy<Value = Start> {
    prop_oneof![
        1 => Just(Start::Fresh),
        2 => Just(Start::Homing),
        2 => Just(Start::Ready),
        5 => Just(Start::Following),
    ]
}

fn cmd() -> impl Strategy<Value = Cmd> {
    prop_oneof![
        Just(Cmd::Hello),
        Just(Cmd::Enable),
        Just(Cmd::Disable),
        any::<bool>().prop_map(|rehome| Cmd::Home { rehome }),
        any::<bool>().prop_map(Cmd::Clutch),
        any::<bool>().prop_map(Cmd::Operator),
        Just(Cmd::ClearFault),
        Just(Cmd::AckReset),
        Just(Cmd::EStop),
        Just(Cmd::Status),
        Just(Cmd::StoreGeometry),
    ]
}

fn foreign() -> impl Strategy<Value = Foreign> {
    prop_oneof![
        Just(Foreign::SecondHello),
        cmd().prop_map(Foreign::SecondCommand),
        Just(Foreign::SecondTarget),
        (1u8..40).prop_map(|back| Foreign::Replay { back }),
        // (Not a Hello: a handshake's number is not checked, and a Hello with the owner's
        // nonce and a newer clock is the owner reconnecting; on a link without a key a
        // forger who knows the nonce is the owner, and it resets the owner's sequence
        // to its number. The link key closes that.)
        cmd()
            .prop_filter("a handshake", |c| *c != Cmd::Hello)
            .prop_map(Foreign::FarAhead),
        (0u16..5_000).prop_map(|ahead_ms| Foreign::FutureTarget { ahead_ms }),
        Just(Foreign::StampedMax),
        Just(Foreign::ReplayHelloEnable),
    ]
}

fn injection() -> impl Strategy<Value = Injection> {
    let j = 0u8..6;
    prop_oneof![
        j.clone().prop_map(Injection::EncoderStuck),
        j.clone().prop_map(Injection::EncoderJump),
        j.clone().prop_map(Injection::EncoderDead),
        j.clone().prop_map(Injection::EncoderLosesCounts),
        j.clone().prop_map(Injection::MotorOpen),
        j.clone().prop_map(Injection::MotorShorted),
        j.clone().prop_map(Injection::DriverFault),
        Just(Injection::SupplySag),
        j.clone().prop_map(Injection::Overcurrent),
        j.clone().prop_map(Injection::BridgeStuckOn),
        Just(Injection::RelayWelded),
        Just(Injection::RelayStuckOpen),
        Just(Injection::TickOverrun),
        j.clone().prop_map(Injection::SwitchClosed),
        (0u8..3).prop_map(Injection::SwitchDead),
        j.prop_map(Injection::LoadSeized),
        Just(Injection::BrakesWorn),
    ]
}

fn action() -> impl Strategy<Value = Action> {
    prop_oneof![
        6 => (0u16..400).prop_map(Action::Wait),
        1 => (50u16..700).prop_map(Action::Silence),
        5 => cmd().prop_map(Action::Command),
        5 => (-15i8..=15, -5i8..=5, 1u8..=30, 10u16..1_500).prop_map(
            |(x_mm, z_mm, speed_mm_s, ms)| Action::Stream { x_mm, z_mm, speed_mm_s, ms }
        ),
        1 => (0u8..6, -30i8..=30, 10u16..600)
            .prop_map(|(joint, velocity, ms)| Action::Jog { joint, velocity, ms }),
        3 => foreign().prop_map(Action::Foreign),
        4 => injection().prop_map(Action::Fault),
        1 => Just(Action::Repair),
        1 => any::<bool>().prop_map(Action::Button),
        1 => any::<bool>().prop_map(Action::Tool),
        1 => (any::<bool>(), 0u16..400).prop_map(|(plus, depth_um)| Action::Push { plus, depth_um }),
        1 => (any::<bool>(), 0u16..3_000).prop_map(|(plus, ahead_um)| Action::Wall { plus, ahead_um }),
    ]
}

proptest! {
    #![proptest_config(proptest_config::cases(SEARCH_CASES))]

    /// Property (SR-1, SR-2, SR-3, SR-4, SR-5, SR-6, SR-7): from any start (powered up,
    /// homing, ready, following), any sequence of the owner's commands and streams,
    /// foreign frames, faults (alone or two at once), the button, the tool, walls and
    /// pushes keeps every safety requirement at every tick.
    #[test]
    fn random_sequences_keep_every_requirement(
        start in start(),
        actions in proptest::collection::vec(action(), 1..24),
    ) {
        let r = run_case(start, &actions, &open());
        prop_assert!(r.setup.is_none(), "set-up: {:?}", r.setup);
        prop_assert!(r.violations.is_empty(), "{}", r.first().unwrap_or_default());
    }
}

/// Property (SR-6): no foreign frame is taken while the owner's session lives: a second
/// master's Hello, its commands and targets, replayed frames, frames far ahead in the
/// owner's sequence, a target stamped in the future.
#[test]
fn a_foreign_frame_never_moves_the_robot() {
    use Action as A;
    let hold = [A::Command(Cmd::Clutch(true)), A::Wait(200)];
    let cases: Vec<(&str, Vec<Action>)> = vec![
        (
            "a second master's Hello while the owner holds",
            [&hold[..], &[A::Foreign(Foreign::SecondHello), A::Wait(100)]].concat(),
        ),
        (
            "a second master's target after its Hello",
            vec![
                A::Foreign(Foreign::SecondHello),
                A::Wait(10),
                A::Foreign(Foreign::SecondTarget),
                A::Wait(300),
            ],
        ),
        (
            "the owner's Hello replayed, then its old target",
            vec![A::Foreign(Foreign::Replay { back: 30 }), A::Wait(10)],
        ),
        (
            "a target far ahead in the owner's sequence",
            vec![
                A::Foreign(Foreign::FarAhead(Cmd::Clutch(false))),
                A::Wait(50),
            ],
        ),
        (
            "a target stamped in the future",
            vec![
                A::Foreign(Foreign::FutureTarget { ahead_ms: 1_000 }),
                A::Wait(300),
            ],
        ),
    ];
    for (what, actions) in cases {
        let r = run_case(Start::Following, &actions, OPEN);
        assert!(
            r.violations.is_empty(),
            "{what}: {}",
            r.first().unwrap_or_default()
        );
        for v in &r.tolerated {
            println!("{what}: open: {v}");
        }
    }
}

/// Not a property: the long search. `SEARCH_EXPLORE=N` (fresh random cases) or
/// `SEARCH_MINUTES=M` (as many as fit in M minutes of wall time), run with
/// `cargo test --release -p faults --test search -- --ignored explore --nocapture`: every
/// case runs to its end without stopping or shrinking (the holes of `OPEN` tolerated), and
/// every distinct violation is printed (its requirement and words) with a case that shows
/// it, then the figures: cases, actions, virtual time, wall time, violations.
#[test]
#[ignore = "the long search: run it by hand (SEARCH_EXPLORE, SEARCH_MINUTES)"]
fn explore() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    let minutes = env("SEARCH_MINUTES");
    let n = env("SEARCH_EXPLORE").unwrap_or(if minutes.is_some() { u64::MAX } else { 200 });
    let budget = std::time::Duration::from_secs(minutes.unwrap_or(u64::MAX / 120) * 60);
    let t0 = std::time::Instant::now();
    let mut runner = TestRunner::default();
    let strategy = (start(), proptest::collection::vec(action(), 1..24));
    let mut seen: std::collections::BTreeMap<String, (usize, String)> = Default::default();
    let (mut cases, mut steps, mut virtual_s, mut found) = (0u64, 0usize, 0.0f64, 0usize);
    while cases < n && t0.elapsed() < budget {
        let (s, actions) = strategy.new_tree(&mut runner).unwrap().current();
        let r = run_case(s, &actions, &open());
        cases += 1;
        steps += actions.len();
        virtual_s += r.virtual_s;
        found += r.violations.len();
        for v in r.violations.iter().chain(r.tolerated.iter()) {
            // The kind of violation: its requirement and its words without figures.
            let words: String = v
                .what
                .split(|c: char| c.is_ascii_digit())
                .next()
                .unwrap_or_default()
                .to_string();
            let key = format!("{} {words}", v.requirement.id());
            let e = seen
                .entry(key)
                .or_insert((0, format!("{v} from {s:?}: {actions:?}")));
            e.0 += 1;
        }
    }
    for (k, (count, example)) in &seen {
        println!("{count:4} x {k}\n       {example}\n");
    }
    println!(
        "explored: {cases} cases, {steps} actions, {virtual_s:.0} s virtual, {:.0} s wall, \
         {found} violations not tolerated, {} distinct kinds (tolerated included)",
        t0.elapsed().as_secs_f64(),
        seen.len()
    );
}

/// Replays each `(what, start, actions)` case with the holes of `open` tolerated (printed):
/// fails with every case that broke a requirement.
fn replay(cases: &[(&str, Start, Vec<Action>)], open: &[OpenHole]) {
    let mut failed = Vec::new();
    for (what, start, actions) in cases {
        let r = run_case(*start, actions, open);
        for v in &r.tolerated {
            println!("{what}: open: {v}");
        }
        if let Some(v) = r.first() {
            failed.push(format!("{what}: {v}"));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// The counterexamples the long search found that were the oracles' (a fault counted as
/// showing that could not show, a standing fault's repeat blamed on a later one, a contact
/// flag taken for motion, a stop that did its work and was then cleared taken for none)
/// or causes the board cannot tell apart (SR-5's row), each
/// replayed from the sequence the search printed, with no hole tolerated.
/// (SR-1, SR-5, SR-7: each case names the requirement it broke.)
#[test]
fn counterexamples_of_the_oracles_hold_now() {
    use Action as A;
    use Cmd::*;
    use Foreign::*;
    use Injection::*;
    let cases: Vec<(&str, Start, Vec<Action>)> = vec![
        (
            "SR-7: the owner's ClearFault 2 ms after its EmergencyStop, taken after the STO \
             had done its work (torque off and brakes applied at the first tick, 23.134 s, \
             and the next), was judged a missing reaction at the second tick (the stop in \
             force is None, the table's: Sto)",
            Start::Following,
            vec![
                A::Wait(342),
                A::Command(Clutch(false)),
                A::Stream {
                    x_mm: -11,
                    z_mm: 1,
                    speed_mm_s: 3,
                    ms: 1490,
                },
                A::Stream {
                    x_mm: 15,
                    z_mm: -3,
                    speed_mm_s: 27,
                    ms: 1234,
                },
                A::Command(EStop),
                A::Wait(2),
                A::Command(ClearFault),
                A::Wall {
                    plus: false,
                    ahead_um: 2928,
                },
                A::Repair,
            ],
        ),
        (
            "SR-1: a link resting against its stop where homing put it, the safety relay \
             opening: the stop's contact flag came back with no motion (joint 4 at its stop \
             in Fault)",
            Start::Homing,
            vec![
                A::Stream {
                    x_mm: -15,
                    z_mm: -3,
                    speed_mm_s: 18,
                    ms: 1001,
                },
                A::Stream {
                    x_mm: 15,
                    z_mm: 0,
                    speed_mm_s: 13,
                    ms: 1471,
                },
                A::Wait(277),
                A::Command(Hello),
                A::Command(Hello),
                A::Wait(206),
                A::Stream {
                    x_mm: -8,
                    z_mm: -5,
                    speed_mm_s: 10,
                    ms: 59,
                },
                A::Wait(363),
                A::Command(Hello),
                A::Command(ClearFault),
                A::Command(StoreGeometry),
                A::Push {
                    plus: true,
                    depth_um: 380,
                },
                A::Stream {
                    x_mm: 13,
                    z_mm: 4,
                    speed_mm_s: 6,
                    ms: 983,
                },
                A::Wait(248),
                A::Wall {
                    plus: false,
                    ahead_um: 2219,
                },
                A::Stream {
                    x_mm: 9,
                    z_mm: -2,
                    speed_mm_s: 13,
                    ms: 888,
                },
                A::Repair,
                A::Wall {
                    plus: true,
                    ahead_um: 1629,
                },
                A::Fault(RelayStuckOpen),
                A::Foreign(ReplayHelloEnable),
                A::Command(AckReset),
            ],
        ),
        (
            "SR-5: a switch forced closed, then forced open in the same instant, was \
             judged closed and undetected (SwitchClosed(2) not detected after 3 ms)",
            Start::Following,
            vec![
                A::Fault(SwitchClosed(2)),
                A::Command(Home { rehome: false }),
                A::Foreign(SecondTarget),
                A::Command(Home { rehome: false }),
                A::Command(Hello),
                A::Fault(TickOverrun),
                A::Fault(SwitchDead(2)),
            ],
        ),
        (
            "SR-5: a bridge stuck on, detected, cleared and not repaired, faulted again at \
             the next Enable: blamed on worn brakes injected since (DriverFault on joint \
             255 after BrakesWorn)",
            Start::Following,
            vec![
                A::Fault(BridgeStuckOn(3)),
                A::Stream {
                    x_mm: 11,
                    z_mm: -4,
                    speed_mm_s: 11,
                    ms: 989,
                },
                A::Wait(382),
                A::Wait(320),
                A::Stream {
                    x_mm: 15,
                    z_mm: -3,
                    speed_mm_s: 7,
                    ms: 505,
                },
                A::Command(AckReset),
                A::Command(ClearFault),
                A::Foreign(Replay { back: 25 }),
                A::Jog {
                    joint: 1,
                    velocity: -5,
                    ms: 31,
                },
                A::Command(Clutch(true)),
                A::Wall {
                    plus: true,
                    ahead_um: 1411,
                },
                A::Jog {
                    joint: 4,
                    velocity: 0,
                    ms: 450,
                },
                A::Stream {
                    x_mm: 9,
                    z_mm: 1,
                    speed_mm_s: 30,
                    ms: 1362,
                },
                A::Command(AckReset),
                A::Command(ClearFault),
                A::Fault(BrakesWorn),
                A::Command(StoreGeometry),
                A::Foreign(SecondTarget),
                A::Stream {
                    x_mm: 13,
                    z_mm: 0,
                    speed_mm_s: 27,
                    ms: 246,
                },
                A::Command(AckReset),
                A::Command(Enable),
                A::Wait(133),
                A::Fault(SupplySag),
            ],
        ),
        (
            "SR-5: a link's winding shorted during homing, at a small duty, is named \
             EncoderDead on its joint (after MotorShorted(2) + Overcurrent(4))",
            Start::Homing,
            vec![
                A::Wait(107),
                A::Wait(289),
                A::Command(ClearFault),
                A::Command(Clutch(false)),
                A::Stream {
                    x_mm: -13,
                    z_mm: 4,
                    speed_mm_s: 4,
                    ms: 712,
                },
                A::Wall {
                    plus: false,
                    ahead_um: 2182,
                },
                A::Wall {
                    plus: true,
                    ahead_um: 1051,
                },
                A::Fault(MotorShorted(2)),
                A::Command(Home { rehome: false }),
                A::Jog {
                    joint: 3,
                    velocity: -10,
                    ms: 358,
                },
                A::Fault(Overcurrent(4)),
                A::Stream {
                    x_mm: -12,
                    z_mm: -4,
                    speed_mm_s: 3,
                    ms: 1082,
                },
                A::Repair,
                A::Fault(TickOverrun),
                A::Wait(325),
                A::Stream {
                    x_mm: 8,
                    z_mm: -5,
                    speed_mm_s: 17,
                    ms: 972,
                },
                A::Fault(EncoderJump(5)),
                A::Stream {
                    x_mm: 10,
                    z_mm: 4,
                    speed_mm_s: 2,
                    ms: 198,
                },
                A::Fault(MotorShorted(5)),
                A::Command(Enable),
                A::Fault(EncoderDead(1)),
            ],
        ),
        (
            "SR-5: a link's motor leads opening are named EncoderDead (after Overcurrent(2) \
             + MotorOpen(5))",
            Start::Following,
            vec![
                A::Fault(Overcurrent(2)),
                A::Fault(MotorOpen(5)),
                A::Jog {
                    joint: 0,
                    velocity: -20,
                    ms: 420,
                },
            ],
        ),
        (
            "SR-5: a link's motor leads opening, then a dead switch, are named EncoderDead \
             (after MotorOpen(4))",
            Start::Following,
            vec![
                A::Command(Enable),
                A::Fault(MotorOpen(4)),
                A::Foreign(FutureTarget { ahead_ms: 2208 }),
                A::Wall {
                    plus: true,
                    ahead_um: 2641,
                },
                A::Command(Clutch(false)),
                A::Stream {
                    x_mm: 9,
                    z_mm: 4,
                    speed_mm_s: 7,
                    ms: 755,
                },
                A::Button(false),
                A::Wait(243),
                A::Wait(198),
                A::Command(Disable),
                A::Push {
                    plus: false,
                    depth_um: 219,
                },
                A::Fault(SwitchDead(2)),
                A::Foreign(ReplayHelloEnable),
                A::Wall {
                    plus: true,
                    ahead_um: 1333,
                },
            ],
        ),
        (
            "SR-5: a leg's encoder stuck while homing with the tool is named MotorOpen \
             (after EncoderStuck(0))",
            Start::Homing,
            vec![
                A::Wait(155),
                A::Wait(366),
                A::Tool(true),
                A::Stream {
                    x_mm: 13,
                    z_mm: -1,
                    speed_mm_s: 30,
                    ms: 15,
                },
                A::Silence(96),
                A::Command(Home { rehome: false }),
                A::Wait(370),
                A::Push {
                    plus: false,
                    depth_um: 82,
                },
                A::Fault(EncoderStuck(0)),
            ],
        ),
        (
            "SR-5: a link's dead encoder is named CurrentImplausible (after EncoderDead(3))",
            Start::Homing,
            vec![
                A::Push {
                    plus: false,
                    depth_um: 118,
                },
                A::Command(Operator(true)),
                A::Fault(EncoderDead(3)),
                A::Foreign(SecondCommand(Enable)),
                A::Wait(343),
                A::Stream {
                    x_mm: -3,
                    z_mm: 2,
                    speed_mm_s: 24,
                    ms: 1431,
                },
                A::Stream {
                    x_mm: -9,
                    z_mm: 4,
                    speed_mm_s: 4,
                    ms: 186,
                },
                A::Stream {
                    x_mm: 13,
                    z_mm: 0,
                    speed_mm_s: 28,
                    ms: 1188,
                },
                A::Jog {
                    joint: 3,
                    velocity: 23,
                    ms: 166,
                },
                A::Stream {
                    x_mm: -2,
                    z_mm: 5,
                    speed_mm_s: 6,
                    ms: 1277,
                },
                A::Push {
                    plus: true,
                    depth_um: 128,
                },
                A::Wait(52),
                A::Wait(328),
                A::Jog {
                    joint: 1,
                    velocity: 30,
                    ms: 114,
                },
            ],
        ),
        (
            "SR-5: a leg's encoder losing one count in three is named MotorOpen (after \
             EncoderLosesCounts(1))",
            Start::Following,
            vec![
                A::Foreign(StampedMax),
                A::Tool(true),
                A::Foreign(StampedMax),
                A::Wall {
                    plus: true,
                    ahead_um: 2863,
                },
                A::Command(Enable),
                A::Fault(EncoderLosesCounts(1)),
                A::Wait(111),
                A::Wait(265),
                A::Stream {
                    x_mm: 6,
                    z_mm: 5,
                    speed_mm_s: 3,
                    ms: 484,
                },
                A::Command(Hello),
                A::Wait(154),
                A::Wait(335),
                A::Stream {
                    x_mm: 6,
                    z_mm: -5,
                    speed_mm_s: 23,
                    ms: 901,
                },
                A::Command(Disable),
                A::Repair,
                A::Jog {
                    joint: 1,
                    velocity: 8,
                    ms: 346,
                },
            ],
        ),
        (
            "SR-5: a short (Overcurrent(2)) on leg joint 2 holding against a seized joint 3 drew \
             0.17 to 0.27 A, over a twentieth of its peak current on 51 scattered ticks of \
             630 ms, its filtered current never at the twentieth the board judges from: \
             judged a detection 1 ms late; it shows from a tenth (every such sample is judged)",
            Start::Following,
            vec![
                A::Fault(LoadSeized(3)),
                A::Wait(139),
                A::Fault(Overcurrent(2)),
                A::Stream {
                    x_mm: -5,
                    z_mm: 1,
                    speed_mm_s: 7,
                    ms: 808,
                },
                A::Foreign(SecondTarget),
                A::Wall {
                    plus: true,
                    ahead_um: 953,
                },
                A::Command(ClearFault),
                A::Foreign(FutureTarget { ahead_ms: 730 }),
                A::Wait(8),
                A::Foreign(FutureTarget { ahead_ms: 2088 }),
                A::Jog {
                    joint: 1,
                    velocity: -9,
                    ms: 267,
                },
                A::Stream {
                    x_mm: 0,
                    z_mm: 5,
                    speed_mm_s: 24,
                    ms: 1069,
                },
            ],
        ),
        (
            "SR-2, SR-7: an STO (DriverFault(5)) with the tool on, its brakes worn to a fifth \
             since the brake check that enabled the board, coasted 0.768 mm against v t_e, \
             0.751 mm: the distance rests on brakes that passed the check; worn ones are the \
             next enable's brake check's \
             (brakes_worn_since_the_last_enable_fail_the_next_brake_check)",
            Start::Following,
            vec![
                A::Tool(true),
                A::Stream {
                    x_mm: -11,
                    z_mm: 2,
                    speed_mm_s: 29,
                    ms: 391,
                },
                A::Repair,
                A::Fault(Overcurrent(1)),
                A::Fault(BrakesWorn),
                A::Fault(DriverFault(5)),
            ],
        ),
        (
            "SR-5: a welded safety relay shown twice, 18 ms with the button pressed, then \
             21 ms from the next press to its detection (the chain's debounce restarts when \
             the button and the relay agree), was judged as 24 ms of showing against 23 ms",
            Start::Following,
            vec![
                A::Fault(RelayWelded),
                A::Command(Disable),
                A::Wait(18),
                A::Button(false),
                A::Foreign(ReplayHelloEnable),
                A::Command(StoreGeometry),
                A::Wait(384),
                A::Command(Operator(true)),
                A::Command(Hello),
                A::Wait(244),
                A::Wait(353),
                A::Jog {
                    joint: 3,
                    velocity: -9,
                    ms: 363,
                },
                A::Button(true),
                A::Push {
                    plus: true,
                    depth_um: 120,
                },
                A::Wait(323),
                A::Foreign(Replay { back: 39 }),
                A::Fault(MotorOpen(4)),
                A::Wait(226),
            ],
        ),
        (
            "SR-1: homing swept link joint 3 towards its hard stop at 0.435 rad/s when a \
             supply sag's STO cut the torque; the link coasted the last 2.7 mrad onto the \
             stop at 0.35 rad/s, in Fault: the homing's own contact, slower",
            Start::Homing,
            vec![
                A::Stream {
                    x_mm: -2,
                    z_mm: 1,
                    speed_mm_s: 15,
                    ms: 578,
                },
                A::Foreign(StampedMax),
                A::Stream {
                    x_mm: -11,
                    z_mm: 0,
                    speed_mm_s: 19,
                    ms: 1209,
                },
                A::Stream {
                    x_mm: 15,
                    z_mm: 0,
                    speed_mm_s: 24,
                    ms: 1262,
                },
                A::Wait(14),
                A::Foreign(ReplayHelloEnable),
                A::Stream {
                    x_mm: -2,
                    z_mm: 5,
                    speed_mm_s: 18,
                    ms: 26,
                },
                A::Command(Status),
                A::Foreign(Replay { back: 15 }),
                A::Stream {
                    x_mm: -13,
                    z_mm: -4,
                    speed_mm_s: 8,
                    ms: 1061,
                },
                A::Foreign(FutureTarget { ahead_ms: 898 }),
                A::Jog {
                    joint: 4,
                    velocity: 0,
                    ms: 480,
                },
                A::Fault(SupplySag),
                A::Command(Clutch(true)),
                A::Wait(200),
            ],
        ),
    ];
    replay(&cases, &[]);
}

/// The counterexamples the search found, each replayed: the holes fixed hold now, the
/// holes still open show as such (covered by [`OPEN`], printed) until their work lands.
/// (SR-1 .. SR-7: each case names the requirement it broke.)
#[test]
fn counterexamples_found_once_hold_now() {
    use Action as A;
    let stream = |x_mm, speed_mm_s, ms| A::Stream {
        x_mm,
        z_mm: 0,
        speed_mm_s,
        ms,
    };
    let hold = [A::Command(Cmd::Clutch(true)), A::Wait(200)];
    let cases: Vec<(&str, Start, Vec<Action>)> = vec![
        (
            "SR-3: StoreGeometry during the SS1 of a Disable was taken",
            Start::Following,
            vec![
                stream(10, 25, 400),
                A::Command(Cmd::Disable),
                A::Wait(5),
                A::Command(Cmd::StoreGeometry),
                A::Wait(400),
            ],
        ),
        (
            "SR-4: ClearFault with the safety relay welded re-enabled the drives",
            Start::Following,
            vec![
                A::Fault(Injection::RelayWelded),
                A::Wait(100),
                A::Button(false),
                A::Wait(50),
                A::Command(Cmd::ClearFault),
                A::Wait(10),
                A::Command(Cmd::Operator(true)),
                A::Command(Cmd::Enable),
                A::Wait(300),
            ],
        ),
        (
            "SR-6: a second master's Hello during a hold took the board and moved it",
            Start::Following,
            [
                &hold[..],
                &[
                    A::Foreign(Foreign::SecondHello),
                    A::Wait(10),
                    A::Foreign(Foreign::SecondCommand(Cmd::Clutch(false))),
                    A::Foreign(Foreign::SecondTarget),
                    A::Wait(300),
                ],
            ]
            .concat(),
        ),
        (
            "SR-6: the owner's Hello and Enable replayed enabled the robot",
            Start::Following,
            vec![
                A::Command(Cmd::Disable),
                A::Wait(400),
                A::Foreign(Foreign::ReplayHelloEnable),
                A::Wait(300),
            ],
        ),
        (
            "SR-6: a former owner's Hello replayed after a second master took over took the \
             board back",
            Start::Fresh,
            vec![
                A::Foreign(Foreign::SecondHello),
                A::Wait(10),
                A::Foreign(Foreign::ReplayHelloEnable),
                A::Wait(300),
            ],
        ),
        (
            "SR-5: a leg's encoder dying 129 ms into homing was named MotorOpen (the motor \
             turning faster than its encoder said drew less than the model's current)",
            Start::Homing,
            vec![
                A::Wait(129),
                A::Fault(Injection::EncoderDead(0)),
                A::Wait(2_000),
            ],
        ),
        (
            "SR-6: the owner's Home queued in the tick a second master's Hello took the \
             board was taken from the displaced owner",
            Start::Ready,
            vec![
                A::Foreign(Foreign::SecondHello),
                A::Command(Cmd::Home { rehome: true }),
                A::Wait(300),
            ],
        ),
        (
            "SR-6: a frame 30 000 ahead in the owner's sequence locked the owner out",
            Start::Following,
            vec![
                A::Foreign(Foreign::FarAhead(Cmd::Status)),
                A::Wait(10),
                A::Command(Cmd::Status),
                A::Wait(300),
            ],
        ),
        (
            "SR-6: a target stamped u64::MAX made the owner's targets stale",
            Start::Following,
            vec![A::Foreign(Foreign::StampedMax), stream(5, 10, 300)],
        ),
        (
            "SR-1: a leg's home switch failed closed drove the leg out of its range",
            Start::Homing,
            vec![A::Fault(Injection::SwitchClosed(1)), A::Wait(4_000)],
        ),
        (
            "SR-3: Home during the SS1 of a Disable ended the stop and homed under power",
            Start::Following,
            vec![
                stream(10, 25, 400),
                A::Command(Cmd::Disable),
                A::Wait(5),
                A::Command(Cmd::Home { rehome: true }),
                A::Wait(400),
            ],
        ),
        (
            "SR-1: a leg's dead home switch drove the leg through its travel while homing",
            Start::Homing,
            vec![A::Fault(Injection::SwitchDead(1)), A::Wait(4_000)],
        ),
        (
            "SR-5: the safety relay opening while the robot moves was named MotorOpen (the \
             drives had lost their supply; the monitors judged the motors)",
            Start::Following,
            vec![
                stream(6, 10, 200),
                A::Fault(Injection::RelayStuckOpen),
                stream(12, 10, 300),
            ],
        ),
        (
            "SR-5: three overruns in a row across the 100-tick boundary of the overrun count \
             were never a missed deadline (the count restarted every 100 ticks)",
            Start::Following,
            vec![A::Wait(7), A::Fault(Injection::TickOverrun), A::Wait(10)],
        ),
        (
            "SR-5: a link's open motor at a small duty is named EncoderDead (the back-EMF \
             check believes a circuit that drew current in the last 100 ticks: the samples \
             of a dead encoder)",
            Start::Following,
            vec![A::Fault(Injection::MotorOpen(5)), stream(11, 14, 700)],
        ),
        (
            "SR-5: an encoder losing one count in three is named MotorOpen (its motor turns \
             freely under the open-circuit floor: the samples of an open circuit)",
            Start::Following,
            vec![
                A::Fault(Injection::EncoderLosesCounts(0)),
                stream(0, 1, 40),
                stream(5, 10, 400),
            ],
        ),
        (
            "SR-5: a short without current regulation (Overcurrent(2)) during the brake \
             check pushed leg joint 2 through its applied brake, named BrakeCheck: the check \
             knows the current its duty drives and names the short when thrice that flows",
            Start::Following,
            vec![
                A::Command(Cmd::Disable),
                A::Wait(358),
                A::Command(Cmd::Enable),
                A::Repair,
                A::Command(Cmd::StoreGeometry),
                A::Repair,
                A::Fault(Injection::Overcurrent(2)),
                A::Stream {
                    x_mm: 1,
                    z_mm: -4,
                    speed_mm_s: 5,
                    ms: 551,
                },
            ],
        ),
        (
            "SR-3: the e-stop button's latch, the owner's ClearFault and Home { rehome } \
             answered in one tick during a hold (SOS): the ClearFault, sent before the \
             owner could know of the stop, ended the STO and the Home started homing under \
             power",
            Start::Following,
            {
                use Cmd::*;
                use Foreign::*;
                use Injection::*;
                vec![
                    A::Fault(EncoderLosesCounts(1)),
                    A::Push {
                        plus: true,
                        depth_um: 136,
                    },
                    A::Command(Status),
                    A::Foreign(FarAhead(Status)),
                    A::Silence(465),
                    A::Wait(0),
                    A::Button(true),
                    A::Command(ClearFault),
                    A::Command(Home { rehome: true }),
                    A::Repair,
                    A::Fault(RelayStuckOpen),
                    A::Push {
                        plus: false,
                        depth_um: 293,
                    },
                    A::Fault(SwitchDead(2)),
                    A::Command(AckReset),
                    A::Push {
                        plus: true,
                        depth_um: 239,
                    },
                    A::Button(false),
                    A::Jog {
                        joint: 5,
                        velocity: 25,
                        ms: 565,
                    },
                    A::Foreign(StampedMax),
                ]
            },
        ),
        (
            "SR-3: the e-stop button pressed and released during a hold, the owner's \
             ClearFault and Home { rehome } answered in the tick that latched it",
            Start::Following,
            vec![
                A::Silence(200),
                A::Button(true),
                A::Button(false),
                A::Command(Cmd::ClearFault),
                A::Command(Cmd::Home { rehome: true }),
                A::Wait(300),
            ],
        ),
    ];
    replay(&cases, OPEN);
}

/// SR-5, and the premise of SR-2's STO distance: brakes that wear to a fifth of their
/// holding while the board is enabled are found by the brake check of the next enable,
/// within its time (100 ms of enabling): the board latches `BrakeCheck` and never reaches
/// `Enabled` with them.
#[test]
fn brakes_worn_since_the_last_enable_fail_the_next_brake_check() {
    use faults::search::World;
    use master_link::{FaultCause, RobotState};
    let mut w = World::at(Start::Following).expect("the board follows");
    let mut states = Vec::new();
    for a in [
        Action::Fault(Injection::BrakesWorn),
        Action::Wait(50),
        Action::Command(Cmd::Disable),
        Action::Wait(300),
        Action::Command(Cmd::Enable),
    ] {
        w.act(&a).expect("the case runs");
    }
    let enabled_at = w.now_us();
    let mut found_at = None;
    for _ in 0..600 {
        w.tick(true).expect("the board ticks");
        let s = w.board.runtime().status();
        if states.last() != Some(&s.state) {
            states.push(s.state);
        }
        if found_at.is_none() && s.fault.cause == FaultCause::BrakeCheck {
            found_at = Some(w.now_us());
        }
    }
    let found_at = found_at.unwrap_or_else(|| panic!("no BrakeCheck; states {states:?}"));
    assert!(
        found_at - enabled_at <= 100_000,
        "BrakeCheck {} ms after the Enable",
        (found_at - enabled_at) / 1000
    );
    assert!(
        !states.contains(&RobotState::Enabled),
        "the board enabled with worn brakes"
    );
    assert!(
        w.oracle.violations().is_empty(),
        "{:?}",
        w.oracle.violations()
    );
}

/// Counterexamples of the searches from homing whose causes were the board's or the
/// plant's, replayed
/// with no hole tolerated. (SR-5: each case names the requirement it
/// broke.)
#[test]
fn counterexamples_from_homing_hold_now() {
    use Action as A;
    use Cmd::*;
    use Foreign::*;
    use Injection::*;
    let stream = |x_mm, z_mm, speed_mm_s, ms| A::Stream {
        x_mm,
        z_mm,
        speed_mm_s,
        ms,
    };
    let cases: Vec<(&str, Start, Vec<Action>)> = vec![
        (
            "SR-5: a Disable while l1 backed off its home switch latched LimitSwitch on \
             joint 0 (the switch where the homing had just referenced the leg), then no \
             ClearFault could end it (after EncoderDead(3) + EncoderDead(4))",
            Start::Homing,
            vec![
                stream(0, 3, 10, 824),
                A::Wait(297),
                A::Fault(EncoderDead(3)),
                A::Foreign(FarAhead(Home { rehome: true })),
                A::Wait(187),
                A::Fault(EncoderDead(4)),
                A::Command(Disable),
                A::Jog {
                    joint: 0,
                    velocity: 2,
                    ms: 550,
                },
                stream(-11, -2, 15, 1408),
                stream(13, 0, 20, 153),
                A::Wait(210),
                A::Wait(109),
                stream(5, -1, 20, 1450),
                A::Silence(104),
            ],
        ),
        (
            "SR-5: a switch failed closed (SwitchClosed(3)) on joint 3 (a link) resting at \
             its home position after a Disable stopped the homing reads as the link on its \
             switch, which the board rightly takes for no limit before the references; the \
             oracle judged it undetected after 3 ms",
            Start::Homing,
            vec![
                A::Foreign(Replay { back: 22 }),
                A::Jog {
                    joint: 4,
                    velocity: 21,
                    ms: 533,
                },
                stream(5, 0, 21, 749),
                stream(1, -4, 19, 640),
                stream(15, 4, 11, 1023),
                A::Wait(271),
                A::Repair,
                A::Command(Clutch(false)),
                A::Wait(125),
                A::Command(AckReset),
                stream(11, -3, 25, 1152),
                A::Command(StoreGeometry),
                A::Wait(31),
                A::Command(Status),
                A::Wait(157),
                A::Command(Disable),
                A::Fault(SwitchClosed(3)),
                A::Button(true),
                A::Foreign(StampedMax),
            ],
        ),
        (
            "SR-5: l1 backing off its switch was named EncoderDead on joint 0 (after \
             MotorOpen(2)): the plant's motor landed on the flank of a load its stiction \
             held and kept the velocity of its free step, drawing the current of a turning \
             motor with a still encoder",
            Start::Homing,
            vec![
                stream(-4, 3, 8, 309),
                A::Command(Clutch(false)),
                stream(1, -5, 16, 487),
                A::Wall {
                    plus: true,
                    ahead_um: 2254,
                },
                A::Wait(242),
                A::Fault(MotorOpen(2)),
                A::Command(Operator(false)),
                stream(-15, 5, 17, 447),
                A::Fault(MotorOpen(2)),
                stream(-12, -3, 13, 973),
                stream(12, -3, 11, 1434),
                A::Foreign(SecondTarget),
                A::Command(Disable),
                A::Fault(SupplySag),
                A::Fault(BridgeStuckOn(3)),
                A::Foreign(ReplayHelloEnable),
                A::Fault(SwitchClosed(4)),
                A::Foreign(FarAhead(Home { rehome: true })),
                A::Command(Enable),
                A::Command(ClearFault),
                A::Wait(52),
            ],
        ),
    ];
    replay(&cases, &[]);
}
