//! A synthetic operator: the hand's motion as the voluntary path plus physiological
//! tremor, known exactly, to measure what the teleoperation chain does to each.
//!
//! - **Voluntary motion** (0-2 Hz): surgical-like strokes, each a minimum-jerk move
//!   `x(τ) = x0 + d (10 τ³ − 15 τ⁴ + 6 τ⁵)`, `τ = t/T` (Flash and Hogan 1985: the profile of
//!   unconstrained reaching), of 2-8 mm in 0.7-1.4 s (peak speed `1.875 d/T` ≤ 12 mm/s),
//!   with small rotations of 1-3 deg, suturing arcs (circles of 2-3 mm in 2-2.5 s, the
//!   angle itself a minimum-jerk turn), and
//!   pauses of 0.4-1 s in between.
//! - **Tremor** (8-12 Hz): a sinusoid whose frequency drifts,
//!   `f(t) = 10 + 1.5 sin(2π t/13) + 0.5 sin(2π t/3.7)` Hz (within 8-12 Hz), and whose
//!   amplitude drifts, `A(t) = 125 + 75 sin(2π t/9 + 0.5)` µm (50-200 µm), on x, y, z
//!   with factors 1, 0.8, 0.6 and phases 0, 0.9, 2.1 rad; on the rotation
//!   `A(t) × 10 rad/m` (0.5-2 mrad) with the same phases. It goes on through the pauses
//!   (postural tremor).
//!
//! Positions are offsets from the hand's start, m; rotations rotation vectors, rad.

use crate::pose::{rotate, CartesianPose, Twist};
use nalgebra::{UnitQuaternion, Vector3};
use std::f64::consts::PI;

/// One stroke of the voluntary path.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stroke {
    /// A minimum-jerk move by `d` (m) and `r` (rad) over `duration_s`.
    Move {
        d: [f64; 3],
        r: [f64; 3],
        duration_s: f64,
    },
    /// A circle of `radius_m` in the x-y plane at `hz`, one turn, back where it started.
    Arc { radius_m: f64, hz: f64 },
    /// Still for `duration_s`.
    Pause { duration_s: f64 },
}

impl Stroke {
    fn duration_s(&self) -> f64 {
        match *self {
            Stroke::Move { duration_s, .. } | Stroke::Pause { duration_s } => duration_s,
            Stroke::Arc { hz, .. } => 1.0 / hz,
        }
    }

    /// Position and rotation offsets `t` s into the stroke.
    fn at(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        match *self {
            Stroke::Move { d, r, duration_s } => {
                let tau = (t / duration_s).clamp(0.0, 1.0);
                // minimum jerk: 10 τ³ − 15 τ⁴ + 6 τ⁵
                let s = tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
                (d.map(|x| x * s), r.map(|x| x * s))
            }
            Stroke::Arc { radius_m, hz } => {
                // starts and ends at rest: the angle follows a minimum-jerk turn
                let tau = (t * hz).clamp(0.0, 1.0);
                let s = tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
                let a = 2.0 * PI * s;
                (
                    [radius_m * (a.cos() - 1.0), radius_m * a.sin(), 0.0],
                    [0.0; 3],
                )
            }
            Stroke::Pause { .. } => ([0.0; 3], [0.0; 3]),
        }
    }
}

/// The synthetic operator.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticOperator {
    /// (start time, stroke, position and rotation at its start).
    strokes: Vec<(f64, Stroke, [f64; 3], [f64; 3])>,
    duration_s: f64,
    /// Whether the tremor is on.
    tremor: bool,
}

