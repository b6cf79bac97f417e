//! The scenarios: what the master sends and when, which faults are injected, which time
//! intervals the report judges. Built from the configuration, or by hand (tests).
//!
//! A master streams timestamped target poses, each a small increment along a path
//! ([`Stream::Path`]), or sends single targets at given instants ([`Stream::Jumps`]: the
//! step responses and refused targets).

use super::config::SimConfig;
use kinematics_core::pose::rotation_angle;
use kinematics_core::Pose;
use nalgebra::{Rotation3, Vector3};
use plant::Fault;
use std::f64::consts::PI;

/// The names `--scenario` accepts, the default first.
pub const NAMES: [&str; 5] = [
    "laparoscope",
    "step",
    "box-sweep",
    "payload",
    "backlash-off",
];

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

/// The laparoscope's closed figure-eight (see `[scenario.laparoscope]` in default.toml).
#[derive(Clone, Debug, PartialEq)]
pub struct Figure8 {
    /// Centre, m.
    pub centre: Vector3<f64>,
    /// Size, m: the amplitudes in x and y, the dip below the centre in z.
    pub size: Vector3<f64>,
    /// Largest tilt, rad.
    pub tilt: f64,
    /// Cumulative length at u = i / (n - 1), m.
    table: Vec<f64>,
}

impl Figure8 {
    const SAMPLES: usize = 4001;

    /// The figure with its arc-length table.
    pub fn new(centre: Vector3<f64>, size: Vector3<f64>, tilt: f64) -> Self {
        let mut f = Figure8 {
            centre,
            size,
            tilt,
            table: Vec::with_capacity(Self::SAMPLES),
        };
        let mut acc = 0.0;
        let mut prev = f.position(0.0);
        f.table.push(0.0);
        for i in 1..Self::SAMPLES {
            let p = f.position(i as f64 / (Self::SAMPLES - 1) as f64);
            acc += (p - prev).norm();
            f.table.push(acc);
            prev = p;
        }
        f
    }

    /// Length of the loop, m.
    pub fn length(&self) -> f64 {
        self.table.last().copied().unwrap_or(0.0)
    }

    fn position(&self, u: f64) -> Vector3<f64> {
        let a = 2.0 * PI * u;
        self.centre
            + Vector3::new(
                self.size.x * a.sin(),
                self.size.y * (2.0 * a).sin(),
                self.size.z * (a.cos() - 1.0),
            )
    }

    /// The pose at parameter `u` in [0, 1].
    pub fn pose_at_u(&self, u: f64) -> Pose<f64> {
        let theta = self.tilt * (PI * u).sin().powi(2);
        let axis = Vector3::new((PI * u).cos(), (PI * u).sin(), 0.0);
        Pose {
            t: self.position(u),
            r: Rotation3::from_scaled_axis(axis * theta),
        }
    }

    /// The pose at arc length `s`, m.
    pub fn pose_at_length(&self, s: f64) -> Pose<f64> {
        let n = self.table.len();
        if n < 2 {
            return self.pose_at_u(0.0);
        }
        let s = s.clamp(0.0, self.length());
        let i = self.table.partition_point(|x| *x < s).clamp(1, n - 1);
        let (s0, s1) = (self.table[i - 1], self.table[i]);
        let f = if s1 > s0 { (s - s0) / (s1 - s0) } else { 0.0 };
        self.pose_at_u(((i - 1) as f64 + f) / (n - 1) as f64)
    }
}

/// One piece of a master path.
#[derive(Clone, Debug, PartialEq)]
pub enum Piece {
    /// Stay at a pose.
    Hold { pose: Pose<f64>, duration_s: f64 },
    /// A straight move (translation linear, rotation about a fixed world axis), the
    /// profile over the fraction 0..1 of the way.
    Line {
        from: Pose<f64>,
        to: Pose<f64>,
        profile: Profile,
    },
    /// One lap of a figure-eight, the profile over its arc length (m).
    Loop { figure: Figure8, profile: Profile },
}

impl Piece {
    /// Duration, s.
    pub fn duration(&self) -> f64 {
        match self {
            Piece::Hold { duration_s, .. } => *duration_s,
            Piece::Line { profile, .. } | Piece::Loop { profile, .. } => profile.duration(),
        }
    }

