//! The console (see `host-sim console`).
