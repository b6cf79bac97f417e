//! Homing: the incremental encoders find their reference, joint by joint, against a
//! switch or a hard stop. While one joint homes, the others hold where they are under
//! servo. The park move that follows is the runtime's: it goes through the setpoint
//! supervisor and its guards like any target ([`crate::runtime`]).
//!
//! Each tick the runtime's sensing has read the encoders; [`Homing::step`] reads the
//! joints and counts through [`JointReferences`], with the switches and the currents, sets
//! the reference of a joint through it and returns the duties (the runtime limits them and
//! drives the outputs; on a failure it stops as the stop table says).
//!
//! A stall counts as the hard stop only within a window of the travel expected from the
//! rest position (where the robot is when it is homed: its brakes held it where it was
//! parked): a stall well before (an obstacle) or after is a failure.

use hal::{CurrentSense, LimitSwitches};
use num_traits::Float;
use servo::backlash::Direction;
use servo::config::ConfigError;
use servo::joint_servo::JointServo;
use servo::{ServoConfig, NUM_JOINTS};

use crate::scalar::lit;

/// The encoders as the homing sees them (the runtime's sensing): this tick's joints,
/// motors and counts, the reference of a joint, and the backlash offsets of the homing's
/// servo.
pub trait JointReferences<S> {
    /// This tick's joint positions (relative for the joints not referenced yet): the
    /// motors' less the backlash offsets.
    fn joints(&self) -> [S; NUM_JOINTS];
    /// This tick's motor positions in joint units (the servo closes its loops on them).
    fn motors(&self) -> [S; NUM_JOINTS];
    /// The backlash offsets (motor less joint) the homing's servo applies, from the next
    /// tick on.
    fn set_backlash(&mut self, offsets: &[S; NUM_JOINTS]);
    /// This tick's extended counts.
    fn counts(&self) -> [i64; NUM_JOINTS];
    /// Joint `joint` is at `q` now (its count is kept); false outside `0..6`.
    fn set_reference(&mut self, joint: usize, q: S) -> bool;
}

/// How a joint finds its reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeMethod {
    /// Drive to the home switch; a stall before it is a failure.
    Switch,
    /// Drive into the mechanical stop under the current/duty limit; the stall is the
    /// reference.
    HardStop,
}

/// Homing of one joint. Joint units: m (legs), rad (links); currents in A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointHoming<S> {
    /// Switch or hard stop.
    pub method: HomeMethod,
    /// Approach towards `+q` (else towards `-q`).
    pub towards_positive: bool,
    /// Joint position at the switch point or the stop (the board's mechanics).
    pub home_position: S,
    /// Where the joint rests before homing (the park position its brake held), and so
    /// the expected travel to the reference: `|rest - home_position|`.
    pub rest_position: S,
    /// A stall counts as the hard stop only within this much of the expected travel.
    pub travel_tolerance: S,
    /// |duty| while approaching (slow), within the duty limit.
    pub approach_duty: S,
    /// |duty| while backing off.
    pub backoff_duty: S,
    /// Distance to back off from the reference.
    pub backoff_distance: S,
    /// Largest travel while searching before giving up.
    pub max_travel: S,
    /// Above this |current| the duty is cut for the tick (the current limit); lasting
    /// for the stall time it counts as a stall. Infinite disables it.
    pub current_limit: S,
    /// The most a switch may be driven off before it must change (its hysteresis and a
    /// margin): the travel allowed to leave a switch actuated at the start, and how far
    /// from its switch a joint may rest and still find it actuated.
    pub switch_travel_max: S,
    /// Where the joint may be while homing (m, rad): its mechanical range, widened only as
    /// far as its switch or stop. Before its reference exists the joint's position is
    /// estimated from where it rested ([`JointHoming::rest_position`]) and how far it has
    /// moved since the start.
    pub range: [S; 2],
    /// The fastest the joint's motor may move while homing (m/s, rad/s, over 10 ms).
    pub speed_limit: S,
    /// The largest share of the approach's push (the effort of `approach_duty` at stall)
    /// that a known load (a declared tool) may take against the approach at any point of
    /// the homing: the homing drives open loop, so a heavier load would stop or drive the
    /// joint itself (`LoadTooHeavy`, found at `Home` before anything moves).
    pub load_share: S,
    /// The least travel towards its hard stop before a stall counts as the stop: less is
    /// a joint that did not move (`NoProgress`).
    pub stall_min_travel: S,
    /// How far the joint may move backwards (against its approach) before its load is
    /// taken to overcome the homing's push (`LoadTooHeavy`).
    pub backward_slack: S,
}

