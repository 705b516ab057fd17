//! Galerkin coarse levels for a constant limiter (CDA): A_c = R A P with the cycle's own
//! transfers (linear P in node positions, R its adjoint over 8), box stencils of radius 1
//! (27 points) or 2 along cell-coarsened axes, solved for the correction (the coarse problem
//! is linear) with a multi-colour Gauss–Seidel smoother ([`super::CoarseOp::Galerkin`];
//! measured in the module docs of [`super`]). A first version, written for the measurement:
//! the rows are scalar (those within r of a face clip the box with bounds checks) and the
//! setup probes the finer operator once per stencil entry, so it is slower than the
//! rediscretised levels (module docs).

use super::{prolong_into, restrict_fw_into};
use crate::Grid;
use rayon::prelude::*;

/// An operator on a grid's interior voxels with a box stencil of radius `r[d]` per axis
/// (1: 27 points; 2 along cell-coarsened axes, where P reaches two coarse voxels further);
/// the Dirichlet layer holds zero (the unknown is a correction).
#[derive(Debug)]
pub(super) struct BoxStencil {
    grid: Grid,
    r: [usize; 3],
    /// Entries per voxel: Π (2 r[d] + 1).
    len: usize,
    /// Row-major: voxel, then offset (x fastest).
    a: Vec<f64>,
    /// Per slot, the offset's distance in the flat index (for voxels at least r from every
    /// face, whose rows need no bounds checks).
    delta: Vec<isize>,
}

/// The stencil radius per axis of R A P onto the coarse grid of `fg`, given the finer
/// operator's: 1 along vertex-coarsened axes of a radius-1 operator, else 2 (on a
/// cell-coarsened axis the linear P reaches one coarse voxel further; radius 2 stays 2).
pub(super) fn coarse_radius(fg: &Grid, fine_r: [usize; 3]) -> [usize; 3] {
    let ax = super::axes(fg);
    [0, 1, 2].map(|d| if ax[d].vertex && fine_r[d] == 1 { 1 } else { 2 })
}

impl BoxStencil {
    /// The slot of offset `o` (each in −r..=r).
    fn slot(&self, o: [isize; 3]) -> usize {
        let w = self.r.map(|r| 2 * r + 1);
        let u = [0, 1, 2].map(|d| (o[d] + self.r[d] as isize) as usize);
        (u[2] * w[1] + u[1]) * w[0] + u[0]
    }

    /// The centre slot.
    fn centre(&self) -> usize {
        self.slot([0, 0, 0])
    }

    /// R A P of the finer operator `apply` (interior values of A x into the output, zero on
    /// the layer; x is zero on the layer), whose stencil radius per axis is `fine_r`, onto
    /// `cg`, by probing: coarse voxels equal mod 2r + 1 per axis are far enough apart that
    /// each coarse voxel's restricted result holds one entry of its row per probe.
    pub(super) fn galerkin(
        fg: &Grid,
        cg: &Grid,
        fine_r: [usize; 3],
        mut apply: impl FnMut(&[f64], &mut [f64]),
    ) -> Self {
        let r = coarse_radius(fg, fine_r);
        let w = r.map(|r| 2 * r + 1);
        let len = w[0] * w[1] * w[2];
        let (sx, sy) = (cg.n[0] as isize, (cg.n[0] * cg.n[1]) as isize);
        let delta = (0..len)
            .map(|s| {
                let o = [s % w[0], s / w[0] % w[1], s / (w[0] * w[1])];
                let o = [0, 1, 2].map(|d| o[d] as isize - r[d] as isize);
                o[2] * sy + o[1] * sx + o[0]
            })
            .collect();
        let mut op = Self {
            grid: *cg,
            r,
            len,
            a: vec![0.0; cg.len() * len],
            delta,
        };
        let [cnx, cny, cnz] = cg.n;
        let mut probe = vec![0.0; cg.len()];
        let mut fine = vec![0.0; fg.len()];
        let mut af = vec![0.0; fg.len()];
        let mut rc = Vec::new();
        let interior = |i: usize, n: usize| i > 0 && i + 1 < n;
        for class in 0..len {
            let c = [class % w[0], class / w[0] % w[1], class / (w[0] * w[1])];
            for k in 0..cnz {
                for j in 0..cny {
                    for i in 0..cnx {
                        let x = [i, j, k];
                        let on = interior(i, cnx)
                            && interior(j, cny)
                            && interior(k, cnz)
                            && (0..3).all(|d| x[d] % w[d] == c[d]);
                        probe[cg.index(i, j, k)] = if on { 1.0 } else { 0.0 };
                    }
                }
            }
            prolong_into(fg, cg, &probe, &mut fine);
            apply(&fine, &mut af);
            restrict_fw_into(fg, cg, &af, &mut rc);
            for k in 1..cnz.saturating_sub(1) {
                for j in 1..cny - 1 {
                    for i in 1..cnx - 1 {
                        let x = [i, j, k];
                        // The member of this class within ±r of (i, j, k), per axis.
                        let o = [0, 1, 2].map(|d| {
                            let m = ((c[d] + w[d] - x[d] % w[d]) % w[d]) as isize;
                            if m > r[d] as isize {
                                m - w[d] as isize
                            } else {
                                m
                            }
                        });
                        let q = cg.index(i, j, k);
                        let slot = op.slot(o);
                        op.a[q * len + slot] = rc[q];
                    }
                }
            }
        }
        op
    }

