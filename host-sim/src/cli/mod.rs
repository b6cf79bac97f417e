//! The command line: the robot and limits selection shared by every subcommand, and the
//! subcommands. New subcommands are new variants of [`Command`] with their own `Args`
//! struct; the row-wise ones live in [`crate::commands`], the others here: [`design`]
//! (`forces --path`, `report`, `ranges`, `workspace`, `synth`, `compare`), [`sim`],
//! [`teleop`] and [`calibrate`], each turning its flags into the library's settings and printing what the
//! library returns.

pub mod board;
pub mod board_session;
pub mod calibrate;
pub mod commission;
pub mod describe;
pub mod design;
pub mod identify;
pub mod operator;
pub mod ros2;
pub mod sim;
pub mod teleop;
pub mod view;

use crate::commands::{check, fk, ik, jacobian, singularity};
use crate::error::CliError;
use clap::{Args, Parser, Subcommand, ValueEnum};
use robot_config::selection::{BuiltinRobot, SelectedLimits, SelectedRobot};
use std::path::PathBuf;

/// Host tool of the RSPR/USR surgical robots: kinematics, statics and design reports.
///
/// Lengths are millimetres and angles degrees at this edge; poses are
/// x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg with (rx, ry, rz) the rotation vector (axis * angle).
/// Every row-wise command has a single-pose form (flags) and a batch form (--csv: CSV with a
/// header on stdin, CSV on stdout, one output row per input row).
///
/// Files: a command that writes files writes them to its --out DIR, else to
/// target/<tool>/ under the current directory (target/sim/<scenario>/, target/faults/,
/// target/replay/<recording>/, target/calibration/, target/teleop/<scenario>/,
/// target/design/<command>/).
#[derive(Debug, Parser)]
#[command(name = "host-sim", version)]
pub struct Cli {
    #[command(flatten)]
    pub robot: RobotArgs,
    #[command(flatten)]
    pub limits: LimitsArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// A built-in robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RobotChoice {
    /// The RSPR prototype of thesis chapter 11 (Table 11.1): e 20, rb 90, rp 50, hc 160 mm.
    Rspr,
    /// The USR of thesis Appendix A (Table 4.1): e 30, rp 30, l1 60, l2 80, hc 80 mm.
    Usr,
}

/// Which robot the command works on.
#[derive(Debug, Args)]
pub struct RobotArgs {
    /// Built-in reference robot [default: rspr].
    #[arg(long, global = true, value_enum, conflicts_with = "geometry")]
    pub robot: Option<RobotChoice>,
    /// Geometry file (TOML, mm): robot = "rspr" with e_mm, rb_mm, rp_mm, hc_mm,
    /// robot = "usr" with e_mm, rp_mm, l1_mm, l2_mm, hc_mm, or robot = "rspr-per-chain",
    /// the calibrated geometry `calibrate` writes.
    #[arg(long, global = true, value_name = "FILE.toml")]
    pub geometry: Option<PathBuf>,
}

/// Which limits the guards use (`check`, `workspace`, `sim`).
#[derive(Debug, Args)]
pub struct LimitsArgs {
    /// Limits file (TOML; mm, deg, N, N m; unit-suffixed keys, each optional, defaulting
    /// to the reference limits; see host-sim/robot-config/limits/reference.toml)
    /// [default: the reference limits]. Loaded and validated whenever given.
    #[arg(long, global = true, value_name = "FILE.toml")]
    pub limits: Option<PathBuf>,
}

impl LimitsArgs {
    /// The limits: the file if given, else the reference limits.
    pub fn select(&self) -> Result<SelectedLimits, CliError> {
        Ok(match &self.limits {
            Some(path) => SelectedLimits::from_file(path)?,
            None => SelectedLimits::reference(),
        })
    }
}

