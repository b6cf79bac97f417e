//! `teleop`: the host master of the board behind `host-sim teleop`, over a Unix socket
//! (the board emulator `firmware/board-emulator`, or the simulated board `host-sim board`)
//! or a serial device (a real board).
//!
//! It speaks the firmware's protocol (`master-link`: COBS frames, CRC-32, postcard
//! messages, protocol version, sequence numbers, the session the board issues, and with a
//! pre-shared key (`--key-file PATH`, [`link::read_key_file`]) the HMAC-SHA256 tag of every
//! frame): Hello (its nonce and clock; the board answers with the session, or refuses it
//! when another master owns the enabled robot), `OperatorPresent` (a new owner starts with
//! its operator absent; this master has no dead-man), Home, Enable, then streams a
//! path (the laparoscope figure-eight of `host-sim sim`, from the `trajectory` crate) as
//! timestamped pose targets while
//! sending heartbeats, records the status telemetry (`status.csv` under
//! `target/teleop/<scenario>/`) and prints a summary: tracking figures, refusals, link
//! counters of both directions, the board's tick timing.
//!
//! `--scenario ci` adds the checks of the CI run (the board emulator's scenarios run them
//! on the board's release image, `host-sim/board-scenarios`): a target
//! outside the workspace is refused and the robot holds; garbage on the link is counted
//! and ignored; when the heartbeat stops the board holds, then turns the drives off. It
//! exits non-zero when a check fails.

pub mod ci;
pub mod commission;
pub mod error;
pub mod faultlog;
pub mod link;
pub mod pacing;
pub mod session;
pub mod start;
pub mod tracking;

pub use error::TeleopError;
pub use tracking::Pass;

use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use nalgebra::Vector3;
use session::Session;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;
use trajectory::{laparoscope, line, Laparoscope, MasterLimits, Trajectory};

/// What the master does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum TeleopScenario {
    /// Hello, home, enable, stream the path, disable.
    Path,
    /// The path and every check of the CI scenario; non-zero exit on a failed check.
    Ci,
}

/// The path streamed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum PathChoice {
    /// The laparoscope figure-eight of `host-sim sim` (both passes: 2.5 and 25 mm/s).
    Laparoscope,
    /// Its 25 mm/s pass only.
    Fast,
    /// A 10 mm straight line in x and back at 10 mm/s.
    Line,
}

/// The clock the master streams, beats and measures by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ClockChoice {
    /// Paced by the board's telemetry (20 ms per status): follows an emulated board that
    /// its host stalls; the board's own clock when an emulated board shares it beside its
    /// socket (`Session::share_board_clock`).
    Board,
    /// The host's clock.
    Host,
}

/// What a teleoperation run does (`host-sim teleop`'s options).
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The board: a Unix socket or a serial device.
    pub connect: PathBuf,
    pub scenario: TeleopScenario,
    pub path: PathChoice,
    pub clock: ClockChoice,
    /// Target stream rate, Hz.
    pub stream_rate_hz: f64,
    /// Serial devices: the baud rate (set with stty).
    pub baud: u32,
    /// How long to wait for the socket or device and for the board's HelloReply, s.
    pub connect_timeout_s: f64,
    /// Longest homing, s.
    pub home_timeout_s: f64,
    /// The largest distance of the measured tip position from the streamed path, mm.
    pub max_deviation_mm: f64,
    /// Where `status.csv` goes.
    pub out: PathBuf,
    /// The laparoscope path (the simulation's `[scenario.laparoscope]` settings) ...
    pub laparoscope: Laparoscope,
    /// ... and the master's limits on a move (its `[master]` settings).
    pub master: MasterLimits,
    /// The link's pre-shared key (None: frames without tags, a board on a desk).
    pub key: Option<master_link::LinkKey>,
    /// What the person allowed at start (`--acknowledge-reset`, `--clear-fault`).
    pub start: start::StartOptions,
}

