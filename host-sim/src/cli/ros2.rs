//! `host-sim ros2`: the ROS 2 interface with CRTK names (the `ros2` crate) in front of a
//! live board, with the front ends' session rules (one owner, the robot disabled on the
//! way out: `operator::shutdown`).

use super::board_session::{shutdown_on_signals, with_board};
use super::operator::StartArgs;
use crate::error::CliError;
use clap::Args;
use kinematics_core::guards::Limits;
use kinematics_core::Branch;
use operator::board::Board;
use robot_config::selection::SelectedRobot;
use robot_description::Description;
use ros2::{Bridge, Network, NodeConfig, RosNode};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// `host-sim ros2` options.
#[derive(Debug, Args)]
pub struct Ros2Args {
    /// The board: a Unix socket (`host-sim board`, the emulator) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// The namespace of the node and its topics (`<namespace>/measured_cp` ...).
    #[arg(long, default_value = "/rspr")]
    pub namespace: String,
    /// The DDS domain [default: $ROS_DOMAIN_ID, else 0].
    #[arg(long)]
    pub domain_id: Option<u16>,
    /// Which interfaces DDS uses: `loopback` (127.0.0.1: this machine only), `all`
    /// (multicast discovery on every interface: the lab's network), or addresses
    /// separated by commas (those interfaces only).
    #[arg(long, default_value = "loopback")]
    pub network: String,
    /// Bring the board up first: hello, homing when not homed, enable (otherwise only
    /// hello: enable it with `state_command`).
    #[arg(long)]
    pub enable: bool,
    /// Stop after this many seconds [default: until Ctrl-C].
    #[arg(long)]
    pub duration_s: Option<f64>,
    #[command(flatten)]
    pub key: super::KeyArgs,
    #[command(flatten)]
    pub start: StartArgs,
}

/// The interfaces of `--network`.
fn network(text: &str) -> Result<Network, CliError> {
    match text {
        "loopback" => Ok(Network::Loopback),
        "all" => Ok(Network::All),
        list => list
            .split(',')
            .map(|a| {
                a.trim().parse().map_err(|_| CliError::UnknownName {
                    what: "--network (loopback, all, or IP addresses separated by commas)",
                    name: a.to_string(),
                })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Network::Only),
    }
}

/// The DDS domain: the flag, else `ROS_DOMAIN_ID`, else 0.
fn domain(flag: Option<u16>) -> Result<u16, CliError> {
    if let Some(d) = flag {
        return Ok(d);
    }
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(v) if !v.trim().is_empty() => v.trim().parse().map_err(|_| CliError::UnknownName {
            what: "ROS_DOMAIN_ID (a number 0..232)",
            name: v,
        }),
        _ => Ok(0),
    }
}

/// Serves the board on ROS 2 until Ctrl-C (or the duration); the robot disabled on the
/// way out. The selected geometry and limits make the robot description of
/// `/joint_states`, `/tf`, `setpoint_js` and `servo_jp` (the prototype's branch, 0).
pub fn run(
    args: &Ros2Args,
    selected: &SelectedRobot,
    limits: &Limits<f64>,
) -> Result<(), CliError> {
    let description = Description::new(&selected.robot, limits, Branch::OUTER)
        .map_err(|e| CliError::Ros2Description(e.to_string()))?;
    let config = NodeConfig {
        domain: domain(args.domain_id)?,
        namespace: args.namespace.clone(),
        network: network(&args.network)?,
        ..NodeConfig::default()
    };
    let node = RosNode::new(&config)?;
    let shutdown = shutdown_on_signals()?;
    super::board_session::stop_after(&shutdown, args.duration_s);
    let mut board = Board::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(10),
        args.key.key()?,
    )?;
    let start = args.start.options();
    with_board(&mut board, &shutdown, |board| {
        super::board_session::bring_up_or_connect(board, args.enable, start)?;
        println!(
            "ROS 2 node {}/{} on domain {} ({}) for the board {}: publishing {} {} {} {} /joint_states /tf (100 Hz), {} {} (10 Hz), {}; subscribing {} {} {}",
            config.namespace.trim_end_matches('/'),
            config.name,
            config.domain,
            match &config.network {
                Network::Loopback => "loopback only".to_string(),
                Network::All => "every interface".to_string(),
                Network::Only(a) => format!("interfaces {a:?}"),
            },
            args.connect.display(),
            node.topic("measured_cp"),
            node.topic("measured_js"),
            node.topic("setpoint_cp"),
            node.topic("setpoint_js"),
            node.topic("operating_state"),
            node.topic("diagnostics"),
            node.topic("refusal"),
            node.topic("servo_cp"),
            node.topic("servo_jp"),
            node.topic("state_command"),
        );
        let _ = std::io::stdout().flush();
        let mut bridge = Bridge::new(board, &node, &description);
        let result = bridge.run(shutdown.flag(), &mut |m| eprintln!("ros2: {m}"));
        let c = bridge.counters();
        println!(
            "ros2: {} statuses published at {:.1} Hz ({} without /joint_states: no forward kinematics); servo_cp accepted {}, refused {}, superseded {}; servo_jp accepted {}, refused {}, superseded {}; state_command done {}, refused {}",
            c.statuses,
            c.rate_hz(),
            c.unposed,
            c.targets_accepted,
            c.targets_refused,
            c.targets_superseded,
            c.joint_targets_accepted,
            c.joint_targets_refused,
            c.joint_targets_superseded,
            c.commands_done,
            c.commands_refused
        );
        result.map_err(CliError::from)
    })
}
