//! A scripted operator: a position master that plays a list of timed waypoints, for tests
//! and demonstrations without a device.
//!
//! The pose moves linearly (position) and along the shortest arc (orientation) from one
//! waypoint to the next in the time between them, and rests at the last one; the buttons
//! are those of the last waypoint reached. Times are relative to the first poll.

use crate::device::{DeviceError, Master, MasterInput, MasterKind, MasterSample, OperatorButtons};
use crate::pose::CartesianPose;
use thiserror::Error;

/// One point of the script.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    /// When the master is at `pose`, s after the first poll.
    pub at_s: f64,
    /// The master's pose (its own frame).
    pub pose: CartesianPose,
    /// The buttons from `at_s` on.
    pub buttons: OperatorButtons,
}

/// A script that cannot be played.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ScriptError {
    /// No waypoint.
    #[error("script: no waypoints")]
    Empty,
    /// Times not increasing or not finite, or a pose not finite.
    #[error("script: waypoint {index} at {at_s} s is not finite or not after the one before")]
    BadWaypoint {
        /// Its index.
        index: usize,
        /// Its time.
        at_s: f64,
    },
}

/// The scripted master.
#[derive(Clone, Debug)]
pub struct ScriptedMaster {
    name: String,
    waypoints: Vec<Waypoint>,
    start_s: Option<f64>,
}

impl ScriptedMaster {
    /// Checks the script (times finite and strictly increasing, poses finite).
    pub fn new(name: impl Into<String>, waypoints: Vec<Waypoint>) -> Result<Self, ScriptError> {
        if waypoints.is_empty() {
            return Err(ScriptError::Empty);
        }
        let mut previous = f64::NEG_INFINITY;
        for (index, w) in waypoints.iter().enumerate() {
            if !(w.at_s.is_finite() && w.at_s > previous && w.pose.is_finite()) {
                return Err(ScriptError::BadWaypoint {
                    index,
                    at_s: w.at_s,
                });
            }
            previous = w.at_s;
        }
        Ok(ScriptedMaster {
            name: name.into(),
            waypoints,
            start_s: None,
        })
    }

    /// The script's length, s (the last waypoint's time).
    pub fn duration_s(&self) -> f64 {
        self.waypoints.last().map_or(0.0, |w| w.at_s)
    }

    /// Time since the first poll, s (0 before it).
    pub fn elapsed_s(&self, now_s: f64) -> f64 {
        self.start_s.map_or(0.0, |s| now_s - s)
    }

    /// The pose and buttons at `t` s into the script.
    pub fn at(&self, t: f64) -> (CartesianPose, OperatorButtons) {
        let i = self.waypoints.partition_point(|w| w.at_s <= t);
        match (
            i.checked_sub(1).and_then(|k| self.waypoints.get(k)),
            self.waypoints.get(i),
        ) {
            (Some(a), Some(b)) => {
                let s = (t - a.at_s) / (b.at_s - a.at_s);
                let pose = CartesianPose {
                    position_m: a.pose.position_m + (b.pose.position_m - a.pose.position_m) * s,
                    orientation: a.pose.orientation.slerp(&b.pose.orientation, s),
                };
                (pose, a.buttons)
            }
            (Some(a), None) => (a.pose, a.buttons),
            (None, Some(b)) => (b.pose, b.buttons),
            (None, None) => (CartesianPose::identity(), OperatorButtons::default()),
        }
    }
}

impl Master for ScriptedMaster {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> MasterKind {
        MasterKind::Position
    }

    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError> {
        let start = *self.start_s.get_or_insert(now_s);
        let (pose, buttons) = self.at(now_s - start);
        Ok(Some(MasterSample {
            t_s: now_s,
            input: MasterInput::Pose(pose),
            buttons,
            device_time_us: None,
            deflection: None,
        }))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use nalgebra::Vector3;

    fn at(x_mm: f64) -> CartesianPose {
        CartesianPose {
            position_m: Vector3::new(x_mm * 1e-3, 0.0, 0.0),
            ..CartesianPose::identity()
        }
    }

    /// Halfway between two waypoints the pose is halfway; the buttons change at the
    /// waypoint; after the last the master rests.
    #[test]
    fn interpolates_and_rests() {
        let on = OperatorButtons {
            clutch: false,
            operator_present: true,
        };
        let clutched = OperatorButtons {
            clutch: true,
            operator_present: true,
        };
        let s = ScriptedMaster::new(
            "script",
            vec![
                Waypoint {
                    at_s: 0.0,
                    pose: at(0.0),
                    buttons: on,
                },
                Waypoint {
                    at_s: 1.0,
                    pose: at(10.0),
                    buttons: clutched,
                },
                Waypoint {
                    at_s: 2.0,
                    pose: at(10.0),
                    buttons: on,
                },
            ],
        )
        .unwrap();
        let (p, b) = s.at(0.5);
        assert!((p.position_m.x - 0.005).abs() < 1e-15);
        assert_eq!(b, on);
        assert_eq!(s.at(1.5).1, clutched);
        assert_eq!(s.at(5.0).0, at(10.0));
        assert!(ScriptedMaster::new("x", vec![]).is_err());
        let twice = Waypoint {
            at_s: 1.0,
            pose: at(0.0),
            buttons: on,
        };
        assert!(ScriptedMaster::new("x", vec![twice, twice]).is_err());
    }
}