    /// Pose `t` seconds into the piece.
    pub fn pose(&self, t: f64) -> Pose<f64> {
        match self {
            Piece::Hold { pose, .. } => *pose,
            Piece::Line { from, to, profile } => {
                kinematics_core::supervisor::interpolate(from, to, profile.distance(t))
            }
            Piece::Loop { figure, profile } => figure.pose_at_length(profile.distance(t)),
        }
    }

    /// Pose at the end.
    pub fn end(&self) -> Pose<f64> {
        self.pose(self.duration())
    }
}

/// A master path: pieces one after the other from t = 0.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    pieces: Vec<(f64, Piece)>,
    end_s: f64,
}

impl Trajectory {
    /// Appends a piece; returns its start time, s.
    pub fn push(&mut self, piece: Piece) -> f64 {
        let start = self.end_s;
        self.end_s += piece.duration();
        self.pieces.push((start, piece));
        start
    }

    /// End time, s.
    pub fn end_s(&self) -> f64 {
        self.end_s
    }

    /// Pose at time `t` (the last pose after the end); `None` when empty.
    pub fn pose(&self, t: f64) -> Option<Pose<f64>> {
        let i = self.pieces.partition_point(|(s, _)| *s <= t);
        let (start, piece) = self.pieces.get(i.saturating_sub(1))?;
        Some(piece.pose(t - start))
    }

    /// Pose at the end; `None` when empty.
    pub fn last(&self) -> Option<Pose<f64>> {
        self.pieces.last().map(|(_, p)| p.end())
    }
}

/// A single target sent at an instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jump {
    /// When the master sends it (its stamp), s.
    pub at_s: f64,
    /// The target.
    pub pose: Pose<f64>,
}

/// What the master sends.
#[derive(Clone, Debug, PartialEq)]
pub enum Stream {
    /// The path's pose every 1 / `master.stream_rate_hz` from t = 0 to its end.
    Path(Trajectory),
    /// Single targets.
    Jumps(Vec<Jump>),
}

/// A time interval the report judges separately.
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    pub name: String,
    pub start_s: f64,
    pub end_s: f64,
    /// The tip speed along the path, mm/s, for passes at a constant speed.
    pub speed_mm_s: Option<f64>,
}

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

/// A pose from the edge form x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
pub fn pose_mm_deg(p: &[f64; 6]) -> Pose<f64> {
    Pose {
        t: Vector3::new(p[0], p[1], p[2]) * 1e-3,
        r: Rotation3::from_scaled_axis(Vector3::new(p[3], p[4], p[5]).map(f64::to_radians)),
    }
}

/// A pose displaced from `base` by an edge-form offset (translation added, rotation
/// vector composed in the world frame).
pub fn offset_pose(base: &Pose<f64>, d: &[f64; 6]) -> Pose<f64> {
    let off = pose_mm_deg(d);
    Pose {
        t: base.t + off.t,
        r: off.r * base.r,
    }
}

/// A straight move at `speed_mm_s` (and the master's angular limits for the rotation).
pub fn line(cfg: &SimConfig, from: &Pose<f64>, to: &Pose<f64>, speed_mm_s: f64) -> Piece {
    let m = &cfg.master;
    let dist = (to.t - from.t).norm();
    let angle = rotation_angle(&(to.r * from.r.inverse()));
    let mut rate = f64::INFINITY;
    let mut acc = f64::INFINITY;
    if dist > 0.0 {
        rate = rate.min(speed_mm_s * 1e-3 / dist);
        acc = acc.min(m.accel_mm_s2 * 1e-3 / dist);
    }
    if angle > 0.0 {
        rate = rate.min(m.angular_speed_deg_s.to_radians() / angle);
        acc = acc.min(m.angular_accel_deg_s2.to_radians() / angle);
    }
    let profile = if rate.is_finite() {
        Profile::new(1.0, rate, acc)
    } else {
        Profile::new(0.0, 0.0, 0.0)
    };
    Piece::Line {
        from: *from,
        to: *to,
        profile,
    }
}

fn payload_from_start(cfg: &SimConfig) -> Option<f64> {
    cfg.payload.enabled.then_some(0.0)
}

impl Scenario {
    /// The named scenario with the settings of `cfg`; `hc` is the robot's central height, m.
    pub fn from_config(name: &str, cfg: &SimConfig, hc: f64) -> Result<Self, String> {
        let centre = Pose::central(hc);
        match name {
            "laparoscope" => Ok(Self::laparoscope(cfg, &centre, "laparoscope", None)),
            "backlash-off" => Ok(Self::laparoscope(cfg, &centre, "backlash-off", Some(false))),
            "step" => Ok(Self::step(cfg, &centre)),
            "box-sweep" => Ok(Self::box_sweep(cfg, &centre)),
            "payload" => Ok(Self::payload(cfg, &centre)),
            other => Err(format!(
                "unknown scenario `{other}` (known: {}, all)",
                NAMES.join(", ")
            )),
        }
    }

