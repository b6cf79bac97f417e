//! The second position channel: an absolute position sensor per joint on the load side
//! (on the reference robot a potentiometer read by a 16-bit converter: `hal::AbsolutePositions`),
//! monitored against the encoders on the motors every tick.
//!
//! The two channels fail differently. An incremental encoder fails by losing counts (stuck,
//! dead, miscounting): it counts **less** motion than the joint made. A potentiometer fails
//! by sticking (a worn track, a lifted wiper: less motion than the joint made), by an open
//! wire (its input at a rail) or by drifting (a reading that walks while nothing moves).
//! So when the two disagree beyond what their resolutions, noise and the backlash between
//! them allow, the one that saw less motion is the one that failed, except a reading that
//! walked away slower than any motion worth the name, which is a drift of the sensor:
//!
//! * [`FaultCause::EncoderDisagree`] (the encoder named): the channel saw more motion than
//!   the encoder, faster than [`ChannelConfig::drift_speed`];
//! * [`FaultCause::PositionSensor`] (the sensor named): a reading missing or at a rail
//!   ([`ChannelConfig::rails`]), a jump beyond the joint's top speed, less motion than the
//!   encoder counted, or a disagreement that grew slower than the drift speed;
//! * [`FaultCause::StandstillLost`]: while the robot holds (a safe operating stop, or the
//!   brakes holding with torque off) both channels agree that the joint moved beyond its
//!   standstill window ([`ChannelConfig::standstill`]): the hold did not hold.
//!
//! ## The two checks
//!
//! Both watch `h = p - m`, the channel's filtered reading `p` less the motor's position by
//! its encoder `m` (in joint units, filtered alike so that the filter's lag cancels): the
//! load less the motor. Between a healthy encoder and a healthy sensor it moves only as the
//! motor crosses the backlash gap, so over any motion its range stays within the gap,
//! whatever the gap's state and whatever the backlash compensation believes of it.
//!
//! * **Always** (the window): the range of `h` since the window began beyond
//!   `agree + backlash + scale * |p - p0|` for [`ChannelConfig::persist_ticks`] ticks. The
//!   scale term is the channel's gain error over the window's motion; a quiet window
//!   starts anew after each [`ChannelConfig::reanchor`] of motion, so it stays small.
//! * **While the robot holds**: a motor that pushes its load (its current beyond
//!   [`ChannelConfig::push_current`], its sign the side it pushes to) holds the load on
//!   that flank of the gap, where `h` is at an end of its range. The load can leave the
//!   flank by the gap without the motor, never press into it without the motor following:
//!   from where the motor took the flank (standing, the channel settled), `h` may move
//!   away from it by `agree + backlash`, into it only by `agree`, or by
//!   [`ChannelConfig::agree_slow`] on a second, slower filter (a joint pushed while its
//!   encoder miscounts moves little: the servo still holds it); a motor that pushes
//!   neither way allows the gap both ways. A stuck encoder under a push into the flank is
//!   found within `agree` of motion. Once the motor has stood where it took the flank
//!   for [`ChannelConfig::season_ticks`] readings, with `h` there, their mean is the
//!   anchor: a quieter one than one filtered reading, so both bounds shrink
//!   ([`ChannelConfig::agree_seasoned`], [`ChannelConfig::agree_slow_seasoned`]). The
//!   fast filter's bounds must hold for [`ChannelConfig::persist_ticks`] ticks; the
//!   slower filter's count from the first tick beyond them (its filter is its
//!   persistence: one reading moves it by a quarter of its deviation). The flank is the
//!   current's, not the backlash compensation's belief: a load it does not know of (an
//!   undeclared tool) may rest the load on the other flank. While the robot holds, both
//!   channels also watch the joint's standstill from where the hold began.
//!
//! The disagreement found names the channel that saw less motion (the encoder: the motor's
//! motion `m - m0`; the sensor: `p - p0`); a motor that did not move while `h` walked away
//! slower than [`ChannelConfig::drift_speed`] (over the last 24 to 32 ticks) is the
//! sensor's drift.
//!
//! The bounds ([`ChannelConfig::reference`]) come from the resolutions and the noise of
//! the two channels, stated there with their sources. The channel's calibration (counts to
//! joint units) is [`ChannelCalibration`], the sensing's.

use board_profile::position_channel::PositionChannel;
use master_link::FaultCause;
use num_traits::Float;
use servo::NUM_JOINTS;

use crate::monitors::Finding;
use crate::scalar::lit;

