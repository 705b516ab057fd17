//! Line and scatter plots as PNG via plotters, with an embedded font (DejaVu Sans) so no
//! system font library is needed.

use anyhow::{Context, Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;
use std::path::Path;
use std::sync::Once;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// A solid line.
    Line,
    /// A dashed line.
    Dashed,
    /// Circles at the points.
    Points,
}

/// One curve of a plot.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: Style,
    /// Index into the palette; equal indices share a colour.
    pub color: usize,
}

impl Series {
    /// A series.
    pub fn new(
        label: impl Into<String>,
        points: Vec<(f64, f64)>,
        style: Style,
        color: usize,
    ) -> Self {
        Self {
            label: label.into(),
            points,
            style,
            color,
        }
    }
}

/// Axis description.
#[derive(Debug, Clone)]
pub struct Axis {
    /// Axis label.
    pub label: String,
    /// Logarithmic scale.
    pub log: bool,
    /// Fixed range; `None` fits the data.
    pub range: Option<(f64, f64)>,
}

impl Axis {
    /// Linear axis fitted to the data.
    pub fn lin(label: &str) -> Self {
        Self {
            label: label.to_string(),
            log: false,
            range: None,
        }
    }
    /// Logarithmic axis fitted to the data.
    pub fn log(label: &str) -> Self {
        Self {
            label: label.to_string(),
            log: true,
            range: None,
        }
    }
    /// Fixes the range.
    pub fn range(mut self, lo: f64, hi: f64) -> Self {
        self.range = Some((lo, hi));
        self
    }
}

const PALETTE: [RGBColor; 10] = [
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

/// Compact tick labels: `0.5`, `20`, `1e-6`.
pub(crate) fn tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if (1e-3..1e5).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        let s = format!("{v:.1e}");
        s.replace(".0e", "e")
    }
}

/// Registers the embedded DejaVu Sans as plotters' "sans-serif" (once per process).
pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TTF shipped by the `dejavu` crate; failure only loses text.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

