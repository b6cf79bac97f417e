//! The status report, from what the last tick computed.

use kinematics_core::Mechanism;
use master_link::{GuardMargins, StatusReport, Warnings};
use num_traits::Float;

use super::Runtime;
use crate::controller::Controller;
use crate::scalar::Scalar;
use crate::wire;

/// The guard margins at the setpoint, and the warnings they raise.
fn margins<S: Scalar, M: Mechanism<S> + Clone>(
    c: &Controller<S, M>,
    warnings: &mut Warnings,
) -> GuardMargins {
    let sup = c.supervisor();
    let (sing, limits) = (sup.margins(), sup.guards().limits());
    let k = sup.setpoint_margins();
    let parallel = (sing.parallel - limits.parallel.stop) / (S::one() - limits.parallel.stop);
    let mut m = GuardMargins {
        nearest: f32::NAN,
        serial: wire::to_f32(k.serial),
        parallel: wire::to_f32(parallel),
        stroke: wire::to_f32(Float::min(k.stroke, k.link_angle)),
        tilt: wire::to_f32(k.tilt),
        collision: wire::to_f32(k.collision),
        workspace: wire::to_f32(k.workspace),
    };
    m.nearest = [
        m.serial,
        m.parallel,
        m.stroke,
        m.tilt,
        m.collision,
        m.workspace,
    ]
    .iter()
    .fold(
        f32::INFINITY,
        |a, x| if *x < a || x.is_nan() { *x } else { a },
    );
    warnings.set(
        Warnings::NEAR_SERIAL_SINGULARITY,
        sing.serial < limits.serial.warn,
    );
    warnings.set(
        Warnings::NEAR_PARALLEL_SINGULARITY,
        sing.parallel < limits.parallel.warn,
    );
    warnings.set(
        Warnings::NEAR_JOINT_LIMIT,
        Float::min(k.stroke, k.link_angle) < kinematics_core::scalar::lit(0.1),
    );
    m
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// The status report of the last tick: the measured pose and joints (NaN until
    /// homed), the setpoint and the guard margins at it (NaN while the supervisor does not
    /// run), the stop in force, the latched fault with its cause, joint and value, the
    /// reset, the currents and the supply, warnings and timing. The link counters are
    /// added as it goes out ([`crate::telemetry::with_link`]).
    pub fn status(&self) -> StatusReport {
        let m = self.sensing.measured();
        let nan = f32::NAN;
        let nan3 = [nan; 3];
        let (position_m, rotation_vector_rad) =
            m.pose.map_or((nan3, nan3), |p| wire::pose_to_wire(&p));
        let f32s = |a: &[S; servo::NUM_JOINTS]| a.map(wire::to_f32);
        let mut warnings = self.warnings;
        let ctl = self.controller();
        let unknown = GuardMargins {
            nearest: nan,
            serial: nan,
            parallel: nan,
            stroke: nan,
            tilt: nan,
            collision: nan,
            workspace: nan,
        };
        let margins = ctl.map_or(unknown, |c| margins(c, &mut warnings));
        let (setpoint_p, setpoint_r) = ctl.map_or((nan3, nan3), |c| {
            wire::pose_to_wire(c.supervisor().setpoint())
        });
        StatusReport {
            state: self.state(),
            position_m,
            rotation_vector_rad,
            joints: f32s(&m.q),
            warnings,
            faults: self
                .mode
                .latched()
                .map_or(master_link::Faults::NONE, |l| l.faults),
            serial_singularity_margin: ctl
                .map_or(nan, |c| wire::to_f32(c.supervisor().margins().serial)),
            parallel_singularity_margin: ctl
                .map_or(nan, |c| wire::to_f32(c.supervisor().margins().parallel)),
            link: Default::default(),
            tick_jitter_max_us: self.tick_timing.0,
            tick_exec_max_us: self.tick_timing.1,
            targets_refused: ctl.map_or(0, |c| c.supervisor().counters().refused()),
            stop: self.mode.stop_status(),
            fault: self.latched_fault(),
            reset: self.reset,
            setpoint_position_m: setpoint_p,
            setpoint_rotation_vector_rad: setpoint_r,
            margins,
            currents_a: f32s(&self.inputs.currents),
            supply_v: wire::to_f32(self.inputs.supply_v),
            fault_log_len: u16::try_from(self.log.len()).unwrap_or(u16::MAX),
            missed_ticks: self.missed_ticks,
            owner_changes: self.session.owner_changes(),
        }
    }
}
