//! The estimates from a recorded staircase ([`crate::excitation`]): two linear
//! least-squares problems in integral form (no differentiated signal), then the backlash
//! from the second position channel.
//!
//! ## 1. Electrical: `R`, `k`, `L`
//! Over a window of `W` periods `[a, b]` inside one segment (the two periods after a duty
//! step left out, where the current jumps within a period):
//! ```text
//! V T sum(u) = R int(i dt) + k (x_b - x_a) + L (i_b - i_a)
//! ```
//! `int(i dt)` by the trapezoid rule over the samples; `x` the encoder position; `k` the
//! back-EMF constant times the gear, in SI equal to the torque constant times the gear.
//!
//! ## 2. Mechanical: `M`, `b`, `Fc` (in amperes, then times `k`)
//! Over each half of a segment in which the joint moves one way (sign `s`):
//! ```text
//! int(i dt) = (M / k) (v_b - v_a) + (b / k) (x_b - x_a) + (Fc / k) s (t_b - t_a)
//! ```
//! The velocities at the window's ends are the slopes of straight lines fitted to the
//! encoder positions around them (one-sided at a duty step, where the joint is steady:
//! at rest or at the end of the previous segment; centred in mid-segment). The current
//! integral takes the period after a duty step as the RL circuit's exponential with the
//! time constant `L / R` of step 1 (the trapezoid rule is off by a quarter of the jump
//! times the period there), the trapezoid rule elsewhere.
//!
//! ## 3. Backlash (with the second position channel)
//! The encoder sits on the motor, the channel on the load. In the steady halves the motor
//! drives the load, on the flank of its direction: `x_enc - x_abs = c0 + c1 x_enc + s w / 2`
//! (`c0` the channel's offset, `c1` its scale error, `w` the backlash).
//!
//! Each problem's covariance is its residual variance times `(A^T A)^-1`
//! ([`crate::lsq`]); products carry both factors' deviations to first order (treated as
//! independent). The residuals include what the model leaves out (the transmission's
//! load-proportional friction, stiction, the current's lag), so the deviations are those
//! of the fit, not a bound on the error against the plant: the tests measure that.

use crate::error::IdentifyError;
use crate::lsq::{solve, Estimate};
use crate::recording::Recording;

/// The identified joint, joint units (m, N on a leg; rad, N m on a link).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identified {
    /// Circuit resistance, ohm.
    pub resistance: Estimate,
    /// Circuit inductance, H.
    pub inductance: Estimate,
    /// Torque constant times the gear, `k = n Kt` (= `n Ke`), N/A or N m/A.
    pub force_per_amp: Estimate,
    /// Reflected mass or inertia, kg or kg m^2.
    pub mass: Estimate,
    /// Viscous friction, N s/m or N m s/rad.
    pub viscous: Estimate,
    /// Coulomb friction, N or N m.
    pub coulomb: Estimate,
    /// Backlash between motor and load, m or rad (with the second position channel).
    pub backlash: Option<Estimate>,
    /// The supply the duties apply, V.
    pub supply_v: f64,
    /// Rows and rms residual of the electrical problem (V s).
    pub electrical_fit: (usize, f64),
    /// Rows and rms residual of the mechanical problem (A s).
    pub mechanical_fit: (usize, f64),
}

impl Identified {
    /// Effort per unit duty at rest, `K_u = k V / R`.
    pub fn force_per_duty(&self) -> f64 {
        self.force_per_amp.value * self.supply_v / self.resistance.value
    }

    /// Total damping seen from the duty, `B = b + k^2 / R`.
    pub fn damping(&self) -> f64 {
        let k = self.force_per_amp.value;
        self.viscous.value + k * k / self.resistance.value
    }

    /// Mechanical time constant `M / B`, s.
    pub fn time_constant(&self) -> f64 {
        self.mass.value / self.damping()
    }

    /// The current's time constant `L / R`, s (0 when the inductance came out
    /// non-positive: below the resolution of the recording).
    pub fn electrical_time_constant(&self) -> f64 {
        (self.inductance.value / self.resistance.value).max(0.0)
    }
}

/// A segment of constant duty: `[start, end)` in ticks.
#[derive(Debug, Clone, Copy)]
struct Segment {
    start: usize,
    end: usize,
    duty: f64,
}

fn segments(rec: &Recording) -> Vec<Segment> {
    let n = rec.samples.len().saturating_sub(1);
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=n {
        if k == n || rec.samples[k].duty != rec.samples[start].duty {
            out.push(Segment {
                start,
                end: k,
                duty: rec.samples[start].duty,
            });
            start = k;
        }
    }
    out
}

/// Slope of the least-squares line through the positions of ticks `lo..=hi`, per s.
fn slope(rec: &Recording, lo: usize, hi: usize) -> f64 {
    let n = (hi - lo + 1) as f64;
    let tm = (lo + hi) as f64 / 2.0;
    let xm = (lo..=hi).map(|k| rec.position(k)).sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for k in lo..=hi {
        let dt = k as f64 - tm;
        sxy += dt * (rec.position(k) - xm);
        sxx += dt * dt;
    }
    sxy / sxx / rec.period_s
}

