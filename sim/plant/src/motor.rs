//! Brushed DC motor: armature circuit and torque.
//!
//! ```text
//! L di/dt = u - R i - Ke w        torque = Kt i
//! ```
//!
//! `R` is the total resistance of the circuit (winding plus H-bridge switches). Over one
//! step the motor speed `w` is treated as constant, and the current is advanced with the
//! exact solution of the linear ODE,
//!
//! ```text
//! i(dt) = i_ss + (i0 - i_ss) exp(-dt R / L),   i_ss = (u - Ke w) / R,
//! ```
//!
//! which is exact for any `dt`, however small `L/R` is. The mechanical step uses the mean
//! current over the step, which is affine in `w`:
//!
//! ```text
//! mean(i) = phi i0 + (1 - phi) (u - Ke w) / R,   phi = (1 - exp(-x)) / x,  x = dt R / L
//! ```
//!
//! and takes `w` at the end of the step (see [`crate::joint`]), so the back-EMF acts as an
//! implicit damping `Kt Ke (1 - phi) / R`: the electro-mechanical coupling is stable for
//! every `dt`.

/// Parameters of one DC motor, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DcMotor {
    /// Winding (terminal) resistance, ohm.
    pub resistance: f64,
    /// Winding inductance, H.
    pub inductance: f64,
    /// Torque constant Kt, N m/A.
    pub torque_constant: f64,
    /// Back-EMF constant Ke, V s/rad.
    pub back_emf_constant: f64,
    /// Rotor inertia, kg m^2.
    pub rotor_inertia: f64,
    /// Maximum continuous current, A.
    pub nominal_current: f64,
}

/// Mean torque over a step as an affine function of the end-of-step speed:
/// `torque = constant - damping * w`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanTorque {
    /// Speed-independent part, N m.
    pub constant: f64,
    /// Back-EMF damping, N m s/rad.
    pub damping: f64,
}

/// `(1 - exp(-x)) / x`, accurate also for tiny `x`.
pub(crate) fn phi(x: f64) -> f64 {
    if x < 1e-8 {
        1.0 - 0.5 * x
    } else {
        -(-x).exp_m1() / x
    }
}

impl DcMotor {
    /// Electrical time constant `L / r_total`, s.
    pub fn electrical_time_constant(&self, r_total: f64) -> f64 {
        self.inductance / r_total
    }

    /// Current after `dt` from `i0` with terminal voltage `u` and speed `w` held
    /// (exact), A. `r_total` is the winding plus bridge resistance.
    pub fn current_after(&self, i0: f64, u: f64, w: f64, r_total: f64, dt: f64) -> f64 {
        let i_ss = (u - self.back_emf_constant * w) / r_total;
        let decay = (-dt * r_total / self.inductance).exp();
        i_ss + (i0 - i_ss) * decay
    }

    /// Mean motor torque over a step of length `dt` starting at current `i0` with
    /// terminal voltage `u`, as an affine function of the speed.
    pub fn mean_torque(&self, i0: f64, u: f64, r_total: f64, dt: f64) -> MeanTorque {
        let p = phi(dt * r_total / self.inductance);
        let kt = self.torque_constant;
        MeanTorque {
            constant: kt * (p * i0 + (1.0 - p) * u / r_total),
            damping: kt * self.back_emf_constant * (1.0 - p) / r_total,
        }
    }

    /// Steady no-load speed at voltage `u` against a Coulomb torque `tc` and viscous
    /// coefficient `b` (both at the motor shaft), rad/s.
    pub fn steady_speed(&self, u: f64, r_total: f64, tc: f64, b: f64) -> f64 {
        let kt = self.torque_constant;
        let drive = kt * u / r_total;
        let net = (drive.abs() - tc).max(0.0) * drive.signum();
        net / (kt * self.back_emf_constant / r_total + b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> DcMotor {
        DcMotor {
            resistance: 2.14,
            inductance: 0.238e-3,
            torque_constant: 0.0234,
            back_emf_constant: 0.0234,
            rotor_inertia: 1.08e-6,
            nominal_current: 1.2,
        }
    }

    #[test]
    fn stall_current_is_supply_over_resistance() {
        // Shaft held (w = 0): the current settles at V / R whatever the step.
        let m = motor();
        for dt in [1e-6, 1e-4, 1e-2] {
            let mut i = 0.0;
            for _ in 0..((0.01 / dt) as usize).max(1) {
                i = m.current_after(i, 24.0, 0.0, 2.14, dt);
            }
            assert!((i - 24.0 / 2.14).abs() < 1e-6, "dt {dt}: {i}");
        }
    }

    #[test]
    fn exact_exponential_over_one_time_constant() {
        let m = motor();
        let tau = m.electrical_time_constant(2.14);
        let i = m.current_after(0.0, 24.0, 0.0, 2.14, tau);
        assert!((i - 24.0 / 2.14 * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
    }

    #[test]
    fn mean_torque_matches_the_integral_of_the_current() {
        let m = motor();
        let (i0, u, w, dt) = (1.0, 12.0, 100.0, 3e-4);
        let mt = m.mean_torque(i0, u, 2.14, dt);
        let n = 100_000;
        let h = dt / n as f64;
        let mean: f64 = (0..n)
            .map(|k| m.current_after(i0, u, w, 2.14, (k as f64 + 0.5) * h))
            .sum::<f64>()
            / n as f64;
        let torque = mt.constant - mt.damping * w;
        assert!((torque - 0.0234 * mean).abs() < 1e-9);
    }
}
