//! `simulation`: the closed-loop simulation behind `host-sim sim`, the project's main job.
//!
//! The board's control application (`firmware/control`: encoders -> FK -> supervisor ->
//! IK -> PID -> PWM, in f64) runs against the plant model of the six actuated joints
//! (`sim/plant`) through the hardware traits of `firmware/servo`. The controller
//! ticks at `control.rate_hz` (1 kHz default, up to 10 kHz); the plant is integrated
//! `control.plant_steps_per_tick` (>= 10) times per tick. A master streams timestamped
//! target poses (or single targets); the tool's weight (1.2 kg on a 0.1 m lever) is mapped
//! to joint loads through tau = J^-T s_e at the true pose. Each run writes a JSON summary,
//! a CSV trace and PNG plots.
//!
//! Modules: [`config`] (the TOML settings, `default.toml`), [`scenario`] (what the master
//! sends, faults; the paths are the `trajectory` crate's), [`engine`] (the loop),
//! [`metrics`] (errors, efforts, faults), [`run`] (one scenario), [`output`] (files),
//! [`report`] (the summary `host-sim sim` prints, [`report_text`]).
//!
//! [`board`] runs the whole board application (the tick service: state machine, stops,
//! brakes, monitors, fault log, deadline policy, the link) on the plant with the board
//! around it (drivers, brakes, e-stop chain, switches and stops, the tool, a wall), in
//! virtual time; [`bench`] is a master in the same process that drives it over the wire
//! protocol. The fault campaigns and the served simulated board use them.

pub mod bench;
pub mod board;
pub mod config;
pub mod engine;
pub mod metrics;
pub mod output;
pub mod report;
pub mod run;
pub mod scenario;
pub mod serve;

pub use config::{ConfigError, SimConfig};
pub use engine::EngineError;
pub use output::OutputError;
pub use report::report_text;
pub use run::RunError;
pub use scenario::UnknownScenario;

use kinematics_core::{Robot, RsprGeometry};
use thiserror::Error;

/// Why `host-sim sim` stopped.
#[derive(Debug, Error)]
pub enum SimError {
    /// The plant models the RSPR prototype only.
    #[error("sim: the plant models the RSPR prototype's joints; choose an RSPR robot")]
    NotRspr,
    /// The controller of the simulation runs the symmetric RSPR model only.
    #[error(
        "sim: the simulated controller runs the symmetric RSPR model (e, rb, rp, hc); \
         a per-chain (calibrated) geometry is not simulated yet"
    )]
    PerChainGeometry,
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scenario(#[from] UnknownScenario),
    #[error(transparent)]
    Run(#[from] RunError),
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// The threads a run uses by default: 2 when the machine has at least 2 cores.
pub fn default_threads() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(2)
}

/// The RSPR geometry of a robot (the plant models the RSPR prototype only).
pub fn rspr(robot: &Robot<f64>) -> Result<RsprGeometry<f64>, SimError> {
    match robot {
        Robot::Rspr(g) => Ok(*g),
        Robot::Usr(_) => Err(SimError::NotRspr),
        Robot::RsprPerChain(_) => Err(SimError::PerChainGeometry),
    }
}
