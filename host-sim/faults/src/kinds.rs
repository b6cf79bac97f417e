//! The fault kinds of the campaign: how each is injected, what the board must notice, by
//! when, and how it must react.

use control::stops::{reaction, StopCategory, StopEvent};
use master_link::{FaultCause, MasterToBoard, NackReason};
use plant::Fault;
use simulation::bench::{frame_in, Bench};
use simulation::board::Wall;

/// A fault kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FaultKind {
    /// A leg's encoder counter freezes (a cut cable).
    EncoderStuck,
    /// A leg's encoder counter jumps by 1 000 counts (noise on the A/B lines).
    EncoderJump,
    /// A link's encoder counts one edge in ten (a failing sensor, a dirty disc).
    EncoderDead,
    /// A leg's motor leads open (a broken connector).
    MotorOpen,
    /// A link's motor terminals short.
    MotorShorted,
    /// A driver reports a fault of its own (over-temperature).
    DriverFault,
    /// The bridges' supply sags to 16 V.
    SupplySag,
    /// A leg's winding shorts (a twentieth of its resistance left) and its driver's
    /// current regulation has failed: the current per duty is seven times the model's.
    Overcurrent,
    /// A transistor of a leg's bridge fails short: the full supply on the motor, no
    /// current regulation (the driver's own overcurrent protection must trip).
    BridgeStuckOn,
    /// The master's link goes silent (a cut cable).
    LinkLoss,
    /// 300 bytes of noise on the link.
    GarbageBurst,
    /// Frames of the master replayed (an old target, an old Enable).
    ReplayedFrames,
    /// The e-stop button.
    EStop,
    /// The e-stop button with the safety relay's contacts welded.
    RelayWelded,
    /// Three control ticks overrun their period (a stuck bus, a runaway loop).
    TickOverrun,
    /// A target with a NaN coordinate.
    NanTarget,
    /// A target 50 mm outside the task box.
    UnreachableTarget,
    /// A leg's limit switch fails closed while running.
    LimitSwitchClosed,
    /// A link's load side seizes (a collision, a jam): theta2, which every streamed
    /// motion moves.
    LoadSeized,
    /// A stiff wall (100 N/mm) across the platform's path.
    WallContact,
    /// A leg's home switch is dead while homing (never closes).
    HomingSwitchDead,
    /// The brakes hold nothing at the enable's brake check.
    BrakeWeak,
}

/// How the board notices a fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Detection {
    /// A fault with one of these causes is logged (on the joint, if given).
    Cause(&'static [FaultCause], Option<u8>),
    /// The request is refused with one of these reasons.
    Nack(&'static [NackReason]),
    /// The link counters count the bad frames (and nothing reaches the runtime).
    Counted,
    /// The robot holds (the heartbeat's hold) before the heartbeat fault.
    HeartbeatHold,
}

/// What the board must do once it noticed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reaction {
    /// The stop of the stop table for the cause.
    Stop(StopCategory),
    /// Nothing: it keeps doing what it did (the bad input is dropped or refused).
    Continue,
}

impl Reaction {
    /// The name in the matrix.
    pub fn name(&self) -> &'static str {
        match self {
            Reaction::Stop(StopCategory::Sto) => "STO",
            Reaction::Stop(StopCategory::Ss1) => "SS1",
            Reaction::Stop(StopCategory::Ss2) => "SS2",
            Reaction::Continue => "continue",
        }
    }
}

/// The state the kind is injected in, when it is not one of the running conditions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Only {
    /// While homing.
    Homing,
    /// At the enable.
    Enabling,
}

/// What the campaign expects of a kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expectation {
    /// How the board notices it.
    pub detection: Detection,
    /// Latest detection, ms after the injection (or after the probe motion starts, for a
    /// fault that only shows in motion).
    pub bound_ms: u64,
    /// The reaction.
    pub reaction: Reaction,
    /// The fault only shows while the joint works: in a holding condition (and moving
    /// slowly) the master starts a probe after the injection.
    pub needs_motion: bool,
    /// The probe: a drift at 2.5 mm/s (None), or a step of this many mm (a demand for
    /// current: the supervisor takes it at its acceleration limit).
    pub probe_step_mm: Option<f64>,
    /// Timed from when the fault shows: the first tick joint `.0`'s current exceeds the
    /// fraction `.1` of its peak (a latent fault: a short shows once current flows).
    pub shows_at_current: Option<(usize, f64)>,
    /// The kind applies to this phase only (the running conditions are not applicable).
    pub only: Option<Only>,
}

/// What an encoder that no longer follows its joint is logged as: the back-EMF check, the
/// following error, or no motion under drive.
const ENCODER_LOST: &[FaultCause] = &[
    FaultCause::EncoderDead,
    FaultCause::FollowingError,
    FaultCause::NoMotion,
];

