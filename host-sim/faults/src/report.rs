//! The campaign's matrix: printed (one row per kind, one column per condition), as CSV
//! (one row per cell) and as a PNG (the grid, green where the cell passed, red where not,
//! with the detection time, the motion and the requirements each cell checks).

use std::fmt::Write as _;
use std::path::Path;

use plots::plotters::prelude::*;
use plots::PlotError;
use serde::Serialize;
use thiserror::Error;

use crate::campaign::{Cell, Condition};
use crate::kinds::FaultKind;

/// A file of the report could not be written.
#[derive(Debug, Error)]
pub enum ReportError {
    #[error("{path}: {source}")]
    Csv { path: String, source: csv::Error },
    #[error("{path}: {source}")]
    Plot { path: String, source: PlotError },
}

/// The columns of the matrix, in order: every condition.
pub const COLUMNS: [Condition; 11] = Condition::ALL;

fn cell_of(cells: &[Cell], k: FaultKind, c: Condition) -> Option<&Cell> {
    cells.iter().find(|x| x.kind == k && x.condition == c)
}

/// One cell's text in the printed matrix: `ok 3 ms STO 0.19` or `FAIL ...`.
fn short(c: &Cell) -> String {
    let t = c
        .detect_ms
        .map_or("-".to_string(), |ms| format!("{ms:.0}ms"));
    format!(
        "{} {} {} {:.2}",
        if c.pass { "ok" } else { "FAIL" },
        t,
        c.reaction.name(),
        c.moved_mm
    )
}

/// The matrix as text: a row per kind (with its bound and expected reaction), a column
/// per condition; each cell `ok|FAIL, time to detect, the reaction, motion (mm)`; then
/// the failures with why.
pub fn matrix_text(cells: &[Cell]) -> String {
    let mut o = String::new();
    let kinds: Vec<FaultKind> = FaultKind::ALL
        .into_iter()
        .filter(|k| cells.iter().any(|c| c.kind == *k))
        .collect();
    let _ = write!(o, "{:<20} {:>7} {:>8}", "kind", "bound", "expect");
    for c in COLUMNS {
        let _ = write!(o, " | {:<22}", c.name());
    }
    o.push('\n');
    // What each column checks (a row of the link's frames checks SR-6 for SR-7).
    let _ = write!(o, "{:<20} {:>7} {:>8}", "checks", "", "");
    for c in COLUMNS {
        let ids: Vec<&str> = c
            .requirements(FaultKind::EncoderJump)
            .iter()
            .map(|r| r.id())
            .collect();
        let _ = write!(o, " | {:<22}", ids.join(" "));
    }
    o.push('\n');
    for k in kinds {
        let e = k.expectation();
        let _ = write!(
            o,
            "{:<20} {:>5}ms {:>8}",
            k.name(),
            e.bound_ms,
            e.reaction.name()
        );
        for c in COLUMNS {
            let text = cell_of(cells, k, c).map_or("n/a".to_string(), short);
            let _ = write!(o, " | {text:<22}");
        }
        o.push('\n');
    }
    let failed: Vec<&Cell> = cells.iter().filter(|c| !c.pass).collect();
    let _ = writeln!(
        o,
        "cells: {}, passed {}, failed {}",
        cells.len(),
        cells.len() - failed.len(),
        failed.len()
    );
    for c in failed {
        let _ = writeln!(
            o,
            "FAILED {} in {}: {} (noticed: {})",
            c.kind.name(),
            c.condition.name(),
            c.why,
            if c.noticed.is_empty() {
                "nothing"
            } else {
                &c.noticed
            }
        );
    }
    o
}

#[derive(Serialize)]
struct Row<'a> {
    kind: &'a str,
    condition: &'a str,
    detected: bool,
    detect_ms: Option<f64>,
    bound_ms: u64,
    noticed: &'a str,
    expected_reaction: &'a str,
    reaction: &'a str,
    final_stop: String,
    moved_mm: f64,
    allowed_mm: f64,
    before_mm: f64,
    before_allowed_mm: f64,
    requirements: &'a str,
    pass: bool,
    why: &'a str,
}