/// Homing settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingConfig<S> {
    /// Per joint.
    pub joints: [JointHoming<S>; NUM_JOINTS],
    /// Joints in the order they are homed (each index once).
    pub order: [u8; NUM_JOINTS],
    /// Largest |duty| of any homing move.
    pub duty_limit: S,
    /// How long every joint holds under servo before the first moves, µs.
    pub settle_us: u64,
    /// No motion of at least `stall_counts` for this long while driving is a stall, µs.
    pub stall_time_us: u64,
    /// Counts that make "motion".
    pub stall_counts: i64,
    /// Longest time of one phase of one joint, µs.
    pub phase_timeout_us: u64,
    /// After homing, move to these joints (e.g. the central configuration) through the
    /// supervisor, or stay where the last back-off ended.
    pub park: Option<[S; NUM_JOINTS]>,
}

/// The board's mechanics the homing and the joint-range monitor rely on (the drawing's
/// values; the board's configuration carries them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics<S> {
    /// The legs' home switches close at this length, m (homing towards -q).
    pub leg_switch_m: S,
    /// The links' hard stops are this far below their central angles, rad (homing towards
    /// -q).
    pub link_stop_below_central_rad: S,
    /// Every joint's mechanical range (m, rad), joint order: a measured joint outside it
    /// is a fault.
    pub range: [[S; 2]; NUM_JOINTS],
}

impl<S: Float> HomingConfig<S> {
    /// The settings for a robot whose central configuration is `central` (joints), with
    /// the mechanics `mech`, resting at `rest` (joints) before homing and parking at
    /// `park`: legs home on their switches, links against their hard stops.
    pub fn for_mechanics(
        mech: &Mechanics<S>,
        central: &[S; NUM_JOINTS],
        rest: &[S; NUM_JOINTS],
        park: Option<[S; NUM_JOINTS]>,
    ) -> Self {
        let at = |a: &[S; NUM_JOINTS], j: usize| a.get(j).copied().unwrap_or_else(S::zero);
        let at2 = |a: &[[S; 2]; NUM_JOINTS], j: usize| {
            a.get(j).copied().unwrap_or([S::zero(), S::zero()])
        };
        let leg = |j: usize| JointHoming {
            method: HomeMethod::Switch,
            towards_positive: false,
            home_position: mech.leg_switch_m,
            rest_position: at(rest, j),
            travel_tolerance: lit(0.010),
            approach_duty: lit(0.03),
            backoff_duty: lit(0.04),
            backoff_distance: lit(0.002),
            max_travel: lit(0.080),
            // Under the overload monitor's 90 % of the 5.2 A peak.
            current_limit: lit(3.0),
            switch_travel_max: lit(0.003),
            load_share: lit(0.5),
            backward_slack: lit(0.0002),
            stall_min_travel: lit(0.0005),
            range: at2(&mech.range, j),
            // 1.5 x the fastest of a homing on the reference plant (14 mm/s backing off).
            speed_limit: lit(0.022),
        };
        let link = |j: usize| JointHoming {
            method: HomeMethod::HardStop,
            towards_positive: false,
            home_position: at(central, j) - mech.link_stop_below_central_rad,
            rest_position: at(rest, j),
            travel_tolerance: lit(25f64.to_radians()),
            approach_duty: lit(0.02),
            backoff_duty: lit(0.03),
            backoff_distance: lit(0.05),
            max_travel: lit(3.5),
            // Well under the overload monitor's 90 % of the 0.66 A peak: a stop found at
            // the homing's limit is not an overload.
            current_limit: lit(0.4),
            switch_travel_max: lit(3f64.to_radians()),
            load_share: lit(0.5),
            backward_slack: lit(0.5f64.to_radians()),
            stall_min_travel: lit(2f64.to_radians()),
            range: {
                // Down to the hard stop and a degree beyond it.
                let [lo, hi] = at2(&mech.range, j);
                let stop = at(central, j) - mech.link_stop_below_central_rad;
                [lo.min(stop - lit(1f64.to_radians())), hi]
            },
            // 1.5 x the fastest of a homing on the reference plant (0.72 rad/s backing off).
            speed_limit: lit(1.1),
        };
        HomingConfig {
            joints: [leg(0), leg(1), leg(2), link(3), link(4), link(5)],
            order: [0, 1, 2, 3, 4, 5],
            duty_limit: lit(0.3),
            settle_us: 100_000,
            stall_time_us: 150_000,
            stall_counts: 4,
            phase_timeout_us: 30_000_000,
            park,
        }
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<(), HomingError> {
        let bad = |joint: usize| Err(HomingError::Config { joint });
        let mut seen = [false; NUM_JOINTS];
        for j in self.order {
            match seen.get_mut(usize::from(j)) {
                Some(s) if !*s => *s = true,
                _ => return bad(usize::from(j)),
            }
        }
        let pos = |x: S| x.is_finite() && x > S::zero();
        if !(pos(self.duty_limit) && self.duty_limit <= S::one()) || self.stall_time_us == 0 {
            return bad(0);
        }
        for (j, h) in self.joints.iter().enumerate() {
            let ok = h.home_position.is_finite()
                && h.rest_position.is_finite()
                && pos(h.travel_tolerance)
                && pos(h.approach_duty)
                && pos(h.backoff_duty)
                && pos(h.backoff_distance)
                && pos(h.max_travel)
                && pos(h.switch_travel_max)
                && pos(h.speed_limit)
                && pos(h.load_share)
                && pos(h.stall_min_travel)
                && h.load_share <= S::one()
                && pos(h.backward_slack)
                && h.range[0] < h.range[1]
                && h.home_position >= h.range[0]
                && h.home_position <= h.range[1]
                && h.current_limit > S::zero()
                && !h.current_limit.is_nan();
            let park_ok = match self.park {
                Some(p) => p.get(j).is_some_and(|x| x.is_finite()),
                None => true,
            };
            if !(ok && park_ok) {
                return bad(j);
            }
        }
        Ok(())
    }
}

/// Why homing failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomingError {
    /// A setting is invalid (the joint it concerns).
    Config {
        /// Joint.
        joint: usize,
    },
    /// A phase took longer than `phase_timeout_us`.
    Timeout {
        /// Joint.
        joint: usize,
    },
    /// Travelled `max_travel` without finding the reference.
    NotFound {
        /// Joint.
        joint: usize,
    },
    /// Stalled before reaching its switch (obstacle, jam).
    StalledBeforeSwitch {
        /// Joint.
        joint: usize,
    },
    /// Stalled outside the window of the travel expected to its hard stop (an obstacle).
    StalledOutsideWindow {
        /// Joint.
        joint: usize,
    },
    /// The switch stayed actuated after backing off.
    SwitchStuck {
        /// Joint.
        joint: usize,
    },
    /// A switch reads actuated where the joint cannot be near it (it rests farther from it
    /// than the switch's travel): a cut wire or a failed switch; found before any motion.
    SwitchImplausible {
        /// Joint.
        joint: usize,
    },
    /// The joint left its homing range (its estimated position, before its reference).
    OutOfRange {
        /// Joint.
        joint: usize,
    },
    /// The joint's motor moved faster than the homing allows (a runaway).
    Overspeed {
        /// Joint.
        joint: usize,
    },
    /// The joint's load (the tool's weight) takes so much of the homing's push that the
    /// open-loop push cannot control the joint, or it pushed the joint backwards: remove
    /// the tool, or support it, and home again.
    LoadTooHeavy {
        /// Joint.
        joint: usize,
    },
    /// The joint stalled before it moved towards its hard stop: a load or a jam holds it
    /// (or it rests at the stop already); not taken for the stop.
    NoProgress {
        /// Joint.
        joint: usize,
    },
    /// The park move after the references (`reason`: 1 a guard along the path, 2 a point
    /// of the path without a pose, 3 invalid settings, 4 not settled at the park joints, 5
    /// the supervisor refused to start at the park pose).
    Park {
        /// Why, 1 ..= 5.
        reason: u8,
    },
}

