//! The operator's front ends on the command line (the `operator` crate): `teleop --device`
//! (a hand controller), `replay`, `console` and `igtl`.

use super::board_session::{shutdown_on_signals, with_board};
use crate::error::CliError;
use clap::{Args, ValueEnum};
use masters::{MotionScale, TeleopConfig, TeleopState, TremorSuppression};
use operator::board::{Board, BringUpTimeouts};
use operator::devices::{self, DeviceSpec};
use operator::navigation::{self, BoardRobot};
use operator::teleoperation::{self, TeleoperationSettings, TickView};
use robot_config::output;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;
use teleop::start::StartOptions;

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
    /// How the hand's tremor is taken out: canceller (adaptive, estimates the tremor and
    /// subtracts it: no delay of the voluntary motion), classic (5 Hz low-pass + 10 Hz
    /// notch: 60 ms of delay) or off. Their settings and defaults:
    /// host-sim/masters/README.md.
    #[arg(long, value_enum, default_value_t = Tremor::Canceller)]
    pub tremor: Tremor,
    /// The session recording (MCAP) [default: target/teleop/sessions/session-<unix time>.mcap].
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Stop after this many seconds [default: until Ctrl-C, or q on the keyboard].
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Serve the live 3-D view on this WebSocket port (127.0.0.1) or ADDR:PORT: the
    /// channels of `host-sim view`, with the targets this master streams as /servo_cp.
    #[arg(long, value_name = "[ADDR:]PORT", requires = "device")]
    pub view: Option<String>,
}

/// The tremor suppression chosen on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Tremor {
    /// The adaptive canceller with its default settings (`masters::CancellerConfig`).
    Canceller,
    /// The classic low-pass and notch with their default corners
    /// (`masters::TremorFilterConfig`).
    Classic,
    /// None.
    Off,
}

impl Tremor {
    /// The mapping's setting.
    pub fn suppression(self) -> Option<TremorSuppression> {
        match self {
            Tremor::Canceller => Some(TremorSuppression::Canceller(Default::default())),
            Tremor::Classic => Some(TremorSuppression::classic()),
            Tremor::Off => None,
        }
    }
}

/// What the person allows a front end to do at start (`teleop::start`): never done
/// without the flag.
#[derive(Debug, Args, Clone, Copy)]
pub struct StartArgs {
    /// Acknowledge the board's last reset when it is a watchdog or brown-out reset not
    /// acknowledged yet (find out why first: `host-sim faultlog`); without it the tool
    /// refuses to go on and names the cause.
    #[arg(long)]
    pub acknowledge_reset: bool,
    /// Clear a latched fault (shown in words first); without it the tool shows the fault
    /// and refuses to go on.
    #[arg(long)]
    pub clear_fault: bool,
}

