//! Backlash: a deadband between the motor side and the load side of a transmission.
//!
//! Both sides are rigid bodies in joint units: the motor side at `x_m` (motor angle / n),
//! the load side at `q`. Their difference, the gap `g = x_m - q`, is free inside
//! `[-b/2, b/2]` (`b` the total backlash at the joint). At `g = +b/2` the motor side can
//! push the load in `+q` (and the load can lean on the motor towards `-q`); at `-b/2`
//! the other flanks touch. The flanks are rigid and the contact is inelastic: a side that
//! closes the gap moves on together with the other, with momentum conserved. Inside the
//! gap the load moves only under its own forces (external load, load-side friction), so
//! the encoder, which sits on the motor, moves by the backlash after a reversal before the
//! load follows, unless an external load keeps the flanks pressed together.

/// Which pair of flanks is in contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flank {
    /// `g = +b/2`: the motor side leads, it pushes the load towards `+q`.
    Positive,
    /// `g = -b/2`: the motor side trails, it pushes the load towards `-q`.
    Negative,
}

impl Flank {
    /// +1 or -1.
    pub fn sign(self) -> f64 {
        match self {
            Flank::Positive => 1.0,
            Flank::Negative => -1.0,
        }
    }
}

/// A deadband of total width `width` (joint units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backlash {
    /// Total backlash at the joint, m or rad (>= 0).
    pub width: f64,
}

impl Backlash {
    /// Half the width: the gap limit.
    pub fn half(&self) -> f64 {
        0.5 * self.width
    }

    /// The flanks that a predicted gap would press together, if any.
    pub fn contact(&self, predicted_gap: f64) -> Option<Flank> {
        let h = self.half();
        if predicted_gap > h {
            Some(Flank::Positive)
        } else if predicted_gap < -h {
            Some(Flank::Negative)
        } else {
            None
        }
    }

    /// Gap at a flank.
    pub fn gap_at(&self, flank: Flank) -> f64 {
        flank.sign() * self.half()
    }

    /// Splits a gap closure `dg` between two bodies of masses `m_motor` and `m_load`
    /// so that their centre of mass does not move: returns the displacements
    /// `(d_motor, d_load)` with `d_motor - d_load = dg` and
    /// `m_motor d_motor + m_load d_load = 0`.
    pub fn split_closure(dg: f64, m_motor: f64, m_load: f64) -> (f64, f64) {
        let mt = m_motor + m_load;
        (dg * m_load / mt, -dg * m_motor / mt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closure_keeps_the_centre_of_mass() {
        let (dm, dl) = Backlash::split_closure(1e-4, 63.0, 0.4);
        assert!((dm - dl - 1e-4).abs() < 1e-18);
        assert!((63.0 * dm + 0.4 * dl).abs() < 1e-15);
    }

    #[test]
    fn contact_only_beyond_the_half_width() {
        let b = Backlash { width: 2.0 };
        assert_eq!(b.contact(0.99), None);
        assert_eq!(b.contact(1.01), Some(Flank::Positive));
        assert_eq!(b.contact(-1.01), Some(Flank::Negative));
    }
}
