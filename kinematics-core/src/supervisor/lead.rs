//! The lead: the supervisor heads for where the master's stream will be, not where it was.
//!
//! The profile stops at its goal (the braking curve), so a robot following a goal that
//! moves at speed u trails it by D = u²/2a' + u·dt, where the braking curve's speed is u
//! (a' the curve's deceleration): 1.34 mm, 54 ms behind the master at 25 mm/s and
//! 250 mm/s². A target led by D along the stream's path puts the robot on the master's
//! pose; the lag is then what verification takes. The path ahead is predicted to second
//! order (the velocity and its change across it, measured over windows of the stream): on
//! a curve, a lead along the tangent alone would sit D²/2R outside the path and move
//! faster than the stream, so that a robot at its speed limit would fall behind it on
//! every curve. The master has also moved on since the target's stamp, by the target's
//! delay on arrival and, until the next target, by up to a period of the stream: the lead
//! covers the delay and the target's mean age at the ticks it is the newest, (T - dt)/2
//! for a period T (nothing for a target every tick).
//!
//! Only the translation is led. The rotation follows the master's own orientation: a
//! rotation lead of ω/2α' (1.1 deg at 25 deg/s) reaches far beyond the certified regions
//! (at most about 0.5 deg), so led rotations would be path-checked one by one instead of
//! accepted at once.
//!
//! Safety is unchanged: a led target is a target like any other (accepted at once inside a
//! certified region, else verified along its path, see the supervisor). A led target
//! whose path check fails is not a refusal: the lead pauses for [`HOLD_OFF_US`] and the
//! master's own target is verified instead. What the lead changes is where the robot
//! stops when the stream stops without slowing down first: up to D beyond the master's
//! last pose (a verified pose), and back to that pose once the stream has stood still for
//! a window or fallen silent for [`SILENCE_US`]. A stream that slows down within the
//! robot's deceleration brings the lead down with it.

use crate::pose::Pose;
use crate::scalar::{dot3, lit, norm3, Real};
use nalgebra::Vector3;

/// The stream's velocity is measured over windows of at least this long, µs (the
/// master's pose is noisy at 1 kHz; over 10 ms its quantisation averages out).
pub const WINDOW_US: u64 = 10_000;
/// A window longer than this means the stream was interrupted: the velocity is taken as
/// zero, µs.
pub const GAP_US: u64 = 50_000;
/// After this long without a target, the goal goes back to the master's last target, µs.
pub const SILENCE_US: u64 = 50_000;
/// After a led target's path check failed the lead pauses this long, µs.
pub const HOLD_OFF_US: u64 = 200_000;
/// The lead never exceeds this time at the followed speed, s (a deceleration scaled far
/// down near a singularity would ask for long leads).
pub const MAX_LEAD_S: f64 = 0.1;

/// How far the braking curve trails a goal moving at speed `u` (deceleration `a`, already
/// the curve's share of the limit): D = u²/2a + u·dt, where the curve's speed is u; at
/// most u × [`MAX_LEAD_S`]. Zero for a deceleration that is not positive.
pub fn lead_distance<T: Real>(u: T, a: T, dt: T) -> T {
    if !(a > T::zero() && u > T::zero()) {
        return T::zero();
    }
    u * (u / (lit::<T>(2.0) * a) + dt).min(lit(MAX_LEAD_S))
}

