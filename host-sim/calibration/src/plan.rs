//! Pose-set design: the N poses of the task box to measure, chosen to maximise the
//! identifiability of the parameters (D-optimal: the determinant of the information
//! matrix over the combinations a full candidate set determines, which for a fixed N
//! maximises the observability index O1 of Borm and Menq).
//!
//! Candidates: a grid of the thesis's task box (40 × 40 × 20 mm about [0, 0, hc]; 5 × 5 × 3
//! points by default) at the platform parallel to the base and tilted 10 and 20 deg about
//! eight horizontal axes, each kept only when the guards find no stop-level violation on
//! the nominal robot (the reference robot does not reach every tilted corner). Selection:
//! greedy, then exchanges (Fedorov) until no swap raises the determinant.

use crate::identify::Identifiability;
use crate::measurements::Measurement;
use crate::model::{Model, Noise};
use crate::parameters::{self, Tolerances};
use crate::rigid::Rigid;
use crate::CalibrationError;
use kinematics_core::guards::{Guards, Limits};
use kinematics_core::{inverse, Branch, Joints, PerChainGeometry, Pose};
use nalgebra::{DMatrix, Vector3};
use rand::{RngExt, SeedableRng};

/// Settings of a plan.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanOptions {
    /// Poses to choose.
    pub poses: usize,
    /// The tracker measures positions only.
    pub position_only: bool,
    /// The tracker's noise.
    pub noise: Noise,
    /// The parameters' scales.
    pub tolerances: Tolerances,
    /// Smallest singular value of a determined combination.
    pub determined_threshold: f64,
    /// Grid points of the task box along x, y, z.
    pub grid: [usize; 3],
    /// Tilts of the platform, rad (besides parallel), each about eight horizontal axes.
    pub tilts_rad: Vec<f64>,
    /// The guards' limits the candidates must pass.
    pub limits: Limits<f64>,
    /// The marker's expected pose on the platform.
    pub marker_in_platform: Rigid,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            poses: 60,
            position_only: false,
            noise: Noise::default(),
            tolerances: Tolerances::default(),
            determined_threshold: 1.0,
            grid: [5, 5, 3],
            tilts_rad: vec![10f64.to_radians(), 20f64.to_radians()],
            limits: Limits::reference(),
            marker_in_platform: default_marker(),
        }
    }
}

/// A marker 30 mm above the platform centre and 20 mm off it (a tracker body on the tool
/// flange): the lever that makes the orientation visible to a position-only tracker.
pub fn default_marker() -> Rigid {
    Rigid::new(Vector3::new(0.02, 0.0, 0.03), Vector3::zeros())
}

/// The chosen poses.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The poses, in visiting order (sorted along the box to shorten the moves).
    pub poses: Vec<Pose<f64>>,
    /// Their joints on the nominal robot.
    pub joints: Vec<Joints<f64>>,
    /// Candidates that passed the guards.
    pub candidates: usize,
    /// Identifiability of the plan.
    pub identifiability: Identifiability,
    /// O1 of as many candidates drawn at random (seed 1), for comparison.
    pub random_observability_index: f64,
}

/// The candidate poses of the task box about [0, 0, hc] that pass the guards on `robot`.
pub fn candidates(
    robot: &PerChainGeometry<f64>,
    grid: [usize; 3],
    tilts_rad: &[f64],
    limits: &Limits<f64>,
) -> Result<Vec<Pose<f64>>, CalibrationError> {
    let guards =
        Guards::new(*robot, Branch::OUTER, *limits).map_err(|_| CalibrationError::NoCandidates)?;
    let hc = robot.nominal().hc;
    let lin = |n: usize, half: f64, k: usize| {
        if n <= 1 {
            0.0
        } else {
            -half + 2.0 * half * k as f64 / (n - 1) as f64
        }
    };
    let mut orientations = vec![Vector3::zeros()];
    for &tilt in tilts_rad {
        for k in 0..8 {
            let a = k as f64 * std::f64::consts::FRAC_PI_4;
            orientations.push(Vector3::new(a.cos(), a.sin(), 0.0) * tilt);
        }
    }
    let mut out = Vec::new();
    for rv in &orientations {
        for i in 0..grid[0] {
            for j in 0..grid[1] {
                for k in 0..grid[2] {
                    let t = Vector3::new(
                        lin(grid[0], 0.02, i),
                        lin(grid[1], 0.02, j),
                        hc + lin(grid[2], 0.01, k),
                    );
                    let Ok(pose) = Pose::from_position_rotation_vector(t, *rv) else {
                        continue;
                    };
                    let (verdict, sol) = guards.check_pose(&pose);
                    if sol.is_some() && !verdict.is_stop() {
                        out.push(pose);
                    }
                }
            }
        }
    }
    if out.is_empty() {
        return Err(CalibrationError::NoCandidates);
    }
    Ok(out)
}

