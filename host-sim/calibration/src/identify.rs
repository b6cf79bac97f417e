//! Identification: the parameters that best explain the measurements, by nonlinear least
//! squares (Levenberg-Marquardt, the `levenberg-marquardt` crate), with an optional robust
//! loss (Huber or Cauchy, by iteratively reweighted least squares), restricted to the
//! parameter combinations the measurements determine.
//!
//! **Identifiability.** At the start, the identification Jacobian (whitened residuals over
//! parameters divided by their tolerances, [`crate::parameters`]) is decomposed by the SVD.
//! A right singular vector whose singular value is at least
//! [`Options::determined_threshold`] (default 1: the measurements fix that combination to
//! better than its tolerance, one standard deviation) is **determined**; the solver moves
//! the parameters only along the determined directions, so every other combination stays
//! at its reference (nominal) value. The report lists the singular values, each
//! parameter's share in the determined subspace (1: determined by itself, 0: not at all,
//! between: only in combinations) and its standard deviation, and each undetermined
//! combination by its main terms. The structural ones, whatever the poses: the leg's two
//! offsets (only their sum), the base frame against the tracker transform and the platform
//! frame against the marker transform (6 each: a rigid motion of either is absorbed by the
//! transform), and with position-only rows the marker's orientation.
//!
//! **Stages.** First the two transforms alone, on the reference robot (the registration a
//! nominal model gets: "before calibration"), then everything ("after").

use crate::measurements::Measurement;
use crate::model::{initial_transforms, Model, Noise, RowResidual};
use crate::parameters::{self, Info, Tolerances, COUNT, ROBOT};
use crate::rigid::Rigid;
use crate::CalibrationError;
use kinematics_core::PerChainGeometry;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector};
use nalgebra_lm::{Dyn, Owned};

/// The robust loss of the rows (thresholds in units of the whitened residual: a row's
/// residual norm divided by the square root of its row count).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Loss {
    /// Plain least squares.
    Squared,
    /// Huber: quadratic up to the threshold, linear beyond.
    Huber(f64),
    /// Cauchy: log(1 + (r/c)²), for gross outliers.
    Cauchy(f64),
}

impl Loss {
    /// The IRLS weight of a row with normalised residual `r`.
    fn weight(&self, r: f64) -> f64 {
        match *self {
            Loss::Squared => 1.0,
            Loss::Huber(c) => {
                if r <= c {
                    1.0
                } else {
                    c / r
                }
            }
            Loss::Cauchy(c) => 1.0 / (1.0 + (r / c) * (r / c)),
        }
    }
}

/// Which parameters move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Free {
    /// Everything the measurements determine.
    All,
    /// The two transforms only (the robot stays at its reference).
    Transforms,
}

/// Settings of an identification.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// The parameters' scales.
    pub tolerances: Tolerances,
    /// The tracker's noise (the rows' weights).
    pub noise: Noise,
    /// The loss.
    pub loss: Loss,
    /// Smallest singular value of a determined combination (default 1).
    pub determined_threshold: f64,
    /// Most reweighting passes of a robust loss (default 8; fewer when the weights settle).
    pub reweighting_passes: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            tolerances: Tolerances::default(),
            noise: Noise::default(),
            loss: Loss::Squared,
            determined_threshold: 1.0,
            reweighting_passes: 8,
        }
    }
}

/// A combination of parameters the measurements do not determine.
#[derive(Clone, Debug, PartialEq)]
pub struct Combination {
    /// Its singular value.
    pub singular_value: f64,
    /// Its main terms (parameter name, coefficient in tolerance units), largest first.
    pub terms: Vec<(String, f64)>,
}

/// One parameter's identification.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterResult {
    /// Name, unit, scale.
    pub info: Info,
    /// Its deviation from the reference (SI).
    pub delta: f64,
    /// Its share in the determined subspace, 0..1.
    pub determined_share: f64,
    /// Its standard deviation (SI) within the determined subspace.
    pub std: f64,
}

/// What the SVD of the identification Jacobian says.
#[derive(Clone, Debug, PartialEq)]
pub struct Identifiability {
    /// Singular values, largest first (whitened residuals over parameter tolerances).
    pub singular_values: Vec<f64>,
    /// How many combinations are determined.
    pub determined: usize,
    /// The threshold used.
    pub threshold: f64,
    /// The undetermined combinations, smallest singular value first.
    pub undetermined: Vec<Combination>,
    /// The observability index O1 = (σ1 … σr)^(1/r) / √m over the determined ones
    /// (Borm and Menq), m the residual rows.
    pub observability_index: f64,
    /// σ1 / σr over the determined ones.
    pub condition: f64,
}

