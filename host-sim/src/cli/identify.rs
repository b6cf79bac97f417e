//! `host-sim identify` on the command line: one joint of the simulated plant (nominal, or
//! perturbed from a seed) identified and tuned by the `identify` crate, printed with the
//! plant's true values beside the estimates.

use crate::error::CliError;
use board_profile::BoardProfile;
use clap::Args;
use identify::perturb::perturbed;
use identify::{identify_and_tune, rig_of, Estimate, Prior, Report, Settings};
use plant::{JointKind, PlantConfig};

/// `host-sim identify` arguments.
#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// The joint: l1, l2, l3, theta1, theta2 or theta3.
    #[arg(long, default_value = "l1", value_name = "NAME")]
    pub joint: String,
    /// The plant: 0 the nominal one (the shipped plant file), else one whose parameters
    /// are drawn within --spread-pct of nominal from this seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// How far a seeded plant's parameters are from nominal, %.
    #[arg(long, default_value_t = 30.0)]
    pub spread_pct: f64,
    /// The servo loop's crossover, Hz [default: 25].
    #[arg(long)]
    pub crossover_hz: Option<f64>,
    /// The phase margin at the crossover, deg [default: 60].
    #[arg(long)]
    pub phase_margin_deg: Option<f64>,
    /// A leg's test travel, mm [default: 3].
    #[arg(long)]
    pub travel_mm: Option<f64>,
    /// A link's test travel, deg [default: 5].
    #[arg(long)]
    pub travel_deg: Option<f64>,
    /// Without the second position channel (no backlash estimate).
    #[arg(long)]
    pub no_position_channel: bool,
}

/// The edge units of a joint kind: (length or angle name, factor from SI, effort name,
/// mass name).
struct Units {
    pos: &'static str,
    pos_scale: f64,
    effort: &'static str,
    mass: &'static str,
}

fn units(kind: JointKind) -> Units {
    match kind {
        JointKind::Prismatic => Units {
            pos: "mm",
            pos_scale: 1e3,
            effort: "N",
            mass: "kg",
        },
        JointKind::Rotary => Units {
            pos: "deg",
            pos_scale: 180.0 / std::f64::consts::PI,
            effort: "N m",
            mass: "kg m^2",
        },
    }
}

fn row(name: &str, unit: &str, e: &Estimate, truth: f64, scale: f64) -> String {
    format!(
        "  {name:<24} {:>12.5e} +- {:<10.2e} {unit:<12} (plant {:>12.5e}, error {:+6.2} %, {:+5.1} sigma)",
        e.value * scale,
        e.std * scale,
        truth * scale,
        100.0 * (e.value / truth - 1.0),
        (e.value - truth) / e.std,
    )
}

/// Runs `host-sim identify`.
pub fn run(args: &IdentifyArgs) -> Result<(), CliError> {
    let joint = servo::JOINT_NAMES
        .iter()
        .position(|n| *n == args.joint)
        .ok_or_else(|| CliError::UnknownName {
            what: "joint (l1, l2, l3, theta1, theta2, theta3)",
            name: args.joint.clone(),
        })?;
    let nominal =
        PlantConfig::shipped().map_err(|e| identify::IdentifyError::Plant(e.to_string()))?;
    let plant = if args.seed == 0 {
        nominal.clone()
    } else {
        perturbed(&nominal, args.seed, args.spread_pct / 100.0)?
    };
    let profile = BoardProfile::REFERENCE;
    let rig = rig_of(&plant, &profile, joint, !args.no_position_channel)?;
    let prior = Prior::from_model(rig_of(&nominal, &profile, joint, false)?.model());
    let kind = rig.kind();
    let mut settings = Settings::for_kind(kind);
    if let Some(f) = args.crossover_hz {
        settings.spec.crossover_hz = f;
    }
    if let Some(p) = args.phase_margin_deg {
        settings.spec.phase_margin_deg = p;
    }
    match (kind, args.travel_mm, args.travel_deg) {
        (JointKind::Prismatic, Some(mm), None) => settings.limits.travel = mm * 1e-3,
        (JointKind::Rotary, None, Some(deg)) => settings.limits.travel = deg.to_radians(),
        (_, None, None) => {}
        (JointKind::Prismatic, _, Some(_)) => {
            return Err(CliError::Identify(identify::IdentifyError::Setting {
                name: "travel_deg",
                value: args.travel_deg.unwrap_or(f64::NAN),
                expected: "a leg's travel is --travel-mm",
            }))
        }
        (JointKind::Rotary, Some(mm), _) => {
            return Err(CliError::Identify(identify::IdentifyError::Setting {
                name: "travel_mm",
                value: mm,
                expected: "a link's travel is --travel-deg",
            }))
        }
    }
    let report = identify_and_tune(&rig, &prior, &settings)?;
    print!("{}", text(&report, &rig, args));
    Ok(())
}