/// Synthetic rows at `poses` (the nominal robot's joints, an identity tracker): what the
/// information of a pose depends on.
fn rows_at(
    robot: &PerChainGeometry<f64>,
    poses: &[Pose<f64>],
    marker: &Rigid,
    position_only: bool,
) -> Result<Vec<Measurement>, CalibrationError> {
    poses
        .iter()
        .enumerate()
        .map(|(k, x)| {
            let q = inverse(robot, x, Branch::OUTER)
                .map_err(|error| CalibrationError::Ik { row: k + 1, error })?
                .q();
            let m = Rigid::from_pose(x).then(marker);
            Ok(Measurement {
                joints: q,
                position: m.t,
                rotation: (!position_only).then(|| m.rotation_vector()),
                label: None,
            })
        })
        .collect()
}

/// The blocks G_k (rows of candidate k × determined directions) and the analysis.
fn blocks(
    robot: &PerChainGeometry<f64>,
    poses: &[Pose<f64>],
    opts: &PlanOptions,
) -> Result<(Vec<DMatrix<f64>>, DMatrix<f64>), CalibrationError> {
    let rows = rows_at(robot, poses, &opts.marker_in_platform, opts.position_only)?;
    let model = Model::new(
        *robot,
        Rigid::identity(),
        opts.marker_in_platform,
        opts.noise,
        &rows,
    )?;
    let infos = parameters::infos(&opts.tolerances);
    let delta = vec![0.0; parameters::COUNT];
    let mut j = model.jacobian(&delta, poses, &infos)?;
    for (c, info) in infos.iter().enumerate() {
        j.column_mut(c).scale_mut(info.scale);
    }
    let d = if opts.position_only { 3 } else { 6 };
    let (basis, _, _) = crate::identify::analyse(&j, &infos, opts.determined_threshold)?;
    let g = j * &basis;
    let blocks = (0..poses.len())
        .map(|k| g.rows(k * d, d).into_owned())
        .collect();
    Ok((blocks, basis))
}

