//! What a run measures, per tick, and the JSON summary it becomes.
//!
//! Two pose errors are kept apart (both from the TRUE pose: the plant's load-side joints
//! through forward kinematics, never the encoders):
//! - the **tracking error**: the true pose at the instant the controller reads its
//!   encoders against the supervisor's setpoint of that same tick (what the servo is asked
//!   to hold at that instant);
//! - the **target error**: the same true pose against the last target the master sent,
//!   which also contains the supervisor's deliberate rate limiting and its lag behind the
//!   stream.
//!
//! The tip is the platform centre o_p (CONVENTIONS.md: the tip speed is the speed of o_p).

use super::engine::TickSample;
use super::scenario::{Phase, StepSpec};
use kinematics_core::pose::{rotation_angle, rotation_vector};
use kinematics_core::supervisor::Mode;
use kinematics_core::Pose;
use serde::Serialize;
use servo::tracking::{FaultKind, TrackingFault};
use servo::JOINT_NAMES;

/// Joints 0..3 are legs (m, shown in mm), 3..6 links (rad, shown in deg).
fn to_edge(j: usize, v: f64) -> f64 {
    if j < 3 {
        v * 1e3
    } else {
        v.to_degrees()
    }
}

/// A pose at the edge: x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
pub fn edge_pose(p: &Pose<f64>) -> [f64; 6] {
    let r = rotation_vector(&p.r).map(f64::to_degrees);
    [p.t.x * 1e3, p.t.y * 1e3, p.t.z * 1e3, r.x, r.y, r.z]
}

/// Position (mm) and orientation (deg) error of `a` against `b`.
pub fn pose_error(a: &Pose<f64>, b: &Pose<f64>) -> (f64, f64) {
    (
        (a.t - b.t).norm() * 1e3,
        rotation_angle(&(a.r * b.r.inverse())).to_degrees(),
    )
}

/// RMS and maximum of a series.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stat {
    pub n: u64,
    pub sum_sq: f64,
    pub max: f64,
    pub max_at_s: f64,
}

impl Stat {
    pub fn add(&mut self, v: f64, t: f64) {
        self.n += 1;
        self.sum_sq += v * v;
        if v.abs() > self.max {
            self.max = v.abs();
            self.max_at_s = t;
        }
    }
    pub fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
    pub fn merge(&mut self, o: &Stat) {
        self.n += o.n;
        self.sum_sq += o.sum_sq;
        if o.max > self.max {
            self.max = o.max;
            self.max_at_s = o.max_at_s;
        }
    }
}

/// Position and orientation errors of one kind.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseStats {
    pub tip: Stat,
    pub orientation: Stat,
}

impl PoseStats {
    fn add(&mut self, (tip, ori): (f64, f64), t: f64) {
        self.tip.add(tip, t);
        self.orientation.add(ori, t);
    }
    fn merge(&mut self, o: &PoseStats) {
        self.tip.merge(&o.tip);
        self.orientation.merge(&o.orientation);
    }
    /// As JSON.
    pub fn summary(&self) -> PoseErrorSummary {
        PoseErrorSummary {
            tip_rms_mm: self.tip.rms(),
            tip_max_mm: self.tip.max,
            tip_max_at_s: self.tip.max_at_s,
            orientation_rms_deg: self.orientation.rms(),
            orientation_max_deg: self.orientation.max,
            orientation_max_at_s: self.orientation.max_at_s,
            samples: self.tip.n,
        }
    }
}

/// Tracking, target and joint errors over an interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Window {
    pub tracking: PoseStats,
    pub target: PoseStats,
    /// True joint minus joint setpoint, m or rad.
    pub joints: [Stat; 6],
}

impl Window {
    fn merge(&mut self, o: &Window) {
        self.tracking.merge(&o.tracking);
        self.target.merge(&o.target);
        for (a, b) in self.joints.iter_mut().zip(&o.joints) {
            a.merge(b);
        }
    }
    fn joint_summaries(&self) -> Vec<JointErrorSummary> {
        self.joints
            .iter()
            .enumerate()
            .map(|(j, s)| {
                let leg = j < 3;
                let (rms, max) = (to_edge(j, s.rms()), to_edge(j, s.max));
                JointErrorSummary {
                    joint: JOINT_NAMES[j],
                    rms_mm: leg.then_some(rms),
                    max_mm: leg.then_some(max),
                    rms_deg: (!leg).then_some(rms),
                    max_deg: (!leg).then_some(max),
                    max_at_s: s.max_at_s,
                }
            })
            .collect()
    }
}