fn fit(axis: &Axis, values: impl Iterator<Item = f64>) -> (f64, f64) {
    if let Some(r) = axis.range {
        return r;
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (!axis.log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if axis.log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if axis.log {
        (lo / 1.5, hi * 1.5)
    } else {
        let pad = 0.05 * (hi - lo).max(1e-12);
        (lo - pad, hi + pad)
    }
}

/// Legend text size (px).
const LEGEND_FONT: u32 = 14;
/// Padding inside the legend box (px).
const LEGEND_PAD: i32 = 7;
/// Width of a legend entry's style sample (px).
const GLYPH_W: i32 = 32;
/// Height of one legend row (px).
const ROW_H: i32 = 19;
/// Gap between the legend box and the plot frame (px).
const INSET: i32 = 8;
/// Clearance kept between the legend box and any drawn data (px): half a line width plus a
/// marker radius.
const CLEAR: i32 = 4;
/// Dash and gap lengths of [`Style::Dashed`] (px), the same in the plot and its legend.
const DASH: (i32, i32) = (6, 4);

/// One legend row: a label and the styles its sample shows — the series' own style plus
/// those of the unlabelled series of the same colour drawn right after it (the curve that
/// goes with labelled points, say), so that every drawn style can be read off the legend.
#[derive(Debug, Clone, PartialEq)]
struct Entry {
    label: String,
    color: usize,
    styles: Vec<Style>,
}

fn legend_entries(series: &[Series]) -> Vec<Entry> {
    let mut entries = Vec::new();
    let mut i = 0;
    while i < series.len() {
        let s = &series[i];
        i += 1;
        if s.label.is_empty() {
            continue;
        }
        let mut styles = vec![s.style];
        while i < series.len() && series[i].label.is_empty() && series[i].color == s.color {
            if !styles.contains(&series[i].style) {
                styles.push(series[i].style);
            }
            i += 1;
        }
        entries.push(Entry {
            label: s.label.clone(),
            color: s.color,
            styles,
        });
    }
    entries
}

/// Where the legend goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Placement {
    /// Inside the plot frame with its top-left corner at this pixel.
    Inside(i32, i32),
    /// In a margin right of the plot frame (no spot inside is free of data).
    Outside,
}

/// The first spot inside the plot frame `area` (x and y pixel ranges) where a legend box of
/// `size` pixels covers none of the data pixels `samples` (with [`CLEAR`] pixels to spare),
/// trying the corners (upper right, upper left, lower right, lower left), then the edge
/// midpoints (top, bottom, right, left); [`Placement::Outside`] if there is none.
fn choose_legend(
    area: (Range<i32>, Range<i32>),
    size: (i32, i32),
    samples: &[(i32, i32)],
) -> Placement {
    let (xs, ys) = area;
    let (w, h) = size;
    if w + 2 * INSET > xs.end - xs.start || h + 2 * INSET > ys.end - ys.start {
        return Placement::Outside;
    }
    let (l, r) = (xs.start + INSET, xs.end - INSET - w);
    let (t, b) = (ys.start + INSET, ys.end - INSET - h);
    let (cx, cy) = ((l + r) / 2, (t + b) / 2);
    let candidates = [
        (r, t),
        (l, t),
        (r, b),
        (l, b),
        (cx, t),
        (cx, b),
        (r, cy),
        (l, cy),
    ];
    candidates
        .into_iter()
        .find(|&(x, y)| {
            !samples.iter().any(|&(px, py)| {
                (x - CLEAR..=x + w + CLEAR).contains(&px)
                    && (y - CLEAR..=y + h + CLEAR).contains(&py)
            })
        })
        .map_or(Placement::Outside, |(x, y)| Placement::Inside(x, y))
}

/// The pixels a series of `style` through the pixel positions `pixels` covers: the markers'
/// centres, or points every ≤ 2 px along the line segments.
fn trace(pixels: &[(i32, i32)], style: Style, out: &mut Vec<(i32, i32)>) {
    out.extend(pixels.first());
    if style == Style::Points {
        out.extend(pixels.iter().skip(1));
        return;
    }
    for seg in pixels.windows(2) {
        let (a, b) = (seg[0], seg[1]);
        let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) + 1) / 2;
        let n = n.max(1);
        out.extend((1..=n).map(|k| (a.0 + (b.0 - a.0) * k / n, a.1 + (b.1 - a.1) * k / n)));
    }
}

/// Draws the legend box with its top-left corner at `at` on `area`.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    at: (i32, i32),
    size: (i32, i32),
    entries: &[Entry],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (x, y) = at;
    let corners = [(x, y), (x + size.0, y + size.1)];
    area.draw(&Rectangle::new(corners, WHITE.filled()))?;
    area.draw(&Rectangle::new(corners, BLACK.stroke_width(1)))?;
    let font = ("sans-serif", LEGEND_FONT)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (i, e) in entries.iter().enumerate() {
        let color = PALETTE[e.color % PALETTE.len()];
        let cy = y + LEGEND_PAD + ROW_H * i as i32 + ROW_H / 2;
        let gx = x + LEGEND_PAD;
        let solid = e.styles.contains(&Style::Line);
        let dashed = e.styles.contains(&Style::Dashed);
        // Both line styles in one entry: solid above, dashed below.
        let (sy, dy) = if solid && dashed {
            (cy - 3, cy + 3)
        } else {
            (cy, cy)
        };
        if solid {
            area.draw(&PathElement::new(
                vec![(gx, sy), (gx + GLYPH_W, sy)],
                color.stroke_width(2),
            ))?;
        }
        if dashed {
            let mut a = gx;
            while a < gx + GLYPH_W {
                let b = (a + DASH.0).min(gx + GLYPH_W);
                area.draw(&PathElement::new(
                    vec![(a, dy), (b, dy)],
                    color.stroke_width(2),
                ))?;
                a += DASH.0 + DASH.1;
            }
        }
        if e.styles.contains(&Style::Points) {
            area.draw(&Circle::new((gx + GLYPH_W / 2, cy), 4, color.filled()))?;
        }
        area.draw_text(&e.label, &font, (gx + GLYPH_W + LEGEND_PAD, cy))?;
    }
    Ok(())
}

