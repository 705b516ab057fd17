//! POP's angular radiance at probes (Fig 12's polar plots; spec §3 Fig 12 (a)): the
//! radiance a cell holds is L(ω) = Σ_m L^m f_hg(ω·d, a^m) (the lobe of every iteration,
//! not the phase-convolved view lobe of Eq 8), azimuthally symmetric about d. Averaged over a
//! band μ ∈ [μ₀, μ₁) of μ = ω·d and its azimuth it is
//! Σ_m L^m (G(μ₁, a^m) − G(μ₀, a^m))/(2π(μ₁ − μ₀)) with G = 2πF_hg the closed form of
//! [`super::cumulative`], the same band average the path tracer's angular tally
//! (`reference::pathtracer::angular`) estimates; summed over bands with their solid angles
//! it is φ = Σ_m L^m (`probe_bands_sum_to_the_fluence`).

use super::kernel::cumulative;
use super::{Ordinate, PopConfig, PopMedium};
use crate::{Real, SolverError};
use std::f64::consts::PI;

/// Band-averaged radiance `[probe][band]` of one ordinate, averaged over each probe's cells
/// (the cells containing the world points of the probe; a cell named twice counts twice),
/// for the bands between consecutive `edges` (increasing, within [−1, 1]), run to
/// `config`'s stop. Typed errors for bad edges, an empty probe or a point outside the
/// ordinate's grid.
pub fn angular<T: Real>(
    medium: &PopMedium,
    ordinate: &Ordinate,
    config: &PopConfig,
    probes: &[Vec<[f64; 3]>],
    edges: &[f64],
) -> Result<Vec<Vec<f64>>, SolverError> {
    super::validate_solve::<T>(medium, std::slice::from_ref(ordinate), config)?;
    if edges.len() < 2
        || edges
            .windows(2)
            .any(|w| w[0] >= w[1] || w[0].is_nan() || w[1].is_nan())
        || edges[0] < -1.0
        || edges[edges.len() - 1] > 1.0
    {
        return Err(SolverError::BadParameter {
            name: "edges",
            value: edges.len() as f64,
            reason: "at least two increasing band edges within [−1, 1]",
        });
    }
    let (grid, mut pop) = super::prepare::<T>(medium, ordinate, config);
    let mut cells = Vec::with_capacity(probes.len());
    for points in probes {
        if points.is_empty() {
            return Err(SolverError::BadParameter {
                name: "probes",
                value: 0.0,
                reason: "a probe needs at least one point",
            });
        }
        let mut c = Vec::with_capacity(points.len());
        for &p in points {
            let u = grid.local(p);
            if u.iter().any(|&x| !(0.0..grid.n as f64).contains(&x)) {
                return Err(SolverError::BadParameter {
                    name: "probes",
                    value: u[0],
                    reason: "a probe point lies outside the ordinate's grid",
                });
            }
            let [i, j, k] = u.map(|x| x as usize);
            c.push(i + grid.n * (j + grid.n * k));
        }
        cells.push(c);
    }
    let bands = edges.len() - 1;
    let mut out = vec![vec![0.0; bands]; probes.len()];
    let accumulate = |pop: &super::CpuPop<T>, out: &mut Vec<Vec<f64>>| {
        for (p, cs) in cells.iter().enumerate() {
            let w = 1.0 / cs.len() as f64;
            for &c in cs {
                let (l, a) = pop.cell(c, 0);
                let (l, a) = (l.f(), a.f().clamp(0.0, 1.0));
                if l == 0.0 {
                    continue;
                }
                for (b, e) in edges.windows(2).enumerate() {
                    let g = cumulative(e[1], a) - cumulative(e[0], a);
                    out[p][b] += w * l * g / (2.0 * PI * (e[1] - e[0]));
                }
            }
        }
    };
    accumulate(&pop, &mut out);
    loop {
        if let Some(&r) = pop.history().last()
            && (!r.is_finite() || r < config.tolerance || r == 0.0)
        {
            break;
        }
        if pop.steps() >= config.max_iterations {
            break;
        }
        pop.step();
        accumulate(&pop, &mut out);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Grid;

    /// Σ_bands L̄ 2πΔμ = the probe-mean φ of the solve (same run), and the stop matches.
    #[test]
    fn probe_bands_sum_to_the_fluence() {
        let grid = Grid::cube(8, 1.0).unwrap();
        let m = PopMedium::homogeneous(grid, 4.0, 0.2, 0.7).unwrap();
        let o = Ordinate::directional([1.0, 0.0, 0.0], 1.0).unwrap();
        let config = PopConfig::new::<f64>(8);
        let probes: Vec<Vec<[f64; 3]>> = [1, 6]
            .iter()
            .map(|&i| vec![grid.center(i, 3, 4), grid.center(i, 4, 4)])
            .collect();
        let edges: Vec<f64> = (0..=10).map(|k| -1.0 + 0.2 * k as f64).collect();
        let bands = angular::<f64>(&m, &o, &config, &probes, &edges).unwrap();
        let sol = super::super::solve::<f64>(&m, &[o], &config).unwrap();
        for (p, pts) in probes.iter().enumerate() {
            let sum: f64 = bands[p].iter().map(|v| v * 2.0 * PI * 0.2).sum();
            let phi: f64 = pts
                .iter()
                .map(|&x| sol.runs[0].fluence_at(0, x))
                .sum::<f64>()
                / pts.len() as f64;
            assert!((sum / phi - 1.0).abs() < 1e-12, "probe {p}: {sum} vs {phi}");
        }
        let bad = angular::<f64>(&m, &o, &config, &probes, &[0.5, 0.2]);
        assert!(matches!(bad, Err(SolverError::BadParameter { .. })));
        let outside = angular::<f64>(&m, &o, &config, &[vec![[5.0, 0.5, 0.5]]], &edges);
        assert!(matches!(outside, Err(SolverError::BadParameter { .. })));
    }
}
