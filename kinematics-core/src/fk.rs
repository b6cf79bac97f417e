//! Forward kinematics by Newton iteration on the inverse-kinematics residual, warm-started
//! from the last pose (as LinuxCNC's hexapod kinematics does).
//!
//! Each step solves Jtilde Δx = Js Δq (Eq. 7.17-7.18 rearranged), so it needs no inverse of
//! the serial part and works at serial singularities; the step is limited in length and
//! angle, and the result is returned only when the inverse kinematics of the final pose
//! reproduces the joints within the tolerances.

use crate::branch::Branch;
use crate::chain::{Chain, PerChain};
use crate::double_buffer::DoubleBuffer;
use crate::ik::{inverse, inverse_into, IkError, Solution};
use crate::jacobian::tripod_jacobian;
use crate::lu::Lu6;
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::Pose;
use crate::scalar::{larger, lit, wrap_angle, Real};
use crate::vectors::Joints;
use core::fmt;
use nalgebra::{Matrix6, Vector3, Vector6};

/// Newton solver settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkConfig<T: Real> {
    /// Largest number of Newton steps (default 30).
    pub max_iterations: u32,
    /// Largest accepted residual of a prismatic joint, m.
    pub tol_linear: T,
    /// Largest accepted residual of an angular joint, rad.
    pub tol_angular: T,
    /// Longest translation of one step, m (default 20 mm).
    pub max_step_linear: T,
    /// Largest rotation of one step, rad (default 0.2 rad).
    pub max_step_angular: T,
}

impl<T: Real> Default for FkConfig<T> {
    /// Tolerances at a few units in the last place of the scalar for a 0.1 m robot:
    /// about 7.6e-7 m / 7.6e-6 rad in f32 and 1.4e-15 m / 1.4e-14 rad in f64.
    fn default() -> Self {
        let eps = T::default_epsilon();
        FkConfig {
            max_iterations: 30,
            tol_linear: eps * lit(6.4),
            tol_angular: eps * lit(64.0),
            max_step_linear: lit(0.02),
            max_step_angular: lit(0.2),
        }
    }
}

/// Why the forward kinematics failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FkError {
    /// A joint value or the initial pose is not finite (index in q order, 6 = initial pose).
    NonFiniteInput { index: u8 },
    /// The settings are not usable (a tolerance or step limit is not positive).
    InvalidConfig,
    /// The iteration reached a pose where the chosen branch has no solution.
    LeftBranch { iteration: u32, error: IkError },
    /// The Newton step could not be solved: Jtilde is singular (a parallel singularity).
    SingularStep { iteration: u32 },
    /// The iteration limit was reached before the residual met the tolerances.
    DidNotConverge {
        iterations: u32,
        /// Largest remaining residual, m or rad.
        residual: f64,
    },
}

impl fmt::Display for FkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FkError::NonFiniteInput { index } if *index < 6 => {
                write!(f, "joint q{} is not finite", index + 1)
            }
            FkError::NonFiniteInput { .. } => f.write_str("the initial pose is not finite"),
            FkError::InvalidConfig => f.write_str("invalid solver settings"),
            FkError::LeftBranch { iteration, error } => {
                write!(f, "left the branch at iteration {iteration}: {error}")
            }
            FkError::SingularStep { iteration } => {
                write!(
                    f,
                    "singular Newton step at iteration {iteration} (parallel singularity)"
                )
            }
            FkError::DidNotConverge {
                iterations,
                residual,
            } => write!(
                f,
                "did not converge in {iterations} iterations (residual {residual:.3e})"
            ),
        }
    }
}

/// A converged forward-kinematics result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkSolution<T: Real> {
    /// The pose.
    pub pose: Pose<T>,
    /// The inverse-kinematics solution at that pose (it reproduces the joints).
    pub solution: Solution<T>,
    /// Newton steps taken.
    pub iterations: u32,
    /// Largest joint residual left, m or rad.
    pub residual: T,
}

