//! The safety requirements of the board, written once: each with its identifier
//! (`SR-1` ..), its statement and its bound ([`Requirement`], [`Bounds`]), the fault causes
//! whose monitors guard it ([`guards`]), and the tests that check it
//! ([`Requirement::checked_by`]). The firmware README prints the table ([`write_table`];
//! `firmware/control/tests/readme.rs` checks that its copy is the code's) and
//! `tests/tests/safety_requirements.rs` checks that every citation names a test that
//! exists and cites the requirement back.
//!
//! The bounds come from the settings and the mathematics, not from a run: the supervisor's
//! limits (tip speed v, tip acceleration a), the control period dt, the brakes' engage time
//! t_e and the safe operating stop's standstill windows ([`Bounds::of`]). The distances a
//! stop may travel ([`Bounds::stop_distance_m`]):
//!
//! * STO: torque off, the platform coasts until the brakes hold: v·t_e.
//! * SS1, SS2: the supervisor brakes its setpoint along its braking curve, v²/(2a), after
//!   at most one period at speed, v·dt; the platform follows its setpoint and holds it
//!   within the standstill windows, mapped to the platform's centre through the Jacobian
//!   (w, below); plus the distance the platform stood from its setpoint when the stop
//!   began (the servos' lag, measured: it is the platform's, not the stop's).
//!
//! w: a joint error δq moves o_p by the first three rows of J⁻¹ δq (J = ∂q/∂x, Eq. 7.18),
//! at most Σ_j |J⁻¹_{0..3, j}| · window_j; the largest over the task box's centre and its
//! eight corners.

use core::fmt;

use kinematics_core::{inverse, jacobian, Mechanism, Pose};
use master_link::FaultCause;
use nalgebra::Vector3;
use servo::NUM_JOINTS;

use crate::monitors::Standstill;
use crate::runtime::RuntimeConfig;
use crate::scalar::Scalar;
use crate::stops::StopCategory;

/// A safety requirement of the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Requirement {
    /// SR-1: no joint leaves its mechanical travel.
    Range,
    /// SR-2: a stop travels at most its stated distance.
    StopDistance,
    /// SR-3: no command weakens a stop in force.
    StopNotWeakened,
    /// SR-4: the drives are on only where the mode allows torque.
    Torque,
    /// SR-5: a fault is detected in time, named by its cause.
    Detection,
    /// SR-6: only the owning master's fresh commands move the robot.
    Authority,
    /// SR-7: after a detection, the stop table's stop and its distance.
    Reaction,
}

impl Requirement {
    /// Every requirement, in the table's order.
    pub const ALL: [Requirement; 7] = [
        Requirement::Range,
        Requirement::StopDistance,
        Requirement::StopNotWeakened,
        Requirement::Torque,
        Requirement::Detection,
        Requirement::Authority,
        Requirement::Reaction,
    ];

