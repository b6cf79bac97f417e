//! The proof in simulation: a "true" robot perturbed within the tolerances, a tracker at an
//! unknown pose with an unknown marker on the platform, measurement noise; the controller
//! holds the nominal model. Reported over random poses of the task box that were not used
//! for the identification: the pose error before calibration (the nominal model, registered
//! to the tracker), after, and the limit the noise allows.
//!
//! **The pose error.** The controller commands x in its base frame: the joints are its
//! model's IK of x; the true robot at those joints is at X (FK of the true geometry); the
//! tracker sees the marker there, and the pose the system reports is that marker pose
//! brought back to the base frame through the identified transforms,
//! `base_in_tracker⁻¹ · tracker's marker pose · marker_in_platform⁻¹`. The error is that
//! pose against x: the accuracy of the robot registered to the tracker (the only frame
//! the measurements define; the base frame's placement is a free choice that the
//! tracker transform absorbs). With a **position-only** tracker the marker's orientation
//! on the platform is not observable, so the error is that of the tracked point (the
//! marker, e.g. a reflector at the tool tip): where the tracker sees it, brought back
//! through the base transform, against where the model puts it for the commanded pose;
//! no orientation error is reported.
//!
//! **The noise limit** is the error the tracker's noise alone leaves (Cramér-Rao): the
//! covariance of the identified combinations (the inverse of the information matrix over
//! the determined directions) propagated to each validation pose's error by the
//! sensitivities of that error; reported as the RMS and the largest of the per-pose
//! expected errors.
//!
//! **The joints** settle within half an encoder count of the commanded ones (uniform),
//! and the rows record the commanded counts, as a servo at rest reports them.

use crate::identify::{identify, Identification, Loss, Options};
use crate::measurements::Measurement;
use crate::model::Noise;
use crate::parameters::{self, leg_count_m, link_count_rad, Tolerances};
use crate::plan::{plan, PlanOptions};
use crate::rigid::Rigid;
use crate::CalibrationError;
use kinematics_core::guards::{Guards, Limits};
use kinematics_core::{
    forward, inverse, Branch, ChainDimensions, FkConfig, Joints, PerChainGeometry, Pose,
    RsprGeometry,
};
use nalgebra::{Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_xorshift::XorShiftRng;

/// A simulated calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// The seed of everything random.
    pub seed: u64,
    /// The tolerances the true robot is perturbed within (uniformly).
    pub tolerances: Tolerances,
    /// The tracker's noise (normal, per axis): the identification's weights.
    pub noise: Noise,
    /// The noise actually added to the readings, as a multiple of `noise` (1; 0 for
    /// noise-free readings).
    pub noise_scale: f64,
    /// Identification poses (chosen by [`plan`]).
    pub poses: usize,
    /// Validation poses (uniform in the task box, tilts up to 20 deg).
    pub validation: usize,
    /// The tracker measures positions only.
    pub position_only: bool,
    /// The loss of the identification.
    pub loss: Loss,
    /// Rows whose tracker reading is given a gross error: the position moved by
    /// [`Scenario::outlier_m`] along (5, -3, 4), the rotation turned by 2 deg about y.
    pub outliers: usize,
    /// How far an outlier's position is moved, m (default |(5, -3, 4)| mm = 7.07 mm).
    pub outlier_m: f64,
    /// The true base pose in the tracker's frame.
    pub base_in_tracker: Rigid,
    /// The true marker pose on the platform.
    pub marker_in_platform: Rigid,
    /// How far the marker's drawing (the identification's first guess) is from the truth:
    /// m and rad.
    pub marker_guess_error: (f64, f64),
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            seed: 19,
            tolerances: Tolerances::default(),
            noise: Noise::default(),
            noise_scale: 1.0,
            poses: 60,
            validation: 300,
            position_only: false,
            loss: Loss::Squared,
            outliers: 0,
            outlier_m: 50f64.sqrt() * 1e-3,
            // A tracker 1.2 m away, looking down at the robot.
            base_in_tracker: Rigid::new(
                Vector3::new(0.15, -0.25, 1.2),
                Vector3::new(2.9, 0.3, -0.4),
            ),
            marker_in_platform: Rigid::new(
                Vector3::new(0.021, -0.004, 0.032),
                Vector3::new(0.05, -0.08, 0.6),
            ),
            marker_guess_error: (2e-3, 2f64.to_radians()),
        }
    }
}