impl SyntheticOperator {
    /// The surgical-like session described in the module documentation, about 24 s: a
    /// pause, reaches, a suturing arc, reaches back, pauses.
    pub fn surgical() -> Self {
        let mv = |d: [f64; 3], r_deg: [f64; 3], duration_s: f64| Stroke::Move {
            d: d.map(|x| x * 1e-3),
            r: r_deg.map(f64::to_radians),
            duration_s,
        };
        let pause = |duration_s| Stroke::Pause { duration_s };
        let list = [
            pause(1.0),
            mv([6.0, 2.0, -1.0], [1.0, 0.0, 2.0], 1.2),
            pause(0.6),
            mv([-2.0, 5.0, 0.5], [0.0, -1.5, 0.0], 1.0),
            pause(0.4),
            Stroke::Arc {
                radius_m: 0.003,
                hz: 0.4,
            },
            pause(0.8),
            mv([3.0, -3.0, 2.0], [-1.0, 1.0, 3.0], 0.8),
            mv([-8.0, 0.0, -1.0], [0.0, 0.5, -2.0], 1.4),
            pause(1.0),
            mv([2.0, -4.0, 0.0], [0.0, 0.0, -3.0], 0.7),
            pause(0.5),
            Stroke::Arc {
                radius_m: 0.002,
                hz: 0.5,
            },
            mv([-1.0, 0.0, -0.5], [0.0, 0.0, 0.0], 0.9),
            pause(0.6),
            mv([4.0, 3.0, 1.0], [2.0, 0.0, 0.0], 1.1),
            pause(0.5),
            mv([-4.0, -3.0, -1.0], [-3.0, 0.0, 0.0], 1.1),
            pause(1.0),
            mv([5.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0),
            mv([-5.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0),
            pause(1.0),
        ];
        let mut strokes = Vec::with_capacity(list.len());
        let (mut t, mut p, mut r) = (0.0, [0.0; 3], [0.0; 3]);
        for s in list {
            strokes.push((t, s, p, r));
            let (dp, dr) = s.at(s.duration_s());
            for i in 0..3 {
                if let (Some(a), Some(b), Some(c), Some(d)) =
                    (p.get_mut(i), dp.get(i), r.get_mut(i), dr.get(i))
                {
                    *a += b;
                    *c += d;
                }
            }
            t += s.duration_s();
        }
        SyntheticOperator {
            strokes,
            duration_s: t,
            tremor: true,
        }
    }

    /// The same session without tremor (or with, `on`).
    pub fn with_tremor(mut self, on: bool) -> Self {
        self.tremor = on;
        self
    }

    /// How long the session lasts, s.
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    /// The voluntary motion at `t`: position offset (m) and rotation vector (rad).
    pub fn voluntary(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let i = self.strokes.partition_point(|(t0, ..)| *t0 <= t);
        let Some((t0, s, p0, r0)) = self.strokes.get(i.saturating_sub(1)) else {
            return ([0.0; 3], [0.0; 3]);
        };
        let (dp, dr) = s.at(t - t0);
        let mut p = *p0;
        let mut r = *r0;
        for (a, b) in p.iter_mut().zip(dp) {
            *a += b;
        }
        for (a, b) in r.iter_mut().zip(dr) {
            *a += b;
        }
        (p, r)
    }

    /// The tremor's frequency at `t`, Hz.
    pub fn tremor_hz(t: f64) -> f64 {
        10.0 + 1.5 * (2.0 * PI * t / 13.0).sin() + 0.5 * (2.0 * PI * t / 3.7).sin()
    }

    /// The tremor's amplitude at `t`, m.
    pub fn tremor_amplitude_m(t: f64) -> f64 {
        1e-6 * (125.0 + 75.0 * (2.0 * PI * t / 9.0 + 0.5).sin())
    }

    /// The tremor's phase at `t`: 2π ∫ f, rad (the integral of [`Self::tremor_hz`] in
    /// closed form).
    fn tremor_phase(t: f64) -> f64 {
        let a = 1.5 * 13.0 / (2.0 * PI) * (1.0 - (2.0 * PI * t / 13.0).cos());
        let b = 0.5 * 3.7 / (2.0 * PI) * (1.0 - (2.0 * PI * t / 3.7).cos());
        2.0 * PI * (10.0 * t + a + b)
    }

    /// The tremor at `t`: position (m) and rotation vector (rad); zero when off.
    pub fn tremor(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        if !self.tremor {
            return ([0.0; 3], [0.0; 3]);
        }
        let a = Self::tremor_amplitude_m(t);
        let ph = Self::tremor_phase(t);
        let f = [1.0, 0.8, 0.6];
        let phase = [0.0, 0.9, 2.1];
        let mut p = [0.0; 3];
        let mut r = [0.0; 3];
        for i in 0..3 {
            if let (Some(pi), Some(ri), Some(fi), Some(phi)) =
                (p.get_mut(i), r.get_mut(i), f.get(i), phase.get(i))
            {
                *pi = a * fi * (ph + phi).sin();
                *ri = 10.0 * *pi;
            }
        }
        (p, r)
    }

    /// The hand's pose at `t` starting from `origin`: voluntary motion plus tremor.
    pub fn hand(&self, origin: &CartesianPose, t: f64) -> CartesianPose {
        let (vp, vr) = self.voluntary(t);
        let (tp, tr) = self.tremor(t);
        offset(origin, vp, vr, tp, tr)
    }

    /// The voluntary pose at `t` from `origin`.
    pub fn voluntary_pose(&self, origin: &CartesianPose, t: f64) -> CartesianPose {
        let (vp, vr) = self.voluntary(t);
        offset(origin, vp, vr, [0.0; 3], [0.0; 3])
    }

    /// The hand's twist at `t` (central difference over 0.1 ms): what a rate master's
    /// deflection commands when its integral is to be the hand's path.
    pub fn hand_twist(&self, t: f64) -> Twist {
        let h = 1e-4;
        let o = CartesianPose {
            position_m: Vector3::zeros(),
            orientation: UnitQuaternion::identity(),
        };
        let (a, b) = (self.hand(&o, t - h / 2.0), self.hand(&o, t + h / 2.0));
        Twist {
            linear_m_s: (b.position_m - a.position_m) / h,
            angular_rad_s: crate::pose::rotation_increment(&a.orientation, &b.orientation) / h,
        }
    }
}

fn offset(
    origin: &CartesianPose,
    vp: [f64; 3],
    vr: [f64; 3],
    tp: [f64; 3],
    tr: [f64; 3],
) -> CartesianPose {
    let p = Vector3::from(vp) + Vector3::from(tp);
    let r = Vector3::from(vr) + Vector3::from(tr);
    CartesianPose {
        position_m: origin.position_m + p,
        orientation: rotate(&origin.orientation, &r),
    }
}