/// RMS and maximum of a pose error (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PoseErrorSummary {
    pub tip_rms_mm: f64,
    pub tip_max_mm: f64,
    pub tip_max_at_s: f64,
    pub orientation_rms_deg: f64,
    pub orientation_max_deg: f64,
    pub orientation_max_at_s: f64,
    pub samples: u64,
}

/// One joint's error, true minus setpoint (JSON; mm for legs, deg for links).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct JointErrorSummary {
    pub joint: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_deg: Option<f64>,
    pub max_at_s: f64,
}

/// One judged interval (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PhaseSummary {
    pub name: String,
    pub start_s: f64,
    pub end_s: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speed_mm_s: Option<f64>,
    pub tracking: PoseErrorSummary,
    pub target: PoseErrorSummary,
    pub joints: Vec<JointErrorSummary>,
    /// The setpoint's lag behind the master's stream over the phase.
    pub lag: Option<LagSummary>,
    /// Where the master's stream asks more than the robot's tip acceleration limit, and
    /// the target error elsewhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub beyond_limits: Option<BeyondLimits>,
}

/// Where the master's stream itself asks for more than the limits allow (JSON): its
/// acceleration (central differences over ±[`ACCEL_HALF_SPAN_S`]) above the tip
/// acceleration limit. A robot on its limits cannot follow the path there, and at the
/// tip speed limit it cannot make up afterwards for what it lost; the target error is
/// also given without those ticks and the [`CATCH_UP_S`] after each.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BeyondLimits {
    /// The stream's tip acceleration limit, m/s².
    pub tip_accel_limit_m_s2: f64,
    /// The stream's largest acceleration over the phase, m/s².
    pub peak_accel_m_s2: f64,
    /// The intervals where it is above the limit, [start, end] s.
    pub intervals_s: Vec<[f64; 2]>,
    /// The target error (true vs master, tip) RMS over the rest of the phase, mm, and
    /// the share of the phase's ticks that is.
    pub target_rms_elsewhere_mm: f64,
    pub elsewhere_share: f64,
}

/// Half the span of the stream's acceleration differences, s.
pub const ACCEL_HALF_SPAN_S: f64 = 0.005;
/// After the stream was beyond the limits, this long is left to the robot to come back
/// onto the path before the target error counts again, s.
pub const CATCH_UP_S: f64 = 0.2;

/// The accuracy target, judged on the tracking error (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AccuracyVerdict {
    pub judged_on: String,
    pub tip_rms_mm: f64,
    pub tip_max_mm: f64,
    pub limit_tip_rms_mm: f64,
    pub limit_tip_max_mm: f64,
    pub met: bool,
    /// The same passes against the master's targets (includes the rate limiting).
    pub target_tip_rms_mm: f64,
    pub target_tip_max_mm: f64,
}

/// One step response (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StepSummary {
    pub at_s: f64,
    pub step_mm: f64,
    pub step_deg: f64,
    /// 10 % to 90 % of the step (translation, or rotation for a pure rotation), s.
    pub rise_s: Option<f64>,
    /// How far the true pose went past the target along the step, mm (>= 0).
    pub overshoot_mm: f64,
    /// How far the true orientation went past the target about the step's axis, deg.
    pub overshoot_deg: f64,
    /// From the step until the true pose stays within `settle_band_mm` and
    /// `settle_band_deg` of the target (None: not within the hold).
    pub settle_s: Option<f64>,
    pub settle_band_mm: f64,
    pub settle_band_deg: f64,
    /// True pose against the target at the end of the hold.
    pub final_error_mm: f64,
    pub final_error_deg: f64,
}

/// One actuator's effort (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ActuatorSummary {
    pub joint: &'static str,
    pub peak_duty: f64,
    /// Over every plant step.
    pub peak_current_a: f64,
    pub rms_current_a: f64,
    pub nominal_current_a: f64,
    /// Time with |current| above the nominal (continuous) current, s.
    pub over_nominal_s: f64,
    /// Largest |tau| holding the tool: N for legs, N m for links.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_payload_force_n: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_payload_torque_nm: Option<f64>,
}

