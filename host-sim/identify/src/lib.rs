//! # identify: per-joint identification and servo tuning
//!
//! For one joint of the robot, with the others braked: the breakaway duty in each
//! direction (a slow duty ramp until the encoder moves, [`rig::JointRig::breakaway`]), a
//! bounded excitation the board applies one duty per control period ([`excitation`]),
//! the estimates of the joint's
//! reflected inertia, viscous and Coulomb friction, torque constant times gear, circuit
//! resistance and inductance and (with the second position channel) backlash, each with
//! its standard deviation, from the recorded duty, current and encoder position
//! ([`estimate`], least squares with covariance, [`lsq`]), the PID and feed-forward gains
//! of the board's servo for a stated crossover and phase margin on the identified model
//! ([`tuning`], loop shaping on the sampled loop), and the step response those gains give,
//! predicted on the identified model and measured on the joint ([`response`]).
//!
//! Everything runs here against the plant model ([`rig`]: the plant's own joint model
//! behind the board's PWM, encoder, current sense and servo code); the commissioning mode
//! of the board applies the same excitation and hands the same recording to
//! [`estimate::identify`].
//!
//! Units: SI in joint units (m, N on a leg; rad, N m on a link), `f64` (host side).
//! Joint order and names as everywhere (CONVENTIONS.md, Joints).

pub mod error;
pub mod estimate;
pub mod excitation;
pub mod lsq;
pub mod perturb;
pub mod recording;
pub mod response;
pub mod rig;
pub mod tuning;

pub use error::IdentifyError;
pub use estimate::{identify, Identified};
pub use excitation::{Excitation, ExcitationDesign, ExcitationLimits, Prior};
pub use lsq::Estimate;
pub use recording::{Recording, Sample};
pub use response::{StepResponse, Tracking};
pub use rig::{JointRig, Watch};
pub use tuning::{Tuning, TuningSpec};

use board_profile::BoardProfile;
use plant::{JointKind, Plant, PlantConfig};
use servo::PidGains;

/// The settings of one identification and tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// The test's travel and effort bounds.
    pub limits: ExcitationLimits,
    /// The staircase's layout.
    pub design: ExcitationDesign,
    /// The loop's crossover and margin.
    pub spec: TuningSpec,
    /// The step of the step response, m or rad.
    pub step: f64,
    /// The step response's length, s.
    pub step_duration_s: f64,
}

impl Settings {
    /// The defaults of a joint kind: [`ExcitationLimits::for_kind`],
    /// [`ExcitationDesign::default`], [`TuningSpec::default_for`]; a step of 0.5 mm on a
    /// leg and 1 deg on a link (within the servo's following-error windows, 1 mm and
    /// 1.15 deg), watched for 0.6 s.
    pub fn for_kind(kind: JointKind) -> Self {
        Settings {
            limits: ExcitationLimits::for_kind(kind),
            design: ExcitationDesign::default(),
            spec: TuningSpec::default_for(kind),
            step: match kind {
                JointKind::Prismatic => 0.5e-3,
                JointKind::Rotary => 1f64.to_radians(),
            },
            step_duration_s: 0.6,
        }
    }
}

/// The servo's default gains of a joint kind (the reference gains).
pub fn reference_gains(kind: JointKind) -> PidGains<f64> {
    match kind {
        JointKind::Prismatic => PidGains::leg(),
        JointKind::Rotary => PidGains::link(),
    }
}