/// Trapezoid integral of the current over ticks `[a, b]`, A s.
fn trapezoid(rec: &Recording, a: usize, b: usize) -> f64 {
    let t = rec.period_s;
    (a..b)
        .map(|k| 0.5 * t * (rec.samples[k].current_a + rec.samples[k + 1].current_a))
        .sum()
}

/// The integral of the current over the period `[k, k + 1]` that starts with a duty step:
/// the exponential approach of an RL circuit with time constant `tau_e` from `i_k`
/// towards the value `i_ss` that reaches `i_(k+1)` at the period's end.
fn step_period_integral(rec: &Recording, k: usize, tau_e: f64) -> f64 {
    let t = rec.period_s;
    let (i0, i1) = (rec.samples[k].current_a, rec.samples[k + 1].current_a);
    if tau_e <= 0.0 {
        return i1 * t;
    }
    let e = (-t / tau_e).exp();
    let i_ss = (i1 - i0 * e) / (1.0 - e);
    i_ss * t + (i0 - i_ss) * tau_e * (1.0 - e)
}

/// The shortest electrical window, periods.
const ELECTRICAL_WINDOW: usize = 10;
/// Periods left out of the electrical windows after each duty step.
const AFTER_STEP: usize = 2;

fn electrical(rec: &Recording, segs: &[Segment]) -> Result<crate::lsq::Solution, IdentifyError> {
    let v = rec.supply_v;
    let t = rec.period_s;
    let mut rows = Vec::new();
    for s in segs {
        // Windows of a sixth of the segment, at least ELECTRICAL_WINDOW periods: the
        // encoder's quantisation is an error in the regressor `x_b - x_a`, so the windows
        // span many counts.
        let w = ((s.end - s.start).saturating_sub(AFTER_STEP) / 6).max(ELECTRICAL_WINDOW);
        let mut a = s.start + AFTER_STEP;
        while a + w <= s.end {
            let b = a + w;
            let y = v * t * (a..b).map(|k| rec.samples[k].duty).sum::<f64>();
            let dx = rec.position(b) - rec.position(a);
            let di = rec.samples[b].current_a - rec.samples[a].current_a;
            let q = trapezoid(rec, a, b);
            // At rest with no duty the row says nothing.
            if y != 0.0 || dx != 0.0 || q != 0.0 {
                rows.push((vec![q, dx, di], y));
            }
            a = b;
        }
    }
    solve(
        "electrical (R, k, L)",
        &["resistance", "force_per_amp", "inductance"],
        &rows,
    )
}

/// The velocity at the start of segment `i` (the end of the previous one), if the joint
/// was steady there: at rest, or moving in the direction `dir`.
fn velocity_at_start(rec: &Recording, segs: &[Segment], i: usize, h: usize) -> Option<f64> {
    let s = segs.get(i)?;
    if i == 0 {
        return Some(0.0);
    }
    let prev = segs.get(i - 1)?;
    if s.start < prev.start + 2 * h {
        return None;
    }
    let lo = s.start - 2 * h;
    let c0 = rec.samples[lo].count;
    if (lo..=s.start).all(|k| rec.samples[k].count == c0) {
        return Some(0.0);
    }
    Some(slope(rec, lo, s.start))
}

/// A steady half of a segment: its first and last tick and the direction of motion.
type SteadyHalf = (usize, usize, f64);

fn mechanical(
    rec: &Recording,
    segs: &[Segment],
    tau_e: f64,
) -> Result<(crate::lsq::Solution, Vec<SteadyHalf>), IdentifyError> {
    let t = rec.period_s;
    let mut rows = Vec::new();
    // The steady halves (start, end, direction), for the backlash.
    let mut steady = Vec::new();
    // The direction of the last segment that drove the joint.
    let mut last_dir = 0.0;
    for (i, s) in segs.iter().enumerate() {
        if s.duty == 0.0 {
            continue;
        }
        let dir = s.duty.signum();
        // The first segment of a direction takes up the backlash: the motor runs alone
        // through the gap before it drives the load (the friction and the inertia it feels
        // are not the joint's).
        let taking_up = dir != last_dir;
        last_dir = dir;
        if taking_up {
            continue;
        }
        let len = s.end - s.start;
        let h = (len / 8).max(2);
        if len < 4 * h + 2 {
            continue;
        }
        // Monotone motion in the duty's direction throughout.
        let monotone = (s.start..s.end)
            .all(|k| ((rec.samples[k + 1].count - rec.samples[k].count) as f64) * dir >= 0.0);
        if !monotone {
            continue;
        }
        let Some(v_a) = velocity_at_start(rec, segs, i, h) else {
            continue;
        };
        if v_a * dir < 0.0 {
            continue;
        }
        let m = s.start + len / 2;
        let v_m = slope(rec, m - h, m + h);
        let v_b = slope(rec, s.end - 2 * h, s.end);
        if v_m * dir <= 0.0 || v_b * dir <= 0.0 {
            continue;
        }
        let first = step_period_integral(rec, s.start, tau_e);
        let q_am = first + trapezoid(rec, s.start + 1, m);
        let q_mb = trapezoid(rec, m, s.end);
        for (a, b, va, vb, q) in [(s.start, m, v_a, v_m, q_am), (m, s.end, v_m, v_b, q_mb)] {
            let dx = rec.position(b) - rec.position(a);
            rows.push((vec![vb - va, dx, dir * (b - a) as f64 * t], q));
        }
        steady.push((m, s.end, dir));
    }
    let sol = solve(
        "mechanical (M, b, Fc)",
        &["mass", "viscous", "coulomb"],
        &rows,
    )?;
    Ok((sol, steady))
}

