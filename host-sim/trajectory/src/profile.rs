//! A trapezoidal speed profile along a move.

/// A speed profile along a move of `length` (any unit): trapezoidal, from rest to rest,
/// peak speed `speed`, acceleration `accel` (triangular when too short to reach `speed`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Profile {
    length: f64,
    speed: f64,
    accel: f64,
    t_acc: f64,
    duration: f64,
}

impl Profile {
    /// The profile; a zero length gives a zero duration.
    pub fn new(length: f64, speed: f64, accel: f64) -> Self {
        if !(length > 0.0 && speed > 0.0 && accel > 0.0) {
            return Profile {
                length: 0.0,
                speed: 0.0,
                accel: 0.0,
                t_acc: 0.0,
                duration: 0.0,
            };
        }
        let mut t_acc = speed / accel;
        let mut v = speed;
        let d_acc = 0.5 * accel * t_acc * t_acc;
        let duration = if 2.0 * d_acc >= length {
            t_acc = (length / accel).sqrt();
            v = accel * t_acc;
            2.0 * t_acc
        } else {
            2.0 * t_acc + (length - 2.0 * d_acc) / speed
        };
        Profile {
            length,
            speed: v,
            accel,
            t_acc,
            duration,
        }
    }

    /// Duration of the move, s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Distance covered `t` seconds after the start (clamped to the move).
    pub fn distance(&self, t: f64) -> f64 {
        if self.duration <= 0.0 {
            return self.length;
        }
        let t = t.clamp(0.0, self.duration);
        let d_acc = 0.5 * self.accel * self.t_acc * self.t_acc;
        if t < self.t_acc {
            0.5 * self.accel * t * t
        } else if t < self.duration - self.t_acc {
            d_acc + self.speed * (t - self.t_acc)
        } else {
            let r = self.duration - t;
            self.length - 0.5 * self.accel * r * r
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_reaches_the_end_at_its_duration() {
        let p = Profile::new(0.1, 0.025, 0.1);
        assert!((p.distance(p.duration()) - 0.1).abs() < 1e-12);
        assert!((p.duration() - (0.1 / 0.025 + 0.025 / 0.1)).abs() < 1e-12);
        let short = Profile::new(1e-4, 0.025, 0.1);
        assert!((short.distance(short.duration()) - 1e-4).abs() < 1e-15);
    }
}
