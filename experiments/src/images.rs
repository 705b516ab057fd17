//! Image helpers shared by the rendering experiments: tone-mapped PNGs of radiance images
//! (grey or RGB, a common white point so that images side by side are comparable), signed
//! error images, side-by-side strips, and the image error metrics the atlas reports.
//!
//! **Metrics.** For an image `a` against a reference `r` (all channels and pixels pooled):
//! * relative RMSE = √(Σ(a − r)²) / √(Σ r²) — a relative L2 error, dominated by the bright
//!   pixels, 0 for a perfect match;
//! * the reference's own noise in the same units, √(Σ se_r²) / √(Σ r²): the error a perfect
//!   method would show against this reference (in expectation, a method's squared error is
//!   its true squared error plus the reference's variance, which
//!   [`relative_rmse_debiased`] subtracts).

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// √(Σ(a − r)²) / √(Σ r²) over every channel and pixel (NaN if the reference is black).
pub fn relative_rmse(a: &[&[f64]], r: &[&[f64]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (ac, rc) in a.iter().zip(r) {
        for (x, y) in ac.iter().zip(rc.iter()) {
            num += (x - y) * (x - y);
            den += y * y;
        }
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        f64::NAN
    }
}

/// √(Σ se²) / √(Σ r²): the reference's own noise as a relative RMSE.
pub fn relative_noise(stderr: &[&[f64]], r: &[&[f64]]) -> f64 {
    let s2: f64 = stderr.iter().flat_map(|c| c.iter()).map(|s| s * s).sum();
    let r2: f64 = r.iter().flat_map(|c| c.iter()).map(|y| y * y).sum();
    if r2 > 0.0 { (s2 / r2).sqrt() } else { f64::NAN }
}

/// The relative RMSE with the reference's variance removed:
/// √(max(0, Σ(a − r)² − Σ se²)) / √(Σ r²).
pub fn relative_rmse_debiased(a: &[&[f64]], r: &[&[f64]], stderr: &[&[f64]]) -> f64 {
    let (mut num, mut den, mut var) = (0.0, 0.0, 0.0);
    for ((ac, rc), sc) in a.iter().zip(r).zip(stderr) {
        for ((x, y), s) in ac.iter().zip(rc.iter()).zip(sc.iter()) {
            num += (x - y) * (x - y);
            den += y * y;
            var += s * s;
        }
    }
    if den > 0.0 {
        ((num - var).max(0.0) / den).sqrt()
    } else {
        f64::NAN
    }
}

/// The white point of images: the 99.5th percentile of the largest channel over the pixels
/// (so a few very bright pixels, e.g. a light seen directly, do not darken the image).
pub fn white_point(channels: &[&[f64]]) -> f64 {
    let n = channels.first().map_or(0, |c| c.len());
    let mut v: Vec<f64> = (0..n)
        .map(|p| channels.iter().map(|c| c[p]).fold(0.0, f64::max))
        .collect();
    if v.is_empty() {
        return 1.0;
    }
    v.sort_by(f64::total_cmp);
    let w = v[(v.len() * 995 / 1000).min(v.len() - 1)];
    if w > 0.0 { w } else { 1.0 }
}

fn draw_error(path: &Path, e: impl std::fmt::Display) -> anyhow::Error {
    anyhow!("writing {}: {e}", path.display())
}

/// One tile of a strip: 1 (grey) or 3 (RGB) channels of `w × h` pixels, row-major.
#[derive(Debug)]
pub struct Tile<'a> {
    /// The channels.
    pub channels: Vec<&'a [f64]>,
    /// How a value maps to a colour.
    pub map: ColourMap,
    /// Text shown above the tile (say method, albedo, resolution; `\n` starts a new line);
    /// empty: none.
    pub label: String,
}

impl<'a> Tile<'a> {
    /// An unlabelled tile.
    pub fn new(channels: Vec<&'a [f64]>, map: ColourMap) -> Self {
        Self {
            channels,
            map,
            label: String::new(),
        }
    }
    /// Sets the text shown above the tile.
    pub fn labelled(mut self, label: impl Into<String>) -> Self {
        self.label = label.into();
        self
    }
}

/// How a tile's values become colours.
#[derive(Debug, Clone, Copy)]
pub enum ColourMap {
    /// Radiance: v/white clamped to [0, 1], gamma 2.2.
    Radiance {
        /// The value shown as white.
        white: f64,
    },
    /// Signed values (the first channel): blue below 0, red above, white at 0, saturated
    /// at ±`scale` (a symmetric scale; a strip with such tiles carries a colour bar).
    Signed {
        /// The magnitude shown fully saturated.
        scale: f64,
    },
}