/// Counts of the converter at mid-scale.
pub const MID_SCALE: f64 = 32768.0;

/// The channel's calibration: counts to joint units, `q = mid + (counts - 32768) /
/// counts_per_unit`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelCalibration<S> {
    /// Counts per joint unit (counts/m, counts/rad), joint order.
    pub counts_per_unit: [S; NUM_JOINTS],
    /// The joint position at mid-scale (m, rad).
    pub mid: [S; NUM_JOINTS],
    /// One step of the converter, in counts of the 16-bit readings (1 for a 16-bit
    /// converter; a converter of fewer bits is scaled up to 16).
    pub step_counts: S,
}

impl<S: Float> ChannelCalibration<S> {
    /// The reference robot's potentiometers and converter
    /// (`board_profile::position_channel::PositionChannel::REFERENCE`: the legs' linear
    /// ones, 100 mm of electrical travel, the links' single-turn ones, 340 deg, an AD7689's
    /// 16 bits), each with its mid-travel at the middle of its joint's monitored range
    /// `range` (m, rad; the board's mechanics).
    pub fn reference(range: &[[S; 2]; NUM_JOINTS]) -> Self {
        Self::of(&PositionChannel::REFERENCE, range)
    }

    /// The calibration of the channel `channel` (its converter and its sensors' travel),
    /// mid-travel at the middle of each joint's range `range`.
    pub fn of(channel: &PositionChannel, range: &[[S; 2]; NUM_JOINTS]) -> Self {
        ChannelCalibration {
            counts_per_unit: core::array::from_fn(|j| lit(channel.counts_per_unit(j))),
            mid: range.map(|[lo, hi]| (lo + hi) * lit(0.5)),
            step_counts: lit(channel.step_counts()),
        }
    }

    /// The joint positions the readings `raw` stand for.
    pub fn positions(&self, raw: &[u16; NUM_JOINTS]) -> [S; NUM_JOINTS] {
        core::array::from_fn(|j| {
            let (Some(c), Some(cpu), Some(mid)) =
                (raw.get(j), self.counts_per_unit.get(j), self.mid.get(j))
            else {
                return S::nan();
            };
            *mid + (S::from(*c).unwrap_or_else(S::nan) - lit(MID_SCALE)) / *cpu
        })
    }
}

/// The monitor's settings (see the module documentation; [`ChannelConfig::reference`]
/// derives them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelConfig<S> {
    /// A reading at or below `rails[0]`, or at or above `rails[1]`, is a failed wire
    /// (counts).
    pub rails: [u16; 2],
    /// The weight of a new reading in the filter of both channels (1: none).
    pub filter: S,
    /// The weight of a new reading in the hold check's second, slower filter: a joint that
    /// holds still is judged on fewer counts of noise too.
    pub filter_slow: S,
    /// `agree` of the slower filter (m, rad per joint).
    pub agree_slow: [S; NUM_JOINTS],
    /// Readings of `h` whose mean becomes the hold's anchor, once the motor stood that long
    /// where it took its flank.
    pub season_ticks: u16,
    /// `agree` from that mean (m, rad per joint).
    pub agree_seasoned: [S; NUM_JOINTS],
    /// `agree_slow` from that mean (m, rad per joint).
    pub agree_slow_seasoned: [S; NUM_JOINTS],
    /// What two channels that agree may differ by over a motion with no backlash in it
    /// (m, rad per joint): the filtered noise and both resolutions.
    pub agree: [S; NUM_JOINTS],
    /// The backlash the motor may cross without the load (m, rad per joint).
    pub backlash: [S; NUM_JOINTS],
    /// The channel's gain error against the encoder, a fraction of the motion.
    pub scale: S,
    /// The motion after which a quiet moving check takes a new anchor (m, rad per joint).
    pub reanchor: [S; NUM_JOINTS],
    /// Ticks a disagreement of the fast filter must last (the slow filter's counts at once).
    pub persist_ticks: u16,
    /// A disagreement that grew slower than this (m/s, rad/s per joint) is the sensor's
    /// drift, not motion.
    pub drift_speed: [S; NUM_JOINTS],
    /// The largest change of a reading in one tick (m, rad per joint): beyond it the
    /// reading jumped.
    pub jump: [S; NUM_JOINTS],
    /// Standstill windows while the robot holds (m, rad per joint).
    pub standstill: [S; NUM_JOINTS],
    /// A motor current beyond this pushes the load on one flank of the gap (A per joint).
    pub push_current: [S; NUM_JOINTS],
    /// A motor that moved no more than this did not move (m, rad per joint).
    pub still: [S; NUM_JOINTS],
    /// The control period, s.
    pub dt: S,
}

