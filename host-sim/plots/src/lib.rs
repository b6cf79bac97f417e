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
//! no legend entry ([`legend_entries`]); the legend sits in a strip of its own right of
//! the plot ([`legend_strip_px`]), never on the data or the shading; [`PALETTE`] gives
//! distinct colours.
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

/// What a legend entry shows beside its label.
#[derive(Clone, Copy, Debug)]
enum Swatch {
    /// A band's shading.
    Band(RGBColor),
    /// A series' line.
    Line(ShapeStyle),
    /// A level's dashed line.
    Dashed(ShapeStyle),
}

/// The legend's entries with their swatches, in drawing order (see [`legend_entries`]).
fn legend_items(panel: &Panel) -> Vec<(String, Swatch)> {
    let mut out: Vec<(String, Swatch)> = Vec::new();
    for b in &panel.bands {
        if !out.iter().any(|(l, _)| *l == b.label) {
            out.push((b.label.clone(), Swatch::Band(b.color)));
        }
    }
    for s in &panel.series {
        if let Some(l) = &s.label {
            if !segments(&s.points).is_empty() {
                out.push((l.clone(), Swatch::Line(s.style)));
            }
        }
    }
    out.extend(
        panel
            .levels
            .iter()
            .map(|l| (l.label.clone(), Swatch::Dashed(l.color.stroke_width(2)))),
    );
    out
}

/// The legend's entries of a panel, in drawing order: each band label once, each series
/// with a label and at least one finite point, each level.
pub fn legend_entries(panel: &Panel) -> Vec<String> {
    legend_items(panel).into_iter().map(|(l, _)| l).collect()
}

/// Height of one legend row, pixels.
const LEGEND_ROW_PX: i32 = 20;
/// The legend's font size, pixels.
const LEGEND_FONT_PX: u32 = 15;
/// The swatch's width and the gaps around it and the text, pixels.
const LEGEND_SWATCH_PX: i32 = 22;
const LEGEND_PAD_PX: i32 = 8;

/// The widest of the legend's labels in `font`, pixels (0 without labels).
fn legend_label_px(items: &[(String, Swatch)], font: &FontDesc<'_>) -> u32 {
    items
        .iter()
        .map(|(l, _)| font.box_size(l).map_or(0, |(w, _)| w))
        .max()
        .unwrap_or(0)
}

/// The width of the legend strip right of a panel whose legend labels are at most
/// `label_px` wide (0: no legend, no strip), within a panel `area_px` wide: the swatch,
/// the label and their padding, at most 45 % of the panel (a longer label is cut by
/// the picture's edge, the data never covered).
pub fn legend_strip_px(label_px: u32, area_px: u32) -> u32 {
    if label_px == 0 {
        return 0;
    }
    let want = label_px + (LEGEND_SWATCH_PX + 4 * LEGEND_PAD_PX) as u32;
    want.min(area_px * 45 / 100)
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
    for (whole, panel) in areas.iter().zip(panels) {
        // The legend's strip, right of the chart: the chart never lies under it.
        let items = legend_items(panel);
        let font = ("sans-serif", LEGEND_FONT_PX).into_font();
        let (width, _) = whole.dim_in_pixel();
        let strip_px = legend_strip_px(legend_label_px(&items, &font), width);
        let (area, strip) = whole.split_horizontally(width - strip_px);
        let area = &area;
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
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(a, y0), (z, y1)],
                    b.color.mix(0.18).filled(),
                )))
                .map_err(PlotError::new)?;
        }
        for s in &panel.series {
            for run in &segments(&s.points) {
                chart
                    .draw_series(LineSeries::new(run.iter().copied(), s.style))
                    .map_err(PlotError::new)?;
            }
        }
        for l in &panel.levels {
            let style = l.color.stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new([(x0, l.y), (x1, l.y)], 8, 5, style))
                .map_err(PlotError::new)?;
        }
        // The legend's top at the plot's top.
        let top = chart.plotting_area().get_base_pixel().1 - whole.get_base_pixel().1;
        draw_legend(&strip, &items, &font, top)?;
    }
    root.present().map_err(PlotError::new)
}