/// Writes the cells as CSV, one row per cell.
pub fn write_csv(cells: &[Cell], path: &Path) -> Result<(), ReportError> {
    let err = |source| ReportError::Csv {
        path: path.display().to_string(),
        source,
    };
    let mut w = csv::Writer::from_path(path).map_err(err)?;
    for c in cells {
        w.serialize(Row {
            kind: c.kind.name(),
            condition: c.condition.name(),
            detected: c.detected,
            detect_ms: c.detect_ms,
            bound_ms: c.bound_ms,
            noticed: &c.noticed,
            expected_reaction: c.expected.name(),
            reaction: c.reaction.name(),
            final_stop: format!("{:?}", c.final_stop),
            moved_mm: c.moved_mm,
            allowed_mm: c.allowed_mm,
            before_mm: c.before_mm,
            before_allowed_mm: c.before_allowed_mm,
            requirements: &c.requirements,
            pass: c.pass,
            why: &c.why,
        })
        .map_err(err)?;
    }
    w.flush().map_err(|e| err(csv::Error::from(e)))?;
    Ok(())
}

/// Draws the matrix as a PNG grid: a row per kind, a column per condition, green where
/// the cell passed, red where it failed, grey where it does not apply; each cell shows the
/// time to detect, the reaction and the motion afterwards.
pub fn write_png(cells: &[Cell], path: &Path) -> Result<(), ReportError> {
    plots::register_font();
    let err = |e: PlotError| ReportError::Plot {
        path: path.display().to_string(),
        source: e,
    };
    let kinds: Vec<FaultKind> = FaultKind::ALL
        .into_iter()
        .filter(|k| cells.iter().any(|c| c.kind == *k))
        .collect();
    let (label_w, cell_w, cell_h, head_h) = (190i32, 150i32, 40i32, 60i32);
    let width = label_w + cell_w * COLUMNS.len() as i32 + 10;
    let height = head_h + cell_h * kinds.len() as i32 + 40;
    let root = BitMapBackend::new(path, (width as u32, height as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(PlotError::new(e)))?;
    let font = ("sans-serif", 13).into_font();
    let small = ("sans-serif", 11).into_font();
    let bold = ("sans-serif", 15).into_font();
    let passed = cells.iter().filter(|c| c.pass).count();
    root.draw(&Text::new(
        format!(
            "fault-injection campaign: {passed} of {} cells pass (time to detect, reaction, motion after; the requirements each cell checks)",
            cells.len()
        ),
        (10, 10),
        bold.clone(),
    ))
    .map_err(|e| err(PlotError::new(e)))?;
    for (i, c) in COLUMNS.iter().enumerate() {
        let x = label_w + cell_w * i as i32;
        root.draw(&Text::new(c.name(), (x + 8, head_h - 22), bold.clone()))
            .map_err(|e| err(PlotError::new(e)))?;
    }
    for (r, k) in kinds.iter().enumerate() {
        let y = head_h + cell_h * r as i32;
        root.draw(&Text::new(k.name(), (8, y + 8), font.clone()))
            .map_err(|e| err(PlotError::new(e)))?;
        for (i, c) in COLUMNS.iter().enumerate() {
            let x = label_w + cell_w * i as i32;
            let (fill, text, checks) = match cell_of(cells, *k, *c) {
                Some(cell) => (
                    if cell.pass {
                        RGBColor(190, 235, 190)
                    } else {
                        RGBColor(245, 170, 170)
                    },
                    format!(
                        "{} {} {:.2}mm",
                        cell.detect_ms
                            .map_or("-".to_string(), |ms| format!("{ms:.0}ms")),
                        cell.reaction.name(),
                        cell.moved_mm
                    ),
                    cell.requirements.clone(),
                ),
                None => (RGBColor(225, 225, 225), "n/a".to_string(), String::new()),
            };
            root.draw(&Rectangle::new(
                [(x + 1, y + 1), (x + cell_w - 1, y + cell_h - 1)],
                fill.filled(),
            ))
            .map_err(|e| err(PlotError::new(e)))?;
            root.draw(&Text::new(text, (x + 6, y + 5), font.clone()))
                .map_err(|e| err(PlotError::new(e)))?;
            root.draw(&Text::new(checks, (x + 6, y + 22), small.clone()))
                .map_err(|e| err(PlotError::new(e)))?;
        }
    }
    root.present().map_err(|e| err(PlotError::new(e)))?;
    Ok(())
}
