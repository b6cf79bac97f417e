//! Test plants: a DC-motor joint `x'' = (k u - b x' + d) / J` and the same motor driving
//! a load through a backlash deadband. Parameters approximate the RSPR plant
//! (`sim/plant/plant.toml`): no-load speed `k/b` and mechanical time constant `J/b`.
#![allow(dead_code)]

/// A DC motor driving a joint, in joint units: `x'' = (k u - b x' + d) / J`.
#[derive(Debug, Clone, Copy)]
pub struct DcMotor {
    /// Position, u.
    pub x: f64,
    /// Velocity, u/s.
    pub v: f64,
    /// Gain, u/s^2 per duty times J.
    pub k: f64,
    /// Viscous (back-EMF) damping.
    pub b: f64,
    /// Inertia.
    pub j: f64,
    /// Constant disturbance (same units as k u).
    pub disturbance: f64,
}

impl DcMotor {
    /// A leg: no-load speed 0.378 m/s at full duty, time constant 5.6 ms.
    pub fn leg() -> Self {
        DcMotor {
            x: 0.0,
            v: 0.0,
            k: 0.378,
            b: 1.0,
            j: 0.0056,
            disturbance: 0.0,
        }
    }

    /// A link: no-load speed 28.5 rad/s at full duty, time constant 15 ms.
    pub fn link() -> Self {
        DcMotor {
            x: 0.0,
            v: 0.0,
            k: 28.5,
            b: 1.0,
            j: 0.015,
            disturbance: 0.0,
        }
    }

    /// Advances by `dt` with duty `u` held (exact solution of the linear ODE).
    pub fn step(&mut self, u: f64, dt: f64) {
        let v_inf = (self.k * u + self.disturbance) / self.b;
        let tau = self.j / self.b;
        let e = (-dt / tau).exp();
        self.x += v_inf * dt + (self.v - v_inf) * tau * (1.0 - e);
        self.v = v_inf + (self.v - v_inf) * e;
    }
}

/// A motor driving a load through a backlash of total width `width`: the load follows
/// only when the gap is closed (`|x_motor - x_load| = width / 2`) and stays put
/// otherwise (load friction, no load inertia).
#[derive(Debug, Clone, Copy)]
pub struct BacklashJoint {
    pub motor: DcMotor,
    pub load: f64,
    pub width: f64,
}

impl BacklashJoint {
    /// Motor at 0, load at 0 (gap centred).
    pub fn new(motor: DcMotor, width: f64) -> Self {
        BacklashJoint {
            motor,
            load: 0.0,
            width,
        }
    }

    /// Advances by `dt` in `substeps` steps with duty `u` held.
    pub fn step(&mut self, u: f64, dt: f64, substeps: u32) {
        let h = dt / f64::from(substeps);
        let half = 0.5 * self.width;
        for _ in 0..substeps {
            self.motor.step(u, h);
            let gap = self.motor.x - self.load;
            if gap > half {
                self.load = self.motor.x - half;
            } else if gap < -half {
                self.load = self.motor.x + half;
            }
        }
    }
}

/// A triangular back-and-forth trajectory between 0 and `amplitude` at `speed`:
/// returns (position, velocity) at time `t`.
pub fn triangle(t: f64, amplitude: f64, speed: f64) -> (f64, f64) {
    let period = 2.0 * amplitude / speed;
    let phase = t.rem_euclid(period);
    if phase < period / 2.0 {
        (speed * phase, speed)
    } else {
        (amplitude - speed * (phase - period / 2.0), -speed)
    }
}

/// Root mean square of a slice.
pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|e| e * e).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

/// Largest absolute value of a slice.
pub fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, e| m.max(e.abs()))
}

/// Six test joints (three legs, three links) in joint order.
#[derive(Debug, Clone, Copy)]
pub struct SixJoints {
    pub joints: [DcMotor; 6],
    /// A disconnected motor ignores its duty.
    pub disconnected: [bool; 6],
}

impl SixJoints {
    pub fn new() -> Self {
        let l = DcMotor::leg();
        let r = DcMotor::link();
        SixJoints {
            joints: [l, l, l, r, r, r],
            disconnected: [false; 6],
        }
    }

    /// Advances by `dt` (10 substeps) with the duties held.
    pub fn step(&mut self, duty: &[f64; 6], dt: f64) {
        for ((j, u), off) in self.joints.iter_mut().zip(duty).zip(self.disconnected) {
            let u = if off { 0.0 } else { *u };
            for _ in 0..10 {
                j.step(u, dt / 10.0);
            }
        }
    }

    pub fn positions(&self) -> [f64; 6] {
        self.joints.map(|j| j.x)
    }
}

/// A smooth six-joint trajectory: legs 5 mm amplitude at 1 Hz around 0 (peak 31 mm/s),
/// links 0.3 rad at 0.7 Hz (peak 1.3 rad/s), phase-shifted per joint; (q, q_dot).
pub fn smooth(t: f64) -> ([f64; 6], [f64; 6]) {
    let mut q = [0.0; 6];
    let mut v = [0.0; 6];
    for j in 0..6 {
        let (a, f) = if j < 3 { (5e-3, 1.0) } else { (0.3, 0.7) };
        let w = std::f64::consts::TAU * f;
        let phase = j as f64 * 0.7;
        q[j] = a * ((w * t + phase).sin() - phase.sin());
        v[j] = a * w * (w * t + phase).cos();
    }
    (q, v)
}
