//! The adaptive tremor canceller: estimates the tremor itself (its frequency, amplitude
//! and phase, per axis) and subtracts it, so that the voluntary motion passes undelayed.
//!
//! # Design: a weighted-frequency Fourier linear combiner on the tremor band
//!
//! Per channel (`[x, y, z, rx, ry, rz]`, the motion since engagement), at the stream rate:
//!
//! 1. **The tremor band.** The motion `u_k` goes through a 4th-order high-pass (two
//!    2nd-order Butterworth sections at `highpass_hz`, 5 Hz by default, bilinear with
//!    pre-warping): `s_k = P(z) u_k`. It removes the voluntary motion (0-2 Hz: −48 dB at
//!    1 Hz, −32 dB at 2 Hz) from what the estimator sees; it is never subtracted itself.
//! 2. **The WFLC** (Riviere, Rader and Thakor 1998) on `s_k`: a sinusoid of adaptive
//!    frequency ω_k (rad per sample) and weights `w = [w_s, w_c]`,
//!    `θ_k = θ_{k−1} + ω_k`, `x_k = [sin θ_k, cos θ_k]`, `ŝ_k = w·x_k`, `ε_k = s_k − ŝ_k`,
//!    `ω_{k+1} = ω_k + 2 μ_0 ε_k (w_s cos θ_k − w_c sin θ_k) / max(p_k, a_min²)`,
//!    `w_{k+1} = w_k + 2 μ_1 ε_k x_k`,
//!    the frequency step normalised by the band's power `p_k` (a running mean of `s²`, time
//!    constant 1 s) so that it does not depend on the tremor's amplitude or the channel's
//!    unit (floored at a tremor of amplitude `a_min`), ω kept within `[min_hz, max_hz]`.
//! 3. **Back to the motion.** The estimate `ŝ` is the tremor as the high-pass shows it:
//!    scaled by `|P(e^{jω})|` and advanced by `arg P(e^{jω})` at the tracked frequency.
//!    The tremor in the motion is `t̂_k = (w'·x_k)` with the weights turned back by that
//!    phase and divided by that gain: with `G = P(e^{jω_k}) = |G| e^{jγ}`,
//!    `w'_s = (w_s cos γ + w_c sin γ)/|G|`, `w'_c = (w_c cos γ − w_s sin γ)/|G|`.
//! 4. **The output** is `y_k = u_k − t̂_k`.
//!
//! # Why the voluntary motion is not delayed
//!
//! The voluntary motion reaches the output directly (`u_k` itself); what is subtracted is
//! the estimate of a sinusoid at the tracked frequency, which sees the voluntary motion
//! only through the 4th-order high-pass: its transfer from `u` has four zeros at DC, so the
//! output's group delay at DC is exactly zero and the voluntary motion's distortion at
//! 0-2 Hz is at most `|P(f)|` times the combiner's band-pass gain there (below 1 % of the
//! motion with the defaults). A fixed band-stop (the classic filter, a fixed bank of
//! oscillators as in BMFLC, or a steady-state Kalman filter of a fixed oscillator bank)
//! cannot do this: by Bode's gain-phase relation a minimum-phase filter with −20 dB over
//! 8-12 Hz and unit gain elsewhere delays DC by `(2/π) ∫ −ln|H(ω)| dω/ω²` ≥ 9.7 ms, and
//! any other causal filter with that gain delays more (the crate's README has the
//! figures). Tracking one moving sinusoid removes the tremor where it is now, not over the
//! whole band.
//!
//! # Starting, stopping
//!
//! From rest (zero weights, zero filter state) and zero input the output is exactly zero,
//! which the teleoperation mapping's zero-jump property needs: [`TremorCanceller::reset`]
//! zeroes the weights, the band's state and power, and keeps the tracked frequency (a
//! re-engagement starts from the frequency learnt). When the tremor stops, the weights
//! decay (time constant `1/(2 μ_1)` samples in the band's units): the subtracted sinusoid
//! fades, continuously, over about 0.1 s.

use crate::tremor::{Biquad, CHANNELS};
use nalgebra::Complex;
use std::f64::consts::PI;
use thiserror::Error;