/// Time per supervisor mode (JSON).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct ModeTimes {
    pub holding_s: f64,
    pub verifying_s: f64,
    pub moving_s: f64,
    pub braking_s: f64,
    pub stopped_s: f64,
}

/// Refused targets by reason (JSON).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Refusals {
    pub total: u32,
    pub stale: u32,
    pub out_of_order: u32,
    pub too_far: u32,
    pub path: u32,
    pub non_finite: u32,
    pub while_stopped: u32,
    /// The first refusal: when and why.
    pub first_at_s: Option<f64>,
    pub first_reason: Option<String>,
}

/// The supervisor's side of the run (JSON).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct SupervisorSummary {
    pub targets_sent: u64,
    pub accepted: u32,
    /// Accepted at once inside a certified region (of `accepted`), and of those led along
    /// the master's stream.
    pub certified: u32,
    pub led: u32,
    pub superseded: u32,
    pub refused: Refusals,
    /// Time with a warn-level guard violated at the setpoint, s.
    pub warn_s: f64,
    /// The same by guard: (guard, s).
    pub warn_by_guard: Vec<(String, f64)>,
    /// The setpoint's lag behind the master's stream over the run.
    pub lag: Option<LagSummary>,
    /// Time stopped (latched), s.
    pub stopped_s: f64,
    pub modes: ModeTimes,
    pub brakes: u32,
    pub stops: u32,
    pub stop_reason: Option<String>,
    /// Forward-kinematics failures of the controller (encoders).
    pub fk_failures: u32,
    pub fk_max_iterations: u32,
}

/// A value per joint: mm for the legs, deg for the links (JSON).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct JointMotion {
    pub l1_mm: f64,
    pub l2_mm: f64,
    pub l3_mm: f64,
    pub theta1_deg: f64,
    pub theta2_deg: f64,
    pub theta3_deg: f64,
}

impl JointMotion {
    /// In joint order.
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.l1_mm,
            self.l2_mm,
            self.l3_mm,
            self.theta1_deg,
            self.theta2_deg,
            self.theta3_deg,
        ]
    }

    fn from_array(a: [f64; 6]) -> Self {
        JointMotion {
            l1_mm: a[0],
            l2_mm: a[1],
            l3_mm: a[2],
            theta1_deg: a[3],
            theta2_deg: a[4],
            theta3_deg: a[5],
        }
    }
}

/// A servo tracking fault and what happened after it (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ServoFaultSummary {
    pub at_s: f64,
    pub kind: String,
    pub joint: Option<&'static str>,
    /// The error that tripped it (a leg's, mm, or a link's, deg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_deg: Option<f64>,
    /// From the first injected plant fault to the trip, s.
    pub after_injection_s: Option<f64>,
    /// Largest motion of each true joint after the trip (includes coasting from the
    /// speed the joint had at the trip).
    pub motion_after_trip: JointMotion,
    /// Largest motion of each true joint from 0.1 s after the trip on: creep.
    pub motion_from_0_1_s_after_trip: JointMotion,
    /// Largest |duty| applied after the trip (0 = outputs off).
    pub max_duty_after_trip: f64,
}

/// A fault injected into the plant (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct InjectedFault {
    pub at_s: f64,
    pub joint: &'static str,
    pub fault: String,
}

/// Faults (JSON).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct FaultSummary {
    pub injected: Vec<InjectedFault>,
    pub servo: Option<ServoFaultSummary>,
    /// Forward-kinematics failures on the true joints (the run keeps the last pose).
    pub true_fk_failures: u64,
}

fn fault_kind(k: FaultKind) -> String {
    format!("{k:?}")
}

/// Online analysis of one step response.
#[derive(Clone, Debug)]
pub struct StepWatch {
    spec: StepSpec,
    dir: nalgebra::Vector3<f64>,
    size: f64,
    axis: nalgebra::Vector3<f64>,
    angle: f64,
    max_progress: f64,
    max_rot_progress: f64,
    t10: Option<f64>,
    t90: Option<f64>,
    last_outside: Option<f64>,
    final_err: (f64, f64),
    dt: f64,
}

