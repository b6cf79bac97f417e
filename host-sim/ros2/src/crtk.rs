//! The CRTK (Collaborative Robotics Toolkit) view of the board: its operating state from a
//! status, and the `state_command` words as the board's requests.
//!
//! CRTK's meta-states are `DISABLED`, `ENABLED`, `PAUSED` and `FAULT`, with `is_homed` and
//! `is_busy` beside them. The board's states map onto them as follows:
//!
//! | board | CRTK state | is_busy |
//! | --- | --- | --- |
//! | `Boot` (starting) | `DISABLED` | yes |
//! | `Disabled` (not homed), `Ready` (homed, drives off) | `DISABLED` | no |
//! | `Homing` (drives on, moving to the switches) | `ENABLED` | yes |
//! | `Enabling` (brake check) | `DISABLED` | yes |
//! | `Commissioning` (a joint's wiring test, open loop) | `ENABLED` | yes |
//! | `Enabled`, following | `ENABLED` | while a stop decelerates |
//! | `Enabled`, holding under SS2 (clutch, `pause`) | `PAUSED` | while it decelerates |
//! | `Fault` | `FAULT` | while its stop decelerates or brakes |
//!
//! `is_homed` is the board's `NOT_HOMED` warning negated.
//!
//! The commands: `enable` sends `Enable` (again while the board answers `Busy` during its
//! brake check), `disable` sends `Disable`, `home` sends `Home` (never a re-home: on a homed
//! robot it is a no-op, as CRTK's `home` is), `pause` engages the clutch (the board holds
//! under SS2 and refuses targets), `resume` releases it. CRTK's `unhome` has no counterpart
//! on the board (homing is lost only with power, or by commissioning) and is refused with
//! that reason.

use master_link::{MasterToBoard, RobotState, StatusReport, StopStatus, Warnings};
use std::fmt;
use std::str::FromStr;
use thiserror::Error;

/// A CRTK meta-state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MetaState {
    Disabled,
    Enabled,
    Paused,
    Fault,
}

impl MetaState {
    /// The word CRTK uses.
    pub fn as_str(self) -> &'static str {
        match self {
            MetaState::Disabled => "DISABLED",
            MetaState::Enabled => "ENABLED",
            MetaState::Paused => "PAUSED",
            MetaState::Fault => "FAULT",
        }
    }
}

/// The CRTK operating state of a board status.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Operating {
    pub state: MetaState,
    pub is_homed: bool,
    pub is_busy: bool,
}

/// Whether a stop is still under way (decelerating or braking), not done.
fn stop_in_progress(stop: StopStatus) -> bool {
    matches!(
        stop,
        StopStatus::SafeStop1Decelerating
            | StopStatus::SafeStop1Braking
            | StopStatus::SafeStop2Decelerating
    )
}

/// The CRTK operating state of `s` (the table of the module documentation).
pub fn operating_state(s: &StatusReport) -> Operating {
    let is_homed = !s.warnings.contains(Warnings::NOT_HOMED);
    let stopping = stop_in_progress(s.stop);
    let (state, is_busy) = match s.state {
        RobotState::Boot | RobotState::Enabling => (MetaState::Disabled, true),
        RobotState::Disabled | RobotState::Ready => (MetaState::Disabled, false),
        RobotState::Homing | RobotState::Commissioning => (MetaState::Enabled, true),
        RobotState::Enabled => {
            let holding = matches!(
                s.stop,
                StopStatus::SafeStop2Decelerating | StopStatus::SafeOperatingStop
            );
            (
                if holding {
                    MetaState::Paused
                } else {
                    MetaState::Enabled
                },
                stopping,
            )
        }
        RobotState::Fault => (MetaState::Fault, stopping),
    };
    Operating {
        state,
        is_homed,
        is_busy,
    }
}

/// A CRTK `state_command`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateCommand {
    Enable,
    Disable,
    Home,
    Unhome,
    Pause,
    Resume,
}

/// The words `state_command` takes, in CRTK's spelling.
pub const COMMAND_WORDS: [&str; 6] = ["enable", "disable", "home", "unhome", "pause", "resume"];

/// A `state_command` that is none of CRTK's words.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("unknown state_command {0:?}: CRTK's are enable, disable, home, unhome, pause, resume")]
pub struct UnknownCommand(pub String);

impl FromStr for StateCommand {
    type Err = UnknownCommand;