/// Pose errors over a set of poses.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseErrors {
    /// RMS of the position error of o_p, m.
    pub position_rms_m: f64,
    /// Largest position error, m.
    pub position_max_m: f64,
    /// RMS of the orientation error, rad.
    pub rotation_rms_rad: f64,
    /// Largest orientation error, rad.
    pub rotation_max_rad: f64,
}

impl PoseErrors {
    fn of(errors: &[(f64, f64)]) -> Self {
        let n = errors.len().max(1) as f64;
        PoseErrors {
            position_rms_m: (errors.iter().map(|e| e.0 * e.0).sum::<f64>() / n).sqrt(),
            position_max_m: errors.iter().map(|e| e.0).fold(0.0, f64::max),
            rotation_rms_rad: (errors.iter().map(|e| e.1 * e.1).sum::<f64>() / n).sqrt(),
            rotation_max_rad: errors.iter().map(|e| e.1).fold(0.0, f64::max),
        }
    }
}

/// What a simulated calibration gives.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The true robot.
    pub truth: PerChainGeometry<f64>,
    /// The measurements.
    pub rows: Vec<Measurement>,
    /// The identification.
    pub identification: Identification,
    /// The validation poses.
    pub validation: Vec<Pose<f64>>,
    /// Per validation pose (position m, rotation rad): before, after.
    pub errors_before: Vec<(f64, f64)>,
    pub errors_after: Vec<(f64, f64)>,
    /// Per validation pose, the expected error the noise leaves (position m, rotation rad).
    pub errors_limit: Vec<(f64, f64)>,
    /// Summaries.
    pub before: PoseErrors,
    pub after: PoseErrors,
    pub limit: PoseErrors,
    /// The plan's observability index and that of a random set.
    pub plan_index: (f64, f64),
}

fn uniform(rng: &mut XorShiftRng, half: f64) -> f64 {
    if half > 0.0 {
        rng.random_range(-half..half)
    } else {
        0.0
    }
}

/// A direction tilted from `v` by up to `angle` (uniform about it).
fn tilt(rng: &mut XorShiftRng, v: &Vector3<f64>, angle: f64) -> Vector3<f64> {
    let (e1, e2) = parameters::tilt_basis(v);
    let a = rng.random_range(0.0..std::f64::consts::TAU);
    let t = rng.random_range(0.0..angle.max(f64::MIN_POSITIVE));
    Rotation3::from_scaled_axis((e1 * a.cos() + e2 * a.sin()) * t) * v
}

/// The nominal robot perturbed within `tol`, uniformly: every position and length by up to
/// the length tolerance per component, every axis by up to the axis tolerance, every
/// encoder zero by up to its counts.
pub fn true_robot(
    nominal: &RsprGeometry<f64>,
    tol: &Tolerances,
    rng: &mut XorShiftRng,
) -> Result<PerChainGeometry<f64>, CalibrationError> {
    let sym = PerChainGeometry::from(*nominal);
    let l = tol.length_m;
    let mut chains = *sym.chains();
    for d in chains.0.iter_mut() {
        let mut jitter =
            |v: Vector3<f64>| v + Vector3::new(uniform(rng, l), uniform(rng, l), uniform(rng, l));
        let base_pivot = jitter(d.base_pivot);
        let platform_joint = jitter(d.platform_joint);
        *d = ChainDimensions {
            base_pivot,
            base_axis: tilt(rng, &d.base_axis, tol.axis_rad),
            link_length: d.link_length + uniform(rng, l),
            platform_joint,
            platform_axis: tilt(rng, &d.platform_axis, tol.axis_rad),
            leg_offset: uniform(rng, l),
            leg_zero: uniform(rng, tol.zero_counts * leg_count_m()),
            link_zero: uniform(rng, tol.zero_counts * link_count_rad()),
        };
    }
    PerChainGeometry::new(*nominal, chains).map_err(CalibrationError::Geometry)
}