impl StepWatch {
    pub fn new(spec: StepSpec, dt: f64) -> Self {
        let d = spec.to.t - spec.from.t;
        let size = d.norm();
        let rv = rotation_vector(&(spec.to.r * spec.from.r.inverse()));
        let angle = rv.norm();
        StepWatch {
            spec,
            dir: if size > 0.0 { d / size } else { d },
            size,
            axis: if angle > 0.0 { rv / angle } else { rv },
            angle,
            max_progress: 0.0,
            max_rot_progress: 0.0,
            t10: None,
            t90: None,
            last_outside: None,
            final_err: (0.0, 0.0),
            dt,
        }
    }

    fn add(&mut self, t: f64, truth: &Pose<f64>) {
        if t < self.spec.at_s || t >= self.spec.until_s {
            return;
        }
        let p = (truth.t - self.spec.from.t).dot(&self.dir);
        let pr = rotation_vector(&(truth.r * self.spec.from.r.inverse())).dot(&self.axis);
        self.max_progress = self.max_progress.max(p);
        self.max_rot_progress = self.max_rot_progress.max(pr);
        let frac = if self.size > 0.0 {
            p / self.size
        } else if self.angle > 0.0 {
            pr / self.angle
        } else {
            1.0
        };
        if self.t10.is_none() && frac >= 0.1 {
            self.t10 = Some(t);
        }
        if self.t90.is_none() && frac >= 0.9 {
            self.t90 = Some(t);
        }
        let err = pose_error(truth, &self.spec.to);
        if err.0 * 1e-3 > self.spec.band_m || err.1.to_radians() > self.spec.band_rad {
            self.last_outside = Some(t);
        }
        self.final_err = err;
    }

    fn summary(&self) -> StepSummary {
        let settled = match self.last_outside {
            None => Some(0.0),
            Some(t) if t + self.dt < self.spec.until_s - self.dt => {
                Some(t + self.dt - self.spec.at_s)
            }
            Some(_) => None,
        };
        StepSummary {
            at_s: self.spec.at_s,
            step_mm: self.size * 1e3,
            step_deg: self.angle.to_degrees(),
            rise_s: match (self.t10, self.t90) {
                (Some(a), Some(b)) => Some(b - a),
                _ => None,
            },
            overshoot_mm: if self.size > 0.0 {
                ((self.max_progress - self.size) * 1e3).max(0.0)
            } else {
                0.0
            },
            overshoot_deg: if self.angle > 0.0 {
                (self.max_rot_progress - self.angle).to_degrees().max(0.0)
            } else {
                0.0
            },
            settle_s: settled,
            settle_band_mm: self.spec.band_m * 1e3,
            settle_band_deg: self.spec.band_rad.to_degrees(),
            final_error_mm: self.final_err.0,
            final_error_deg: self.final_err.1,
        }
    }
}

/// A tripped servo fault: its summary, the true joints at the trip and 0.1 s later.
struct Trip {
    summary: ServoFaultSummary,
    q_trip: [f64; 6],
    q_later: Option<[f64; 6]>,
    /// Largest motion since the trip and since 0.1 s after it (mm, deg).
    motion: [f64; 6],
    creep: [f64; 6],
}

impl Trip {
    /// The servo fault `f` tripped at tick `s`; `first_injection_s` the first injected
    /// fault's time, if any.
    fn new(f: &TrackingFault<f64>, s: &TickSample, first_injection_s: Option<f64>) -> Self {
        let t = s.t_s;
        let joint = f.joint.and_then(|j| JOINT_NAMES.get(j).copied());
        let leg = f.joint.is_some_and(|j| j < 3);
        let error = f.joint.map(|j| to_edge(j, f.error));
        Trip {
            summary: ServoFaultSummary {
                at_s: t,
                kind: fault_kind(f.kind),
                joint,
                error_mm: error.filter(|_| leg),
                error_deg: error.filter(|_| !leg),
                after_injection_s: first_injection_s.map(|i| t - i),
                motion_after_trip: JointMotion::default(),
                motion_from_0_1_s_after_trip: JointMotion::default(),
                max_duty_after_trip: 0.0,
            },
            q_trip: s.true_q,
            q_later: None,
            motion: [0.0; 6],
            creep: [0.0; 6],
        }
    }