/// The path as a trajectory from the central pose, with its passes: the laparoscope path
/// of `laparoscope` (all passes, or its 25 mm/s pass only), or a 10 mm line and back,
/// within the master's `limits`.
pub fn trajectory(
    choice: PathChoice,
    centre: &Pose<f64>,
    laparoscope_settings: &Laparoscope,
    limits: &MasterLimits,
) -> (Trajectory, Vec<Pass>) {
    if choice == PathChoice::Line {
        let end = Pose {
            t: centre.t + Vector3::new(0.010, 0.0, 0.0),
            r: centre.r,
        };
        let mut t = Trajectory::default();
        t.push(line(limits, centre, &end, 10.0));
        t.push(line(limits, &end, centre, 10.0));
        let passes = vec![("10 mm line and back at 10 mm/s".to_string(), 0.0, t.end_s())];
        return (t, passes);
    }
    let mut settings = laparoscope_settings.clone();
    if choice == PathChoice::Fast {
        settings.pass_speeds_mm_s = vec![25.0];
        settings.pass_scales = vec![1.0];
    }
    let (traj, phases) = laparoscope(&settings, limits.accel_mm_s2, centre);
    let passes = phases
        .into_iter()
        .map(|p| (p.name, p.start_s, p.end_s))
        .collect();
    (traj, passes)
}

/// The scenario's name: `path` or `ci` (the default output directory's).
pub fn scenario_name(scenario: TeleopScenario) -> &'static str {
    match scenario {
        TeleopScenario::Path => "path",
        TeleopScenario::Ci => "ci",
    }
}

/// Runs the master (it prints the checks as they come, then the summary) until the path
/// ends or `stop` is set (a signal): whatever ends the run, the robot is left disabled
/// ([`ci::disable_on_exit`]).
pub fn run(args: &Settings, stop: &Arc<AtomicBool>) -> Result<(), TeleopError> {
    let geometry = RsprGeometry::<f64>::reference();
    let centre = Pose::central(geometry.hc);
    let central_q = {
        let q = inverse(&geometry, &centre, Branch::OUTER)
            .map_err(TeleopError::CentralPose)?
            .q();
        [q.x, q.y, q.z, q.w, q.a, q.b]
    };
    let (traj, passes) = trajectory(args.path, &centre, &args.laparoscope, &args.master);
    let name = scenario_name(args.scenario);
    let out = &args.out;
    println!(
        "host-sim teleop: {} ({} scenario, path {:?}: {:.1} s at {} Hz)",
        args.connect.display(),
        name,
        args.path,
        traj.end_s(),
        args.stream_rate_hz
    );
    let timeout = Duration::from_secs_f64(args.connect_timeout_s.max(0.0));
    let link = link::open_with_key(&args.connect, args.baud, timeout, args.key.clone())?;
    let mut s = Session::new(link);
    s.paced = args.clock == ClockChoice::Board;
    if s.paced {
        s.share_board_clock(&args.connect);
    }
    s.stop = Some(Arc::clone(stop));
    let mut checks = ci::Checks::default();
    let result = steps(
        &mut s,
        &mut checks,
        args,
        (&traj, &passes),
        &centre,
        &central_q,
    );
    if let Some(done) = ci::disable_on_exit(&mut s) {
        println!("{done}");
    }
    match result {
        // What the person must decide (a reset, a fault, another master): no summary.
        Err(
            e @ (TeleopError::ResetNotAcknowledged(_)
            | TeleopError::Faulted(_)
            | TeleopError::Busy(_)
            | TeleopError::HelloRefused(_)),
        ) => return Err(e),
        Err(TeleopError::Interrupted) => {
            checks.check("run", false, "stopped by a signal".into());
        }
        Err(e) => checks.check("run", false, format!("stopped: {e}")),
        Ok(()) => {}
    }
    let written = write_csv(&s, out);
    print!("{}", summary(&s, &checks));
    match written {
        Ok(p) => println!("telemetry: {}", p.display()),
        Err(e) => println!("telemetry not written: {e}"),
    }
    if checks.all_ok() {
        println!("teleop: {} checks passed", checks.list.len());
        Ok(())
    } else {
        let failed: Vec<String> = checks
            .list
            .iter()
            .filter(|c| !c.ok)
            .map(|c| c.name.clone())
            .collect();
        Err(TeleopError::ChecksFailed {
            failed,
            total: checks.list.len(),
        })
    }
}