/// Random poses in the task box about [0, 0, hc] with tilts up to 20 deg that pass the
/// guards on `robot`.
pub fn validation_poses(
    robot: &PerChainGeometry<f64>,
    n: usize,
    rng: &mut XorShiftRng,
) -> Result<Vec<Pose<f64>>, CalibrationError> {
    let guards = Guards::new(*robot, Branch::OUTER, Limits::reference())
        .map_err(|_| CalibrationError::NoCandidates)?;
    let hc = robot.nominal().hc;
    let mut out = Vec::with_capacity(n);
    let mut tries = 0;
    while out.len() < n && tries < 100 * n {
        tries += 1;
        let t = Vector3::new(
            uniform(rng, 0.02),
            uniform(rng, 0.02),
            hc + uniform(rng, 0.01),
        );
        let a = rng.random_range(0.0..std::f64::consts::TAU);
        let angle = rng.random_range(0.0..20f64.to_radians());
        let rv = Vector3::new(a.cos(), a.sin(), 0.0) * angle;
        let Ok(pose) = Pose::from_position_rotation_vector(t, rv) else {
            continue;
        };
        let (verdict, sol) = guards.check_pose(&pose);
        if sol.is_some() && !verdict.is_stop() {
            out.push(pose);
        }
    }
    Ok(out)
}

/// The tracker's rows at the commanded poses `x` (the controller's `model` gives the
/// joints, the `truth` is where the platform goes).
#[allow(clippy::too_many_arguments)]
pub fn measure(
    model: &PerChainGeometry<f64>,
    truth: &PerChainGeometry<f64>,
    base_in_tracker: &Rigid,
    marker_in_platform: &Rigid,
    poses: &[Pose<f64>],
    noise: &Noise,
    position_only: bool,
    rng: &mut XorShiftRng,
) -> Result<Vec<Measurement>, CalibrationError> {
    let np = Normal::new(0.0, noise.position_m).map_err(|error| CalibrationError::Noise {
        what: "position",
        error,
    })?;
    let nr = Normal::new(0.0, noise.rotation_rad).map_err(|error| CalibrationError::Noise {
        what: "rotation",
        error,
    })?;
    let cfg = FkConfig::default();
    let mut rows = Vec::with_capacity(poses.len());
    for (k, x) in poses.iter().enumerate() {
        let q = inverse(model, x, Branch::OUTER)
            .map_err(|error| CalibrationError::Ik { row: k + 1, error })?
            .q();
        let mut settled: Joints<f64> = q;
        for i in 0..6 {
            let count = if i < 3 {
                leg_count_m()
            } else {
                link_count_rad()
            };
            settled[i] += uniform(rng, 0.5 * count);
        }
        let at = forward(truth, &settled, Branch::OUTER, x, &cfg)
            .map_err(|error| CalibrationError::Fk { row: k + 1, error })?;
        let seen = base_in_tracker
            .then(&Rigid::from_pose(&at.pose))
            .then(marker_in_platform);
        let dp = Vector3::new(np.sample(rng), np.sample(rng), np.sample(rng));
        let dr = Vector3::new(nr.sample(rng), nr.sample(rng), nr.sample(rng));
        rows.push(Measurement {
            joints: q,
            position: seen.t + dp,
            rotation: (!position_only).then(|| {
                crate::rigid::rotation_vector(&(Rotation3::from_scaled_axis(dr) * seen.r))
            }),
            label: Some(format!("pose {}", k + 1)),
        });
    }
    Ok(rows)
}