/// The result of an identification.
#[derive(Clone, Debug)]
pub struct Identification {
    /// The identified robot.
    pub geometry: PerChainGeometry<f64>,
    /// The base in the tracker's frame.
    pub base_in_tracker: Rigid,
    /// The marker on the platform.
    pub marker_in_platform: Rigid,
    /// All parameters, deviations from the reference.
    pub parameters: Vec<ParameterResult>,
    /// The SVD at the solution.
    pub identifiability: Identifiability,
    /// Each row's residual with the reference robot (transforms registered).
    pub before: Vec<RowResidual>,
    /// Each row's residual after.
    pub after: Vec<RowResidual>,
    /// Each row's final weight (1 without a robust loss).
    pub weights: Vec<f64>,
    /// Residual evaluations the solver made.
    pub evaluations: usize,
    /// The deviations (SI, [`parameters::COUNT`] of them) from the reference robot and
    /// [`Identification::reference_transforms`].
    pub delta: Vec<f64>,
    /// The transforms' first estimates the deviations are taken from.
    pub reference_transforms: (Rigid, Rigid),
    /// The transforms of the nominal robot registered alone (stage 1: "before").
    pub registered: (Rigid, Rigid),
    /// The determined directions at the solution (columns, parameters over their scales).
    pub basis: DMatrix<f64>,
    /// Their singular values.
    pub determined_singular_values: Vec<f64>,
}

/// The residual of every row at a trial geometry that cannot assemble a measured
/// configuration (residuals are metres and radians: this is a kilometre).
const INFEASIBLE_RESIDUAL: f64 = 1e3;

/// The Levenberg-Marquardt problem over the determined directions `basis` (columns, in
/// scaled units) around `origin`.
struct Problem<'m, 'a> {
    model: &'m Model<'a>,
    infos: &'m [Info],
    origin: Vec<f64>,
    basis: DMatrix<f64>,
    row_weights: DVector<f64>,
    z: nalgebra_lm::DVector<f64>,
    /// Why the last residual or Jacobian evaluation failed.
    failure: std::cell::RefCell<Option<String>>,
}

impl Problem<'_, '_> {
    fn delta(&self, z: &[f64]) -> Vec<f64> {
        let zz = DVector::from_column_slice(z);
        let step = &self.basis * zz;
        self.origin
            .iter()
            .zip(self.infos)
            .enumerate()
            .map(|(j, (o, info))| o + step[j] * info.scale)
            .collect()
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &nalgebra_lm::DVector<f64>) {
        self.z = x.clone();
    }
    fn params(&self) -> nalgebra_lm::DVector<f64> {
        self.z.clone()
    }
    fn residuals(&self) -> Option<nalgebra_lm::DVector<f64>> {
        let d = self.delta(self.z.as_slice());
        match self.model.residuals(&d) {
            Ok((r, _)) => {
                let w = r.component_mul(&self.row_weights);
                Some(nalgebra_lm::DVector::from_column_slice(w.as_slice()))
            }
            Err(e) => {
                *self.failure.borrow_mut() = Some(e.to_string());
                if self.z.iter().all(|v| *v == 0.0) {
                    // The starting point itself: a real failure.
                    None
                } else {
                    // A trial step to a geometry on which a measured configuration cannot
                    // be assembled: a cost far above any feasible one, so the solver
                    // rejects the step and shortens it instead of giving up.
                    Some(nalgebra_lm::DVector::from_element(
                        self.row_weights.len(),
                        INFEASIBLE_RESIDUAL,
                    ))
                }
            }
        }
    }
    fn jacobian(&self) -> Option<nalgebra_lm::DMatrix<f64>> {
        let d = self.delta(self.z.as_slice());
        let j = self
            .model
            .residuals(&d)
            .and_then(|(_, poses)| self.model.jacobian(&d, &poses, self.infos));
        let j = match j {
            Ok(j) => j,
            Err(e) => {
                *self.failure.borrow_mut() = Some(e.to_string());
                return None;
            }
        };
        let scaled = scale_columns(&j, self.infos);
        let mut jz = scaled * &self.basis;
        for (i, w) in self.row_weights.iter().enumerate() {
            jz.row_mut(i).scale_mut(*w);
        }
        Some(nalgebra_lm::DMatrix::from_column_slice(
            jz.nrows(),
            jz.ncols(),
            jz.as_slice(),
        ))
    }
}

fn scale_columns(j: &DMatrix<f64>, infos: &[Info]) -> DMatrix<f64> {
    let mut s = j.clone();
    for (c, info) in infos.iter().enumerate() {
        s.column_mut(c).scale_mut(info.scale);
    }
    s
}

/// The determined directions (columns), the report, and per parameter its share in the
/// determined subspace and its standard deviation in tolerance units.
pub type Analysis = (DMatrix<f64>, Identifiability, Vec<(f64, f64)>);

