//! How far one time-stamped path lags another: the end-to-end latency of teleoperation,
//! from the master's input to the target sent, to the board's setpoint and to the measured
//! pose.
//!
//! # Method
//!
//! A follower (the setpoint, say) lags its reference (what the operator commanded) by `τ`
//! when its position at time `t` is where the reference was at `t − τ`. For each follower
//! sample `(t, p)` the reference's polyline over `[t − window, t]` is searched for the point
//! nearest to `p`; its time `t*` (interpolated along the segment) gives `τ = t − t*`.
//! This is the figure the issue quotes ("the setpoint lags the master's stream by about
//! 40-80 ms, 2.0 mm behind at 25 mm/s"): distance behind along the path over speed.
//!
//! A lag is defined only while the reference moves: a sample is used when the reference's
//! speed is at least `min_speed_m_s` both at `t*` and over the last `window` before `t`
//! (the average speed), and the follower lies within `max_offset_m` of the path (a follower
//! that cuts a corner or has stopped is not matched to a point it is not following). The
//! figures are the median, the 90th percentile and the largest of the matched samples.

use nalgebra::Vector3;
use std::fmt;

/// Settings of the lag measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LagConfig {
    /// How far back the reference is searched, s.
    pub window_s: f64,
    /// The reference must move at least this fast, m/s.
    pub min_speed_m_s: f64,
    /// The follower must lie within this distance of the reference's path, m.
    pub max_offset_m: f64,
}

impl Default for LagConfig {
    /// A 0.5 s window, 1 mm/s, 0.2 mm.
    fn default() -> Self {
        LagConfig {
            window_s: 0.5,
            min_speed_m_s: 0.001,
            max_offset_m: 0.0002,
        }
    }
}

/// The lags of the matched samples, summarised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LagStats {
    /// Samples matched.
    pub samples: usize,
    /// Median, s.
    pub median_s: f64,
    /// 90th percentile, s.
    pub p90_s: f64,
    /// Largest, s.
    pub max_s: f64,
}

impl LagStats {
    /// The statistics of `lags` (None when empty or not finite).
    pub fn of(lags: &[f64]) -> Option<LagStats> {
        let mut v: Vec<f64> = lags.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| {
            let i = ((v.len() - 1) as f64 * q).round() as usize;
            v.get(i).copied().unwrap_or(f64::NAN)
        };
        Some(LagStats {
            samples: v.len(),
            median_s: at(0.5),
            p90_s: at(0.9),
            max_s: at(1.0),
        })
    }
}

impl fmt::Display for LagStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "median {:.1} ms, p90 {:.1} ms, max {:.1} ms ({} samples)",
            self.median_s * 1e3,
            self.p90_s * 1e3,
            self.max_s * 1e3,
            self.samples
        )
    }
}

/// A time-stamped position, `(t_s, p_m)`; paths are in time order.
pub type Stamped = (f64, Vector3<f64>);

/// The lag of each follower sample behind `reference` (see the module documentation), in
/// follower order; samples that cannot be matched are left out.
pub fn lags(reference: &[Stamped], follower: &[Stamped], cfg: &LagConfig) -> Vec<f64> {
    follower
        .iter()
        .filter_map(|(t, p)| lag_at(reference, *t, p, cfg))
        .collect()
}

/// The lag of one follower sample `p` at `t`.
pub fn lag_at(reference: &[Stamped], t: f64, p: &Vector3<f64>, cfg: &LagConfig) -> Option<f64> {
    let end = reference.partition_point(|(tr, _)| *tr <= t);
    let start = reference.partition_point(|(tr, _)| *tr < t - cfg.window_s);
    let slice = reference.get(start..end)?;
    let (first, last) = (slice.first()?, slice.last()?);
    let span = last.0 - first.0;
    if span <= 0.0 {
        return None;
    }
    // The reference must be moving now: its average speed over the window.
    let mean_speed = path_length(slice) / span;
    if mean_speed < cfg.min_speed_m_s {
        return None;
    }
    // (distance, time, speed of the segment)
    let mut best: Option<(f64, f64, f64)> = None;
    for w in slice.windows(2) {
        let [(ta, a), (tb, b)] = w else { continue };
        let dt = tb - ta;
        if dt <= 0.0 {
            continue;
        }
        let (d, s) = point_segment(p, a, b);
        if best.is_none_or(|(bd, _, _)| d < bd) {
            best = Some((d, ta + dt * s, (b - a).norm() / dt));
        }
    }
    let (d, t_star, speed) = best?;
    (d <= cfg.max_offset_m && speed >= cfg.min_speed_m_s).then_some(t - t_star)
}