impl StartArgs {
    /// The options of `teleop::start`.
    pub fn options(&self) -> StartOptions {
        StartOptions {
            acknowledge_reset: self.acknowledge_reset,
            clear_fault: self.clear_fault,
        }
    }
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

/// `host-sim teleop --device ...`: bring the board up from the state it is in,
/// teleoperate, and, whatever ends it, disable (`operator::shutdown`); summarise. With
/// `--view`, the live 3-D view of the selected robot (`robot`) is served meanwhile.
#[allow(clippy::too_many_arguments)]
pub fn hand_controller(
    board: BoardLink<'_>,
    connect_timeout_s: f64,
    home_timeout_s: f64,
    stream_rate_hz: f64,
    args: &HandControllerArgs,
    device: &str,
    start: StartOptions,
    robot: (
        &robot_config::selection::SelectedRobot,
        &kinematics_core::guards::Limits<f64>,
    ),
) -> Result<(), CliError> {
    let BoardLink { connect, baud, key } = board;
    let mut live = match &args.view {
        Some(listen) => {
            let l = super::view::start_scene(listen, None, robot.0, robot.1)?;
            println!(
                "Foxglove WebSocket on {} (the channels of host-sim view, targets as /servo_cp)",
                l.url
            );
            Some(l)
        }
        None => None,
    };
    let spec: DeviceSpec = device.parse()?;
    let shutdown = shutdown_on_signals()?;
    let mut master = devices::open(&spec, shutdown.flag())?;
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
    let settings = teleoperation_settings(args, device, stream_rate_hz)?;
    let report = with_board(&mut board, &shutdown, |board| {
        board.bring_up(&timeouts, start, &mut |m| print!("board: {m}{eol}"))?;
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
        let _ = std::io::stdout().flush();
        let mut last_print = f64::NEG_INFINITY;
        let (mut last_scene, mut last_description) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        let report = teleoperation::run(
            board,
            master.as_mut(),
            &settings,
            shutdown.flag(),
            &mut |v| {
                if let (Some(l), Some(s)) = (live.as_mut(), v.status) {
                    // The board's status period: every status once, with the last target.
                    if v.t_s - last_scene >= 0.02 {
                        last_scene = v.t_s;
                        let mut snap = operator::view::snapshot(operator::view::now_ns(), s);
                        snap.target = v.target.as_ref().map(operator::view::pose_of);
                        l.scene.log(&snap);
                    }
                    if v.t_s - last_description >= operator::view::DESCRIPTION_PERIOD_S {
                        last_description = v.t_s;
                        l.scene.log_description(operator::view::now_ns());
                    }
                }
                if v.t_s - last_print < 0.2 {
                    return;
                }
                last_print = v.t_s;
                eprint!("\r{}", live_line(v));
                let _ = std::io::stderr().flush();
            },
        );
        eprint!("{eol}");
        Ok(Some(report?))
    });
    drop(master);
    if let Some(l) = live {
        l.close()?;
    }
    if let Some(report) = report? {
        // The summary's final state is the one the board reports after the shutdown
        // path's Disable.
        let after = board
            .wait_status(1.0, |s| s.state != master_link::RobotState::Enabled)
            .ok()
            .flatten();
        print!("{}", report.summary_after(after.as_ref()));
    }
    Ok(())
}

/// The run's settings from the options: the mapping at `stream_rate_hz` with the scales
/// and the tremor suppression, the recording (by default under
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
        output::default_dir(&["teleop", "sessions"]).join(format!("session-{unix}.mcap"))
    });
    let teleop = TeleopConfig {
        stream_rate_hz,
        scale: MotionScale::new(args.scale_translation, args.scale_rotation)
            .map_err(operator::OperatorError::from)?,
        tremor: args.tremor.suppression(),
        ..TeleopConfig::default()
    };
    Ok(TeleoperationSettings {
        teleop,
        duration_s: args.duration_s,
        record: Some(record),
        settings_text: [
            ("device".to_string(), device.to_string()),
            (
                "tremor".to_string(),
                format!("{:?}", args.tremor).to_lowercase(),
            ),
        ]
        .into(),
        ..TeleoperationSettings::default()
    })
}

/// The widest live line, columns: one less than an 80-column terminal, so that the
/// cursor never wraps to a new line.
pub const LIVE_LINE_COLUMNS: usize = 79;

/// How long a refusal stays on the live line after the board's latest one, s.
const REFUSAL_SHOWN_S: f64 = 2.0;

/// The line shown in place while teleoperating, at most [`LIVE_LINE_COLUMNS`] wide, in
/// the order of what matters: the board's state, the measured position, then the latest
/// refusal of a target (its guard, value and limit) for [`REFUSAL_SHOWN_S`] after it,
/// else why the mapping holds, else the workspace-edge cue and the nearest margin. What
/// does not fit is cut, marked `~`.
fn live_line(v: &TickView) -> String {
    let (p, board_state) = match v.status {
        Some(s) => (
            operator::conversions::measured_cp(s)
                .map(|p| p.to_mm_deg())
                .unwrap_or([f64::NAN; 6]),
            board_words::state_label(s.state),
        ),
        None => ([f64::NAN; 6], "?"),
    };
    let detail = match (v.refusal, v.state) {
        (Some((t, words)), _) if v.t_s - t <= REFUSAL_SHOWN_S => format!("refused: {words}"),
        (_, TeleopState::Holding(r)) => format!("holding: {}", r.as_str().replace('_', " ")),
        (_, TeleopState::Following) => {
            let margin = v.status.map_or("--".to_string(), |s| {
                board_words::nearest_margin_short(&s.margins)
            });
            format!("edge {} {margin}", v.cue.as_str().replace('_', " "))
        }
    };
    // Compact: the platform stays within a few tens of mm of the centre, so the position
    // takes at most 25 columns and a refusal (up to 33 characters but the spherical
    // joints' 42) fits whole.
    let line = format!(
        "{board_state} x{:.1} y{:.1} z{:.1} mm  {detail}",
        p[0], p[1], p[2]
    );
    fit(&line, LIVE_LINE_COLUMNS)
}

