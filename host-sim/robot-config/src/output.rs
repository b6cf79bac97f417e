//! Where the host tools write their files: one rule for every tool.
//!
//! A tool writes to the directory its `--out DIR` names, else to `target/<tool>/` under
//! the current directory (`target/sim/<scenario>/`, `target/faults/`,
//! `target/replay/<recording>/`, `target/calibration/`, `target/teleop/<scenario>/`,
//! `target/design/<command>/`). The current directory, not the binary's own build
//! directory: a person who runs the tool finds its files where they stand, whichever way
//! the binary was built or installed.

use std::path::{Path, PathBuf};

/// The root of every tool's default output directory, relative to the current directory.
pub const ROOT: &str = "target";

/// The default output directory of a tool: `target/` joined with `parts`
/// (e.g. `["sim", "laparoscope"]`).
pub fn default_dir(parts: &[&str]) -> PathBuf {
    parts
        .iter()
        .fold(Path::new(ROOT).to_path_buf(), |d, p| d.join(p))
}

/// `out` if given, else [`default_dir`] of `parts`.
pub fn out_dir(out: Option<&Path>, parts: &[&str]) -> PathBuf {
    out.map_or_else(|| default_dir(parts), Path::to_path_buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_is_relative_to_the_current_directory_and_out_wins() {
        assert_eq!(
            default_dir(&["sim", "step"]),
            PathBuf::from("target/sim/step")
        );
        assert!(default_dir(&["faults"]).is_relative());
        assert_eq!(
            out_dir(Some(Path::new("/tmp/x")), &["faults"]),
            PathBuf::from("/tmp/x")
        );
    }
}
