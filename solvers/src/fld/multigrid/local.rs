//! Local relaxation around point-like sources ([`super::MgConfig::local_sweeps`]): Brandt's
//! remedy for singularities, which keep a multigrid cycle's rate from being
//! grid-independent because the smoother and the coarse levels both see the singular
//! neighbourhood worse the finer the grid is (the one-voxel source of `point_source` holds
//! j = 1/Δl³, and FLD's R ≈ 1/(σr) near it grows without bound as Δl shrinks).
//!
//! A *point-like source* is a voxel at least two voxels inside the Dirichlet layer that holds
//! at least [`POINT_SHARE`] of the grid's total emission (at most [`MAX_BOXES`] of them,
//! the largest). Around each, a box (dropped if it holds vacuum, [`VACUUM_CONTRAST`]) of optical half-width `local_radius` (in voxels per axis
//! ⌈τ₀ / (σ Δl)⌉ with the source voxel's floored σ, at most a quarter of the axis, clipped two
//! voxels inside the layer) gets `local_sweeps` extra red-black sweeps of the finest level's
//! equation with D recomputed from φ before each colour (the nonlinear Gauss–Seidel of FLD
//! Eq 32 with the smoother's ω and projection φ ≥ 0), twice per cycle: after the coarse-grid
//! correction and after the post-smoothing. Measured in the module docs of [`super`].

use crate::Grid;
use crate::fld::limiter::with_limiter;
use crate::fld::{FldConfig, FluxLimiter};
use rayon::prelude::*;

/// The share of the total emission one voxel must hold to count as a point-like source.
pub const POINT_SHARE: f64 = 0.01;

/// A box holding a σ below this fraction of its largest σ holds vacuum and is dropped.
pub const VACUUM_CONTRAST: f64 = 0.01;

/// At most this many boxes (the voxels with the largest emission first).
pub const MAX_BOXES: usize = 8;

/// An axis-aligned box of voxels (inclusive bounds), at least two voxels inside the
/// Dirichlet layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct LocalBox {
    pub lo: [usize; 3],
    pub hi: [usize; 3],
}

impl LocalBox {
    /// Voxels in the box.
    pub fn len(&self) -> usize {
        (0..3).map(|d| self.hi[d] + 1 - self.lo[d]).product()
    }

    /// The box grown by `by` voxels per side (the caller keeps it on the grid).
    pub fn grown(&self, by: usize) -> Self {
        Self {
            lo: self.lo.map(|x| x - by),
            hi: self.hi.map(|x| x + by),
        }
    }
}

/// The boxes around the point-like sources of the right-hand side `rhs` (natural layout),
/// with the floored σ `sig` and the optical half-width `radius`.
pub(super) fn source_boxes(g: &Grid, rhs: &[f64], sig: &[f64], radius: f64) -> Vec<LocalBox> {
    let total: f64 = rhs.iter().filter(|x| x.is_finite() && **x > 0.0).sum();
    if !total.is_finite() || total <= 0.0 || g.n.iter().any(|&n| n < 5) {
        return Vec::new();
    }
    // Only the few voxels over the share are located (no pass over every voxel's coordinates).
    let inside = |c: [usize; 3]| (0..3).all(|d| c[d] >= 2 && c[d] + 3 <= g.n[d]);
    let mut points: Vec<(f64, [usize; 3])> = rhs
        .iter()
        .enumerate()
        .filter(|&(_, &x)| x / total >= POINT_SHARE)
        .map(|(p, &x)| (x / total, g.coords(p)))
        .filter(|&(_, c)| inside(c))
        .collect();
    points.sort_by(|a, b| b.0.total_cmp(&a.0));
    points.truncate(MAX_BOXES);
    points
        .into_iter()
        .map(|(_, c)| {
            // ⌈τ₀/(σΔl)⌉ voxels, at least 1 and at most a quarter of the axis (a source in
            // vacuum, σΔl → 0, gets the cap).
            let r = (radius / (sig[g.index(c[0], c[1], c[2])] * g.dl)).ceil();
            let half = [0, 1, 2].map(|d| {
                let cap = (g.n[d] / 4).max(1);
                if r.is_finite() {
                    (r.max(1.0) as usize).min(cap)
                } else {
                    cap
                }
            });
            LocalBox {
                lo: [0, 1, 2].map(|d| c[d].saturating_sub(half[d]).max(2)),
                hi: [0, 1, 2].map(|d| (c[d] + half[d]).min(g.n[d] - 3)),
            }
        })
        .filter(|b| !has_vacuum(g, sig, b))
        .collect()
}