/// log det(I + G F⁻¹ Gᵀ) given the Cholesky factor L of F (the gain of adding G).
fn gain(l: &nalgebra::Cholesky<f64, nalgebra::Dyn>, g: &DMatrix<f64>) -> f64 {
    let w = l
        .l()
        .solve_lower_triangular(&g.transpose())
        .unwrap_or_else(|| g.transpose());
    let m = DMatrix::identity(g.nrows(), g.nrows()) + w.transpose() * w;
    match m.cholesky() {
        Some(c) => 2.0 * c.l().diagonal().iter().map(|x| x.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}

fn information(blocks: &[DMatrix<f64>], chosen: &[usize], r: usize, ridge: f64) -> DMatrix<f64> {
    let mut f = DMatrix::identity(r, r) * ridge;
    for &k in chosen {
        if let Some(g) = blocks.get(k) {
            f += g.transpose() * g;
        }
    }
    f
}

/// Chooses `opts.poses` poses of the task box for `robot`.
pub fn plan(robot: &PerChainGeometry<f64>, opts: &PlanOptions) -> Result<Plan, CalibrationError> {
    let cands = candidates(robot, opts.grid, &opts.tilts_rad, &opts.limits)?;
    if cands.len() < opts.poses || opts.poses < 4 {
        return Err(CalibrationError::TooFewCandidates {
            wanted: opts.poses,
            available: cands.len(),
        });
    }
    let (blocks, basis) = blocks(robot, &cands, opts)?;
    let r = basis.ncols();
    let mut chosen = choose(&blocks, opts.poses, r)?;
    // Visiting order: by orientation, then along the box.
    chosen.sort_unstable();
    let poses: Vec<Pose<f64>> = chosen
        .iter()
        .filter_map(|&k| cands.get(k).copied())
        .collect();
    let joints = poses
        .iter()
        .enumerate()
        .map(|(k, x)| {
            inverse(robot, x, Branch::OUTER)
                .map(|s| s.q())
                .map_err(|error| CalibrationError::Ik { row: k + 1, error })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let identifiability = identifiability_of(&blocks, &chosen, r)?;
    let mut rng = rand_xorshift::XorShiftRng::seed_from_u64(1);
    let mut pool: Vec<usize> = (0..cands.len()).collect();
    let mut random = Vec::with_capacity(opts.poses);
    for _ in 0..opts.poses {
        let i = rng.random_range(0..pool.len());
        random.push(pool.swap_remove(i));
    }
    let random_observability_index = identifiability_of(&blocks, &random, r)?.observability_index;
    Ok(Plan {
        poses,
        joints,
        candidates: cands.len(),
        identifiability,
        random_observability_index,
    })
}

/// The regularisation of the information matrices while choosing.
const RIDGE: f64 = 1e-6;

/// Chooses `count` of the candidates (their blocks of the reduced Jacobian, `r` columns)
/// for the largest information: greedily, one at a time, then exchanging a chosen one for
/// a better one while that helps (at most ten rounds).
fn choose(blocks: &[DMatrix<f64>], count: usize, r: usize) -> Result<Vec<usize>, CalibrationError> {
    let mut chosen: Vec<usize> = Vec::with_capacity(count);
    let mut used = vec![false; blocks.len()];
    for _ in 0..count {
        let f = information(blocks, &chosen, r, RIDGE);
        let l = f.cholesky().ok_or(CalibrationError::NothingDetermined)?;
        let Some((k, _)) = best_unused(blocks, &used, &l) else {
            break;
        };
        chosen.push(k);
        if let Some(u) = used.get_mut(k) {
            *u = true;
        }
    }
    for _ in 0..10 {
        if !exchange(blocks, &mut chosen, &mut used, r) {
            break;
        }
    }
    Ok(chosen)
}

/// The candidate not used yet that adds the most information to the factor `l`, and its
/// gain.
fn best_unused(
    blocks: &[DMatrix<f64>],
    used: &[bool],
    l: &nalgebra::Cholesky<f64, nalgebra::Dyn>,
) -> Option<(usize, f64)> {
    (0..blocks.len())
        .filter(|&k| !used.get(k).copied().unwrap_or(true))
        .map(|k| (k, blocks.get(k).map_or(f64::NEG_INFINITY, |g| gain(l, g))))
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// One round of exchanges: each chosen candidate in turn replaced by the best unused one
/// when that gains more than keeping it; whether any was.
fn exchange(blocks: &[DMatrix<f64>], chosen: &mut [usize], used: &mut [bool], r: usize) -> bool {
    let mut improved = false;
    for s in 0..chosen.len() {
        let Some(&out) = chosen.get(s) else { continue };
        let rest: Vec<usize> = chosen.iter().copied().filter(|&k| k != out).collect();
        let f = information(blocks, &rest, r, RIDGE);
        let Some(l) = f.cholesky() else { continue };
        let keep = blocks.get(out).map_or(f64::NEG_INFINITY, |g| gain(&l, g));
        if let Some((k, g)) = best_unused(blocks, used, &l) {
            if g > keep + 1e-9 {
                if let Some(slot) = chosen.get_mut(s) {
                    *slot = k;
                }
                if let Some(u) = used.get_mut(out) {
                    *u = false;
                }
                if let Some(u) = used.get_mut(k) {
                    *u = true;
                }
                improved = true;
            }
        }
    }
    improved
}

/// The identifiability of the `r` reduced directions from the candidates of `set`.
fn identifiability_of(
    blocks: &[DMatrix<f64>],
    set: &[usize],
    r: usize,
) -> Result<Identifiability, CalibrationError> {
    let d = blocks.first().map_or(6, |g| g.nrows());
    let mut g = DMatrix::zeros(set.len() * d, r);
    for (i, &k) in set.iter().enumerate() {
        if let Some(b) = blocks.get(k) {
            g.rows_mut(i * d, d).copy_from(b);
        }
    }
    let names: Vec<parameters::Info> = (0..r)
        .map(|c| parameters::Info {
            name: format!("direction {}", c + 1),
            unit: parameters::Unit::Length,
            scale: 1.0,
        })
        .collect();
    Ok(crate::identify::analyse(&g, &names, 0.0)?.1)
}
