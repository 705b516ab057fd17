//! Back to world space (POP Secs 4.4 and 5.3; spec §1.11, D13, D19): the ordinate grids'
//! accumulators merged into one medium-aligned grid at `factor`× their resolution (the
//! paper: "double the resolution of the individual propagation grids"), then brought to the
//! medium's voxels by joint bilateral upsampling (Kopf et al. 2007) guided by σs, or by
//! trilinear interpolation (the control).
//!
//! * **Merge (D13).** The merged grid is [`IsoGrid::over`] the medium's box with
//!   `factor`·N cells across its largest extent (cubic cells, the residuum's grid). Each
//!   merged cell takes Σ_n of the clamped trilinear gather of ordinate n's accumulator at its
//!   centre ([`super::OrdinateRun::fluence_at`]'s rule; 0 outside the rotated grid). φ and
//!   L_acc are intensive, so nothing is rescaled.
//! * **Guide.** σs per channel on the medium's voxels, and σs↓ on the merged grid: the mean
//!   of the medium voxels whose centres lie in the merged cell (a cell that holds no voxel
//!   centre takes σs at its own centre, nearest voxel).
//! * **Joint bilateral upsampling (D19).** For a medium voxel p at continuous merged-cell
//!   coordinates u_p, over the 4³ merged cells q around it (clamped at the borders):
//!   S_p = Σ_q S_q w_s w_r / Σ_q w_s w_r with w_s = exp(−‖u_p − u_q‖²/2σ_d²), σ_d = 1 merged
//!   cell, and w_r = exp(−(σs(p) − σs↓(q))²/2σ_r²), σ_r = 0.1·(max σs − min σs) over the
//!   medium (w_r = 1 for a constant σs). A voxel whose weights all vanish (cannot happen in
//!   f64: |Δσs| ≤ 10σ_r keeps w_r ≥ e⁻⁵⁰) would fall back to the spatial filter.
//! * **Trilinear (control).** S_p = clamped trilinear interpolation of the merged grid at p.
//! * **Direct** ([`Upsample::Direct`]): no merged grid, the ordinate grids gathered at the
//!   medium's voxel centres ([`super::PopSolution::fluence_on`], what the method returned
//!   before this module).
//!
//! Tests (`tests` below): T14, a constant guide makes the JBU the spatial filter (to
//! 10⁻¹², against an independent evaluation) and a step-edge guide gives no value outside
//! the range of the 4³ neighbourhood (exact); a constant field stays constant through merge,
//! JBU and trilinear (10⁻¹²); and the W10 measurement below.
//!
//! **W10, what the resampling costs in energy** (`w10_…`, measured): Σ σs φ over the medium's
//! voxels on the Fig 12 cube (16³ voxels, g = 0.7, σs = 4 in the lower half and 0.4 in the
//! upper, one ordinate along x, N = 4, merged 8³, converged): merge and trilinear +0.08 %,
//! merge and JBU −0.31 % relative to the direct gather (bound 1 %). None of the stages conserves
//! energy by construction (spec W10); the JBU moves light towards the side of the edge whose
//! σs matches, which is what it is for.

use super::residuum::IsoGrid;
use super::{Observer, Ordinate, PopConfig, PopMedium, PopSolution};
use crate::pipeline::raymarch::{Term, render_term};
use crate::scene::{Camera, Projection};
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;

/// How the merged grid reaches the medium's voxels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Upsample {
    /// Each ordinate grid gathered straight at the medium's voxel centres (no merged grid).
    #[default]
    Direct,
    /// Merged grid, then clamped trilinear interpolation (the control of D19).
    Trilinear,
    /// Merged grid, then joint bilateral upsampling guided by σs (POP Sec 4.4, D19).
    Jbu,
}

impl std::str::FromStr for Upsample {
    type Err = SolverError;
    fn from_str(s: &str) -> Result<Self, SolverError> {
        match s {
            "direct" => Ok(Self::Direct),
            "trilinear" => Ok(Self::Trilinear),
            "jbu" => Ok(Self::Jbu),
            _ => Err(SolverError::Unsupported(format!(
                "unknown POP upsampling {s:?}: expected direct, trilinear or jbu"
            ))),
        }
    }
}

/// The merge factor of the paper (Sec 5.3: "double the resolution").
pub const DEFAULT_FACTOR: usize = 2;

/// Spatial σ_d of the JBU in merged cells (D19).
pub const SIGMA_D: f64 = 1.0;

/// Range σ_r of the JBU as a fraction of the medium's σs range (D19).
pub const SIGMA_R_FRACTION: f64 = 0.1;

