#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The tremor filter does what its documentation states, measured by streaming sines
//! through it at the 100 Hz stream rate (not only by evaluating its transfer function):
//! the attenuation at 8, 10 and 12 Hz, the delay at 1 Hz, and the DC group delay
//! against the analytic formula; for random designs, the analytic DC group delay is the
//! slope of the phase at DC and the simulated phase delay is the transfer function's.

mod common;

use common::proptest_config;
use masters::tremor::{FilterDesignError, TremorFilter, TremorFilterConfig};
use proptest::prelude::*;
use std::f64::consts::PI;

/// Streams `A sin(2π f t)` through channel 0 for `seconds`, then measures the output's
/// amplitude ratio and phase delay (s) at `f` by correlation over whole periods of the
/// last half.
fn measure(filter: &mut TremorFilter, f: f64, seconds: f64) -> (f64, f64) {
    let fs = filter.sample_rate_hz();
    filter.reset();
    let n = (seconds * fs).round() as usize;
    let period = fs / f;
    let periods = ((n / 2) as f64 / period).floor();
    let first = n - (periods * period).round() as usize;
    let (mut re, mut im, mut count) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let ph = 2.0 * PI * f * k as f64 / fs;
        let y = filter.step([ph.sin(), 0.0, 0.0, 0.0, 0.0, 0.0])[0];
        if k >= first {
            re += y * ph.sin();
            im += y * ph.cos();
            count += 1.0;
        }
    }
    // y = g sin(ωt − φ): Σ y sin = g cos φ · N/2, Σ y cos = −g sin φ · N/2
    let gain = 2.0 * (re * re + im * im).sqrt() / count;
    let phi = (-im).atan2(re);
    (gain, phi / (2.0 * PI * f))
}

fn db(g: f64) -> f64 {
    20.0 * g.log10()
}

/// The default filter at 100 Hz: −16.3 dB at 8 Hz, beyond 100 dB at 10 Hz (the notch's
/// zero), −24.7 dB at 12 Hz; 60.7 ms phase delay at 1 Hz; DC group delay 60.0 ms exact,
/// 60.9 ms for the analog prototypes. Measured values agree with the transfer function
/// to 0.01 dB and 1 µs.
#[test]
fn default_filter_figures() {
    let config = TremorFilterConfig::default();
    let mut f = TremorFilter::design(&config, 100.0).unwrap();
    for (hz, stated_db) in [(8.0, -16.3), (12.0, -24.7)] {
        let (g, _) = measure(&mut f, hz, 20.0);
        assert!((db(g) - stated_db).abs() < 0.05, "{hz} Hz: {} dB", db(g));
        assert!(
            (db(g) - f.gain_db(hz)).abs() < 0.01,
            "{hz} Hz vs H: {} dB",
            f.gain_db(hz)
        );
    }
    let (g10, _) = measure(&mut f, 10.0, 20.0);
    assert!(db(g10) < -100.0, "10 Hz: {} dB", db(g10));
    let (g1, d1) = measure(&mut f, 1.0, 20.0);
    assert!(db(g1).abs() < 0.1, "1 Hz passes: {} dB", db(g1));
    assert!((d1 - 0.0607).abs() < 0.00005, "1 Hz delay {d1}");
    assert!((d1 - f.phase_delay_s(1.0)).abs() < 1e-6);
    let tau = f.dc_group_delay_s();
    assert!((tau - 0.0600).abs() < 0.00005, "DC group delay {tau}");
    let closed = TremorFilter::prewarped_dc_group_delay_s(&config, 100.0);
    assert!((closed - tau).abs() < 1e-12, "closed form {closed}");
    let analog = TremorFilter::analog_dc_group_delay_s(&config);
    assert!((analog - 0.0609).abs() < 0.00005, "analog {analog}");
    // the DC gain is 1; the passband figures of the table
    assert!((f.response(0.0).norm() - 1.0).abs() < 1e-12);
    for (hz, stated_db) in [(1.0, -0.05), (2.0, -0.28), (3.0, -0.94)] {
        assert!(
            (f.gain_db(hz) - stated_db).abs() < 0.01,
            "{hz} Hz: {} dB",
            f.gain_db(hz)
        );
    }
    // the notch alone: -3 dB at 6.3 and 15.4 Hz
    let n = masters::tremor::Biquad::notch(10.0, 1.0, 100.0);
    for hz in [6.31, 15.41] {
        let g = 20.0 * n.response(hz, 100.0).norm().log10();
        assert!((g + 3.01).abs() < 0.02, "{hz} Hz: {g} dB");
    }
}