    /// The identifier (`SR-1` ..), cited by the tests, the campaign and the fault log.
    pub const fn id(self) -> &'static str {
        match self {
            Requirement::Range => "SR-1",
            Requirement::StopDistance => "SR-2",
            Requirement::StopNotWeakened => "SR-3",
            Requirement::Torque => "SR-4",
            Requirement::Detection => "SR-5",
            Requirement::Authority => "SR-6",
            Requirement::Reaction => "SR-7",
        }
    }

    /// The requirement of an identifier.
    pub fn of_id(id: &str) -> Option<Requirement> {
        Requirement::ALL.into_iter().find(|r| r.id() == id)
    }

    /// The statement.
    pub const fn statement(self) -> &'static str {
        match self {
            Requirement::Range => {
                "No joint leaves its mechanical travel, in any mode, homing included: a joint \
                 meets a hard stop only where homing drives a link against its own stop"
            }
            Requirement::StopDistance => {
                "While a stop is in force, the platform moves at most the stop's stated \
                 distance from where it stood when the stop began (or last grew stronger)"
            }
            Requirement::StopNotWeakened => {
                "No command weakens a stop in force: it ends only by completing (torque off, \
                 brakes applied) or, for a hold, with its cause; a new stop only strengthens it"
            }
            Requirement::Torque => {
                "The drives are on only in the modes that allow torque (homing, parking, \
                 enabling, enabled, commissioning, a stop under power), the brakes released only with them, \
                 never after an STO until a fresh Enable or Home, and never with a welded \
                 safety relay found and not repaired"
            }
            Requirement::Detection => {
                "A fault is detected within its stated time of showing, logged with its \
                 cause (the first fault logged names it; without the second position channel \
                 a joint's current and encoder cannot tell an encoder that counts less than \
                 its motor turns from an open or a shorted winding within the monitors' \
                 windows, and either may be named for the other), and the platform moves at \
                 most the tip speed times that time before"
            }
            Requirement::Authority => {
                "No motion follows a command from anyone but the owning master: a second \
                 master's Hello takes the board only while the robot is disabled, no \
                 foreign, replayed or far-ahead frame, nor a target stamped in the future, \
                 is taken, and none locks the owner out or makes its targets stale"
            }
            Requirement::Reaction => {
                "Once a fault is detected, the stop in force is at least the stop table's for \
                 its cause, and the platform moves at most that stop's distance after it"
            }
        }
    }

    /// The tests that check it (`path::test`, from the repository's root). Each cites the
    /// requirement's identifier in its documentation.
    pub const fn checked_by(self) -> &'static [&'static str] {
        const SEARCH: &str =
            "host-sim/faults/tests/search.rs::random_sequences_keep_every_requirement";
        const CAMPAIGN: &str =
            "host-sim/faults/tests/campaign.rs::every_cell_of_the_campaign_passes";
        const ROWS: &str = "firmware/control/tests/stops.rs::every_row_of_the_stop_table_stops_as_its_category_says";
        match self {
            Requirement::Range => &[
                SEARCH,
                CAMPAIGN,
                "firmware/control/tests/state.rs::a_switch_that_never_closes_stops_the_joint_at_its_range",
            ],
            Requirement::StopDistance => &[SEARCH, CAMPAIGN, ROWS],
            Requirement::StopNotWeakened => &[
                SEARCH,
                "firmware/control/tests/modes.rs::random_sequences_never_weaken_a_stop",
                "firmware/control/tests/stops.rs::stops_only_escalate_and_a_lost_standstill_is_sto",
                "host-sim/simulation/tests/stop_precedence.rs::home_and_store_geometry_never_weaken_a_stop",
                "firmware/control/tests/failsafe.rs::no_command_of_the_tick_that_latched_an_emergency_stop_ends_it",
            ],
            Requirement::Torque => &[
                SEARCH,
                "firmware/control/tests/failsafe.rs::outputs_stay_off_outside_the_driving_states",
                "firmware/control/tests/modes.rs::random_sequences_never_weaken_a_stop",
            ],
            Requirement::Detection => &[
                SEARCH,
                CAMPAIGN,
                "firmware/control/tests/channel.rs::encoder_faults_in_a_held_stop_are_named_within_20_ms_and_0_1_mm",
            ],
            Requirement::Authority => &[
                SEARCH,
                "host-sim/faults/tests/search.rs::a_foreign_frame_never_moves_the_robot",
            ],
            Requirement::Reaction => &[SEARCH, CAMPAIGN, ROWS],
        }
    }

    /// The fault causes whose monitors guard it (the reverse of [`guards`]).
    pub fn guarded_by(self) -> impl Iterator<Item = FaultCause> {
        FaultCause::ALL
            .into_iter()
            .filter(move |c| guards(*c).contains(&self))
    }
}

impl fmt::Display for Requirement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.id())
    }
}

