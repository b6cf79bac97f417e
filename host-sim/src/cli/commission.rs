//! `host-sim commission --connect <board>`: the first power-up of a robot just built, joint
//! by joint, with plain instructions for the person at the robot. The board's
//! commissioning mode (`control::commissioning`) tests each joint's wiring; this command
//! shows each finding and the fix it implies, and writes the commissioning report
//! (`report.txt`), the board profile with the measured gear ratios (`board-profile.toml`,
//! `board_profile::BoardProfile`'s TOML form) and the wiring corrections for the board's
//! pin map (`wiring.toml`: the signs of `INVERT_MOTOR`, `INVERT_ENCODER`, the encoder each
//! counter reads, the switches, the brakes, the current offsets).

use crate::error::CliError;
use board_profile::BoardProfile;
use clap::Args;
use master_link::{CommissionFindings as F, CommissionRecord};
use robot_config::output;
use std::fmt::Write as _;
use std::io::BufRead;
use std::path::PathBuf;
use std::time::Duration;

/// `host-sim commission` options.
#[derive(Debug, Args)]
pub struct CommissionArgs {
    /// The board: a Unix socket (the simulated board, the emulator) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// The joints to test, comma-separated (0..5: l1, l2, l3, theta1, theta2, theta3)
    /// [default: all].
    #[arg(long, value_delimiter = ',')]
    pub joints: Vec<u8>,
    /// A person at the robot confirms commissioning a robot that is homed or has a fault
    /// latched (the board refuses otherwise).
    #[arg(long)]
    pub confirm: bool,
    /// Do not wait for Enter before each joint, and ask nothing (scripts, tests).
    #[arg(long)]
    pub yes: bool,
    /// Output directory [default: target/commission/ under the current directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub key: super::KeyArgs,
}

use teleop::commission::{Person, NAMES};

/// The person at the robot on this terminal: Enter before each joint, asked which way a
/// joint moved where the board cannot tell; with `--yes` nothing is asked.
struct Terminal {
    yes: bool,
    lines: std::io::Lines<std::io::StdinLock<'static>>,
}

impl Person for Terminal {
    fn ready(&mut self, _joint: u8) {
        if !self.yes {
            println!("Press Enter when the joint is clear (Ctrl-C to stop).");
            let _ = self.lines.next();
        }
    }
    fn moved_towards_plus(&mut self, joint: u8) -> Option<bool> {
        if self.yes {
            return None;
        }
        let name = board_words::joint_name(joint).unwrap_or_default();
        println!(
            "Did {name} move towards +q ({})? [y/n]",
            if joint < 3 {
                "extend"
            } else {
                "counter-clockwise"
            }
        );
        let answer = self.lines.next().and_then(Result::ok).unwrap_or_default();
        Some(answer.trim().starts_with('y'))
    }
    fn say(&mut self, text: &str) {
        println!("{text}");
    }
}

/// Runs commissioning joint by joint and writes the report and the corrections.
pub fn commission(args: &CommissionArgs) -> Result<(), CliError> {
    let joints: Vec<u8> = if args.joints.is_empty() {
        (0..6).collect()
    } else {
        args.joints.clone()
    };
    if let Some(j) = joints.iter().find(|j| **j > 5) {
        return Err(CliError::Commission(format!(
            "--joints: {j} is not a joint (0..5: l1, l2, l3, theta1, theta2, theta3)"
        )));
    }
    let link = teleop::link::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(5),
        args.key.key()?,
    )?;
    let mut s = teleop::session::Session::new(link);
    s.hello(10.0)?;
    println!("Commissioning: one joint at a time, the others unpowered with their brakes applied;");
    println!("{}.", teleop::commission::LIMITS);
    println!("Before you start: power the drives from a current-limited supply, keep the e-stop");
    println!("within reach, and keep hands and tools clear of the robot.");
    let mut person = Terminal {
        yes: args.yes,
        lines: std::io::stdin().lock().lines(),
    };
    let records = teleop::commission::run(&mut s, &joints, args.confirm, &mut person).map_err(
        |e| match e {
            teleop::commission::CommissionError::Teleop(e) => CliError::from(e),
            e => CliError::Commission(e.to_string()),
        },
    )?;
    let out = output::out_dir(args.out.as_deref(), &["commission"]);
    std::fs::create_dir_all(&out).map_err(|source| CliError::CreateDir {
        path: out.display().to_string(),
        source,
    })?;
    let report = teleop::commission::report_text(&records);
    let profile = profile_toml(&BoardProfile::REFERENCE, &records);
    let wiring = wiring_toml(&records);
    for (file, text) in [
        ("report.txt", &report),
        ("board-profile.toml", &profile),
        ("wiring.toml", &wiring),
    ] {
        let path = out.join(file);
        std::fs::write(&path, text).map_err(|source| CliError::CreateDir {
            path: path.display().to_string(),
            source,
        })?;
    }
    let found = records.iter().filter(|r| !r.findings.is_empty()).count();
    println!();
    if found == 0 {
        println!("commissioning: every joint tested is wired as the pin map says");
    } else {
        println!("commissioning: {found} joint(s) need a fix (above); re-run after fixing");
    }
    println!(
        "wrote {}, {} and {}",
        out.join("report.txt").display(),
        out.join("board-profile.toml").display(),
        out.join("wiring.toml").display()
    );
    Ok(())
}

