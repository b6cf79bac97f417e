//! The scenarios: what the master sends and when, which faults are injected, which time
//! intervals the report judges. Built from the configuration, or by hand (tests).
//!
//! A master streams timestamped target poses, each a small increment along a path
//! ([`Stream::Path`]), or sends single targets at given instants ([`Stream::Jumps`]: the
//! step responses and refused targets); the paths themselves are the `trajectory` crate's.

use crate::config::SimConfig;
use kinematics_core::Pose;
use nalgebra::{Rotation3, Vector3};
use plant::Fault;
use thiserror::Error;
use trajectory::{laparoscope, line, offset_pose, pose_mm_deg, Jump, Piece, Stream, Trajectory};

pub use trajectory::Phase;

/// The names `--scenario` accepts, the default first.
pub const NAMES: [&str; 5] = [
    "laparoscope",
    "step",
    "box-sweep",
    "payload",
    "backlash-off",
];

/// A step whose response the report measures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepSpec {
    pub at_s: f64,
    pub until_s: f64,
    pub from: Pose<f64>,
    pub to: Pose<f64>,
    /// Settled = within this distance of `to`, m ...
    pub band_m: f64,
    /// ... and this angle, rad.
    pub band_rad: f64,
}

/// A fault injected into the plant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultEvent {
    pub at_s: f64,
    pub joint: usize,
    pub fault: Fault,
}

/// A complete scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    pub name: String,
    pub description: String,
    /// Where the robot starts (homed, at rest).
    pub start: Pose<f64>,
    pub stream: Stream,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Backlash compensation: `None` = `control.backlash_compensation`.
    pub compensation: Option<bool>,
    /// When the tool is attached (`None` = never).
    pub payload_attach_s: Option<f64>,
    pub faults: Vec<FaultEvent>,
    pub phases: Vec<Phase>,
    pub steps: Vec<StepSpec>,
}

/// A scenario name that `--scenario` does not know.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("unknown scenario `{name}` (known: {}, all)", NAMES.join(", "))]
pub struct UnknownScenario {
    pub name: String,
}

fn payload_from_start(cfg: &SimConfig) -> Option<f64> {
    cfg.payload.enabled.then_some(0.0)
}

/// The box sweep's tour of the eight corners (signs of the half-extents along x, y, z). It
/// ends at the low corner [+x, +y, -z], the one the tilted platform cannot reach: its
/// refused targets end the tour.
const CORNER_TOUR: [[f64; 3]; 8] = [
    [-1.0, 1.0, -1.0],
    [-1.0, 1.0, 1.0],
    [1.0, 1.0, 1.0],
    [1.0, -1.0, 1.0],
    [-1.0, -1.0, 1.0],
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
];

impl Scenario {
    /// The named scenario with the settings of `cfg`; `hc` is the robot's central height, m.
    pub fn from_config(name: &str, cfg: &SimConfig, hc: f64) -> Result<Self, UnknownScenario> {
        let centre = Pose::central(hc);
        match name {
            "laparoscope" => Ok(Self::laparoscope(cfg, &centre, "laparoscope", None)),
            "backlash-off" => Ok(Self::laparoscope(cfg, &centre, "backlash-off", Some(false))),
            "step" => Ok(Self::step(cfg, &centre)),
            "box-sweep" => Ok(Self::box_sweep(cfg, &centre)),
            "payload" => Ok(Self::payload(cfg, &centre)),
            other => Err(UnknownScenario { name: other.into() }),
        }
    }

    fn laparoscope(
        cfg: &SimConfig,
        centre: &Pose<f64>,
        name: &str,
        compensation: Option<bool>,
    ) -> Self {
        let l = &cfg.scenario.laparoscope;
        let (traj, phases) = laparoscope(l, cfg.master.accel_mm_s2, centre);
        let duration_s = traj.end_s() + 0.1;
        let compensated = compensation.unwrap_or(cfg.control.backlash_compensation);
        Scenario {
            name: name.into(),
            description: format!(
                "laparoscope path: figure-eight loops through the task box from the central \
                 pose at {} mm/s, tilting up to {} deg; backlash compensation {}",
                l.pass_speeds_mm_s
                    .iter()
                    .map(|v| v.to_string())
                    .collect::<Vec<_>>()
                    .join(" and "),
                l.tilt_deg,
                if compensated { "on" } else { "off" }
            ),
            start: *centre,
            stream: Stream::Path(traj),
            duration_s,
            compensation,
            payload_attach_s: payload_from_start(cfg),
            faults: Vec::new(),
            phases,
            steps: Vec::new(),
        }
    }

    fn step(cfg: &SimConfig, centre: &Pose<f64>) -> Self {
        let s = &cfg.scenario.step;
        let t0 = 0.3;
        let mut jumps = Vec::new();
        let mut steps = Vec::new();
        let mut from = *centre;
        for (i, d) in s.steps_mm_deg.iter().enumerate() {
            let at_s = t0 + i as f64 * s.hold_s;
            let to = offset_pose(centre, d);
            jumps.push(Jump { at_s, pose: to });
            steps.push(StepSpec {
                at_s,
                until_s: at_s + s.hold_s,
                from,
                to,
                band_m: s.settle_band_mm * 1e-3,
                band_rad: s.settle_band_deg.to_radians(),
            });
            from = to;
        }
        let duration_s = t0 + s.steps_mm_deg.len() as f64 * s.hold_s;
        Scenario {
            name: "step".into(),
            description: format!(
                "step responses: {} single targets relative to the central pose, each held \
                 {} s (the supervisor ramps them at its speed/acceleration limits)",
                s.steps_mm_deg.len(),
                s.hold_s
            ),
            start: *centre,
            stream: Stream::Jumps(jumps),
            duration_s,
            compensation: None,
            payload_attach_s: payload_from_start(cfg),
            faults: Vec::new(),
            phases: vec![Phase {
                name: "steps".into(),
                start_s: t0,
                end_s: duration_s,
                speed_mm_s: None,
            }],
            steps,
        }
    }