    fn laparoscope(
        cfg: &SimConfig,
        centre: &Pose<f64>,
        name: &str,
        compensation: Option<bool>,
    ) -> Self {
        let l = &cfg.scenario.laparoscope;
        let size = Vector3::from(l.loop_size_mm) * 1e-3;
        let mut traj = Trajectory::default();
        traj.push(Piece::Hold {
            pose: *centre,
            duration_s: l.hold_s,
        });
        let mut phases = Vec::new();
        for (i, (speed, scale)) in l.pass_speeds_mm_s.iter().zip(&l.pass_scales).enumerate() {
            let figure = Figure8::new(centre.t, size * *scale, l.tilt_deg.to_radians());
            let length = figure.length();
            let profile = Profile::new(length, speed * 1e-3, cfg.master.accel_mm_s2 * 1e-3);
            let start = traj.push(Piece::Loop { figure, profile });
            phases.push(Phase {
                name: format!(
                    "pass {}: {speed} mm/s, figure-eight x{scale} ({:.1} mm, tilt up to {} deg)",
                    i + 1,
                    length * 1e3,
                    l.tilt_deg
                ),
                start_s: start,
                end_s: start + profile.duration() + l.settle_s,
                speed_mm_s: Some(*speed),
            });
            traj.push(Piece::Hold {
                pose: *centre,
                duration_s: l.hold_s.max(l.settle_s),
            });
        }
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
        let h = Vector3::new(20.0, 20.0, 10.0) * (1e-3 * b.reach);
        // A tour of the eight corners that ends at the low corner [+x, +y, -z], the one the
        // tilted platform cannot reach: its refused targets end the tour.
        let signs: [[f64; 3]; 8] = [
            [-1.0, 1.0, -1.0],
            [-1.0, 1.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, -1.0, 1.0],
            [-1.0, -1.0, 1.0],
            [-1.0, -1.0, -1.0],
            [1.0, -1.0, -1.0],
            [1.0, 1.0, -1.0],
        ];
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
            let start = traj.push(line(cfg, &at, &oriented, b.speed_mm_s));
            at = oriented;
            for s in &signs {
                let corner = Pose {
                    t: centre.t + Vector3::new(s[0] * h.x, s[1] * h.y, s[2] * h.z),
                    r,
                };
                traj.push(line(cfg, &at, &corner, b.speed_mm_s));
                traj.push(Piece::Hold {
                    pose: corner,
                    duration_s: b.hold_s,
                });
                at = corner;
            }
            traj.push(line(cfg, &at, &oriented, b.speed_mm_s));
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
        traj.push(line(cfg, &at, centre, b.speed_mm_s));
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
        let target = pose_mm_deg(&p.move_to_mm_deg);
        let mut traj = Trajectory::default();
        traj.push(Piece::Hold {
            pose: *centre,
            duration_s: p.attach_s + p.hold_s,
        });
        let out = traj.push(line(cfg, centre, &target, p.speed_mm_s));
        traj.push(Piece::Hold {
            pose: target,
            duration_s: p.hold_s,
        });
        traj.push(line(cfg, &target, centre, p.speed_mm_s));
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn profile_reaches_the_end_at_its_duration() {
        let p = Profile::new(0.1, 0.025, 0.1);
        assert!((p.distance(p.duration()) - 0.1).abs() < 1e-12);
        assert!((p.duration() - (0.1 / 0.025 + 0.025 / 0.1)).abs() < 1e-12);
        let short = Profile::new(1e-4, 0.025, 0.1);
        assert!((short.distance(short.duration()) - 1e-4).abs() < 1e-15);
    }

    #[test]
    fn figure8_starts_and_ends_at_the_centre() {
        let c = Vector3::new(0.0, 0.0, 0.16);
        let f = Figure8::new(c, Vector3::new(0.015, 0.012, 0.007), 0.3);
        for s in [0.0, f.length()] {
            let p = f.pose_at_length(s);
            assert!((p.t - c).norm() < 1e-9);
            assert!(rotation_angle(&p.r) < 1e-9);
        }
    }
}