fn backlash(rec: &Recording, steady: &[SteadyHalf]) -> Result<Option<Estimate>, IdentifyError> {
    let Some(cpu_abs) = rec.abs_counts_per_unit else {
        return Ok(None);
    };
    let Some(p0) = rec.samples.first().and_then(|s| s.abs_count) else {
        return Ok(None);
    };
    let mut rows = Vec::new();
    for &(a, b, dir) in steady {
        for k in a..=b {
            let Some(p) = rec.samples[k].abs_count else {
                return Err(IdentifyError::Recording(format!(
                    "the second position channel has no reading at tick {k}"
                )));
            };
            let x = rec.position(k);
            let x_abs = (f64::from(p) - f64::from(p0)) / cpu_abs;
            rows.push((vec![1.0, x, dir], x - x_abs));
        }
    }
    let both = steady.iter().any(|s| s.2 > 0.0) && steady.iter().any(|s| s.2 < 0.0);
    if !both {
        return Ok(None);
    }
    let sol = solve(
        "backlash (offset, scale, half width)",
        &["offset", "scale", "half_backlash"],
        &rows,
    )?;
    Ok(Some(sol.theta[2].scaled(2.0)))
}

/// Identifies the joint from a recorded staircase.
pub fn identify(rec: &Recording) -> Result<Identified, IdentifyError> {
    if !(rec.period_s.is_finite() && rec.period_s > 0.0) {
        return Err(IdentifyError::Recording(format!(
            "period {} s is not positive",
            rec.period_s
        )));
    }
    if !(rec.supply_v.is_finite() && rec.supply_v > 0.0) {
        return Err(IdentifyError::Recording(format!(
            "supply {} V is not positive",
            rec.supply_v
        )));
    }
    if !(rec.counts_per_unit.is_finite() && rec.counts_per_unit > 0.0) {
        return Err(IdentifyError::Recording(format!(
            "counts per unit {} is not positive",
            rec.counts_per_unit
        )));
    }
    if let Some(k) = rec
        .samples
        .iter()
        .position(|s| !(s.duty.is_finite() && s.current_a.is_finite()))
    {
        return Err(IdentifyError::Recording(format!(
            "sample {k}: duty or current not finite"
        )));
    }
    let segs = segments(rec);
    let el = electrical(rec, &segs)?;
    let (r, k, l) = (el.theta[0], el.theta[1], el.theta[2]);
    if r.value <= 0.0 {
        return Err(IdentifyError::NotPhysical {
            name: "resistance",
            value: r.value,
            why: "a resistance is positive",
        });
    }
    if k.value <= 0.0 {
        return Err(IdentifyError::NotPhysical {
            name: "force_per_amp",
            value: k.value,
            why: "positive duty must drive towards +q (a reversed motor or encoder: run \
                  commissioning first)",
        });
    }
    let tau_e = (l.value / r.value).clamp(0.0, rec.period_s);
    let (mech, steady) = mechanical(rec, &segs, tau_e)?;
    let [m, b, fc] = [mech.theta[0], mech.theta[1], mech.theta[2]].map(|e| e.times(&k));
    if m.value <= 0.0 {
        return Err(IdentifyError::NotPhysical {
            name: "mass",
            value: m.value,
            why: "an inertia is positive",
        });
    }
    if fc.value < 0.0 {
        return Err(IdentifyError::NotPhysical {
            name: "coulomb",
            value: fc.value,
            why: "friction opposes motion",
        });
    }
    for (name, e) in [("mass", m), ("coulomb", fc)] {
        // A quarter: beyond it the excitation did not determine the parameter (too few
        // segments moved, too little acceleration).
        let r = e.relative_std();
        if r.is_nan() || r > 0.25 {
            return Err(IdentifyError::Uncertain {
                name,
                relative_std: r,
            });
        }
    }
    let backlash = backlash(rec, &steady)?;
    Ok(Identified {
        resistance: r,
        inductance: l,
        force_per_amp: k,
        mass: m,
        viscous: b,
        coulomb: fc,
        backlash,
        supply_v: rec.supply_v,
        electrical_fit: (el.rows, el.rms_residual),
        mechanical_fit: (mech.rows, mech.rms_residual),
    })
}
