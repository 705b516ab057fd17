//! Restriction of the medium and the diffusion source to a coarser grid (FLD Section 6.2:
//! "we solved for φ(x) on grids with a quarter of their original resolution").
//!
//! A coarse voxel covers k³ fine voxels (k = the downsampling factor). Where the fine grid
//! is not a multiple of k, the last coarse voxel along an axis sticks out of the medium's
//! box; the missing children count as vacuum (σt = 0, no source). With V = Δl³ the fine
//! voxel volume and k³V the coarse one:
//! * σt_c = Σ σt / k³ (the mean over the coarse voxel, vacuum children included): the
//!   total extinction ∫σt dV — and so the optical depth along a ray averaged over the
//!   coarse voxel — is conserved;
//! * α_c = Σ σs / Σ σt (0 where Σ σt = 0), so σs_c = α_c σt_c = Σ σs / k³: scattering and
//!   absorption, ∫σs dV and ∫σa dV, are conserved separately;
//! * q_c = Σ q / k³: the source power ∫q dV is conserved.
//!
//! Then `pad` layers of vacuum are added around the coarse grid, so that the Dirichlet
//! layer of the solve (φ = 0 on the outermost voxels, FLD Section 5) lies outside the
//! medium and every medium voxel is solved for. k = 1 only pads.

use crate::{Grid, Medium, SolverError};

/// The coarse grid of a fine grid restricted by `k` and padded by `pad` voxels.
pub fn coarse_grid(fine: &Grid, k: usize, pad: usize) -> Result<Grid, SolverError> {
    if k == 0 {
        return Err(SolverError::BadParameter {
            name: "downsample",
            value: 0.0,
            reason: "the downsampling factor must be at least 1",
        });
    }
    let dl = fine.dl * k as f64;
    let n = fine.n.map(|n| n.div_ceil(k) + 2 * pad);
    let origin = fine.origin.map(|o| o - pad as f64 * dl);
    Grid::with_origin(n, dl, origin)
}

/// Restricts σt, albedo and the source `q` (per fine voxel) to the coarse grid (see the
/// module docs); the returned medium carries the restricted source as its `emission`.
pub fn restrict(
    fine: &Medium<f64>,
    q: &[f64],
    k: usize,
    pad: usize,
) -> Result<Medium<f64>, SolverError> {
    if q.len() != fine.grid.len() {
        return Err(SolverError::FieldSize {
            field: "source",
            expected: fine.grid.len(),
            got: q.len(),
        });
    }
    let g = fine.grid;
    let cg = coarse_grid(&g, k, pad)?;
    let n = cg.len();
    let mut st = vec![0.0; n];
    let mut ss = vec![0.0; n];
    let mut qc = vec![0.0; n];
    for kz in 0..g.n[2] {
        for jy in 0..g.n[1] {
            for ix in 0..g.n[0] {
                let f = g.index(ix, jy, kz);
                let c = cg.index(ix / k + pad, jy / k + pad, kz / k + pad);
                st[c] += fine.sigma_t[f];
                ss[c] += fine.sigma_t[f] * fine.albedo[f];
                qc[c] += q[f];
            }
        }
    }
    let inv = 1.0 / (k * k * k) as f64;
    let albedo = st
        .iter()
        .zip(&ss)
        .map(|(&t, &s)| {
            if t > 0.0 {
                (s / t).clamp(0.0, 1.0)
            } else {
                0.0
            }
        })
        .collect();
    st.iter_mut().for_each(|v| *v *= inv);
    qc.iter_mut().for_each(|v| *v *= inv);
    Medium::new(cg, st, albedo, qc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::SplitMix64;

    #[test]
    fn restriction_conserves_extinction_scattering_and_source() {
        // 10 = 2·4 + 2: the last coarse voxel is half outside the medium.
        let g = Grid::with_origin([10, 7, 5], 0.1, [0.3, -0.2, 1.0]).unwrap();
        let mut rng = SplitMix64::new(5);
        let n = g.len();
        let st: Vec<f64> = (0..n)
            .map(|_| {
                let u = rng.next_f64();
                if u < 0.3 { 0.0 } else { 10.0 * u }
            })
            .collect();
        let al: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
        let q: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
        let m = Medium::new(g, st, al, vec![0.0; n]).unwrap();
        for (k, pad) in [(1, 0), (1, 1), (2, 1), (4, 1), (4, 2), (2, 0)] {
            let c = restrict(&m, &q, k, pad).unwrap();
            let vf = g.dl.powi(3);
            let vc = c.grid.dl.powi(3);
            let tot = |m: &Medium<f64>, v: f64, f: &dyn Fn(usize) -> f64| {
                (0..m.grid.len()).map(f).sum::<f64>() * v
            };
            let pairs = [
                (
                    tot(&m, vf, &|i| m.sigma_t[i]),
                    tot(&c, vc, &|i| c.sigma_t[i]),
                ),
                (
                    tot(&m, vf, &|i| m.sigma_t[i] * m.albedo[i]),
                    tot(&c, vc, &|i| c.sigma_t[i] * c.albedo[i]),
                ),
                (tot(&m, vf, &|i| q[i]), tot(&c, vc, &|i| c.emission[i])),
            ];
            for (a, b) in pairs {
                assert!(
                    (a - b).abs() <= 1e-12 * a.abs(),
                    "k={k} pad={pad}: {a} vs {b}"
                );
            }
            // The coarse box contains the fine one, aligned at the lower corner + padding.
            for ax in 0..3 {
                let lo = c.grid.origin[ax] + pad as f64 * c.grid.dl;
                assert!((lo - g.origin[ax]).abs() < 1e-12);
                assert!(
                    c.grid.origin[ax] + c.grid.size()[ax] >= g.origin[ax] + g.size()[ax] - 1e-12
                );
            }
            // Padding is vacuum.
            if pad > 0 {
                assert_eq!(c.sigma_t[0], 0.0);
                assert_eq!(c.emission[0], 0.0);
            }
        }
        assert!(restrict(&m, &q, 0, 1).is_err());
        assert!(restrict(&m, &q[1..], 2, 1).is_err());
    }
}