    /// A tick after the trip: how far the joints moved since it and since 0.1 s after it,
    /// and the largest duty.
    fn follow(&mut self, s: &TickSample) {
        let t = s.t_s;
        let sum = &mut self.summary;
        if self.q_later.is_none() && t >= sum.at_s + 0.1 - 1e-9 {
            self.q_later = Some(s.true_q);
        }
        for j in 0..6 {
            let d = to_edge(j, (s.true_q[j] - self.q_trip[j]).abs());
            self.motion[j] = self.motion[j].max(d);
            if let Some(q) = self.q_later {
                let d = to_edge(j, (s.true_q[j] - q[j]).abs());
                self.creep[j] = self.creep[j].max(d);
            }
            sum.max_duty_after_trip = sum.max_duty_after_trip.max(s.duty[j].abs());
        }
        sum.motion_after_trip = JointMotion::from_array(self.motion);
        sum.motion_from_0_1_s_after_trip = JointMotion::from_array(self.creep);
    }
}

/// Everything accumulated over a run.
pub struct Metrics {
    dt: f64,
    pub all: Window,
    phases: Vec<(Phase, Window)>,
    steps: Vec<StepWatch>,
    peak_duty: [f64; 6],
    peak_current: [f64; 6],
    current_sq: [f64; 6],
    over_nominal_ticks: [u64; 6],
    nominal: [f64; 6],
    peak_tau: [f64; 6],
    ticks: u64,
    warn_ticks: u64,
    modes: [u64; 5],
    trip: Option<Trip>,
    first_injection_s: Option<f64>,
    pub injected: Vec<InjectedFault>,
    pub first_refusal: Option<(f64, String)>,
    pub targets_sent: u64,
    /// Per tick: time, the master's own position and the setpoint's (for the lag).
    lag_series: Vec<(f64, [f64; 3], [f64; 3])>,
    /// Per tick: the target error at the tip (true vs master), mm.
    target_tip_mm: Vec<f64>,
    /// The robot's tip acceleration limit, m/s² (for [`BeyondLimits`]; infinite: none).
    tip_accel_limit: f64,
    /// Ticks with the warning flag, by the guard that raised it.
    warn_by_guard: std::collections::BTreeMap<&'static str, u64>,
}

/// The setpoint's lag behind the master's stream (JSON): the best-fitting delay
/// ([`trajectory::best_fitting_delay`], searched from -50 to 200 ms by 0.1 ms: a led
/// setpoint can run ahead).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct LagSummary {
    /// The best-fitting delay, ms (negative: the setpoint runs ahead of the stream).
    pub delay_ms: f64,
    /// RMS distance of the setpoint from the delayed stream, mm.
    pub rms_at_delay_mm: f64,
    /// RMS distance of the setpoint from the stream at no delay, mm.
    pub rms_at_zero_mm: f64,
}

/// The lag over the samples of `series` within [from, to] s.
fn lag_over(series: &[(f64, [f64; 3], [f64; 3])], from: f64, to: f64) -> Option<LagSummary> {
    let part: Vec<_> = series
        .iter()
        .filter(|(t, _, _)| *t >= from && *t <= to)
        .collect();
    let t: Vec<f64> = part.iter().map(|x| x.0).collect();
    let stream: Vec<[f64; 3]> = part.iter().map(|x| x.1).collect();
    let follower: Vec<[f64; 3]> = part.iter().map(|x| x.2).collect();
    trajectory::best_fitting_delay(&t, &stream, &follower, -0.05, 0.2, 1e-4).map(|l| LagSummary {
        delay_ms: l.delay_s * 1e3,
        rms_at_delay_mm: l.rms_m * 1e3,
        rms_at_zero_mm: l.rms_at_zero_m * 1e3,
    })
}

/// The errors of one tick (for the trace).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickErrors {
    pub tracking: (f64, f64),
    pub target: (f64, f64),
    /// True minus setpoint, mm or deg.
    pub joints: [f64; 6],
}

impl Metrics {
    pub fn new(dt: f64, phases: &[Phase], steps: &[StepSpec], nominal_current: [f64; 6]) -> Self {
        Metrics {
            dt,
            all: Window::default(),
            phases: phases
                .iter()
                .map(|p| (p.clone(), Window::default()))
                .collect(),
            steps: steps.iter().map(|s| StepWatch::new(*s, dt)).collect(),
            peak_duty: [0.0; 6],
            peak_current: [0.0; 6],
            current_sq: [0.0; 6],
            over_nominal_ticks: [0; 6],
            nominal: nominal_current,
            peak_tau: [0.0; 6],
            ticks: 0,
            warn_ticks: 0,
            modes: [0; 5],
            trip: None,
            first_injection_s: None,
            injected: Vec::new(),
            first_refusal: None,
            targets_sent: 0,
            lag_series: Vec::new(),
            target_tip_mm: Vec::new(),
            tip_accel_limit: f64::INFINITY,
            warn_by_guard: Default::default(),
        }
    }