fn path_length(path: &[Stamped]) -> f64 {
    path.windows(2)
        .map(|w| match w {
            [(_, a), (_, b)] => (b - a).norm(),
            _ => 0.0,
        })
        .sum()
}

/// Distance from `x` to the segment `a`-`b` and the parameter of the nearest point.
fn point_segment(x: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> (f64, f64) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let s = if len2 > 0.0 {
        ((x - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((a + ab * s - x).norm(), s)
}

/// The latency figures of a teleoperation run: each stage's lag behind the previous one,
/// and the whole chain from the operator's command.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatencyFigures {
    /// Commanded (the master's scaled input, stamped with the input sample's time) → target
    /// sent: the tremor filter's delay, the limits and the host's loop.
    pub input_to_target: Option<LagStats>,
    /// Target sent → the board's setpoint (status arrival): the link, the supervisor's
    /// verification and its speed profile.
    pub target_to_setpoint: Option<LagStats>,
    /// Setpoint → measured pose: the servo.
    pub setpoint_to_measured: Option<LagStats>,
    /// Commanded → setpoint.
    pub input_to_setpoint: Option<LagStats>,
    /// Commanded → measured pose: the whole chain.
    pub input_to_measured: Option<LagStats>,
}

impl LatencyFigures {
    /// From the commanded path, the targets, the setpoints and the measured poses.
    pub fn measure(
        commanded: &[Stamped],
        targets: &[Stamped],
        setpoints: &[Stamped],
        measured: &[Stamped],
        cfg: &LagConfig,
    ) -> Self {
        let stats = |r: &[Stamped], f: &[Stamped]| LagStats::of(&lags(r, f, cfg));
        LatencyFigures {
            input_to_target: stats(commanded, targets),
            target_to_setpoint: stats(targets, setpoints),
            setpoint_to_measured: stats(setpoints, measured),
            input_to_setpoint: stats(commanded, setpoints),
            input_to_measured: stats(commanded, measured),
        }
    }
}

impl fmt::Display for LatencyFigures {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rows = [
            ("master input -> target sent", self.input_to_target),
            ("target sent -> board setpoint", self.target_to_setpoint),
            ("board setpoint -> measured pose", self.setpoint_to_measured),
            ("master input -> board setpoint", self.input_to_setpoint),
            ("master input -> measured pose", self.input_to_measured),
        ];
        for (name, s) in rows {
            match s {
                Some(s) => writeln!(f, "  {name:<32} {s}")?,
                None => writeln!(f, "  {name:<32} (no motion to measure it on)")?,
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A ramp at 10 mm/s and a copy of it delayed by 37 ms: every matched lag is 37 ms.
    #[test]
    fn delayed_ramp_lags_by_its_delay() {
        let v = 0.010;
        let ramp = |t: f64| Vector3::new(v * t.max(0.0), 0.0, 0.16);
        let reference: Vec<Stamped> = (0..200)
            .map(|k| (k as f64 * 0.01, ramp(k as f64 * 0.01)))
            .collect();
        let follower: Vec<Stamped> = (0..100)
            .map(|k| {
                let t = 0.5 + k as f64 * 0.013;
                (t, ramp(t - 0.037))
            })
            .collect();
        let l = lags(&reference, &follower, &LagConfig::default());
        assert_eq!(l.len(), follower.len());
        for x in l {
            assert!((x - 0.037).abs() < 1e-9, "{x}");
        }
    }

    /// A reference at rest gives no lag (undefined), and a follower off the path is not
    /// matched.
    #[test]
    fn no_lag_without_motion_or_off_the_path() {
        let still: Vec<Stamped> = (0..100)
            .map(|k| (k as f64 * 0.01, Vector3::zeros()))
            .collect();
        assert!(lag_at(&still, 0.5, &Vector3::zeros(), &LagConfig::default()).is_none());
        let moving: Vec<Stamped> = (0..100)
            .map(|k| {
                (
                    k as f64 * 0.01,
                    Vector3::new(0.01 * k as f64 * 0.01, 0.0, 0.0),
                )
            })
            .collect();
        let off = Vector3::new(0.004, 0.001, 0.0);
        assert!(lag_at(&moving, 0.5, &off, &LagConfig::default()).is_none());
    }
}