impl HomingError {
    /// A number for the fault record's value: the kind × 10 + the joint (the park move:
    /// 70 + its reason).
    pub fn code(&self) -> f32 {
        let (kind, joint) = match *self {
            HomingError::Config { joint } => (1, joint),
            HomingError::Timeout { joint } => (2, joint),
            HomingError::NotFound { joint } => (3, joint),
            HomingError::StalledBeforeSwitch { joint } => (4, joint),
            HomingError::StalledOutsideWindow { joint } => (5, joint),
            HomingError::SwitchStuck { joint } => (6, joint),
            HomingError::Park { reason } => (7, usize::from(reason)),
            HomingError::SwitchImplausible { joint } => (8, joint),
            HomingError::OutOfRange { joint } => (9, joint),
            HomingError::Overspeed { joint } => (10, joint),
            HomingError::LoadTooHeavy { joint } => (11, joint),
            HomingError::NoProgress { joint } => (12, joint),
        };
        (kind * 10 + joint) as f32
    }
    /// The joint it concerns, if any.
    pub fn joint(&self) -> Option<usize> {
        match *self {
            HomingError::Config { joint }
            | HomingError::Timeout { joint }
            | HomingError::NotFound { joint }
            | HomingError::StalledBeforeSwitch { joint }
            | HomingError::StalledOutsideWindow { joint }
            | HomingError::SwitchStuck { joint }
            | HomingError::SwitchImplausible { joint }
            | HomingError::OutOfRange { joint }
            | HomingError::Overspeed { joint }
            | HomingError::LoadTooHeavy { joint }
            | HomingError::NoProgress { joint } => Some(joint),
            HomingError::Park { .. } => None,
        }
    }
}

