//! Either robot, for code that picks the architecture at run time (the command line, the
//! geometry files): the symmetric RSPR, the USR, or the RSPR with per-chain dimensions.

use crate::chain::Chain;
use crate::chain_geometry::PerChainGeometry;
use crate::geometry::{RsprGeometry, UsrGeometry};
use crate::mechanism::{
    ChainSolution, IkFailure, JointKind, Mechanism, PlatformChain, SerialBlock,
};
use crate::pose::Pose;
use crate::scalar::Real;

/// Which architecture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RobotKind {
    Rspr,
    Usr,
}

/// Either robot, for code that picks the architecture at run time (the CLI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Robot<T: Real> {
    Rspr(RsprGeometry<T>),
    Usr(UsrGeometry<T>),
    /// An RSPR with per-chain dimensions and encoder zero offsets (a calibrated robot).
    RsprPerChain(PerChainGeometry<T>),
}

impl<T: Real> Robot<T> {
    /// The architecture.
    pub fn kind(&self) -> RobotKind {
        match self {
            Robot::Rspr(_) | Robot::RsprPerChain(_) => RobotKind::Rspr,
            Robot::Usr(_) => RobotKind::Usr,
        }
    }
}

/// Dispatches a `Mechanism` method to the variant's geometry.
macro_rules! each {
    ($self:ident, $g:ident => $e:expr) => {
        match $self {
            Robot::Rspr($g) => $e,
            Robot::Usr($g) => $e,
            Robot::RsprPerChain($g) => $e,
        }
    };
}

impl<T: Real> Mechanism<T> for Robot<T> {
    fn rp(&self) -> T {
        each!(self, g => g.rp())
    }
    fn e(&self) -> T {
        each!(self, g => Mechanism::e(g))
    }
    fn hc(&self) -> T {
        each!(self, g => g.hc())
    }
    fn joint_kinds(&self) -> [JointKind; 6] {
        each!(self, g => g.joint_kinds())
    }
    fn length_scale(&self) -> T {
        each!(self, g => g.length_scale())
    }
    fn platform_chain(&self, pose: &Pose<T>, chain: Chain) -> PlatformChain<T> {
        each!(self, g => g.platform_chain(pose, chain))
    }
    fn chain_ik(
        &self,
        chain: Chain,
        pc: &PlatformChain<T>,
        bit_set: bool,
        out: &mut ChainSolution<T>,
    ) -> Result<(), IkFailure> {
        each!(self, g => g.chain_ik(chain, pc, bit_set, out))
    }
    fn serial_block(&self, s: &ChainSolution<T>) -> SerialBlock<T> {
        each!(self, g => g.serial_block(s))
    }
    fn serial_measure(&self, s: &ChainSolution<T>) -> (T, T) {
        each!(self, g => g.serial_measure(s))
    }
}