/// Which accumulator to bring to world space.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// Fluence φ = Σ_m L^m.
    Fluence,
    /// The Eq 8 radiance towards the observer, L_acc.
    Radiance,
}

impl Slot {
    fn index(self) -> usize {
        match self {
            Slot::Fluence => 0,
            Slot::Radiance => 2,
        }
    }
}

/// One channel's field on the merged grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Merged {
    /// The merged grid (medium-aligned, cubic cells).
    pub grid: IsoGrid,
    /// Values per merged cell, one vector per channel.
    pub values: Vec<Vec<f64>>,
}

impl<T: Real> PopSolution<T> {
    /// The merged grid of spec D13: `cells` cells across the largest extent of `medium`'s
    /// box, each the sum over ordinates of the trilinear gather of `slot` at its centre.
    pub fn merge(&self, medium: &Grid, cells: usize, slot: Slot) -> Merged {
        let grid = IsoGrid::over(medium, cells.max(1));
        let nc = self.runs.first().map_or(0, |r| r.channels);
        let [nx, ny, _] = grid.dims;
        let values = (0..nc)
            .map(|ch| {
                let mut out = vec![0.0; grid.len()];
                out.par_iter_mut().enumerate().for_each(|(idx, v)| {
                    let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
                    let p = grid.center(i, j, k);
                    *v = self.runs.iter().map(|r| r.slot_at(ch, slot, p)).sum();
                });
                out
            })
            .collect();
        Merged { grid, values }
    }

    /// `slot` per channel at the voxel centres of `target`: Σ over ordinates of the clamped
    /// trilinear gather in each rotated grid (no merged grid).
    pub fn on_grid(&self, target: &Grid, slot: Slot) -> Vec<Vec<f64>> {
        let nc = self.runs.first().map_or(0, |r| r.channels);
        (0..nc)
            .map(|ch| {
                let mut out = target.sample(|_| 0.0);
                out.par_iter_mut().enumerate().for_each(|(idx, v)| {
                    let [i, j, k] = target.coords(idx);
                    let p = target.center(i, j, k);
                    *v = self.runs.iter().map(|r| r.slot_at(ch, slot, p)).sum();
                });
                out
            })
            .collect()
    }

    /// `slot` per channel on the medium's voxels, by `mode`; the merged grid has
    /// `factor`·N cells across the box (N: the ordinate grids' cells per axis).
    pub fn world(
        &self,
        medium: &PopMedium,
        slot: Slot,
        mode: Upsample,
        factor: usize,
    ) -> Result<Vec<Vec<f64>>, SolverError> {
        let target = &medium.grid;
        if mode == Upsample::Direct {
            return Ok(self.on_grid(target, slot));
        }
        if factor == 0 {
            return Err(SolverError::BadParameter {
                name: "pop.merge_factor",
                value: 0.0,
                reason: "the merged grid needs at least the ordinate grids' resolution (≥ 1)",
            });
        }
        let n = self.runs.first().map_or(1, |r| r.grid.n);
        let merged = self.merge(target, factor.saturating_mul(n), slot);
        Ok(merged
            .values
            .iter()
            .enumerate()
            .map(|(ch, low)| {
                let guide = medium
                    .sigma_s
                    .get(ch)
                    .or(medium.sigma_s.first())
                    .map_or(&[][..], |v| &v[..]);
                upsample(&merged.grid, low, target, guide, mode)
            })
            .collect())
    }
}

impl<T: Real> super::OrdinateRun<T> {
    /// Accumulator `slot` of channel `ch` at world point `p` (clamped trilinear in the
    /// rotated grid, 0 outside it).
    pub fn slot_at(&self, ch: usize, slot: Slot, p: [f64; 3]) -> f64 {
        let stride = self.channels * super::cpu::ACC;
        self.grid
            .interpolate_with(&self.acc, stride, ch * super::cpu::ACC + slot.index(), p)
    }
}

/// POP's own image (Sec 4.4: "the emission term corresponds to the scattered radiance
/// accumulated in L_acc"), with what it took.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewImage {
    /// Radiance per pixel, row-major, top-left first.
    pub pixels: Vec<f64>,
    /// The largest number of propagation steps over the ordinates.
    pub steps: usize,
    /// The largest final R/P_inj over the ordinates.
    pub residual: f64,
    /// Wall seconds of the stages: the solve (grids, resampling, injection, propagation),
    /// back to world space (merge and upsampling), the raymarch.
    pub seconds: [f64; 3],
}