/// The master's stream as the lead sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stream<T: Real> {
    /// The target that opened the current window, and its stamp.
    anchor: Option<(Pose<T>, u64)>,
    /// The stream's velocity at the end of the last closed window, m/s (world frame): the
    /// window's mean velocity carried on by the change since the window before over half
    /// a window (exact for a stream accelerating uniformly, as a master's hand does on a
    /// ramp; the mean alone lags half a window behind).
    v: Vector3<T>,
    /// The last window's mean velocity, m/s.
    mean: Vector3<T>,
    /// The last window's length, s (0: no window yet).
    span_s: T,
    /// The stream's acceleration across its velocity (the curve's centripetal part), from
    /// the change of the mean velocity between the last two windows, m/s².
    accel: Vector3<T>,
    /// The newest target's time after the end of the last closed window, s.
    age_s: T,
    /// Targets in the current window, and the stream's period over the last closed one
    /// (its span over its targets), s.
    count: u32,
    period_s: T,
    /// The master's newest target.
    newest: Option<Pose<T>>,
    /// A led target was taken since the stream last fell silent: on silence the goal goes
    /// back to the master's newest target.
    leading: bool,
    /// Time since the last target, µs.
    silent_us: u64,
    /// The lead pauses this long yet, µs.
    hold_off_us: u64,
}

impl<T: Real> Default for Stream<T> {
    fn default() -> Self {
        Stream {
            anchor: None,
            v: Vector3::zeros(),
            mean: Vector3::zeros(),
            span_s: T::zero(),
            accel: Vector3::zeros(),
            age_s: T::zero(),
            count: 0,
            period_s: T::zero(),
            newest: None,
            leading: false,
            silent_us: 0,
            hold_off_us: 0,
        }
    }
}

impl<T: Real> Stream<T> {
    /// A target of the stream arrived, stamped `stamp_us`: the velocity is updated when
    /// its window closes.
    pub fn observe(&mut self, target: &Pose<T>, stamp_us: u64) {
        self.silent_us = 0;
        self.newest = Some(*target);
        let Some((from, t0)) = self.anchor else {
            self.anchor = Some((*target, stamp_us));
            self.count = 0;
            return;
        };
        let span = stamp_us.saturating_sub(t0);
        let span_s = lit::<T>(span as f64 * 1e-6);
        self.count = self.count.saturating_add(1);
        if span < WINDOW_US {
            self.age_s = span_s;
            return;
        }
        self.age_s = T::zero();
        self.period_s = span_s / lit::<T>(f64::from(self.count));
        self.count = 0;
        if span > GAP_US {
            self.v = Vector3::zeros();
            self.mean = Vector3::zeros();
            self.span_s = T::zero();
            self.accel = Vector3::zeros();
        } else {
            let mean = (target.t - from.t) * (T::one() / span_s);
            // Mean velocities half a window apart at each end: the change over the last
            // window carried on by half a window (the mean alone after a gap or for the
            // first window: there is no earlier mean to take the change from).
            self.v = if self.span_s > T::zero() {
                mean + (mean - self.mean) * lit::<T>(0.5)
            } else {
                mean
            };
            // The change of the mean velocity between the windows' middles, its part
            // across the velocity (the part along it changes the speed, which the braking
            // curve follows on its own).
            self.accel = if self.span_s > T::zero() {
                let a = (mean - self.mean) * (lit::<T>(2.0) / (span_s + self.span_s));
                let u2 = dot3(&self.v, &self.v);
                if u2 > T::zero() {
                    a - self.v * (dot3(&a, &self.v) / u2)
                } else {
                    Vector3::zeros()
                }
            } else {
                Vector3::zeros()
            };
            self.mean = mean;
            self.span_s = span_s;
        }
        self.anchor = Some((*target, stamp_us));
    }

    /// The stream's velocity, m/s.
    pub fn velocity(&self) -> &Vector3<T> {
        &self.v
    }

