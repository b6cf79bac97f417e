//! `host-sim`: the command line of the RSPR/USR host tools. This library is the binary's
//! code and nothing else (its only public items are [`Cli`], [`run`] and [`CliError`]);
//! the work is done by the library crates it drives.
//!
//! The core (`kinematics-core`) is SI; the edge in millimetres and degrees
//! (the repository's `CONVENTIONS.md`) is `robot-config`'s. Modules:
//! - `cli`: the clap command line, the robot and limits selection, and the commands that
//!   drive the libraries (`design`, `simulation`, `teleop`);
//! - `commands`: the row-wise commands `ik`, `fk`, `jacobian`, `forces`, `singularity`,
//!   `check` (whose `--task-box` form sweeps the task);
//! - `batch`: the one CSV loop (and single-pose form) all row-wise commands share;
//! - `columns`: CSV column names, a row's fields found by name, and the readers of
//!   poses, joints, wrenches, branches;
//! - `flags`: the values of the flags (number lists, grids, scan ranges, the task box);
//! - `error`: what a failed command reports.

mod batch;
mod cli;
mod columns;
mod commands;
mod error;
mod flags;

pub use cli::Cli;
pub use error::CliError;

/// Runs a parsed command line.
pub fn run(cli: &Cli) -> Result<(), CliError> {
    let selected = cli.robot.select()?;
    let limits = cli.limits.select()?;
    cli.command.run(&selected, &limits)
}
