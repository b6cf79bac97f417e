//! The files of the design tools: the output directory and CSV and text files, and what
//! stops a tool writing its output.

use plots::PlotError;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// An output directory or file that cannot be written.
#[derive(Debug, Error)]
pub enum FileError {
    #[error("cannot create the output directory {}: {source}", dir.display())]
    CreateDir {
        dir: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {}: {source}", path.display())]
    WriteCsv { path: PathBuf, source: csv::Error },
}

/// A tool's output that cannot be written: a file or a plot.
#[derive(Debug, Error)]
pub enum OutputError {
    #[error(transparent)]
    File(#[from] FileError),
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// The output directory: `out` if given, else `target/design/<command>`; created.
pub fn out_dir(out: Option<&Path>, command: &str) -> Result<PathBuf, FileError> {
    let dir = match out {
        Some(d) => d.to_path_buf(),
        None => Path::new("target").join("design").join(command),
    };
    std::fs::create_dir_all(&dir).map_err(|source| FileError::CreateDir {
        dir: dir.clone(),
        source,
    })?;
    Ok(dir)
}

/// Writes a CSV file with a header.
pub fn write_csv(path: &Path, header: &[String], rows: &[Vec<String>]) -> Result<(), FileError> {
    let err = |source: csv::Error| FileError::WriteCsv {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_path(path).map_err(err)?;
    w.write_record(header).map_err(err)?;
    for r in rows {
        w.write_record(r).map_err(err)?;
    }
    w.flush().map_err(|source| FileError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes a text file.
pub fn write_text(path: &Path, text: &str) -> Result<(), FileError> {
    std::fs::write(path, text).map_err(|source| FileError::Write {
        path: path.to_path_buf(),
        source,
    })
}