    /// CRTK's words, lower case, surrounding white space ignored.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.trim() {
            "enable" => StateCommand::Enable,
            "disable" => StateCommand::Disable,
            "home" => StateCommand::Home,
            "unhome" => StateCommand::Unhome,
            "pause" => StateCommand::Pause,
            "resume" => StateCommand::Resume,
            _ => return Err(UnknownCommand(s.to_string())),
        })
    }
}

impl fmt::Display for StateCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StateCommand::Enable => "enable",
            StateCommand::Disable => "disable",
            StateCommand::Home => "home",
            StateCommand::Unhome => "unhome",
            StateCommand::Pause => "pause",
            StateCommand::Resume => "resume",
        })
    }
}

impl StateCommand {
    /// The board request that carries it out, or why there is none.
    pub fn request(self) -> Result<MasterToBoard, &'static str> {
        Ok(match self {
            StateCommand::Enable => MasterToBoard::Enable,
            StateCommand::Disable => MasterToBoard::Disable,
            StateCommand::Home => MasterToBoard::Home { rehome: false },
            StateCommand::Unhome => {
                return Err(
                    "the board cannot unhome: homing is lost only with power or by commissioning",
                )
            }
            StateCommand::Pause => MasterToBoard::Clutch { engaged: true },
            StateCommand::Resume => MasterToBoard::Clutch { engaged: false },
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::expect_used)]
    use super::*;

    fn status(state: RobotState, stop: StopStatus, homed: bool) -> StatusReport {
        let mut s = StatusReport {
            state,
            stop,
            ..StatusReport::default()
        };
        if !homed {
            s.warnings.insert(Warnings::NOT_HOMED);
        }
        s
    }

    /// Every row of the module's table: the board's state and stop give the CRTK state,
    /// is_busy, and is_homed follows the NOT_HOMED warning.
    #[test]
    fn the_table_of_states() {
        use MetaState::*;
        use StopStatus as S;
        let rows = [
            (RobotState::Boot, S::None, Disabled, true),
            (RobotState::Disabled, S::SafeTorqueOff, Disabled, false),
            (RobotState::Ready, S::SafeStop1Done, Disabled, false),
            (RobotState::Homing, S::None, Enabled, true),
            (RobotState::Enabling, S::None, Disabled, true),
            (RobotState::Commissioning, S::None, Enabled, true),
            (RobotState::Enabled, S::None, Enabled, false),
            (RobotState::Enabled, S::SafeStop2Decelerating, Paused, true),
            (RobotState::Enabled, S::SafeOperatingStop, Paused, false),
            (RobotState::Fault, S::SafeStop1Decelerating, Fault, true),
            (RobotState::Fault, S::SafeStop1Braking, Fault, true),
            (RobotState::Fault, S::SafeTorqueOff, Fault, false),
        ];
        for (board, stop, crtk, busy) in rows {
            for homed in [true, false] {
                let o = operating_state(&status(board, stop, homed));
                assert_eq!(
                    o,
                    Operating {
                        state: crtk,
                        is_homed: homed,
                        is_busy: busy
                    },
                    "{board:?} {stop:?} homed {homed}"
                );
            }
        }
    }

    /// Every CRTK word parses to the command that prints as it, and maps to the board's
    /// request of the module's documentation (unhome to a refusal); anything else is
    /// refused with the word quoted.
    #[test]
    fn commands_round_trip_and_map() {
        for w in COMMAND_WORDS {
            let c: StateCommand = w.parse().expect("a CRTK word");
            assert_eq!(c.to_string(), w);
            assert_eq!(format!(" {w}\n").parse::<StateCommand>(), Ok(c));
        }
        assert_eq!(StateCommand::Enable.request(), Ok(MasterToBoard::Enable));
        assert_eq!(StateCommand::Disable.request(), Ok(MasterToBoard::Disable));
        assert_eq!(
            StateCommand::Home.request(),
            Ok(MasterToBoard::Home { rehome: false })
        );
        assert_eq!(
            StateCommand::Pause.request(),
            Ok(MasterToBoard::Clutch { engaged: true })
        );
        assert_eq!(
            StateCommand::Resume.request(),
            Ok(MasterToBoard::Clutch { engaged: false })
        );
        assert!(StateCommand::Unhome.request().is_err());
        let e = "Enable".parse::<StateCommand>().expect_err("case matters");
        assert!(e.to_string().contains("\"Enable\""), "{e}");
    }
}