/// Whether box `b` holds vacuum: a voxel whose σ is below [`VACUUM_CONTRAST`] of the box's
/// largest. Such boxes are dropped: there the sweeps' freshly recomputed D swings as it does
/// at the cloud's D peak (module docs of [`super`]), and FLD-LP on white noise with 95 %
/// vacuum stalled (`Stalled` after 38 cycles to 10⁻⁹, where it converges in 27 without).
fn has_vacuum(g: &Grid, sig: &[f64], b: &LocalBox) -> bool {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for k in b.lo[2]..=b.hi[2] {
        for j in b.lo[1]..=b.hi[1] {
            for i in b.lo[0]..=b.hi[0] {
                let s = sig[g.index(i, j, k)];
                (lo, hi) = (lo.min(s), hi.max(s));
            }
        }
    }
    lo < VACUUM_CONTRAST * hi
}

/// The finest level's fields a local sweep reads (natural layout, normalised units).
pub(super) struct Fields<'a> {
    pub grid: &'a Grid,
    pub rhs: &'a [f64],
    pub sig: &'a [f64],
    pub absorb: &'a [f64],
    /// D of a constant limiter (CDA), else `None` (D is recomputed from φ).
    pub d_fixed: Option<&'a [f64]>,
    pub config: &'a FldConfig,
    /// The floor of |∇φ| and σφ in R (as the residual's D uses it).
    pub floor: f64,
    pub omega: f64,
}

/// `sweeps` red-black sweeps over box `b` of φ (natural layout, updated in place); the rest
/// of φ is the boundary data. D is recomputed from φ before each colour (FLD limiters; a
/// constant limiter's fixed D is read as it is).
pub(super) fn relax(f: &Fields<'_>, b: &LocalBox, phi: &mut [f64], sweeps: usize) {
    let g = f.grid;
    let [nx, ny, _] = g.n;
    let plane = nx * ny;
    // D over the box grown by one (every neighbour a box voxel couples to), box-local.
    let e = b.grown(1);
    let ew = [0, 1, 2].map(|d| e.hi[d] + 1 - e.lo[d]);
    let mut dloc = match f.d_fixed {
        Some(_) => Vec::new(),
        None => vec![0.0; e.len()],
    };
    let bw = [0, 1, 2].map(|d| b.hi[d] + 1 - b.lo[d]);
    // Both colours' candidate values, row by row (box-local layout); a colour writes back
    // its own. A voxel's six neighbours all have the other colour, so a row computed from
    // the φ before the colour's pass gives the colour's voxels exactly the values a
    // per-voxel red-black update gives them, in contiguous loops that vectorise.
    let mut upd = vec![0.0; b.len()];
    let dl2 = g.dl * g.dl;
    // Where D is read: the fixed field (natural layout) or the box-local one.
    let (d_origin, [s1, s2, s3]) = match f.d_fixed {
        Some(_) => (None, [1, nx, plane]),
        None => (Some(e.lo), [1, ew[0], ew[0] * ew[1]]),
    };
    for _ in 0..sweeps {
        for colour in 0..2 {
            if f.d_fixed.is_none() {
                fill_d(f, &e, ew, phi, &mut dloc);
            }
            let dfield: &[f64] = f.d_fixed.unwrap_or(&dloc);
            let d_at = |i: usize, j: usize, k: usize| match d_origin {
                Some(o) => ((k - o[2]) * ew[1] + (j - o[1])) * ew[0] + (i - o[0]),
                None => g.index(i, j, k),
            };
            let phi_r: &[f64] = phi;
            upd.par_chunks_mut(bw[0] * bw[1])
                .enumerate()
                .for_each(|(kk, slab)| {
                    let k = b.lo[2] + kk;
                    for (jj, row) in slab.chunks_mut(bw[0]).enumerate() {
                        let j = b.lo[1] + jj;
                        let n = g.index(b.lo[0], j, k);
                        let m = d_at(b.lo[0], j, k);
                        let w = bw[0];
                        let ph = |o: usize| &phi_r[o..o + w];
                        let dd = |o: usize| &dfield[o..o + w];
                        // Neighbours in the order x−, x+, y−, y+, z−, z+ (the sums' order).
                        let nbp = [n - 1, n + 1, n - nx, n + nx, n - plane, n + plane].map(&ph);
                        let nbd = [m - s1, m + s1, m - s2, m + s2, m - s3, m + s3].map(&dd);
                        let (pc, dc) = (ph(n), dd(m));
                        let (ab, rh) = (&f.absorb[n..n + w], &f.rhs[n..n + w]);
                        for q in 0..w {
                            let dp = dc[q];
                            let (mut num, mut den) = (0.0, ab[q]);
                            for t in 0..6 {
                                let c = 0.5 * (dp + nbd[t][q]);
                                num += c * nbp[t][q];
                                den += c;
                            }
                            let new = (rh[q] * dl2 + num) / den;
                            let x = (1.0 - f.omega) * pc[q] + f.omega * new;
                            row[q] = x.max(0.0);
                        }
                    }
                });
            // Write the colour's new values back, plane by plane.
            phi.par_chunks_mut(plane)
                .skip(b.lo[2])
                .take(bw[2])
                .zip(upd.par_chunks(bw[0] * bw[1]))
                .enumerate()
                .for_each(|(kk, (pl, slab))| {
                    for_colour(b, kk, colour, |j, i, at| pl[j * nx + i] = slab[at]);
                });
        }
    }
}