impl<S: Float> ChannelConfig<S> {
    /// The reference robot's, from its two channels:
    ///
    /// * the channel's resolution: one count of the 16-bit converter, `1 / cal.counts_per_unit`
    ///   (1.53 um on a leg, 0.0052 deg on a link: [`ChannelCalibration::reference`]);
    /// * its noise: 1 count rms (the converter's transition noise, 0.5 counts rms by its
    ///   data sheet, and the wiper's and the cable's pickup behind each input's 1.6 kHz
    ///   filter; `sim/plant/plant.toml`, `[position_sensor] noise_lsb`), `sqrt(1 + step^2/12)`
    ///   counts with the converter's quantisation (`cal.step_counts`): 1.04 counts with
    ///   the AD7689's one-count step (4.73 with a 12-bit converter's 16). Both channels go through a first-order
    ///   filter of weight 1/2 (a lag of one tick), which leaves `sqrt(1/3)` of it; a
    ///   disagreement is the difference of two filtered readings (now and at the anchor):
    ///   `sigma_e = 1.04 sqrt(2/3)` = 0.85 counts; five of them, 4.2 counts;
    /// * the encoders' resolution: one count, `1 / encoder_counts_per_unit` (1.5 um, 0.005
    ///   deg; `servo::encoder`), which two readings may differ by;
    /// * so `agree` = 4.2 channel counts + 1 encoder count: 8.0 um on a leg, 0.027 deg on a
    ///   link;
    /// * the hold check's slower filter, weight 1/4 (a lag of three ticks), leaves
    ///   `sqrt(1/7)` of the noise: `sigma_e = 1.04 sqrt(2/7)` = 0.56 counts, five of them
    ///   2.8 counts, so `agree_slow` = 2.8 channel counts + 1 encoder count: 5.7 um and
    ///   0.019 deg. A joint pushed while its encoder miscounts (the servo still holds
    ///   it, within a few hundredths of a millimetre) shows a disagreement of a third of
    ///   that: only the slow filter resolves it;
    /// * a seasoned anchor: the mean of `season_ticks` = 24 raw readings of `h` (the
    ///   motor standing on its flank that long: any motion before it has left both
    ///   filters, 0.75^24 of it in the slow one), its variance a 24th of one reading's
    ///   instead of the filtered reading's third (fast) or seventh (slow):
    ///   `agree_seasoned` = 5 x 1.04
    ///   `sqrt(1/3 + 1/24)` = 3.2 channel counts + 1 encoder count (6.4 um, 0.021 deg),
    ///   `agree_slow_seasoned` = 5 x 1.04 `sqrt(1/7 + 1/24)` = 2.2 counts + 1 encoder
    ///   count (4.9 um, 0.017 deg);
    /// * the backlash: the legs' largest by the thesis (0.2 mm; the servo compensates 0.12
    ///   mm), on the links twice the compensated 20 arcsec (`backlash_width`, the servo's);
    /// * the scale: 0.2 % (the potentiometers' linearity class, 0.1 %, at the anchor and now),
    ///   over at most `reanchor` = 2 mm or 2 deg between anchors;
    /// * the jump: the joint's top speed `top_speed` (m/s, rad/s: its motor's no-load speed)
    ///   times 1.5 over one tick `dt`, and 8 counts of noise (7 and one converter step);
    /// * the drift speed: 0.5 mm/s on a leg, 0.5 deg/s on a link, a hundred times less
    ///   than a homing's approach and far above any drift of a healthy ratiometric
    ///   potentiometer (nothing but the noise);
    /// * the rails: 512 counts from either end (0.8 % of the travel; the reference
    ///   mechanics keep every joint 36 mm or 85 deg from its potentiometer's ends);
    /// * two ticks of persistence on the fast filter: one reading beyond the bound is not a
    ///   fault. The hold check's slower filter needs none: one reading moves it by a
    ///   quarter of its deviation, so a lone reading crosses `agree_slow` only when more
    ///   than 11 counts off (4 times its 2.8 channel counts; the noise is 1.04 counts rms,
    ///   and the fast filter's two ticks let through a lone reading up to 17 counts off),
    ///   while two ticks would cost a tick of motion on every finding. A miscounting
    ///   encoder (one count lost in `n`) leaves a disagreement of an `n`-th of its motor's
    ///   motion: a hold that keeps the motor
    ///   within `n * agree` (24 um on a leg, 0.081 deg on a link, for `n` = 3) leaves it
    ///   within what the channel resolves, and it may go unnamed (the safety
    ///   requirements' SR-5);
    /// * the standstill windows of the safe operating stop (`monitors::Standstill`);
    /// * a motor pushes its load on one flank beyond 5 % of its continuous current
    ///   `continuous_a` (A): the motors' own friction at rest takes up to about 3.5 %
    ///   (their no-load currents, data sheets, and 20 % more to break away);
    /// * a motor that moved two encoder counts or less did not move.
    pub fn reference(
        cal: &ChannelCalibration<S>,
        encoder_counts_per_unit: &[S; NUM_JOINTS],
        backlash_width: &[S; NUM_JOINTS],
        top_speed: &[S; NUM_JOINTS],
        continuous_a: &[S; NUM_JOINTS],
        dt: S,
    ) -> Self {
        let lsb = |j: usize| {
            cal.counts_per_unit
                .get(j)
                .map_or(S::zero(), |c| S::one() / *c)
        };
        let enc = |j: usize| {
            encoder_counts_per_unit
                .get(j)
                .map_or(S::zero(), |c| S::one() / *c)
        };
        let at = |a: &[S; NUM_JOINTS], j: usize| a.get(j).copied().unwrap_or_else(S::zero);
        // A reading's deviation: the noise (1 count rms) and the converter's quantisation
        // (`step^2 / 12`): 1.04 counts with the AD7689's one-count step, 4.73 counts with a
        // 12-bit converter's 16.
        let sigma = (S::one() + cal.step_counts * cal.step_counts / lit(12.0)).sqrt();
        let sigma_e = sigma * (lit::<S>(2.0 / 3.0)).sqrt();
        // The variance of a seasoned anchor, the mean of `SEASON_TICKS` readings, in units
        // of one reading's.
        let season = S::one() / lit(f64::from(SEASON_TICKS));
        let leg = |j: usize| j < 3;
        ChannelConfig {
            rails: [512, 65535 - 512],
            filter: lit(0.5),
            filter_slow: lit(0.25),
            agree_slow: core::array::from_fn(|j| {
                lit::<S>(5.0) * sigma * lit::<S>(2.0 / 7.0).sqrt() * lsb(j) + enc(j)
            }),
            agree: core::array::from_fn(|j| lit::<S>(5.0) * sigma_e * lsb(j) + enc(j)),
            season_ticks: SEASON_TICKS,
            agree_seasoned: core::array::from_fn(|j| {
                lit::<S>(5.0) * sigma * (lit::<S>(1.0 / 3.0) + season).sqrt() * lsb(j) + enc(j)
            }),
            agree_slow_seasoned: core::array::from_fn(|j| {
                lit::<S>(5.0) * sigma * (lit::<S>(1.0 / 7.0) + season).sqrt() * lsb(j) + enc(j)
            }),
            backlash: core::array::from_fn(|j| {
                if leg(j) {
                    lit(0.2e-3)
                } else {
                    at(backlash_width, j) * lit(2.0)
                }
            }),
            scale: lit(0.002),
            reanchor: core::array::from_fn(|j| {
                if leg(j) {
                    lit(2e-3)
                } else {
                    lit(2f64.to_radians())
                }
            }),
            persist_ticks: 2,
            drift_speed: core::array::from_fn(|j| {
                if leg(j) {
                    lit(0.5e-3)
                } else {
                    lit(0.5f64.to_radians())
                }
            }),
            jump: core::array::from_fn(|j| {
                at(top_speed, j) * lit(1.5) * dt + (lit::<S>(7.0) + cal.step_counts) * lsb(j)
            }),
            standstill: core::array::from_fn(|j| if leg(j) { lit(0.25e-3) } else { lit(0.005) }),
            push_current: continuous_a.map(|a| a * lit(0.05)),
            still: core::array::from_fn(|j| enc(j) * lit(2.0)),
            dt,
        }
    }
}