/// A fault the board logs with one of `causes` (on `joint`, if given) within `bound_ms`,
/// stopped as the stop table says for the first of them.
const fn logged(
    causes: &'static [FaultCause],
    joint: Option<u8>,
    bound_ms: u64,
    needs_motion: bool,
) -> Expectation {
    e(
        Detection::Cause(causes, joint),
        bound_ms,
        stop_of(causes[0]),
        needs_motion,
    )
}

const fn e(
    detection: Detection,
    bound_ms: u64,
    reaction: Reaction,
    needs_motion: bool,
) -> Expectation {
    Expectation {
        detection,
        bound_ms,
        reaction,
        needs_motion,
        probe_step_mm: None,
        shows_at_current: None,
        only: None,
    }
}

/// A request refused with one of `reasons` within `bound_ms`; the board goes on.
const fn refused(reasons: &'static [NackReason], bound_ms: u64) -> Expectation {
    e(
        Detection::Nack(reasons),
        bound_ms,
        Reaction::Continue,
        false,
    )
}

/// Bad frames counted by the link within `bound_ms`; the board goes on.
const fn counted(bound_ms: u64) -> Expectation {
    e(Detection::Counted, bound_ms, Reaction::Continue, false)
}

const fn stop_of(c: FaultCause) -> Reaction {
    Reaction::Stop(reaction(StopEvent::Fault(c)).category)
}

impl FaultKind {
    /// Every kind, in the matrix's order.
    pub const ALL: [FaultKind; 22] = [
        FaultKind::EncoderStuck,
        FaultKind::EncoderJump,
        FaultKind::EncoderDead,
        FaultKind::MotorOpen,
        FaultKind::MotorShorted,
        FaultKind::DriverFault,
        FaultKind::SupplySag,
        FaultKind::Overcurrent,
        FaultKind::BridgeStuckOn,
        FaultKind::LinkLoss,
        FaultKind::GarbageBurst,
        FaultKind::ReplayedFrames,
        FaultKind::EStop,
        FaultKind::RelayWelded,
        FaultKind::TickOverrun,
        FaultKind::NanTarget,
        FaultKind::UnreachableTarget,
        FaultKind::LimitSwitchClosed,
        FaultKind::LoadSeized,
        FaultKind::WallContact,
        FaultKind::HomingSwitchDead,
        FaultKind::BrakeWeak,
    ];

