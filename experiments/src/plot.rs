//! Line and scatter plots as PNG via plotters, with an embedded font (DejaVu Sans) so no
//! system font library is needed.

use anyhow::{Context, Result, anyhow};
use plotters::prelude::*;
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
fn tick(v: &f64) -> String {
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

fn register_font() {
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

/// Draws `series` into a PNG at `path` (900 × 650 px).
pub fn plot(path: &Path, title: &str, x: &Axis, y: &Axis, series: &[Series]) -> Result<()> {
    register_font();
    let xr = fit(x, series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let yr = fit(y, series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let root = BitMapBackend::new(path, (900, 650)).into_drawing_area();
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(80);
    // plotters' log and linear coordinates are different types; draw through one generic body.
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
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
            for s in series {
                let color = PALETTE[s.color % PALETTE.len()];
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| {
                        p.0.is_finite()
                            && p.1.is_finite()
                            && (!x.log || p.0 > 0.0)
                            && (!y.log || p.1 > 0.0)
                    })
                    .filter(|p| p.0 >= xr.0 && p.0 <= xr.1 && p.1 >= yr.0 && p.1 <= yr.1)
                    .collect();
                let anno = match s.style {
                    Style::Line => chart
                        .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                        .map_err(|e| err(&e))?,
                    Style::Dashed => chart
                        .draw_series(DashedLineSeries::new(pts, 6, 4, color.stroke_width(2)))
                        .map_err(|e| err(&e))?,
                    Style::Points => chart
                        .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                        .map_err(|e| err(&e))?,
                };
                if !s.label.is_empty() {
                    let style = s.style;
                    anno.label(s.label.as_str())
                        .legend(move |(lx, ly)| match style {
                            Style::Points => {
                                Circle::new((lx + 10, ly), 4, color.filled()).into_dyn()
                            }
                            _ => PathElement::new(
                                vec![(lx, ly), (lx + 20, ly)],
                                color.stroke_width(2),
                            )
                            .into_dyn(),
                        });
                }
            }
            if series.iter().any(|s| !s.label.is_empty()) {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 14))
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()
                    .map_err(|e| err(&e))?;
            }
        }};
    }
    match (x.log, y.log) {
        (false, false) => draw!(
            builder
                .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
                .map_err(|e| err(&e))?
        ),
        (true, false) => draw!(
            builder
                .build_cartesian_2d((xr.0..xr.1).log_scale(), yr.0..yr.1)
                .map_err(|e| err(&e))?
        ),
        (false, true) => draw!(
            builder
                .build_cartesian_2d(xr.0..xr.1, (yr.0..yr.1).log_scale())
                .map_err(|e| err(&e))?
        ),
        (true, true) => draw!(
            builder
                .build_cartesian_2d((xr.0..xr.1).log_scale(), (yr.0..yr.1).log_scale())
                .map_err(|e| err(&e))?
        ),
    }
    root.present()
        .map_err(|e| err(&e))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