/// The requirements a fault's monitor guards: the one whose violation it catches or
/// prevents (what the fault log cites for each entry).
pub const fn guards(cause: FaultCause) -> &'static [Requirement] {
    use FaultCause as F;
    use Requirement as R;
    match cause {
        // The operator's and the hard-wired chain's torque off.
        F::EmergencyStopButton | F::EmergencyStopMessage => &[R::Torque, R::StopDistance],
        F::SafetyRelayMismatch => &[R::Torque],
        // No master: nobody owns the motion any more.
        F::HeartbeatTimeout => &[R::Authority],
        F::JointLimit | F::LimitSwitch | F::HomingFailed => &[R::Range],
        F::Singularity | F::GuardStop | F::ForwardKinematics => &[R::Range],
        // The robot is not where the setpoint says: a runaway, a jam, a sensor that lies.
        F::FollowingError | F::NoMotion | F::EncoderJump | F::EncoderDead => {
            &[R::Range, R::Detection]
        }
        // The second position channel: an encoder that lies (stuck, dead, miscounting,
        // also in a held stop), or the channel itself failed.
        F::EncoderDisagree => &[R::Range, R::Detection, R::StopDistance],
        F::PositionSensor => &[R::Detection],
        F::MotorOpen | F::StandstillLost | F::BrakeCheck | F::Overload => &[R::StopDistance],
        // The power stage does not do what it is told.
        F::CurrentImplausible
        | F::Overcurrent
        | F::DriverFault
        | F::SupplyVoltage
        | F::OverTemperature
        | F::NonFiniteInput
        | F::Internal => &[R::Torque],
        F::DeadlineMissed => &[R::Detection, R::Torque],
        F::None => &[],
    }
}

/// The identifiers of the requirements `cause` guards, as text (`SR-1 SR-5`; `-` for
/// none), for logs and reports.
pub fn write_guarded(out: &mut impl fmt::Write, cause: FaultCause) -> fmt::Result {
    let rs = guards(cause);
    if rs.is_empty() {
        return out.write_str("-");
    }
    for (i, r) in rs.iter().enumerate() {
        if i > 0 {
            out.write_str(" ")?;
        }
        out.write_str(r.id())?;
    }
    Ok(())
}

/// An encoder fault in a held stop, the second channel fitted, is named within this time
/// of showing (s; SR-5).
pub const HELD_ENCODER_FAULT_S: f64 = 0.020;
/// ... and before its joint moved this far (m on a leg, rad on a link; SR-5).
pub const HELD_ENCODER_FAULT_M: [f64; 2] = [0.1e-3, 0.1 * core::f64::consts::PI / 180.0];
/// The miscounting encoder the requirements state figures for: one count lost in this many.
pub const MISCOUNT_ONE_IN: u32 = 3;

/// The numbers the requirements' bounds are made of, from the settings (SI, f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// The supervisor's tip speed limit v, m/s.
    pub tip_speed_m_s: f64,
    /// The supervisor's tip acceleration limit a (its braking deceleration), m/s².
    pub tip_accel_m_s2: f64,
    /// The control period dt, s.
    pub period_s: f64,
    /// The brakes' engage time t_e (the drives hold that long after the brakes are
    /// applied in SS1; STO coasts that long), s.
    pub brake_engage_s: f64,
    /// The longest controlled deceleration before a stop escalates to STO, s.
    pub decel_timeout_s: f64,
    /// The safe operating stop's standstill windows per joint (m, rad).
    pub standstill: [f64; NUM_JOINTS],
    /// The standstill windows mapped to o_p (w, see the module documentation), m.
    pub standstill_platform_m: f64,
    /// The heartbeat's hold and fault times, s.
    pub heartbeat_s: [f64; 2],
    /// What the second position channel and the encoder may differ by with neither
    /// failed, over a motion with no backlash in it (`absolute::ChannelConfig::agree`; m,
    /// rad per joint).
    pub channel_agree: [f64; NUM_JOINTS],
}

fn f64_of<S: Scalar>(x: S) -> f64 {
    x.to_f64().unwrap_or(f64::NAN)
}

impl Bounds {
    /// The bounds of the settings `cfg` for `robot`.
    pub fn of<S: Scalar, M: Mechanism<S>>(cfg: &RuntimeConfig<S>, robot: &M) -> Self {
        let l = &cfg.controller.limits;
        let standstill = Standstill::<f64>::reference().windows();
        Bounds {
            tip_speed_m_s: f64_of(l.tip_speed),
            tip_accel_m_s2: f64_of(l.tip_accel),
            period_s: 1.0 / f64_of(cfg.controller.rate_hz),
            brake_engage_s: cfg.stops.brake_engage_us as f64 * 1e-6,
            decel_timeout_s: cfg.stops.decel_timeout_us as f64 * 1e-6,
            standstill,
            standstill_platform_m: standstill_platform(cfg, robot, &standstill),
            heartbeat_s: [
                cfg.heartbeat.hold_after_us as f64 * 1e-6,
                cfg.heartbeat.disable_after_us as f64 * 1e-6,
            ],
            channel_agree: cfg.channel.agree.map(f64_of),
        }
    }