/// The error of each commanded pose (position m, rotation rad) with the controller on
/// `model` and the pose read back through the transforms `a` and `b` (see the module
/// documentation).
#[allow(clippy::too_many_arguments)]
pub fn pose_errors(
    model: &PerChainGeometry<f64>,
    a: &Rigid,
    b: &Rigid,
    truth: &PerChainGeometry<f64>,
    true_a: &Rigid,
    true_b: &Rigid,
    poses: &[Pose<f64>],
    position_only: bool,
) -> Result<Vec<(f64, f64)>, CalibrationError> {
    Ok(
        pose_error_vectors(model, a, b, truth, true_a, true_b, poses, position_only)?
            .iter()
            .map(|(dp, dr)| (dp.norm(), dr.norm()))
            .collect(),
    )
}

/// Error vectors of poses: position (m), rotation vector (rad).
type ErrorVectors = Vec<(Vector3<f64>, Vector3<f64>)>;

/// The error vectors (position m, rotation vector rad) of [`pose_errors`].
#[allow(clippy::too_many_arguments)]
fn pose_error_vectors(
    model: &PerChainGeometry<f64>,
    a: &Rigid,
    b: &Rigid,
    truth: &PerChainGeometry<f64>,
    true_a: &Rigid,
    true_b: &Rigid,
    poses: &[Pose<f64>],
    position_only: bool,
) -> Result<ErrorVectors, CalibrationError> {
    let cfg = FkConfig::default();
    let back = a.inverse();
    let unmark = b.inverse();
    poses
        .iter()
        .enumerate()
        .map(|(k, x)| {
            let q = inverse(model, x, Branch::OUTER)
                .map_err(|error| CalibrationError::Ik { row: k + 1, error })?
                .q();
            let at = forward(truth, &q, Branch::OUTER, x, &cfg)
                .map_err(|error| CalibrationError::Fk { row: k + 1, error })?;
            let actual = Rigid::from_pose(&at.pose);
            if position_only {
                let seen = back.then(true_a).then(&actual).then(true_b).t;
                let wanted = x.r * b.t + x.t;
                return Ok((seen - wanted, Vector3::zeros()));
            }
            let seen = back.then(true_a).then(&actual).then(true_b).then(&unmark);
            Ok((
                seen.t - x.t,
                crate::rigid::rotation_vector(&(seen.r * x.r.inverse())),
            ))
        })
        .collect()
}

/// The marker's drawing: off the true marker by the scenario's stated error, in a random
/// direction and about a random axis.
fn marker_drawing(s: &Scenario, rng: &mut XorShiftRng) -> Rigid {
    let dir = tilt(rng, &Vector3::z(), std::f64::consts::PI);
    let axis = tilt(rng, &Vector3::x(), std::f64::consts::PI);
    Rigid {
        t: s.marker_in_platform.t + dir * s.marker_guess_error.0,
        r: Rotation3::from_scaled_axis(axis * s.marker_guess_error.1) * s.marker_in_platform.r,
    }
}

/// Spoils `count` of the rows (spread over them): the marker moved by `distance_m` along
/// (5, -3, 4) and turned by 2 deg about y.
fn add_outliers(rows: &mut [Measurement], count: usize, distance_m: f64) {
    let shift = Vector3::new(5.0, -3.0, 4.0).normalize() * distance_m;
    for k in 0..count.min(rows.len()) {
        let i = (k * 7919 + 3) % rows.len();
        if let Some(row) = rows.get_mut(i) {
            row.position += shift;
            row.rotation = row
                .rotation
                .map(|r| r + Vector3::new(0.0, 2f64.to_radians(), 0.0));
        }
    }
}

