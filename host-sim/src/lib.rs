//! `host-sim`: the host-side command-line tool of the RSPR/USR surgical robots.
//!
//! The core (`kinematics-core`) is SI; this crate is the edge in millimetres and degrees
//! (shared/CONVENTIONS.md). Modules:
//! - [`cli`]: the clap command line and the robot selection;
//! - [`geometry_file`]: TOML geometry files;
//! - [`limits_file`]: TOML limits files for the guards;
//! - [`units`]: mm/deg <-> SI and the output number formats;
//! - [`columns`]: CSV column names and the readers of poses, joints, wrenches, branches;
//! - [`batch`]: the one CSV loop (and single-pose form) all row-wise commands share;
//! - [`commands`]: the row-wise commands `ik`, `fk`, `jacobian`, `forces`, `singularity`,
//!   `check` (whose `--task-box` form sweeps the task);
//! - [`task_box`]: the thesis's task box and its grid;
//! - [`report`]: the text report over the task box;
//! - [`sim`]: the closed-loop simulation (`host-sim sim`);
//! - [`design`]: the design tools `forces --path`, `ranges` and `workspace` (thesis ch. 8).

pub mod batch;
pub mod cli;
pub mod columns;
pub mod commands;
pub mod design;
pub mod geometry_file;
pub mod limits_file;
pub mod report;
pub mod sim;
pub mod task_box;
pub mod teleop;
pub mod units;

/// Runs a parsed command line.
pub fn run(cli: &cli::Cli) -> Result<(), String> {
    let selected = cli.robot.select()?;
    let limits = cli.limits.select()?;
    cli.command.run(&selected, &limits)
}