/// The SVD of the scaled Jacobian (columns of fixed parameters zeroed): the determined
/// basis and the report.
pub fn analyse(
    scaled: &DMatrix<f64>,
    infos: &[Info],
    threshold: f64,
) -> Result<Analysis, CalibrationError> {
    let n = scaled.ncols();
    // The SVD of JᵀJ (n × n) gives V and σ²; rows can be many more than columns.
    let jtj = scaled.transpose() * scaled;
    let eig = jtj.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let sv: Vec<f64> = order
        .iter()
        .map(|&k| eig.eigenvalues[k].max(0.0).sqrt())
        .collect();
    let r = sv.iter().take_while(|&&s| s >= threshold).count();
    if r == 0 {
        return Err(CalibrationError::NothingDetermined);
    }
    let basis = DMatrix::from_fn(n, r, |i, c| {
        order.get(c).map_or(0.0, |&k| eig.eigenvectors[(i, k)])
    });
    let mut undetermined = Vec::new();
    for (c, &k) in order.iter().enumerate().skip(r).rev() {
        let v = eig.eigenvectors.column(k);
        let mut terms: Vec<(String, f64)> = v
            .iter()
            .enumerate()
            .filter(|(_, x)| x.abs() >= 0.2)
            .map(|(i, x)| (infos.get(i).map_or(String::new(), |f| f.name.clone()), *x))
            .collect();
        terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        undetermined.push(Combination {
            singular_value: sv.get(c).copied().unwrap_or(0.0),
            terms,
        });
    }
    // Per parameter: share in the determined subspace, standard deviation within it.
    let per: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let mut share = 0.0;
            let mut var = 0.0;
            for (c, &k) in order.iter().enumerate().take(r) {
                let x = eig.eigenvectors[(i, k)];
                share += x * x;
                let s = sv.get(c).copied().unwrap_or(1.0);
                var += x * x / (s * s);
            }
            (share, var.sqrt())
        })
        .collect();
    let m = scaled.nrows().max(1) as f64;
    let logs: f64 = sv.iter().take(r).map(|s| s.ln()).sum();
    let id = Identifiability {
        condition: sv.first().copied().unwrap_or(0.0) / sv.get(r - 1).copied().unwrap_or(1.0),
        observability_index: (logs / r as f64).exp() / m.sqrt(),
        singular_values: sv,
        determined: r,
        threshold,
        undetermined,
    };
    Ok((basis, id, per))
}

/// Runs one LM (with reweighting for a robust loss) from `origin` over the determined
/// directions of the parameters `free` selects; returns the deviations, the row weights
/// and the evaluations.
fn solve(
    model: &Model<'_>,
    infos: &[Info],
    origin: Vec<f64>,
    free: Free,
    opts: &Options,
) -> Result<(Vec<f64>, Vec<f64>, usize), CalibrationError> {
    let rows = model.rows();
    let passes = match opts.loss {
        Loss::Squared => 1,
        _ => opts.reweighting_passes.max(1),
    };
    let mut current = origin;
    // A robust loss weighs the rows from the start by their residuals at the origin: a
    // first pass at equal weights would let a gross outlier drag the fit away (a 100 mm
    // reading is a thousand noise deviations), and the passes after it would start from
    // there.
    let mut row_weights = robust_weights(model, &current, opts.loss)?;
    let mut evaluations = 0;
    for _ in 0..passes {
        let expand = |w: &[f64]| {
            let mut v = Vec::with_capacity(model.residual_count());
            for (m, wk) in rows.iter().zip(w) {
                v.extend(std::iter::repeat_n(wk.sqrt(), m.rows()));
            }
            DVector::from_vec(v)
        };
        let rw = expand(&row_weights);
        let (_, poses) = model.residuals(&current)?;
        let j = model.jacobian(&current, &poses, infos)?;
        let mut scaled = scale_columns(&j, infos);
        if free == Free::Transforms {
            for c in 0..ROBOT {
                scaled.column_mut(c).fill(0.0);
            }
        }
        for (i, w) in rw.iter().enumerate() {
            scaled.row_mut(i).scale_mut(*w);
        }
        let (basis, _, _) = analyse(&scaled, infos, opts.determined_threshold)?;
        let r = basis.ncols();
        let problem = Problem {
            model,
            infos,
            origin: current.clone(),
            basis,
            row_weights: rw,
            z: nalgebra_lm::DVector::zeros(r),
            failure: std::cell::RefCell::new(None),
        };
        let (problem, report) = LevenbergMarquardt::new()
            .with_patience(200)
            .minimize(problem);
        evaluations += report.number_of_evaluations;
        if !report.termination.was_successful() {
            let why = problem.failure.borrow().clone();
            return Err(CalibrationError::Solver(match why {
                Some(w) => format!("{:?}: {w}", report.termination),
                None => format!("{:?}", report.termination),
            }));
        }
        current = problem.delta(problem.z.as_slice());
        let next = robust_weights(model, &current, opts.loss)?;
        let change = next
            .iter()
            .zip(&row_weights)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        row_weights = next;
        if change < WEIGHTS_SETTLED {
            break;
        }
    }
    Ok((current, row_weights, evaluations))
}