    /// `target` with its translation led along the stream's path by the braking curve's
    /// distance at the speed the robot can follow (the stream's, at most `cap`),
    /// deceleration `a` ([`lead_distance`]); `None` while the stream stands still or the
    /// lead pauses.
    ///
    /// The master has moved on since the target's stamp: by its delay on arrival,
    /// `delay_s` (the link's latency), and, at the ticks until the next target, by 0, dt,
    /// .., T - dt more for a stream period T: (T - dt)/2 on average. The lead covers that
    /// too: τ = D/u + delay + (T - dt)/2 ahead of the target's stamp (at most
    /// [`MAX_LEAD_S`]), so that the robot is on the master's pose of the moment, not of
    /// the stamp.
    ///
    /// The path ahead is predicted to second order: the stream's velocity carried on to
    /// the target's time and bent by its acceleration across the velocity (at most `a`,
    /// more than any curve the robot can follow at its speed): on a curve of radius R a
    /// lead along the tangent alone would sit D²/2R outside it, and move faster than the
    /// stream by the factor √(1 + (D/R)²), which a robot at its speed limit cannot
    /// follow.
    pub fn led(&self, target: &Pose<T>, cap: T, a: T, dt: T, delay_s: T) -> Option<Pose<T>> {
        let u = norm3(&self.v);
        if !(u > T::zero()) || self.hold_off_us > 0 {
            return None;
        }
        let d = lead_distance(u.min(cap), a, dt);
        let late = if delay_s > T::zero() {
            delay_s
        } else {
            T::zero()
        };
        let held = if self.period_s > dt {
            (self.period_s - dt) * lit::<T>(0.5)
        } else {
            T::zero()
        };
        let tau = (d / u + late + held).min(lit(MAX_LEAD_S));
        let bend = norm3(&self.accel);
        let across = if bend > a {
            self.accel * (a / bend)
        } else {
            self.accel
        };
        let ahead = (self.v + across * self.age_s) * tau + across * (lit::<T>(0.5) * tau * tau);
        let led = target.displaced(&ahead, &Vector3::zeros());
        (d > T::zero() && led.is_finite()).then_some(led)
    }

    /// A led target was taken (to be verified, or accepted at once).
    pub fn lead_taken(&mut self) {
        self.leading = true;
    }

    /// One control tick of `dt_us`: the master's newest target to go back to when the
    /// stream has been silent for [`SILENCE_US`] after a led target was taken (once). The
    /// newest, not the one the last accepted led target leads: newer targets may still be
    /// in verification, and going back to an older one would supersede them.
    pub fn tick(&mut self, dt_us: u64) -> Option<Pose<T>> {
        self.hold_off_us = self.hold_off_us.saturating_sub(dt_us);
        self.silent_us = self.silent_us.saturating_add(dt_us);
        if self.silent_us < SILENCE_US {
            return None;
        }
        self.anchor = None;
        self.v = Vector3::zeros();
        self.mean = Vector3::zeros();
        self.span_s = T::zero();
        self.accel = Vector3::zeros();
        self.count = 0;
        self.period_s = T::zero();
        if !core::mem::take(&mut self.leading) {
            return None;
        }
        self.newest
    }

    /// A led target's path check failed: no lead for [`HOLD_OFF_US`].
    pub fn hold_off(&mut self) {
        self.hold_off_us = HOLD_OFF_US;
    }

