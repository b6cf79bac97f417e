//! The faults the search injects, on any joint where the fault has one, and what the
//! board must make of each (SR-5): the causes that name it, the cause whose bit must be
//! latched in time, the time, and when the fault shows (a fault that needs motion or
//! torque cannot be seen without them).

use master_link::FaultCause;
use plant::Fault;
use simulation::board::BoardSim;

/// An injected fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Injection {
    /// The joint's encoder counter freezes.
    EncoderStuck(u8),
    /// The joint's encoder jumps by 1 000 counts once.
    EncoderJump(u8),
    /// The joint's encoder keeps one count in ten.
    EncoderDead(u8),
    /// The joint's encoder loses one count in three.
    EncoderLosesCounts(u8),
    /// The joint's motor leads open.
    MotorOpen(u8),
    /// The joint's motor terminals short.
    MotorShorted(u8),
    /// The joint's driver reports a fault of its own.
    DriverFault(u8),
    /// The bridges' supply sags to 16 V.
    SupplySag,
    /// The joint's winding shorts and its current regulation fails.
    Overcurrent(u8),
    /// A transistor of the joint's bridge fails short.
    BridgeStuckOn(u8),
    /// The safety relay's contacts weld, and the button is pressed.
    RelayWelded,
    /// The safety relay opens without the button.
    RelayStuckOpen,
    /// Three ticks overrun their period.
    TickOverrun,
    /// The joint's switch fails closed (actuated).
    SwitchClosed(u8),
    /// The joint's switch fails open (never actuated: a dead home switch).
    SwitchDead(u8),
    /// The joint's load side seizes.
    LoadSeized(u8),
    /// Every brake's lining is worn to a fifth of its holding torque: it still holds the
    /// platform and the tool (the legs' brakes 44 N), not the brake check's push (30 % of
    /// the rating). A brake that holds nothing while the drives are off drops the
    /// platform whatever the board does: no requirement can hold then.
    BrakesWorn,
}

/// When a fault can be seen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shows {
    /// At once.
    Always,
    /// While the drives are on.
    Torque,
    /// While the joint moves at least at this speed (m/s or rad/s) under torque.
    Moving(usize, f64),
    /// While the joint draws at least this fraction of its peak current.
    Current(usize, f64),
    /// While the joint's bridge drives its motor (a duty, the drivers powered).
    Driven(usize),
    /// Outside homing.
    NotHoming,
    /// Joint's switch forced closed: outside homing, where the switch is implausible (the
    /// robot homed, or the joint truly farther than its switch's travel from its home
    /// position). Before the references a switch closed where its joint rests at its home
    /// position is where a stopped homing left it: a switch failed closed there reads as
    /// the joint resting on it, and the board rightly takes it for no limit.
    SwitchImplausible(usize),
    /// While the board is enabling (the brake check).
    Enabling,
    /// While the safety relay disagrees with the e-stop button (pressed and closed, or
    /// released and open); its time counts from the start of each unbroken disagreement
    /// ([`Shows::restarts`]).
    RelayDisagrees,
    /// Its time is not judged (the consequences are: SR-1, SR-2).
    Unjudged,
}

impl Shows {
    /// Its time of showing starts again whenever it stops showing: the detector judges
    /// only an unbroken stretch. The safety chain's check is a debounce (the relay's
    /// switching time, 20 control periods) that restarts whenever the button and the
    /// relay agree: every press and release of a sound chain disagrees for the relay's
    /// switching time, so a disagreement shorter than the debounce is not a fault, and
    /// stretches broken by agreement do not add up.
    pub fn restarts(self) -> bool {
        matches!(self, Shows::RelayDisagrees)
    }
}

/// What the board must make of an injected fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spec {
    /// The causes that name it (the first fault latched after it must be one of them,
    /// or be explained by something else the case did).
    pub causes: &'static [FaultCause],
    /// The causes that name it while homing (the homing's own checks see most faults
    /// first, as a failed homing on the joint).
    pub homing_causes: &'static [FaultCause],
    /// The joint the fault must be named on, if it has one.
    pub joint: Option<u8>,
    /// Detected when one of these causes' bits is latched.
    pub detected_by: &'static [FaultCause],
    /// The time from when it shows, ms.
    pub bound_ms: u64,
    /// When it shows.
    pub shows: Shows,
}

const HOMING: &[FaultCause] = &[FaultCause::HomingFailed];

// The causes one current sensor and one encoder per joint (the board without the second
// position channel) cannot tell apart within the monitors' windows: one sample gives one
// equation, `i = (V·d − Ke·ω)/R`, for two unknowns, the speed and the circuit. Each set is
// its fault's own causes and those whose samples it produces (`control::safety`, SR-5).