/// What the check needs of the tick besides the readings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelInputs<'a, S> {
    /// The channel's raw readings (None: the read failed).
    pub raw: Option<&'a [u16; NUM_JOINTS]>,
    /// Its positions by the calibration (m, rad).
    pub p: &'a [S; NUM_JOINTS],
    /// The motors' positions by the encoders, in joint units (m, rad).
    pub motor: &'a [S; NUM_JOINTS],
    /// The motor currents, A (their sign is the side the motor pushes its load to).
    pub current: &'a [S; NUM_JOINTS],
    /// The robot holds (a safe operating stop, or the brakes holding with torque off).
    pub holding: bool,
    /// The sensing's reference epoch (`Sensing::reference_epoch`): a new reference moves the
    /// encoders at once, and the check starts over.
    pub epoch: u32,
}

/// Readings of `h` a hold's anchor is the mean of once seasoned (see
/// [`ChannelConfig::reference`]).
const SEASON_TICKS: u16 = 24;

/// Ticks between two entries of a joint's history of `h` (the drift's rate is measured
/// over the history: 4 entries, 24 to 32 ticks).
const HISTORY_EVERY: u32 = 8;

/// One joint's state.
#[derive(Clone, Copy, Debug, PartialEq)]
struct JointState<S> {
    /// The filtered channel and motor.
    p: S,
    m: S,
    /// The last raw position (for the jump check).
    last: S,
    /// The window: the channel and the motor at its start, the least and the most `h`.
    start: (S, S),
    h_range: (S, S),
    /// The slowly filtered channel and motor.
    p_slow: S,
    m_slow: S,
    /// The motor's last unfiltered position.
    m_last: S,
    /// The hold, since it began.
    hold: Option<Hold<S>>,
    /// Ticks the window, the hold, have been over their bounds.
    over: u16,
    over_hold: u16,
    /// `h` every `HISTORY_EVERY` ticks, oldest first.
    history: [S; 4],
    /// The last disagreement and the motions it compares, channel and motor: (e, dp, dm).
    last_e: (S, S, S),
    /// At the last check the encoder saw less motion than the channel by more than half
    /// what the check allows: the disagreement.
    excess: Option<S>,
}

