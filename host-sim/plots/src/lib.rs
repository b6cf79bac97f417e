//! `plots`: the PNG line charts of the host tools, drawn once for all of them.
//!
//! - [`register_font`]: the embedded DejaVu Sans as "sans-serif" (no system fonts needed);
//! - [`span`]: the padded range of some values, for an axis;
//! - [`line_charts`]: a PNG of one or more [`Panel`]s of line [`Series`] under a title,
//!   stacked or side by side ([`Layout`]);
//! - [`PlotError`]: what the drawing backend reported.
//!
//! What every chart does, so that a person reads it at a glance: a line is never drawn
//! across a gap (a non-finite point splits a series, [`segments`]; [`break_gaps`] inserts
//! one where the samples stop for longer than a bound); a panel's warn and stop levels
//! ([`Level`]) are dashed lines with their value and unit in the legend; intervals (passes,
//! holds, clutch periods: [`Band`]) are shaded behind the lines (at least 3 pixels wide); a series without data gets
//! no legend entry ([`legend_entries`]); the legend sits in the corner with the fewest
//! points ([`legend_corner`]); [`PALETTE`] gives distinct colours.
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

/// Ten colours told apart at a glance (Tableau 10): blue, orange, green, red, purple,
/// brown, pink, grey, olive, cyan.
pub const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// A horizontal level of a panel (a warn or a stop threshold): a dashed line across it,
/// its label (with the value and unit) in the legend.
#[derive(Clone, Debug)]
pub struct Level {
    pub label: String,
    pub y: f64,
    pub color: RGBColor,
}

/// An interval of x shaded behind the lines (a pass, a hold, a clutch period); its label
/// is in the legend once however many intervals carry it.
#[derive(Clone, Debug)]
pub struct Band {
    pub label: String,
    pub x: (f64, f64),
    pub color: RGBColor,
}

/// The runs of finite points of `points`: a non-finite x or y ends a run, so that no line
/// is drawn across it.
pub fn segments(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut run: Vec<(f64, f64)> = Vec::new();
    for &(x, y) in points {
        if x.is_finite() && y.is_finite() {
            run.push((x, y));
        } else if !run.is_empty() {
            out.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        out.push(run);
    }
    out
}

/// `points` with a non-finite point inserted wherever x advances by more than `max_gap`
/// (samples that stopped: an idle link, a paused stream), so that [`segments`] splits
/// the line there.
pub fn break_gaps(points: Vec<(f64, f64)>, max_gap: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(points.len());
    let mut last: Option<f64> = None;
    for (x, y) in points {
        if let Some(l) = last {
            if x - l > max_gap {
                out.push((f64::NAN, f64::NAN));
            }
        }
        if x.is_finite() {
            last = Some(x);
        }
        out.push((x, y));
    }
    out
}

/// The intervals of x where `flag` holds, from samples `(x, flag)` in order: an interval
/// runs from the first sample that holds to the first that does not (or the last sample).
pub fn intervals(samples: &[(f64, bool)]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut start: Option<f64> = None;
    for &(x, on) in samples {
        match (start, on) {
            (None, true) => start = Some(x),
            (Some(s), false) => {
                out.push((s, x));
                start = None;
            }
            _ => {}
        }
    }
    if let (Some(s), Some(&(x, _))) = (start, samples.last()) {
        out.push((s, x));
    }
    out
}

/// The legend's entries of a panel, in drawing order: each band label once, each series
/// with a label and at least one finite point, each level.
pub fn legend_entries(panel: &Panel) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for b in &panel.bands {
        if !out.contains(&b.label) {
            out.push(b.label.clone());
        }
    }
    for s in &panel.series {
        if let Some(l) = &s.label {
            if !segments(&s.points).is_empty() {
                out.push(l.clone());
            }
        }
    }
    out.extend(panel.levels.iter().map(|l| l.label.clone()));
    out
}

/// A corner of a panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corner {
    UpperRight,
    UpperLeft,
    LowerRight,
    LowerLeft,
}