/// Residual q_target - q(x), angles wrapped; returns it and whether it meets the tolerances.
/// (Inlined: where the caller knows the joint kinds, each component is its kind's
/// arithmetic alone.)
#[inline(always)]
fn residual<T: Real>(
    kinds: &[JointKind; 6],
    target: &Joints<T>,
    q: &Joints<T>,
    cfg: &FkConfig<T>,
) -> (Joints<T>, bool, T) {
    // Over plain arrays, the six components written out: the robot's joint kinds are
    // constants, so each component compiles to its own kind's arithmetic (nalgebra's
    // iterators, or a loop matching on the kind, cost several times that on the
    // Cortex-M4).
    let [t] = &target.data.0;
    let [q] = &q.data.0;
    let mut ok = true;
    let mut worst = T::zero();
    let mut component = |k: usize| {
        let (Some(ti), Some(qi), Some(kind)) = (t.get(k), q.get(k), kinds.get(k)) else {
            return T::zero();
        };
        let d = *ti - *qi;
        let (d, tol) = match kind {
            JointKind::Linear => (d, cfg.tol_linear),
            JointKind::Angular => (wrap_angle(d), cfg.tol_angular),
        };
        let a = d.abs();
        ok &= a <= tol;
        // (A NaN residual already makes `ok` false.)
        worst = larger(worst, a);
        d
    };
    let r = [
        component(0),
        component(1),
        component(2),
        component(3),
        component(4),
        component(5),
    ];
    (Joints::from(r), ok, worst)
}

/// Forward kinematics: the pose whose inverse kinematics on `branch` gives `q`, found by
/// Newton iteration from `guess` (the last pose, or the central configuration).
pub fn forward<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    q: &Joints<T>,
    branch: Branch,
    guess: &Pose<T>,
    cfg: &FkConfig<T>,
) -> Result<FkSolution<T>, FkError> {
    if let Some(k) = q.iter().position(|x| !x.is_finite()) {
        return Err(FkError::NonFiniteInput { index: k as u8 });
    }
    if !guess.is_finite() {
        return Err(FkError::NonFiniteInput { index: 6 });
    }
    let positive = |x: T| x > T::zero() && x.is_finite();
    if !(positive(cfg.tol_linear)
        && positive(cfg.tol_angular)
        && positive(cfg.max_step_linear)
        && positive(cfg.max_step_angular))
    {
        return Err(FkError::InvalidConfig);
    }
    let kinds = m.joint_kinds();
    let scale = m.length_scale();
    let mut pose = *guess;
    let mut sol = inverse(m, &pose, branch).map_err(|error| FkError::LeftBranch {
        iteration: 0,
        error,
    })?;
    let step = |pose: &Pose<T>, sol: &Solution<T>, r: &Joints<T>, iteration, tries| {
        newton_step(
            m, pose, sol, r, branch, &kinds, q, cfg, scale, iteration, tries,
        )
    };
    let mut iteration = 0u32;
    let mut polished = 0u32;
    loop {
        let (r, ok, worst) = residual(&kinds, q, &sol.q(), cfg);
        if ok {
            // Polish: within tolerance, one more step is kept while it still lowers the
            // residual, so the result sits at the scalar's rounding floor (this matters in
            // f32, where the tolerance is a few µm-equivalents of joint error).
            if iteration < cfg.max_iterations && polished < MAX_POLISH {
                polished += 1;
                if let Ok(Step::Improved(p, s)) = step(&pose, &sol, &r, iteration + 1, 1) {
                    iteration += 1;
                    pose = p;
                    sol = s;
                    continue;
                }
            }
            return Ok(FkSolution {
                pose,
                solution: sol,
                iterations: iteration,
                residual: worst,
            });
        }
        if iteration >= cfg.max_iterations {
            return Err(FkError::DidNotConverge {
                iterations: iteration,
                residual: crate::scalar::to_f64(worst),
            });
        }
        iteration += 1;
        match step(&pose, &sol, &r, iteration, MAX_HALVINGS)? {
            Step::Improved(p, s) | Step::NotImproved(p, s) => {
                pose = p;
                sol = s;
            }
        }
    }
}

/// The outcome of one damped Newton step.
enum Step<T: Real> {
    /// The residual went down.
    Improved(Pose<T>, Solution<T>),
    /// No halving lowered the residual; the full step is taken anyway (rounding floor).
    NotImproved(Pose<T>, Solution<T>),
}