impl<S: Float> JointState<S> {
    fn at(p: S, m: S) -> Self {
        let h = p - m;
        let z = S::zero();
        JointState {
            p,
            m,
            last: p,
            start: (p, m),
            h_range: (h, h),
            p_slow: p,
            m_slow: m,
            m_last: m,
            hold: None,
            over: 0,
            over_hold: 0,
            history: [h; 4],
            last_e: (z, z, z),
            excess: None,
        }
    }
}

/// A hold: where the channel stood when it began, and its anchor: the flank the motor
/// holds the load on (+1: pushing towards +q, -1, 0: not known) and `h`, the channel and
/// the motor when the motor took it; `h` of the slow filter once that filter settled there;
/// the readings of `h` summed while the motor stood where it took the flank (how many, their
/// sum), and their mean once there are [`ChannelConfig::season_ticks`] of them.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Hold<S> {
    p0: S,
    flank: i8,
    anchor: [S; 3],
    anchor_slow: Option<S>,
    season: (u16, S),
    seasoned: Option<S>,
}

/// The monitor of the second channel (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelCheck<S> {
    cfg: ChannelConfig<S>,
    joints: [JointState<S>; NUM_JOINTS],
    started: bool,
    epoch: u32,
    ticks: u32,
}

impl<S: Float> ChannelCheck<S> {
    /// Nothing read yet.
    pub fn new(cfg: ChannelConfig<S>) -> Self {
        ChannelCheck {
            cfg,
            joints: [JointState::at(S::zero(), S::zero()); NUM_JOINTS],
            started: false,
            epoch: 0,
            ticks: 0,
        }
    }

    /// The settings.
    pub fn config(&self) -> &ChannelConfig<S> {
        &self.cfg
    }

    /// Starts over at the next reading (a cleared fault: from where the channels stand).
    pub fn restart(&mut self) {
        self.started = false;
    }

    /// The readings `raw` are the channel's failure: missing, or one at a rail.
    pub fn failed_reading(&self, raw: Option<&[u16; NUM_JOINTS]>) -> Option<Finding> {
        let Some(raw) = raw else {
            return Some(Finding::board::<S>(FaultCause::PositionSensor, S::zero()));
        };
        let [lo, hi] = self.cfg.rails;
        raw.iter().position(|c| *c <= lo || *c >= hi).map(|j| {
            let c = raw.get(j).copied().unwrap_or(0);
            Finding::joint(
                FaultCause::PositionSensor,
                j,
                S::from(c).unwrap_or_else(S::zero),
            )
        })
    }

