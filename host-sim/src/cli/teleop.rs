//! `host-sim teleop` on the command line: the flags of the host master (the `teleop`
//! crate), with the laparoscope path and the master's limits of the simulation's default
//! settings.

use crate::error::CliError;
use clap::Args;
use robot_config::output;
use simulation::config::SimConfig;
use std::path::PathBuf;
use teleop::{ClockChoice, PathChoice, Settings, TeleopScenario};

/// `host-sim teleop` options: a scripted path (`--scenario`, `--path`), or a hand
/// controller (`--device`).
#[derive(Debug, Args)]
pub struct TeleopArgs {
    /// The board: a Unix socket (QEMU `-serial unix:PATH,server=on,wait=off`) or a serial
    /// device (/dev/ttyUSB0, a pty).
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// What to run.
    #[arg(long, value_enum, default_value = "path")]
    pub scenario: TeleopScenario,
    /// The path to stream.
    #[arg(long, value_enum, default_value = "laparoscope")]
    pub path: PathChoice,
    /// The master's clock.
    #[arg(long, value_enum, default_value = "board")]
    pub clock: ClockChoice,
    /// Target stream rate, Hz.
    #[arg(long, default_value_t = 100.0)]
    pub stream_rate_hz: f64,
    /// Serial devices: the baud rate (set with stty).
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// How long to wait for the socket or device and for the board's HelloReply, s.
    #[arg(long, default_value_t = 15.0)]
    pub connect_timeout_s: f64,
    /// Longest homing, s.
    #[arg(long, default_value_t = 60.0)]
    pub home_timeout_s: f64,
    /// Tracking limit: the largest distance of the measured tip position from the
    /// streamed path, mm (default: the legs' following-error window of the servo, 1 mm).
    #[arg(long, default_value_t = 1.0)]
    pub max_deviation_mm: f64,
    /// Output directory [default: target/teleop/<scenario>/ under the current directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub hand: super::operator::HandControllerArgs,
    #[command(flatten)]
    pub key: super::KeyArgs,
    #[command(flatten)]
    pub start: super::operator::StartArgs,
}

/// Runs the master.
pub fn run(
    args: &TeleopArgs,
    selected: &robot_config::selection::SelectedRobot,
    limits: &kinematics_core::guards::Limits<f64>,
) -> Result<(), CliError> {
    if let Some(device) = &args.hand.device {
        return super::operator::hand_controller(
            super::operator::BoardLink {
                connect: &args.connect,
                baud: args.baud,
                key: args.key.key()?,
            },
            args.connect_timeout_s,
            args.home_timeout_s,
            args.stream_rate_hz,
            &args.hand,
            device,
            args.start.options(),
            (selected, limits),
        );
    }
    let cfg = SimConfig::builtin()?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| output::default_dir(&["teleop", teleop::scenario_name(args.scenario)]));
    let settings = Settings {
        connect: args.connect.clone(),
        scenario: args.scenario,
        path: args.path,
        clock: args.clock,
        stream_rate_hz: args.stream_rate_hz,
        baud: args.baud,
        connect_timeout_s: args.connect_timeout_s,
        home_timeout_s: args.home_timeout_s,
        max_deviation_mm: args.max_deviation_mm,
        out,
        laparoscope: cfg.scenario.laparoscope.clone(),
        master: cfg.master.limits(),
        key: args.key.key()?,
        start: args.start.options(),
    };
    // SIGINT and SIGTERM end the run through its way out: the robot disabled.
    let shutdown = super::board_session::shutdown_on_signals()?;
    Ok(teleop::run(&settings, shutdown.flag())?)
}