/// The canceller's settings (`TeleopConfig::tremor`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CancellerConfig {
    /// The tremor's frequency is tracked within `[min_hz, max_hz]` (physiological tremor:
    /// 6-14 Hz).
    pub min_hz: f64,
    /// See `min_hz`.
    pub max_hz: f64,
    /// Where the tracking starts, Hz (10: the centre of the band).
    pub start_hz: f64,
    /// Corner of the 4th-order Butterworth high-pass that shows the estimator the tremor
    /// band, Hz (5: −48 dB at 1 Hz, −0.3 dB at 8 Hz).
    pub highpass_hz: f64,
    /// μ_0, the frequency's adaptation gain (normalised by the band's power): 0.02.
    pub frequency_gain: f64,
    /// μ_1, the weights' adaptation gain: 0.1 (the amplitude follows within about
    /// `1/(2 μ_1)` = 5 samples, 50 ms at 100 Hz).
    pub amplitude_gain: f64,
    /// Tremor amplitude below which the frequency adapts more slowly (the normalisation's
    /// floor), translation, m: 1 µm.
    pub floor_m: f64,
    /// The same for rotation, rad: 20 µrad.
    pub floor_rad: f64,
}

impl Default for CancellerConfig {
    fn default() -> Self {
        CancellerConfig {
            min_hz: 6.0,
            max_hz: 14.0,
            start_hz: 10.0,
            highpass_hz: 5.0,
            frequency_gain: 0.02,
            amplitude_gain: 0.1,
            floor_m: 1e-6,
            floor_rad: 2e-5,
        }
    }
}

/// A canceller that cannot be built.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum CancellerError {
    /// A setting out of range.
    #[error("tremor canceller: {field} = {value} is out of range ({range})")]
    Setting {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        range: &'static str,
    },
}

/// One channel's state.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Channel {
    /// The high-pass sections' state (direct form II transposed).
    band: [[f64; 2]; 2],
    /// WFLC weights on [sin θ, cos θ].
    w: [f64; 2],
    /// Tracked frequency, rad per sample.
    omega: f64,
    /// Phase, rad, in [0, 2π).
    theta: f64,
    /// Running mean of the band's square.
    power: f64,
    /// Floor of `power`.
    floor: f64,
}

/// The adaptive tremor canceller on six channels.
#[derive(Clone, Debug, PartialEq)]
pub struct TremorCanceller {
    config: CancellerConfig,
    fs_hz: f64,
    band: [Biquad; 2],
    /// Running-mean factor of the band's power (time constant 1 s).
    power_alpha: f64,
    omega_min: f64,
    omega_max: f64,
    channels: [Channel; CHANNELS],
}