/// `text` cut to `columns` characters, the last one `~` when cut, else padded with spaces
/// (so that a shorter line overwrites a longer one in place).
fn fit(text: &str, columns: usize) -> String {
    let n = text.chars().count();
    if n > columns {
        text.chars()
            .take(columns.saturating_sub(1))
            .collect::<String>()
            + "~"
    } else {
        format!("{text}{}", " ".repeat(columns - n))
    }
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

/// The magic bytes every MCAP file starts with (MCAP specification, "Magic").
const MCAP_MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Refuses a file that is not MCAP (a CSV trace, a status log) before it is parsed.
fn check_mcap(path: &std::path::Path) -> Result<(), CliError> {
    use std::io::Read as _;
    let mut head = Vec::with_capacity(MCAP_MAGIC.len());
    std::fs::File::open(path)
        .and_then(|f| f.take(MCAP_MAGIC.len() as u64).read_to_end(&mut head))
        .map_err(|e| CliError::Input {
            path: path.to_path_buf(),
            error: e.to_string(),
        })?;
    if head.as_slice() == MCAP_MAGIC {
        return Ok(());
    }
    Err(CliError::NotMcap {
        path: path.to_path_buf(),
        first: String::from_utf8_lossy(&head).into_owned(),
    })
}

/// Prints a recording's summary and writes its plots.
pub fn replay(args: &ReplayArgs) -> Result<(), CliError> {
    check_mcap(&args.file)?;
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .file
            .file_stem()
            .map_or("session".into(), |s| s.to_string_lossy().into_owned());
        output::default_dir(&["replay", &stem])
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

/// Runs the console; whatever ends it (q, SIGINT, SIGTERM, an error), the robot is
/// disabled on the way out.
pub fn console(args: &ConsoleArgs) -> Result<(), CliError> {
    let shutdown = shutdown_on_signals()?;
    let mut board = Board::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(10),
        args.key.key()?,
    )?;
    with_board(&mut board, &shutdown, |board| {
        Ok(operator::console::run(board, shutdown.flag())?)
    })
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
    /// Where OpenIGTLink clients connect: a port (on 127.0.0.1, this machine only) or
    /// ADDR:PORT (e.g. 0.0.0.0:18944 for every interface: then use --allow and
    /// --token-file). 18944 is 3D Slicer's default.
    #[arg(long, default_value = "18944")]
    pub listen: String,
    /// Serve only clients from this address (repeatable) [default: any that reaches the
    /// listening address]; others are logged and closed.
    #[arg(long, value_name = "IP")]
    pub allow: Vec<std::net::IpAddr>,
    /// Require every client to send the token in this file (its first line) as its first
    /// message: a STRING to device `Token`; others are logged and closed.
    #[arg(long, value_name = "PATH")]
    pub token_file: Option<PathBuf>,
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
    #[command(flatten)]
    pub start: StartArgs,
}

/// Reads a token file: its first line, trimmed; an error when empty.
fn read_token(path: &Path) -> Result<String, CliError> {
    let text = std::fs::read_to_string(path).map_err(|source| {
        CliError::from(operator::OperatorError::Io {
            path: path.to_path_buf(),
            source,
        })
    })?;
    let token = text.lines().next().unwrap_or_default().trim().to_string();
    if token.is_empty() {
        return Err(CliError::UnknownName {
            what: "token (the first line of --token-file is empty)",
            name: path.display().to_string(),
        });
    }
    Ok(token)
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
        Ok(port) => format!("127.0.0.1:{port}"),
        Err(_) => args.listen.clone(),
    };
    let mut config = navigation::server_config(args.rate_hz, registration);
    config.allow = args.allow.clone();
    config.token = args.token_file.as_deref().map(read_token).transpose()?;
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
        let mut server = igtl::Server::bind_with(addr.as_str(), config)
            .map_err(operator::OperatorError::from)?;
        println!(
            "OpenIGTLink on {} for the board {}: targets TRANSFORM/POSITION to device Target, pose TRANSFORM from device Robot at {} Hz, state STATUS RobotStatus / STRING RobotState{}{}",
            server.local_addr(),
            args.connect.display(),
            args.rate_hz,
            if args.allow.is_empty() { String::new() } else { format!("; clients allowed: {}", args.allow.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")) },
            if args.token_file.is_some() { "; a token is required (STRING to device Token first)" } else { "" },
        );
        let _ = std::io::stdout().flush();
        let mut robot = BoardRobot::new(board);
        navigation::serve(
            &mut server,
            &mut robot,
            shutdown.flag(),
            Duration::from_millis(1),
            &mut |m| eprintln!("igtl: {m}"),
        )?;
        let c = server.counters();
        println!(
            "igtl: targets accepted {}, refused {}; messages: {c}",
            robot.accepted, robot.refused
        );
        Ok(())
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::cli::{Cli, Command};
    use clap::Parser;

    fn hand(extra: &[&str]) -> Result<HandControllerArgs, clap::Error> {
        let mut argv = vec![
            "host-sim",
            "teleop",
            "--connect",
            "/tmp/board.sock",
            "--device",
            "keyboard",
        ];
        argv.extend_from_slice(extra);
        match Cli::try_parse_from(argv)?.command {
            Command::Teleop(t) => Ok(t.hand),
            other => panic!("parsed as {other:?}"),
        }
    }

    /// The live line fits an 80-column terminal whatever it shows, and keeps the state,
    /// the position and a refusal's guard, value and limit in it.
    #[test]
    fn the_live_line_fits_80_columns() {
        use master_link::{FaultCause, RobotState, StatusReport};
        use masters::{CueLevel, HoldReason, OperatorButtons};
        let mut s = StatusReport {
            state: RobotState::Enabled,
            ..StatusReport::default()
        };
        s.fault.cause = FaultCause::None;
        // The measured pose at the workspace's corner, the widest numbers it shows.
        s.position_m = [-0.0201, -0.0201, 0.1751];
        let words = "platform tilt 25.1 deg > 25.0 deg";
        let view = |state, refusal, t_s| TickView {
            t_s,
            state,
            cue: CueLevel::Approaching,
            status: Some(&s),
            target: None,
            buttons: OperatorButtons::default(),
            refusal,
        };
        let lines = [
            live_line(&view(TeleopState::Following, Some((1.0, words)), 1.5)),
            live_line(&view(TeleopState::Following, Some((1.0, words)), 9.0)),
            live_line(&view(
                TeleopState::Holding(HoldReason::OperatorAbsent),
                None,
                1.0,
            )),
            live_line(&view(TeleopState::Following, None, 1.0)),
            live_line(&view(
                TeleopState::Following,
                Some((1.0, "tilt spherical joint 1 30.1 deg > 30.0 deg")),
                1.0,
            )),
        ];
        for l in &lines {
            assert!(
                l.chars().count() <= 79,
                "{} columns: {l}",
                l.chars().count()
            );
        }
        assert!(lines[0].starts_with("Enabled "), "{}", lines[0]);
        assert!(
            lines[0]
                .contains("x-20.1 y-20.1 z175.1 mm  refused: platform tilt 25.1 deg > 25.0 deg"),
            "{}",
            lines[0]
        );
        assert!(!lines[1].contains("refused"), "{}", lines[1]);
        assert!(
            lines[2].contains("holding: operator absent"),
            "{}",
            lines[2]
        );
        assert!(lines[3].contains("edge approaching"), "{}", lines[3]);
        // Cut, not wrapped.
        assert_eq!(fit("abcdef", 4), "abc~");
        assert_eq!(fit("ab", 4), "ab  ");
    }

    /// `--tremor` chooses the mapping's suppression (the canceller when not given); a
    /// word it does not know is refused, naming the choices.
    #[test]
    fn the_tremor_flag_chooses_the_suppression() {
        let tremor = |extra: &[&str]| {
            let args = hand(extra).unwrap();
            teleoperation_settings(&args, "keyboard", 100.0)
                .unwrap()
                .teleop
                .tremor
        };
        assert_eq!(
            tremor(&[]),
            Some(TremorSuppression::Canceller(Default::default()))
        );
        assert_eq!(tremor(&["--tremor", "canceller"]), tremor(&[]));
        assert_eq!(
            tremor(&["--tremor", "classic"]),
            Some(TremorSuppression::classic())
        );
        assert_eq!(tremor(&["--tremor", "off"]), None);
        let e = hand(&["--tremor", "butterworth"]).unwrap_err().to_string();
        assert!(
            e.contains("butterworth") && e.contains("canceller") && e.contains("classic"),
            "{e}"
        );
    }
}
