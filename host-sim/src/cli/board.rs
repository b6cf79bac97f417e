//! `host-sim faults`, `host-sim board` and `host-sim faultlog`: the fault-injection
//! campaign against the whole board application in simulation, the simulated board served
//! on a socket, and the fault log of a board read over its link.

use crate::error::CliError;
use clap::Args;
use robot_config::output;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// `host-sim faults` options.
#[derive(Debug, Args)]
pub struct FaultsArgs {
    /// Fault kinds, comma-separated [default: all]: encoder-stuck, encoder-jump,
    /// encoder-dead, motor-open, motor-shorted, driver-fault, supply-sag, overcurrent,
    /// bridge-stuck-on, link-loss, garbage-burst, replayed-frames, e-stop, relay-welded,
    /// tick-overrun, nan-target, unreachable-target, limit-switch-closed, load-seized,
    /// wall-contact, homing-switch-dead, brake-weak.
    #[arg(long, value_delimiter = ',')]
    pub kinds: Vec<String>,
    /// Conditions, comma-separated [default: all]: holding, slow, fast, tool, homing,
    /// brake-check, held-tool-push, during-ss1, during-ss2, after-enable, double.
    #[arg(long, value_delimiter = ',')]
    pub conditions: Vec<String>,
    /// Threads [default: 2].
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Output directory [default: target/faults/ under the current directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs the campaign: the matrix printed, campaign.csv and campaign.png written; an error
/// when a cell fails.
pub fn faults(args: &FaultsArgs) -> Result<(), CliError> {
    let kinds = if args.kinds.is_empty() {
        faults::FaultKind::ALL.to_vec()
    } else {
        args.kinds
            .iter()
            .map(|k| {
                faults::FaultKind::from_name(k).ok_or_else(|| CliError::UnknownName {
                    what: "fault kind",
                    name: k.clone(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?
    };
    let conditions = if args.conditions.is_empty() {
        faults::Condition::ALL.to_vec()
    } else {
        args.conditions
            .iter()
            .map(|c| {
                faults::Condition::from_name(c).ok_or_else(|| CliError::UnknownName {
                    what: "condition",
                    name: c.clone(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?
    };
    let t0 = std::time::Instant::now();
    let cells = faults::run(&kinds, &conditions, args.threads, &|c| {
        eprintln!(
            "  {:<20} {:<8} {}",
            c.kind.name(),
            c.condition.name(),
            if c.pass { "ok" } else { "FAILED" }
        );
    })?;
    print!("{}", faults::report::matrix_text(&cells));
    let out = output::out_dir(args.out.as_deref(), &["faults"]);
    std::fs::create_dir_all(&out).map_err(|source| CliError::CreateDir {
        path: out.display().to_string(),
        source,
    })?;
    let csv = out.join("campaign.csv");
    let png = out.join("campaign.png");
    faults::report::write_csv(&cells, &csv)?;
    faults::report::write_png(&cells, &png)?;
    println!(
        "campaign: {} cells in {:.1} s; wrote {} and {}",
        cells.len(),
        t0.elapsed().as_secs_f64(),
        csv.display(),
        png.display()
    );
    let failed = cells.iter().filter(|c| !c.pass).count();
    if failed > 0 {
        return Err(CliError::CampaignFailed(failed));
    }
    Ok(())
}

/// `host-sim board` options.
#[derive(Debug, Args)]
pub struct BoardArgs {
    /// The Unix socket to listen on.
    #[arg(long, value_name = "PATH")]
    pub socket: PathBuf,
    /// Attach the thesis's tool (1.2 kg on a 0.1 m lever).
    #[arg(long)]
    pub tool: bool,
    /// The board's link key (masters need the same `--key-file`).
    #[command(flatten)]
    pub key: super::KeyArgs,
}

/// Serves the simulated board until the process is stopped.
pub fn board(args: &BoardArgs) -> Result<(), CliError> {
    let mut cfg = simulation::board::BoardSimConfig::reference(None)?;
    if args.tool {
        cfg.tool = Some(control::ToolLoad::thesis());
    }
    cfg.key = args.key.key()?;
    // The host is not real time: a late tick is the host's, not the board's.
    cfg.service.watchdog.max_lateness_us = 1_000_000;
    cfg.service.overruns_to_fault = u32::MAX;
    let keyed = cfg.key.is_some();
    let stop = AtomicBool::new(false);
    let socket = args.socket.display().to_string();
    simulation::serve::serve(&args.socket, cfg, &stop, &|| {
        println!("simulated board on {socket} (the board application on the plant, its clock paced by the wall clock and its masters; stop with Ctrl-C){}", if keyed { "; link key set: frames without a valid tag are dropped" } else { "" });
    })?;
    Ok(())
}

/// `host-sim faultlog` options.
#[derive(Debug, Args)]
pub struct FaultLogArgs {
    /// The board: a Unix socket (the simulated board, the emulator) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    #[command(flatten)]
    pub key: super::KeyArgs,
}

/// Reads the fault log and the event log and prints them.
pub fn faultlog(args: &FaultLogArgs) -> Result<(), CliError> {
    let link = teleop::link::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(5),
        args.key.key()?,
    )?;
    let mut s = teleop::session::Session::new(link);
    let (reset, entries) = teleop::faultlog::read(&mut s)?;
    print!("{}", teleop::faultlog::table(&reset, &entries));
    let (events, page) = teleop::faultlog::read_events(&mut s)?;
    println!();
    print!("{}", teleop::faultlog::events_table(&events, &page));
    Ok(())
}