fn colour(map: ColourMap, px: &[f64]) -> RGBColor {
    let g = |v: f64| ((v.clamp(0.0, 1.0)).powf(1.0 / 2.2) * 255.0).round() as u8;
    match map {
        ColourMap::Radiance { white } => {
            if px.len() == 3 {
                RGBColor(g(px[0] / white), g(px[1] / white), g(px[2] / white))
            } else {
                let c = g(px[0] / white);
                RGBColor(c, c, c)
            }
        }
        ColourMap::Signed { scale } => {
            let t = (px[0] / scale.max(1e-300)).clamp(-1.0, 1.0);
            let fade = |t: f64| (255.0 * (1.0 - t.abs())).round() as u8;
            if t >= 0.0 {
                RGBColor(255, fade(t), fade(t))
            } else {
                RGBColor(fade(t), fade(t), 255)
            }
        }
    }
}

/// The colour-bar label [`write_strip`] uses.
pub const DEFAULT_BAR_LABEL: &str = "signed difference (method − reference)";

/// Tiles narrower than this are enlarged (nearest neighbour, integer factor) when a strip
/// carries text, so that labels and colour-bar ticks fit (px).
const MIN_TILE_W: usize = 180;
const GAP: i32 = 2;
const FONT: u32 = 13;
const LINE_H: i32 = 16;
const PAD: i32 = 6;
const BAR_H: i32 = 14;
/// Room each side of the colour bar for its outermost tick labels (px).
const BAR_MARGIN: i32 = 30;

/// The value the colour bar shows at column `i` of `n`: −`scale` at the first column,
/// +`scale` at the last, linear in between.
fn bar_value(i: i32, n: i32, scale: f64) -> f64 {
    if n <= 1 {
        return 0.0;
    }
    scale * (2.0 * f64::from(i) / f64::from(n - 1) - 1.0)
}

/// Pixel geometry of a strip.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Layout {
    /// Enlargement factor of the tiles.
    zoom: usize,
    /// Canvas size.
    width: i32,
    height: i32,
    /// Left edge of the first tile.
    x0: i32,
    /// Top edge of the tiles (below the label band).
    y0: i32,
    /// The signed scale, when there is a colour bar, and the bar's top edge.
    bar: Option<(f64, i32)>,
}

fn text_width(text: &str) -> i32 {
    ("sans-serif", FONT)
        .into_font()
        .box_size(text)
        .map_or(0, |(w, _)| w as i32)
}

fn bar_caption(bar_label: &str, scale: f64) -> String {
    format!(
        "{bar_label}: blue < 0 < red, symmetric, clipped at ±{}",
        crate::plot::tick(&scale)
    )
}