/// The homing procedure's phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomingPhase {
    /// Not started.
    Idle,
    /// Every joint holds under servo for the settle time before anything moves: the
    /// currents that hold the robot's load (the tool's weight) are measured.
    Settle,
    /// Driving off a switch that was already actuated at the start.
    LeaveSwitch {
        /// Joint.
        joint: usize,
    },
    /// Driving slowly towards the switch or stop.
    Approach {
        /// Joint.
        joint: usize,
    },
    /// Backing off from the reference.
    BackOff {
        /// Joint.
        joint: usize,
    },
    /// Every joint has its reference.
    Referenced,
    /// Failed.
    Failed(HomingError),
}

/// What one homing step reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingStatus {
    /// Still going.
    Running(HomingPhase),
    /// Every joint's encoder has its reference (the sensing's joints are absolute from
    /// now on); the park move is next.
    Referenced,
    /// Failed.
    Failed(HomingError),
}

/// The homing procedure, one [`Homing::step`] per control tick.
#[derive(Clone, Debug)]
pub struct Homing<S> {
    cfg: HomingConfig<S>,
    /// Holds the joints not being homed.
    servo: JointServo<S>,
    phase: HomingPhase,
    /// Index into `order`.
    index: usize,
    phase_start_us: u64,
    phase_start_q: S,
    /// Where the joint being homed started its approach (for the travel window).
    approach_start_q: S,
    motion_count: i64,
    motion_us: u64,
    over_current_since: Option<u64>,
    /// Current limiting: the factor on the commanded duty.
    duty_scale: S,
    /// Where the joints not being homed hold.
    hold: [S; NUM_JOINTS],
    /// Where the joints rested at the start (the travel windows' reference).
    rest: [S; NUM_JOINTS],
    last_us: u64,
    /// The joints at the last step.
    q: [S; NUM_JOINTS],
    /// The extended counts at the last step.
    counts: [i64; NUM_JOINTS],
    /// First step of the phase.
    fresh: bool,
    /// The joints at the start (before any reference), for the estimated positions.
    start_q: [S; NUM_JOINTS],
    /// The joints whose reference this homing has set.
    referenced: [bool; NUM_JOINTS],
    /// The motors' positions and the time at the start of the speed window.
    speed_window: ([S; NUM_JOINTS], u64),
    /// The duties and the currents of the last step.
    last_duty: [S; NUM_JOINTS],
    last_currents: [S; NUM_JOINTS],
    /// What held the moving joint's load when its phase began: the duty and the current.
    load: (S, S),
}

/// The window over which the homing measures the motors' speeds, µs.
const SPEED_WINDOW_US: u64 = 10_000;

fn joint_of<S>(cfg: &HomingConfig<S>, index: usize) -> Option<usize> {
    cfg.order.get(index).map(|j| usize::from(*j))
}

fn set<S: Copy>(a: &mut [S; NUM_JOINTS], j: usize, v: S) {
    if let Some(x) = a.get_mut(j) {
        *x = v;
    }
}

impl<S: Float> Homing<S> {
    /// A homing procedure (validates `cfg`; the servo settings hold the other joints).
    pub fn new(cfg: &HomingConfig<S>, servo: &ServoConfig<S>) -> Result<Self, HomingSetupError> {
        cfg.validate().map_err(HomingSetupError::Homing)?;
        Ok(Homing {
            cfg: *cfg,
            servo: JointServo::new(servo).map_err(HomingSetupError::Servo)?,
            phase: HomingPhase::Idle,
            index: 0,
            phase_start_us: 0,
            phase_start_q: S::zero(),
            approach_start_q: S::zero(),
            motion_count: 0,
            motion_us: 0,
            over_current_since: None,
            duty_scale: S::one(),
            hold: [S::zero(); NUM_JOINTS],
            rest: cfg.joints.map(|h| h.rest_position),
            last_us: 0,
            q: [S::zero(); NUM_JOINTS],
            counts: [0; NUM_JOINTS],
            fresh: false,
            start_q: [S::zero(); NUM_JOINTS],
            referenced: [false; NUM_JOINTS],
            speed_window: ([S::zero(); NUM_JOINTS], 0),
            last_duty: [S::zero(); NUM_JOINTS],
            last_currents: [S::zero(); NUM_JOINTS],
            load: (S::zero(), S::zero()),
        })
    }

    /// The settings.
    pub fn config(&self) -> &HomingConfig<S> {
        &self.cfg
    }
    /// The phase.
    pub fn phase(&self) -> HomingPhase {
        self.phase
    }