/// One Newton step from `pose` (where the inverse kinematics gives `sol` and the residual
/// is `r`): solves Jtilde Δx = Js Δq, limits the step, and halves it (up to `tries` trials
/// in all) while it leaves the branch or does not lower the residual.
#[allow(clippy::too_many_arguments)]
fn newton_step<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    pose: &Pose<T>,
    sol: &Solution<T>,
    r: &Joints<T>,
    branch: Branch,
    kinds: &[JointKind; 6],
    q: &Joints<T>,
    cfg: &FkConfig<T>,
    scale: T,
    iteration: u32,
    tries: usize,
) -> Result<Step<T>, FkError> {
    let rhs = serial_rhs(m, sol, r);
    let dx = Lu6::new(&tripod_jacobian(sol))
        .map(|lu| lu.solve(&rhs))
        .filter(|d| d.iter().all(|x| x.is_finite()))
        .ok_or(FkError::SingularStep { iteration })?;
    let (mut dv, mut dw) = limited_step(&dx, cfg);
    // Backtracking: halve the step while it leaves the branch or does not reduce the
    // residual (joint angles weighted by the length scale).
    let merit = |r: &Joints<T>| weighted_norm(kinds, r, scale);
    let current = merit(r);
    let mut last_error = None;
    let mut fallback = None;
    let half = lit::<T>(0.5);
    for _ in 0..tries {
        let trial = pose.displaced(&dv, &dw);
        match inverse(m, &trial, branch) {
            Ok(s) => {
                let (rt, _, _) = residual(kinds, q, &s.q(), cfg);
                if merit(&rt) < current {
                    return Ok(Step::Improved(trial, s));
                }
                if fallback.is_none() {
                    fallback = Some((trial, s));
                }
            }
            Err(e) => last_error = Some(e),
        }
        dv *= half;
        dw *= half;
    }
    match (fallback, last_error) {
        (Some((p, s)), _) => Ok(Step::NotImproved(p, s)),
        (None, Some(error)) => Err(FkError::LeftBranch { iteration, error }),
        (None, None) => Err(FkError::SingularStep { iteration }),
    }
}

/// The right side Js Δq of a step (Eq. 7.17-7.18): per chain, rows (i, 3+i) are
/// B_i [Δqa_i; Δqb_i] with the serial blocks at `sol`.
fn serial_rhs<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    sol: &Solution<T>,
    r: &Joints<T>,
) -> Vector6<T> {
    let ra = PerChain([r.x, r.y, r.z]);
    let rb = PerChain([r.w, r.a, r.b]);
    let rhs = PerChain::from_fn(|c: Chain| {
        let blk = m.serial_block(&sol.chains[c]);
        (
            blk.a11 * ra[c] + blk.a12 * rb[c],
            blk.a21 * ra[c] + blk.a22 * rb[c],
        )
    });
    let [(t1, b1), (t2, b2), (t3, b3)] = rhs.0;
    Vector6::new(t1, t2, t3, b1, b2, b3)
}

/// The translation and rotation of a step Δx, shortened so that a poor guess cannot throw
/// the iterate far away.
fn limited_step<T: Real>(dx: &Vector6<T>, cfg: &FkConfig<T>) -> (Vector3<T>, Vector3<T>) {
    let dv = Vector3::new(dx.x, dx.y, dx.z);
    let dw = Vector3::new(dx.w, dx.a, dx.b);
    // (`larger`, not `max`, which is a call to libm's fmaxf on the Cortex-M4: the same
    // value, a NaN ratio left out as fmaxf leaves it.)
    let shrink = larger(
        larger(T::one(), crate::scalar::norm3(&dv) / cfg.max_step_linear),
        crate::scalar::norm3(&dw) / cfg.max_step_angular,
    );
    (dv / shrink, dw / shrink)
}

/// Extra Newton steps taken once within tolerance (quadratic convergence needs one).
const MAX_POLISH: u32 = 1;

/// Halvings of a Newton step tried before giving up (2⁻¹² of the step at the last try).
const MAX_HALVINGS: usize = 12;

/// sqrt(Σ linear² + Σ (L·angular)²): a residual norm with angles scaled to lengths.
fn weighted_norm<T: Real>(kinds: &[JointKind; 6], r: &Joints<T>, scale: T) -> T {
    let [r] = r.data.0;
    let mut acc = T::zero();
    for (x, kind) in r.iter().zip(kinds.iter()) {
        let v = match kind {
            JointKind::Linear => *x,
            JointKind::Angular => *x * scale,
        };
        acc += v * v;
    }
    crate::scalar::sqrt(acc)
}

/// What one [`FkTracker::update`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tracked {
    /// The estimate already reproduced the joints within the tolerances (or within
    /// [`TRACK_RESIDUAL_MAX`] and no step could improve it).
    Unchanged,
    /// Newton steps (at most [`TRACK_STEPS`], each with up to [`TRACK_HALVINGS`]
    /// halvings) brought the residual below [`TRACK_RESIDUAL_MAX`].
    Stepped { steps: u32 },
    /// The steps did not do that: the full solver ran from the estimate.
    Solved { iterations: u32 },
}

/// Halvings each of the tracker's Newton steps may take.
pub const TRACK_HALVINGS: usize = 2;

/// Newton steps the tracker takes before falling back to [`forward`] (one is the rule on
/// the MCU; at the speed limits both f32 and f64 sometimes need the second).
pub const TRACK_STEPS: u32 = 2;

