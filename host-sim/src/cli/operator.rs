//! The operator's front ends on the command line (the `operator` crate): `teleop --device`
//! (a hand controller), `replay`, `console` and `igtl`.

use crate::error::CliError;
use clap::Args;
use masters::{MotionScale, TeleopConfig, TeleopState};
use operator::board::{Board, BringUpTimeouts};
use operator::devices::{self, DeviceSpec};
use operator::navigation::{self, BoardRobot};
use operator::teleoperation::{self, TeleoperationSettings, TickView};
use simulation::config::default_target_dir;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The hand-controller options of `host-sim teleop` (with `--device`).
#[derive(Debug, Args)]
pub struct HandControllerArgs {
    /// Teleoperate with a hand controller instead of streaming a path: spacemouse
    /// (spacenavd if its socket exists, else evdev), spacenavd[:SOCKET], evdev[:PATH],
    /// udp:PORT (a position master, datagram format in host-sim/masters/README.md) or
    /// keyboard (d/a w/s r/f: x y z; i/k l/j u/o: rotations; c clutch; Space operator
    /// present; Esc stop; q quit).
    #[arg(long, value_name = "DEVICE")]
    pub device: Option<String>,
    /// Motion scaling of translation: robot motion per master motion (1:5 is 0.2).
    #[arg(long, default_value_t = 1.0)]
    pub scale_translation: f64,
    /// Motion scaling of rotation.
    #[arg(long, default_value_t = 1.0)]
    pub scale_rotation: f64,
    /// No tremor filter (5 Hz low-pass + 10 Hz notch, 60 ms of delay).
    #[arg(long)]
    pub no_tremor_filter: bool,
    /// The session recording (MCAP) [default: target/teleop/sessions/session-<unix time>.mcap].
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Stop after this many seconds [default: until Ctrl-C, or q on the keyboard].
    #[arg(long)]
    pub duration_s: Option<f64>,
}

/// Installs the Ctrl-C handler that sets `stop`.
fn stop_on_ctrl_c() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    // Without a handler (installed twice, or no signals) Ctrl-C ends the process as usual.
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    stop
}

/// Where the board is: its socket or serial device, the baud rate, the link key.
pub struct BoardLink<'a> {
    /// A Unix socket or a serial device.
    pub connect: &'a Path,
    /// Serial devices: the baud rate.
    pub baud: u32,
    /// The link's pre-shared key, if any.
    pub key: Option<master_link::LinkKey>,
}

/// `host-sim teleop --device ...`: bring the board up, teleoperate, disable, summarise.
pub fn hand_controller(
    board: BoardLink<'_>,
    connect_timeout_s: f64,
    home_timeout_s: f64,
    stream_rate_hz: f64,
    args: &HandControllerArgs,
    device: &str,
) -> Result<(), CliError> {
    let BoardLink { connect, baud, key } = board;
    let spec: DeviceSpec = device.parse()?;
    let stop = stop_on_ctrl_c();
    let mut master = devices::open(&spec, &stop)?;
    let keyboard = spec == DeviceSpec::Keyboard;
    let eol = if keyboard { "\r\n" } else { "\n" };
    let mut board = Board::open_with_key(
        connect,
        baud,
        Duration::from_secs_f64(connect_timeout_s.max(0.0)),
        key,
    )?;
    let timeouts = BringUpTimeouts {
        hello_s: connect_timeout_s,
        home_s: home_timeout_s,
        ..BringUpTimeouts::default()
    };
    board.bring_up(&timeouts, &mut |m| print!("board: {m}{eol}"))?;
    let settings = teleoperation_settings(args, device, stream_rate_hz)?;
    print!(
        "teleoperating with {} at {stream_rate_hz} Hz, scale {} / {}; {}{eol}",
        master.name(),
        args.scale_translation,
        args.scale_rotation,
        if keyboard {
            "keys: d/a w/s r/f move, i/k l/j u/o turn, +/- speed, c clutch, Space operator present, Esc stop, q quit"
        } else {
            "Ctrl-C to stop"
        }
    );
    let mut last_print = f64::NEG_INFINITY;
    let report = teleoperation::run(&mut board, master.as_mut(), &settings, &stop, &mut |v| {
        if v.t_s - last_print < 0.2 {
            return;
        }
        last_print = v.t_s;
        eprint!("\r{}", live_line(v));
        let _ = std::io::stderr().flush();
    });
    eprint!("{eol}");
    drop(master);
    let report = report?;
    // Leave the robot disabled (holding brakes on): nobody streams to it any more.
    let _ = board.request(master_link::MasterToBoard::Disable);
    // The summary's final state is the one the board reports after the Disable.
    let after = board
        .wait_status(1.0, |s| s.state != master_link::RobotState::Enabled)
        .ok()
        .flatten();
    print!("{}", report.summary_after(after.as_ref()));
    Ok(())
}

