//! An OpenIGTLink server in front of a simulated robot (`igtl::fake_robot`): its measured
//! pose moves towards the last accepted target at 25 mm/s and 30 deg/s, and targets outside
//! the task box (plus margin) or tilted beyond 25 deg are refused with a STATUS.
//!
//! ```sh
//! cargo run -p igtl --example fake_robot -- --bind 127.0.0.1:18944
//! ```
//! Prints `listening on ADDR` first (with the port chosen when the port is 0), then one line
//! per connection and per refused target on stderr.

use clap::Parser;
use igtl::fake_robot::{FakeRobot, FakeRobotConfig};
use igtl::{Registration, Server, ServerConfig};
use std::io::Write;
use std::net::ToSocketAddrs;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Parser, Debug)]
#[command(about = "OpenIGTLink server in front of a simulated robot")]
struct Args {
    /// Address to listen on (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:18944")]
    bind: String,
    /// Device name of target poses (TRANSFORM, POSITION, QTRANS).
    #[arg(long, default_value = "Target")]
    target_device: String,
    /// Device name of the measured pose.
    #[arg(long, default_value = "Robot")]
    pose_device: String,
    /// Rate of the measured-pose stream, Hz.
    #[arg(long, default_value_t = 50.0)]
    rate_hz: f64,
    /// Registration client frame -> robot base as a TOML file (key image_to_base_mm).
    #[arg(long, conflicts_with = "registration_matrix")]
    registration: Option<PathBuf>,
    /// Registration as 16 numbers, row-major, translation in mm.
    #[arg(long, allow_hyphen_values = true)]
    registration_matrix: Option<String>,
    /// Speed limit of the simulated robot, mm/s.
    #[arg(long, default_value_t = 25.0)]
    speed_mm_s: f64,
    /// Answer accepted targets with STATUS OK.
    #[arg(long)]
    acknowledge: bool,
    /// Also connect out to a client that listens (3D Slicer's OpenIGTLinkIF in server
    /// mode), HOST:PORT; reconnected every second while closed.
    #[arg(long)]
    connect: Option<String>,
    /// Do not push pose and state on connection (clients use STT_TRANS / GET_).
    #[arg(long)]
    no_push: bool,
    /// Stop after this many seconds and print the counters (default: run until killed).
    #[arg(long)]
    duration_s: Option<f64>,
    /// Loop period, microseconds.
    #[arg(long, default_value_t = 500)]
    tick_us: u64,
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("fake_robot: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Box<dyn std::error::Error>> {
    if !(args.rate_hz.is_finite() && args.rate_hz > 0.0) {
        return Err(format!("--rate-hz {} must be positive", args.rate_hz).into());
    }
    if !(args.speed_mm_s.is_finite() && args.speed_mm_s > 0.0) {
        return Err(format!("--speed-mm-s {} must be positive", args.speed_mm_s).into());
    }
    let registration = match (&args.registration, &args.registration_matrix) {
        (Some(path), _) => Registration::load(path)?,
        (None, Some(text)) => Registration::parse_numbers_mm(text)?,
        (None, None) => Registration::identity(),
    };
    let config = ServerConfig {
        target_device: args.target_device.clone(),
        pose_device: args.pose_device.clone(),
        pose_period: Duration::from_secs_f64(1.0 / args.rate_hz),
        acknowledge_targets: args.acknowledge,
        stream_on_connect: !args.no_push,
        registration,
        ..ServerConfig::default()
    };
    let mut server = Server::bind_with(args.bind.as_str(), config)?;
    let mut robot = FakeRobot::new(FakeRobotConfig {
        speed: args.speed_mm_s / 1000.0,
        ..FakeRobotConfig::default()
    });
    println!("listening on {}", server.local_addr());
    std::io::stdout().flush()?;

    let connect_to = match &args.connect {
        Some(a) => Some(
            a.to_socket_addrs()?
                .next()
                .ok_or_else(|| format!("--connect {a}: no address"))?,
        ),
        None => None,
    };
    let mut outgoing_open = false;
    let mut next_connect = Instant::now();

    let start = Instant::now();
    let mut last = start;
    let tick = Duration::from_micros(args.tick_us.max(1));
    loop {
        let now = Instant::now();
        robot.step(now - last);
        last = now;
        if let Some(addr) = connect_to {
            if !outgoing_open && now >= next_connect {
                next_connect = now + Duration::from_secs(1);
                match server.connect_to(addr, Duration::from_millis(500)) {
                    Ok(()) => {
                        outgoing_open = true;
                        eprintln!("connected to {addr}");
                    }
                    Err(e) => eprintln!("{e}"),
                }
            }
        }
        let report = server.poll(&mut robot);
        if let Some(e) = &report.accept_error {
            eprintln!("{e}");
        }
        if report
            .closed
            .iter()
            .any(|(peer, _)| Some(*peer) == connect_to)
        {
            outgoing_open = false;
        }
        for peer in &report.accepted {
            eprintln!("connected: {peer}");
        }
        for (peer, reason) in &report.closed {
            eprintln!("closed: {peer} ({reason:?})");
        }
        if report.targets_refused > 0 {
            eprintln!("targets refused: {}", report.targets_refused);
        }
        if args
            .duration_s
            .is_some_and(|d| start.elapsed().as_secs_f64() >= d)
        {
            println!("{}", server.counters().to_json());
            return Ok(());
        }
        std::thread::sleep(tick);
    }
}