    /// The distance the platform may travel from where it stood when a stop of `category`
    /// began (for SS1 and SS2, less the platform's distance from its setpoint then), m.
    pub fn stop_distance_m(&self, category: StopCategory) -> f64 {
        let v = self.tip_speed_m_s;
        match category {
            StopCategory::Sto => v * self.brake_engage_s,
            StopCategory::Ss1 | StopCategory::Ss2 => {
                v * v / (2.0 * self.tip_accel_m_s2) + v * self.period_s + self.standstill_platform_m
            }
        }
    }

    /// The distance the platform may travel before a fault is detected `detect_s` after
    /// it shows (the tip speed for that long), m.
    pub fn before_detection_m(&self, detect_s: f64) -> f64 {
        self.tip_speed_m_s * detect_s
    }
}

/// Joint windows `window` (m, rad per joint) mapped to o_p, the largest over the task box's
/// centre and corners (w for the standstill windows, see the module documentation); NaN
/// where a pose has no Jacobian.
pub fn standstill_platform<S: Scalar, M: Mechanism<S>>(
    cfg: &RuntimeConfig<S>,
    robot: &M,
    window: &[f64; NUM_JOINTS],
) -> f64 {
    let l = &cfg.controller.limits;
    let half = l.box_half;
    let mut worst = 0.0f64;
    for k in 0..9u8 {
        let sign = |bit: u8| match k {
            0 => S::zero(),
            _ if (k - 1) & bit != 0 => S::one(),
            _ => -S::one(),
        };
        let mut pose = Pose::central(robot.hc());
        pose.t += Vector3::new(half.x * sign(1), half.y * sign(2), half.z * sign(4));
        let Some(w) = window_at(robot, &pose, cfg, window) else {
            return f64::NAN;
        };
        worst = worst.max(w);
    }
    worst
}

fn window_at<S: Scalar, M: Mechanism<S>>(
    robot: &M,
    pose: &Pose<S>,
    cfg: &RuntimeConfig<S>,
    window: &[f64; NUM_JOINTS],
) -> Option<f64> {
    let sol = inverse(robot, pose, cfg.controller.branch).ok()?;
    let j = jacobian(robot, &sol).ok()?.j;
    let inv = j.try_inverse()?;
    let mut w = 0.0f64;
    for (c, win) in window.iter().enumerate() {
        let col = |r: usize| f64_of(inv.get((r, c)).copied().unwrap_or_else(S::nan));
        let (x, y, z) = (col(0), col(1), col(2));
        w += num_traits::Float::sqrt(x * x + y * y + z * z) * *win;
    }
    Some(w)
}

/// Writes the requirements as a Markdown table with the bounds of `b` (the firmware README
/// prints it; a test checks that the README's copy is this one).
pub fn write_table(out: &mut impl fmt::Write, b: &Bounds) -> fmt::Result {
    writeln!(
        out,
        "| id | requirement | bound | guarded by (fault causes) | checked by |"
    )?;
    writeln!(out, "| --- | --- | --- | --- | --- |")?;
    for r in Requirement::ALL {
        write!(out, "| {} | {} | ", r.id(), r.statement())?;
        write_bound(out, r, b)?;
        out.write_str(" | ")?;
        let mut any = false;
        for c in r.guarded_by() {
            if any {
                out.write_str(", ")?;
            }
            out.write_str(c.name())?;
            any = true;
        }
        if !any {
            out.write_str("-")?;
        }
        out.write_str(" | ")?;
        for (i, t) in r.checked_by().iter().enumerate() {
            if i > 0 {
                out.write_str(", ")?;
            }
            write!(out, "`{t}`")?;
        }
        writeln!(out, " |")?;
    }
    Ok(())
}