/// The corner whose quarter of the panel (40 % of each range from that corner) holds the
/// fewest points of the series and levels, and how many it holds: where the legend hides
/// the least data. Ties go to the first in [`Corner`]'s order.
pub fn legend_corner(panel: &Panel) -> (Corner, usize) {
    let (x0, x1) = panel.x_range;
    let (y0, y1) = panel.y_range;
    let (wx, wy) = ((x1 - x0) * 0.4, (y1 - y0) * 0.4);
    let inside = |c: Corner, (x, y): (f64, f64)| {
        let right = x >= x1 - wx;
        let left = x <= x0 + wx;
        let upper = y >= y1 - wy;
        let lower = y <= y0 + wy;
        match c {
            Corner::UpperRight => right && upper,
            Corner::UpperLeft => left && upper,
            Corner::LowerRight => right && lower,
            Corner::LowerLeft => left && lower,
        }
    };
    let points: Vec<(f64, f64)> = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .chain(panel.levels.iter().flat_map(|l| {
            // A level crosses the whole panel: sample it across.
            (0..=20).map(move |k| (x0 + (x1 - x0) * f64::from(k) / 20.0, l.y))
        }))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    let corners = [
        Corner::UpperRight,
        Corner::UpperLeft,
        Corner::LowerRight,
        Corner::LowerLeft,
    ];
    let count = |c: Corner| points.iter().filter(|p| inside(c, **p)).count();
    corners
        .into_iter()
        .map(|c| (c, count(c)))
        .min_by_key(|(_, n)| *n)
        .unwrap_or((Corner::UpperRight, 0))
}

/// Height of one legend row and the legend's frame, pixels.
const LEGEND_ROW_PX: f64 = 20.0;
const LEGEND_FRAME_PX: f64 = 16.0;