/// Zero in, zero state: exactly zero out (the mapping's zero-jump property needs it).
#[test]
fn zero_in_zero_out() {
    let mut f = TremorFilter::design(&TremorFilterConfig::default(), 100.0).unwrap();
    f.step([1.0, -2.0, 3.0, 0.1, 0.2, 0.3]);
    f.reset();
    for _ in 0..5 {
        assert_eq!(f.step([0.0; 6]), [0.0; 6]);
    }
}

#[test]
fn impossible_designs_are_refused() {
    let c = TremorFilterConfig {
        lowpass_hz: 60.0,
        ..TremorFilterConfig::default()
    };
    assert!(matches!(
        TremorFilter::design(&c, 100.0),
        Err(FilterDesignError::Frequency {
            what: "lowpass_hz",
            ..
        })
    ));
    let c = TremorFilterConfig {
        notch_q: 0.0,
        ..TremorFilterConfig::default()
    };
    assert!(matches!(
        TremorFilter::design(&c, 100.0),
        Err(FilterDesignError::Quality(_))
    ));
    assert!(matches!(
        TremorFilter::design(&TremorFilterConfig::default(), 0.0),
        Err(FilterDesignError::Rate(_))
    ));
}

proptest! {
    #![proptest_config(proptest_config(48))]

    /// For any design, the DC group delay from the coefficients equals the closed form
    /// with pre-warped corners (1e-9 relative) and is the slope of the phase near DC
    /// (1e-4 relative); the analog prototypes at the unwarped corners delay more (tan x >
    /// x); and the delay measured by streaming a slow sine is the transfer function's
    /// phase delay, within 1 µs.
    #[test]
    fn delay_as_stated(
        fs in 50.0f64..500.0,
        lp_frac in 0.01f64..0.2,
        notch in proptest::option::of(0.02f64..0.2),
        q in 0.5f64..3.0,
    ) {
        let config = TremorFilterConfig {
            lowpass_hz: lp_frac * fs,
            notch_hz: notch.map(|n| n * fs),
            notch_q: q,
        };
        let mut f = TremorFilter::design(&config, fs).unwrap();
        let tau = f.dc_group_delay_s();
        let df = 1e-4 * config.lowpass_hz;
        let slope = -(f.response(2.0 * df).arg() - f.response(df).arg()) / (2.0 * PI * df);
        prop_assert!((slope - tau).abs() <= 1e-4 * tau, "slope {slope} vs {tau}");
        let closed = TremorFilter::prewarped_dc_group_delay_s(&config, fs);
        prop_assert!((closed - tau).abs() <= 1e-9 * tau, "closed form {closed} vs {tau}");
        let analog = TremorFilter::analog_dc_group_delay_s(&config);
        prop_assert!(analog > tau, "analog {analog} vs {tau}");
        // a whole number of samples per period, so the measuring window holds whole periods
        let slow = fs / (10.0 * fs / config.lowpass_hz).round();
        let (_, measured) = measure(&mut f, slow, 40.0 / slow);
        prop_assert!((measured - f.phase_delay_s(slow)).abs() < 1e-6,
            "measured {measured} vs {}", f.phase_delay_s(slow));
    }
}
