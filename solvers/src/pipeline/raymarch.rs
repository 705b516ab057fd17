//! The primary raymarch (FLD Eq 3) with the source of FLD Eq 8, on CPU (rayon over pixels).
//!
//! Along each camera ray, L = ∫ T(s) Q(s) ds with 4πQ = q_ri + σs φ + j (FLD Eq 8), split
//! into four independently integrated components (see `crate::scene::effects` for their
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
//! * background: L_env·T(camera ray), the environment seen through the medium (order 0
//!   from the lights), with T = exp(−∫σt) exact by voxel traversal; a ray that misses the
//!   box sees L_env. Sphere lights seen directly are not rendered (the planner refuses
//!   them), and `[camera] hide_background = true` leaves the term out.
//!
//! **Integration.** σt, σs and j are piecewise constant per voxel (the project convention,
//! the same nearest-voxel fields the path tracer samples). The ray is split exactly at voxel
//! faces (3D DDA), so the transmittance is exact. Inside a voxel the segment is cut into
//! m = ⌈length / (step·Δl)⌉ equal sub-steps of length h. Over a sub-step the integrand is
//! e^{−τ(s)}·f(s), τ the total optical depth (camera side, plus the light side for single
//! scattering) and f the rest of the source; both are evaluated at the sub-step's ends and
//! integrated exactly as if linear (`exp_linear`: ∫₀ʰ e^{−(τa + cs)}(fa + f′s) ds in closed
//! form, from the far end when τ falls along s). So:
//! * emission (f = j/4π constant per voxel): exact whatever `step`;
//! * multiple scattering (f = σs φ/4π, φ trilinear): exact for the attenuation, second
//!   order in h for φ's variation;
//! * single scattering: the depth to a light is piecewise linear along a ray in
//!   piecewise-constant media, with kinks where the shadow ray's exit face or the voxels it
//!   crosses change. Each sub-step checks the depth at its midpoint and is bisected (at most
//!   [`MAX_BISECTIONS`] times) while it deviates from linear by more than [`TAU_LINEARITY`]
//!   (10⁻²; the measured trade of accuracy and time is beside it); the phase function and
//!   1/r² are smooth and taken linear.
//!
//! The default step is then right for σt·Δl from 0 to 10⁶: *measured* on albedo-1 16³ cubes
//! (σt·Δl = 0.6, 6, 60, 6000, directional light, 48×48 rays per pixel), image means within
//! 1.3·10⁻³ of the path tracer (|z| ≤ 0.76) and every pixel within its Šidák-corrected test,
//! and the same image at step 0.05 (`reference/tests/raymarch_dense.rs`). The earlier
//! midpoint rule gave 1.5·10⁻¹² for 0.021 at σt·Δl = 62.5. FLD Eq 3 is the Riemann-sum
//! version of the same integral. Rays stop once the optical depth from the camera exceeds
//! [`TAU_CUTOFF`] (T < 10⁻¹⁶).
//!
//! **Pixels.** `pixel_samples` = s gives s×s stratified ray positions per pixel (centres of
//! the sub-squares), averaged: the box filter of the path tracer, in the limit. s = 1 is the
//! pixel centre.

use super::bake::{BakedLight, Shadows};
use super::geometry::{CameraRays, optical_depth, ray_box, traverse, trilinear};
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
    /// σs·S with S on `grid`: a view-dependent source, the in-scattered radiance per unit σs
    /// towards *this* camera (POP's L_acc for an observer at the camera, `pop::upsample`).
    /// Unlike [`Term::Multiple`] there is no 1/4π: S is already a radiance.
    ViewSource {
        /// The grid of S.
        grid: &'a Grid,
        /// S per voxel of `grid`.
        radiance: &'a [f64],
    },
    /// j/4π.
    Emission,
    /// The environment seen through the medium: `radiance`·T along the camera ray.
    Background {
        /// Summed radiance of the environment lights.
        radiance: f64,
    },
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

/// ∫₀ʰ e^{−c s} ds = h·(1 − e^{−ch})/(ch), for c ≥ 0 (series near 0).
#[inline]
fn w0(c: f64, h: f64) -> f64 {
    let x = c * h;
    if x < 1e-4 {
        h * (1.0 - x / 2.0 + x * x / 6.0)
    } else {
        -(-x).exp_m1() / c
    }
}

/// ∫₀ʰ e^{−c s} s ds = (1 − e^{−ch}(1 + ch))/c², for c ≥ 0 (series near 0).
#[inline]
fn w1(c: f64, h: f64) -> f64 {
    let x = c * h;
    if x < 1e-3 {
        h * h * (0.5 - x / 3.0 + x * x / 8.0)
    } else {
        (-(-x).exp_m1() - x * (-x).exp()) / (c * c)
    }
}

/// ∫₀ʰ e^{−(τa + (τb − τa)s/h)} f(s) ds with f linear from `fa` to `fb`: exact for an
/// optical depth linear over the sub-step. `tau_a`, `tau_b` are the total optical depths
/// (camera side plus light side) at its ends; a depth that falls along the sub-step
/// (moving towards a light through thinner voxels) is integrated from the far end, so no
/// exponential overflows.
#[inline]
fn exp_linear(tau_a: f64, tau_b: f64, fa: f64, fb: f64, h: f64) -> f64 {
    let c = (tau_b - tau_a) / h;
    let slope = (fb - fa) / h;
    if c >= 0.0 {
        (-tau_a).exp() * (fa * w0(c, h) + slope * w1(c, h))
    } else {
        (-tau_b).exp() * (fb * w0(-c, h) - slope * w1(-c, h))
    }
}

