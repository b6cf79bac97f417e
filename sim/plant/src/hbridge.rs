//! H-bridge: the averaged output of a PWM full bridge with synchronous rectification.
//!
//! The motor sees `duty * supply` (the PWM ripple is averaged out: at 20 kHz and more the
//! ripple period is far below the electrical time constant). Duty 0 shorts the motor
//! terminals through the low-side switches, which brakes it. The bridge is four-quadrant:
//! current flows back into the supply when the back-EMF exceeds the applied voltage.
//!
//! A duty outside [-1, 1] cannot be produced: it is saturated to the nearest end and the
//! saturation is reported (never silently). A duty that is not finite is an error.

/// One H-bridge (all six are alike).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HBridge {
    /// Supply voltage, V.
    pub supply: f64,
    /// Resistance of the two conducting switches, ohm.
    pub on_resistance: f64,
}

/// A duty command after supply-voltage saturation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Duty {
    /// Duty actually applied, in [-1, 1].
    pub applied: f64,
    /// The command was outside [-1, 1] and was saturated.
    pub saturated: bool,
}

impl HBridge {
    /// Saturates a duty command to [-1, 1]; `None` if it is not finite.
    pub fn saturate(duty: f64) -> Option<Duty> {
        if !duty.is_finite() {
            return None;
        }
        let applied = duty.clamp(-1.0, 1.0);
        Some(Duty {
            applied,
            saturated: applied != duty,
        })
    }

    /// Mean voltage across the motor for an applied duty, V.
    pub fn voltage(&self, duty: Duty) -> f64 {
        duty.applied * self.supply
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saturation_is_reported_and_non_finite_is_rejected() {
        assert_eq!(
            HBridge::saturate(0.5),
            Some(Duty {
                applied: 0.5,
                saturated: false
            })
        );
        assert_eq!(
            HBridge::saturate(-1.5),
            Some(Duty {
                applied: -1.0,
                saturated: true
            })
        );
        assert_eq!(HBridge::saturate(f64::NAN), None);
        assert_eq!(HBridge::saturate(f64::INFINITY), None);
    }
}
