//! The text report of an identification, the calibrated geometry file and the residual
//! plots.