/// Runs a simulated calibration.
pub fn run(s: &Scenario) -> Result<Outcome, CalibrationError> {
    let mut rng = XorShiftRng::seed_from_u64(s.seed);
    let nominal_rspr = RsprGeometry::reference();
    let nominal = PerChainGeometry::from(nominal_rspr);
    let truth = true_robot(&nominal_rspr, &s.tolerances, &mut rng)?;
    let guess = marker_drawing(s, &mut rng);
    let plan_opts = PlanOptions {
        poses: s.poses,
        position_only: s.position_only,
        noise: s.noise,
        tolerances: s.tolerances,
        marker_in_platform: guess,
        ..PlanOptions::default()
    };
    let plan = plan(&nominal, &plan_opts)?;
    let mut rows = measure(
        &nominal,
        &truth,
        &s.base_in_tracker,
        &s.marker_in_platform,
        &plan.poses,
        &Noise {
            position_m: s.noise.position_m * s.noise_scale,
            rotation_rad: s.noise.rotation_rad * s.noise_scale,
        },
        s.position_only,
        &mut rng,
    )?;
    add_outliers(&mut rows, s.outliers, s.outlier_m);
    let opts = Options {
        tolerances: s.tolerances,
        noise: s.noise,
        loss: s.loss,
        ..Options::default()
    };
    let id = identify(&nominal, &rows, guess, &opts)?;
    let validation = validation_poses(&nominal, s.validation, &mut rng)?;
    let (ta, tb) = (&s.base_in_tracker, &s.marker_in_platform);
    let errors_before = pose_errors(
        &nominal,
        &id.registered.0,
        &id.registered.1,
        &truth,
        ta,
        tb,
        &validation,
        s.position_only,
    )?;
    let errors_after = pose_errors(
        &id.geometry,
        &id.base_in_tracker,
        &id.marker_in_platform,
        &truth,
        ta,
        tb,
        &validation,
        s.position_only,
    )?;
    let errors_limit = noise_limit(&id, &nominal, &truth, ta, tb, &validation, s)?;
    Ok(Outcome {
        before: PoseErrors::of(&errors_before),
        after: PoseErrors::of(&errors_after),
        limit: PoseErrors::of(&errors_limit),
        truth,
        rows,
        identification: id,
        validation,
        errors_before,
        errors_after,
        errors_limit,
        plan_index: (
            plan.identifiability.observability_index,
            plan.random_observability_index,
        ),
    })
}

/// The expected error (position m, rotation rad) the tracker's noise leaves at each pose:
/// Σ_k (∂e/∂z_k)² / σ_k² over the determined directions z_k of the identification.
fn noise_limit(
    id: &Identification,
    nominal: &PerChainGeometry<f64>,
    truth: &PerChainGeometry<f64>,
    ta: &Rigid,
    tb: &Rigid,
    poses: &[Pose<f64>],
    s: &Scenario,
) -> Result<Vec<(f64, f64)>, CalibrationError> {
    let infos = parameters::infos(&s.tolerances);
    let reference_a = id.reference_transforms.0;
    let reference_b = id.reference_transforms.1;
    let at = |delta: &[f64]| -> Result<ErrorVectors, CalibrationError> {
        let g = parameters::geometry(nominal, delta).map_err(CalibrationError::Geometry)?;
        let a = parameters::transform(&reference_a, delta, parameters::TRACKER);
        let b = parameters::transform(&reference_b, delta, parameters::MARKER);
        pose_error_vectors(&g, &a, &b, truth, ta, tb, poses, s.position_only)
    };
    let mut var = vec![(0.0, 0.0); poses.len()];
    let h = 1e-2;
    for (c, sv) in id.determined_singular_values.iter().enumerate() {
        let step: Vec<f64> = infos
            .iter()
            .enumerate()
            .map(|(j, info)| id.basis[(j, c)] * info.scale * h)
            .collect();
        let plus: Vec<f64> = id.delta.iter().zip(&step).map(|(d, s)| d + s).collect();
        let minus: Vec<f64> = id.delta.iter().zip(&step).map(|(d, s)| d - s).collect();
        let (ep, em) = (at(&plus)?, at(&minus)?);
        for ((v, p), m) in var.iter_mut().zip(&ep).zip(&em) {
            let dp = (p.0 - m.0) / (2.0 * h);
            let dr = (p.1 - m.1) / (2.0 * h);
            v.0 += dp.norm_squared() / (sv * sv);
            v.1 += dr.norm_squared() / (sv * sv);
        }
    }
    Ok(var.into_iter().map(|(p, r)| (p.sqrt(), r.sqrt())).collect())
}