/// Joint `joint` of the plant `config` on the bench, as the board `profile` reads it:
/// at the middle of its second position channel's travel (where the test starts), with
/// the channel when `position_channel`.
pub fn rig_of(
    config: &PlantConfig,
    profile: &BoardProfile,
    joint: usize,
    position_channel: bool,
) -> Result<JointRig, IdentifyError> {
    let plant = Plant::new(config).map_err(|e| IdentifyError::Plant(e.to_string()))?;
    let j = plant
        .joint(joint)
        .map_err(|_| IdentifyError::NoSuchJoint(joint))?;
    let jp = profile
        .joints
        .get(joint)
        .ok_or(IdentifyError::NoSuchJoint(joint))?;
    let sensor = plant
        .position_sensor(joint)
        .map_err(|_| IdentifyError::NoSuchJoint(joint))?
        .clone();
    JointRig::new(
        joint,
        *j.model(),
        config.encoder.counts_per_rev(),
        jp.counts_per_unit(),
        profile.period_s(),
        sensor.mid,
        position_channel.then_some(sensor),
    )
}

/// Everything one identification and tuning found.
#[derive(Debug, Clone)]
pub struct Report {
    /// The joint's name.
    pub joint: &'static str,
    /// The breakaway duties measured first (towards +q, -q).
    pub breakaway: [f64; 2],
    /// The excitation applied.
    pub excitation: Excitation,
    /// The largest excursion measured during it (the encoder), m or rad.
    pub measured_travel: f64,
    /// The largest excursion of the joint itself (its load side) over the breakaway and
    /// the excitation, braking to rest included (the plant's truth), m or rad.
    pub joint_excursion: f64,
    /// The largest current measured during it, A.
    pub measured_peak_current_a: f64,
    /// The estimates.
    pub identified: Identified,
    /// The gains and the margins they give on the model.
    pub tuning: Tuning,
    /// The step response predicted on the identified model.
    pub predicted: StepResponse,
    /// The step response measured on the joint.
    pub measured: StepResponse,
}

/// Identifies the joint of `rig` (designing the excitation on `prior`), tunes its servo
/// and predicts and measures the step response, as `settings` say. The rig itself is not
/// moved (each run works on a copy from its rest state).
pub fn identify_and_tune(
    rig: &JointRig,
    prior: &Prior,
    settings: &Settings,
) -> Result<Report, IdentifyError> {
    let mut bench = rig.clone();
    // The breakaway: a ramp of four times the prior's friction duty per second, until the
    // encoder has moved 3 counts, up to the effort limit's duty.
    let friction_duty = prior.coulomb / prior.force_per_duty();
    let max_duty = settings.limits.effort / prior.force_per_duty();
    let breakaway = bench.breakaway(4.0 * friction_duty, max_duty, 3, settings.limits.travel)?;
    let exc = excitation::design(
        prior,
        &settings.limits,
        &settings.design,
        rig.period_s(),
        Some(breakaway),
    )?;
    let rec = bench.record(&exc.duties, &exc.watch())?;
    let x0 = rec.position(0);
    let measured_travel = (0..rec.samples.len())
        .map(|k| (rec.position(k) - x0).abs())
        .fold(0.0, f64::max);
    let measured_peak_current_a = rec
        .samples
        .iter()
        .map(|s| s.current_a.abs())
        .fold(0.0, f64::max);
    let identified = identify(&rec)?;
    let base = reference_gains(rig.kind());
    let tuning = tuning::tune(&identified, &settings.spec, rig.period_s(), &base)?;
    let ticks = (settings.step_duration_s / rig.period_s()).ceil() as usize;
    let model = response::model_joint(&identified, rig.model());
    let model_rig = JointRig::new(
        rig.index(),
        model,
        rig.counts_per_rev(),
        rig.counts_per_unit(),
        rig.period_s(),
        rig.start_q(),
        None,
    )?;
    let (predicted, _) = response::step_response(&model_rig, &tuning.gains, settings.step, ticks)?;
    let (measured, _) = response::step_response(rig, &tuning.gains, settings.step, ticks)?;
    Ok(Report {
        joint: rig.name(),
        breakaway,
        excitation: exc,
        measured_travel,
        joint_excursion: bench.joint_excursion(),
        measured_peak_current_a,
        identified,
        tuning,
        predicted,
        measured,
    })
}
