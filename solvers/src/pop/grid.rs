//! Propagation grids aligned with an ordinate (spec D2–D4): the deterministic frame, the N³
//! cubic cells over the rotated bounding box, and the medium resampled into them.

use super::PopMedium;
use crate::{Grid, SolverError};

/// A unit vector from `d`, or a typed error naming `name` for a zero or non-finite vector.
pub fn normalise(name: &'static str, d: [f64; 3]) -> Result<[f64; 3], SolverError> {
    let len = dot(d, d).sqrt();
    if !(len.is_finite() && len > 0.0) {
        return Err(SolverError::BadParameter {
            name,
            value: len,
            reason: "an ordinate direction must be a non-zero finite vector",
        });
    }
    Ok(d.map(|v| v / len))
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The deterministic orthonormal frame (t₁, t₂, d) of a unit direction `d` (spec D2): the
/// branch-free basis of Duff et al. (*Building an orthonormal basis, revisited*, 2017).
/// Right-handed (t₁ × t₂ = d), continuous except across d_z = 0 where the sign flips. For
/// d = +x it is t₁ = −z, t₂ = +y, so an axis-aligned grid coincides with the medium's voxels.
pub fn frame(d: [f64; 3]) -> [[f64; 3]; 3] {
    let sign = 1f64.copysign(d[2]);
    let a = -1.0 / (sign + d[2]);
    let b = d[0] * d[1] * a;
    let t1 = [1.0 + sign * d[0] * d[0] * a, sign * b, -sign * d[0]];
    let t2 = [b, sign + d[1] * d[1] * a, -d[1]];
    [t1, t2, d]
}

/// One propagation grid: `n³` cubic cells of edge `dx` whose axes are `axes` = (t₁, t₂, d);
/// cell (i, j, k) (i along t₁, j along t₂, k along d, index `i + n(j + n k)`) has its centre
/// at `origin + Σ (index + ½)·dx·axis`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PropagationGrid {
    /// Cells per axis.
    pub n: usize,
    /// Cell edge Δx_n.
    pub dx: f64,
    /// t₁, t₂ and the principal direction d.
    pub axes: [[f64; 3]; 3],
    /// World position of the grid's lower corner.
    pub origin: [f64; 3],
}

impl PropagationGrid {
    /// The grid of direction `d` (unit) over the box of `medium` (spec D3): the box's extent
    /// along each frame axis, Δx = the largest of them / n, centred on the box.
    pub fn over(medium: &Grid, d: [f64; 3], n: usize) -> Self {
        Self::with_axes(medium, frame(d), n)
    }

    /// As [`PropagationGrid::over`] with an explicit orthonormal frame (t₁, t₂, d), for the
    /// frame-invariance test (T12).
    pub fn with_axes(medium: &Grid, axes: [[f64; 3]; 3], n: usize) -> Self {
        let size = medium.size();
        let centre: [f64; 3] = std::array::from_fn(|c| medium.origin[c] + size[c] / 2.0);
        let mut extent = 0f64;
        for ax in &axes {
            // Half extent of the box along `ax`: Σ |ax_c|·size_c/2.
            let half: f64 = (0..3).map(|c| ax[c].abs() * size[c] / 2.0).sum();
            extent = extent.max(2.0 * half);
        }
        let dx = extent / n as f64;
        let half = n as f64 * dx / 2.0;
        let origin =
            std::array::from_fn(|c| centre[c] - half * (axes[0][c] + axes[1][c] + axes[2][c]));
        Self {
            n,
            dx,
            axes,
            origin,
        }
    }

    /// Number of cells, n³.
    pub fn len(&self) -> usize {
        self.n * self.n * self.n
    }

    /// Always false (n ≥ 1).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// World centre of cell (i, j, k).
    pub fn center(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        let u = [i, j, k].map(|v| (v as f64 + 0.5) * self.dx);
        std::array::from_fn(|c| {
            self.origin[c]
                + u[0] * self.axes[0][c]
                + u[1] * self.axes[1][c]
                + u[2] * self.axes[2][c]
        })
    }

    /// Continuous cell coordinates of world point `p` (cell (i, j, k) spans [i, i+1) …).
    pub fn local(&self, p: [f64; 3]) -> [f64; 3] {
        let r = [
            p[0] - self.origin[0],
            p[1] - self.origin[1],
            p[2] - self.origin[2],
        ];
        self.axes.map(|ax| dot(r, ax) / self.dx)
    }

