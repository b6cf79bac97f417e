//! The tremor filter: attenuates physiological tremor (8-12 Hz) in the master's motion
//! at the stream rate, with a small, known delay for the voluntary motion below 2 Hz.
//!
//! # Design
//!
//! A cascade of two biquads, both from their analog prototypes by the bilinear transform
//! with the frequency pre-warped (so each corner lands exactly where asked):
//!
//! - a 2nd-order Butterworth low-pass at `lowpass_hz` (default 5 Hz),
//!   `H(s) = ω_c² / (s² + √2 ω_c s + ω_c²)`;
//! - a notch at `notch_hz` (default 10 Hz, the centre of the band) with quality `notch_q`
//!   (default 1: a wide notch; at 100 Hz its −3 dB edges are 6.3 and 15.4 Hz, its −6 dB
//!   edges 7.6 and 13.0 Hz),
//!   `H(s) = (s² + ω_0²) / (s² + (ω_0/Q) s + ω_0²)`.
//!
//! # Delay
//!
//! At low frequency the filter delays the motion by its group delay at DC. Analog
//! prototypes at the asked corners: `τ = √2/ω_c + 1/(Q ω_0)` = 45.0 + 15.9 = 60.9 ms with
//! the defaults. The bilinear transform keeps the DC group delay of the prototype with
//! the **pre-warped** corners `Ω = 2 f_s tan(π f / f_s)`, so the discrete filter's is
//! `τ = √2/Ω_c + 1/(Q Ω_0)` = 44.6 + 15.4 = **60.0 ms** at 100 Hz
//! ([`TremorFilter::prewarped_dc_group_delay_s`]); its coefficients give the same,
//! `Σ_sections (Σ k b_k / Σ b_k − Σ k a_k / Σ a_k) / f_s`
//! ([`TremorFilter::dc_group_delay_s`]). The phase delay at 1 Hz is **60.7 ms** (the
//! tests measure it by streaming a 1 Hz sine through the filter, and through the whole
//! teleoperation mapping).
//!
//! # Attenuation at 100 Hz (defaults)
//!
//! | 1 Hz | 2 Hz | 3 Hz | 8 Hz | 10 Hz | 12 Hz |
//! | --- | --- | --- | --- | --- | --- |
//! | −0.05 dB | −0.3 dB | −0.9 dB | −16.3 dB | notch zero (> 100 dB) | −24.7 dB |
//!
//! Each channel is a direct form II transposed cascade; with zero state and zero input
//! the output is exactly zero, which the teleoperation mapping uses (it filters the
//! motion since engagement, which is exactly zero at engagement).

use nalgebra::Complex;
use std::f64::consts::PI;
use thiserror::Error;

/// One second-order section `(b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad {
    /// Numerator b0, b1, b2.
    pub b: [f64; 3],
    /// Denominator a1, a2 (a0 = 1).
    pub a: [f64; 2],
}

impl Biquad {
    /// 2nd-order Butterworth low-pass at `fc_hz`, sample rate `fs_hz` (pre-warped).
    pub fn butterworth_lowpass(fc_hz: f64, fs_hz: f64) -> Self {
        let k = (PI * fc_hz / fs_hz).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let n = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * n;
        Biquad {
            b: [b0, 2.0 * b0, b0],
            a: [2.0 * (k * k - 1.0) * n, (1.0 - k / q + k * k) * n],
        }
    }

    /// 2nd-order Butterworth high-pass at `fc_hz`, sample rate `fs_hz` (pre-warped): the
    /// band the tremor canceller's estimator sees.
    pub fn butterworth_highpass(fc_hz: f64, fs_hz: f64) -> Self {
        let k = (PI * fc_hz / fs_hz).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let n = 1.0 / (1.0 + k / q + k * k);
        Biquad {
            b: [n, -2.0 * n, n],
            a: [2.0 * (k * k - 1.0) * n, (1.0 - k / q + k * k) * n],
        }
    }