impl RobotArgs {
    /// The robot: the geometry file if given, else the chosen or default reference robot.
    pub fn select(&self) -> Result<SelectedRobot, CliError> {
        if let Some(path) = &self.geometry {
            return Ok(SelectedRobot::from_file(path)?);
        }
        Ok(SelectedRobot::builtin(
            match self.robot.unwrap_or(RobotChoice::Rspr) {
                RobotChoice::Rspr => BuiltinRobot::Rspr,
                RobotChoice::Usr => BuiltinRobot::Usr,
            },
        ))
    }
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Inverse kinematics: the joints q1..q6 of a pose on a branch.
    ///
    /// In: x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg, optionally branch (else --branch). Out:
    /// the input, then RSPR l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg or USR
    /// alpha1_deg,alpha2_deg,alpha3_deg,beta1_deg,beta2_deg,beta3_deg, then guards (ok, or
    /// the first limit of the worst severity broken, with its value and limit, under
    /// --limits) and error.
    Ik(ik::IkArgs),
    /// Forward kinematics: the pose of joints q1..q6 on a branch (Newton iteration).
    ///
    /// In: the joints (the names ik writes), optionally branch (else --branch) and the
    /// initial pose x0_mm..rz0_deg (absent or empty = [0, 0, hc], R = I). Out: the input,
    /// then x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,iterations, guards (the verdict on the pose
    /// found, as ik's) and error. Input columns named like an output column are echoed as
    /// in_<name>.
    Fk(fk::FkArgs),
    /// The Jacobian J = dq/dx (SI, rows in q order, columns [v; w]) and its conditioning.
    ///
    /// In: x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg, optionally branch (else --branch). Out:
    /// the input, then j11..j66 (row-major; m/m, m/rad, rad/m, rad/rad), inv_cond (of the
    /// tripod Jacobian with its moment columns divided by rp), guards (as ik's), error.
    Jacobian(jacobian::JacobianArgs),
    /// Actuator forces tau = J^-T s_e for a wrench the platform exerts on its environment.
    ///
    /// In: x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm, optionally
    /// branch (else --branch). Out: the input, then tau in q order (RSPR f1_n,f2_n,f3_n on
    /// the legs, t1_nm,t2_nm,t3_nm on the rotating links; USR t_alpha1_nm..t_beta3_nm),
    /// guards (as ik's), error.
    ///
    /// --path diagonal: the forces along a straight path at a fixed orientation (default
    /// the thesis's diagonal [-20,-20,-10] -> [20,20,10] mm about [0, 0, hc], 20 deg about
    /// [1,1,1], wrench 7,7,7,0.7,0.7,0.7); writes forces_path.csv (s, x_mm..rz_deg, RSPR
    /// f1_n..f3_n,t1_nm..t3_nm or USR t_alpha1_nm..t_beta3_nm, error) and forces_path.png
    /// to --out (default target/design/forces/).
    Forces(design::ForcesCommandArgs),
    /// Serial and parallel singularity measures and the nearest singularity.
    ///
    /// In: x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch. Out: the input, then RSPR
    /// serial1_mm..serial3_mm (|Cn2_i|) or USR serial1_mm2..serial3_mm2
    /// (|Cn1 Cr2 - Cr1 Cn2|), serial1_frac..serial3_frac (over rb, or l1^2),
    /// parallel_inv_cond, det_sign, nearest (parallel or serial:N), then the line
    /// geometry of thesis chapter 10: rank (of the six Plücker lines of the tripod
    /// Jacobian), circuits (every minimal dependent subset as variety:lines, e.g. 3D:1245),
    /// configurations (the S1..S13 of Table 10.3 whose conditions hold), complex (5A or 5B
    /// at rank 5), gained (the twists the platform gains: twist=(v; rp*w) unit,
    /// pitch_mm, axis_mm relative to o_p), serial1_case..serial3_case (RSPR a..d of Eq.
    /// 10.6, USR A..F of Eq. 10.11, joined by +), error.
    Singularity(singularity::SingularityArgs),
    /// The pose nearest each singular configuration S1..S13 (thesis Table 10.3) over a
    /// task box.
    ///
    /// Out: a comment line, then CSV configuration,residual,which,x_mm..rz_deg,pose: the
    /// smallest residual of the configuration's condition over the grid (lengths over rp,
    /// sines of angles, singular values; 0 at the configuration), the index set that gives
    /// it (e.g. S9(1,2)) and the pose where it is smallest.
    SingularityScan(singularity::SingularityScanArgs),
    /// A readable report of the robot over the thesis's task box.
    ///
    /// Dimensions, the inverse kinematics of the central pose on all 8 branches, the
    /// measures and forces at the central pose, and over the task box (branch 0, platform
    /// parallel and tilted) the joint ranges, Jacobian conditioning, serial margins,
    /// spherical-joint tilt, actuator force ranges and every pose that failed.
    Report(design::ReportArgs),
    /// The guards' verdict at a pose, or the worst margins over the thesis's task box.
    ///
    /// Single pose or batch: in x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch; out the input,
    /// then ok (true unless a stop-level guard is violated), severity (empty, warn or
    /// stop), violations (guard:subject:value:limit;... in mm, deg, N, N m or as is for
    /// dimensionless measures) and error. A computed verdict exits 0 whatever it says;
    /// only bad input fails.
    ///
    /// --task-box: every static guard's worst margin over the task box (40 x 40 x 20 mm
    /// at [0, 0, hc], platform parallel and rotated +20 deg about [1,1,0]), where it
    /// occurs, the counts of grid points with stop and warn violations, and a conclusion.
    /// The limits come from --limits FILE or the reference limits.
    Check(check::CheckArgs),
    /// The closed-loop simulation: the board's controller against the plant model.
    ///
    /// Runs a scenario (laparoscope, step, box-sweep, payload, backlash-off, or all) with
    /// the controller at control.rate_hz and the plant at least 10x faster, the tool's
    /// weight mapped to the joints, and writes summary.json, trace.csv, path.png,
    /// errors.png and scene.mcap (the run's 3-D scene for Foxglove, the channels of `view`)
    /// (default target/sim/<scenario>/). Settings:
    /// host-sim/simulation/default.toml.
    Sim(sim::SimArgs),
    /// The columns of thesis Tables 8.2/8.3 over the task box: joint min, max and span,
    /// spherical-joint tilt, USR gamma_i and delta_i, actuator force and torque ranges.
    ///
    /// The task: the 40 x 40 x 20 mm box at [0, 0, hc], platform parallel and rotated
    /// +20 deg about [1,1,0], wrench 7,7,7,0.7,0.7,0.7. A table per quantity (parallel,
    /// rotated and both); --csv for quantity,orientation,min,max,span,poses.
    Ranges(design::RangesArgs),
    /// Constant-height sections of the reachable workspace at the task orientations.
    ///
    /// Thesis section 8.4: for each height z and direction phi, the largest radius rho_max
    /// with a guard-admissible solution (no stop-level violation, the workspace guard
    /// excluded). Writes workspace.csv (orientation, rx_deg..rz_deg, z_mm, phi_deg,
    /// rho_max_mm), sections_parallel.png / sections_rotated.png and the 3-D views of the
    /// boundary boundary_parallel.png / boundary_rotated.png to --out (default
    /// target/design/workspace/), states whether the task box footprint lies inside each
    /// section, and whether the whole task box (a 2 mm grid at both orientations) lies
    /// inside the workspace.
    Workspace(design::WorkspaceArgs),
    /// Dimensional synthesis scan (thesis section 8.2) for the selected robot's kind.
    ///
    /// The task, the scan ranges and the bounds come from a TOML task file (--task FILE;
    /// default host-sim/design/tasks/thesis.toml, embedded; absent keys keep its values); the
    /// scan ranges may be overridden (RSPR --e-mm --rb-mm --rp-mm --hc-mm; USR --e-mm
    /// --rp-mm --l1-mm --l2-mm --hc-mm, each FROM,TO,STEP). Every robot of the grid is
    /// evaluated over the task on every core (--jobs N) and kept when it meets the
    /// requirements (task solved, no singularity measure below its level, forces, torques,
    /// tilt, RSPR actuator length and stroke; USR alpha, gamma, delta ranges). Writes
    /// synth.csv (every robot in scan order: dimensions, size, verdict, first unmet bound,
    /// each quantity's min and max), admissible.csv and admissible.md (the admissible
    /// robots ranked by size with the columns of Tables 8.2/8.3) to --out (default
    /// target/design/synth/), and says whether the reference robot is admissible or which
    /// bound it misses; progress bar on a terminal.
    Synth(design::SynthArgs),
    /// The RSPR with zero eccentricity against the RRPS robot (thesis Appendix A, Fig. 4.4).
    ///
    /// Both robots with the selected RSPR's rb, rp, hc and e = 0, along the thesis's
    /// diagonal [-20,-20,-10] -> [20,20,10] mm about [0, 0, hc], 20 deg about [1,1,1],
    /// wrench 7,7,7,0.7,0.7,0.7: prints the peak leg forces and rotary torques side by side
    /// and the ratio of the peak rotary torques; writes compare.csv (s, x_mm..rz_deg,
    /// rspr_f1_n..rspr_t3_nm, rrps_f1_n..rrps_t3_nm, error) and compare.png to --out
    /// (default target/design/compare/).
    Compare(design::CompareArgs),
    /// The double circular-triangular robot of thesis Appendix A (Table 4.1's "double
    /// planar"): two planar circle-triangle mechanisms, U joints, a prismatic and a
    /// helical joint on the output link.
    ///
    /// Without --pose: the appendix's evaluation (the task box about the central
    /// configuration, the 200 mm envelope, the slider forces along the diagonal against
    /// the reference RSPR's leg forces, and the thesis's conclusion checked). With --pose
    /// (x_mm..rz_deg of the tool point): the joints (arc length along the circle, mm, and
    /// the slider angle, deg; lower mechanism first), the triangles' poses, J = dq/dx (SI)
    /// and the sliders' forces for --wrench at the screw's --eta. The geometry flags do not
    /// apply (the robot is Table 4.1's).
    Dct(design::DctArgs),
    /// The host master of the board: hello, home, enable, stream a path with heartbeats,
    /// record the status telemetry and print a summary (tracking, refusals, link counters).
    ///
    /// --connect: a Unix socket (the board emulator's or the simulated board's `serve
    /// --socket PATH`) or a serial device. --scenario ci adds the checks of the CI run
    /// (refused target, garbage on the link, heartbeat loss) and exits non-zero when one
    /// fails. Writes status.csv to --out (default target/teleop/<scenario>/).
    Teleop(teleop::TeleopArgs),
    /// The fault-injection campaign: every fault kind in every condition against the whole
    /// board application in simulation.
    ///
    /// Each cell: detected or not, the time to detect against the kind's bound, the
    /// reaction against the stop table's, and how far the platform moved afterwards
    /// against the stops' bounds (0.5 mm after STO; 0.1 mm beyond the braking travel after
    /// SS1/SS2; within 1 mm of the setpoint when the board continues). Prints the matrix,
    /// writes campaign.csv and campaign.png to --out (default target/faults/), and exits
    /// non-zero when a cell fails.
    Faults(board::FaultsArgs),
    /// A recorded teleoperation session (MCAP, `teleop --device`): prints its summary (with
    /// the latency figures) and writes its plots: input.png, position.png,
    /// orientation.png, lag.png, margins.png (default target/replay/<file stem>/).
    Replay(operator::ReplayArgs),
    /// The operator's console: a terminal UI (80x24 and larger) showing the board's state,
    /// stop, faults, poses, joints, margins, link counters and tick timing live, with keys
    /// for hello, home (re-homing confirmed), enable, disable, clear fault, stop, jog,
    /// clutch and dead-man; every command shows the board's reply.
    Console(operator::ConsoleArgs),
    /// OpenIGTLink (versions 2 and 3) for 3D Slicer, PLUS and trackers: TRANSFORM or
    /// POSITION to device Target are pose targets (platform frame {p} in the robot base {0},
    /// mm, or in the client frame with --registration) through the board's supervisor; the
    /// measured pose is streamed as TRANSFORM from device Robot, the state as STATUS and
    /// STRING; GET_ requests are answered.
    Igtl(operator::IgtlArgs),
    /// ROS 2 with CRTK names (no ROS installation needed): measured_cp, setpoint_cp
    /// (PoseStamped), measured_js, setpoint_js (JointState), /joint_states (every joint of
    /// the URDF of `describe --urdf`, passive ones computed) and /tf (the URDF's tree) at
    /// 100 Hz, operating_state (crtk_msgs/OperatingState), diagnostics (the latched fault,
    /// the guard margins) and refusal (a refused command and its reason); servo_cp
    /// (PoseStamped: a target through the board's supervisor), servo_jp (JointState: the
    /// six actuated joints, their forward kinematics a target) and state_command (enable,
    /// disable, home, pause, resume) subscribed. DDS stays on the loopback unless --network
    /// says otherwise.
    Ros2(ros2::Ros2Args),
    /// The simulated board (the board application on the plant) on a Unix socket, its
    /// virtual clock paced by the wall clock and by its masters (it pauses, never jumps,
    /// when the host falls behind), for `teleop`, the console, `igtl` and `faultlog`.
    Board(board::BoardArgs),
    /// The fault log and the non-volatile event log of a board (or the simulated board, or
    /// the emulator), read over its link: time, cause, joint, value, the stop it caused,
    /// repeats, the last reset; then every event the flash kept (faults, stops, resets,
    /// masters, geometries, the relay test) with its boot and time, in plain words.
    Faultlog(board::FaultLogArgs),
    /// Commissioning a robot just built: the board's commissioning mode tests each joint's
    /// wiring (motor and encoder direction, swapped encoders, counts per unit against the
    /// second channel, home switch, brake, current sense, driver fault line) with the others
    /// braked, at most 3 mm or 3 deg of travel; prints each finding with its fix in words and
    /// writes report.txt, board-profile.toml (the gear ratios measured) and wiring.toml (the
    /// signs for the pin map) to --out (default target/commission/).
    Commission(commission::CommissionArgs),
    /// Kinematic calibration from external measurements.
    ///
    /// --measurements FILE.csv: joint readings paired with the marker pose (or position)
    /// a tracker measured; identifies the per-chain geometry with the tracker-to-base and
    /// marker-to-platform transforms (Levenberg-Marquardt over the combinations the SVD
    /// of the identification Jacobian determines, --robust for outliers), prints the
    /// residuals before and after and the identifiability, and writes calibrated.toml
    /// (use it with --geometry), report.txt, residuals.csv and residuals.png (default
    /// target/calibration/). `calibrate plan`: the poses to measure. `calibrate
    /// simulate`: the proof on a simulated robot and tracker.
    Calibrate(calibrate::CalibrateArgs),
    /// Per-joint identification and servo tuning on the simulated plant.
    ///
    /// One joint (--joint), the others braked: a duty staircase within the test's travel
    /// (3 mm, 5 deg) and effort (110 N, 0.25 N m), designed on the nominal parameters;
    /// from the recorded duty, current and encoder (and the second position channel) the
    /// least-squares estimates of the reflected inertia, viscous and Coulomb friction,
    /// torque constant times gear, circuit resistance and inductance and backlash, each
    /// with one sigma and beside the plant's true value; the PID and feed-forward gains
    /// for --crossover-hz and --phase-margin-deg (loop shaping on the sampled identified
    /// model); the step response predicted on the identified model and measured on the
    /// plant, both through the board's servo. --seed N: a plant whose parameters are drawn
    /// within --spread-pct of nominal.
    Identify(identify::IdentifyArgs),
    /// The robot description (URDF) of the geometry in use, and its joint states.
    ///
    /// --urdf: the base, the three rotating (USR: lower) links, the spherical joints, the
    /// legs (cylinder and piston; USR: upper links), the platform pins and the platform as
    /// primitives at the geometry's dimensions, for RViz, Foxglove and Slicer; the closed
    /// chains as a tree (the platform hangs off chain 1; every passive joint follows
    /// /joint_states). --out PATH writes it to a file, else to stdout. --joint-states:
    /// every joint's value for actuated joints read as CSV (see its flag).
    Describe(describe::DescribeArgs),
    /// The live 3-D view of a board for Foxglove (read-only): the robot description, its
    /// transforms, the measured and setpoint poses, the joints, the guard margins and the
    /// latched fault from the board's status stream, on the Foxglove SDK's WebSocket
    /// server (--listen, default 127.0.0.1:8765; --record FILE.mcap records the same).
    View(view::ViewArgs),
}