    /// Starts homing from the joints `q`, motors `motor` and counts `counts` the sensing
    /// reads now: every joint holds there under servo until its turn (the backlash
    /// compensation resumes with the offsets `motor - q`). `rest`: where the joints are,
    /// when known (a robot homed already and homed again), instead of the configured rest
    /// positions (the travel windows are measured from it).
    pub fn start(
        &mut self,
        q: &[S; NUM_JOINTS],
        motor: &[S; NUM_JOINTS],
        counts: &[i64; NUM_JOINTS],
        rest: Option<&[S; NUM_JOINTS]>,
        now_us: u64,
    ) {
        self.rest = match rest {
            Some(r) => *r,
            None => self.cfg.joints.map(|h| h.rest_position),
        };
        self.start_q = *q;
        self.referenced = [false; NUM_JOINTS];
        self.speed_window = (*motor, now_us);
        self.q = *q;
        self.counts = *counts;
        self.hold = *q;
        self.servo.reset(motor);
        let mut offsets = *motor;
        for (o, x) in offsets.iter_mut().zip(q) {
            *o = *o - *x;
        }
        self.servo.resume_backlash(q, &offsets);
        self.index = 0;
        self.last_us = now_us;
        self.last_duty = [S::zero(); NUM_JOINTS];
        self.last_currents = [S::zero(); NUM_JOINTS];
        self.enter(HomingPhase::Settle, now_us);
    }

    /// The end of the settle time: the first joint approaches.
    fn settled(&mut self, now_us: u64) -> Result<(), HomingError> {
        match joint_of(&self.cfg, 0) {
            Some(j) => {
                self.approach_start_q = self.q.get(j).copied().unwrap_or_else(S::zero);
                self.enter(HomingPhase::Approach { joint: j }, now_us);
                Ok(())
            }
            None => Err(HomingError::Config { joint: 0 }),
        }
    }

    /// Aborts: the phase becomes `Idle`.
    pub fn abort(&mut self) {
        self.phase = HomingPhase::Idle;
    }

    /// Checks the switches before any motion: a switch that reads actuated where its
    /// joint rests farther from it than the switch's travel cannot be (a cut wire or a
    /// failed switch): homing fails before it moves anything.
    pub fn check_switches(&mut self, switches: &[bool; NUM_JOINTS]) -> Result<(), HomingError> {
        for (joint, h) in self.cfg.joints.iter().enumerate() {
            let actuated = switches.get(joint).copied().unwrap_or(false);
            let rest = self.rest.get(joint).copied().unwrap_or(h.rest_position);
            if h.method == HomeMethod::Switch
                && actuated
                && (rest - h.home_position).abs() > h.switch_travel_max
            {
                let e = HomingError::SwitchImplausible { joint };
                self.phase = HomingPhase::Failed(e);
                return Err(e);
            }
        }
        Ok(())
    }

    /// The joints' positions as the homing knows them: a referenced joint's is measured;
    /// before its reference, where it rested plus how far it has moved since the start.
    pub fn estimated(&self, q: &[S; NUM_JOINTS]) -> [S; NUM_JOINTS] {
        core::array::from_fn(|j| {
            let qj = q.get(j).copied().unwrap_or_else(S::zero);
            if self.referenced.get(j).copied().unwrap_or(false) {
                return qj;
            }
            let rest = self.rest.get(j).copied().unwrap_or_else(S::zero);
            let start = self.start_q.get(j).copied().unwrap_or_else(S::zero);
            rest + (qj - start)
        })
    }

    /// Every joint within its homing range (estimated positions) and every motor within
    /// its homing speed (over the speed window): else the first joint that is not. While
    /// approaching, the joint being homed leaving its range means its switch or stop was
    /// not where it must be (`NotFound`).
    fn check_motion(
        &mut self,
        q: &[S; NUM_JOINTS],
        motor: &[S; NUM_JOINTS],
        now_us: u64,
    ) -> Result<(), HomingError> {
        let est = self.estimated(q);
        for (joint, (h, x)) in self.cfg.joints.iter().zip(est.iter()).enumerate() {
            let [lo, hi] = h.range;
            if !(*x >= lo && *x <= hi) {
                return Err(match self.phase {
                    HomingPhase::Approach { joint: j } if j == joint => {
                        HomingError::NotFound { joint }
                    }
                    _ => HomingError::OutOfRange { joint },
                });
            }
        }
        let (from, t0) = self.speed_window;
        let elapsed = now_us.saturating_sub(t0);
        if elapsed >= SPEED_WINDOW_US {
            let dt = S::from(elapsed).unwrap_or_else(S::one) * lit(1e-6);
            for (joint, ((h, a), b)) in self.cfg.joints.iter().zip(from).zip(motor).enumerate() {
                if !((*b - a).abs() <= h.speed_limit * dt) {
                    return Err(HomingError::Overspeed { joint });
                }
            }
            self.speed_window = (*motor, now_us);
        }
        Ok(())
    }

    fn enter(&mut self, phase: HomingPhase, now_us: u64) {
        self.phase = phase;
        self.fresh = true;
        self.phase_start_us = now_us;
        self.motion_us = now_us;
        self.over_current_since = None;
        self.duty_scale = S::one();
        if let HomingPhase::LeaveSwitch { joint }
        | HomingPhase::Approach { joint }
        | HomingPhase::BackOff { joint } = phase
        {
            self.phase_start_q = self.q.get(joint).copied().unwrap_or_else(S::zero);
            self.motion_count = self.counts.get(joint).copied().unwrap_or(0);
            // The joint was held under servo until now: what held it holds its load.
            self.load = (
                self.last_duty.get(joint).copied().unwrap_or_else(S::zero),
                self.last_currents
                    .get(joint)
                    .copied()
                    .unwrap_or_else(S::zero),
            );
        }
    }