    /// The kind's name (the matrix's rows, the command line's `--kinds`).
    pub const fn name(self) -> &'static str {
        match self {
            FaultKind::EncoderStuck => "encoder-stuck",
            FaultKind::EncoderJump => "encoder-jump",
            FaultKind::EncoderDead => "encoder-dead",
            FaultKind::MotorOpen => "motor-open",
            FaultKind::MotorShorted => "motor-shorted",
            FaultKind::DriverFault => "driver-fault",
            FaultKind::SupplySag => "supply-sag",
            FaultKind::Overcurrent => "overcurrent",
            FaultKind::BridgeStuckOn => "bridge-stuck-on",
            FaultKind::LinkLoss => "link-loss",
            FaultKind::GarbageBurst => "garbage-burst",
            FaultKind::ReplayedFrames => "replayed-frames",
            FaultKind::EStop => "e-stop",
            FaultKind::RelayWelded => "relay-welded",
            FaultKind::TickOverrun => "tick-overrun",
            FaultKind::NanTarget => "nan-target",
            FaultKind::UnreachableTarget => "unreachable-target",
            FaultKind::LimitSwitchClosed => "limit-switch-closed",
            FaultKind::LoadSeized => "load-seized",
            FaultKind::WallContact => "wall-contact",
            FaultKind::HomingSwitchDead => "homing-switch-dead",
            FaultKind::BrakeWeak => "brake-weak",
        }
    }

    /// A fault of the robot or the board (not of the link, a target, a phase of its own
    /// or the environment).
    pub fn is_physical(self) -> bool {
        !matches!(
            self,
            FaultKind::LinkLoss
                | FaultKind::GarbageBurst
                | FaultKind::ReplayedFrames
                | FaultKind::NanTarget
                | FaultKind::UnreachableTarget
                | FaultKind::WallContact
                | FaultKind::HomingSwitchDead
                | FaultKind::BrakeWeak
        )
    }

    /// The joint the kind is injected on, if one.
    pub const fn joint(self) -> Option<usize> {
        match self {
            FaultKind::EncoderStuck | FaultKind::DriverFault | FaultKind::HomingSwitchDead => {
                Some(0)
            }
            FaultKind::EncoderJump | FaultKind::Overcurrent | FaultKind::BridgeStuckOn => Some(1),
            FaultKind::MotorOpen | FaultKind::LimitSwitchClosed => Some(2),
            FaultKind::EncoderDead | FaultKind::LoadSeized => Some(4),
            FaultKind::MotorShorted => Some(5),
            _ => None,
        }
    }

    /// The kind of a name.
    pub fn from_name(name: &str) -> Option<FaultKind> {
        FaultKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// What the board must notice, by when, and how it reacts. The bounds: the monitors'
    /// own windows (firmware/control/src/monitors.rs, current.rs, stops.rs) plus one tick.
    pub const fn expectation(self) -> Expectation {
        use FaultCause as C;
        match self {
            // The back-EMF check (5 ticks) or the following-error window.
            FaultKind::EncoderStuck => logged(ENCODER_LOST, Some(0), 100, true),
            FaultKind::EncoderJump => logged(&[C::EncoderJump], Some(1), 2, false),
            FaultKind::EncoderDead => logged(ENCODER_LOST, Some(4), 150, true),
            // The open-circuit check: 5 ticks once the model asks for a current above its
            // floor (in a holding condition, while the probe move starts).
            FaultKind::MotorOpen => logged(&[C::MotorOpen], Some(2), 30, true),
            FaultKind::MotorShorted => logged(&[C::DriverFault], None, 2, true),
            FaultKind::DriverFault => logged(&[C::DriverFault], None, 2, false),
            // 3 ticks out of range.
            FaultKind::SupplySag => logged(&[C::SupplyVoltage], None, 5, false),
            // Five samples of a current three times the model's (or one above 1.5 x the
            // peak), once the servo asks the joint for a current: in a holding condition
            // while the probe move starts.
            // Timed from the first tick the leg draws a twentieth of its peak current
            // (where the check begins to judge: `control::monitors::MotorCheck`), the
            // probe a 3 mm step: the check's 10 counts (two per sample that shows it, one
            // back per sample that does not, none for a sample too small to judge) take 5
            // samples in a row, or a servo hunting through zero for a few ms more, judged
            // on the currents filtered over two ticks; at 25 mm/s the back-EMF carries
            // most of the voltage and the short shows only when the hunting draws three
            // times the model's current. The driver's own overcurrent protection (15 A)
            // stands behind it.
            FaultKind::Overcurrent => Expectation {
                probe_step_mm: Some(3.0),
                shows_at_current: Some((1, 0.05)),
                ..logged(&[C::Overcurrent, C::CurrentImplausible], Some(1), 50, true)
            },
            // The driver's VDS protection latches within microseconds; the next tick
            // reads its fault line.
            FaultKind::BridgeStuckOn => logged(&[C::DriverFault], None, 2, false),
            // The heartbeat's hold time, 100 ms, after the last heartbeat (at most 50 ms
            // before the cut).
            FaultKind::LinkLoss => e(
                Detection::HeartbeatHold,
                102,
                Reaction::Stop(StopCategory::Ss2),
                false,
            ),
            FaultKind::GarbageBurst => counted(2),
            FaultKind::ReplayedFrames => counted(2),
            FaultKind::EStop => logged(&[C::EmergencyStopButton], None, 1, false),
            // The relay's debounce, 20 ticks.
            FaultKind::RelayWelded => logged(&[C::SafetyRelayMismatch], None, 23, false),
            // The third overrun within the window.
            FaultKind::TickOverrun => logged(&[C::DeadlineMissed], None, 3, false),
            FaultKind::NanTarget => refused(&[NackReason::InvalidValue], 2),
            FaultKind::UnreachableTarget => {
                refused(&[NackReason::VelocityLimit, NackReason::OutOfWorkspace], 2)
            }
            FaultKind::LimitSwitchClosed => logged(&[C::LimitSwitch], Some(2), 2, false),
            // The following-error window or no motion under full drive.
            FaultKind::LoadSeized => logged(
                &[C::FollowingError, C::NoMotion, C::Overload],
                Some(4),
                150,
                true,
            ),
            // The overload time, 8 ms, once the current sits at the limit: timed from the
            // start of the sustained overload (the tripping joint's current at 90 % of its
            // peak or more): a sustained overload trips within 10 ms.
            FaultKind::WallContact => logged(&[C::Overload], None, 10, true),
            FaultKind::HomingSwitchDead => Expectation {
                only: Some(Only::Homing),
                ..logged(&[C::HomingFailed], Some(0), 3_000, false)
            },
            FaultKind::BrakeWeak => Expectation {
                only: Some(Only::Enabling),
                ..logged(&[C::BrakeCheck], None, 100, false)
            },
        }
    }

    /// Injects the fault into the bench now; the sequence number of a frame whose reply
    /// tells the detection, if any.
    pub fn inject(self, b: &mut Bench) -> Option<u16> {
        let plant = &mut b.board.hw.plant;
        // (The joints are in range: the injections cannot fail.)
        match self {
            FaultKind::EncoderStuck => {
                let _ = plant.inject(0, Fault::EncoderStuck);
            }
            FaultKind::EncoderJump => {
                let _ = plant.inject(1, Fault::EncoderJump { counts: 1000 });
            }
            FaultKind::EncoderDead => {
                let _ = plant.inject(4, Fault::EncoderCountsOneIn { one_in: 10 });
            }
            FaultKind::MotorOpen => {
                let _ = plant.inject(2, Fault::MotorDisconnected);
            }
            FaultKind::MotorShorted => {
                let _ = plant.inject(5, Fault::MotorShorted);
            }
            FaultKind::DriverFault => {
                let _ = plant.inject(0, Fault::DriverFailed);
            }
            FaultKind::SupplySag => {
                let _ = plant.set_supply_voltage(16.0);
            }
            FaultKind::Overcurrent => {
                let _ = plant.inject(1, Fault::CurrentRegulationLost);
                let _ = plant.inject(
                    1,
                    Fault::WindingShort {
                        resistance_ratio: 0.01,
                    },
                );
            }
            FaultKind::BridgeStuckOn => {
                let _ = plant.inject(1, Fault::BridgeStuckOn);
            }
            FaultKind::LinkLoss => b.link_up = false,
            FaultKind::GarbageBurst => b.send_raw(&noise()),
            FaultKind::ReplayedFrames => replay_old_frames(b),
            FaultKind::EStop => b.board.press_estop(true),
            FaultKind::RelayWelded => {
                b.board.hw.relay_welded = true;
                b.board.press_estop(true);
            }
            FaultKind::TickOverrun => b.board.overrun_next_ticks(3, 950),
            FaultKind::NanTarget => return Some(send_target_now(b, [0.0, f32::NAN, 0.160])),
            FaultKind::UnreachableTarget => return Some(send_target_now(b, [0.070, 0.0, 0.160])),
            FaultKind::LimitSwitchClosed => b.board.hw.switch_forced[2] = Some(true),
            FaultKind::LoadSeized => {
                let _ = plant.inject(4, Fault::LoadSeized);
            }
            FaultKind::WallContact => {
                let wall = wall_ahead(b);
                b.board.set_wall(Some(wall));
            }
            FaultKind::HomingSwitchDead => b.board.hw.switch_forced[0] = Some(false),
            FaultKind::BrakeWeak => {
                // (Applied before the enable: see the campaign's Enabling phase.)
            }
        }
        None
    }
}