fn layout(w: usize, h: usize, tiles: &[Tile<'_>], bar_label: &str) -> Result<Layout> {
    let mut scales = tiles.iter().filter_map(|t| match t.map {
        ColourMap::Signed { scale } => Some(scale),
        ColourMap::Radiance { .. } => None,
    });
    let scale = scales.next();
    if let Some(s) = scale {
        if scales.any(|o| o != s) {
            return Err(anyhow!(
                "signed tiles of one strip must share one scale (one colour bar)"
            ));
        }
    }
    let lines = tiles
        .iter()
        .map(|t| {
            if t.label.is_empty() {
                0
            } else {
                t.label.lines().count() as i32
            }
        })
        .max()
        .unwrap_or(0);
    let text = lines > 0 || scale.is_some();
    let zoom = if text {
        MIN_TILE_W.div_ceil(w).max(1)
    } else {
        1
    };
    let tiles_w = (tiles.len() * w * zoom) as i32 + (tiles.len() as i32 - 1) * GAP;
    let label_h = if lines > 0 { lines * LINE_H + PAD } else { 0 };
    let tiles_h = (h * zoom) as i32;
    let (width, bar) = match scale {
        Some(s) => {
            let caption = text_width(&bar_caption(bar_label, s)) + 2 * PAD;
            (
                tiles_w.max(caption).max(2 * BAR_MARGIN + 120),
                Some((s, label_h + tiles_h + PAD)),
            )
        }
        None => (tiles_w, None),
    };
    let bar_h = if bar.is_some() {
        PAD + BAR_H + 4 + 2 * LINE_H + PAD
    } else {
        0
    };
    Ok(Layout {
        zoom,
        width,
        height: label_h + tiles_h + bar_h,
        x0: (width - tiles_w) / 2,
        y0: label_h,
        bar,
    })
}

fn draw_strip<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    l: &Layout,
    w: usize,
    h: usize,
    tiles: &[Tile<'_>],
    bar_label: &str,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&BLACK)?;
    let z = l.zoom as i32;
    let font = ("sans-serif", FONT).into_font().color(&WHITE);
    let centred = font.pos(Pos::new(HPos::Center, VPos::Top));
    let mut px = Vec::with_capacity(3);
    for (t, tile) in tiles.iter().enumerate() {
        let tx = l.x0 + t as i32 * ((w as i32) * z + GAP);
        for (k, line) in tile.label.lines().enumerate() {
            let pos = (tx + (w as i32) * z / 2, PAD / 2 + k as i32 * LINE_H);
            root.draw_text(line, &centred, pos)?;
        }
        for y in 0..h {
            for x in 0..w {
                px.clear();
                px.extend(tile.channels.iter().map(|c| c[y * w + x]));
                let c = colour(tile.map, &px);
                let (x0, y0) = (tx + x as i32 * z, l.y0 + y as i32 * z);
                if z == 1 {
                    root.draw_pixel((x0, y0), &c)?;
                } else {
                    root.draw(&Rectangle::new([(x0, y0), (x0 + z, y0 + z)], c.filled()))?;
                }
            }
        }
    }
    if let Some((scale, top)) = l.bar {
        let (left, right) = (BAR_MARGIN, l.width - BAR_MARGIN);
        let n = right - left;
        let map = ColourMap::Signed { scale };
        for i in 0..n {
            let c = colour(map, &[bar_value(i, n, scale)]);
            root.draw(&Rectangle::new(
                [(left + i, top), (left + i + 1, top + BAR_H)],
                c.filled(),
            ))?;
        }
        let ticks = if n >= 300 { 4 } else { 2 };
        for k in 0..=ticks {
            let i = (n - 1) * k / ticks;
            let v = bar_value(i, n, scale);
            let x = left + i;
            root.draw(&PathElement::new(
                vec![(x, top + BAR_H), (x, top + BAR_H + 4)],
                WHITE.stroke_width(1),
            ))?;
            root.draw_text(&crate::plot::tick(&v), &centred, (x, top + BAR_H + 4))?;
        }
        root.draw_text(
            &bar_caption(bar_label, scale),
            &centred,
            (l.width / 2, top + BAR_H + 4 + LINE_H + 2),
        )?;
    }
    Ok(())
}