    fn fail(&mut self, e: HomingError) -> HomingStatus {
        self.phase = HomingPhase::Failed(e);
        HomingStatus::Failed(e)
    }

    fn next_joint(&mut self, done: usize, now_us: u64) {
        // The joint just homed holds where its back-off ended.
        set(
            &mut self.hold,
            done,
            self.q.get(done).copied().unwrap_or_else(S::zero),
        );
        self.index += 1;
        match joint_of(&self.cfg, self.index) {
            Some(j) => {
                self.approach_start_q = self.q.get(j).copied().unwrap_or_else(S::zero);
                self.enter(HomingPhase::Approach { joint: j }, now_us);
            }
            None => self.phase = HomingPhase::Referenced,
        }
    }

    /// The duties that hold every joint but `moving` where it is (`moving`'s servo
    /// setpoint follows it, so that its tracking monitor sees no error; its loop restarts
    /// bumplessly each tick, so that it holds without a kick when its move ends).
    fn hold_others(
        &mut self,
        q: &[S; NUM_JOINTS],
        motor: &[S; NUM_JOINTS],
        moving: Option<usize>,
        dt: S,
    ) -> [S; NUM_JOINTS] {
        if let Some(j) = moving {
            let qj = q.get(j).copied().unwrap_or_else(S::zero);
            set(&mut self.hold, j, qj);
            self.servo
                .reset_joint(j, motor.get(j).copied().unwrap_or_else(S::zero));
        }
        let out = self
            .servo
            .update(&self.hold, &[S::zero(); NUM_JOINTS], motor, dt);
        let limit = self.cfg.duty_limit;
        out.duty.map(|d| d.max(-limit).min(limit))
    }

    /// Holds every joint at its hold position under the homing's servo (after the
    /// references, while the park move's path is checked); `motor` the measured motors.
    pub fn hold(&mut self, motor: &[S; NUM_JOINTS], now_us: u64) -> servo::ServoOutput<S> {
        let hold = self.hold;
        self.track(&hold, &[S::zero(); NUM_JOINTS], motor, now_us)
    }

    /// Follows the joint setpoint `setpoint` (speed `qdot`) under the homing's servo, the
    /// duties within the homing's duty limit (the park move); `motor` the measured
    /// motors. The hold positions follow the setpoint. The servo's backlash offsets are
    /// [`Homing::backlash_offsets`], for the sensing.
    pub fn track(
        &mut self,
        setpoint: &[S; NUM_JOINTS],
        qdot: &[S; NUM_JOINTS],
        motor: &[S; NUM_JOINTS],
        now_us: u64,
    ) -> servo::ServoOutput<S> {
        let dt_us = now_us.saturating_sub(self.last_us).max(1);
        self.last_us = now_us;
        let dt = S::from(dt_us).unwrap_or_else(S::one) * S::from(1e-6).unwrap_or_else(S::zero);
        self.hold = *setpoint;
        let mut out = self.servo.update(setpoint, qdot, motor, dt);
        let limit = self.cfg.duty_limit;
        out.duty = out.duty.map(|d| d.max(-limit).min(limit));
        out
    }

    /// The backlash offsets (motor less joint) the homing's servo applied last, m or rad.
    pub fn backlash_offsets(&self) -> [S; NUM_JOINTS] {
        self.servo.backlash_offsets()
    }

    /// Joint `joint` is at `q` now: the sensing's reference (the motor at `q` plus the
    /// offset the servo's compensation holds), and the compensation restarted there (the
    /// joint's setpoint jumped to its referenced value without a motion).
    fn reference<R: JointReferences<S>>(&mut self, sensing: &mut R, joint: usize, q: S) {
        sensing.set_reference(joint, q);
        if let Some(r) = self.referenced.get_mut(joint) {
            *r = true;
        }
        // The joint's counts now read in the new reference: the speed window restarts
        // from there.
        self.speed_window.0 = sensing.motors();
        let offset = self
            .servo
            .backlash_offsets()
            .get(joint)
            .copied()
            .unwrap_or_else(S::zero);
        self.servo.resume_backlash_joint(joint, q, offset);
        self.q = sensing.joints();
    }