    /// Whether joint `joint`'s encoder saw less motion than the channel by more than half
    /// what the check allows at the last check: the disagreement (m, rad), if so. A monitor whose finding a failing encoder explains (the motor model, the
    /// servo's tracking, the standstill) is then named as the encoder.
    pub fn explains(&self, joint: usize) -> Option<S> {
        if !self.started {
            return None;
        }
        self.joints.get(joint)?.excess
    }

    /// The last disagreement of joint `joint` and the motions it compares, channel and
    /// motor (m, rad): `(e, dp, dm)`.
    pub fn disagreement(&self, joint: usize) -> Option<(S, S, S)> {
        self.joints.get(joint).map(|s| s.last_e)
    }

    /// One tick's check (see the module documentation): the first finding, if any.
    pub fn check(&mut self, inputs: &ChannelInputs<'_, S>) -> Option<Finding> {
        if let Some(f) = self.failed_reading(inputs.raw) {
            self.started = false;
            return Some(f);
        }
        let c = self.cfg;
        if self.epoch != inputs.epoch {
            self.epoch = inputs.epoch;
            self.started = false;
        }
        if !self.started {
            self.started = true;
            for (j, s) in self.joints.iter_mut().enumerate() {
                *s = JointState::at(at(inputs.p, j), at(inputs.motor, j));
            }
        }
        self.ticks = self.ticks.wrapping_add(1);
        let record = self.ticks.is_multiple_of(HISTORY_EVERY);
        let mut found = None;
        for (j, s) in self.joints.iter_mut().enumerate() {
            let p_raw = at(inputs.p, j);
            let (agree, backlash) = (at(&c.agree, j), at(&c.backlash, j));
            // A reading beyond the joint's speed: the sensor jumped.
            let jumped = !((p_raw - s.last).abs() <= at(&c.jump, j));
            s.last = p_raw;
            if jumped {
                found = found.or(Some(Finding::joint(FaultCause::PositionSensor, j, p_raw)));
                continue;
            }
            let m_raw = at(inputs.motor, j);
            s.p = s.p + (p_raw - s.p) * c.filter;
            s.m = s.m + (m_raw - s.m) * c.filter;
            s.p_slow = s.p_slow + (p_raw - s.p_slow) * c.filter_slow;
            s.m_slow = s.m_slow + (m_raw - s.m_slow) * c.filter_slow;
            // The load less the motor: it spans the gap, no more, wherever they are.
            let h = s.p - s.m;
            let (lo, hi) = (s.h_range.0.min(h), s.h_range.1.max(h));
            s.h_range = (lo, hi);
            let (dp, dm) = (s.p - s.start.0, s.m - s.start.1);
            let bound = agree + backlash + c.scale * dp.abs();
            s.over = if hi - lo > bound {
                s.over.saturating_add(1)
            } else {
                0
            };
            // The disagreement: `h` from the far end of its range.
            let e = if h - lo > hi - h { h - lo } else { h - hi };
            let mut last = (e, dp, dm);
            // Past half its bound, a disagreement explains another monitor's finding on
            // the joint (the noise alone reaches it less than once in 10^4 readings).
            let window_excess = (hi - lo > bound * lit(0.5) && dm.abs() < dp.abs()).then_some(e);
            let mut excess = None;
            let mut named = (s.over >= c.persist_ticks).then_some(last);
            if s.over == 0 && dp.abs() >= at(&c.reanchor, j) {
                s.start = (s.p, s.m);
                s.h_range = (h, h);
            }
            // The hold.
            let standing = (m_raw - s.m_last).abs() <= at(&c.still, j) * lit(0.5);
            s.m_last = m_raw;
            if inputs.holding {
                let h_slow = s.p_slow - s.m_slow;
                let here = [h, s.p, s.m];
                let slow = at(&c.agree_slow, j);
                let slow_settled = (p_raw - s.p_slow).abs() <= slow * lit(0.5);
                // h = load - motor: a motor that holds the load on its +q flank (pushing
                // towards +q) has h at the least it can be; the load may leave the flank
                // (h grows) by the gap, but not press into it (h falls) without the motor.
                // The flank: the side the motor's current pushes to, where it pushes beyond
                // its friction (not the backlash compensation's belief: a load it does not
                // know of, the tool's weight, may rest the load on the other flank).
                let push = sign(at(inputs.current, j), at(&c.push_current, j));
                let hold = s.hold.get_or_insert(Hold {
                    p0: s.p,
                    flank: push,
                    anchor: here,
                    anchor_slow: None,
                    season: (0, S::zero()),
                    seasoned: None,
                });
                // A motor that comes to push on the other flank (or on one where none was
                // known), standing, with the channel settled: the flank from here on.
                let settled = (p_raw - s.p).abs() <= agree * lit(0.5);
                if push != 0 && push != hold.flank && standing && settled {
                    hold.flank = push;
                    hold.anchor = here;
                    hold.anchor_slow = None;
                    hold.season = (0, S::zero());
                    hold.seasoned = None;
                }
                if hold.anchor_slow.is_none() && slow_settled {
                    hold.anchor_slow = Some(h_slow);
                }
                let [ha, pa, ma] = hold.anchor;
                // The anchor seasoned: `season_ticks` raw readings of `h` while the motor
                // stood where it took the flank and `h` stayed there (the load on it), their
                // mean a far quieter anchor than one filtered reading.
                let (n, sum) = hold.season;
                let on_flank = (m_raw - ma).abs() <= at(&c.still, j)
                    && (h - ha).abs() <= agree * lit(0.5)
                    && hold.flank != 0;
                if hold.seasoned.is_none() && on_flank {
                    let (n, sum) = (n.saturating_add(1), sum + (p_raw - m_raw));
                    hold.season = (n, sum);
                    if n >= c.season_ticks {
                        hold.seasoned = S::from(n).map(|n| sum / n);
                    }
                }
                let (ha, anchor_slow, agree, slow) = match hold.seasoned {
                    Some(mean) => (
                        mean,
                        Some(mean),
                        at(&c.agree_seasoned, j),
                        at(&c.agree_slow_seasoned, j),
                    ),
                    None => (ha, hold.anchor_slow, agree, slow),
                };
                let de = h - ha;
                let de_slow = anchor_slow.map_or(S::zero(), |a| h_slow - a);
                // Into the flank: h below its anchor on the +q flank, above it on the -q.
                let side = S::from(-hold.flank).unwrap_or_else(S::zero);
                let into = (de * side, de_slow * side);
                // The slow filter's disagreement counts at once (see `persist_ticks`).
                let slow_beyond = hold.flank != 0 && into.1 > slow;
                let (beyond, half) = if hold.flank == 0 {
                    let both = agree + backlash;
                    (de.abs() > both, de.abs() > both * lit(0.5))
                } else {
                    (
                        into.0 > agree || into.1 > slow || -into.0 > agree + backlash,
                        into.0 > agree * lit(0.5) || into.1 > slow * lit(0.5),
                    )
                };
                let shown = if into.1 > into.0 { de_slow } else { de };
                let into = half.then_some((beyond, (shown, s.p - pa, s.m - ma)));
                let hdp = s.p - hold.p0;
                s.over_hold = match into {
                    Some((true, _)) => s.over_hold.saturating_add(1),
                    _ => 0,
                };
                if let Some((_, (de, dp, dm))) = into {
                    last = (de, dp, dm);
                    if dm.abs() < dp.abs() {
                        excess = Some(de);
                    }
                    if s.over_hold >= c.persist_ticks || slow_beyond {
                        named = named.or(Some((de, dp, dm)));
                    }
                }
                if s.over_hold < c.persist_ticks && hdp.abs() > at(&c.standstill, j) {
                    // Both channels agree that the joint left its window.
                    found = found.or(Some(Finding::joint(FaultCause::StandstillLost, j, hdp)));
                }
            } else {
                s.hold = None;
                s.over_hold = 0;
            }
            s.last_e = last;
            s.excess = excess.or(window_excess);
            let oldest = s.history.first().copied().unwrap_or(h);
            if record {
                s.history.rotate_left(1);
                if let Some(x) = s.history.last_mut() {
                    *x = h;
                }
            }
            if let Some((e, dp, dm)) = named {
                // A motor that did not move while the reading walked away slowly: the
                // sensor drifts (a stuck encoder under so slow a push cannot be told
                // from it).
                let span = S::from(HISTORY_EVERY * 4).unwrap_or_else(S::one) * c.dt;
                let rate = (h - oldest).abs() / span;
                let still = dm.abs() <= at(&c.still, j);
                let drifting = still && rate < at(&c.drift_speed, j);
                let cause = if dm.abs() < dp.abs() && !drifting {
                    FaultCause::EncoderDisagree
                } else {
                    FaultCause::PositionSensor
                };
                found = found.or(Some(Finding::joint(cause, j, e)));
            }
        }
        found
    }
}