    /// The setpoint's lag behind the stream over the whole run.
    pub fn lag(&self) -> Option<LagSummary> {
        lag_over(&self.lag_series, f64::NEG_INFINITY, f64::INFINITY)
    }

    /// Seconds with the warning flag raised, by guard (the guard's edge name).
    pub fn warn_by_guard(&self) -> Vec<(String, f64)> {
        self.warn_by_guard
            .iter()
            .map(|(g, n)| (g.to_string(), *n as f64 * self.dt))
            .collect()
    }

    pub fn injected(&mut self, at_s: f64, joint: usize, fault: String) {
        self.first_injection_s.get_or_insert(at_s);
        self.injected.push(InjectedFault {
            at_s,
            joint: JOINT_NAMES.get(joint).copied().unwrap_or("?"),
            fault,
        });
    }

    /// Adds one tick; `target` is the master's own pose at the tick (`Stream::master_pose`:
    /// not the last target received, which left the master a latency earlier).
    pub fn add(&mut self, s: &TickSample, target: &Pose<f64>) -> TickErrors {
        let sp = &s.setpoint;
        let tracking = pose_error(&s.true_pose, &sp.pose);
        let target_err = pose_error(&s.true_pose, target);
        let mut joints = [0.0; 6];
        for (j, e) in joints.iter_mut().enumerate() {
            let mut d = s.true_q[j] - sp.q[j];
            if j >= 3 {
                d = kinematics_core::scalar::wrap_angle(d);
            }
            *e = d;
        }
        self.add_errors(s, tracking, target_err, &joints);
        self.add_actuators(s);
        self.add_supervisor(s, target, target_err);
        match (&mut self.trip, s.report.servo.fault) {
            (None, Some(f)) => self.trip = Some(Trip::new(&f, s, self.first_injection_s)),
            (Some(trip), _) => trip.follow(s),
            _ => {}
        }
        TickErrors {
            tracking,
            target: target_err,
            joints: std::array::from_fn(|j| to_edge(j, joints[j])),
        }
    }

    /// The tick's pose and joint errors, into the whole run's window and its phase's; the
    /// true pose into the step responses.
    fn add_errors(
        &mut self,
        s: &TickSample,
        tracking: (f64, f64),
        target_err: (f64, f64),
        joints: &[f64; 6],
    ) {
        let t = s.t_s;
        let mut w = Window::default();
        w.tracking.add(tracking, t);
        w.target.add(target_err, t);
        for (st, e) in w.joints.iter_mut().zip(joints) {
            st.add(*e, t);
        }
        self.all.merge(&w);
        for (p, pw) in self.phases.iter_mut() {
            if t >= p.start_s && t <= p.end_s {
                pw.merge(&w);
            }
        }
        for st in self.steps.iter_mut() {
            st.add(t, &s.true_pose);
        }
    }

    /// The actuators' peaks: duty, current (and ticks above nominal), effort.
    fn add_actuators(&mut self, s: &TickSample) {
        for j in 0..6 {
            self.peak_duty[j] = self.peak_duty[j].max(s.duty[j].abs());
            self.peak_current[j] = self.peak_current[j].max(s.peak_current_a[j]);
            self.current_sq[j] += s.current_a[j] * s.current_a[j];
            if s.peak_current_a[j] > self.nominal[j] {
                self.over_nominal_ticks[j] += 1;
            }
            self.peak_tau[j] = self.peak_tau[j].max(s.tau[j].abs());
        }
    }