/// The run's settings from the options: the mapping at `stream_rate_hz` with the scales
/// and the tremor filter, the recording (by default under
/// `target/teleop/sessions/`, named by the time), the device named in the recording.
fn teleoperation_settings(
    args: &HandControllerArgs,
    device: &str,
    stream_rate_hz: f64,
) -> Result<TeleoperationSettings, CliError> {
    let record = args.record.clone().unwrap_or_else(|| {
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        default_target_dir()
            .join("teleop")
            .join("sessions")
            .join(format!("session-{unix}.mcap"))
    });
    let mut teleop = TeleopConfig {
        stream_rate_hz,
        scale: MotionScale::new(args.scale_translation, args.scale_rotation)
            .map_err(operator::OperatorError::from)?,
        ..TeleopConfig::default()
    };
    if args.no_tremor_filter {
        teleop.tremor = None;
    }
    Ok(TeleoperationSettings {
        teleop,
        duration_s: args.duration_s,
        record: Some(record),
        settings_text: [("device".to_string(), device.to_string())].into(),
        ..TeleoperationSettings::default()
    })
}

/// The line shown in place while teleoperating: the board's state, the mapping's, the
/// workspace-edge cue, the nearest margin and the measured position.
fn live_line(v: &TickView) -> String {
    let state = match v.state {
        TeleopState::Following => "following".to_string(),
        TeleopState::Holding(r) => format!("holding: {}", r.as_str()),
    };
    let (pose, margin, board_state) = match v.status {
        Some(s) => {
            let p = operator::conversions::measured_cp(s)
                .map(|p| p.to_mm_deg())
                .unwrap_or([f64::NAN; 6]);
            (p, s.margins.nearest, format!("{:?}", s.state))
        }
        None => ([f64::NAN; 6], f32::NAN, "?".into()),
    };
    format!(
        "{board_state:<8} {state:<24} edge {:<10} margin {margin:5.2}  x {:7.2} y {:7.2} z {:7.2} mm   ",
        v.cue.as_str(),
        pose[0],
        pose[1],
        pose[2]
    )
}

/// `host-sim replay` options.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The session recording (MCAP) of `host-sim teleop --device`.
    pub file: PathBuf,
    /// Where the plots go [default: target/replay/<file stem>/].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Prints a recording's summary and writes its plots.
pub fn replay(args: &ReplayArgs) -> Result<(), CliError> {
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .file
            .file_stem()
            .map_or("session".into(), |s| s.to_string_lossy().into_owned());
        default_target_dir().join("replay").join(stem)
    });
    let r = operator::replay::replay(&args.file, &out)?;
    println!("{}", args.file.display());
    print!("{}", r.summary);
    for p in &r.plots {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// `host-sim console` options.
#[derive(Debug, Args)]
pub struct ConsoleArgs {
    /// The board: a Unix socket (`host-sim board`, the emulator) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    #[command(flatten)]
    pub key: super::KeyArgs,
}

/// Runs the console.
pub fn console(args: &ConsoleArgs) -> Result<(), CliError> {
    let board = Board::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(10),
        args.key.key()?,
    )?;
    operator::console::run(board)?;
    Ok(())
}