    /// The stencil radius per axis.
    pub(super) fn radius(&self) -> [usize; 3] {
        self.r
    }

    /// out = f − A e on the interior (A e without `f`), 0 on the layer.
    pub(super) fn residual_into(&self, e: &[f64], f: Option<&[f64]>, out: &mut [f64]) {
        let g = self.grid;
        let [nx, ny, nz] = g.n;
        let plane = nx * ny;
        out.par_chunks_mut(plane).enumerate().for_each(|(k, slab)| {
            slab.fill(0.0);
            if k == 0 || k + 1 == nz {
                return;
            }
            for j in 1..ny.saturating_sub(1) {
                for i in 1..nx.saturating_sub(1) {
                    let q = g.index(i, j, k);
                    let ae = self.row_dot([i, j, k], e);
                    slab[j * nx + i] = f.map_or(ae, |f| f[q] - ae);
                }
            }
        });
    }

    /// Σ over the row of voxel `x` times e (offsets that leave the grid have zero entries).
    /// Voxels at least r from every face take the flat offsets in slot order; the others
    /// clip the box to the grid (the same slots in the same order, so the same sum).
    fn row_dot(&self, x: [usize; 3], e: &[f64]) -> f64 {
        let g = &self.grid;
        let q = g.index(x[0], x[1], x[2]);
        let row = &self.a[q * self.len..(q + 1) * self.len];
        if (0..3).all(|d| x[d] >= self.r[d] && x[d] + self.r[d] < g.n[d]) {
            return row
                .iter()
                .zip(&self.delta)
                .fold(0.0, |s, (a, &dq)| s + a * e[q.wrapping_add_signed(dq)]);
        }
        let range = |d: usize| {
            let lo = x[d].saturating_sub(self.r[d]);
            let hi = (x[d] + self.r[d]).min(g.n[d] - 1);
            lo..=hi
        };
        let mut s = 0.0;
        for k in range(2) {
            for j in range(1) {
                for i in range(0) {
                    let o = [
                        i as isize - x[0] as isize,
                        j as isize - x[1] as isize,
                        k as isize - x[2] as isize,
                    ];
                    s += row[self.slot(o)] * e[g.index(i, j, k)];
                }
            }
        }
        s
    }

    /// One Gauss–Seidel sweep in colours: voxels equal mod r + 1 per axis (8 colours for 27
    /// points, up to 27 for radius 2) are outside each other's stencil, so each colour's
    /// updates are independent and the result does not depend on the thread count.
    /// `scratch` is as long as the grid.
    pub(super) fn sweep(&self, e: &mut [f64], f: &[f64], scratch: &mut [f64]) {
        let g = self.grid;
        let [nx, ny, nz] = g.n;
        let plane = nx * ny;
        let m = self.r.map(|r| r + 1);
        let centre = self.centre();
        for colour in 0..m[0] * m[1] * m[2] {
            let c = [colour % m[0], colour / m[0] % m[1], colour / (m[0] * m[1])];
            let src: &[f64] = e;
            scratch
                .par_chunks_mut(plane)
                .enumerate()
                .for_each(|(k, slab)| {
                    if k == 0 || k + 1 == nz || k % m[2] != c[2] {
                        return;
                    }
                    for j in colour_range(ny, m[1], c[1]) {
                        for i in colour_range(nx, m[0], c[0]) {
                            let q = g.index(i, j, k);
                            let diag = self.a[q * self.len + centre];
                            let off = self.row_dot([i, j, k], src) - diag * src[q];
                            slab[j * nx + i] = (f[q] - off) / diag;
                        }
                    }
                });
            e.par_chunks_mut(plane)
                .zip(scratch.par_chunks(plane))
                .enumerate()
                .for_each(|(k, (slab, new))| {
                    if k == 0 || k + 1 == nz || k % m[2] != c[2] {
                        return;
                    }
                    for j in colour_range(ny, m[1], c[1]) {
                        for i in colour_range(nx, m[0], c[0]) {
                            slab[j * nx + i] = new[j * nx + i];
                        }
                    }
                });
        }
    }
}

/// The interior indices 1..n − 1 equal to `c` mod `m`.
fn colour_range(n: usize, m: usize, c: usize) -> impl Iterator<Item = usize> {
    // The first index ≥ 1 that is c mod m.
    let first = 1 + (c + m - 1) % m;
    (first..n.saturating_sub(1)).step_by(m)
}
