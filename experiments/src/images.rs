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
use plotters::prelude::*;
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
    /// at ±`scale`.
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

/// Writes tiles of `w × h` pixels side by side (2-pixel black gaps) as one PNG.
pub fn write_strip(path: &Path, w: usize, h: usize, tiles: &[Tile<'_>]) -> Result<()> {
    if tiles.is_empty() || w == 0 || h == 0 {
        return Err(anyhow!("writing {}: no pixels", path.display()));
    }
    let gap = 2;
    let total_w = tiles.len() * w + (tiles.len() - 1) * gap;
    let root = BitMapBackend::new(path, (total_w as u32, h as u32)).into_drawing_area();
    root.fill(&BLACK).map_err(|e| draw_error(path, e))?;
    let mut px = Vec::with_capacity(3);
    for (t, tile) in tiles.iter().enumerate() {
        if tile.channels.iter().any(|c| c.len() != w * h) {
            return Err(anyhow!(
                "writing {}: tile {t} is not {w}x{h}",
                path.display()
            ));
        }
        let x0 = t * (w + gap);
        for y in 0..h {
            for x in 0..w {
                px.clear();
                px.extend(tile.channels.iter().map(|c| c[y * w + x]));
                root.draw_pixel(((x0 + x) as i32, y as i32), &colour(tile.map, &px))
                    .map_err(|e| draw_error(path, e))?;
            }
        }
    }
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
        &[Tile {
            channels: channels.to_vec(),
            map: ColourMap::Radiance { white },
        }],
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
}
