//! Design tools over the thesis's task (chapter 8): actuator forces along a path
//! (`forces --path`), the joint and force ranges over the task box (`ranges`) and the
//! reachable workspace's constant-height sections (`workspace`), the dimensional
//! synthesis scan (`synth`) and the RSPR/RRPS comparison (`compare`).
//!
//! Every file goes to `--out DIR`, by default `target/design/<command>/` (relative to the
//! working directory); mm, deg, N and N m at the edge, unit-suffixed column names.

pub mod compare;
pub mod forces_path;
pub mod ranges;
pub mod synth;
pub mod workspace;

use plotters::style::FontStyle;
use std::path::{Path, PathBuf};

/// The output directory: `--out` if given, else `target/design/<command>`; created.
pub fn out_dir(out: Option<&Path>, command: &str) -> Result<PathBuf, String> {
    let dir = match out {
        Some(d) => d.to_path_buf(),
        None => Path::new("target").join("design").join(command),
    };
    std::fs::create_dir_all(&dir)
        .map_err(|e| format!("cannot create the output directory {}: {e}", dir.display()))?;
    Ok(dir)
}

/// Writes a CSV file with a header.
pub fn write_csv(path: &Path, header: &[String], rows: &[Vec<String>]) -> Result<(), String> {
    let err = |e: csv::Error| format!("cannot write {}: {e}", path.display());
    let mut w = csv::Writer::from_path(path).map_err(err)?;
    w.write_record(header).map_err(err)?;
    for r in rows {
        w.write_record(r).map_err(err)?;
    }
    w.flush()
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Registers the embedded DejaVu Sans as "sans-serif" (as the simulation's plots do).
pub(crate) fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The embedded font is valid; a failure would only lose the text.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// A plotting error as a message.
pub(crate) fn perr<E: std::fmt::Display>(e: E) -> String {
    format!("plot: {e}")
}

/// The padded range of some values, for a plot axis.
pub(crate) fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() || !hi.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    (lo - pad, hi + pad)
}