/// The observer of Eq 8 for `camera` (D7): the eye of a perspective camera; for an
/// orthographic one the direction from the scene towards the camera.
pub fn observer_of(camera: &Camera) -> Result<Observer, SolverError> {
    Ok(match camera.projection {
        Projection::Perspective { .. } => Observer::Point(camera.eye),
        Projection::Orthographic { .. } => Observer::Direction(super::grid::normalise(
            "camera.eye - camera.target",
            [0, 1, 2].map(|a| camera.eye[a] - camera.target[a]),
        )?),
    })
}

/// POP's image of a one-channel `medium` (phase g) lit by `ordinates`, through `camera`:
/// a solve with the camera as the Eq 8 observer ([`observer_of`]; `config.observer` is
/// replaced), L_acc brought to the medium's voxels by `mode` (merged at
/// [`DEFAULT_FACTOR`]× the ordinate grids' resolution), then the raymarch of σs·L_acc with
/// the full-resolution transmittance (D20) by [`Term::ViewSource`] (`step` in voxel edges,
/// `pixel_samples`² rays per pixel). Every order of scattering comes from POP, the first
/// one included (its m = 0 lobe); the background is not rendered.
#[allow(clippy::too_many_arguments)]
pub fn view_image<T: Real>(
    medium: &Medium<f64>,
    g: f64,
    ordinates: &[Ordinate],
    config: &PopConfig,
    camera: &Camera,
    mode: Upsample,
    step: f64,
    pixel_samples: usize,
) -> Result<ViewImage, SolverError> {
    camera.validate()?;
    let pm = PopMedium::new(std::slice::from_ref(medium), &[g])?;
    let config = PopConfig {
        observer: Some(observer_of(camera)?),
        ..*config
    };
    let t0 = std::time::Instant::now();
    let sol = super::solve::<T>(&pm, ordinates, &config)?;
    let t1 = std::time::Instant::now();
    let s = sol.world(&pm, Slot::Radiance, mode, DEFAULT_FACTOR)?;
    let field = s.first().map_or(&[][..], |v| &v[..]);
    let t2 = std::time::Instant::now();
    let pixels = render_term(
        medium,
        camera,
        Term::ViewSource {
            grid: &medium.grid,
            radiance: field,
        },
        step,
        pixel_samples,
    );
    Ok(ViewImage {
        pixels,
        steps: sol.runs.iter().map(|r| r.steps).max().unwrap_or(0),
        residual: sol
            .runs
            .iter()
            .filter_map(|r| r.history.last().copied())
            .fold(0.0, f64::max),
        seconds: [
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            t2.elapsed().as_secs_f64(),
        ],
    })
}

/// σs↓: the mean of `guide` (on `target`'s voxels) over the voxel centres inside each cell
/// of `low`; a cell without a voxel centre takes the nearest voxel's value at its centre.
pub fn downsample_guide(low: &IsoGrid, target: &Grid, guide: &[f64]) -> Vec<f64> {
    let mut sum = vec![0.0; low.len()];
    let mut count = vec![0u32; low.len()];
    for (idx, &g) in guide.iter().enumerate().take(target.len()) {
        let [i, j, k] = target.coords(idx);
        if let Some(c) = cell_of(low, target.center(i, j, k)) {
            sum[c] += g;
            count[c] += 1;
        }
    }
    let [nx, ny, _] = low.dims;
    (0..low.len())
        .map(|c| {
            if count[c] > 0 {
                sum[c] / count[c] as f64
            } else {
                let p = low.center(c % nx, (c / nx) % ny, c / (nx * ny));
                let v = [0, 1, 2].map(|a| {
                    (((p[a] - target.origin[a]) / target.dl).floor())
                        .clamp(0.0, (target.n[a] - 1) as f64) as usize
                });
                guide
                    .get(target.index(v[0], v[1], v[2]))
                    .copied()
                    .unwrap_or(0.0)
            }
        })
        .collect()
}

fn cell_of(low: &IsoGrid, p: [f64; 3]) -> Option<usize> {
    let mut idx = [0usize; 3];
    for a in 0..3 {
        let u = (p[a] - low.origin[a]) / low.h;
        if !(0.0..low.dims[a] as f64).contains(&u) {
            return None;
        }
        idx[a] = u as usize;
    }
    Some(idx[0] + low.dims[0] * (idx[1] + low.dims[1] * idx[2]))
}