fn steps(
    s: &mut Session,
    checks: &mut ci::Checks,
    args: &Settings,
    (traj, passes): (&Trajectory, &[Pass]),
    centre: &Pose<f64>,
    central_q: &[f64; 6],
) -> Result<(), TeleopError> {
    ci::hello(s, checks, args.connect_timeout_s)?;
    if ci::prepare(s, checks, args.start)? {
        checks.check(
            "homes",
            true,
            "already homed (Ready): homing skipped".into(),
        );
    } else if !ci::home(s, checks, args.home_timeout_s, central_q)? {
        return Ok(());
    }
    if !ci::enable(s, checks)? {
        return Ok(());
    }
    ci::stream(
        s,
        checks,
        traj,
        passes,
        args.stream_rate_hz,
        args.max_deviation_mm * 1e-3,
    )?;
    if args.scenario == TeleopScenario::Ci {
        ci::refuse(s, checks, centre)?;
        ci::garbage(s, checks)?;
        ci::heartbeat_loss(s, checks)?;
    }
    ci::disable(s, checks)
}

/// The summary: link counters of both directions, the board's timing, the refusals.
pub fn summary(s: &Session, checks: &ci::Checks) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "--- teleop summary");
    let _ = writeln!(
        o,
        "master -> board: {} frames ({} bytes) sent, {} acks received, {} refused",
        s.link.frames_sent,
        s.link.bytes_sent,
        s.acks,
        s.refused.len()
    );
    for r in &s.refused {
        let phase = s.phases.get(r.phase).map_or("?", String::as_str);
        let when = if r.later {
            "by the path check after its acknowledgement"
        } else {
            "at once"
        };
        let _ = writeln!(
            o,
            "  refused in {phase} ({when}): {}: {}",
            request_name(&r.request),
            r.words
        );
    }
    if let Some(last) = s.last_status() {
        let c = last.status.link;
        let _ = writeln!(
            o,
            "board's receive counters: frames ok {}, bad checksum {}, malformed {}, oversized {}, wrong version {}, out of order {}, wrong session {}, bad tag {}, dropped {}",
            c.frames_ok, c.bad_checksum, c.malformed, c.oversized, c.wrong_version, c.out_of_order, c.wrong_session, c.bad_tag, c.dropped
        );
        let _ = writeln!(
            o,
            "board tick: worst execution {} us, worst start jitter {} us; final state {}; {}",
            last.status.tick_exec_max_us,
            last.status.tick_jitter_max_us,
            board_words::state(last.status.state),
            board_words::fault(&last.status.fault).unwrap_or_else(|| "no fault".to_string())
        );
    }
    let c = s.link.counters();
    let _ = writeln!(
        o,
        "master's receive counters: frames ok {}, rejected {}, dropped {}; statuses recorded {}",
        c.frames_ok,
        c.rejected(),
        c.dropped,
        s.statuses.len()
    );
    let failed = checks.list.iter().filter(|c| !c.ok).count();
    let _ = writeln!(
        o,
        "checks: {} passed, {failed} failed",
        checks.list.len() - failed
    );
    o
}