/// The reweighting stops when no row's weight changes by more than this.
const WEIGHTS_SETTLED: f64 = 1e-3;

/// Each row's IRLS weight at the deviations `delta`.
///
/// A row's normalised residual is its whitened residual's norm over the square root of its
/// row count (about 1 for a row that only carries the tracker's noise), divided by the
/// **scale**: the median row's normalised residual, but at least 1. Far from the solution
/// (the nominal robot, or a fit an outlier has pulled) every row's residual is large and
/// the scale follows them, so only the rows far beyond the bulk lose their weight; at the
/// solution the scale is the noise and the loss's threshold is in noise deviations, as
/// documented on [`Loss`].
fn robust_weights(
    model: &Model<'_>,
    delta: &[f64],
    loss: Loss,
) -> Result<Vec<f64>, CalibrationError> {
    let rows = model.rows();
    if loss == Loss::Squared {
        return Ok(vec![1.0; rows.len()]);
    }
    let (res, _) = model.residuals(delta)?;
    let mut norms = Vec::with_capacity(rows.len());
    let mut at = 0;
    for m in rows {
        let n = m.rows();
        norms.push(res.rows(at, n).norm() / (n as f64).sqrt());
        at += n;
    }
    let mut sorted = norms.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(1.0);
    let scale = median.max(1.0);
    Ok(norms.iter().map(|r| loss.weight(r / scale)).collect())
}

/// Identifies the robot and the transforms from `rows`, starting from `reference` and the
/// marker's drawing `marker_guess` (the base in the tracker is estimated from the data).
pub fn identify(
    reference: &PerChainGeometry<f64>,
    rows: &[Measurement],
    marker_guess: Rigid,
    opts: &Options,
) -> Result<Identification, CalibrationError> {
    if rows.len() < 4 {
        return Err(CalibrationError::TooFewRows(rows.len()));
    }
    let infos = parameters::infos(&opts.tolerances);
    // First estimates of the transforms on the reference robot.
    let probe = Model::new(
        *reference,
        Rigid::identity(),
        marker_guess,
        opts.noise,
        rows,
    )?;
    let (a0, b0) = initial_transforms(probe.reference_poses(), rows, marker_guess)?;
    let model = Model::new(*reference, a0, b0, opts.noise, rows)?;
    // Stage 1: the transforms alone (the nominal robot, registered).
    let (registered, _, e1) = solve(&model, &infos, vec![0.0; COUNT], Free::Transforms, opts)?;
    let before = model.row_residuals(&registered)?;
    // Stage 2: everything the measurements determine.
    let (delta, weights, e2) = solve(&model, &infos, registered.clone(), Free::All, opts)?;
    let after = model.row_residuals(&delta)?;
    let (geometry, base_in_tracker, marker_in_platform) = model.at(&delta)?;
    // The SVD at the solution, for the report.
    let (_, poses) = model.residuals(&delta)?;
    let mut scaled = scale_columns(&model.jacobian(&delta, &poses, &infos)?, &infos);
    let mut at = 0;
    for (m, w) in rows.iter().zip(&weights) {
        for i in 0..m.rows() {
            scaled.row_mut(at + i).scale_mut(w.sqrt());
        }
        at += m.rows();
    }
    let (basis, identifiability, per) = analyse(&scaled, &infos, opts.determined_threshold)?;
    let registered_transforms = (
        parameters::transform(&a0, &registered, parameters::TRACKER),
        parameters::transform(&b0, &registered, parameters::MARKER),
    );
    let parameters = infos
        .iter()
        .zip(&delta)
        .zip(per)
        .map(|((info, d), (share, std))| ParameterResult {
            info: info.clone(),
            delta: *d,
            determined_share: share,
            std: std * info.scale,
        })
        .collect();
    Ok(Identification {
        geometry,
        base_in_tracker,
        marker_in_platform,
        parameters,
        before,
        after,
        weights,
        evaluations: e1 + e2,
        delta,
        reference_transforms: (a0, b0),
        registered: registered_transforms,
        determined_singular_values: identifiability
            .singular_values
            .iter()
            .take(identifiability.determined)
            .copied()
            .collect(),
        basis,
        identifiability,
    })
}
