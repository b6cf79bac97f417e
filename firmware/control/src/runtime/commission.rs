//! The `Commission` command: into the commissioning mode ([`crate::modes::next`]), a
//! joint's test started, its record read.

use kinematics_core::Mechanism;
use master_link::NackReason;
use servo::NUM_JOINTS;

use super::mode::Mode;
use super::Runtime;
use crate::commissioning::{JointTest, Readings};
use crate::link::Answer;
use crate::modes::Event;
use crate::scalar::Scalar;

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// `Commission { joint, confirm }`: the record of `joint`'s test when it is the one in
    /// hand; otherwise, once no test runs, `joint`'s test starts from where the joints
    /// stand (the mode entered first, as the table allows). The homing is lost: the test
    /// moves joints without a reference.
    pub(super) fn commission(
        &mut self,
        joint: u8,
        confirm: bool,
        now_us: u64,
    ) -> Result<Answer, NackReason> {
        let j = usize::from(joint);
        if j >= NUM_JOINTS {
            self.refusals = self.refusals.wrapping_add(1);
            return Err(NackReason::InvalidJoint);
        }
        if let Mode::Commissioning(test) = &self.mode {
            if test.joint() == j {
                return Ok(Answer::Commission(test.record()));
            }
            if !test.done() {
                self.refusals = self.refusals.wrapping_add(1);
                return Err(NackReason::Busy);
            }
        }
        self.apply(Event::Commission { confirm }, now_us)?;
        self.session.rearm(now_us);
        self.sensing.lose_reference();
        self.monitors.channel.restart();
        let m = self.sensing.measured();
        let r = Readings {
            motor: m.motor,
            absolute: m.absolute,
            current: self.inputs.currents,
            switches: self.inputs.switches,
            driver_fault: self.inputs.driver_fault,
        };
        let test = JointTest::start(self.cfg.commission, j, &r);
        self.mode = Mode::Commissioning(test);
        Ok(Answer::Commission(test.record()))
    }
}