    /// Notch at `f0_hz` with quality `q` (pre-warped).
    pub fn notch(f0_hz: f64, q: f64, fs_hz: f64) -> Self {
        let k = (PI * f0_hz / fs_hz).tan();
        let n = 1.0 / (1.0 + k / q + k * k);
        let b0 = (1.0 + k * k) * n;
        let b1 = 2.0 * (k * k - 1.0) * n;
        Biquad {
            b: [b0, b1, b0],
            a: [b1, (1.0 - k / q + k * k) * n],
        }
    }

    /// The frequency response at `f_hz`.
    pub fn response(&self, f_hz: f64, fs_hz: f64) -> Complex<f64> {
        let z1 = Complex::from_polar(1.0, -2.0 * PI * f_hz / fs_hz);
        let z2 = z1 * z1;
        let num = z1 * self.b[1] + z2 * self.b[2] + self.b[0];
        let den = z1 * self.a[0] + z2 * self.a[1] + 1.0;
        num / den
    }

    /// Group delay at DC, samples: Σ k b_k / Σ b_k − Σ k a_k / Σ a_k.
    pub fn dc_group_delay_samples(&self) -> f64 {
        let [b0, b1, b2] = self.b;
        let [a1, a2] = self.a;
        (b1 + 2.0 * b2) / (b0 + b1 + b2) - (a1 + 2.0 * a2) / (1.0 + a1 + a2)
    }
}

/// The filter's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TremorFilterConfig {
    /// Butterworth low-pass corner, Hz.
    pub lowpass_hz: f64,
    /// Notch centre, Hz (None: no notch).
    pub notch_hz: Option<f64>,
    /// Notch quality.
    pub notch_q: f64,
}

impl Default for TremorFilterConfig {
    fn default() -> Self {
        TremorFilterConfig {
            lowpass_hz: 5.0,
            notch_hz: Some(10.0),
            notch_q: 1.0,
        }
    }
}

/// A filter that cannot be built.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum FilterDesignError {
    /// A frequency is not inside (0, Nyquist).
    #[error("tremor filter: {what} = {hz} Hz is not inside (0, {nyquist_hz}) Hz (Nyquist at the stream rate)")]
    Frequency {
        /// Which.
        what: &'static str,
        /// Its value.
        hz: f64,
        /// Half the stream rate.
        nyquist_hz: f64,
    },
    /// The notch quality is not positive and finite.
    #[error("tremor filter: notch quality {0} is not positive and finite")]
    Quality(f64),
    /// The stream rate is not positive and finite.
    #[error("tremor filter: stream rate {0} Hz is not positive and finite")]
    Rate(f64),
}

/// Number of channels: `[x, y, z, rx, ry, rz]`.
pub const CHANNELS: usize = 6;

/// The tremor filter on six channels.
#[derive(Clone, Debug, PartialEq)]
pub struct TremorFilter {
    sections: Vec<Biquad>,
    fs_hz: f64,
    /// state[section][channel] = (s1, s2)
    state: Vec<[[f64; 2]; CHANNELS]>,
}

impl TremorFilter {
    /// Designs the filter for the stream rate `fs_hz`.
    pub fn design(config: &TremorFilterConfig, fs_hz: f64) -> Result<Self, FilterDesignError> {
        if !(fs_hz.is_finite() && fs_hz > 0.0) {
            return Err(FilterDesignError::Rate(fs_hz));
        }
        let nyquist_hz = fs_hz / 2.0;
        let check = |what, hz: f64| {
            if hz.is_finite() && hz > 0.0 && hz < nyquist_hz {
                Ok(())
            } else {
                Err(FilterDesignError::Frequency {
                    what,
                    hz,
                    nyquist_hz,
                })
            }
        };
        check("lowpass_hz", config.lowpass_hz)?;
        let mut sections = vec![Biquad::butterworth_lowpass(config.lowpass_hz, fs_hz)];
        if let Some(f0) = config.notch_hz {
            check("notch_hz", f0)?;
            if !(config.notch_q.is_finite() && config.notch_q > 0.0) {
                return Err(FilterDesignError::Quality(config.notch_q));
            }
            sections.push(Biquad::notch(f0, config.notch_q, fs_hz));
        }
        let state = vec![[[0.0; 2]; CHANNELS]; sections.len()];
        Ok(TremorFilter {
            sections,
            fs_hz,
            state,
        })
    }

