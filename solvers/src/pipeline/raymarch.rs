//! The primary raymarch (FLD Eq 3) with the source of FLD Eq 8, on CPU (rayon over pixels).
//!
//! Along each camera ray, L = ∫ T(s) Q(s) ds with 4πQ = q_ri + σs φ + j (FLD Eq 8), split
//! into three independently integrated components (see `crate::scene::effects` for their
//! meaning in scattering orders):
//! * single scattering: σs(x) Σ_l p(cos θ_l) E_l(x) exp(−τ_l(x)) (τ_l from the deep
//!   shadow map, see [`super::bake`]), with the scene's phase
//!   function p (HG or isotropic; the isotropic fast path skips the cosine) and θ_l between
//!   light l's propagation direction and the direction towards the camera. With p = 1/4π
//!   this is exactly the paper's q_ri/4π;
//! * multiple scattering: σs(x) φ(x)/4π, φ trilinearly upsampled from the diffusion grid
//!   (isotropic, FLD Section 3);
//! * emission: j(x)/4π.
//!
//! There is no background term: environment and sphere lights are not supported by the
//! pipeline (order-0 light from lights is never rendered).
//!
//! **Integration.** σt, σs and j are piecewise constant per voxel (the project convention,
//! the same nearest-voxel fields the path tracer samples). The ray is split exactly at voxel
//! faces (3D DDA), so the transmittance is exact. Inside a voxel the segment is cut into
//! m = ⌈length / (step·Δl)⌉ equal sub-steps of length h; over a sub-step the source is
//! taken at its midpoint and integrated against the exact attenuation,
//! ∫₀ʰ e^{−σt s} ds = (1 − e^{−σt h})/σt. For the emission term (constant per voxel) this is
//! exact whatever `step`; for the others the error is O(h²). FLD Eq 3 is the Riemann-sum
//! version of the same integral. Rays stop once the optical depth from the camera exceeds
//! [`TAU_CUTOFF`] (T < 10⁻¹⁶).
//!
//! **Pixels.** `pixel_samples` = s gives s×s stratified ray positions per pixel (centres of
//! the sub-squares), averaged: the box filter of the path tracer, in the limit. s = 1 is the
//! pixel centre.

use super::bake::{BakedLight, Shadows};
use super::geometry::{CameraRays, ray_box, traverse, trilinear};
use crate::scene::{Camera, Phase};
use crate::vec3::Vec3;
use crate::{Grid, Medium};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Optical depth from the camera beyond which a ray stops (e^{−37} < 10⁻¹⁶).
pub const TAU_CUTOFF: f64 = 37.0;

const INV_4PI: f64 = 1.0 / (4.0 * PI);

/// What the raymarch integrates.
#[derive(Debug, Clone, Copy)]
pub enum Term<'a> {
    /// Single scattering of these baked lights with this phase function.
    Single {
        /// The lights whose single scattering is rendered.
        lights: &'a [BakedLight],
        /// The phase function (isotropic takes the fast path).
        phase: Phase,
        /// Exact shadow rays or the deep shadow map.
        shadows: Shadows,
    },
    /// σs φ/4π with φ on `grid`.
    Multiple {
        /// The grid of φ.
        grid: &'a Grid,
        /// φ per voxel of `grid`.
        phi: &'a [f64],
    },
    /// j/4π.
    Emission,
}

/// Renders one term through `camera`: radiance per pixel, row-major, top-left first.
pub fn render_term(
    medium: &Medium<f64>,
    camera: &Camera,
    term: Term<'_>,
    step: f64,
    pixel_samples: usize,
) -> Vec<f64> {
    let rays = CameraRays::new(camera);
    let [w, h] = camera.resolution;
    let s = pixel_samples.max(1);
    let sigma_s: Vec<f64> = medium
        .sigma_t
        .iter()
        .zip(&medium.albedo)
        .map(|(t, a)| t * a)
        .collect();
    let step_len = step * medium.grid.dl;
    (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            let mut sum = 0.0;
            for sy in 0..s {
                for sx in 0..s {
                    let px = x + (sx as f64 + 0.5) / s as f64;
                    let py = y + (sy as f64 + 0.5) / s as f64;
                    let (o, d) = rays.ray(px, py);
                    sum += march(medium, &sigma_s, o, d, term, step_len);
                }
            }
            sum / (s * s) as f64
        })
        .collect()
}

/// ∫ T(s)·source(s) ds along one ray for one term.
pub fn march(
    medium: &Medium<f64>,
    sigma_s: &[f64],
    o: Vec3,
    d: Vec3,
    term: Term<'_>,
    step_len: f64,
) -> f64 {
    let g = &medium.grid;
    let Some((t0, t1)) = ray_box(g, o, d, 0.0) else {
        return 0.0;
    };
    let to_camera = d.map(|v| -v);
    let mut tau = 0.0;
    let mut acc = 0.0;
    traverse(g, o, d, t0, t1, |i, a, b| {
        let len = b - a;
        let st = medium.sigma_t[i];
        let (m, h) = match term {
            Term::Emission => (1, len),
            _ => {
                let m = (len / step_len).ceil().max(1.0);
                (m as usize, len / m)
            }
        };
        let weight = if st > 0.0 {
            -(-st * h).exp_m1() / st
        } else {
            h
        };
        let source_at = |t: f64| -> f64 {
            let p = [0, 1, 2].map(|k| o[k] + t * d[k]);
            match term {
                Term::Emission => medium.emission[i] * INV_4PI,
                Term::Multiple { grid, phi } => {
                    sigma_s[i] * trilinear(grid, phi, p, false) * INV_4PI
                }
                Term::Single {
                    lights,
                    phase,
                    shadows,
                } => {
                    let mut sum = 0.0;
                    for l in lights {
                        let (e, dir) = l.unattenuated(p);
                        let t = (-l.tau_at(medium, p, shadows)).exp();
                        let pf = match phase {
                            Phase::Isotropic => INV_4PI,
                            Phase::HenyeyGreenstein { g } => {
                                let cos = dir[0] * to_camera[0]
                                    + dir[1] * to_camera[1]
                                    + dir[2] * to_camera[2];
                                let q = 1.0 + g * g - 2.0 * g * cos;
                                INV_4PI * (1.0 - g * g) / (q * q.sqrt())
                            }
                        };
                        sum += pf * e * t;
                    }
                    sigma_s[i] * sum
                }
            }
        };
        let active = match term {
            Term::Emission => medium.emission[i] > 0.0,
            _ => sigma_s[i] > 0.0,
        };
        if active {
            for k in 0..m {
                let tk = a + (k as f64 + 0.5) * h;
                acc += (-(tau + st * k as f64 * h)).exp() * weight * source_at(tk);
            }
        }
        tau += st * len;
        tau < TAU_CUTOFF
    });
    acc
}