/// `profile` with each joint's gear ratio scaled by the measured counts per unit where
/// commissioning found the scale off (the TOML form `BoardProfile::from_toml_str` reads).
pub fn profile_toml(profile: &BoardProfile, records: &[CommissionRecord]) -> String {
    let mut t = String::from(
        "# The board profile with the gear ratios commissioning measured (host-sim commission):\n\
         # a joint whose encoder counted more or fewer counts per unit than the profile's has its\n\
         # gear_ratio scaled by the measured ratio. Units: us, Hz, m, rad.\n",
    );
    let _ = writeln!(t, "control_period_us = {}", profile.control_period_us);
    let _ = writeln!(t, "cpu_hz = {}", profile.cpu_hz);
    for (j, p) in profile.joints.iter().enumerate() {
        let scale = records
            .iter()
            .find(|r| usize::from(r.joint) == j && r.findings.contains(F::SCALE))
            .map(|r| f64::from(r.scale));
        let gear = p.gear_ratio * scale.unwrap_or(1.0);
        let _ = writeln!(t, "\n[[joints]]");
        if let Some(s) = scale {
            let _ = writeln!(
                t,
                "# {}: measured {s:.4} x the profile's counts per unit",
                NAMES[j]
            );
        }
        let kind = match p.kind {
            board_profile::JointKind::Prismatic => "prismatic",
            board_profile::JointKind::Revolute => "revolute",
        };
        let _ = writeln!(t, "kind = \"{kind}\"");
        let _ = writeln!(t, "encoder_lines_per_rev = {}", p.encoder_lines_per_rev);
        let _ = writeln!(t, "quadrature = {}", p.quadrature);
        let _ = writeln!(t, "gear_ratio = {gear:?}");
        let _ = writeln!(t, "lead_m = {:?}", p.lead_m);
        let _ = writeln!(t, "range = [{:?}, {:?}]", p.range[0], p.range[1]);
    }
    t
}

/// The wiring corrections for the board's pin map (`firmware/cortex-m/board/src/board.rs`):
/// per joint in joint order, what commissioning found (joints not tested keep the pin
/// map's).
pub fn wiring_toml(records: &[CommissionRecord]) -> String {
    let of = |f: F| -> [bool; 6] {
        std::array::from_fn(|j| {
            records
                .iter()
                .any(|r| usize::from(r.joint) == j && r.findings.contains(f))
        })
    };
    let mut channel: [usize; 6] = std::array::from_fn(|j| j);
    for r in records {
        if r.findings.contains(F::ENCODER_SWAPPED) && r.moved_encoder < 6 {
            channel[usize::from(r.joint).min(5)] = usize::from(r.moved_encoder);
        }
    }
    let offsets: [f32; 6] = std::array::from_fn(|j| {
        records
            .iter()
            .find(|r| usize::from(r.joint) == j && r.findings.contains(F::CURRENT_OFFSET))
            .map_or(0.0, |r| r.current_offset_a)
    });
    let mut t = String::from(
        "# Wiring corrections found by commissioning (host-sim commission), joint order l1, l2,\n\
         # l3, theta1, theta2, theta3: the board's pin map (firmware/cortex-m/board/src/board.rs)\n\
         # takes invert_motor as INVERT_MOTOR and invert_encoder as INVERT_ENCODER; the others\n\
         # are fixed in the wiring (the report says how). Rewiring instead is the better fix.\n",
    );
    let _ = writeln!(t, "invert_motor = {:?}", of(F::MOTOR_REVERSED));
    let _ = writeln!(t, "invert_encoder = {:?}", of(F::ENCODER_REVERSED));
    let _ = writeln!(t, "# the counter that reads each joint's encoder");
    let _ = writeln!(t, "encoder_channel = {channel:?}");
    let _ = writeln!(
        t,
        "home_switch_normally_open = {:?}",
        of(F::SWITCH_INVERTED)
    );
    let _ = writeln!(t, "brake_inverted = {:?}", of(F::BRAKE_INVERTED));
    let _ = writeln!(t, "current_offset_a = {offsets:?}");
    t
}