    /// Forgets the stream (a stop, a clear, a brake).
    pub fn reset(&mut self) {
        *self = Stream::default();
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn at(x_mm: f64) -> Pose<f64> {
        Pose {
            t: Vector3::new(x_mm * 1e-3, 0.0, 0.16),
            r: Rotation3::identity(),
        }
    }

    /// A stream at 25 mm/s along x, one target per ms from `t0_us`, for `n` targets.
    fn stream(s: &mut Stream<f64>, t0_us: u64, n: u64) -> Pose<f64> {
        let mut last = at(0.0);
        for k in 0..n {
            let t = t0_us + k * 1000;
            last = at(25.0 * t as f64 * 1e-6);
            s.observe(&last, t);
        }
        last
    }

    #[test]
    fn the_lead_is_the_braking_curves_distance_at_the_followed_speed() {
        let (a, dt) = (0.95 * 0.25, 1e-3);
        // D = u²/2a + u·dt at 25 mm/s: 1.3158 + 0.025 mm.
        let d = lead_distance(0.025, a, dt);
        assert!((d - (0.025f64.powi(2) / (2.0 * a) + 0.025 * dt)).abs() < 1e-15);
        assert!((d * 1e3 - 1.3408).abs() < 1e-4, "{d}");
        // The braking curve's speed at D is u: the robot keeps pace D behind the goal.
        let curve = (a * a * dt * dt + 2.0 * a * d).sqrt() - a * dt;
        assert!((curve - 0.025).abs() < 1e-12);
        assert_eq!(lead_distance(0.025, 0.0, dt), 0.0);
        assert_eq!(lead_distance(0.0, a, dt), 0.0);
        // Bounded by u × MAX_LEAD_S.
        assert!((lead_distance(0.025, 1e-3, dt) - 0.025 * MAX_LEAD_S).abs() < 1e-15);
    }

    #[test]
    fn the_stream_velocity_is_measured_over_windows_and_the_target_led_along_it() {
        // After the first window the velocity is its mean (no earlier window to carry a
        // change on from: not 1.5x the mean, as the change from zero would give).
        let mut first = Stream::default();
        stream(&mut first, 1_000_000, 11);
        assert!((first.velocity() - Vector3::new(0.025, 0.0, 0.0)).norm() < 1e-12);
        let mut s = Stream::default();
        let last = stream(&mut s, 1_000_000, 25);
        assert!((s.velocity() - Vector3::new(0.025, 0.0, 0.0)).norm() < 1e-12);
        let (a, dt) = (0.2375, 1e-3);
        // One target per ms, one per tick: the braking curve's distance.
        assert!((s.period_s - 1e-3).abs() < 1e-15);
        let led = s.led(&last, 0.025, a, dt, 0.0).unwrap();
        let ahead = led.t - last.t;
        assert!((ahead.x - lead_distance(0.025, a, dt)).abs() < 1e-15);
        assert!(ahead.y.abs() + ahead.z.abs() < 1e-18 && led.r == last.r);
        // A target 3 ms old on arrival: 3 ms more.
        let late = s.led(&last, 0.025, a, dt, 3e-3).unwrap();
        let more = (late.t - last.t).x - ahead.x;
        assert!((more - 0.025 * 3e-3).abs() < 1e-15, "{more}");
        // A stream faster than the robot is led by the robot's distance.
        let fast = s.led(&last, 0.010, a, dt, 0.0).unwrap();
        let expected = lead_distance(0.010, a, dt);
        assert!(((fast.t - last.t).x - expected).abs() < 1e-15);
        // Never more than MAX_LEAD_S ahead of the stamp, however old the target.
        let old = s.led(&last, 0.025, a, dt, 1.0).unwrap();
        assert!(((old.t - last.t).x - 0.025 * MAX_LEAD_S).abs() < 1e-15);
        // A stream at 100 Hz: its mean age over the ticks it is the newest, 4.5 ms.
        let mut slow = Stream::default();
        for k in 0..5u64 {
            slow.observe(&at(0.25 * k as f64), 1_000_000 + k * 10_000);
        }
        assert!((slow.period_s - 10e-3).abs() < 1e-15);
        let led = slow.led(&at(1.0), 0.025, a, dt, 0.0).unwrap();
        let expected = lead_distance(0.025, a, dt) + 0.025 * 4.5e-3;
        assert!(((led.t - at(1.0).t).x - expected).abs() < 1e-12);
        // Paused: no lead.
        s.hold_off();
        assert!(s.led(&last, 0.025, a, dt, 0.0).is_none());
        for _ in 0..HOLD_OFF_US / 1000 {
            assert!(s.led(&last, 0.025, a, dt, 0.0).is_none());
            s.tick(1000);
            s.silent_us = 0; // (the stream goes on)
        }
        assert!(s.led(&last, 0.025, a, dt, 0.0).is_some());
    }

    /// A stream on a circle of radius R at 25 mm/s, one target per ms: the led target
    /// lies on the circle (within R θ⁴/8 + 4 µm, θ = D/R: 7 µm at R = 5 mm; a lead along
    /// the tangent alone sits D²/2R outside it, 180 µm at R = 5 mm) and D along it; on a
    /// curve tighter than the
    /// robot can follow at that speed the bend is capped at the deceleration `a`.
    #[test]
    fn on_a_curve_the_lead_stays_on_the_path() {
        let (a, dt, u) = (0.2375, 1e-3, 0.025);
        let d = lead_distance(u, a, dt);
        for r_mm in [5.0, 10.0, 20.0, 50.0] {
            let r = r_mm * 1e-3;
            let at = |k: u64| {
                let phi = u * (k as f64 * 1e-3) / r;
                Pose {
                    t: Vector3::new(r * phi.cos(), r * phi.sin(), 0.16),
                    r: Rotation3::identity(),
                }
            };
            let mut s = Stream::default();
            for k in 0..57 {
                let target = at(k);
                s.observe(&target, 1_000_000 + k * 1000);
                if k < 40 {
                    continue;
                }
                let led = s.led(&target, u, a, dt, 0.0).unwrap();
                let radial = (led.t.xy().norm() - r).abs();
                let along = (led.t - target.t).norm();
                // The second-order prediction's own error, R θ⁴/8 (θ = D/R), and 4 µm for
                // the velocity and acceleration measured over 10-ms windows and carried on
                // up to a window.
                let bound = r * (d / r).powi(4) / 8.0 + 4e-6;
                assert!(
                    radial < bound,
                    "R {r_mm} mm, target {k}: {radial:e} m off the circle"
                );
                // D ahead (one target per tick).
                let lead = d;
                assert!(
                    (along - lead).abs() < 0.02 * lead,
                    "R {r_mm} mm: {along} m ahead, D {d}"
                );
            }
        }
        // A curve of R = 1 mm at 25 mm/s needs 0.625 m/s² across the path: capped at `a`.
        let r = 1e-3;
        let mut s = Stream::default();
        let mut last = at(0.0);
        for k in 0..60u64 {
            let phi = u * (k as f64 * 1e-3) / r;
            last = Pose {
                t: Vector3::new(r * phi.cos(), r * phi.sin(), 0.16),
                r: Rotation3::identity(),
            };
            s.observe(&last, k * 1000);
        }
        assert!((norm3(&s.accel) - u * u / r).abs() < 0.1 * u * u / r);
        let led = s.led(&last, u, a, dt, 0.0).unwrap();
        let tau = d / norm3(s.velocity());
        let straight = last.t + s.velocity() * tau;
        let bent = (led.t - straight).norm();
        assert!(bent <= a * (s.age_s * tau + 0.5 * tau * tau) * (1.0 + 1e-12));
    }

    #[test]
    fn a_stream_standing_still_or_interrupted_is_not_led() {
        let mut s = Stream::default();
        let p = at(3.0);
        for k in 0..30 {
            s.observe(&p, 1_000_000 + k * 1000);
        }
        assert!(s.led(&p, 0.025, 0.2375, 1e-3, 0.0).is_none());
        // A window longer than GAP_US: the velocity is zero.
        let mut s = Stream::default();
        s.observe(&at(0.0), 0);
        s.observe(&at(5.0), GAP_US + 1);
        assert_eq!(*s.velocity(), Vector3::zeros());
    }

    #[test]
    fn a_silent_stream_gives_back_the_masters_target_once() {
        let mut s = Stream::default();
        let last = stream(&mut s, 0, 20);
        s.lead_taken();
        for _ in 0..SILENCE_US / 1000 - 1 {
            assert!(s.tick(1000).is_none());
        }
        assert_eq!(s.tick(1000), Some(last));
        assert!(s.tick(1000).is_none());
        assert_eq!(*s.velocity(), Vector3::zeros());
        // A stream no led target was taken from gives nothing back.
        let mut s = Stream::default();
        stream(&mut s, 0, 20);
        assert!((0..100).all(|_| s.tick(1000).is_none()));
    }
}
