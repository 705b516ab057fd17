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
use crate::fld::FldConfig;
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
    let mut upd = vec![0.0; b.len()];
    let dl2 = g.dl * g.dl;
    for _ in 0..sweeps {
        for colour in 0..2 {
            if f.d_fixed.is_none() {
                fill_d(f, &e, ew, phi, &mut dloc);
            }
            let dat = |i: usize, j: usize, k: usize| match f.d_fixed {
                Some(d) => d[g.index(i, j, k)],
                None => dloc[((k - e.lo[2]) * ew[1] + (j - e.lo[1])) * ew[0] + (i - e.lo[0])],
            };
            let phi_r: &[f64] = phi;
            upd.par_chunks_mut(bw[0] * bw[1])
                .enumerate()
                .for_each(|(kk, slab)| {
                    for_colour(b, kk, colour, |j, i, at| {
                        let k = b.lo[2] + kk;
                        let n = g.index(i, j, k);
                        let dp = dat(i, j, k);
                        let nb = [
                            (n - 1, dat(i - 1, j, k)),
                            (n + 1, dat(i + 1, j, k)),
                            (n - nx, dat(i, j - 1, k)),
                            (n + nx, dat(i, j + 1, k)),
                            (n - plane, dat(i, j, k - 1)),
                            (n + plane, dat(i, j, k + 1)),
                        ];
                        let (mut num, mut den) = (0.0, f.absorb[n]);
                        for (q, dq) in nb {
                            let c = 0.5 * (dp + dq);
                            num += c * phi_r[q];
                            den += c;
                        }
                        let new = (f.rhs[n] * dl2 + num) / den;
                        let x = (1.0 - f.omega) * phi_r[n] + f.omega * new;
                        slab[at] = x.max(0.0);
                    });
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
/// differences, as the multigrid's residual evaluates it inside.
fn fill_d(f: &Fields<'_>, e: &LocalBox, ew: [usize; 3], phi: &[f64], out: &mut [f64]) {
    let g = f.grid;
    let [nx, ny, _] = g.n;
    let plane = nx * ny;
    let inv_2dl = 0.5 / g.dl;
    let floor = f.floor;
    let limiter = f.config.limiter;
    out.par_chunks_mut(ew[0] * ew[1])
        .enumerate()
        .for_each(|(kk, slab)| {
            let k = e.lo[2] + kk;
            for jj in 0..ew[1] {
                let j = e.lo[1] + jj;
                for ii in 0..ew[0] {
                    let n = g.index(e.lo[0] + ii, j, k);
                    let s = f.sig[n];
                    let gx = (phi[n + 1] - phi[n - 1]) * inv_2dl;
                    let gy = (phi[n + nx] - phi[n - nx]) * inv_2dl;
                    let gz = (phi[n + plane] - phi[n - plane]) * inv_2dl;
                    let r =
                        (gx * gx + gy * gy + gz * gz).sqrt().max(floor) / (s * phi[n]).max(floor);
                    let (num, den) = limiter.fraction(r);
                    slab[jj * ew[0] + ii] = num / (den * s);
                }
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
}
