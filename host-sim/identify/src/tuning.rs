//! Servo gains from the identified model: loop shaping for a stated crossover and phase
//! margin on the sampled loop, and the feed-forward terms the servo has.
//!
//! ## The loop (sample `T`, the board's servo law of `servo::pid`)
//! The identified joint seen from the duty, `G(s) = K_u / (s (M s + B))` (see
//! [`crate::excitation`]), times the current's lag `1 / (1 + s L / R)`, held over each
//! period: its zero-order-hold equivalent, with `K = K_u / B`, `tau = M / B`,
//! `e = exp(-T / tau)`:
//! ```text
//! G(z) = K ((T - tau (1 - e)) z + (tau (1 - e) - T e)) / ((z - 1)(z - e))
//! ```
//! The servo: `u_k = kp e_k + I_k + kd (r_dot - v_f)`, the integral used one sample late
//! (`I(z) = ki T z^-1 / (1 - z^-1)`), the derivative on the backward-difference velocity
//! through the first-order filter `a = 1 - exp(-2 pi fc T)`:
//! ```text
//! C(z) = kp (1 + w_i T z^-1 / (1 - z^-1)) + kd a (1 - z^-1) / (T (1 - (1 - a) z^-1)),
//! ki = kp w_i,  w_i = w_c / integral_ratio
//! ```
//! ## The method
//! `C` is linear in `(kp, kd)`; at `z_c = exp(j w_c T)` the loop must be
//! `L(z_c) = C(z_c) G(z_c) = -exp(j PM)`: gain 1 (the crossover) with the phase
//! `-180 deg + PM`. That is two real equations in `kp` and `kd`, solved directly; a
//! negative solution means the specification cannot be met with this structure (a lower
//! crossover or a smaller margin). The crossover and margin the gains actually give are
//! then read off `L(exp(j w T))` on a grid up to the Nyquist frequency (the crossover
//! need not be unique), with the gain margin.
//!
//! ## Feed-forward
//! The steady duty at speed `v` is `(B v + Fc sgn v) / K_u`: `kv = B / K_u`,
//! `friction_ff = Fc / K_u` (the servo ramps it in over `friction_band`), and
//! `ka = M / K_u` (used when the caller passes accelerations).

use nalgebra::Complex;
use servo::PidGains;

use crate::error::IdentifyError;
use crate::estimate::Identified;

type C64 = Complex<f64>;

/// What the loop is tuned for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TuningSpec {
    /// The open loop's crossover frequency, Hz (> 0, below a fifth of the control rate).
    pub crossover_hz: f64,
    /// The phase margin at the crossover, deg (10 .. 89).
    pub phase_margin_deg: f64,
    /// Crossover over the integral's corner frequency, >= 2. Default 5.
    pub integral_ratio: f64,
}

impl TuningSpec {
    /// The defaults: 25 Hz and 60 deg on a leg, 25 Hz and 60 deg on a link; the integral's
    /// corner a fifth of the crossover.
    pub fn default_for(_kind: plant::JointKind) -> Self {
        TuningSpec {
            crossover_hz: 25.0,
            phase_margin_deg: 60.0,
            integral_ratio: 5.0,
        }
    }
}

/// The gains and what the loop they close achieves on the identified model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tuning {
    /// The servo's gains (the fields not tuned taken from the base gains).
    pub gains: PidGains<f64>,
    /// The crossover the gains give on the model, Hz.
    pub crossover_hz: f64,
    /// Their phase margin there, deg.
    pub phase_margin_deg: f64,
    /// Their gain margin, dB (infinite if the phase never reaches -180 deg below Nyquist).
    pub gain_margin_db: f64,
}

/// The plant's sampled response at `z = exp(j w T)` (see the module documentation).
fn plant_response(model: &Identified, w: f64, t: f64) -> C64 {
    let ku = model.force_per_duty();
    let b = model.damping();
    let k = ku / b;
    let tau = model.mass.value / b;
    let e = (-t / tau).exp();
    let z = C64::from_polar(1.0, w * t);
    let num = (z * (t - tau * (1.0 - e)) + (tau * (1.0 - e) - t * e)) * k;
    let den = (z - 1.0) * (z - e);
    let lag = C64::new(1.0, w * model.electrical_time_constant()).inv();
    num / den * lag
}

/// The servo's two parts at `z = exp(j w T)`: the PI part per unit `kp` and the D part per
/// unit `kd`.
fn controller_parts(w: f64, t: f64, w_i: f64, a: f64) -> (C64, C64) {
    let zi = C64::from_polar(1.0, -w * t);
    let one = C64::new(1.0, 0.0);
    let pi = one + zi * (w_i * t) / (one - zi);
    let d = (one - zi) * a / ((one - zi * (1.0 - a)) * t);
    (pi, d)
}

fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), IdentifyError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(IdentifyError::Setting {
            name,
            value,
            expected,
        })
    }
}

