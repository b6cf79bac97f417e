//! The master's motion commands while following: pose targets and joint jogs. Both pass
//! the supervisor like any target (speed limits, path check, guards).

use kinematics_core::Mechanism;
use master_link::NackReason;
use num_traits::Float;
use servo::NUM_JOINTS;

use super::mode::{Jog, Mode};
use super::{Runtime, JOG_HORIZON_S};
use crate::controller::JogError;
use crate::modes::{next, Event};
use crate::scalar::Scalar;
use crate::wire;

fn jog_reason(e: JogError) -> NackReason {
    match e {
        JogError::NonFinite => NackReason::InvalidValue,
        JogError::NoSolution => NackReason::OutOfWorkspace,
    }
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// Whether targets are taken now (following), or why not.
    fn target_gate(&mut self, now_us: u64) -> Result<(), NackReason> {
        match next(self.mode.kind(), Event::Target, self.context(now_us)) {
            Ok(_) => Ok(()),
            Err(r) => {
                self.refusals = self.refusals.wrapping_add(1);
                Err(r.into())
            }
        }
    }

    /// Jog: while following, move joint `joint` at `velocity` (m/s or rad/s). The joint's
    /// target advances by velocity × the time since the last Jog of the same stream, and
    /// never leads the setpoint by more than velocity × JOG_HORIZON_S: the master's
    /// repeated Jog is a dead-man, and when Jogs stop the robot stops within that horizon.
    pub(super) fn jog(&mut self, joint: u8, velocity: f32, now_us: u64) -> Result<(), NackReason> {
        let j = usize::from(joint);
        if j >= NUM_JOINTS {
            return Err(NackReason::InvalidJoint);
        }
        if !velocity.is_finite() {
            return Err(NackReason::InvalidValue);
        }
        self.target_gate(now_us)?;
        let Mode::Following { ctl, jog } = &self.mode else {
            return Err(NackReason::InvalidState);
        };
        let lit = kinematics_core::scalar::lit::<S>;
        let setpoint = ctl.setpoint_joints().map_err(jog_reason)?;
        let horizon_us = (JOG_HORIZON_S * 1e6) as u64;
        // The other joints stay where the stream started, the jogged one advances.
        let (mut target, elapsed_us) = match jog {
            Some(s) if s.joint == j && now_us.saturating_sub(s.last_us) <= horizon_us => {
                (s.target, now_us.saturating_sub(s.last_us))
            }
            _ => (setpoint, horizon_us),
        };
        let here = setpoint.get(j).copied().ok_or(NackReason::InvalidJoint)?;
        let lead = lit(f64::from(velocity).abs() * JOG_HORIZON_S);
        let slot = target.get_mut(j).ok_or(NackReason::InvalidJoint)?;
        let advanced = *slot + lit(f64::from(velocity)) * lit(elapsed_us as f64 * 1e-6);
        *slot = Float::min(Float::max(advanced, here - lead), here + lead);
        let pose = ctl.joints_target(&target).map_err(jog_reason)?;
        let stamp = self.session.board_stamp(now_us);
        let Mode::Following { ctl, jog } = &mut self.mode else {
            return Err(NackReason::InvalidState);
        };
        if let Err(r) = ctl.submit(&pose, stamp, now_us) {
            let refused = wire::refused_target(&r, ctl.supervisor().config(), 0);
            self.refused.now = Some(refused);
            return Err(refused.reason);
        }
        self.refused.submitted(stamp, 0);
        *jog = Some(Jog {
            joint: j,
            last_us: now_us,
            target,
        });
        self.last_target_us = now_us;
        Ok(())
    }

    /// A pose target (wire units; master clock µs) while following.
    pub(super) fn target(
        &mut self,
        stamp_us: u64,
        position_m: [f32; 3],
        rotation_vector_rad: [f32; 3],
        now_us: u64,
    ) -> Result<(), NackReason> {
        let pose = wire::pose_from_wire::<S>(position_m, rotation_vector_rad)?;
        self.target_gate(now_us)?;
        let board_stamp = self.session.accept_target(stamp_us, now_us)?;
        let Mode::Following { ctl, jog } = &mut self.mode else {
            return Err(NackReason::InvalidState);
        };
        if let Err(r) = ctl.submit(&pose, board_stamp, now_us) {
            let refused = wire::refused_target(&r, ctl.supervisor().config(), stamp_us);
            self.refused.now = Some(refused);
            return Err(refused.reason);
        }
        self.refused.submitted(board_stamp, stamp_us);
        // A Cartesian target ends any jog stream.
        *jog = None;
        self.last_target_us = now_us;
        Ok(())
    }
}