/// The bound of `r` in words and figures.
fn write_bound(out: &mut impl fmt::Write, r: Requirement, b: &Bounds) -> fmt::Result {
    let mm = |x: f64| x * 1e3;
    let ms = |x: f64| x * 1e3;
    match r {
        Requirement::Range => out.write_str(
            "no contact with an end stop (legs: 1 mm beyond `Mechanics::range`); a link's \
             hard stop (central +- `link_stop_below_central_rad`) only while homing, or \
             coasting on, torque off, within the brakes' engage time after a stop ended a \
             homing that swept it there",
        ),
        Requirement::StopDistance => write!(
            out,
            "STO: v t_e = {:.2} mm, with brakes that hold what the brake check of the last \
             enable tested (brakes worn since are found by the next enable's check, SR-5; \
             until then an STO's distance is theirs); SS1, SS2 (and the safe operating \
             stop): v^2/(2a) + v dt + \
             w = {:.3} mm (w = {:.3} mm, the standstill windows {:.2} mm / {:.0} mrad at o_p) \
             + the platform's distance from its setpoint at the start; v = {:.0} mm/s, \
             a = {:.2} m/s^2, dt = {:.0} ms, t_e = {:.0} ms",
            mm(b.stop_distance_m(StopCategory::Sto)),
            mm(b.stop_distance_m(StopCategory::Ss1)),
            mm(b.standstill_platform_m),
            mm(b.standstill[0]),
            b.standstill[3] * 1e3,
            mm(b.tip_speed_m_s),
            b.tip_accel_m_s2,
            ms(b.period_s),
            ms(b.brake_engage_s),
        ),
        Requirement::StopNotWeakened => out
            .write_str("strength STO > SS1 > SS2 never drops while the stop is in force (0 ticks)"),
        Requirement::Torque => write!(
            out,
            "0 ticks with the drives on outside those modes; an SS1 applies the brakes {:.0} \
             ms before torque off",
            ms(b.brake_engage_s)
        ),
        Requirement::Detection => write!(
            out,
            "each fault kind's time (the campaign's table: its monitor's window + 1 tick); \
             before it, v x that time ({:.3} mm per ms); with the second channel, an encoder \
             stuck, dead or miscounting in a held stop: named within {:.0} ms and {:.1} mm \
             ({:.1} deg), except a miscount (one count in n lost) that the hold keeps within \
             n x agree of motor motion (n = {}: {:.0} um on a leg, {:.3} deg on a link; \
             agree = {:.1} um, {:.3} deg: 5 sigma of the channel's filtered noise and one \
             encoder count), a disagreement (an n-th of the motion) the channel cannot \
             resolve",
            mm(b.tip_speed_m_s) * 1e-3,
            ms(HELD_ENCODER_FAULT_S),
            mm(HELD_ENCODER_FAULT_M[0]),
            HELD_ENCODER_FAULT_M[1].to_degrees(),
            MISCOUNT_ONE_IN,
            b.channel_agree[0] * MISCOUNT_ONE_IN as f64 * 1e6,
            (b.channel_agree[3] * MISCOUNT_ONE_IN as f64).to_degrees(),
            b.channel_agree[0] * 1e6,
            b.channel_agree[3].to_degrees(),
        ),
        Requirement::Authority => write!(
            out,
            "0 frames taken; a master that stays silent {:.0} ms loses the session's motion \
             (the heartbeat's hold, then its fault at {:.0} ms)",
            ms(b.heartbeat_s[0]),
            ms(b.heartbeat_s[1])
        ),
        Requirement::Reaction => write!(
            out,
            "the stop table's category (or stronger) within 1 tick; its SR-2 distance after \
             (STO {:.2} mm, SS1 and SS2 {:.3} mm + the lag); a deceleration ends within {:.0} \
             ms or escalates to STO",
            mm(b.stop_distance_m(StopCategory::Sto)),
            mm(b.stop_distance_m(StopCategory::Ss1)),
            ms(b.decel_timeout_s)
        ),
    }
}
