//! `design`: the host's design tools. For now the kinematics of the RRPS robot that
//! `host-sim compare` sets against the RSPR ([`rrps`]); host-only, so out of the no_std
//! `kinematics-core`.

pub mod rrps;