    /// The supervisor's tick: its warning (by guard), its mode, its setpoint against the
    /// master's `target` for the lag.
    fn add_supervisor(&mut self, s: &TickSample, target: &Pose<f64>, target_err: (f64, f64)) {
        let sp = &s.setpoint;
        self.ticks += 1;
        if sp.warning {
            self.warn_ticks += 1;
            let name = sp.warn_guard.map_or("?", |g| g.name());
            *self.warn_by_guard.entry(name).or_insert(0) += 1;
        }
        let xyz = |p: &Pose<f64>| [p.t.x, p.t.y, p.t.z];
        self.lag_series.push((s.t_s, xyz(target), xyz(&sp.pose)));
        self.target_tip_mm.push(target_err.0);
        let m = match sp.mode {
            Mode::Holding => 0,
            Mode::Verifying => 1,
            Mode::Moving => 2,
            Mode::Braking => 3,
            Mode::Stopped => 4,
        };
        self.modes[m] += 1;
    }

    /// Joint errors over the whole run.
    pub fn all_joint_summaries(&self) -> Vec<JointErrorSummary> {
        self.all.joint_summaries()
    }

    /// The robot's tip acceleration limit, m/s², against which the stream is judged.
    pub fn set_tip_accel_limit(&mut self, limit_m_s2: f64) {
        self.tip_accel_limit = limit_m_s2;
    }

    /// Where the stream is beyond the tip acceleration limit within [from, to] s
    /// ([`BeyondLimits`]); None with no limit set or no samples.
    fn beyond_limits(&self, from: f64, to: f64) -> Option<BeyondLimits> {
        let limit = self.tip_accel_limit;
        if !limit.is_finite() || self.lag_series.len() < 3 {
            return None;
        }
        let k = ((ACCEL_HALF_SPAN_S / self.dt).round() as usize).max(1);
        let s = &self.lag_series;
        let (mut peak, mut intervals) = (0.0f64, Vec::<[f64; 2]>::new());
        for i in k..s.len().saturating_sub(k) {
            let t = s[i].0;
            if t < from || t > to {
                continue;
            }
            let h = s[i + k].0 - t;
            let a: f64 = (0..3)
                .map(|c| ((s[i + k].1[c] - 2.0 * s[i].1[c] + s[i - k].1[c]) / (h * h)).powi(2))
                .sum::<f64>()
                .sqrt();
            peak = peak.max(a);
            if a > limit {
                match intervals.last_mut() {
                    Some(last) if t - last[1] <= 1.5 * self.dt => last[1] = t,
                    _ => intervals.push([t, t]),
                }
            }
        }
        let (mut sum, mut n, mut total) = (0.0, 0usize, 0usize);
        for (x, e) in s.iter().zip(&self.target_tip_mm) {
            let t = x.0;
            if t < from || t > to {
                continue;
            }
            total += 1;
            if intervals
                .iter()
                .any(|[a, b]| t >= *a && t <= b + CATCH_UP_S)
            {
                continue;
            }
            sum += e * e;
            n += 1;
        }
        (total > 0).then(|| BeyondLimits {
            tip_accel_limit_m_s2: limit,
            peak_accel_m_s2: peak,
            intervals_s: intervals,
            target_rms_elsewhere_mm: if n > 0 { (sum / n as f64).sqrt() } else { 0.0 },
            elsewhere_share: n as f64 / total as f64,
        })
    }

    /// The judged windows.
    pub fn phase_summaries(&self) -> Vec<PhaseSummary> {
        self.phases
            .iter()
            .map(|(p, w)| PhaseSummary {
                name: p.name.clone(),
                start_s: p.start_s,
                end_s: p.end_s,
                speed_mm_s: p.speed_mm_s,
                tracking: w.tracking.summary(),
                target: w.target.summary(),
                lag: lag_over(&self.lag_series, p.start_s, p.end_s),
                beyond_limits: self.beyond_limits(p.start_s, p.end_s),
                joints: w.joint_summaries(),
            })
            .collect()
    }

    /// The accuracy target over the phases at `speed` (None when there is none).
    pub fn accuracy(&self, speed: f64, rms: f64, max: f64) -> Option<AccuracyVerdict> {
        let mut w = Window::default();
        let mut names = Vec::new();
        for (p, pw) in &self.phases {
            if p.speed_mm_s.is_some_and(|v| (v - speed).abs() < 1e-9) {
                w.merge(pw);
                names.push(p.name.clone());
            }
        }
        if names.is_empty() {
            return None;
        }
        let tip = &w.tracking.tip;
        Some(AccuracyVerdict {
            judged_on: format!("tracking error over: {}", names.join("; ")),
            tip_rms_mm: tip.rms(),
            tip_max_mm: tip.max,
            limit_tip_rms_mm: rms,
            limit_tip_max_mm: max,
            met: tip.rms() <= rms && tip.max <= max,
            target_tip_rms_mm: w.target.tip.rms(),
            target_tip_max_mm: w.target.tip.max,
        })
    }

