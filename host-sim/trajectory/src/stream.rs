//! What the master sends and when each target reaches the robot: a path sampled at the
//! stream rate, or single targets at given instants, each handed over once its stamp plus
//! the link's latency has passed.

use crate::path::Trajectory;
use kinematics_core::Pose;

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
    /// The path's pose every stream period from t = 0 to its end.
    Path(Trajectory),
    /// Single targets.
    Jumps(Vec<Jump>),
}

impl Stream {
    /// The master's own pose at `t` (s): the path's (held at its end), or the last single
    /// target sent by then; None before the first. What the robot is compared with: a
    /// target reaches it a latency after its stamp, the master is already elsewhere.
    pub fn master_pose(&self, t: f64) -> Option<Pose<f64>> {
        match self {
            Stream::Path(traj) => traj.pose(t.min(traj.end_s())),
            Stream::Jumps(jumps) => jumps.iter().rev().find(|j| j.at_s <= t).map(|j| j.pose),
        }
    }
}

/// The master's sampling of a [`Stream`]: sample k of a path is the pose at its stamp
/// k * period (up to the path's end); a target reaches the robot once its stamp plus the
/// latency has passed (within 1 ns).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampler {
    period_s: f64,
    latency_s: f64,
    next_sample: u64,
    next_jump: usize,
}

impl Sampler {
    /// A sampler at the start of a stream: a sample every `period_s` (s), received
    /// `latency_s` (s) after its stamp.
    pub fn new(period_s: f64, latency_s: f64) -> Self {
        Sampler {
            period_s,
            latency_s,
            next_sample: 0,
            next_jump: 0,
        }
    }

    /// The index of the next path sample (the number sent so far).
    pub fn next_sample(&self) -> u64 {
        self.next_sample
    }

    /// Hands every target of `stream` that has reached the robot by time `t` (s) and was
    /// not handed over before to `send(stamp_s, pose)`, in order.
    pub fn due(&mut self, stream: &Stream, t: f64, mut send: impl FnMut(f64, Pose<f64>)) {
        let eps = 1e-9;
        match stream {
            Stream::Path(traj) => loop {
                let ts = self.next_sample as f64 * self.period_s;
                if ts > traj.end_s() + eps || ts + self.latency_s > t + eps {
                    break;
                }
                if let Some(pose) = traj.pose(ts) {
                    send(ts, pose);
                }
                self.next_sample += 1;
            },
            Stream::Jumps(jumps) => {
                while let Some(j) = jumps.get(self.next_jump) {
                    if j.at_s + self.latency_s > t + eps {
                        break;
                    }
                    send(j.at_s, j.pose);
                    self.next_jump += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::path::Piece;

    /// Two single targets, at 0.5 s (z 0.16 m) and 0.7 s (z 0.17 m).
    fn two_jumps() -> Stream {
        Stream::Jumps(vec![
            Jump {
                at_s: 0.5,
                pose: Pose::central(0.16),
            },
            Jump {
                at_s: 0.7,
                pose: Pose::central(0.17),
            },
        ])
    }

    /// A 1-s hold sampled every 0.1 s with 0.05 s latency: by t the robot has every sample
    /// stamped at or before t - latency, each once, and nothing after the path's end.
    #[test]
    fn samples_arrive_once_after_their_latency() {
        let mut traj = Trajectory::default();
        traj.push(Piece::Hold {
            pose: Pose::central(0.16),
            duration_s: 1.0,
        });
        let stream = Stream::Path(traj);
        let mut s = Sampler::new(0.1, 0.05);
        let mut stamps = Vec::new();
        s.due(&stream, 0.04, |ts, _| stamps.push(ts));
        assert!(stamps.is_empty());
        s.due(&stream, 0.25, |ts, _| stamps.push(ts));
        assert_eq!(stamps.len(), 3);
        s.due(&stream, 0.25, |ts, _| stamps.push(ts));
        assert_eq!(stamps.len(), 3);
        s.due(&stream, 10.0, |ts, _| stamps.push(ts));
        assert_eq!(stamps.len(), 11);
        assert_eq!(s.next_sample(), 11);
        let jumps = two_jumps();
        let mut s = Sampler::new(0.1, 0.05);
        let mut got = Vec::new();
        s.due(&jumps, 0.6, |ts, p| got.push((ts, p.t.z)));
        assert_eq!(got, vec![(0.5, 0.16)]);
        s.due(&jumps, 0.75, |ts, p| got.push((ts, p.t.z)));
        assert_eq!(got, vec![(0.5, 0.16), (0.7, 0.17)]);
    }

    /// The master's own pose at t: the path's at t (held at its end), whatever the
    /// latency; a single target from its stamp on, nothing before the first.
    #[test]
    fn the_masters_pose_is_the_streams_at_the_instant() {
        let mut traj = Trajectory::default();
        traj.push(Piece::Line {
            from: Pose::central(0.16),
            to: Pose::central(0.17),
            profile: crate::profile::Profile::new(0.01, 0.1, 1.0),
        });
        let end = traj.end_s();
        let stream = Stream::Path(traj.clone());
        for t in [0.0, 0.3 * end, 0.9 * end] {
            assert_eq!(stream.master_pose(t), traj.pose(t));
        }
        assert_eq!(stream.master_pose(end + 1.0), traj.pose(end));
        let jumps = two_jumps();
        assert_eq!(jumps.master_pose(0.4), None);
        assert_eq!(jumps.master_pose(0.5).map(|p| p.t.z), Some(0.16));
        assert_eq!(jumps.master_pose(0.69).map(|p| p.t.z), Some(0.16));
        assert_eq!(jumps.master_pose(0.8).map(|p| p.t.z), Some(0.17));
    }
}