    fn box_sweep(cfg: &SimConfig, centre: &Pose<f64>) -> Self {
        let b = &cfg.scenario.box_sweep;
        let limits = cfg.master.limits();
        let h = Vector3::new(20.0, 20.0, 10.0) * (1e-3 * b.reach);
        let axis = Vector3::new(1.0, 1.0, 0.0).normalize();
        let tilted = Rotation3::from_scaled_axis(axis * b.tilt_deg.to_radians());
        let mut traj = Trajectory::default();
        let mut phases = Vec::new();
        let mut at = *centre;
        traj.push(Piece::Hold {
            pose: at,
            duration_s: 0.3,
        });
        for (label, r) in [("parallel", Rotation3::identity()), ("tilted", tilted)] {
            let oriented = Pose { t: centre.t, r };
            let start = traj.push(line(&limits, &at, &oriented, b.speed_mm_s));
            at = oriented;
            for s in &CORNER_TOUR {
                let corner = Pose {
                    t: centre.t + Vector3::new(s[0] * h.x, s[1] * h.y, s[2] * h.z),
                    r,
                };
                traj.push(line(&limits, &at, &corner, b.speed_mm_s));
                traj.push(Piece::Hold {
                    pose: corner,
                    duration_s: b.hold_s,
                });
                at = corner;
            }
            traj.push(line(&limits, &at, &oriented, b.speed_mm_s));
            at = oriented;
            phases.push(Phase {
                name: format!(
                    "{label}: the 8 corners at {} mm/s{}",
                    b.speed_mm_s,
                    if label == "tilted" {
                        format!(", rotated {} deg about [1,1,0]", b.tilt_deg)
                    } else {
                        String::new()
                    }
                ),
                start_s: start,
                end_s: traj.end_s(),
                speed_mm_s: Some(b.speed_mm_s),
            });
        }
        traj.push(line(&limits, &at, centre, b.speed_mm_s));
        traj.push(Piece::Hold {
            pose: *centre,
            duration_s: 0.3,
        });
        // The master then falls silent: a supervisor left behind by refused targets
        // verifies the last one and returns.
        let duration_s = traj.end_s() + b.tail_s;
        Scenario {
            name: "box-sweep".into(),
            description: format!(
                "task-box sweep: the 8 corners of the 40 x 40 x 20 mm box (x{}) at {} mm/s, \
                 platform parallel, then rotated {} deg about [1,1,0] (the unreachable low \
                 corner last); targets the supervisor refuses are counted",
                b.reach, b.speed_mm_s, b.tilt_deg
            ),
            start: *centre,
            stream: Stream::Path(traj),
            duration_s,
            compensation: None,
            payload_attach_s: payload_from_start(cfg),
            faults: Vec::new(),
            phases,
            steps: Vec::new(),
        }
    }

    fn payload(cfg: &SimConfig, centre: &Pose<f64>) -> Self {
        let p = &cfg.scenario.payload;
        let limits = cfg.master.limits();
        let target = pose_mm_deg(&p.move_to_mm_deg);
        let mut traj = Trajectory::default();
        traj.push(Piece::Hold {
            pose: *centre,
            duration_s: p.attach_s + p.hold_s,
        });
        let out = traj.push(line(&limits, centre, &target, p.speed_mm_s));
        traj.push(Piece::Hold {
            pose: target,
            duration_s: p.hold_s,
        });
        traj.push(line(&limits, &target, centre, p.speed_mm_s));
        traj.push(Piece::Hold {
            pose: *centre,
            duration_s: p.hold_s,
        });
        let duration_s = traj.end_s();
        let phases = vec![
            Phase {
                name: "tool attached, holding".into(),
                start_s: p.attach_s,
                end_s: out,
                speed_mm_s: None,
            },
            Phase {
                name: format!("carrying the tool at {} mm/s", p.speed_mm_s),
                start_s: out,
                end_s: duration_s,
                speed_mm_s: None,
            },
        ];
        Scenario {
            name: "payload".into(),
            description: format!(
                "payload: the {} kg tool on its {:?} mm lever attached at {} s while holding \
                 the central pose, then carried at {} mm/s to {:?} (mm, deg) and back",
                cfg.payload.mass_kg,
                cfg.payload.lever_mm,
                p.attach_s,
                p.speed_mm_s,
                p.move_to_mm_deg
            ),
            start: *centre,
            stream: Stream::Path(traj),
            duration_s,
            compensation: None,
            payload_attach_s: Some(p.attach_s),
            faults: Vec::new(),
            phases,
            steps: Vec::new(),
        }
    }

    /// A scenario that holds `start` and sends single `jumps` (for tests and one-off runs),
    /// with the tool as `cfg` says.
    pub fn jumps(
        cfg: &SimConfig,
        name: &str,
        start: &Pose<f64>,
        jumps: Vec<Jump>,
        duration_s: f64,
    ) -> Self {
        Scenario {
            name: name.into(),
            description: format!("{} single targets from a hold", jumps.len()),
            start: *start,
            stream: Stream::Jumps(jumps),
            duration_s,
            compensation: None,
            payload_attach_s: payload_from_start(cfg),
            faults: Vec::new(),
            phases: Vec::new(),
            steps: Vec::new(),
        }
    }
}