    /// The backlash offset of joint `joint`, driven open loop at duty `own`, `travel` into
    /// its phase: once it has travelled more than the gap, the motor pushes on the flank
    /// of its motion (`+-b/2`); before, the offset stays as it was. (Its compensator is not
    /// left to follow the joint's own measurement: the joint is the motor less the offset,
    /// and a time-ramped offset faster than the motion would turn the measured direction
    /// round.)
    fn moving_flank(
        &mut self,
        joint: usize,
        own: S,
        travel: S,
        q: &[S; NUM_JOINTS],
        motor: &[S; NUM_JOINTS],
    ) {
        let (Some(&qj), Some(&mj)) = (q.get(joint), motor.get(joint)) else {
            return;
        };
        let Some(comp) = self.servo.backlash(joint) else {
            return;
        };
        let direction = Direction::of_sign(own);
        let full = comp.flank_offset(direction);
        let offset = if direction != Direction::Unknown && travel > full.abs() * lit(2.0) {
            full
        } else {
            mj - qj
        };
        self.servo.resume_backlash_joint(joint, qj, offset);
    }

    /// One step on the tick's measurements (`sensing`, updated at the start of the tick):
    /// reads the switches and currents, sets references; returns the status and the duties.
    pub fn step<H, R>(
        &mut self,
        hw: &mut H,
        sensing: &mut R,
        now_us: u64,
    ) -> (HomingStatus, [S; NUM_JOINTS])
    where
        H: LimitSwitches + CurrentSense<S>,
        R: JointReferences<S>,
    {
        let dt_us = now_us.saturating_sub(self.last_us).max(1);
        self.last_us = now_us;
        let dt = S::from(dt_us).unwrap_or_else(S::one) * S::from(1e-6).unwrap_or_else(S::zero);
        let (q, motor, counts) = (sensing.joints(), sensing.motors(), sensing.counts());
        self.q = q;
        self.counts = counts;
        let (switches, currents) = (hw.switches(), hw.currents());
        let zero = [S::zero(); NUM_JOINTS];
        self.last_currents = currents;
        let joint = match self.phase {
            HomingPhase::Idle => return (HomingStatus::Running(HomingPhase::Idle), zero),
            HomingPhase::Settle => {
                if now_us.saturating_sub(self.phase_start_us) >= self.cfg.settle_us {
                    if let Err(e) = self.settled(now_us) {
                        return (self.fail(e), zero);
                    }
                }
                let duty = self.hold_others(&q, &motor, None, dt);
                sensing.set_backlash(&self.servo.backlash_offsets());
                self.last_duty = duty;
                return (self.status(), duty);
            }
            HomingPhase::Failed(e) => return (HomingStatus::Failed(e), zero),
            HomingPhase::Referenced => {
                let duty = self.hold_others(&q, &motor, None, dt);
                sensing.set_backlash(&self.servo.backlash_offsets());
                return (HomingStatus::Referenced, duty);
            }
            HomingPhase::LeaveSwitch { joint }
            | HomingPhase::Approach { joint }
            | HomingPhase::BackOff { joint } => joint,
        };
        let (Some(h), Some(&qj), Some(&cj), Some(&sw), Some(&ij)) = (
            self.cfg.joints.get(joint).copied(),
            q.get(joint),
            counts.get(joint),
            switches.get(joint),
            currents.get(joint),
        ) else {
            return (self.fail(HomingError::Config { joint }), zero);
        };
        let fresh = core::mem::replace(&mut self.fresh, false);
        if now_us.saturating_sub(self.phase_start_us) > self.cfg.phase_timeout_us {
            return (self.fail(HomingError::Timeout { joint }), zero);
        }
        if let Err(e) = self.check_motion(&q, &motor, now_us) {
            return (self.fail(e), zero);
        }
        let stalled = self.watch_motion(&h, cj, ij, now_us);
        let travel = (qj - self.phase_start_q).abs();
        let seen = Seen {
            joint,
            qj,
            switch: sw,
            fresh,
            stalled,
            travel,
        };
        let own = match self.phase_duty(&h, &seen, sensing, now_us) {
            Ok(own) => own,
            Err(e) => return (self.fail(e), zero),
        };
        let duty = self.duties(joint, own, travel, dt, sensing);
        self.last_duty = duty;
        (self.status(), duty)
    }

    /// Tracks the joint's motion and current: whether it has stalled (no motion of
    /// `stall_counts` for the stall time, or at 90 % of the current limit for as long).
    /// Above the limit the duty is scaled down for the tick, then relaxed back slowly.
    fn watch_motion(&mut self, h: &JointHoming<S>, count: i64, current: S, now_us: u64) -> bool {
        if (count - self.motion_count).abs() >= self.cfg.stall_counts {
            self.motion_count = count;
            self.motion_us = now_us;
        }
        let i_abs = current.abs();
        if i_abs > h.current_limit {
            self.duty_scale = (self.duty_scale * h.current_limit / i_abs).min(S::one());
        } else {
            self.duty_scale = (self.duty_scale * lit(1.05)).min(S::one());
        }
        if i_abs >= h.current_limit * lit(0.9) {
            self.over_current_since.get_or_insert(now_us);
        } else {
            self.over_current_since = None;
        }
        now_us.saturating_sub(self.motion_us) >= self.cfg.stall_time_us
            || self
                .over_current_since
                .is_some_and(|t| now_us.saturating_sub(t) >= self.cfg.stall_time_us)
    }