/// `host-sim igtl` options.
#[derive(Debug, Args)]
pub struct IgtlArgs {
    /// The board: a Unix socket (`host-sim board`, the emulator) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// Where OpenIGTLink clients connect: a port (on all interfaces) or ADDR:PORT.
    /// 18944 is 3D Slicer's default.
    #[arg(long, default_value = "18944")]
    pub listen: String,
    /// Rate of the measured pose streamed as TRANSFORM (device `Robot`), Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// Bring the board up first: hello, homing when not homed, enable (otherwise only
    /// hello: enable it from the console).
    #[arg(long)]
    pub enable: bool,
    /// Registration client frame -> robot base {0}: a TOML file with image_to_base_mm
    /// (row-major 4x4, translation in mm) [default: the client frame is {0}].
    #[arg(long, conflicts_with = "registration_matrix")]
    pub registration: Option<PathBuf>,
    /// The registration as 16 numbers, row-major, translation in mm.
    #[arg(long, allow_hyphen_values = true)]
    pub registration_matrix: Option<String>,
    /// Stop after this many seconds [default: until Ctrl-C].
    #[arg(long)]
    pub duration_s: Option<f64>,
    #[command(flatten)]
    pub key: super::KeyArgs,
}

/// Serves OpenIGTLink for the board until Ctrl-C (or the duration).
pub fn igtl(args: &IgtlArgs) -> Result<(), CliError> {
    let registration = match (&args.registration, &args.registration_matrix) {
        (Some(f), _) => igtl::Registration::load(f).map_err(operator::OperatorError::from)?,
        (None, Some(m)) => {
            igtl::Registration::parse_numbers_mm(m).map_err(operator::OperatorError::from)?
        }
        (None, None) => igtl::Registration::identity(),
    };
    if !(args.rate_hz.is_finite() && args.rate_hz > 0.0) {
        return Err(CliError::UnknownName {
            what: "pose rate (Hz, positive)",
            name: args.rate_hz.to_string(),
        });
    }
    let addr = match args.listen.parse::<u16>() {
        Ok(port) => format!("0.0.0.0:{port}"),
        Err(_) => args.listen.clone(),
    };
    let stop = stop_on_ctrl_c();
    let mut board = Board::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(10),
        args.key.key()?,
    )?;
    if args.enable {
        board.bring_up(&BringUpTimeouts::default(), &mut |m| println!("board: {m}"))?;
    } else {
        board.hello(10.0).map_err(CliError::from)?;
    }
    let mut server = igtl::Server::bind_with(
        addr.as_str(),
        navigation::server_config(args.rate_hz, registration),
    )
    .map_err(operator::OperatorError::from)?;
    println!(
        "OpenIGTLink on {} for the board {}: targets TRANSFORM/POSITION to device Target, pose TRANSFORM from device Robot at {} Hz, state STATUS RobotStatus / STRING RobotState",
        server.local_addr(),
        args.connect.display(),
        args.rate_hz
    );
    let _ = std::io::stdout().flush();
    if let Some(d) = args.duration_s {
        let flag = Arc::clone(&stop);
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_secs_f64(d.max(0.0)));
            flag.store(true, Ordering::Relaxed);
        });
    }
    let mut robot = BoardRobot::new(board);
    navigation::serve(
        &mut server,
        &mut robot,
        &stop,
        Duration::from_millis(1),
        &mut |m| {
            eprintln!("igtl: {m}");
        },
    )?;
    let c = server.counters();
    println!(
        "igtl: targets accepted {}, refused {}; counters {c:?}",
        robot.accepted, robot.refused
    );
    if args.enable {
        let _ = robot.board().request(master_link::MasterToBoard::Disable);
    }
    Ok(())
}