fn text(r: &Report, rig: &identify::JointRig, args: &IdentifyArgs) -> String {
    let kind = rig.kind();
    let u = units(kind);
    let truth = Prior::from_model(rig.model());
    let id = &r.identified;
    let e = &r.excitation;
    let mut s = String::new();
    let plant = if args.seed == 0 {
        "the nominal plant".to_string()
    } else {
        format!(
            "a plant drawn within +-{} % of nominal, seed {}",
            args.spread_pct, args.seed
        )
    };
    s += &format!("identify {} on {plant}\n", r.joint);
    s += &format!(
        "breakaway duty {:.4} towards +q, {:.4} towards -q\n",
        r.breakaway[0], r.breakaway[1]
    );
    s += &format!(
        "excitation: duty staircase, {} segments of {} ms, speeds {:.3} / {:.3} / {:.3} {}/s, \
         duties {:.4} / {:.4} / {:.4} (+q); {} ticks\n",
        (e.duties.len() / e.segment_ticks.max(1)),
        e.segment_ticks,
        e.speeds[0] * u.pos_scale,
        e.speeds[1] * u.pos_scale,
        e.speeds[2] * u.pos_scale,
        u.pos,
        e.levels[0][0],
        e.levels[0][1],
        e.levels[0][2],
        e.duties.len()
    );
    s += &format!(
        "  travel {:.3} {} measured ({:.3} predicted, limit {:.3}); peak current {:.3} A \
         (limit {:.3} A)\n",
        r.measured_travel * u.pos_scale,
        u.pos,
        e.predicted_travel * u.pos_scale,
        e.travel_limit * u.pos_scale,
        r.measured_peak_current_a,
        e.current_limit_a
    );
    s += "estimates (one sigma):\n";
    let per = format!(
        "{}/{}",
        u.effort,
        if kind == JointKind::Prismatic {
            "(m/s)"
        } else {
            "(rad/s)"
        }
    );
    s += &row("inertia (reflected)", u.mass, &id.mass, truth.mass, 1.0);
    s += "\n";
    s += &row("viscous friction", &per, &id.viscous, truth.viscous, 1.0);
    s += "\n";
    s += &row(
        "Coulomb friction",
        u.effort,
        &id.coulomb,
        truth.coulomb,
        1.0,
    );
    s += "\n";
    s += &row(
        "torque const x gear",
        &format!("{}/A", u.effort),
        &id.force_per_amp,
        truth.force_per_amp,
        1.0,
    );
    s += "\n";
    s += &row(
        "circuit resistance",
        "ohm",
        &id.resistance,
        truth.resistance,
        1.0,
    );
    s += "\n";
    s += &format!(
        "  {:<24} {:>12.5e} +- {:<10.2e} {:<12} (plant {:>12.5e})\n",
        "circuit inductance",
        id.inductance.value * 1e3,
        id.inductance.std * 1e3,
        "mH",
        rig.model().motor.inductance * 1e3
    );
    if let Some(b) = &id.backlash {
        s += &row(
            "backlash",
            u.pos,
            b,
            rig.model().backlash.width,
            u.pos_scale,
        );
        s += "\n";
    }
    let g = &r.tuning.gains;
    s += &format!(
        "gains for {} Hz crossover, {} deg phase margin (loop shaping on the sampled \
         identified model):\n",
        args.crossover_hz.unwrap_or(25.0),
        args.phase_margin_deg.unwrap_or(60.0)
    );
    s += &format!(
        "  kp {:.5e}  ki {:.5e}  kd {:.5e}  kv {:.5e}  ka {:.5e}  friction_ff {:.5e} \
         (duty per SI joint unit)\n",
        g.kp, g.ki, g.kd, g.kv, g.ka, g.friction_ff
    );
    s += &format!(
        "  on the model: crossover {:.2} Hz, phase margin {:.1} deg, gain margin {:.1} dB\n",
        r.tuning.crossover_hz, r.tuning.phase_margin_deg, r.tuning.gain_margin_db
    );
    s += &format!(
        "step response, {:.3} {} step (settling to +-5 %):\n",
        r.predicted.amplitude * u.pos_scale,
        u.pos
    );
    for (what, sr) in [("predicted", &r.predicted), ("measured", &r.measured)] {
        s += &format!(
            "  {what:<10} overshoot {:6.2} %  settling {:7.1} ms  rise {:6.1} ms\n",
            100.0 * sr.overshoot,
            1e3 * sr.settling_time_s,
            1e3 * sr.rise_time_s
        );
    }
    s
}
