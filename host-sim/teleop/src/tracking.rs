//! Tracking figures seen from the master: how far the measured pose of each status lies
//! from the path the master streamed just before it arrived.
//!
//! The master does not see the board's setpoint, and the setpoint lags the stream by the
//! link, the supervisor's verification and its rate limits. So the measured pose is
//! compared with the streamed path over a recent window (default 250 ms): the distance to
//! the nearest point of that polyline (the deviation from the path) and how long ago the
//! master was at that point (the lag).

use kinematics_core::pose::rotation_angle;
use kinematics_core::Pose;
use nalgebra::Vector3;

/// A stretch of the path whose tracking is judged on its own: (name, start s, end s).
pub type Pass = (String, f64, f64);

/// One status's deviation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deviation {
    /// Distance of the measured tip position from the streamed path, m.
    pub position_m: f64,
    /// Angle between the measured orientation and the path's at that point, rad.
    pub angle_rad: f64,
    /// Time since the master streamed that point, s.
    pub lag_s: f64,
}

/// The deviation of `measured` (arrived at `t_s`) from the targets `sent` (time, pose;
/// in time order) over `[t_s - window_s, t_s]`; `None` without targets in the window.
pub fn deviation(
    sent: &[(f64, Pose<f64>)],
    t_s: f64,
    window_s: f64,
    measured: &Pose<f64>,
) -> Option<Deviation> {
    let end = sent.partition_point(|(t, _)| *t <= t_s);
    let start = sent.partition_point(|(t, _)| *t < t_s - window_s);
    let slice = sent.get(start.saturating_sub(1)..end)?;
    // (distance, time, index in `slice` of the nearer target)
    let mut best: Option<(f64, f64, usize)> = None;
    let mut consider = |d: f64, t: f64, i: usize| {
        if best.is_none_or(|(bd, _, _)| d < bd) {
            best = Some((d, t, i));
        }
    };
    match slice {
        [] => return None,
        [(t, p)] => consider((measured.t - p.t).norm(), *t, 0),
        _ => {
            for (i, w) in slice.windows(2).enumerate() {
                let [(ta, a), (tb, b)] = w else { continue };
                let (d, s) = point_segment(&measured.t, &a.t, &b.t);
                consider(d, ta + (tb - ta) * s, if s < 0.5 { i } else { i + 1 });
            }
        }
    }
    let (d, t, i) = best?;
    let (_, p) = slice.get(i)?;
    Some(Deviation {
        position_m: d,
        angle_rad: rotation_angle(&(measured.r * p.r.inverse())),
        lag_s: t_s - t,
    })
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

/// RMS and maximum of `values` (0, 0 when empty).
pub fn rms_max(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let ss: f64 = values.iter().map(|v| v * v).sum();
    let max = values.iter().copied().fold(0.0, f64::max);
    ((ss / values.len() as f64).sqrt(), max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deviation_from_a_straight_stream() {
        let p = |x: f64| {
            Pose::<f64>::from_position_rotation_vector(Vector3::new(x, 0.0, 0.16), Vector3::zeros())
        };
        let sent: Vec<(f64, Pose<f64>)> = (0..10)
            .filter_map(|i| p(i as f64 * 1e-3).ok().map(|q| (i as f64 * 0.01, q)))
            .collect();
        let measured = Pose::from_position_rotation_vector(
            Vector3::new(4.5e-3, 0.2e-3, 0.16),
            Vector3::zeros(),
        );
        let Ok(measured) = measured else { return };
        let d = deviation(&sent, 0.09, 0.25, &measured);
        let Some(d) = d else { panic!("no deviation") };
        assert!((d.position_m - 0.2e-3).abs() < 1e-12);
        assert!((d.lag_s - 0.045).abs() < 1e-9);
        assert_eq!(rms_max(&[3.0, 4.0]).1, 4.0);
    }
}