/// An encoder that counts less than the motor turns (stuck, dead, losing counts):
/// * driven, the motor turns freely and draws only what its friction and load take, which
///   can be under the open-circuit floor (legs 0.173 A, links 0.05 A), while the model at
///   the encoder's standstill expects `V·d/R` (a 0.02 duty: 1.38 A on a leg): the samples
///   of an open circuit, `MotorOpen`;
/// * braking (`V·d` near 0), the motor draws `Ke·ω/R` where the model at the encoder's
///   lower speed expects less (a dead encoder's tenth of the speed: a tenth of the
///   current): three times the model's current or more is the samples of a shorted
///   winding, `CurrentImplausible`.
const ENCODER_SEEN: &[FaultCause] = &[
    FaultCause::EncoderDead,
    FaultCause::FollowingError,
    FaultCause::NoMotion,
    FaultCause::MotorOpen,
    FaultCause::CurrentImplausible,
];

/// Open motor leads: no current, and `V·d` reads as back-EMF. For the first 100 ticks the
/// circuit drew current in (`EncoderCheckConfig::current_memory_ticks`) those are the
/// samples of a motor turning at `V·d/Ke` whose encoder is dead (`EncoderDead`).
const OPEN_SEEN: &[FaultCause] = &[
    FaultCause::MotorOpen,
    FaultCause::FollowingError,
    FaultCause::NoMotion,
    FaultCause::EncoderDead,
];

/// A shorted winding without its current regulation: at a small duty it draws a small
/// current (under twice the floor, 0.1 A: what the back-EMF check takes as explained by
/// the model) that `V·d − R·i` reads as back-EMF of a motor turning against the
/// encoder's standstill (a link at 0.075 A: 0.16 V, 7 rad/s of the motor, 0.19 rad/s),
/// the samples of a dead encoder (`EncoderDead`).
const SHORT_SEEN: &[FaultCause] = &[
    FaultCause::Overcurrent,
    FaultCause::CurrentImplausible,
    FaultCause::DriverFault,
    FaultCause::EncoderDead,
];

/// The fraction of its peak current from which a short shows: twice the fraction from
/// which the board's short check judges its filtered current (`MotorCheck`, a twentieth).
/// The filter weighs a new sample by a half, so a sample of twice that fraction puts the
/// filtered current at the judging fraction or above whatever came before: every such
/// tick is one the board judges. A sample between the two may not be (0.17 to 0.27 A on a
/// leg holding a seized load showed the short on 51 scattered ticks of 630 ms, its
/// filtered current never reaching the 0.26 A judged).
const SHORT_SHOWS: f64 = 0.10;

/// The speed above which a joint's motion shows a fault that needs motion: three times
/// the speed below which the back-EMF check never trusts its estimate (3 rad/s of the
/// motor, `EncoderCheckConfig::emf_floor_rad_s`: 1.43 mm/s on a leg, 0.083 rad/s on a
/// link). Slower, only the following error sees it, after the window over the speed.
fn moving(j: u8) -> Shows {
    let j = usize::from(j % 6);
    let per_unit = if j < 3 {
        2.0 * std::f64::consts::TAU / 0.006
    } else {
        36.0
    };
    Shows::Moving(j, 3.0 * 3.0 / per_unit)
}

impl Injection {
    /// The joint the fault is on, if any.
    pub fn joint(self) -> Option<u8> {
        use Injection as I;
        match self {
            I::EncoderStuck(j)
            | I::EncoderJump(j)
            | I::EncoderDead(j)
            | I::EncoderLosesCounts(j)
            | I::MotorOpen(j)
            | I::MotorShorted(j)
            | I::DriverFault(j)
            | I::Overcurrent(j)
            | I::BridgeStuckOn(j)
            | I::SwitchClosed(j)
            | I::SwitchDead(j)
            | I::LoadSeized(j) => Some(j % 6),
            _ => None,
        }
    }