    /// Clamped trilinear interpolation of the cell-centred field `f` (stride `stride`, slot
    /// `slot`) at world point `p`; 0 outside the grid's box (cells beyond it hold nothing).
    pub fn interpolate_with<T: crate::Real>(
        &self,
        f: &[T],
        stride: usize,
        slot: usize,
        p: [f64; 3],
    ) -> f64 {
        let n = self.n;
        let u = self.local(p);
        if u.iter().any(|&v| !(0.0..=n as f64).contains(&v)) {
            return 0.0;
        }
        trilinear([n, n, n], u, |idx| f[idx * stride + slot].f())
    }
}

/// Clamped trilinear interpolation on a cell-centred grid of `dims` at continuous cell
/// coordinates `u` (inside [0, dims]); `at(linear index)` reads a value.
pub(crate) fn trilinear(dims: [usize; 3], u: [f64; 3], at: impl Fn(usize) -> f64) -> f64 {
    let mut i0 = [0usize; 3];
    let mut w1 = [0f64; 3];
    for c in 0..3 {
        let x = (u[c] - 0.5).clamp(0.0, (dims[c] - 1) as f64);
        let f = x.floor().min((dims[c].max(2) - 2) as f64).max(0.0);
        i0[c] = f as usize;
        w1[c] = if dims[c] == 1 { 0.0 } else { x - f };
    }
    let mut s = 0.0;
    for dz in 0..2 {
        for dy in 0..2 {
            for dx in 0..2 {
                let w = (if dx == 1 { w1[0] } else { 1.0 - w1[0] })
                    * (if dy == 1 { w1[1] } else { 1.0 - w1[1] })
                    * (if dz == 1 { w1[2] } else { 1.0 - w1[2] });
                if w == 0.0 {
                    continue;
                }
                let ix = (i0[0] + dx).min(dims[0] - 1);
                let iy = (i0[1] + dy).min(dims[1] - 1);
                let iz = (i0[2] + dz).min(dims[2] - 1);
                s += w * at(ix + dims[0] * (iy + dims[1] * iz));
            }
        }
    }
    s
}

/// The MIP level of spec D4: ℓ = ⌈log₂(Δx_n/Δx_medium)⌉, at least 0, and at most the level
/// where the coarsest axis still has one voxel.
pub fn mip_level(medium: &Grid, dx: f64) -> u32 {
    let ratio = dx / medium.dl;
    let want = if ratio > 1.0 {
        ratio.log2().ceil() as u32
    } else {
        0
    };
    let nmax = medium.n.into_iter().max().unwrap_or(1).max(1);
    let cap = usize::BITS - 1 - nmax.leading_zeros(); // ⌊log₂ nmax⌋
    want.min(cap)
}

/// σs and σa of every channel box-filtered by 2^`level` (spec D4; the restriction of
/// `pipeline::restrict`: the coarse value is Σ children / k³ with missing children vacuum,
/// so ∫σs dV and ∫σa dV are conserved exactly). Returns the coarse grid's dims, edge and
/// origin and the fields `[channel] → (σs, σa)`.
pub fn box_filter(medium: &PopMedium, level: u32) -> MipLevel {
    let g = &medium.grid;
    let filter = |set: &[Vec<f64>]| -> Vec<Vec<f64>> {
        set.iter().map(|f| restrict(g, f, level).1).collect()
    };
    MipLevel {
        dims: restrict_dims(g, level),
        dl: g.dl * (1usize << level) as f64,
        origin: g.origin,
        box_size: g.size(),
        sigma_s: filter(&medium.sigma_s),
        sigma_a: filter(&medium.sigma_a),
    }
}

/// The voxels per axis of the level-`level` box filter of `g`.
fn restrict_dims(g: &Grid, level: u32) -> [usize; 3] {
    let k = 1usize << level;
    g.n.map(|n| n.div_ceil(k))
}

/// One field on `g` box-filtered by 2^`level` (Σ children / k³, missing children vacuum:
/// ∫f dV is conserved exactly); returns the coarse dims and the field.
fn restrict(g: &Grid, f: &[f64], level: u32) -> ([usize; 3], Vec<f64>) {
    let k = 1usize << level;
    let dims = restrict_dims(g, level);
    let inv = 1.0 / (k * k * k) as f64;
    let mut out = vec![0.0; dims[0] * dims[1] * dims[2]];
    for z in 0..g.n[2] {
        for y in 0..g.n[1] {
            for x in 0..g.n[0] {
                let c = x / k + dims[0] * (y / k + dims[1] * (z / k));
                out[c] += f[g.index(x, y, z)] * inv;
            }
        }
    }
    (dims, out)
}