impl TremorCanceller {
    /// Checks the settings for the stream rate `fs_hz` and builds the canceller at rest.
    pub fn new(config: &CancellerConfig, fs_hz: f64) -> Result<Self, CancellerError> {
        let bad = |field, value, range| {
            Err(CancellerError::Setting {
                field,
                value,
                range,
            })
        };
        if !(fs_hz.is_finite() && fs_hz > 0.0) {
            return bad("stream_rate_hz", fs_hz, "positive");
        }
        let nyquist = fs_hz / 2.0;
        let c = config;
        if !(c.highpass_hz.is_finite() && c.highpass_hz > 0.0 && c.highpass_hz < c.min_hz) {
            return bad("highpass_hz", c.highpass_hz, "in (0, min_hz)");
        }
        if !(c.min_hz.is_finite() && c.min_hz > 0.0 && c.min_hz < c.max_hz) {
            return bad("min_hz", c.min_hz, "in (highpass_hz, max_hz)");
        }
        if !(c.max_hz.is_finite() && c.max_hz < nyquist) {
            return bad("max_hz", c.max_hz, "in (min_hz, Nyquist)");
        }
        if !(c.start_hz >= c.min_hz && c.start_hz <= c.max_hz) {
            return bad("start_hz", c.start_hz, "in [min_hz, max_hz]");
        }
        for (field, value) in [
            ("frequency_gain", c.frequency_gain),
            ("amplitude_gain", c.amplitude_gain),
        ] {
            if !(value.is_finite() && value > 0.0 && value < 0.5) {
                return bad(field, value, "in (0, 0.5)");
            }
        }
        for (field, value) in [("floor_m", c.floor_m), ("floor_rad", c.floor_rad)] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, value, "positive");
            }
        }
        let hp = Biquad::butterworth_highpass(c.highpass_hz, fs_hz);
        let to_omega = |hz: f64| 2.0 * PI * hz / fs_hz;
        let mut channels = [Channel {
            band: [[0.0; 2]; 2],
            w: [0.0; 2],
            omega: to_omega(c.start_hz),
            theta: 0.0,
            power: 0.0,
            floor: 0.0,
        }; CHANNELS];
        for (i, ch) in channels.iter_mut().enumerate() {
            let a = if i < 3 { c.floor_m } else { c.floor_rad };
            ch.floor = a * a / 2.0;
        }
        Ok(TremorCanceller {
            config: *c,
            fs_hz,
            band: [hp, hp],
            power_alpha: 1.0 / fs_hz,
            omega_min: to_omega(c.min_hz),
            omega_max: to_omega(c.max_hz),
            channels,
        })
    }

    /// The settings.
    pub fn config(&self) -> &CancellerConfig {
        &self.config
    }

    /// The sample rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.fs_hz
    }

    /// The tracked tremor frequency of each channel, Hz.
    pub fn frequencies_hz(&self) -> [f64; CHANNELS] {
        self.channels.map(|c| c.omega * self.fs_hz / (2.0 * PI))
    }

    /// The tremor estimate's amplitude of each channel in the motion's units.
    pub fn amplitudes(&self) -> [f64; CHANNELS] {
        self.channels.map(|c| {
            let g = self.band_response(c.omega).norm();
            (c.w[0] * c.w[0] + c.w[1] * c.w[1]).sqrt() / g
        })
    }

    /// The high-pass's response at `omega` rad per sample.
    fn band_response(&self, omega: f64) -> Complex<f64> {
        let f = omega * self.fs_hz / (2.0 * PI);
        self.band
            .iter()
            .fold(Complex::new(1.0, 0.0), |h, s| h * s.response(f, self.fs_hz))
    }

    /// At rest: zero weights, band state and power (the output is then the input until
    /// a tremor is estimated); the tracked frequencies are kept.
    pub fn reset(&mut self) {
        for c in &mut self.channels {
            c.band = [[0.0; 2]; 2];
            c.w = [0.0; 2];
            c.theta = 0.0;
            c.power = 0.0;
        }
    }

    /// One sample of the six channels: the motion with the tremor estimate subtracted.
    pub fn step(&mut self, input: [f64; CHANNELS]) -> [f64; CHANNELS] {
        let mut out = input;
        for i in 0..CHANNELS {
            let (Some(u), Some(c)) = (input.get(i).copied(), self.channels.get(i).copied()) else {
                continue;
            };
            let g = self.band_response(c.omega);
            let (y, next) = self.channel_step(c, u, g);
            if let (Some(o), Some(ch)) = (out.get_mut(i), self.channels.get_mut(i)) {
                *o = y;
                *ch = next;
            }
        }
        out
    }

    /// One channel: its output and next state, `g` the high-pass's response at its
    /// frequency.
    fn channel_step(&self, mut c: Channel, u: f64, g: Complex<f64>) -> (f64, Channel) {
        // θ_k = θ_{k−1} + ω_k (kept in [0, 2π))
        c.theta = (c.theta + c.omega) % (2.0 * PI);
        let (sin, cos) = c.theta.sin_cos();
        // step 3: the estimate turned back through the high-pass's response
        let (gain, gamma) = (g.norm(), g.arg());
        let (sg, cg) = gamma.sin_cos();
        let ws = (c.w[0] * cg + c.w[1] * sg) / gain;
        let wc = (c.w[1] * cg - c.w[0] * sg) / gain;
        let y = u - (ws * sin + wc * cos);
        // step 1: the tremor band
        let mut s = u;
        for (sec, st) in self.band.iter().zip(c.band.iter_mut()) {
            let [b0, b1, b2] = sec.b;
            let [a1, a2] = sec.a;
            let v = b0 * s + st[0];
            st[0] = b1 * s - a1 * v + st[1];
            st[1] = b2 * s - a2 * v;
            s = v;
        }
        // step 2: the WFLC's error, frequency and weight updates (Riviere, Rader and Thakor 1998)
        let eps = s - (c.w[0] * sin + c.w[1] * cos);
        c.power += self.power_alpha * (s * s - c.power);
        let mu0 = self.config.frequency_gain;
        let mu1 = self.config.amplitude_gain;
        c.omega += 2.0 * mu0 * eps * (c.w[0] * cos - c.w[1] * sin) / c.power.max(c.floor);
        c.omega = c.omega.clamp(self.omega_min, self.omega_max);
        c.w[0] += 2.0 * mu1 * eps * sin;
        c.w[1] += 2.0 * mu1 * eps * cos;
        (y, c)
    }
}
