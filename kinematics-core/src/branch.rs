//! Inverse-kinematics branches: a 3-bit choice, one bit per chain, chain 1 in bit 0.

use crate::chain::Chain;
use core::fmt;

/// One of the 8 inverse-kinematics solutions (CONVENTIONS.md, "Branches").
///
/// RSPR: bit clear = "outer" (the root of Eq. 6.22 with the larger t along v_i), set =
/// "inner". USR: bit clear = the root of Eq. 6.32 with the larger wrapped γ_i, set = the
/// smaller. The prototype runs all-outer, [`Branch::OUTER`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Branch(u8);

/// A branch number outside 0..=7.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BranchOutOfRange(pub u32);

impl fmt::Display for BranchOutOfRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "branch {} is out of range 0..=7", self.0)
    }
}

impl Branch {
    /// All chains on the outer (bit clear) solution: the prototype's branch.
    pub const OUTER: Branch = Branch(0);

    /// All eight branches, 0..=7.
    pub const ALL: [Branch; 8] = [
        Branch(0),
        Branch(1),
        Branch(2),
        Branch(3),
        Branch(4),
        Branch(5),
        Branch(6),
        Branch(7),
    ];

    /// The branch with the given number (0..=7).
    pub const fn new(bits: u32) -> Result<Branch, BranchOutOfRange> {
        if bits < 8 {
            Ok(Branch(bits as u8))
        } else {
            Err(BranchOutOfRange(bits))
        }
    }

    /// The branch number 0..=7.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// True when the chain's bit is set (the "inner" RSPR root, the smaller USR γ).
    pub const fn is_set(self, chain: Chain) -> bool {
        (self.0 >> chain.index()) & 1 == 1
    }
}

impl fmt::Display for Branch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}
