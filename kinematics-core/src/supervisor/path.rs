//! The path check's geometry: the straight segment to a target (translation linear,
//! rotation about a fixed world axis), sampled at `path_step` / `path_step_angle`, the end
//! point first, and the progress of a path in verification.

use crate::pose::{rotation_angle, rotation_vector, Pose};
use crate::scalar::{lit, norm3, scale3, sub3, to_f64, Real};
use nalgebra::Vector3;

/// A target to verify: the pose, the master's plain target when the pose leads it along
/// the stream (see [`super::lead`]), and the stamp it was submitted with (its identity in
/// a refusal, [`super::Refusal::Path`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Target<T: Real> {
    pub to: Pose<T>,
    pub plain: Option<Pose<T>>,
    pub stamp_us: u64,
}

impl<T: Real> Target<T> {
    /// The master's target as it came, stamped `stamp_us`.
    pub fn plain(to: &Pose<T>, stamp_us: u64) -> Self {
        Target {
            to: *to,
            plain: None,
            stamp_us,
        }
    }
}

/// A path in verification: the straight segment `from` → `to`, in `samples` steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Pending<T: Real> {
    from: Pose<T>,
    to: Pose<T>,
    /// The master's plain target when `to` leads it.
    plain: Option<Pose<T>>,
    /// The target's stamp.
    stamp_us: u64,
    /// The whole segment ([`segment`]), computed once, not for every sample.
    dv: Vector3<T>,
    dw: Vector3<T>,
    samples: u16,
    /// Next sample to check; sample `samples` (the end) is checked first.
    next: u16,
    end_checked: bool,
}

impl<T: Real> Pending<T> {
    /// The path from `from` to the target `t`, `n` samples long (unrounded, see
    /// [`samples_between`]; at least one).
    pub fn new(from: &Pose<T>, t: &Target<T>, n: T) -> Self {
        let n = n.ceil().max(T::one());
        let samples = to_f64(n) as u16;
        let (dv, dw) = segment(from, &t.to);
        Pending {
            from: *from,
            to: t.to,
            plain: t.plain,
            stamp_us: t.stamp_us,
            dv,
            dw,
            samples: samples.max(1),
            next: 1,
            end_checked: false,
        }
    }

    /// The target the path leads to.
    pub fn target(&self) -> Target<T> {
        Target {
            to: self.to,
            plain: self.plain,
            stamp_us: self.stamp_us,
        }
    }

    /// Whether the sample to check is the end point (checked first).
    pub fn at_end(&self) -> bool {
        !self.end_checked
    }

    /// The fraction of the way of the sample to check.
    pub fn fraction(&self) -> T {
        let k = if self.end_checked {
            self.next
        } else {
            self.samples
        };
        lit::<T>(f64::from(k)) / lit(f64::from(self.samples))
    }

    /// The pose of the sample to check.
    pub fn sample(&self) -> Pose<T> {
        along(&self.from, &self.dv, &self.dw, self.fraction())
    }

    /// The sample to check passed: on to the next. Returns whether every sample has
    /// passed.
    pub fn passed(&mut self) -> bool {
        if self.end_checked {
            self.next += 1;
        } else {
            self.end_checked = true;
        }
        self.next >= self.samples
    }
}

/// How many samples the path `from` → `to` needs (unrounded): its length over `step` or
/// its rotation over `step_angle`, whichever is more.
pub(super) fn samples_between<T: Real>(from: &Pose<T>, to: &Pose<T>, step: T, step_angle: T) -> T {
    let distance = norm3(&(to.t - from.t));
    let angle = rotation_angle(&(to.r * from.r.inverse()));
    (distance / step).max(angle / step_angle)
}

/// Pose at fraction `s` of the straight segment a → b (translation linear, rotation about
/// the fixed world axis of b·aᵀ).
pub fn interpolate<T: Real>(a: &Pose<T>, b: &Pose<T>, s: T) -> Pose<T> {
    let (dv, dw) = segment(a, b);
    along(a, &dv, &dw, s)
}

/// The straight segment a → b: its translation and the rotation vector of b·aᵀ.
fn segment<T: Real>(a: &Pose<T>, b: &Pose<T>) -> (Vector3<T>, Vector3<T>) {
    (sub3(&b.t, &a.t), rotation_vector(&(b.r * a.r.inverse())))
}

/// The pose at fraction `s` of the segment (`dv`, `dw`) from `from` ([`segment`]).
fn along<T: Real>(from: &Pose<T>, dv: &Vector3<T>, dw: &Vector3<T>, s: T) -> Pose<T> {
    from.displaced(&scale3(dv, s), &scale3(dw, s))
}