/// Where the legend goes and the y range that leaves it room: the corner with the fewest
/// points ([`legend_corner`]); when every corner holds data, the y range is raised so that
/// the legend (its rows of [`LEGEND_ROW_PX`]) fits above the data on a plot
/// `plot_height_px` high, upper right.
pub fn legend_placement(panel: &Panel, plot_height_px: f64) -> (Corner, (f64, f64)) {
    let (corner, points) = legend_corner(panel);
    let rows = legend_entries(panel).len() as f64;
    if points == 0 || rows == 0.0 {
        return (corner, panel.y_range);
    }
    let (y0, y1) = panel.y_range;
    let frac = (rows * LEGEND_ROW_PX + LEGEND_FRAME_PX + 10.0) / plot_height_px.max(1.0);
    if frac >= 0.6 {
        // Too many rows to make room for: the least-covered corner.
        return (corner, panel.y_range);
    }
    (
        Corner::UpperRight,
        (y0, y1 + (y1 - y0) * frac / (1.0 - frac)),
    )
}

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
    /// Warn and stop levels (dashed, in the legend).
    pub levels: Vec<Level>,
    /// Shaded intervals of x (behind the lines, in the legend).
    pub bands: Vec<Band>,
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
        // The plot's height: the area less the x labels, the caption and the margins.
        let plot_px = f64::from(area.dim_in_pixel().1)
            - 40.0
            - 24.0
            - if panel.caption.is_some() { 30.0 } else { 0.0 };
        let (corner, (y0, y1)) = legend_placement(panel, plot_px);
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(PlotError::new)?;
        chart
            .configure_mesh()
            .x_desc(panel.x_desc.as_str())
            .y_desc(panel.y_desc.as_str())
            .draw()
            .map_err(PlotError::new)?;
        let mut banded: Vec<&str> = Vec::new();
        // A band narrower than 3 pixels is drawn 3 pixels wide about its middle, so that
        // a short interval shows.
        let (px, _) = area.dim_in_pixel();
        let least = 3.0 * (x1 - x0) / f64::from(px.max(1));
        for b in &panel.bands {
            let (mut a, mut z) = b.x;
            if z - a < least {
                let mid = 0.5 * (a + z);
                (a, z) = (mid - 0.5 * least, mid + 0.5 * least);
            }
            let (a, z) = (a.max(x0), z.min(x1));
            if a.partial_cmp(&z) != Some(std::cmp::Ordering::Less) {
                continue;
            }
            let drawn = chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(a, y0), (z, y1)],
                    b.color.mix(0.18).filled(),
                )))
                .map_err(PlotError::new)?;
            if !banded.contains(&b.label.as_str()) {
                banded.push(b.label.as_str());
                let c = b.color.mix(0.35).filled();
                drawn
                    .label(b.label.as_str())
                    .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], c));
            }
        }
        for s in &panel.series {
            let runs = segments(&s.points);
            let mut first = true;
            for run in &runs {
                let drawn = chart
                    .draw_series(LineSeries::new(run.iter().copied(), s.style))
                    .map_err(PlotError::new)?;
                if let (true, Some(label)) = (first, &s.label) {
                    let style = s.style;
                    drawn
                        .label(label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                }
                first = false;
            }
        }
        for l in &panel.levels {
            let style = l.color.stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new([(x0, l.y), (x1, l.y)], 8, 5, style))
                .map_err(PlotError::new)?
                .label(l.label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
        if !legend_entries(panel).is_empty() {
            let position = match corner {
                Corner::UpperRight => SeriesLabelPosition::UpperRight,
                Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
                Corner::LowerRight => SeriesLabelPosition::LowerRight,
                Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
            };
            chart
                .configure_series_labels()
                .position(position)
                .label_font(("sans-serif", 15))
                .border_style(BLACK)
                .background_style(WHITE.mix(0.85))
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

    /// A gap splits a line: no segment spans a non-finite point, and `break_gaps` puts
    /// one wherever the samples stop for longer than the bound (here a 6 s idle gap).
    #[test]
    fn a_gap_splits_a_series() {
        let pts = vec![(0.0, 1.0), (0.1, 2.0), (6.1, 3.0), (6.2, 4.0)];
        let broken = break_gaps(pts.clone(), 0.5);
        let runs = segments(&broken);
        assert_eq!(
            runs,
            vec![vec![(0.0, 1.0), (0.1, 2.0)], vec![(6.1, 3.0), (6.2, 4.0)]]
        );
        assert_eq!(segments(&break_gaps(pts.clone(), 10.0)), vec![pts]);
        assert!(segments(&[(f64::NAN, 1.0)]).is_empty());
    }

    #[test]
    fn intervals_of_a_flag() {
        let s = [
            (0.0, false),
            (1.0, true),
            (2.0, true),
            (3.0, false),
            (4.0, true),
        ];
        assert_eq!(intervals(&s), vec![(1.0, 3.0), (4.0, 4.0)]);
        assert!(intervals(&[]).is_empty());
    }

    fn bare(series: Vec<Series>) -> Panel {
        Panel {
            caption: None,
            x_desc: "x".into(),
            y_desc: "y".into(),
            x_range: (0.0, 10.0),
            y_range: (0.0, 10.0),
            series,
            levels: Vec::new(),
            bands: Vec::new(),
        }
    }

    /// An empty or all-NaN series has no legend entry; levels and bands have one each.
    #[test]
    fn empty_series_stay_out_of_the_legend() {
        let mut p = bare(vec![
            Series::new("data", vec![(1.0, 1.0)], RED, 1),
            Series::new("empty", Vec::new(), BLUE, 1),
            Series::new("nan", vec![(1.0, f64::NAN)], BLUE, 1),
        ]);
        p.levels.push(Level {
            label: "warn 10 %".into(),
            y: 1.0,
            color: RED,
        });
        for x in [(1.0, 2.0), (3.0, 4.0)] {
            p.bands.push(Band {
                label: "hold".into(),
                x,
                color: BLUE,
            });
        }
        assert_eq!(legend_entries(&p), vec!["hold", "data", "warn 10 %"]);
    }

    /// The legend goes where the data is not: a line along the top puts it low, one
    /// rising to the upper right puts it upper left.
    #[test]
    fn the_legend_avoids_the_data() {
        let top: Vec<(f64, f64)> = (0..=10).map(|i| (f64::from(i), 9.5)).collect();
        assert_eq!(
            legend_corner(&bare(vec![Series::new("a", top, RED, 1)])),
            (Corner::LowerRight, 0)
        );
        let rising: Vec<(f64, f64)> = (0..=10).map(|i| (f64::from(i), f64::from(i))).collect();
        let p = bare(vec![Series::new("a", rising, RED, 1)]);
        assert_eq!(legend_corner(&p), (Corner::UpperLeft, 0));
        assert_eq!(
            legend_placement(&p, 400.0),
            (Corner::UpperLeft, (0.0, 10.0))
        );
    }

    /// Data in every corner: the y range grows so that the legend's rows fit above the
    /// data.
    #[test]
    fn a_crowded_panel_makes_room_for_the_legend() {
        let top: Vec<(f64, f64)> = (0..=10).map(|i| (f64::from(i), 9.5)).collect();
        let bottom: Vec<(f64, f64)> = (0..=10).map(|i| (f64::from(i), 0.5)).collect();
        let p = bare(vec![
            Series::new("top", top, RED, 1),
            Series::new("bottom", bottom, BLUE, 1),
        ]);
        assert_eq!(legend_corner(&p).1, 11 - 6);
        let (corner, (y0, y1)) = legend_placement(&p, 300.0);
        assert_eq!(corner, Corner::UpperRight);
        assert_eq!(y0, 0.0);
        // Two rows of 20 px, the 16 px frame and 10 px apart: 66 px of 300 above the data.
        let room = (y1 - 10.0) / (y1 - y0) * 300.0;
        assert!((room - 66.0).abs() < 1e-9, "{room}");
        // Every point lies below the legend's band.
        let highest = p.series.iter().flat_map(|s| s.points.iter()).map(|q| q.1);
        assert!(highest.fold(f64::MIN, f64::max) <= y1 - (y1 - y0) * 66.0 / 300.0);
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
            levels: vec![Level {
                label: "stop 15".into(),
                y: 15.0,
                color: RED,
            }],
            bands: vec![Band {
                label: "pass".into(),
                x: (2.0, 4.0),
                color: BLUE,
            }],
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