/// 300 bytes of noise, a delimiter now and then: several malformed frames.
fn noise() -> Vec<u8> {
    let mut x: u32 = 0x9e37_79b9;
    (0..300)
        .map(|k| {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            if k % 97 == 96 {
                0
            } else {
                ((x >> 24) as u8).max(1)
            }
        })
        .collect()
}

/// Sends an old Enable and an old target, with stale sequence numbers.
fn replay_old_frames(b: &mut Bench) {
    let old = b.master.next_seq().wrapping_sub(30);
    let session = b.master.session;
    b.send_raw(&frame_in(&MasterToBoard::Enable, session, old));
    let target = MasterToBoard::PoseTarget {
        timestamp_us: 1,
        position_m: [0.010, 0.0, 0.165],
        rotation_vector_rad: [0.0; 3],
    };
    b.send_raw(&frame_in(&target, session, old.wrapping_add(1)));
}

/// Sends a target at `position_m` (no rotation) stamped now; its sequence number.
fn send_target_now(b: &mut Bench, position_m: [f32; 3]) -> u16 {
    let t = b.now_us();
    b.send(&MasterToBoard::PoseTarget {
        timestamp_us: t,
        position_m,
        rotation_vector_rad: [0.0; 3],
    })
}

/// A stiff wall across the path, 1 mm ahead of the platform in the direction it moves
/// (or will move: the probe goes +x).
fn wall_ahead(b: &Bench) -> Wall {
    let p = b.board.truth().pose.t;
    let v = b.board.truth().velocity;
    let dir = if v.x < 0.0 { -1.0 } else { 1.0 };
    Wall {
        point: nalgebra::Vector3::new(p.x + dir * 0.001, 0.0, 0.0),
        normal: nalgebra::Vector3::new(-dir, 0.0, 0.0),
        stiffness_n_per_m: 1e5,
        damping_n_s_per_m: 200.0,
    }
}