/// `field` on `low` brought to `target`'s voxel centres: trilinear, or JBU guided by `guide`
/// (σs on `target`, one value per voxel). [`Upsample::Direct`] is read as trilinear here
/// (there is no ordinate grid to gather from).
pub fn upsample(
    low: &IsoGrid,
    field: &[f64],
    target: &Grid,
    guide: &[f64],
    mode: Upsample,
) -> Vec<f64> {
    let mut out = target.sample(|_| 0.0);
    if mode != Upsample::Jbu || guide.len() != target.len() {
        out.par_iter_mut().enumerate().for_each(|(idx, v)| {
            let [i, j, k] = target.coords(idx);
            *v = low.gather(field, target.center(i, j, k));
        });
        return out;
    }
    let guide_low = downsample_guide(low, target, guide);
    let (lo, hi) = guide
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &g| {
            (a.min(g), b.max(g))
        });
    let sigma_r = SIGMA_R_FRACTION * (hi - lo);
    out.par_iter_mut().enumerate().for_each(|(idx, v)| {
        let [i, j, k] = target.coords(idx);
        let p = target.center(i, j, k);
        *v = jbu_at(low, field, &guide_low, p, guide[idx], sigma_r);
    });
    out
}

/// The JBU value at world point `p` whose guide value is `gp` (σ_r ≤ 0: spatial filter).
fn jbu_at(
    low: &IsoGrid,
    field: &[f64],
    guide_low: &[f64],
    p: [f64; 3],
    gp: f64,
    sigma_r: f64,
) -> f64 {
    let u = [0, 1, 2].map(|a| (p[a] - low.origin[a]) / low.h - 0.5);
    let base = [0, 1, 2].map(|a| u[a].floor() as i64 - 1);
    let (mut num, mut den, mut num_s, mut den_s) = (0.0, 0.0, 0.0, 0.0);
    for dz in 0..4 {
        for dy in 0..4 {
            for dx in 0..4 {
                let q = [base[0] + dx, base[1] + dy, base[2] + dz];
                let mut d2 = 0.0;
                let mut c = [0usize; 3];
                for a in 0..3 {
                    c[a] = q[a].clamp(0, low.dims[a] as i64 - 1) as usize;
                    let du = u[a] - q[a] as f64;
                    d2 += du * du;
                }
                let cell = c[0] + low.dims[0] * (c[1] + low.dims[1] * c[2]);
                let ws = (-d2 / (2.0 * SIGMA_D * SIGMA_D)).exp();
                let wr = if sigma_r > 0.0 {
                    let dg = gp - guide_low[cell];
                    (-dg * dg / (2.0 * sigma_r * sigma_r)).exp()
                } else {
                    1.0
                };
                num += ws * wr * field[cell];
                den += ws * wr;
                num_s += ws * field[cell];
                den_s += ws;
            }
        }
    }
    if den > 0.0 { num / den } else { num_s / den_s }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pop::{Ordinate, PopConfig, solve};

    fn medium_grid(n: usize) -> Grid {
        Grid::cube(n, 1.0).unwrap()
    }

    /// T14 (a): with a constant guide the JBU is the normalised Gaussian spatial filter over
    /// the 4³ neighbourhood, evaluated here independently (world distances).
    #[test]
    fn t14_constant_guide_is_the_spatial_filter() {
        let target = medium_grid(12);
        let low = IsoGrid::over(&target, 5);
        let field: Vec<f64> = (0..low.len())
            .map(|i| ((i * 7919) % 101) as f64 / 7.0 + 0.5)
            .collect();
        let guide = vec![3.0; target.len()];
        let out = upsample(&low, &field, &target, &guide, Upsample::Jbu);
        let mut worst = 0.0f64;
        for (idx, &got) in out.iter().enumerate() {
            let [i, j, k] = target.coords(idx);
            let p = target.center(i, j, k);
            let (mut num, mut den) = (0.0, 0.0);
            // Independent: every cell of the grid within the 4³ window around p, by world
            // distance between p and the (unclamped) window cell centre.
            let f = [0, 1, 2].map(|a| ((p[a] - low.origin[a]) / low.h - 0.5).floor() as i64);
            for qz in f[2] - 1..=f[2] + 2 {
                for qy in f[1] - 1..=f[1] + 2 {
                    for qx in f[0] - 1..=f[0] + 2 {
                        let q = [qx, qy, qz];
                        let centre = [0, 1, 2].map(|a| low.origin[a] + (q[a] as f64 + 0.5) * low.h);
                        let d2: f64 = (0..3).map(|a| ((p[a] - centre[a]) / low.h).powi(2)).sum();
                        let c = [0, 1, 2].map(|a| q[a].clamp(0, low.dims[a] as i64 - 1) as usize);
                        let w = (-d2 / 2.0).exp();
                        num += w * field[c[0] + low.dims[0] * (c[1] + low.dims[1] * c[2])];
                        den += w;
                    }
                }
            }
            worst = worst.max((got - num / den).abs() / (num / den));
        }
        assert!(
            worst < 1e-12,
            "JBU with a constant guide vs spatial filter: {worst:e}"
        );
    }

    /// T14 (b): a step-edge guide gives no value outside [min, max] of the field over the
    /// 4³ neighbourhood, and keeps the edge: a field that jumps with σs is reproduced on
    /// both sides within 1 % in the two voxels that touch the edge, where trilinear blurs
    /// it (1.25 and 1.75).
    #[test]
    fn t14_step_edge_stays_in_range_and_keeps_the_edge() {
        let target = medium_grid(16);
        let low = IsoGrid::over(&target, 8);
        // σs = 1 for x < 0.5, 10 beyond; the field follows σs (1 and 2) on the low grid.
        let guide: Vec<f64> = (0..target.len())
            .map(|i| if target.coords(i)[0] < 8 { 1.0 } else { 10.0 })
            .collect();
        let field: Vec<f64> = (0..low.len())
            .map(|c| if c % low.dims[0] < 4 { 1.0 } else { 2.0 })
            .collect();
        let jbu = upsample(&low, &field, &target, &guide, Upsample::Jbu);
        let tri = upsample(&low, &field, &target, &guide, Upsample::Trilinear);
        for (idx, &v) in jbu.iter().enumerate() {
            assert!((1.0..=2.0).contains(&v), "voxel {idx}: {v} outside [1, 2]");
        }
        // Voxels 7 and 8 along x touch the edge.
        let row = |f: &[f64], i: usize| f[target.index(i, 8, 8)];
        let (j7, j8, t7, t8) = (row(&jbu, 7), row(&jbu, 8), row(&tri, 7), row(&tri, 8));
        assert!(
            (j7 - 1.0).abs() < 0.01 && (j8 - 2.0).abs() < 0.01,
            "JBU {j7} {j8}"
        );
        assert!(
            (t7 - 1.25).abs() < 1e-12 && (t8 - 1.75).abs() < 1e-12,
            "trilinear {t7} {t8}"
        );
    }

    /// A constant field stays constant through the merge and both upsamplings.
    #[test]
    fn constant_field_stays_constant() {
        let target = Grid::new([10, 7, 5], 0.1).unwrap();
        let low = IsoGrid::over(&target, 6);
        let field = vec![2.5; low.len()];
        let guide: Vec<f64> = (0..target.len()).map(|i| (i % 13) as f64).collect();
        for mode in [Upsample::Trilinear, Upsample::Jbu] {
            let out = upsample(&low, &field, &target, &guide, mode);
            let worst = out.iter().fold(0.0f64, |m, v| m.max((v - 2.5).abs()));
            assert!(worst < 1e-12, "{mode:?}: {worst:e}");
        }
    }

    /// W10 and the merge: Σ σs φ over the medium after direct gather, trilinear and JBU
    /// (the Fig 12 cube at N = 4, merged 8³, medium 16³, with a σs step, so the guide matters); the stages agree
    /// to the bounds below (measured: see the module docs).
    #[test]
    fn w10_energy_through_the_stages() {
        let target = medium_grid(16);
        let mut m = PopMedium::homogeneous(target, 4.0, 0.0, 0.7).unwrap();
        for (i, s) in m.sigma_s[0].iter_mut().enumerate() {
            if target.coords(i)[1] >= 8 {
                *s = 0.4;
            }
        }
        let o = [Ordinate::directional([1.0, 0.0, 0.0], 1.0).unwrap()];
        let sol = solve::<f64>(&m, &o, &PopConfig::new::<f64>(4)).unwrap();
        let energy = |mode| {
            let phi = sol.world(&m, Slot::Fluence, mode, 2).unwrap();
            phi[0]
                .iter()
                .zip(&m.sigma_s[0])
                .map(|(p, s)| p * s)
                .sum::<f64>()
        };
        let (d, t, j) = (
            energy(Upsample::Direct),
            energy(Upsample::Trilinear),
            energy(Upsample::Jbu),
        );
        eprintln!(
            "W10 Σσsφ: direct {d:.6}, trilinear {t:.6} ({:+.4}), jbu {j:.6} ({:+.4})",
            t / d - 1.0,
            j / d - 1.0
        );
        assert!((t / d - 1.0).abs() < 0.01 && (j / d - 1.0).abs() < 0.01);
    }
}