    /// The phase's decision for the joint being homed: the duty it drives with, the next
    /// phase, or why homing failed.
    fn phase_duty<R: JointReferences<S>>(
        &mut self,
        h: &JointHoming<S>,
        seen: &Seen<S>,
        sensing: &mut R,
        now_us: u64,
    ) -> Result<S, HomingError> {
        let joint = seen.joint;
        let sign = if h.towards_positive {
            S::one()
        } else {
            -S::one()
        };
        let limit = self.cfg.duty_limit;
        let switch = h.method == HomeMethod::Switch;
        // The load leaves the push too little current (checked as each phase begins), or
        // it drives the joint backwards.
        let progress = sign * (seen.qj - self.phase_start_q);
        match self.phase {
            HomingPhase::Approach { .. } if progress < -h.backward_slack => {
                return Err(HomingError::LoadTooHeavy { joint });
            }
            HomingPhase::Approach { .. } => {
                if switch && seen.switch && seen.fresh {
                    // Already on the switch at the start: leave it first.
                    self.enter(HomingPhase::LeaveSwitch { joint }, now_us);
                } else if switch && seen.switch {
                    // The reference: the position where the switch closes.
                    self.reference(sensing, joint, h.home_position);
                    self.enter(HomingPhase::BackOff { joint }, now_us);
                } else if seen.stalled {
                    if switch {
                        return Err(HomingError::StalledBeforeSwitch { joint });
                    }
                    // A stall is the hard stop only within the expected travel.
                    let rest = self.rest.get(joint).copied().unwrap_or(h.rest_position);
                    let expected = (rest - h.home_position).abs();
                    let from_start = sign * (seen.qj - self.approach_start_q);
                    if from_start < h.stall_min_travel {
                        return Err(HomingError::NoProgress { joint });
                    }
                    if (from_start - expected).abs() > h.travel_tolerance {
                        return Err(HomingError::StalledOutsideWindow { joint });
                    }
                    self.reference(sensing, joint, h.home_position);
                    self.enter(HomingPhase::BackOff { joint }, now_us);
                } else if seen.travel > h.max_travel {
                    return Err(HomingError::NotFound { joint });
                } else {
                    return Ok(sign * h.approach_duty.min(limit) * self.duty_scale);
                }
            }
            HomingPhase::LeaveSwitch { .. } => {
                if !seen.switch {
                    self.enter(HomingPhase::Approach { joint }, now_us);
                } else if seen.travel > h.switch_travel_max || seen.stalled {
                    return Err(HomingError::SwitchStuck { joint });
                } else {
                    return Ok(-sign * h.backoff_duty.min(limit) * self.duty_scale);
                }
            }
            _ => {
                // Back off.
                if seen.travel >= h.backoff_distance {
                    if switch && seen.switch {
                        return Err(HomingError::SwitchStuck { joint });
                    }
                    self.next_joint(joint, now_us);
                } else if seen.stalled {
                    return Err(HomingError::Timeout { joint });
                } else {
                    return Ok(-sign * h.backoff_duty.min(limit) * self.duty_scale);
                }
            }
        }
        Ok(S::zero())
    }

    /// The duties of the tick: the others held under servo, the joint being homed (if one
    /// still is) at `own`, its backlash flank following its motion.
    fn duties<R: JointReferences<S>>(
        &mut self,
        joint: usize,
        own: S,
        travel: S,
        dt: S,
        sensing: &mut R,
    ) -> [S; NUM_JOINTS] {
        let (q_now, motor_now) = (self.q, sensing.motors());
        let moving = match self.phase {
            HomingPhase::Referenced => None,
            _ => Some(joint),
        };
        let mut duty = self.hold_others(&q_now, &motor_now, moving, dt);
        if moving.is_some() {
            set(&mut duty, joint, own);
            self.moving_flank(joint, own, travel, &q_now, &motor_now);
        }
        sensing.set_backlash(&self.servo.backlash_offsets());
        duty
    }

    /// The status of the phase now.
    fn status(&self) -> HomingStatus {
        match self.phase {
            HomingPhase::Referenced => HomingStatus::Referenced,
            p => HomingStatus::Running(p),
        }
    }
}

/// What a homing step saw of the joint being homed.
struct Seen<S> {
    joint: usize,
    /// Its position.
    qj: S,
    /// Its switch is actuated.
    switch: bool,
    /// The phase's first step.
    fresh: bool,
    /// It has stalled.
    stalled: bool,
    /// Its travel in the phase.
    travel: S,
}

/// Why a [`Homing`] or [`crate::runtime::Runtime`] cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingSetupError {
    /// Homing settings.
    Homing(HomingError),
    /// Servo or encoder settings.
    Servo(ConfigError),
}
