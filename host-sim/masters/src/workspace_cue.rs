//! The workspace-edge cue for the surgeon's display: from the board's nearest guard
//! margin (a number in [0, 1], 0 at the stop level of the nearest guard, 1 far from every
//! guard) to a level — none, approaching, at edge — with hysteresis so that the cue does
//! not flicker when the margin hovers at a threshold.
//!
//! A level is entered when the margin falls below its `enter` threshold and left only
//! when the margin rises above its `leave` threshold (`leave > enter`). Defaults:
//! approaching below 0.25, cleared above 0.30; at edge below 0.05, cleared above 0.08.

use thiserror::Error;

/// The cue level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CueLevel {
    /// Far from every guard.
    None,
    /// Nearing a guard.
    Approaching,
    /// At (or within a hair of) a stop level.
    AtEdge,
}

impl CueLevel {
    /// A stable name for recordings and displays.
    pub fn as_str(self) -> &'static str {
        match self {
            CueLevel::None => "none",
            CueLevel::Approaching => "approaching",
            CueLevel::AtEdge => "at_edge",
        }
    }
}

/// Thresholds of one level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hysteresis {
    /// Entered when the margin falls below this.
    pub enter: f64,
    /// Left when the margin rises above this.
    pub leave: f64,
}

/// The cue's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeCueConfig {
    /// Approaching.
    pub approaching: Hysteresis,
    /// At edge.
    pub at_edge: Hysteresis,
}

impl Default for EdgeCueConfig {
    fn default() -> Self {
        EdgeCueConfig {
            approaching: Hysteresis {
                enter: 0.25,
                leave: 0.30,
            },
            at_edge: Hysteresis {
                enter: 0.05,
                leave: 0.08,
            },
        }
    }
}

/// A cue setting or margin that is not usable.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum EdgeCueError {
    /// Thresholds out of order: need 0 ≤ edge.enter < edge.leave ≤ approaching.enter <
    /// approaching.leave ≤ 1.
    #[error("edge cue thresholds out of order: at edge {edge_enter}/{edge_leave}, approaching {approach_enter}/{approach_leave} (need 0 <= edge enter < edge leave <= approaching enter < approaching leave <= 1)")]
    Thresholds {
        /// At-edge enter.
        edge_enter: f64,
        /// At-edge leave.
        edge_leave: f64,
        /// Approaching enter.
        approach_enter: f64,
        /// Approaching leave.
        approach_leave: f64,
    },
    /// A margin outside [0, 1] or not finite.
    #[error("guard margin {0} is not in [0, 1]")]
    Margin(f64),
}

/// The cue with its memory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeCue {
    config: EdgeCueConfig,
    level: CueLevel,
}

impl EdgeCue {
    /// Checks the thresholds; starts at [`CueLevel::None`].
    pub fn new(config: EdgeCueConfig) -> Result<Self, EdgeCueError> {
        let (e, a) = (config.at_edge, config.approaching);
        let ordered = 0.0 <= e.enter
            && e.enter < e.leave
            && e.leave <= a.enter
            && a.enter < a.leave
            && a.leave <= 1.0;
        if !ordered {
            return Err(EdgeCueError::Thresholds {
                edge_enter: e.enter,
                edge_leave: e.leave,
                approach_enter: a.enter,
                approach_leave: a.leave,
            });
        }
        Ok(EdgeCue {
            config,
            level: CueLevel::None,
        })
    }

    /// The current level.
    pub fn level(&self) -> CueLevel {
        self.level
    }

    /// Updates with a new margin; the new level.
    pub fn update(&mut self, margin: f64) -> Result<CueLevel, EdgeCueError> {
        if !(0.0..=1.0).contains(&margin) {
            return Err(EdgeCueError::Margin(margin));
        }
        let (e, a) = (self.config.at_edge, self.config.approaching);
        self.level = if margin < e.enter {
            CueLevel::AtEdge
        } else if margin < a.enter {
            // Between the thresholds: at edge stays until its leave threshold.
            if self.level == CueLevel::AtEdge && margin <= e.leave {
                CueLevel::AtEdge
            } else {
                CueLevel::Approaching
            }
        } else if self.level != CueLevel::None && margin <= a.leave {
            CueLevel::Approaching
        } else {
            CueLevel::None
        };
        Ok(self.level)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// Down through the thresholds and back up: each level is entered below its enter
    /// threshold and left only above its leave threshold.
    #[test]
    fn hysteresis_both_ways() {
        let mut c = EdgeCue::new(EdgeCueConfig::default()).unwrap();
        let down: Vec<CueLevel> = [0.5, 0.27, 0.24, 0.06, 0.04, 0.07, 0.09, 0.26, 0.29, 0.31]
            .iter()
            .map(|m| c.update(*m).unwrap())
            .collect();
        use CueLevel::*;
        assert_eq!(
            down,
            [
                None,
                None,
                Approaching,
                Approaching,
                AtEdge,
                AtEdge,
                Approaching,
                Approaching,
                Approaching,
                None
            ]
        );
        assert!(c.update(1.5).is_err());
        assert!(c.update(f64::NAN).is_err());
    }
}
