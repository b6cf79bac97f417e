//! Small numeric helpers shared by the modules (no panics, NaN-safe).

use num_traits::{Float, NumCast};

/// A literal in the scalar type. Every `f64` literal used in this crate is representable
/// (possibly rounded) in `f32` and `f64`, so the fallback is never taken.
#[inline]
pub(crate) fn lit<S: Float>(x: f64) -> S {
    <S as NumCast>::from(x).unwrap_or_else(S::zero)
}

/// `x` limited to `[lo, hi]`; NaN gives 0 (itself clamped). Needs `lo <= hi`; with a NaN
/// bound the bound is ignored by `max`/`min`, so callers pass sanitized bounds.
#[inline]
pub(crate) fn clamp<S: Float>(x: S, lo: S, hi: S) -> S {
    // Comparisons, not `Float::max/min`: without `std` those call libm's fmaxf/fminf
    // (about 100 instructions each on the Cortex-M4; this runs ~30 times per tick).
    if x.is_nan() {
        S::zero()
    } else if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// `x` limited to `[-b, b]` (`b >= 0`) by two comparisons; a NaN `x` passes through.
/// For values that cannot be NaN (two compares instead of three: it runs ~15 times per
/// joint and tick).
#[inline]
pub(crate) fn bound<S: Float>(x: S, b: S) -> S {
    // One test on |x| in the usual case where nothing is cut (|NaN| > b is false).
    if x.abs() > b {
        if x > S::zero() {
            b
        } else {
            -b
        }
    } else {
        x
    }
}

/// `x`, at least `lo` (a NaN `x` passes through).
#[inline]
pub(crate) fn bound_below<S: Float>(x: S, lo: S) -> S {
    if x < lo {
        lo
    } else {
        x
    }
}

/// `x` limited to `[-bound, bound]` (bound >= 0); NaN gives 0.
#[inline]
pub(crate) fn clamp_sym<S: Float>(x: S, bound: S) -> S {
    clamp(x, -bound, bound)
}

/// A usable limit: NaN, negative or infinite values give 0 / `max` (the limit is then
/// within `[0, max]`).
#[inline]
pub(crate) fn sane_limit<S: Float>(limit: S, max: S) -> S {
    if limit.is_nan() {
        S::zero()
    } else {
        clamp(limit, S::zero(), max)
    }
}

/// A sample time that the filters and integrators can use: finite and > 0.
#[inline]
pub(crate) fn valid_dt<S: Float>(dt: S) -> bool {
    dt.is_finite() && dt > S::zero()
}

/// Sign of `x` with `sign(0) = 0` (and NaN -> 0).
#[inline]
pub(crate) fn sign<S: Float>(x: S) -> S {
    if x > S::zero() {
        S::one()
    } else if x < S::zero() {
        -S::one()
    } else {
        S::zero()
    }
}

/// `dt` seconds as whole microseconds (rounded; 0 for anything invalid).
#[inline]
pub(crate) fn seconds_to_us<S: Float>(dt: S) -> u64 {
    (dt * lit(1e6)).round().to_u64().unwrap_or(0)
}

/// A count difference as a scalar (exact below 2^24 in f32, 2^53 in f64).
#[inline]
pub(crate) fn from_i64<S: Float>(x: i64) -> S {
    // Counts within ±2^31 (all of them in practice) convert in hardware on the Cortex-M4:
    // i32 -> f32 is one instruction, i64 -> f32 a soft-float call. Both round the same
    // integer to nearest, so the result is the same.
    if let Ok(small) = i32::try_from(x) {
        // (`black_box`: otherwise LLVM sees that both branches give the same value and
        // keeps only the i64 conversion.)
        return <S as NumCast>::from(core::hint::black_box(small)).unwrap_or_else(S::zero);
    }
    <S as NumCast>::from(x).unwrap_or_else(S::zero)
}

/// The larger of `a` and `b`, the other one when one is NaN (as `Float::max`, which is an
/// out-of-line libm call on the Cortex-M4).
#[inline]
pub(crate) fn max_of<S: Float>(a: S, b: S) -> S {
    if b > a || a.is_nan() {
        b
    } else {
        a
    }
}