impl Command {
    /// Runs the subcommand on the selected robot with the selected limits.
    pub fn run(&self, selected: &SelectedRobot, limits: &SelectedLimits) -> Result<(), CliError> {
        let robot = &selected.robot;
        match self {
            Command::Ik(args) => Ok(ik::run(args, robot, &limits.limits)?),
            Command::Fk(args) => Ok(fk::run(args, robot, &limits.limits)?),
            Command::Jacobian(args) => Ok(jacobian::run(args, robot, &limits.limits)?),
            Command::Forces(args) => design::forces(args, robot, &limits.limits),
            Command::Singularity(args) => Ok(singularity::run(args, robot)?),
            Command::SingularityScan(args) => Ok(singularity::run_scan(args, robot)?),
            Command::Report(args) => design::report(args, selected),
            Command::Check(args) => Ok(check::run(args, selected, limits)?),
            Command::Sim(args) => sim::run(args, selected, limits),
            Command::Ranges(args) => design::ranges(args, selected),
            Command::Workspace(args) => design::workspace(args, robot, limits),
            Command::Synth(args) => design::synth(args, robot.kind()),
            Command::Compare(args) => design::compare(args, robot),
            Command::Dct(args) => design::dct(args),
            Command::Teleop(args) => teleop::run(args, selected, &limits.limits),
            Command::Faults(args) => board::faults(args),
            Command::Board(args) => board::board(args),
            Command::Replay(args) => operator::replay(args),
            Command::Console(args) => operator::console(args),
            Command::Igtl(args) => operator::igtl(args),
            Command::Ros2(args) => ros2::run(args, selected, &limits.limits),
            Command::Faultlog(args) => board::faultlog(args),
            Command::Commission(args) => commission::commission(args),
            Command::Calibrate(args) => calibrate::run(args, selected, limits),
            Command::Identify(args) => identify::run(args),
            Command::Describe(args) => describe::run(args, selected, &limits.limits),
            Command::View(args) => view::run(args, selected, &limits.limits),
        }
    }
}

/// `--key-file`: the master link's pre-shared key.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct KeyArgs {
    /// The master link's pre-shared key: a file of 64 hexadecimal digits (32 bytes), for a
    /// board whose link leaves the desk; every frame then carries an HMAC-SHA256 tag, and
    /// frames without a valid one are dropped. Without it the link carries no tags (a
    /// board on a desk). The key is never printed.
    #[arg(long, value_name = "PATH")]
    pub key_file: Option<std::path::PathBuf>,
}

impl KeyArgs {
    /// The key, read from its file, if one was given.
    pub fn key(&self) -> Result<Option<master_link::LinkKey>, crate::error::CliError> {
        self.key_file
            .as_deref()
            .map(::teleop::link::read_key_file)
            .transpose()
            .map_err(crate::error::CliError::from)
    }
}
