//! Thesis-style images of a diffused field (thesis §1.3 and Ch. 4 figures; spec
//! `rde.md` §1.8, render path 2): an illustration only, never compared with a reference.
//!
//! The thesis ray-casts the data volume with the emission–absorption volume rendering
//! equation, L_n = L₀τ_n + Σᵢ Q_{e,i}∆x τᵢ (thesis Eq 1.12), with per-sample opacity
//! αᵢ = 1 − e^{−K_{a,i}∆x} and front-to-back UNDER compositing
//!
//! C_out = C_in + (1 − α_in) C   (thesis Eq 1.13),   α_out = α_in + (1 − α_in) α   (thesis Eq 1.14),
//!
//! and draws the diffused energy in green on top of a transfer function of the data
//! (thesis Figs 3.4, 4.4–4.8). The thesis leaves the displayed quantity and the transfer
//! function open (future work); our choices:
//!
//! * **Rays**: orthographic, one per voxel column along a grid axis ([`ThesisStyle::axis`]),
//!   one sample per voxel (∆x = ∆), entering at the low face. Axis-aligned rays make
//!   Eq 1.12's sum exact for piecewise-constant data, so the tests below check the closed
//!   forms.
//! * **Transfer function**: data S ∈ [0, 1] → colour linearly from [`ThesisStyle::low`] to
//!   [`ThesisStyle::high`], opacity K_a∆ = [`ThesisStyle::opacity`]·S.
//! * **Diffused energy**: green emission Q_e∆x = [`ThesisStyle::gain`]·w(φ/max φ) with
//!   w linear, or logarithmic over [`ThesisStyle::log_decades`] decades
//!   (w = max(0, 1 + log₁₀(x)/decades)), so leaks orders of magnitude below the source
//!   stay visible.
//! * A sample's premultiplied colour is C = α·c(S) + Q_e∆x·(0, 1, 0); the background
//!   behind the volume is black (L₀ = 0).
//!
//! Tests (`tests.rs`, `dvr_*`): the closed form 1 − (1 − α)ⁿ of Eq 1.14 and c·(1 − (1 − α)ⁿ)
//! of Eq 1.13 on a uniform column; emission behind one sample attenuated by (1 − α); pure
//! emission summing to Σ Q_e∆x; typed errors for bad input.

use crate::{Grid, SolverError};

/// How a thesis-style image is drawn (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThesisStyle {
    /// The grid axis the rays run along (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// K_a∆ of a voxel with data 1 (opacity per voxel α = 1 − e^{−opacity·S}).
    pub opacity: f64,
    /// Transfer-function colour at data 0.
    pub low: [f64; 3],
    /// Transfer-function colour at data 1.
    pub high: [f64; 3],
    /// Q_e∆x of a voxel at φ = max φ.
    pub gain: f64,
    /// `Some(d)`: logarithmic emission weight over d decades; `None`: linear.
    pub log_decades: Option<f64>,
}

impl Default for ThesisStyle {
    /// Rays along x, K_a∆ = 0.15 at data 1, blue-grey to white, gain 0.25, 4 decades.
    fn default() -> Self {
        Self {
            axis: 0,
            opacity: 0.15,
            low: [0.15, 0.2, 0.35],
            high: [1.0, 1.0, 1.0],
            gain: 0.25,
            log_decades: Some(4.0),
        }
    }
}

/// An RGB image with its accumulated opacity, row-major (`w` pixels per row).
#[derive(Debug, Clone, PartialEq)]
pub struct StyleImage {
    /// Width: the grid's size along the first axis other than `axis`.
    pub w: usize,
    /// Height: the size along the remaining axis.
    pub h: usize,
    /// Red, green, blue planes (premultiplied, background black).
    pub rgb: [Vec<f64>; 3],
    /// The accumulated opacity α_out of thesis Eq 1.14.
    pub alpha: Vec<f64>,
}

/// Renders `data` (∈ [0, 1]) with the diffused field `phi` (≥ 0) on `grid` (module docs).
pub fn render(
    grid: &Grid,
    data: &[f64],
    phi: &[f64],
    style: &ThesisStyle,
) -> Result<StyleImage, SolverError> {
    let len = grid.len();
    for (field, got) in [("data", data.len()), ("phi", phi.len())] {
        if got != len {
            return Err(SolverError::FieldSize {
                field,
                expected: len,
                got,
            });
        }
    }
    if style.axis > 2 {
        return Err(SolverError::BadParameter {
            name: "axis",
            value: style.axis as f64,
            reason: "the ray axis must be 0 (x), 1 (y) or 2 (z)",
        });
    }
    for (name, v) in [("opacity", style.opacity), ("gain", style.gain)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(SolverError::BadParameter {
                name,
                value: v,
                reason: "must be finite and ≥ 0",
            });
        }
    }
    if let Some(d) = style.log_decades {
        if !(d.is_finite() && d > 0.0) {
            return Err(SolverError::BadParameter {
                name: "log_decades",
                value: d,
                reason: "must be finite and > 0",
            });
        }
    }
    if let Some((index, &value)) = data
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && (0.0..=1.0).contains(*v)))
    {
        return Err(SolverError::FieldValue {
            field: "data",
            index,
            value,
            range: "[0, 1]",
        });
    }
    if let Some((index, &value)) = phi
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
    {
        return Err(SolverError::FieldValue {
            field: "phi",
            index,
            value,
            range: "finite and ≥ 0",
        });
    }
    let peak = phi.iter().cloned().fold(0.0, f64::max);
    let weight = |p: f64| -> f64 {
        if peak <= 0.0 {
            return 0.0;
        }
        let x = p / peak;
        match style.log_decades {
            None => x,
            Some(d) if x > 0.0 => (1.0 + x.log10() / d).max(0.0),
            Some(_) => 0.0,
        }
    };
    // Image axes: the two grid axes other than the ray axis, in order.
    let (u, v) = match style.axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let (w, h, depth) = (grid.n[u], grid.n[v], grid.n[style.axis]);
    let mut rgb = [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]];
    let mut alpha = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (mut c, mut a) = ([0.0f64; 3], 0.0f64);
            for t in 0..depth {
                let mut q = [0usize; 3];
                q[u] = x;
                q[v] = y;
                q[style.axis] = t;
                let idx = grid.index(q[0], q[1], q[2]);
                let s = data[idx];
                let alpha_s = 1.0 - (-style.opacity * s).exp();
                let e = style.gain * weight(phi[idx]);
                let transmit = 1.0 - a;
                for (ch, acc) in c.iter_mut().enumerate() {
                    let tf = style.low[ch] + (style.high[ch] - style.low[ch]) * s;
                    let green = if ch == 1 { e } else { 0.0 };
                    // Thesis Eq 1.13 with the sample's premultiplied colour.
                    *acc += transmit * (alpha_s * tf + green);
                }
                // Thesis Eq 1.14.
                a += transmit * alpha_s;
            }
            let p = y * w + x;
            for ch in 0..3 {
                rgb[ch][p] = c[ch];
            }
            alpha[p] = a;
        }
    }
    Ok(StyleImage { w, h, rgb, alpha })
}
