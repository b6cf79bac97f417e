//! Closed-loop runs on a joint: the step response (overshoot, settling time) and the
//! tracking of a smooth path, both through the board's servo ([`crate::rig`]); and the
//! identified model as a joint of the plant's integrator, so that the prediction runs the
//! same servo, PWM and encoder path as the measurement.

use plant::backlash::Backlash;
use plant::friction::Friction;
use plant::gearing::Transmission;
use plant::hbridge::HBridge;
use plant::joint::{BrakeModel, JointKind, JointModel};
use plant::motor::DcMotor;
use servo::{BacklashParams, PidGains};

use crate::error::IdentifyError;
use crate::estimate::Identified;
use crate::rig::{JointRig, TracePoint};

/// The band of the settling time, a fraction of the step.
pub const SETTLING_BAND: f64 = 0.05;

/// A step response, measured on the encoder (the servo's own view of the joint).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepResponse {
    /// The step, m or rad.
    pub amplitude: f64,
    /// The peak beyond the step over the step, >= 0.
    pub overshoot: f64,
    /// From the step to the last time the position was outside +-[`SETTLING_BAND`] of the
    /// step, s.
    pub settling_time_s: f64,
    /// From 10 % to 90 % of the step, s.
    pub rise_time_s: f64,
}

/// The overshoot, settling and rise times of a step of `amplitude` in `trace`.
pub fn step_metrics(trace: &[TracePoint], amplitude: f64) -> Result<StepResponse, IdentifyError> {
    if trace.len() < 3 || amplitude == 0.0 || !amplitude.is_finite() {
        return Err(IdentifyError::Recording(
            "a step response needs a trace and a finite, non-zero step".into(),
        ));
    }
    let y = |p: &TracePoint| p.measured / amplitude;
    let peak = trace.iter().map(y).fold(f64::MIN, f64::max);
    let last_out = trace
        .iter()
        .rposition(|p| (y(p) - 1.0).abs() > SETTLING_BAND)
        .unwrap_or(0);
    if last_out + 1 >= trace.len() {
        return Err(IdentifyError::Recording(format!(
            "the step did not settle within {:.3} s",
            trace.last().map_or(0.0, |p| p.t)
        )));
    }
    let t_at = |frac: f64| trace.iter().find(|p| y(p) >= frac).map(|p| p.t);
    let rise = match (t_at(0.1), t_at(0.9)) {
        (Some(a), Some(b)) => b - a,
        _ => f64::NAN,
    };
    Ok(StepResponse {
        amplitude,
        overshoot: (peak - 1.0).max(0.0),
        settling_time_s: trace[last_out + 1].t,
        rise_time_s: rise,
    })
}

/// Runs a step of `amplitude` from rest through the board's servo with `gains` (backlash
/// compensation off: a step response is the loop's) for `ticks` periods.
pub fn step_response(
    rig: &JointRig,
    gains: &PidGains<f64>,
    amplitude: f64,
    ticks: usize,
) -> Result<(StepResponse, Vec<TracePoint>), IdentifyError> {
    let mut r = rig.clone();
    let trace = r.servo_run(
        gains,
        BacklashParams::off(),
        ticks,
        3.0 * amplitude.abs(),
        |_| (amplitude, 0.0),
    )?;
    Ok((step_metrics(&trace, amplitude)?, trace))
}

/// Tracking of a smooth path, load side (the true position, as the simulation's tracking
/// error) and motor side (the encoder).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracking {
    /// RMS of the true load position minus the setpoint, m or rad.
    pub rms_load: f64,
    /// Its largest magnitude.
    pub max_load: f64,
    /// RMS of the encoder position minus the setpoint.
    pub rms_measured: f64,
}

/// The path of a tracking run: `r = A (1 - cos w t)` over two periods then held, with its
/// velocity as the feed-forward, and `A w` the task's top speed: 2.5 mm at 10 rad/s on a
/// leg (25 mm/s), 5 deg at 3 rad/s on a link (0.26 rad/s).
pub fn tracking_path(kind: JointKind) -> (f64, f64) {
    match kind {
        JointKind::Prismatic => (2.5e-3, 10.0),
        JointKind::Rotary => (5f64.to_radians(), 3.0),
    }
}

/// Runs the tracking path of the joint's kind through the board's servo with `gains` and
/// the backlash compensation `backlash`.
pub fn tracking(
    rig: &JointRig,
    gains: &PidGains<f64>,
    backlash: BacklashParams<f64>,
) -> Result<Tracking, IdentifyError> {
    let (a, w) = tracking_path(rig.kind());
    let duration = 2.0 * std::f64::consts::TAU / w + 0.2;
    let ticks = (duration / rig.period_s()).ceil() as usize;
    let end = 2.0 * std::f64::consts::TAU / w;
    let mut r = rig.clone();
    let trace = r.servo_run(gains, backlash, ticks, 3.0 * a, |t| {
        if t < end {
            (a * (1.0 - (w * t).cos()), a * w * (w * t).sin())
        } else {
            (0.0, 0.0)
        }
    })?;
    let n = trace.len() as f64;
    let rms = |f: &dyn Fn(&TracePoint) -> f64| {
        (trace.iter().map(|p| f(p).powi(2)).sum::<f64>() / n).sqrt()
    };
    Ok(Tracking {
        rms_load: rms(&|p| p.load - p.setpoint),
        max_load: trace
            .iter()
            .map(|p| (p.load - p.setpoint).abs())
            .fold(0.0, f64::max),
        rms_measured: rms(&|p| p.measured - p.setpoint),
    })
}

/// The identified joint as a joint of the plant's integrator: one rigid body of mass `M`
/// behind a gear of the drawing's ratio (no backlash, no transmission losses), the
/// identified friction at the motor, the identified circuit and torque constant, and what
/// the board knows without identifying it (the gear, the supply, the driver's current
/// regulation) from `board`. A viscous estimate below zero (on this plant within its
/// deviation of zero: see the crate's README) enters as zero, the plant's friction model
/// taking no negative coefficient.
pub fn model_joint(id: &Identified, board: &JointModel) -> JointModel {
    let n = board.transmission.ratio;
    let k = id.force_per_amp.value;
    // A non-positive inductance (below the recording's resolution) as a fast circuit.
    let tau_e = id.electrical_time_constant().max(1e-6);
    JointModel {
        kind: board.kind,
        motor: DcMotor {
            resistance: id.resistance.value,
            inductance: tau_e * id.resistance.value,
            torque_constant: k / n,
            back_emf_constant: k / n,
            rotor_inertia: id.mass.value / (n * n),
            nominal_current: board.motor.nominal_current,
        },
        bridge: HBridge {
            supply: board.bridge.supply,
            on_resistance: 0.0,
        },
        transmission: Transmission {
            ratio: n,
            efficiency: 1.0,
            inertia_at_motor: 0.0,
        },
        backlash: Backlash { width: 0.0 },
        motor_friction: Friction {
            coulomb: id.coulomb.value / n,
            viscous: id.viscous.value.max(0.0) / (n * n),
            breakaway_ratio: 1.0,
        },
        // The rigid load: a vanishing share of the mass on the load side.
        load_inertia: id.mass.value * 1e-9,
        load_friction: Friction {
            coulomb: 0.0,
            viscous: 0.0,
            breakaway_ratio: 1.0,
        },
        current_limit: board.current_limit,
        driver_ocp: f64::INFINITY,
        brake: BrakeModel::NONE,
    }
}