/// The sign of `x` as -1, 0 or +1 (0 within `dead`).
fn sign<S: Float>(x: S, dead: S) -> i8 {
    if x > dead {
        1
    } else if x < -dead {
        -1
    } else {
        0
    }
}

fn at<S: Float>(a: &[S; NUM_JOINTS], j: usize) -> S {
    a.get(j).copied().unwrap_or_else(S::zero)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    /// Ticks the check runs before the hold begins.
    const WARM: u32 = 20;
    /// Encoder counts per metre of a leg (1.5 um per count, `servo::encoder`'s order).
    const ENC: f64 = 1.0 / 1.5e-6;

    fn config() -> (ChannelCalibration<f64>, ChannelConfig<f64>) {
        let cal = ChannelCalibration::<f64>::reference(&[[0.141, 0.213]; NUM_JOINTS]);
        let c = ChannelConfig::reference(
            &cal,
            &[ENC; NUM_JOINTS],
            &[1e-4; NUM_JOINTS],
            &[0.05; NUM_JOINTS],
            &[1.0; NUM_JOINTS],
            1e-3,
        );
        (cal, c)
    }

    /// Zero-mean noise of 1 count rms (four uniforms, as the plant's) from `state`.
    fn noise(state: &mut u64) -> f64 {
        let mut sum = 0.0;
        for _ in 0..4 {
            *state ^= *state << 13;
            *state ^= *state >> 7;
            *state ^= *state << 17;
            sum += (*state >> 11) as f64 / (1u64 << 53) as f64;
        }
        (sum - 2.0) * 3f64.sqrt()
    }

    /// The check running for 20 ticks, then joint 0 held on its -q flank (the motor pushing
    /// towards -q), standing `stand` ticks,
    /// then moving with its load at `v` m per tick for `moving` ticks, its encoder counting
    /// `kept` of the motion; the channel noisy (seed `seed`). The first finding and the
    /// motor's motion then.
    fn hold(seed: u64, stand: u32, v: f64, moving: u32, kept: f64) -> Option<(Finding, f64)> {
        let (cal, c) = config();
        let mut check = ChannelCheck::new(c);
        let mut rng = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let q0 = 0.177 + 3.3e-7;
        for k in 0..WARM + stand + moving {
            let moved = v * f64::from(k.saturating_sub(WARM + stand));
            let raw: [u16; NUM_JOINTS] = core::array::from_fn(|j| {
                let q = if j == 0 { q0 + moved } else { q0 };
                let x = MID_SCALE + (q - 0.177) * cal.counts_per_unit[j] + noise(&mut rng);
                x.round() as u16
            });
            let p = cal.positions(&raw);
            let m0 = ((q0 + moved * kept) * ENC).floor() / ENC;
            let motor: [f64; NUM_JOINTS] =
                core::array::from_fn(|j| if j == 0 { m0 } else { (q0 * ENC).floor() / ENC });
            let current = [-1.0; NUM_JOINTS];
            let found = check.check(&ChannelInputs {
                raw: Some(&raw),
                p: &p,
                motor: &motor,
                current: &current,
                holding: k >= WARM,
                epoch: 0,
            });
            if let Some(f) = found {
                return Some((f, moved));
            }
        }
        None
    }

    /// Property: a joint held on its flank, its encoder losing one count in three as a push
    /// moves it 1 um per tick, is named as the encoder before its motor moved 3 times
    /// `agree_seasoned` (the disagreement is a third of the motion; the slow filter's
    /// seasoned bound is below it) and two ticks more; the same motion with a healthy
    /// encoder, and a long hold, raise nothing.
    #[test]
    fn a_seasoned_hold_names_a_miscount_and_nothing_else() {
        let (_, c) = config();
        let v = 1e-6;
        let x = 3.0 * c.agree_seasoned[0] + 2.0 * v;
        for seed in 0..200 {
            let (f, moved) = hold(seed, 30, v, 100, 2.0 / 3.0).expect("named");
            assert_eq!(
                (f.cause, f.joint),
                (FaultCause::EncoderDisagree, Some(0)),
                "seed {seed}"
            );
            assert!(moved <= x, "seed {seed}: moved {moved} > {x}");
            assert_eq!(hold(seed, 30, v, 100, 1.0), None, "seed {seed}");
            assert_eq!(hold(seed, 3000, 0.0, 0, 1.0), None, "seed {seed}");
        }
    }
}