    /// What the board must make of it (the campaign's bounds: each monitor's window plus
    /// a tick, `crate::kinds`).
    pub fn spec(self) -> Spec {
        use FaultCause as C;
        use Injection as I;
        let s = |causes, detected_by, bound_ms, shows, joint| Spec {
            causes,
            homing_causes: HOMING,
            joint,
            detected_by,
            bound_ms,
            shows,
        };
        let j = self.joint();
        let joint = |x: u8| Some(x % 6);
        match self {
            I::EncoderStuck(x) => s(ENCODER_SEEN, ENCODER_SEEN, 100, moving(x), joint(x)),
            I::EncoderJump(x) => s(
                &[C::EncoderJump],
                &[C::EncoderJump],
                2,
                Shows::Always,
                joint(x),
            ),
            I::EncoderDead(x) | I::EncoderLosesCounts(x) => {
                s(ENCODER_SEEN, ENCODER_SEEN, 150, moving(x), joint(x))
            }
            I::MotorOpen(x) => s(OPEN_SEEN, OPEN_SEEN, 30, moving(x), joint(x)),
            I::MotorShorted(x) => s(
                &[C::DriverFault],
                &[C::DriverFault],
                2,
                Shows::Driven(usize::from(x % 6)),
                None,
            ),
            I::DriverFault(_) | I::BridgeStuckOn(_) => {
                s(&[C::DriverFault], &[C::DriverFault], 2, Shows::Torque, None)
            }
            I::SupplySag => s(
                &[C::SupplyVoltage],
                &[C::SupplyVoltage],
                5,
                Shows::Torque,
                None,
            ),
            I::Overcurrent(x) => s(
                SHORT_SEEN,
                SHORT_SEEN,
                50,
                Shows::Current(usize::from(x % 6), SHORT_SHOWS),
                None,
            ),
            I::RelayWelded => s(
                &[C::EmergencyStopButton, C::SafetyRelayMismatch],
                &[C::SafetyRelayMismatch],
                23,
                Shows::RelayDisagrees,
                None,
            ),
            I::RelayStuckOpen => s(
                &[C::SafetyRelayMismatch],
                &[C::SafetyRelayMismatch],
                23,
                Shows::RelayDisagrees,
                None,
            ),
            I::TickOverrun => s(
                &[C::DeadlineMissed],
                &[C::DeadlineMissed],
                3,
                Shows::Always,
                None,
            ),
            I::SwitchClosed(x) => s(
                &[C::LimitSwitch],
                &[C::LimitSwitch],
                2,
                Shows::SwitchImplausible(usize::from(x % 6)),
                joint(x),
            ),
            I::SwitchDead(x) => s(&[C::HomingFailed], HOMING, 0, Shows::Unjudged, joint(x)),
            I::LoadSeized(x) => s(
                &[C::FollowingError, C::NoMotion, C::Overload],
                &[C::FollowingError, C::NoMotion, C::Overload],
                0,
                Shows::Unjudged,
                joint(x),
            ),
            I::BrakesWorn => s(&[C::BrakeCheck], &[C::BrakeCheck], 100, Shows::Enabling, j),
        }
    }
}

/// Injects `i` into the board or the robot (the joints are in range: nothing is refused).
pub fn inject(b: &mut BoardSim, i: Injection) {
    use Injection as I;
    let j = usize::from(i.joint().unwrap_or(0));
    let plant = &mut b.hw.plant;
    let _ = match i {
        I::EncoderStuck(_) => plant.inject(j, Fault::EncoderStuck),
        I::EncoderJump(_) => plant.inject(j, Fault::EncoderJump { counts: 1000 }),
        I::EncoderDead(_) => plant.inject(j, Fault::EncoderCountsOneIn { one_in: 10 }),
        I::EncoderLosesCounts(_) => plant.inject(j, Fault::EncoderLosesCounts { one_in: 3 }),
        I::MotorOpen(_) => plant.inject(j, Fault::MotorDisconnected),
        I::MotorShorted(_) => plant.inject(j, Fault::MotorShorted),
        I::DriverFault(_) => plant.inject(j, Fault::DriverFailed),
        I::SupplySag => plant.set_supply_voltage(16.0),
        I::Overcurrent(_) => plant
            .inject(j, Fault::CurrentRegulationLost)
            .and_then(|()| {
                plant.inject(
                    j,
                    Fault::WindingShort {
                        resistance_ratio: 0.01,
                    },
                )
            }),
        I::BridgeStuckOn(_) => plant.inject(j, Fault::BridgeStuckOn),
        I::LoadSeized(_) => plant.inject(j, Fault::LoadSeized),
        I::BrakesWorn => {
            (0..6).try_for_each(|k| plant.inject(k, Fault::BrakeWorn { holding_ratio: 0.2 }))
        }
        I::RelayWelded => {
            b.hw.relay_welded = true;
            b.press_estop(true);
            Ok(())
        }
        I::RelayStuckOpen => {
            b.hw.relay_stuck_open = true;
            Ok(())
        }
        I::TickOverrun => {
            b.overrun_next_ticks(3, 950);
            Ok(())
        }
        I::SwitchClosed(_) => {
            b.hw.switch_forced[j] = Some(true);
            Ok(())
        }
        I::SwitchDead(_) => {
            b.hw.switch_forced[j] = Some(false);
            Ok(())
        }
    };
}

/// Removes every injected fault: the joints' faults (a joint held by its hard stop stays
/// held), the supply, the switches, the relay, the overruns; the button released.
pub fn repair(b: &mut BoardSim) {
    let at_stop = b.hw.at_stop();
    for (j, s) in at_stop.iter().enumerate() {
        let _ = b.hw.plant.clear_faults(j);
        if s.is_some() {
            if let Ok(mut f) = b.hw.plant.faults(j) {
                f.load_seized = true;
                let _ = b.hw.plant.set_faults(j, f);
            }
        }
    }
    let _ = b.hw.plant.set_supply_voltage(24.0);
    b.hw.switch_forced = [None; 6];
    b.hw.relay_welded = false;
    b.hw.relay_stuck_open = false;
    b.overrun_next_ticks(0, 0);
    b.press_estop(false);
}