/// Calls `f(j, i, at)` for every voxel of colour `colour` ((i + j + k) mod 2) in plane `kk`
/// of box `b` (k = b.lo[2] + kk), with `at` its index in the box's plane.
fn for_colour(b: &LocalBox, kk: usize, colour: usize, mut f: impl FnMut(usize, usize, usize)) {
    let k = b.lo[2] + kk;
    let w = b.hi[0] + 1 - b.lo[0];
    for j in b.lo[1]..=b.hi[1] {
        let first = b.lo[0] + ((b.lo[0] + j + k + colour) & 1);
        for i in (first..=b.hi[0]).step_by(2) {
            f(j, i, (j - b.lo[1]) * w + (i - b.lo[0]));
        }
    }
}

/// FLD's D = F(R)/σ over box `e` (box-local layout, widths `ew`) at φ, with centred
/// differences, as the multigrid's residual evaluates it inside; row by row, one limiter
/// per loop so the loop vectorises.
fn fill_d(f: &Fields<'_>, e: &LocalBox, ew: [usize; 3], phi: &[f64], out: &mut [f64]) {
    with_limiter!(f.config.limiter, |lim| fill_d_with(f, e, ew, phi, lim, out))
}

/// [`fill_d`] for one limiter `lim` ([`FluxLimiter::fraction`]), row by row with the
/// residual's own row kernel ([`super::d_row`]).
fn fill_d_with<L: Fn(f64) -> (f64, f64) + Sync>(
    f: &Fields<'_>,
    e: &LocalBox,
    ew: [usize; 3],
    phi: &[f64],
    lim: L,
    out: &mut [f64],
) {
    let g = f.grid;
    out.par_chunks_mut(ew[0] * ew[1])
        .enumerate()
        .for_each(|(kk, slab)| {
            for (jj, row) in slab.chunks_mut(ew[0]).enumerate() {
                let c = g.index(e.lo[0], e.lo[1] + jj, e.lo[2] + kk);
                super::d_row(g, phi, f.sig, c, f.floor, &lim, row);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The point source's box: one voxel with all the emission gets a box of half-width
    /// ⌈τ₀/(σΔl)⌉ around it; emission spread over the grid gets none; a source in vacuum
    /// (σ tiny) gets at most a quarter of each axis.
    #[test]
    fn boxes_sit_around_point_like_sources_only() {
        let g = Grid::cube(31, 1.0).unwrap();
        let mut rhs = vec![0.0; g.len()];
        let c = g.index(15, 15, 15);
        rhs[c] = 1.0;
        let sig = vec![4.0 * 31.0; g.len()];
        // σΔl = 4: τ₀ = 0.5 → ⌈0.125⌉ = 1; with σΔl = 0.125, ⌈4⌉ = 4.
        assert_eq!(
            source_boxes(&g, &rhs, &sig, 0.5),
            vec![LocalBox {
                lo: [14; 3],
                hi: [16; 3]
            }]
        );
        let thin = vec![0.125 * 31.0; g.len()];
        let b = source_boxes(&g, &rhs, &thin, 0.5);
        assert_eq!(
            b,
            vec![LocalBox {
                lo: [11; 3],
                hi: [19; 3]
            }]
        );
        assert_eq!(b[0].len(), 729);
        let vacuum = vec![1e-9; g.len()];
        assert_eq!(
            source_boxes(&g, &rhs, &vacuum, 0.5),
            vec![LocalBox {
                lo: [8; 3],
                hi: [22; 3]
            }]
        );
        // A source whose box reaches vacuum (σ 10⁴ below the source's) gets none.
        let mut pocket = thin.clone();
        pocket[g.index(12, 15, 15)] = 1e-5 * 31.0;
        assert!(source_boxes(&g, &rhs, &pocket, 0.5).is_empty());
        // Spread emission: no voxel holds 1 %.
        let spread: Vec<f64> = (0..g.len())
            .map(|p| {
                let [i, j, k] = g.coords(p);
                if g.is_boundary(i, j, k) { 0.0 } else { 1.0 }
            })
            .collect();
        assert!(source_boxes(&g, &spread, &sig, 0.5).is_empty());
        // Near the Dirichlet layer the box is clipped two voxels inside it.
        let mut edge = vec![0.0; g.len()];
        edge[g.index(2, 15, 28)] = 1.0;
        assert_eq!(
            source_boxes(&g, &edge, &thin, 0.5),
            vec![LocalBox {
                lo: [2, 11, 24],
                hi: [6, 19, 28]
            }]
        );
    }

    /// The per-voxel red-black box sweep the row kernel replaced, as the reference: D over the
    /// grown box before each colour, then each voxel of the colour in turn.
    fn relax_per_voxel(f: &Fields<'_>, b: &LocalBox, phi: &mut [f64], sweeps: usize) {
        let g = f.grid;
        let e = b.grown(1);
        let inv_2dl = 0.5 / g.dl;
        let steps = [1, g.n[0], g.n[0] * g.n[1]];
        let dl2 = g.dl * g.dl;
        for _ in 0..sweeps {
            for colour in 0..2 {
                let mut d = vec![0.0; g.len()];
                for k in e.lo[2]..=e.hi[2] {
                    for j in e.lo[1]..=e.hi[1] {
                        for i in e.lo[0]..=e.hi[0] {
                            let n = g.index(i, j, k);
                            d[n] = match f.d_fixed {
                                Some(dd) => dd[n],
                                None => {
                                    let gr = steps.map(|s| (phi[n + s] - phi[n - s]) * inv_2dl);
                                    let r = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2])
                                        .sqrt()
                                        .max(f.floor)
                                        / (f.sig[n] * phi[n]).max(f.floor);
                                    let (num, den) = f.config.limiter.fraction(r);
                                    num / (den * f.sig[n])
                                }
                            };
                        }
                    }
                }
                let old = phi.to_vec();
                for k in b.lo[2]..=b.hi[2] {
                    for j in b.lo[1]..=b.hi[1] {
                        for i in b.lo[0]..=b.hi[0] {
                            if (i + j + k + colour) & 1 != 0 {
                                continue;
                            }
                            let n = g.index(i, j, k);
                            let (mut num, mut den) = (0.0, f.absorb[n]);
                            for q in [n - 1, n + 1, n - steps[1], n + steps[1]]
                                .into_iter()
                                .chain([n - steps[2], n + steps[2]])
                            {
                                let c = 0.5 * (d[n] + d[q]);
                                num += c * old[q];
                                den += c;
                            }
                            let new = (f.rhs[n] * dl2 + num) / den;
                            phi[n] = ((1.0 - f.omega) * old[n] + f.omega * new).max(0.0);
                        }
                    }
                }
            }
        }
    }

    /// The row kernel of [`relax`] (whole rows, both colours computed, D row by row) gives
    /// every voxel bit for bit the value of the per-voxel red-black sweep, for a constant
    /// limiter's fixed D and for FLD-LP's D recomputed before each colour, on a box with
    /// odd and even widths and an odd first corner (both colours start a row), and leaves
    /// φ outside the box alone.
    #[test]
    fn the_row_kernel_is_the_per_voxel_red_black_sweep_bit_for_bit() {
        let g = Grid::new([23, 20, 21], 0.05).unwrap();
        let field = |a: f64, b: f64| -> Vec<f64> {
            (0..g.len())
                .map(|p| {
                    let [i, j, k] = g.coords(p);
                    a + b
                        * (0.37 * i as f64 + 0.61 * j as f64 - 0.29 * k as f64)
                            .sin()
                            .abs()
                })
                .collect()
        };
        let (sig, absorb, rhs) = (field(2.0, 30.0), field(0.01, 0.2), field(0.0, 5.0));
        let phi0 = field(0.0, 1.0);
        let d_cda: Vec<f64> = sig.iter().map(|s| 1.0 / (3.0 * s)).collect();
        let b = LocalBox {
            lo: [3, 2, 5],
            hi: [17, 15, 14],
        };
        for limiter in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
            let config = FldConfig::fld(limiter);
            let f = Fields {
                grid: &g,
                rhs: &rhs,
                sig: &sig,
                absorb: &absorb,
                d_fixed: (limiter == FluxLimiter::Cda).then_some(&d_cda[..]),
                config: &config,
                floor: 1e-300,
                omega: 1.2,
            };
            let (mut rows, mut voxels) = (phi0.clone(), phi0.clone());
            relax(&f, &b, &mut rows, 3);
            relax_per_voxel(&f, &b, &mut voxels, 3);
            let changed = rows.iter().zip(&phi0).filter(|(a, b)| a != b).count();
            assert!(changed > b.len() / 2, "{limiter:?}: {changed} voxels moved");
            for (p, (x, y)) in rows.iter().zip(&voxels).enumerate() {
                assert_eq!(x.to_bits(), y.to_bits(), "{limiter:?} at {:?}", g.coords(p));
            }
        }
    }
}