    pub fn step_summaries(&self) -> Vec<StepSummary> {
        self.steps.iter().map(StepWatch::summary).collect()
    }

    /// `tau_of_payload`: whether the tool was attached at any time.
    pub fn actuators(&self, payload: bool) -> Vec<ActuatorSummary> {
        (0..6)
            .map(|j| ActuatorSummary {
                joint: JOINT_NAMES[j],
                peak_duty: self.peak_duty[j],
                peak_current_a: self.peak_current[j],
                rms_current_a: if self.ticks > 0 {
                    (self.current_sq[j] / self.ticks as f64).sqrt()
                } else {
                    0.0
                },
                nominal_current_a: self.nominal[j],
                over_nominal_s: self.over_nominal_ticks[j] as f64 * self.dt,
                peak_payload_force_n: (payload && j < 3).then_some(self.peak_tau[j]),
                peak_payload_torque_nm: (payload && j >= 3).then_some(self.peak_tau[j]),
            })
            .collect()
    }

    pub fn warn_s(&self) -> f64 {
        self.warn_ticks as f64 * self.dt
    }

    pub fn modes(&self) -> ModeTimes {
        let s = |i: usize| self.modes[i] as f64 * self.dt;
        ModeTimes {
            holding_s: s(0),
            verifying_s: s(1),
            moving_s: s(2),
            braking_s: s(3),
            stopped_s: s(4),
        }
    }

    pub fn servo_fault(&self) -> Option<ServoFaultSummary> {
        self.trip.as_ref().map(|t| t.summary.clone())
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A stream at 25 mm/s along a straight line, then around a circle of R = 2 mm (0.3125
    /// m/s² across it, above a 0.25 m/s² limit) for 50 ms, then straight again: the
    /// interval found is the circle's (within the differences' half span), its peak the
    /// circle's acceleration, and the target error elsewhere leaves out the circle and the
    /// catch-up after it.
    #[test]
    fn the_stream_beyond_the_acceleration_limit_is_found() {
        let (u, r, dt) = (0.025, 0.002, 1e-3);
        let mut m = Metrics::new(dt, &[], &[], [1.0; 6]);
        m.set_tip_accel_limit(0.25);
        let w = u / r;
        let (t_in, t_out) = (0.5, 0.55);
        let mut p = [0.0f64, 0.0, 0.16];
        let mut heading = 0.0f64;
        for k in 0..1000 {
            let t = k as f64 * dt;
            if (t_in..t_out).contains(&t) {
                heading += w * dt;
            }
            p[0] += u * dt * heading.cos();
            p[1] += u * dt * heading.sin();
            m.lag_series.push((t, p, p));
            // A target error of 1 mm on the circle and the catch-up, 0.01 mm elsewhere.
            let near = t >= t_in - 0.01 && t <= t_out + CATCH_UP_S + 0.01;
            m.target_tip_mm.push(if near { 1.0 } else { 0.01 });
        }
        let b = m.beyond_limits(0.0, 1.0).unwrap();
        assert_eq!(b.intervals_s.len(), 1, "{b:?}");
        let [a, z] = b.intervals_s[0];
        assert!(
            (a - t_in).abs() <= 0.006 && (z - t_out).abs() <= 0.006,
            "{b:?}"
        );
        assert!(
            (b.peak_accel_m_s2 - u * u / r).abs() < 0.01 * u * u / r,
            "{b:?}"
        );
        // Elsewhere: 0.01 mm, but for the 10 ms either side the interval's ends may miss.
        assert!(b.target_rms_elsewhere_mm < 0.2, "{b:?}");
        assert!(b.elsewhere_share > 0.7 && b.elsewhere_share < 0.8, "{b:?}");
        // Without a limit: nothing judged.
        let mut m2 = Metrics::new(dt, &[], &[], [1.0; 6]);
        m2.lag_series = m.lag_series.clone();
        m2.target_tip_mm = m.target_tip_mm.clone();
        assert!(m2.beyond_limits(0.0, 1.0).is_none());
    }
}