/// Largest joint residual (m or rad) the tracker accepts after its steps, or the solver's
/// angular tolerance when that is larger (f32: 7.6e-6 rad; the rounding of link angles
/// near π alone is 2.4e-7 rad); above it (a jump of the readings, e.g. after homing) the
/// full solver runs at once.
pub const TRACK_RESIDUAL_MAX: f64 = 1e-6;

/// Forward kinematics for a stream of joint readings, one per control tick (LinuxCNC's
/// kinematics do the same with their previous solution as the guess): between ticks the
/// joints move by a few encoder counts, so one Newton step from the previous estimate
/// (Jtilde Δx = Js Δq, as in [`forward`]) brings the residual to the square of the motion.
///
/// The step reuses the LU factors of Jtilde taken at a recent estimate (a chord method:
/// Js comes from the estimate's own solution, only Jtilde is older). A Jtilde a fraction of
/// a millimetre old changes the step by far less than the step itself, so the residual
/// still drops by orders of magnitude per tick; when it no longer drops well, Jtilde is
/// taken again at the new estimate on that tick and factorised on the next, so that no
/// tick pays for the Jacobian, its factorisation and a step together. When the step with
/// the old factors does not meet [`TRACK_RESIDUAL_MAX`], a second step with fresh factors
/// follows at once, and when [`TRACK_STEPS`] steps do not, the full solver runs.
///
/// The estimate always comes with the residual of its own inverse kinematics against the
/// readings, so its accuracy is known, never assumed: after a step it is the tick's motion
/// times the relative change of Jtilde since its factorisation, kept under an eighth of
/// the acceptance level (`TRACK_RESIDUAL_MAX` or the tolerance: in f64 1.25e-7, the pose
/// within 1 µm and 3 µrad of the full solver's at 25 mm/s and 30 deg/s; in f32, on the MCU,
/// the rounding floor), and it converges to the tolerances while the robot stands still.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkTracker<T: Real> {
    branch: Branch,
    /// The estimate's solution (its pose is the estimate) and a trial's: a step solves its
    /// trial pose into the spare and, when it is kept, the two swap roles (no copies).
    sols: DoubleBuffer<Solution<T>>,
    residual: T,
    /// The matrix of the steps: Jtilde's LU factors at a recent estimate, or Jtilde taken
    /// at the estimate and to be factorised on the next update.
    factors: Factors<T>,
    /// Steps taken with factors older than the estimate, and refreshes of the factors.
    counts: TrackerCounts,
}

/// What the tracker did over its life, by name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackerCounts {
    /// Steps with the factors of an older estimate (the chord steps).
    pub chord_steps: u32,
    /// Steps with factors taken at the estimate itself (the Newton steps).
    pub newton_steps: u32,
    /// Times Jtilde was taken again because the residual no longer dropped well.
    pub refreshes: u32,
    /// Times the full solver ran.
    pub full_solves: u32,
}

/// The matrix of the tracker's steps. A refresh's Jtilde and the factors it replaces are
/// never both needed: the next update that steps factorises it before its first step, so
/// the two share one slot (the tracker is 148 bytes smaller).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Factors<T: Real> {
    /// None yet (after the full solver), or Jtilde was singular.
    None,
    /// Jtilde taken at the estimate, to be factorised on the next update.
    Pending(Matrix6<T>),
    /// LU factors of Jtilde at a recent estimate.
    Ready(Lu6<T>),
}

impl<T: Real> Factors<T> {
    /// The factors of `jt`, or None when it is singular.
    fn of(jt: &Matrix6<T>) -> Self {
        Lu6::new(jt).map_or(Factors::None, Factors::Ready)
    }
}

/// A kept step leaves more than this fraction of [`TRACK_RESIDUAL_MAX`] (or of the
/// tolerance, when larger): the factors are taken again (on the next tick's budget).
const TRACK_REFRESH_FRACTION: f64 = 0.125;

impl<T: Real> FkTracker<T> {
    /// Starts tracking: the full solver from `guess`.
    pub fn new<M: Mechanism<T> + ?Sized>(
        m: &M,
        q: &Joints<T>,
        branch: Branch,
        guess: &Pose<T>,
        cfg: &FkConfig<T>,
    ) -> Result<Self, FkError> {
        let s = forward(m, q, branch, guess, cfg)?;
        Ok(FkTracker {
            branch,
            sols: DoubleBuffer::new(s.solution, s.solution),
            residual: s.residual,
            factors: Factors::None,
            counts: TrackerCounts {
                full_solves: 1,
                ..TrackerCounts::default()
            },
        })
    }

    /// The current estimate of the pose.
    pub fn pose(&self) -> &Pose<T> {
        &self.solution().pose
    }

