//! `plots`: the PNG line charts of the host tools, drawn once for all of them.
//!
//! - [`register_font`]: the embedded DejaVu Sans as "sans-serif" (no system fonts needed);
//! - [`span`]: the padded range of some values, for an axis;
//! - [`line_charts`]: a PNG of one or more [`Panel`]s of line [`Series`] under a title,
//!   stacked or side by side ([`Layout`]);
//! - [`PlotError`]: what the drawing backend reported.
//!
//! The tools that need more (the workspace's 3-D boundary view) draw with `plotters`
//! directly and use [`register_font`], [`span`] and [`PlotError`].

use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;
use thiserror::Error;

pub use plotters;

/// A drawing failure (the backend's message: an unwritable file, a bad range, ...).
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("plot: {message}")]
pub struct PlotError {
    /// What the backend reported.
    pub message: String,
}

impl PlotError {
    /// A drawing failure from the backend's error.
    pub fn new(e: impl std::fmt::Display) -> Self {
        PlotError {
            message: e.to_string(),
        }
    }
}

/// One colour per chain (chains 1, 2, 3): red, blue, green.
pub const CHAIN_COLORS: [RGBColor; 3] = [RED, BLUE, RGBColor(0, 130, 0)];

/// Registers the embedded DejaVu Sans as "sans-serif" (once per process).
pub fn register_font() {
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

/// The range of the finite values, padded by 5 % (at least 1e-3) on each side; (-1, 1)
/// when there is none.
pub fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
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

/// One line of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    /// The legend's label; `None` keeps the line out of the legend.
    pub label: Option<String>,
    /// The points, in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Colour and width (also the legend's).
    pub style: ShapeStyle,
}

impl Series {
    /// A line of `color` and `width` pixels with a legend entry.
    pub fn new(
        label: impl Into<String>,
        points: Vec<(f64, f64)>,
        color: impl Color,
        width: u32,
    ) -> Self {
        Series {
            label: Some(label.into()),
            points,
            style: color.stroke_width(width),
        }
    }
}

/// One chart: its axes and lines.
#[derive(Clone, Debug)]
pub struct Panel {
    /// A caption above the chart.
    pub caption: Option<String>,
    /// The axis descriptions.
    pub x_desc: String,
    pub y_desc: String,
    /// The axis ranges.
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    pub series: Vec<Series>,
}

/// How the panels share the picture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// One above the other.
    Stacked,
    /// Side by side.
    SideBySide,
}

/// Draws `panels` under `title` into the PNG at `path` (`size` in pixels). A panel with
/// labelled series gets a legend.
pub fn line_charts(
    path: &Path,
    size: (u32, u32),
    title: &str,
    panels: &[Panel],
    layout: Layout,
) -> Result<(), PlotError> {
    register_font();
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(PlotError::new)?;
    let root = root
        .titled(title, ("sans-serif", 20))
        .map_err(PlotError::new)?;
    let n = panels.len().max(1);
    let areas = match layout {
        Layout::Stacked => root.split_evenly((n, 1)),
        Layout::SideBySide => root.split_evenly((1, n)),
    };
    for (area, panel) in areas.iter().zip(panels) {
        let mut builder = ChartBuilder::on(area);
        builder
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        if let Some(caption) = &panel.caption {
            builder.caption(caption, ("sans-serif", 18));
        }
        let (x0, x1) = panel.x_range;
        let (y0, y1) = panel.y_range;
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(PlotError::new)?;
        chart
            .configure_mesh()
            .x_desc(panel.x_desc.as_str())
            .y_desc(panel.y_desc.as_str())
            .draw()
            .map_err(PlotError::new)?;
        for s in &panel.series {
            let drawn = chart
                .draw_series(LineSeries::new(s.points.iter().copied(), s.style))
                .map_err(PlotError::new)?;
            if let Some(label) = &s.label {
                let style = s.style;
                drawn
                    .label(label.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
            }
        }
        if panel.series.iter().any(|s| s.label.is_some()) {
            chart
                .configure_series_labels()
                .border_style(BLACK)
                .background_style(WHITE.mix(0.8))
                .draw()
                .map_err(PlotError::new)?;
        }
    }
    root.present().map_err(PlotError::new)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn spans_pad_the_finite_values() {
        let (lo, hi) = span([1.0, 3.0, f64::NAN, f64::INFINITY].into_iter());
        assert!(
            (lo - 0.9).abs() < 1e-12 && (hi - 3.1).abs() < 1e-12,
            "{lo} {hi}"
        );
        let (lo, hi) = span([2.0].into_iter());
        assert!((lo - (2.0 - 1e-3)).abs() < 1e-15 && (hi - (2.0 + 1e-3)).abs() < 1e-15);
        assert_eq!(span(std::iter::empty()), (-1.0, 1.0));
        assert_eq!(span([f64::NAN].into_iter()), (-1.0, 1.0));
    }

    #[test]
    fn panels_become_a_png() {
        let dir = std::env::temp_dir().join(format!("plots-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("chart.png");
        let line = |k: f64| (0..10).map(|i| (f64::from(i), k * f64::from(i))).collect();
        let panel = |caption: Option<&str>| Panel {
            caption: caption.map(String::from),
            x_desc: "x".into(),
            y_desc: "y".into(),
            x_range: (0.0, 9.0),
            y_range: span((0..10).map(|i| 2.0 * f64::from(i))),
            series: vec![
                Series::new("one", line(1.0), CHAIN_COLORS[0], 2),
                Series {
                    label: None,
                    points: line(2.0),
                    style: BLUE.stroke_width(1),
                },
            ],
        };
        line_charts(
            &path,
            (400, 300),
            "test",
            &[panel(None), panel(Some("second"))],
            Layout::Stacked,
        )
        .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"));
        let e = line_charts(
            &dir.join("missing").join("chart.png"),
            (400, 300),
            "test",
            &[panel(None)],
            Layout::SideBySide,
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("plot: "), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