/// Writes the telemetry as `status.csv` in `dir`.
pub fn write_csv(s: &Session, dir: &Path) -> Result<PathBuf, TeleopError> {
    std::fs::create_dir_all(dir).map_err(|source| TeleopError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join("status.csv");
    let mut w = csv::Writer::from_path(&path).map_err(|source| TeleopError::Telemetry {
        path: path.clone(),
        source,
    })?;
    let header = [
        "t_s",
        "phase",
        "state",
        "x_mm",
        "y_mm",
        "z_mm",
        "rx_deg",
        "ry_deg",
        "rz_deg",
        "l1_mm",
        "l2_mm",
        "l3_mm",
        "theta1_deg",
        "theta2_deg",
        "theta3_deg",
        "warnings",
        "faults",
        "serial_margin",
        "parallel_margin",
        "frames_ok",
        "rejected",
        "tick_exec_max_us",
        "tick_jitter_max_us",
        "targets_refused",
    ];
    w.write_record(header).map_err(TeleopError::TelemetryRow)?;
    for r in &s.statuses {
        let st = &r.status;
        let mut row = vec![
            format!("{:.4}", r.t_s),
            s.phases.get(r.phase).cloned().unwrap_or_default(),
            format!("{:?}", st.state),
        ];
        row.extend(
            st.position_m
                .iter()
                .map(|x| format!("{:.5}", f64::from(*x) * 1e3)),
        );
        row.extend(
            st.rotation_vector_rad
                .iter()
                .map(|x| format!("{:.5}", f64::from(*x).to_degrees())),
        );
        row.extend(st.joints.iter().enumerate().map(|(j, x)| {
            let x = f64::from(*x);
            format!("{:.5}", if j < 3 { x * 1e3 } else { x.to_degrees() })
        }));
        row.push(format!("{:#x}", st.warnings.bits()));
        row.push(format!("{:#x}", st.faults.bits()));
        row.push(format!("{:.5}", st.serial_singularity_margin));
        row.push(format!("{:.5}", st.parallel_singularity_margin));
        row.push(st.link.frames_ok.to_string());
        row.push(st.link.rejected().to_string());
        row.push(st.tick_exec_max_us.to_string());
        row.push(st.tick_jitter_max_us.to_string());
        row.push(st.targets_refused.to_string());
        w.write_record(&row).map_err(TeleopError::TelemetryRow)?;
    }
    w.flush().map_err(TeleopError::TelemetryFlush)?;
    Ok(path)
}

/// A request's name in words (the summary's lines).
pub fn request_name(msg: &master_link::MasterToBoard) -> String {
    use master_link::MasterToBoard;
    match msg {
        MasterToBoard::PoseTarget {
            timestamp_us,
            position_m,
            ..
        } => format!(
            "target at {:.1}, {:.1}, {:.1} mm (stamp {} µs)",
            f64::from(position_m[0]) * 1e3,
            f64::from(position_m[1]) * 1e3,
            f64::from(position_m[2]) * 1e3,
            timestamp_us
        ),
        MasterToBoard::Jog { joint, velocity } => format!(
            "jog of {} at {velocity}",
            board_words::joint_name(*joint).unwrap_or_else(|| format!("joint {joint}"))
        ),
        MasterToBoard::Hello { .. } => "hello".into(),
        MasterToBoard::Enable => "enable".into(),
        MasterToBoard::Disable => "disable".into(),
        MasterToBoard::Home { rehome: false } => "home".into(),
        MasterToBoard::Home { rehome: true } => "re-home".into(),
        MasterToBoard::Clutch { engaged } => {
            format!("clutch {}", if *engaged { "engaged" } else { "released" })
        }
        MasterToBoard::Heartbeat => "heartbeat".into(),
        MasterToBoard::EmergencyStop => "emergency stop".into(),
        MasterToBoard::ClearFault => "clear fault".into(),
        MasterToBoard::StatusRequest => "status request".into(),
        MasterToBoard::OperatorPresent { present } => {
            format!("operator {}", if *present { "present" } else { "absent" })
        }
        MasterToBoard::AcknowledgeReset => "acknowledge reset".into(),
        MasterToBoard::FaultLogRequest { .. } => "fault log request".into(),
        MasterToBoard::StoreGeometry(_) => "store geometry".into(),
        MasterToBoard::EventLogRequest { .. } => "event log request".into(),
        MasterToBoard::Commission { joint, .. } => format!(
            "commission {}",
            board_words::joint_name(*joint).unwrap_or_else(|| format!("joint {joint}"))
        ),
    }
}
