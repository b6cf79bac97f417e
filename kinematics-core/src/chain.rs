//! The three kinematic chains and per-chain storage that cannot be indexed out of bounds.

use core::fmt;
use core::ops::{Index, IndexMut};

/// One of the three kinematic chains. Chain i sits at ξ_i = 2π(i-1)/3 (Eq. 6.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Chain {
    One,
    Two,
    Three,
}

impl Chain {
    /// All chains in order.
    pub const ALL: [Chain; 3] = [Chain::One, Chain::Two, Chain::Three];

    /// Zero-based index (0, 1, 2).
    pub const fn index(self) -> usize {
        match self {
            Chain::One => 0,
            Chain::Two => 1,
            Chain::Three => 2,
        }
    }

    /// One-based number as in the thesis (1, 2, 3).
    pub const fn number(self) -> u8 {
        match self {
            Chain::One => 1,
            Chain::Two => 2,
            Chain::Three => 3,
        }
    }

    /// The chain with the given zero-based index, if any.
    pub const fn from_index(i: usize) -> Option<Chain> {
        match i {
            0 => Some(Chain::One),
            1 => Some(Chain::Two),
            2 => Some(Chain::Three),
            _ => None,
        }
    }

    /// Multiple of 2π/3 of the chain angle ξ_i = 2π(i-1)/3 (Eq. 6.3).
    pub(crate) const fn xi_thirds(self) -> u8 {
        match self {
            Chain::One => 0,
            Chain::Two => 1,
            Chain::Three => 2,
        }
    }
}

impl fmt::Display for Chain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "chain {}", self.number())
    }
}

/// Three values, one per chain, indexed by [`Chain`] (so never out of bounds).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PerChain<X>(pub [X; 3]);

impl<X> PerChain<X> {
    /// Builds the three values from a function of the chain.
    pub fn from_fn(mut f: impl FnMut(Chain) -> X) -> Self {
        PerChain([f(Chain::One), f(Chain::Two), f(Chain::Three)])
    }

    /// Builds the three values from a fallible function; the first error wins.
    pub fn try_from_fn<E>(mut f: impl FnMut(Chain) -> Result<X, E>) -> Result<Self, E> {
        Ok(PerChain([f(Chain::One)?, f(Chain::Two)?, f(Chain::Three)?]))
    }

    /// Iterates over `(chain, value)` pairs.
    pub fn iter(&self) -> impl Iterator<Item = (Chain, &X)> {
        Chain::ALL.into_iter().zip(self.0.iter())
    }

    /// Maps each value.
    pub fn map<Y>(&self, mut f: impl FnMut(Chain, &X) -> Y) -> PerChain<Y> {
        PerChain::from_fn(|c| f(c, &self[c]))
    }
}

impl<X> Index<Chain> for PerChain<X> {
    type Output = X;
    fn index(&self, c: Chain) -> &X {
        let [a, b, d] = &self.0;
        match c {
            Chain::One => a,
            Chain::Two => b,
            Chain::Three => d,
        }
    }
}

impl<X> IndexMut<Chain> for PerChain<X> {
    fn index_mut(&mut self, c: Chain) -> &mut X {
        let [a, b, d] = &mut self.0;
        match c {
            Chain::One => a,
            Chain::Two => b,
            Chain::Three => d,
        }
    }
}
