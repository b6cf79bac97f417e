//! `host-sim sim` on the command line: the flags, a progress bar on a terminal, the run
//! of each scenario (the `simulation` crate) and its summary.

use crate::error::CliError;
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use robot_config::selection::{SelectedLimits, SelectedRobot};
use simulation::config::SimConfig;
use simulation::scenario::{Scenario, NAMES};
use simulation::{default_threads, report_text};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// `host-sim sim` arguments.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// Scenario: laparoscope (default), step, box-sweep, payload, backlash-off, or all.
    #[arg(long, default_value = "laparoscope", value_name = "NAME")]
    pub scenario: String,
    /// Settings (TOML with the keys of host-sim/simulation/default.toml; only the keys to
    /// change) [default: host-sim/simulation/default.toml, embedded].
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// Output directory [default: output.dir of the config, else target/sim/<scenario>];
    /// with --scenario all, one sub-directory per scenario.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Threads: 1 runs the whole loop on one; 2 runs the master side (target stream and
    /// the controller's supervisor) ahead of the drive side (servo, plant, truth,
    /// metrics), with the same results [default: 2 when the machine has 2 cores]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=2))]
    pub threads: Option<u8>,
}

/// A progress bar on stderr, shown only on a terminal and only once a run has taken
/// longer than a second.
struct Progress {
    bar: ProgressBar,
    started: Instant,
    shown: bool,
    tty: bool,
}

impl Progress {
    fn new(name: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
        if let Ok(style) =
            ProgressStyle::with_template("{prefix} [{bar:40}] {percent:>3}% simulated, eta {eta}")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(name.to_string());
        Progress {
            bar,
            started: Instant::now(),
            shown: false,
            tty: std::io::stderr().is_terminal(),
        }
    }

    fn update(&mut self, done: u64, total: u64) {
        self.bar.set_length(total);
        self.bar.set_position(done);
        if !self.shown && self.tty && self.started.elapsed() > Duration::from_secs(1) {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            self.shown = true;
        }
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// Runs `host-sim sim`: each scenario, its files and its summary.
pub fn run(
    args: &SimArgs,
    selected: &SelectedRobot,
    limits: &SelectedLimits,
) -> Result<(), CliError> {
    let robot = simulation::rspr(&selected.robot)?;
    let cfg = SimConfig::load(args.config.as_deref())?;
    let names: Vec<&str> = if args.scenario == "all" {
        NAMES.to_vec()
    } else {
        vec![args.scenario.as_str()]
    };
    let all = names.len() > 1;
    for name in names {
        let scenario = Scenario::from_config(name, &cfg, robot.hc)?;
        let mut progress = Progress::new(name);
        let threads = args.threads.map_or_else(default_threads, usize::from);
        let outcome = simulation::run::run(
            &robot,
            &limits.limits,
            &cfg,
            &scenario,
            threads,
            &mut |d, t| progress.update(d, t),
        );
        progress.finish();
        let outcome = outcome?;
        let dir = match (&args.out, all) {
            (Some(o), true) => o.join(name),
            (Some(o), false) => o.clone(),
            (None, _) => cfg.output_dir(None, name),
        };
        let mut written = simulation::output::write_all(&outcome, &dir, cfg.output.plots)?;
        written.files.push(simulation::output::write_scene(
            &outcome,
            &kinematics_core::Robot::Rspr(robot),
            &limits.limits,
            &dir.join("scene.mcap"),
        )?);
        print!("{}", report_text(&outcome.summary));
        println!("  wrote {}", dir.display());
        for f in &written.files {
            if let Some(n) = f.file_name() {
                println!("    {}", n.to_string_lossy());
            }
        }
        println!();
    }
    Ok(())
}