/// Writes tiles of `w × h` pixels side by side (2-pixel black gaps) as one PNG, each with
/// its label above it; a strip with signed tiles gets a colour bar labelled
/// [`DEFAULT_BAR_LABEL`] (see [`write_strip_with_bar`]).
pub fn write_strip(path: &Path, w: usize, h: usize, tiles: &[Tile<'_>]) -> Result<()> {
    write_strip_with_bar(path, w, h, tiles, DEFAULT_BAR_LABEL)
}

/// [`write_strip`] with the quantity (and unit) the colour bar of signed tiles shows, e.g.
/// "radiance difference (W m⁻² sr⁻¹)". Tiles narrower than 180 px are enlarged by an
/// integer factor when the strip carries labels or a colour bar; signed tiles must share
/// one scale.
pub fn write_strip_with_bar(
    path: &Path,
    w: usize,
    h: usize,
    tiles: &[Tile<'_>],
    bar_label: &str,
) -> Result<()> {
    if tiles.is_empty() || w == 0 || h == 0 {
        return Err(anyhow!("writing {}: no pixels", path.display()));
    }
    for (t, tile) in tiles.iter().enumerate() {
        if tile.channels.is_empty() || tile.channels.iter().any(|c| c.len() != w * h) {
            return Err(anyhow!(
                "writing {}: tile {t} is not {w}x{h}",
                path.display()
            ));
        }
    }
    crate::plot::register_font();
    let l = layout(w, h, tiles, bar_label).map_err(|e| draw_error(path, e))?;
    let root = BitMapBackend::new(path, (l.width as u32, l.height as u32)).into_drawing_area();
    draw_strip(&root, &l, w, h, tiles, bar_label).map_err(|e| draw_error(path, e))?;
    root.present().map_err(|e| draw_error(path, e))?;
    Ok(())
}

/// Writes one radiance image (1 or 3 channels) as a tone-mapped PNG with `white`.
pub fn write_radiance_png(
    path: &Path,
    w: usize,
    h: usize,
    channels: &[&[f64]],
    white: f64,
) -> Result<()> {
    write_strip(
        path,
        w,
        h,
        &[Tile::new(channels.to_vec(), ColourMap::Radiance { white })],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_of_known_images() {
        let r = [1.0, 2.0, 0.0, 2.0];
        let a = [1.0, 2.0, 0.0, 2.0];
        assert_eq!(relative_rmse(&[&a], &[&r]), 0.0);
        let a = [2.0, 2.0, 0.0, 2.0]; // one pixel off by 1: √1/√9
        assert!((relative_rmse(&[&a], &[&r]) - 1.0 / 3.0).abs() < 1e-15);
        let se = [0.0, 0.0, 0.0, 1.0];
        assert!((relative_noise(&[&se], &[&r]) - 1.0 / 3.0).abs() < 1e-15);
        // Removing a reference variance equal to the squared error leaves 0.
        assert_eq!(relative_rmse_debiased(&[&a], &[&r], &[&se]), 0.0);
        assert!(relative_rmse(&[&a], &[&[0.0; 4]]).is_nan());
    }

    #[test]
    fn colour_bar_ends_are_the_maps_end_colours() {
        let scale = 0.5;
        let map = ColourMap::Signed { scale };
        let n = 101;
        assert_eq!(bar_value(0, n, scale), -scale);
        assert_eq!(bar_value(n - 1, n, scale), scale);
        assert_eq!(bar_value(50, n, scale), 0.0);
        assert_eq!(colour(map, &[bar_value(0, n, scale)]), RGBColor(0, 0, 255));
        assert_eq!(
            colour(map, &[bar_value(n - 1, n, scale)]),
            RGBColor(255, 0, 0)
        );
        assert_eq!(
            colour(map, &[bar_value(50, n, scale)]),
            RGBColor(255, 255, 255)
        );
        // Beyond the scale the map clips to the end colours.
        assert_eq!(colour(map, &[-3.0]), RGBColor(0, 0, 255));
    }

    /// Renders a strip into memory and returns (layout, RGB bytes).
    fn render(w: usize, h: usize, tiles: &[Tile<'_>]) -> (Layout, Vec<u8>) {
        crate::plot::register_font();
        let l = layout(w, h, tiles, "radiance difference").unwrap();
        let mut buf = vec![0u8; (l.width * l.height * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (l.width as u32, l.height as u32))
                .into_drawing_area();
            draw_strip(&root, &l, w, h, tiles, "radiance difference").unwrap();
            root.present().unwrap();
        }
        (l, buf)
    }

    #[test]
    fn signed_strip_draws_its_colour_bar_and_labels() {
        let d = [-1.0, 0.0, 0.0, 1.0];
        let tiles = [
            Tile::new(vec![&d[..]], ColourMap::Signed { scale: 1.0 }).labelled("cda\nα = 0.9"),
            Tile::new(vec![&d[..]], ColourMap::Signed { scale: 1.0 }).labelled("lp"),
        ];
        let (l, buf) = render(2, 2, &tiles);
        let pixel = |x: i32, y: i32| {
            let i = ((y * l.width + x) * 3) as usize;
            RGBColor(buf[i], buf[i + 1], buf[i + 2])
        };
        assert_eq!(l.zoom, 90);
        let (_, top) = l.bar.unwrap();
        let mid = top + BAR_H / 2;
        assert_eq!(pixel(BAR_MARGIN, mid), RGBColor(0, 0, 255));
        assert_eq!(pixel(l.width - BAR_MARGIN - 1, mid), RGBColor(255, 0, 0));
        // The tile's pixels are enlarged: its first pixel (−1) is blue over 90 × 90.
        assert_eq!(pixel(l.x0 + 89, l.y0 + 89), RGBColor(0, 0, 255));
        assert_eq!(pixel(l.x0 + 90, l.y0), RGBColor(255, 255, 255));
        // Two label lines above the tiles, and some text was drawn there.
        assert_eq!(l.y0, 2 * LINE_H + PAD);
        let lit = (0..l.y0)
            .flat_map(|y| (0..l.width).map(move |x| (x, y)))
            .filter(|&(x, y)| pixel(x, y) != RGBColor(0, 0, 0))
            .count();
        assert!(lit > 20, "{lit} label pixels");
        // Different scales would need two bars.
        let other = [
            Tile::new(vec![&d[..]], ColourMap::Signed { scale: 1.0 }),
            Tile::new(vec![&d[..]], ColourMap::Signed { scale: 2.0 }),
        ];
        assert!(layout(2, 2, &other, "x").is_err());
    }

    #[test]
    fn unlabelled_radiance_strip_keeps_its_size() {
        let v = [0.5; 6];
        let tiles = [Tile::new(vec![&v[..]], ColourMap::Radiance { white: 1.0 })];
        let l = layout(3, 2, &tiles, DEFAULT_BAR_LABEL).unwrap();
        assert_eq!((l.zoom, l.width, l.height, l.bar), (1, 3, 2, None));
    }
}