/// The medium's volume emission resampled onto the ordinate grid `grid`, `[cell][channel]`
/// (ours; the same path as σ in D4, then made conservative): the emission box-filtered to
/// the MIP level of [`mip_level`], sampled clamped-trilinear at the rotated cell centres (0
/// at centres outside the medium's box, like σ), then scaled per channel so that
/// Σ j_cell Δx³ = ∫ j dV of the medium exactly. Should no cell centre see the emission (a
/// source smaller than the sampling can reach), each MIP voxel's power goes whole into the
/// cell that holds its centre instead, which conserves it too. Empty without emission.
pub fn resample_emission(medium: &PopMedium, grid: &PropagationGrid) -> Vec<f64> {
    if medium.emission.is_empty() {
        return Vec::new();
    }
    let nc = medium.channels();
    let g = &medium.grid;
    let level = mip_level(g, grid.dx);
    let dl = g.dl * (1usize << level) as f64;
    let size = g.size();
    let n = grid.n;
    let cell_volume = grid.dx.powi(3);
    let mut out = vec![0.0; grid.len() * nc];
    for (ch, field) in medium.emission.iter().enumerate() {
        let total: f64 = field.iter().sum::<f64>() * g.dl.powi(3);
        if total == 0.0 {
            continue;
        }
        let (dims, mip) = restrict(g, field, level);
        let mut sampled = 0.0;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let p = grid.center(i, j, k);
                    let mut u = [0.0; 3];
                    let inside = (0..3).all(|c| {
                        let r = p[c] - g.origin[c];
                        u[c] = r / dl;
                        (0.0..=size[c]).contains(&r)
                    });
                    if inside {
                        let v = trilinear(dims, u, |x| mip[x]);
                        out[(i + n * (j + n * k)) * nc + ch] = v;
                        sampled += v;
                    }
                }
            }
        }
        sampled *= cell_volume;
        if sampled > 0.0 {
            let scale = total / sampled;
            for cell in 0..grid.len() {
                out[cell * nc + ch] *= scale;
            }
        } else {
            deposit_nearest(&mut out, nc, ch, grid, dims, dl, g.origin, &mip);
        }
    }
    out
}

/// The fallback of [`resample_emission`]: every MIP voxel's power j·dl³ into the cell of
/// `grid` that holds the voxel's centre (clamped to the grid), as j per cell volume.
#[allow(clippy::too_many_arguments)]
fn deposit_nearest(
    out: &mut [f64],
    nc: usize,
    ch: usize,
    grid: &PropagationGrid,
    dims: [usize; 3],
    dl: f64,
    origin: [f64; 3],
    mip: &[f64],
) {
    let n = grid.n;
    let ratio = (dl / grid.dx).powi(3);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let v = mip[x + dims[0] * (y + dims[1] * z)];
                if v == 0.0 {
                    continue;
                }
                let p: [f64; 3] =
                    std::array::from_fn(|c| origin[c] + ([x, y, z][c] as f64 + 0.5) * dl);
                let u = grid.local(p).map(|w| (w.max(0.0) as usize).min(n - 1));
                out[(u[0] + n * (u[1] + n * u[2])) * nc + ch] += v * ratio;
            }
        }
    }
}

/// One box-filtered level of the medium (see [`box_filter`]).
#[derive(Debug, Clone)]
pub struct MipLevel {
    /// Voxels per axis.
    pub dims: [usize; 3],
    /// Voxel edge.
    pub dl: f64,
    /// Lower corner (that of the medium).
    pub origin: [f64; 3],
    /// The medium's box size (the level may stick out of it; samples outside are vacuum).
    pub box_size: [f64; 3],
    /// σs per channel per voxel.
    pub sigma_s: Vec<Vec<f64>>,
    /// σa per channel per voxel.
    pub sigma_a: Vec<Vec<f64>>,
}

impl MipLevel {
    /// (σs, σa) of channel `ch` at world point `p`: clamped trilinear inside the medium's
    /// box, vacuum outside.
    pub fn sample(&self, ch: usize, p: [f64; 3]) -> (f64, f64) {
        let mut u = [0.0; 3];
        for c in 0..3 {
            let r = p[c] - self.origin[c];
            if !(0.0..=self.box_size[c]).contains(&r) {
                return (0.0, 0.0);
            }
            u[c] = r / self.dl;
        }
        (
            trilinear(self.dims, u, |i| self.sigma_s[ch][i]),
            trilinear(self.dims, u, |i| self.sigma_a[ch][i]),
        )
    }
}