    /// The sections.
    pub fn sections(&self) -> &[Biquad] {
        &self.sections
    }

    /// The sample rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.fs_hz
    }

    /// Zero state (the output is then zero until the input moves).
    pub fn reset(&mut self) {
        for s in &mut self.state {
            *s = [[0.0; 2]; CHANNELS];
        }
    }

    /// Filters one sample of the six channels.
    pub fn step(&mut self, input: [f64; CHANNELS]) -> [f64; CHANNELS] {
        let mut x = input;
        for (sec, st) in self.sections.iter().zip(self.state.iter_mut()) {
            let [b0, b1, b2] = sec.b;
            let [a1, a2] = sec.a;
            for (xc, s) in x.iter_mut().zip(st.iter_mut()) {
                let y = b0 * *xc + s[0];
                s[0] = b1 * *xc - a1 * y + s[1];
                s[1] = b2 * *xc - a2 * y;
                *xc = y;
            }
        }
        x
    }

    /// The frequency response at `f_hz`.
    pub fn response(&self, f_hz: f64) -> Complex<f64> {
        self.sections.iter().fold(Complex::new(1.0, 0.0), |h, s| {
            h * s.response(f_hz, self.fs_hz)
        })
    }

    /// Gain at `f_hz`, dB.
    pub fn gain_db(&self, f_hz: f64) -> f64 {
        20.0 * self.response(f_hz).norm().log10()
    }

    /// Phase delay at `f_hz`, s: −arg H / ω.
    pub fn phase_delay_s(&self, f_hz: f64) -> f64 {
        -self.response(f_hz).arg() / (2.0 * PI * f_hz)
    }

    /// Exact group delay of the discrete filter at DC, s.
    pub fn dc_group_delay_s(&self) -> f64 {
        self.sections
            .iter()
            .map(Biquad::dc_group_delay_samples)
            .sum::<f64>()
            / self.fs_hz
    }

    /// Group delay at DC of the analog prototypes at the asked corners, s:
    /// √2/ω_c + 1/(Q ω_0).
    pub fn analog_dc_group_delay_s(config: &TremorFilterConfig) -> f64 {
        let lp = std::f64::consts::SQRT_2 / (2.0 * PI * config.lowpass_hz);
        let notch = config
            .notch_hz
            .map_or(0.0, |f0| 1.0 / (config.notch_q * 2.0 * PI * f0));
        lp + notch
    }

    /// Group delay at DC of the discrete filter in closed form, s. The bilinear transform
    /// `s = 2 f_s (1 − z⁻¹)/(1 + z⁻¹)` maps ω ≈ 0 to Ω ≈ ω with dΩ/dω = 1, so the discrete
    /// filter keeps the DC group delay of the prototype with the pre-warped corners
    /// Ω = 2 f_s tan(π f / f_s): `√2/Ω_c + 1/(Q Ω_0)`.
    pub fn prewarped_dc_group_delay_s(config: &TremorFilterConfig, fs_hz: f64) -> f64 {
        let warp = |f: f64| 2.0 * fs_hz * (PI * f / fs_hz).tan();
        let lp = std::f64::consts::SQRT_2 / warp(config.lowpass_hz);
        let notch = config
            .notch_hz
            .map_or(0.0, |f0| 1.0 / (config.notch_q * warp(f0)));
        lp + notch
    }
}