/// The gains for `spec` on the identified `model` at the control period `period_s`; the
/// fields the method does not set (limits, friction band, anti-windup, derivative cutoff)
/// come from `base` (the servo's defaults for the joint's kind).
pub fn tune(
    model: &Identified,
    spec: &TuningSpec,
    period_s: f64,
    base: &PidGains<f64>,
) -> Result<Tuning, IdentifyError> {
    check("period_s", period_s, period_s > 0.0, "finite and positive")?;
    let nyquist = 0.5 / period_s;
    check(
        "crossover_hz",
        spec.crossover_hz,
        spec.crossover_hz > 0.0 && spec.crossover_hz <= nyquist / 2.5,
        "positive and below a fifth of the control rate",
    )?;
    check(
        "phase_margin_deg",
        spec.phase_margin_deg,
        (10.0..=89.0).contains(&spec.phase_margin_deg),
        "10 .. 89 deg",
    )?;
    check(
        "integral_ratio",
        spec.integral_ratio,
        spec.integral_ratio >= 2.0,
        ">= 2",
    )?;
    let t = period_s;
    let wc = std::f64::consts::TAU * spec.crossover_hz;
    let w_i = wc / spec.integral_ratio;
    let a = 1.0 - (-std::f64::consts::TAU * base.derivative_cutoff_hz * t).exp();
    let g = plant_response(model, wc, t);
    let target = -C64::from_polar(1.0, spec.phase_margin_deg.to_radians()) / g;
    let (p, d) = controller_parts(wc, t, w_i, a);
    // [Re p, Re d; Im p, Im d] [kp; kd] = [Re target; Im target]
    let det = p.re * d.im - d.re * p.im;
    if det.abs() < 1e-12 * (p.norm() * d.norm()) {
        return Err(IdentifyError::Tuning(format!(
            "the loop's P and D parts are parallel at {} Hz",
            spec.crossover_hz
        )));
    }
    let kp = (target.re * d.im - d.re * target.im) / det;
    let kd = (p.re * target.im - target.re * p.im) / det;
    if !(kp > 0.0 && kd >= 0.0 && kp.is_finite() && kd.is_finite()) {
        return Err(IdentifyError::Tuning(format!(
            "{} Hz with {} deg of phase margin needs kp = {kp:.4e}, kd = {kd:.4e}: not \
             reachable with positive gains (lower the crossover or the margin)",
            spec.crossover_hz, spec.phase_margin_deg
        )));
    }
    let ku = model.force_per_duty();
    let gains = PidGains {
        kp,
        ki: kp * w_i,
        kd,
        kv: model.damping() / ku,
        ka: model.mass.value / ku,
        friction_ff: model.coulomb.value / ku,
        ..*base
    };
    gains
        .validate(0)
        .map_err(|e| IdentifyError::Tuning(format!("the gains are refused by the servo: {e}")))?;
    let (crossover_hz, phase_margin_deg, gain_margin_db) = margins(model, &gains, t);
    Ok(Tuning {
        gains,
        crossover_hz,
        phase_margin_deg,
        gain_margin_db,
    })
}

/// The open loop `L(exp(j w T))` of `gains` on `model`.
pub fn open_loop(model: &Identified, gains: &PidGains<f64>, w: f64, t: f64) -> C64 {
    let a = 1.0 - (-std::f64::consts::TAU * gains.derivative_cutoff_hz * t).exp();
    let w_i = if gains.kp > 0.0 {
        gains.ki / gains.kp
    } else {
        0.0
    };
    let (p, d) = controller_parts(w, t, w_i, a);
    (p * gains.kp + d * gains.kd) * plant_response(model, w, t)
}

/// The first gain crossover (Hz) and its phase margin (deg), and the gain margin (dB) at
/// the first phase crossover, on a logarithmic grid from 0.1 Hz to the Nyquist frequency.
pub fn margins(model: &Identified, gains: &PidGains<f64>, t: f64) -> (f64, f64, f64) {
    let nyquist = 0.5 / t;
    let n: i32 = 4000;
    let f0: f64 = 0.1;
    let ratio = (nyquist * 0.999 / f0).powf(1.0 / f64::from(n));
    let mut crossover = (f64::NAN, f64::NAN);
    let mut gain_margin = f64::INFINITY;
    let mut prev: Option<(f64, C64, f64)> = None;
    // The phase unwrapped along the grid.
    let mut phase_offset = 0.0;
    for i in 0..=n {
        let f = f0 * ratio.powi(i);
        let l = open_loop(model, gains, std::f64::consts::TAU * f, t);
        let mut ph = l.arg() + phase_offset;
        if let Some((_, _, pph)) = prev {
            while ph - pph > std::f64::consts::PI {
                ph -= std::f64::consts::TAU;
                phase_offset -= std::f64::consts::TAU;
            }
            while ph - pph < -std::f64::consts::PI {
                ph += std::f64::consts::TAU;
                phase_offset += std::f64::consts::TAU;
            }
        }
        if let Some((pf, pl, pph)) = prev {
            if crossover.0.is_nan() && pl.norm() >= 1.0 && l.norm() < 1.0 {
                let s = (pl.norm().ln()) / (pl.norm().ln() - l.norm().ln());
                let fc = pf * (f / pf).powf(s);
                let phc = pph + s * (ph - pph);
                crossover = (fc, 180.0 + phc.to_degrees());
            }
            let minus_pi = -std::f64::consts::PI;
            if gain_margin.is_infinite() && pph > minus_pi && ph <= minus_pi {
                let s = (pph - minus_pi) / (pph - ph);
                let mag = pl.norm().ln() + s * (l.norm().ln() - pl.norm().ln());
                gain_margin = -20.0 * mag / std::f64::consts::LN_10;
            }
        }
        prev = Some((f, l, ph));
    }
    (crossover.0, crossover.1, gain_margin)
}
