//! The certified regions ([`crate::guards::certificate`]): every full evaluation without a
//! stop-level violation certifies a region around its pose (a Lipschitz bound of every
//! stop-level guard's margin along straight motions); the newest two are kept. A target
//! whose whole segment lies in one is accepted without a path check, a braking point whose
//! whole stretch from the setpoint lies in one passes without an evaluation of its own,
//! and a setpoint inside one is solved without the kinematic guards: the region's
//! guarantee covers every pose of those straight motions, not only samples of them.

use crate::guards::Guard;
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;

use super::state::Supervisor;

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// Whether a certified region contains `pose`.
    pub(super) fn in_certified_region(&self, pose: &Pose<T>) -> bool {
        self.certs.iter().flatten().any(|c| c.contains(pose))
    }

    /// Whether a certified region (the newest two) contains the whole straight motion
    /// `from` → `to`: then no pose of it violates a stop-level guard; the region's centre
    /// warning, if any.
    pub(super) fn certified(&self, from: &Pose<T>, to: &Pose<T>) -> Option<Option<Guard>> {
        self.certs
            .iter()
            .flatten()
            .find(|c| c.contains_motion(from, to))
            .map(|c| c.warn)
    }

    /// The checker's evaluation finished without a stop-level violation: the region it
    /// certifies becomes the newest of the two kept.
    pub(super) fn keep_certificate(&mut self) {
        let cert = self
            .checker
            .staged
            .full()
            .and_then(|e| self.guards.certify(&e));
        if let Some(c) = cert {
            self.certs = [Some(c), self.certs[0]];
        }
    }
}