/// Largest deviation of the optical depth to a light at a sub-step's midpoint from the
/// mean of its ends for which the depth counts as linear over the sub-step. *Measured*
/// (worst relative error against the closed form of `solvers/tests/pipeline.rs`; time of
/// `render --scene scenes/nebula.toml --method cda`, 128³ heterogeneous, on 2 cores):
/// 10⁻⁴: 1.4·10⁻⁸, 0.80 s; 10⁻³: 7.1·10⁻⁶, 0.51 s; 10⁻²: 2.2·10⁻⁴, 0.36 s, with the nebula
/// image within 8.4·10⁻⁴ (relative L2) of the 10⁻⁴ one and the dense cubes of
/// `reference/tests/raymarch_dense.rs` unchanged. In heterogeneous media the depth to a
/// light has a kink wherever a shadow ray's crossed voxels change, so a tight threshold
/// bisects almost every sub-step; 10⁻² keeps the exactness that matters (dense voxels,
/// where the kinks are deep) at a cost near the plain sub-step rule's.
pub const TAU_LINEARITY: f64 = 1e-2;

/// Most bisections of a sub-step whose optical depth to a light is not linear (a kink where
/// the shadow ray's exit face changes, a denser voxel on the shadow ray's path): 2⁻²⁰ of
/// the sub-step.
pub const MAX_BISECTIONS: u32 = 20;

/// Single scattering over the sub-step [t, t + h] of a voxel with extinction `st`, the
/// camera-side optical depth `cam` at t, and (source, depth to the light) `fa` at t and
/// `fb` at t + h: [`exp_linear`] when the depth to the light is linear over it (checked at
/// the midpoint against [`TAU_LINEARITY`]), else the sum over its halves.
#[allow(clippy::too_many_arguments)]
fn shadowed(
    node: &impl Fn(f64) -> (f64, f64),
    st: f64,
    t: f64,
    h: f64,
    cam: f64,
    fa: (f64, f64),
    fb: (f64, f64),
    bisections: u32,
) -> f64 {
    let (ta, tb) = (cam + fa.1, cam + st * h + fb.1);
    if bisections > 0 {
        let fm = node(t + 0.5 * h);
        let tm = cam + st * 0.5 * h + fm.1;
        if (tm - 0.5 * (ta + tb)).abs() > TAU_LINEARITY && tm.min(ta).min(tb) < TAU_CUTOFF {
            let half = 0.5 * h;
            return shadowed(node, st, t, half, cam, fa, fm, bisections - 1)
                + shadowed(
                    node,
                    st,
                    t + half,
                    half,
                    cam + st * half,
                    fm,
                    fb,
                    bisections - 1,
                );
        }
    }
    exp_linear(ta, tb, fa.0, fb.0, h)
}

/// ∫ T(s)·source(s) ds along one ray for one term.
///
/// Within a voxel the ray is cut into sub-steps; the source (and, for single scattering,
/// the optical depth to each light) is evaluated at the sub-step ends and the integral
/// over each sub-step is exact for a source linear and an optical depth linear along it
/// (`exp_linear`), so a dense voxel's exponential fall-off is integrated exactly whatever
/// `step_len` (see the module docs).
pub fn march(
    medium: &Medium<f64>,
    sigma_s: &[f64],
    o: Vec3,
    d: Vec3,
    term: Term<'_>,
    step_len: f64,
) -> f64 {
    let g = &medium.grid;
    if let Term::Background { radiance } = term {
        return radiance * (-optical_depth(g, &medium.sigma_t, o, d, f64::INFINITY)).exp();
    }
    let Some((t0, t1)) = ray_box(g, o, d, 0.0) else {
        return 0.0;
    };
    let to_camera = d.map(|v| -v);
    let mut tau = 0.0f64;
    let mut acc = 0.0f64;
    traverse(g, o, d, t0, t1, |i, a, b| {
        let len = b - a;
        let st = medium.sigma_t[i];
        let point = |t: f64| -> Vec3 { [0, 1, 2].map(|k| o[k] + t * d[k]) };
        match term {
            Term::Emission if medium.emission[i] > 0.0 => {
                acc += (-tau).exp() * w0(st, len) * medium.emission[i] * INV_4PI;
            }
            Term::Multiple { grid, phi: field }
            | Term::ViewSource {
                grid,
                radiance: field,
            } if sigma_s[i] > 0.0 => {
                let scale = if matches!(term, Term::Multiple { .. }) {
                    INV_4PI
                } else {
                    1.0
                };
                let m = (len / step_len).ceil().max(1.0) as usize;
                let h = len / m as f64;
                let f = |t: f64| sigma_s[i] * trilinear(grid, field, point(t), false) * scale;
                let mut fa = f(a);
                for k in 0..m {
                    let fb = f(a + (k + 1) as f64 * h);
                    let ta = tau + st * k as f64 * h;
                    acc += exp_linear(ta, ta + st * h, fa, fb, h);
                    fa = fb;
                }
            }
            Term::Single {
                lights,
                phase,
                shadows,
            } if sigma_s[i] > 0.0 => {
                let m = (len / step_len).ceil().max(1.0) as usize;
                let h = len / m as f64;
                for l in lights.iter() {
                    // (σs·p·E, optical depth to the light) at ray parameter t.
                    let node = |t: f64| -> (f64, f64) {
                        let p = point(t);
                        let (e, dir) = l.unattenuated(p);
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
                        (sigma_s[i] * pf * e, l.tau_at(medium, p, shadows))
                    };
                    let mut prev = node(a);
                    for k in 0..m {
                        let ta = a + k as f64 * h;
                        let next = node(ta + h);
                        let cam = tau + st * k as f64 * h;
                        acc += shadowed(&node, st, ta, h, cam, prev, next, MAX_BISECTIONS);
                        prev = next;
                    }
                }
            }
            _ => {}
        }
        tau += st * len;
        tau < TAU_CUTOFF
    });
    acc
}
