//! Viscous and Coulomb friction with stiction, integrated implicitly so that it never
//! chatters at zero speed.
//!
//! A body of mass `m` (or inertia) under a force `f` that is constant over the step, a
//! linear damping `c` (viscous friction plus any other force proportional to velocity,
//! such as the motor's back-EMF braking) and a Coulomb friction of magnitude `fc` takes
//! one backward-Euler velocity step
//!
//! ```text
//! m (v1 - v0) = dt (f - c v1 - fc sgn(v1)),   sgn(0) in [-1, 1]
//! ```
//!
//! This set-valued equation has exactly one solution (Moreau's sweeping process): with
//! `p = m v0 + dt f`, the body sticks (`v1 = 0`) when `|p| <= dt fc`, otherwise
//! `v1 = (p - sgn(p) dt fc) / (m + dt c)`. A body at rest holds up to the breakaway
//! friction `ratio * fc` (stiction) before it slides. The result is stable for every dt
//! and a body at rest stays exactly at rest.

/// Friction of one side of a joint (motor side or load side), in that side's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction {
    /// Coulomb (sliding) friction force or torque, >= 0.
    pub coulomb: f64,
    /// Viscous coefficient, force per velocity, >= 0.
    pub viscous: f64,
    /// Static over Coulomb friction, >= 1.
    pub breakaway_ratio: f64,
}

impl Friction {
    /// Largest friction the side holds at rest, `breakaway_ratio * coulomb`.
    pub fn static_limit(&self) -> f64 {
        self.breakaway_ratio * self.coulomb
    }

    /// Friction force or torque at velocity `v` while sliding (for reporting and steady
    /// state estimates).
    pub fn sliding(&self, v: f64) -> f64 {
        if v == 0.0 {
            0.0
        } else {
            self.coulomb * v.signum() + self.viscous * v
        }
    }
}

/// Result of one implicit velocity step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityStep {
    /// Velocity at the end of the step.
    pub v: f64,
    /// The body is stuck (held by static friction) at the end of the step.
    pub stuck: bool,
}

/// One backward-Euler velocity step with Coulomb friction and stiction (see the module
/// documentation).
///
/// * `m` mass or inertia (> 0), `v0` velocity at the start, `force` the constant force
/// * `damping` linear damping (>= 0), `coulomb` sliding friction (>= 0)
/// * `static_limit` the largest friction a body at rest can hold (>= `coulomb`)
/// * `stuck` the body was stuck at the start of the step: it then holds up to
///   `static_limit`.
#[allow(clippy::too_many_arguments)]
pub fn implicit_velocity_step(
    m: f64,
    v0: f64,
    force: f64,
    damping: f64,
    coulomb: f64,
    static_limit: f64,
    stuck: bool,
    dt: f64,
) -> VelocityStep {
    let v_start = if stuck { 0.0 } else { v0 };
    let p = m * v_start + dt * force;
    let hold = if stuck { static_limit } else { coulomb };
    if p.abs() <= dt * hold {
        return VelocityStep {
            v: 0.0,
            stuck: true,
        };
    }
    let v = (p - p.signum() * dt * coulomb) / (m + dt * damping);
    VelocityStep { v, stuck: false }
}

/// The same backward-Euler step as [`implicit_velocity_step`], for a body stepped many
/// times with one `dt`: from the momentum `p = m v_start + dt f` (`v_start = 0` if the body
/// was stuck), with `dt_coulomb = dt fc`, `dt_hold = dt * (static_limit if stuck, else fc)`
/// and the denominator precomputed, `inv_den = 1 / (m + dt c)`:
/// `v1 = (p - sgn(p) dt fc) / (m + dt c)` unless `|p| <= dt_hold` (stuck).
#[inline]
pub fn velocity_step_from_momentum(
    p: f64,
    dt_coulomb: f64,
    dt_hold: f64,
    inv_den: f64,
) -> VelocityStep {
    if p.abs() <= dt_hold {
        return VelocityStep {
            v: 0.0,
            stuck: true,
        };
    }
    VelocityStep {
        v: (p - dt_coulomb.copysign(p)) * inv_den,
        stuck: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_force_below_the_breakaway_level_does_not_move_a_body_at_rest() {
        let s = implicit_velocity_step(1.0, 0.0, 1.1, 0.0, 1.0, 1.2, true, 1e-3);
        assert_eq!(
            s,
            VelocityStep {
                v: 0.0,
                stuck: true
            }
        );
        let s = implicit_velocity_step(1.0, 0.0, 1.3, 0.0, 1.0, 1.2, true, 1e-3);
        assert!(!s.stuck && (s.v - 0.3e-3).abs() < 1e-12);
    }

    #[test]
    fn a_sliding_body_stops_exactly_and_does_not_chatter() {
        // Decelerates at 1 m/s^2 from 1 mm/s: stops after 1 ms and stays stopped.
        let mut st = VelocityStep {
            v: 1e-3,
            stuck: false,
        };
        let mut stopped_at = None;
        for k in 0..100 {
            st = implicit_velocity_step(1.0, st.v, 0.0, 0.0, 1.0, 1.0, st.stuck, 1e-4);
            assert!(st.v >= 0.0, "velocity changed sign: {}", st.v);
            if st.stuck && stopped_at.is_none() {
                stopped_at = Some(k);
            }
        }
        assert!(matches!(stopped_at, Some(9..=10)), "{stopped_at:?}");
        assert_eq!(st.v, 0.0);
    }

    #[test]
    fn the_momentum_form_is_the_same_step() {
        for &(m, v0, f, c, fc, fs, stuck, dt) in &[
            (1.0, 0.0, 1.1, 0.0, 1.0, 1.2, true, 1e-3),
            (1.0, 0.0, 1.3, 0.0, 1.0, 1.2, true, 1e-3),
            (63.0, -0.02, 40.0, 3.5, 10.7, 12.8, false, 1e-4),
            (3.5e-3, 0.3, -0.02, 1e-3, 0.01, 0.012, false, 1e-4),
            (1e-6, 10.0, 0.0, 1e3, 0.0, 1.0, false, 1.0),
        ] {
            let a = implicit_velocity_step(m, v0, f, c, fc, fs, stuck, dt);
            let p = m * if stuck { 0.0 } else { v0 } + dt * f;
            let hold = if stuck { fs } else { fc };
            let b = velocity_step_from_momentum(p, dt * fc, dt * hold, 1.0 / (m + dt * c));
            assert_eq!(a.stuck, b.stuck);
            assert!((a.v - b.v).abs() <= 1e-14 * a.v.abs(), "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn stable_with_a_huge_step_and_stiff_damping() {
        let s = implicit_velocity_step(1e-6, 10.0, 0.0, 1e3, 0.0, 1.0, false, 1.0);
        assert!(s.v.abs() < 10.0 && s.v >= 0.0);
    }
}