/// Draws `series` into a PNG at `path` (900 × 650 px).
///
/// The legend shows each labelled series' drawing style (solid, dashed, markers; see
/// `Entry` for unlabelled companions) and goes where it covers no data: the first free
/// corner or edge midpoint of the plot frame, else a margin right of the frame.
pub fn plot(path: &Path, title: &str, x: &Axis, y: &Axis, series: &[Series]) -> Result<()> {
    register_font();
    let xr = fit(x, series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let yr = fit(y, series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let (width, height) = (900, 650);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let body = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| err(&e))?;
    // The points drawn: finite, positive on log axes, inside the ranges.
    let visible: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .copied()
                .filter(|p| {
                    p.0.is_finite()
                        && p.1.is_finite()
                        && (!x.log || p.0 > 0.0)
                        && (!y.log || p.1 > 0.0)
                })
                .filter(|p| p.0 >= xr.0 && p.0 <= xr.1 && p.1 >= yr.0 && p.1 <= yr.1)
                .collect()
        })
        .collect();
    let entries = legend_entries(series);
    let font: TextStyle = ("sans-serif", LEGEND_FONT).into_font().into();
    let mut text_w = 0;
    for e in &entries {
        let (w, _) = root
            .estimate_text_size(&e.label, &font)
            .map_err(|e| err(&e))?;
        text_w = text_w.max(w as i32);
    }
    let size = (
        3 * LEGEND_PAD + GLYPH_W + text_w,
        2 * LEGEND_PAD + ROW_H * entries.len() as i32,
    );
    // plotters' log and linear coordinates are different types; run one generic body on the
    // chart built on `$area` (building draws nothing).
    macro_rules! on_chart {
        ($area:expr, |$chart:ident| $body:expr) => {{
            let mut builder = ChartBuilder::on($area);
            builder
                .margin(12)
                .x_label_area_size(48)
                .y_label_area_size(80);
            match (x.log, y.log) {
                (false, false) => {
                    let $chart = &mut builder
                        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
                        .map_err(|e| err(&e))?;
                    $body
                }
                (true, false) => {
                    let $chart = &mut builder
                        .build_cartesian_2d((xr.0..xr.1).log_scale(), yr.0..yr.1)
                        .map_err(|e| err(&e))?;
                    $body
                }
                (false, true) => {
                    let $chart = &mut builder
                        .build_cartesian_2d(xr.0..xr.1, (yr.0..yr.1).log_scale())
                        .map_err(|e| err(&e))?;
                    $body
                }
                (true, true) => {
                    let $chart = &mut builder
                        .build_cartesian_2d((xr.0..xr.1).log_scale(), (yr.0..yr.1).log_scale())
                        .map_err(|e| err(&e))?;
                    $body
                }
            }
        }};
    }
    // Where the data lands with the full width, to find a free spot for the legend.
    let placement = if entries.is_empty() {
        None
    } else {
        let (frame, samples) = on_chart!(&body, |chart| {
            let mut samples = Vec::new();
            for (s, pts) in series.iter().zip(&visible) {
                let px: Vec<(i32, i32)> = pts.iter().map(|p| chart.backend_coord(p)).collect();
                trace(&px, s.style, &mut samples);
            }
            (chart.plotting_area().get_pixel_range(), samples)
        });
        Some(choose_legend(frame, size, &samples))
    };
    let chart_area = match placement {
        Some(Placement::Outside) => body.split_horizontally(width as i32 - size.0 - 2 * INSET).0,
        _ => body.clone(),
    };
    let frame = on_chart!(&chart_area, |chart| {
        chart
            .configure_mesh()
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .x_desc(x.label.as_str())
            .y_desc(y.label.as_str())
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| err(&e))?;
        for (s, pts) in series.iter().zip(&visible) {
            let color = PALETTE[s.color % PALETTE.len()];
            let pts = pts.iter().copied();
            match s.style {
                Style::Line => chart
                    .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                    .map_err(|e| err(&e))?,
                Style::Dashed => chart
                    .draw_series(DashedLineSeries::new(
                        pts,
                        DASH.0 as u32,
                        DASH.1 as u32,
                        color.stroke_width(2),
                    ))
                    .map_err(|e| err(&e))?,
                Style::Points => chart
                    .draw_series(pts.map(|p| Circle::new(p, 3, color.filled())))
                    .map_err(|e| err(&e))?,
            };
        }
        chart.plotting_area().get_pixel_range()
    });
    if let Some(p) = placement {
        let at = match p {
            Placement::Inside(x, y) => (x, y),
            Placement::Outside => (frame.0.end + INSET, frame.1.start),
        };
        draw_legend(&root, at, size, &entries).map_err(|e| err(&e))?;
    }
    root.present()
        .map_err(|e| err(&e))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const FRAME: (Range<i32>, Range<i32>) = (100..900, 50..600);

    #[test]
    fn legend_goes_to_the_first_corner_free_of_data() {
        let size = (200, 100);
        // Nothing drawn: upper right.
        assert_eq!(choose_legend(FRAME, size, &[]), Placement::Inside(692, 58));
        // A line rising to the upper right: the upper left is free.
        let mut rising = Vec::new();
        trace(&[(100, 600), (900, 50)], Style::Line, &mut rising);
        assert_eq!(
            choose_legend(FRAME, size, &rising),
            Placement::Inside(108, 58)
        );
        // Points along the top edge and a line along the bottom: the right edge's middle.
        let mut busy: Vec<(i32, i32)> = (100..900).step_by(20).map(|x| (x, 70)).collect();
        trace(&[(100, 590), (900, 590)], Style::Line, &mut busy);
        assert_eq!(
            choose_legend(FRAME, size, &busy),
            Placement::Inside(692, 275)
        );
        // A single point just off the free corner's box still blocks it (clearance).
        let p = choose_legend(FRAME, size, &[(692 + 200 + CLEAR, 58 + 100)]);
        assert_eq!(p, Placement::Inside(108, 58));
    }

    #[test]
    fn legend_moves_outside_when_every_spot_holds_data() {
        let mut grid = Vec::new();
        for y in (50..600).step_by(30) {
            trace(&[(100, y), (900, y)], Style::Line, &mut grid);
        }
        assert_eq!(choose_legend(FRAME, (200, 100), &grid), Placement::Outside);
        // A legend larger than the frame cannot go inside either.
        assert_eq!(choose_legend(FRAME, (900, 100), &[]), Placement::Outside);
    }

    #[test]
    fn line_traces_have_no_gaps() {
        let mut t = Vec::new();
        trace(&[(0, 0), (10, 3), (10, 40)], Style::Dashed, &mut t);
        assert_eq!(t.first(), Some(&(0, 0)));
        assert_eq!(t.last(), Some(&(10, 40)));
        assert!(
            t.windows(2)
                .all(|w| (w[1].0 - w[0].0).abs() <= 2 && (w[1].1 - w[0].1).abs() <= 2)
        );
        let mut p = Vec::new();
        trace(&[(1, 1), (50, 50)], Style::Points, &mut p);
        assert_eq!(p, vec![(1, 1), (50, 50)]);
    }

    #[test]
    fn legend_entries_show_every_drawn_style() {
        let pts = vec![(1.0, 1.0)];
        let s = |label: &str, style, color| Series::new(label, pts.clone(), style, color);
        let entries = legend_entries(&[
            s("MC", Style::Points, 0),
            s("", Style::Line, 0),
            s("", Style::Dashed, 0),
            s("", Style::Line, 1), // another colour: not part of "MC"
            s("numeric", Style::Line, 2),
            s("analytic", Style::Dashed, 2),
        ]);
        let styles: Vec<(&str, &[Style])> = entries
            .iter()
            .map(|e| (e.label.as_str(), e.styles.as_slice()))
            .collect();
        assert_eq!(
            styles,
            vec![
                ("MC", &[Style::Points, Style::Line, Style::Dashed][..]),
                ("numeric", &[Style::Line][..]),
                ("analytic", &[Style::Dashed][..]),
            ]
        );
    }
}