    /// Its inverse-kinematics solution.
    pub fn solution(&self) -> &Solution<T> {
        self.sols.current()
    }

    /// The largest joint residual of the estimate against the last readings (m or rad).
    pub fn residual(&self) -> T {
        self.residual
    }

    /// The steps, refreshes and full solves so far.
    pub fn counts(&self) -> &TrackerCounts {
        &self.counts
    }

    /// Follows new joint readings. On error the estimate is kept (and stays valid for the
    /// readings it was computed from).
    pub fn update<M: Mechanism<T> + ?Sized>(
        &mut self,
        m: &M,
        q: &Joints<T>,
        cfg: &FkConfig<T>,
    ) -> Result<Tracked, FkError> {
        if let Some(k) = q.iter().position(|x| !x.is_finite()) {
            return Err(FkError::NonFiniteInput { index: k as u8 });
        }
        let kinds = m.joint_kinds();
        let (r, ok, worst) = residual(&kinds, q, &self.solution().q(), cfg);
        if ok {
            self.residual = worst;
            return Ok(Tracked::Unchanged);
        }
        // The second half of a refresh: factorise the Jtilde taken on the last tick.
        if let Factors::Pending(jt) = &self.factors {
            self.factors = Factors::of(jt);
        }
        let accept = larger(
            larger(lit(TRACK_RESIDUAL_MAX), cfg.tol_angular),
            cfg.tol_linear,
        );
        let scale = m.length_scale();
        let (mut r, mut current) = (r, worst);
        for steps in 1..=TRACK_STEPS {
            // The first step with the factors in hand; a second one with fresh factors.
            let chord = steps == 1 && matches!(self.factors, Factors::Ready(_));
            if chord {
                self.counts.chord_steps += 1;
            } else {
                self.factors = Factors::of(&tripod_jacobian(self.solution()));
                self.counts.newton_steps += 1;
            }
            let Some((left, worst)) = self.step(m, q, &r, &kinds, cfg, scale) else {
                // No progress: at the rounding level already, keep what there is.
                if current <= accept {
                    self.residual = current;
                    return Ok(if steps > 1 {
                        Tracked::Stepped { steps: steps - 1 }
                    } else {
                        Tracked::Unchanged
                    });
                }
                continue;
            };
            r = left;
            current = worst;
            if worst <= accept {
                self.residual = worst;
                if worst > accept * lit(TRACK_REFRESH_FRACTION) {
                    // The residual no longer drops well: take Jtilde here (factorised on
                    // the next tick).
                    self.factors = Factors::Pending(tripod_jacobian(self.solution()));
                    self.counts.refreshes += 1;
                }
                return Ok(Tracked::Stepped { steps });
            }
        }
        let from = *self.pose();
        let s = forward(m, q, self.branch, &from, cfg)?;
        self.counts.full_solves += 1;
        *self.sols.spare_mut() = s.solution;
        self.sols.swap();
        self.residual = s.residual;
        self.factors = Factors::None;
        Ok(Tracked::Solved {
            iterations: s.iterations,
        })
    }

    /// One step with the factors in `self.factors` from the estimate (joint residual `r`):
    /// Jtilde Δx = Js Δq with Js at the estimate, limited in length and halved (up to
    /// [`TRACK_HALVINGS`] trials) while it leaves the branch or does not lower the
    /// residual. A kept step becomes the estimate; returns its residual and the largest
    /// component, or None when no trial improved.
    fn step<M: Mechanism<T> + ?Sized>(
        &mut self,
        m: &M,
        q: &Joints<T>,
        r: &Joints<T>,
        kinds: &[JointKind; 6],
        cfg: &FkConfig<T>,
        scale: T,
    ) -> Option<(Joints<T>, T)> {
        let Factors::Ready(lu) = &self.factors else {
            return None;
        };
        let dx = lu.solve(&serial_rhs(m, self.solution(), r));
        if !dx.iter().all(|x| x.is_finite()) {
            return None;
        }
        let (mut dv, mut dw) = limited_step(&dx, cfg);
        let current = weighted_norm(kinds, r, scale);
        let half = lit::<T>(0.5);
        let branch = self.branch;
        for _ in 0..TRACK_HALVINGS {
            let trial = self.pose().displaced(&dv, &dw);
            let slot = self.sols.spare_mut();
            if inverse_into(m, &trial, branch, slot).is_ok() {
                let (rt, _, worst) = residual(kinds, q, &slot.q(), cfg);
                if weighted_norm(kinds, &rt, scale) < current {
                    self.sols.swap();
                    return Some((rt, worst));
                }
            }
            dv *= half;
            dw *= half;
        }
        None
    }
}
