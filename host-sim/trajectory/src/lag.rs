//! The lag of a follower behind a stream: the best-fitting delay between the poses a master
//! streamed and the setpoints (or poses) that followed them, sampled at the same instants.
//!
//! For a delay τ the follower's position at t is compared with the stream's at t - τ (the
//! stream linearly interpolated between its samples); the best-fitting delay is the τ
//! that minimises the RMS distance, searched on a grid of `step_s` from `min_delay_s`
//! (negative: a follower ahead of the stream, as a led follower can be) to `max_delay_s`.
//! The simulation prints it (`host-sim sim`); the emulated board's run can call
//! [`best_fitting_delay`] on its status records (times, targets sent, setpoints).

/// The best-fitting delay and the residual at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lag {
    /// The delay, s (negative: the follower is ahead).
    pub delay_s: f64,
    /// RMS distance between the follower and the delayed stream at that delay, m.
    pub rms_m: f64,
    /// RMS distance at no delay, m.
    pub rms_at_zero_m: f64,
}

/// The best-fitting delay of `follower` behind `stream`, both sampled at the increasing
/// times `t_s` (s; positions in m), searched from `min_delay_s` (≤ 0) to `max_delay_s`
/// (≥ 0); None with fewer than two samples, lengths that differ or a range that does not
/// hold 0. Only the samples with t - max_delay_s and t - min_delay_s within the record
/// count, the same for every τ.
pub fn best_fitting_delay(
    t_s: &[f64],
    stream: &[[f64; 3]],
    follower: &[[f64; 3]],
    min_delay_s: f64,
    max_delay_s: f64,
    step_s: f64,
) -> Option<Lag> {
    let n = t_s.len();
    if n < 2
        || stream.len() != n
        || follower.len() != n
        || step_s.is_nan()
        || step_s <= 0.0
        || !(min_delay_s <= 0.0 && max_delay_s >= 0.0)
    {
        return None;
    }
    let (t0, t_end) = (*t_s.first()?, *t_s.last()?);
    // The stream at time t (linear between samples; clamped at the ends).
    let at = |t: f64, hint: &mut usize| -> [f64; 3] {
        while *hint + 1 < n && t_s[*hint + 1] <= t {
            *hint += 1;
        }
        while *hint > 0 && t_s[*hint] > t {
            *hint -= 1;
        }
        let (i, j) = (*hint, (*hint + 1).min(n - 1));
        let (a, b) = (stream[i], stream[j]);
        let span = t_s[j] - t_s[i];
        let s = if span > 0.0 {
            ((t - t_s[i]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        [
            a[0] + (b[0] - a[0]) * s,
            a[1] + (b[1] - a[1]) * s,
            a[2] + (b[2] - a[2]) * s,
        ]
    };
    // The RMS at delay τ over every `stride`-th sample.
    let rms_over = |tau: f64, stride: usize| -> f64 {
        let (mut sum, mut count, mut hint) = (0.0, 0usize, 0usize);
        for (k, t) in t_s.iter().enumerate().step_by(stride) {
            if *t - max_delay_s < t0 || *t - min_delay_s > t_end {
                continue;
            }
            let p = at(*t - tau, &mut hint);
            let f = follower[k];
            sum += (f[0] - p[0]).powi(2) + (f[1] - p[1]).powi(2) + (f[2] - p[2]).powi(2);
            count += 1;
        }
        if count == 0 {
            f64::NAN
        } else {
            (sum / count as f64).sqrt()
        }
    };
    let rms = |tau: f64| rms_over(tau, 1);
    // Coarse to fine: every 100th step, then every 10th and every step within one coarser
    // step of the best so far; the coarse levels over every 10th sample (the RMS is smooth
    // in τ at those scales; about 1/50 of the evaluations of the whole fine grid). The
    // grid's step k is the delay min_delay_s + k·step_s.
    let delay = |k: usize| min_delay_s + k as f64 * step_s;
    let steps = ((max_delay_s - min_delay_s) / step_s).round() as usize;
    let mut best = 0usize;
    for (level, stride) in [(100usize, 10usize), (10, 10)] {
        let (from, to) = if level == 100 {
            (0, steps)
        } else {
            (
                best.saturating_sub(level * 10),
                (best + level * 10).min(steps),
            )
        };
        let mut found = (best, f64::INFINITY);
        for k in (from..=to).step_by(level) {
            let r = rms_over(delay(k), stride);
            if r < found.1 {
                found = (k, r);
            }
        }
        best = found.0;
    }
    // Every sample, from the best so far (within one coarser step of the minimum, where
    // the RMS has a single minimum): downhill one step at a time (3 evaluations and one
    // per step moved, instead of the 21 of a whole fine level).
    let fine = |k: usize| rms_over(delay(k), 1);
    let mut at_best = fine(best);
    for dir in [1isize, -1] {
        while let Some(k) = best.checked_add_signed(dir).filter(|k| *k <= steps) {
            let r = fine(k);
            if r < at_best {
                (best, at_best) = (k, r);
            } else {
                break;
            }
        }
    }
    // (A delay within half a step of 0 is 0, not -0.0.)
    let d = delay(best);
    let d = if d.abs() < 0.5 * step_s { 0.0 } else { d };
    Some(Lag {
        delay_s: d,
        rms_m: rms(d),
        rms_at_zero_m: rms(0.0),
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A follower that is the stream delayed by 37 ms is found 37 ms behind, with no
    /// residual; a follower on the stream has no delay.
    #[test]
    fn a_delayed_copy_is_found_at_its_delay() {
        let t: Vec<f64> = (0..4000).map(|k| k as f64 * 1e-3).collect();
        let path = |t: f64| [0.01 * (3.0 * t).sin(), 0.008 * (5.0 * t).cos(), 0.002 * t];
        let stream: Vec<[f64; 3]> = t.iter().map(|t| path(*t)).collect();
        let late: Vec<[f64; 3]> = t.iter().map(|t| path(t - 0.037)).collect();
        let lag = best_fitting_delay(&t, &stream, &late, -0.05, 0.2, 1e-4).unwrap();
        assert!((lag.delay_s - 0.037).abs() < 1e-9, "{lag:?}");
        assert!(lag.rms_m < 1e-9 && lag.rms_at_zero_m > 1e-4);
        let lag = best_fitting_delay(&t, &stream, &stream, -0.05, 0.2, 1e-4).unwrap();
        assert_eq!(lag.delay_s, 0.0);
        // A follower 12 ms ahead (a led one) is found at -12 ms.
        let early: Vec<[f64; 3]> = t.iter().map(|t| path(t + 0.012)).collect();
        let lag = best_fitting_delay(&t, &stream, &early, -0.05, 0.2, 1e-4).unwrap();
        assert!((lag.delay_s + 0.012).abs() < 1e-9, "{lag:?}");
        // A range that does not hold 0 is refused.
        assert!(best_fitting_delay(&t, &stream, &early, 0.01, 0.2, 1e-4).is_none());
        assert!(best_fitting_delay(&t, &stream, &early, -0.05, -0.01, 1e-4).is_none());
    }

    /// The coarse-to-fine search finds the delay of a delayed copy anywhere on the grid
    /// (every 0.7 ms from -49 to 199 ms, on a grid of 0.1 ms: within half a step), as
    /// the whole fine grid would.
    #[test]
    fn every_delay_on_the_grid_is_found() {
        let t: Vec<f64> = (0..4000).map(|k| k as f64 * 1e-3).collect();
        let path = |t: f64| [0.01 * (3.0 * t).sin(), 0.008 * (5.0 * t).cos(), 0.002 * t];
        let stream: Vec<[f64; 3]> = t.iter().map(|t| path(*t)).collect();
        for k in 0..355 {
            let d = -0.049 + k as f64 * 0.7e-3;
            let late: Vec<[f64; 3]> = t.iter().map(|t| path(t - d)).collect();
            let lag = best_fitting_delay(&t, &stream, &late, -0.05, 0.2, 1e-4).unwrap();
            assert!((lag.delay_s - d).abs() <= 0.5e-4 + 1e-12, "{d}: {lag:?}");
        }
    }
}
