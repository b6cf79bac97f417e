//! The checker: one full guard evaluation at a time ([`Staged`], a stage per call), what
//! it is for, and the warm starts of the parallel measure's SVD, one per kind of pose (the
//! poses of each kind lie close together from one evaluation to the next).

use crate::branch::Branch;
use crate::guards::{Guards, Staged};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;
use crate::singularity::ConditionEstimator;

/// What the checker is evaluating.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Job {
    /// A sample of the pending path.
    Path,
    /// The end of the pending path (checked first).
    PathEnd,
    /// The braking point; `towards_next`: computed towards the next goal (a check that
    /// passes lets it replace the goal).
    Ahead { towards_next: bool },
    /// The goal, to certify the region around it (when nothing else waits).
    Refresh,
}

/// The checker's evaluation in progress and its warm starts.
#[derive(Clone, Debug)]
pub(super) struct Checker<T: Real> {
    /// The full evaluation in progress (or the last one, finished).
    pub staged: Staged<T>,
    /// What it is for; None when idle.
    pub job: Option<Job>,
    /// The next job goes to the path check (else to the braking point) when both wait.
    pub path_turn: bool,
    cond_path: ConditionEstimator<T>,
    cond_path_end: ConditionEstimator<T>,
    cond_ahead: ConditionEstimator<T>,
}

impl<T: Real> Checker<T> {
    /// An idle checker for `branch`, the path check's turn first.
    pub fn new(branch: Branch) -> Self {
        Checker {
            staged: Staged::new(branch),
            job: None,
            path_turn: true,
            cond_path: ConditionEstimator::new(),
            cond_path_end: ConditionEstimator::new(),
            cond_ahead: ConditionEstimator::new(),
        }
    }

    /// Starts evaluating `pose` for `job`; the other kind of job has the next turn.
    pub fn begin(&mut self, pose: &Pose<T>, job: Job) {
        self.staged.start(pose);
        self.job = Some(job);
        self.path_turn = matches!(job, Job::Ahead { .. });
    }

    /// Drops a path check in progress (its path is gone).
    pub fn drop_path_job(&mut self) {
        if matches!(self.job, Some(Job::Path | Job::PathEnd)) {
            self.job = None;
        }
    }

    /// Runs one stage of the job in progress, with the warm start of its kind of pose.
    /// Returns the job when its evaluation has finished (the checker is then idle).
    pub fn advance<M: Mechanism<T>>(&mut self, guards: &Guards<T, M>) -> Option<Job> {
        let job = self.job?;
        let cond = match job {
            Job::Path => &mut self.cond_path,
            Job::PathEnd | Job::Refresh => &mut self.cond_path_end,
            Job::Ahead { .. } => &mut self.cond_ahead,
        };
        guards.advance(&mut self.staged, cond);
        if !self.staged.is_finished() {
            return None;
        }
        self.job = None;
        Some(job)
    }
}