/// Draws the legend's `items` in `strip` (nothing when there are none), framed, its first
/// row `top` pixels down.
fn draw_legend<DB: DrawingBackend>(
    strip: &DrawingArea<DB, plotters::coord::Shift>,
    items: &[(String, Swatch)],
    font: &FontDesc<'_>,
    top: i32,
) -> Result<(), PlotError> {
    if items.is_empty() {
        return Ok(());
    }
    let (w, _) = strip.dim_in_pixel();
    let (w, n) = (w as i32, items.len() as i32);
    let left = LEGEND_PAD_PX;
    strip
        .draw(&Rectangle::new(
            [
                (left, top),
                (w - 2, top + n * LEGEND_ROW_PX + LEGEND_PAD_PX),
            ],
            BLACK.stroke_width(1),
        ))
        .map_err(PlotError::new)?;
    let style = font
        .color(&BLACK)
        .pos(plotters::style::text_anchor::Pos::new(
            plotters::style::text_anchor::HPos::Left,
            plotters::style::text_anchor::VPos::Center,
        ));
    for (k, (label, swatch)) in items.iter().enumerate() {
        let y = top + LEGEND_PAD_PX / 2 + LEGEND_ROW_PX / 2 + k as i32 * LEGEND_ROW_PX;
        let (a, z) = (
            left + LEGEND_PAD_PX,
            left + LEGEND_PAD_PX + LEGEND_SWATCH_PX,
        );
        match *swatch {
            Swatch::Band(c) => strip.draw(&Rectangle::new(
                [(a, y - 6), (z, y + 6)],
                c.mix(0.35).filled(),
            )),
            Swatch::Line(st) => strip.draw(&PathElement::new(vec![(a, y), (z, y)], st)),
            Swatch::Dashed(st) => strip
                .draw(&PathElement::new(vec![(a, y), (a + 8, y)], st))
                .and_then(|()| strip.draw(&PathElement::new(vec![(a + 13, y), (z, y)], st))),
        }
        .map_err(PlotError::new)?;
        strip
            .draw(&Text::new(
                label.as_str(),
                (z + LEGEND_PAD_PX, y),
                style.clone(),
            ))
            .map_err(PlotError::new)?;
    }
    Ok(())
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

    /// The legend changes no pixel of the chart: two legends of the same width but other
    /// words (the same letters in another order), over a panel shaded from end to end
    /// and crossed by its lines, leave every pixel left of the legend's strip the same,
    /// and differ inside the strip.
    #[test]
    fn the_legend_sits_off_the_data() {
        let panel = |word: &str| Panel {
            caption: Some("caption".into()),
            x_desc: "t [s]".into(),
            y_desc: "mm".into(),
            x_range: (0.0, 10.0),
            y_range: (0.0, 10.0),
            series: vec![Series::new(
                format!("{word} line"),
                (0..=10).map(|i| (f64::from(i), 9.5)).collect(),
                RED,
                2,
            )],
            levels: vec![Level {
                label: format!("{word} level"),
                y: 0.5,
                color: BLUE,
            }],
            bands: vec![Band {
                label: format!("{word} band"),
                x: (0.0, 10.0),
                color: PALETTE[2],
            }],
        };
        let (w, h) = (600u32, 300u32);
        let render = |word: &str| {
            let dir =
                std::env::temp_dir().join(format!("plots-legend-{}-{word}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            let path = dir.join("chart.bmp");
            line_charts(&path, (w, h), "t", &[panel(word)], Layout::Stacked).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            let _ = std::fs::remove_dir_all(&dir);
            bytes
        };
        let (a, b) = (render("ab"), render("ba"));
        assert_eq!(a.len(), b.len());
        // A BMP: rows bottom up, 4-byte aligned, after the header; its pixel size from the
        // header's bits per pixel.
        let offset = u32::from_le_bytes(a[10..14].try_into().unwrap()) as usize;
        let px = usize::from(u16::from_le_bytes(a[28..30].try_into().unwrap()) / 8);
        let row = (w as usize * px).div_ceil(4) * 4;
        let register = root_legend_width(&panel("ab"), w);
        assert_eq!(register, root_legend_width(&panel("ba"), w));
        assert!(register > 0 && register < w / 2, "{register}");
        let chart_px = (w - register) as usize;
        let mut strip_differs = false;
        for y in 0..h as usize {
            let r = offset + y * row;
            let differs = (0..chart_px)
                .find(|x| a[r + x * px..r + (x + 1) * px] != b[r + x * px..r + (x + 1) * px]);
            assert_eq!(
                differs, None,
                "the legend's words changed the chart's row {y} (from the bottom), column {differs:?} of {chart_px}, {px} bytes a pixel"
            );
            strip_differs |= a[r + chart_px * px..r + w as usize * px]
                != b[r + chart_px * px..r + w as usize * px];
        }
        assert!(strip_differs, "no legend in the strip");
    }

    /// The strip's width for a panel `w` pixels wide, as `line_charts` lays it out.
    fn root_legend_width(panel: &Panel, w: u32) -> u32 {
        register_font();
        let font = ("sans-serif", LEGEND_FONT_PX).into_font();
        legend_strip_px(legend_label_px(&legend_items(panel), &font), w)
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
