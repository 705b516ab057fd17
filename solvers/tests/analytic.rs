//! Analytic agreement of the diffusion solver (issue "Diffusion core", acceptance 1, 2, 4, 5).

// Test helpers unwrap: a failed setup should fail the test loudly.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::point_source::{PointSource, Solution};
use solvers::fld::{Boundary, CpuFld, FldConfig, FluxLimiter};
use solvers::{Grid, Medium, Real, scenes};

const FIG5_ALBEDOS: [f64; 6] = [0.1, 0.3, 0.5, 0.7, 0.9, 0.99];

/// Distance of each voxel centre from the source voxel's centre.
fn distance(grid: &Grid, src: [usize; 3], idx: usize) -> f64 {
    let [i, j, k] = grid.coords(idx);
    let d = [
        i as f64 - src[0] as f64,
        j as f64 - src[1] as f64,
        k as f64 - src[2] as f64,
    ];
    grid.dl * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Acceptance 1 (FLD Fig 5a): CDA with Dirichlet values from FLD Eq 27 reproduces Eq 27,
/// 63³, τ = 4 across, α ∈ {0.1, 0.5, 0.9}.
///
/// What holds, and what cannot: the 7-point stencil's truncation error on a 1/r field is
/// anisotropic, ≈ +0.36 (Δl/r)² along the axes and negative along the diagonals, whatever
/// the source representation (measured: +2.4 % at 4 voxels on the axis, −0.8 % at 5.2 voxels
/// on the diagonal, the same in voxel units at 63³ and 127³). So "every voxel within 1 %
/// beyond 3 voxels" is out of reach of the paper's discretisation. This test asserts
/// (a) spherical-shell averages, where the cubic anisotropy averages out, within 1 % of
///     Eq 27 beyond 3 voxels;
/// (b) every single voxel within 1 % beyond 8 voxels;
/// (c) the axis error decays like r⁻² (a discretisation error, not a solver error): the
///     error at 4 voxels is between 2× and 8× the error at 8 voxels.
#[test]
fn cda_with_analytic_boundary_reproduces_eq_27() {
    let n = 63;
    for albedo in [0.1, 0.5, 0.9] {
        let (medium, src) = scenes::point_source::<f64>(n, 4.0, albedo).unwrap();
        let g = medium.grid;
        let ps = PointSource::new(4.0, albedo).unwrap();
        let c = g.center(src[0], src[1], src[2]);
        let exact = |p: [f64; 3]| {
            let r = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
            ps.fluence(Solution::Cda, r)
        };
        let cfg = FldConfig::cda()
            .with_omega(FldConfig::poisson_optimal_omega(n))
            .with_tolerance(1e-9);
        let sol = CpuFld::new(&medium, &Boundary::from_fn(&g, exact), &cfg)
            .unwrap()
            .solve();
        assert!(sol.converged(), "α={albedo}: {:?}", sol.stop);
        let mut shells = vec![(0.0, 0.0); n];
        let mut worst_far = 0.0f64;
        for idx in 0..g.len() {
            let r = distance(&g, src, idx) / g.dl;
            let [i, j, k] = g.coords(idx);
            let (num, ana) = (sol.phi[idx], exact(g.center(i, j, k)));
            if r > 0.0 {
                let b = r.floor() as usize;
                shells[b].0 += num;
                shells[b].1 += ana;
            }
            if r > 8.0 && !g.is_boundary(i, j, k) {
                worst_far = worst_far.max((num / ana - 1.0).abs());
            }
        }
        let worst_shell = (3..n / 2)
            .map(|b| (shells[b].0 / shells[b].1 - 1.0).abs())
            .fold(0.0, f64::max);
        let axis = |d: usize| {
            (sol.phi[g.index(src[0] + d, src[1], src[2])]
                / exact(g.center(src[0] + d, src[1], src[2]))
                - 1.0)
                .abs()
        };
        let ratio = axis(4) / axis(8);
        println!(
            "α={albedo}: shells ≥ 3 voxels max |rel err| {worst_shell:.5}; voxels > 8: {worst_far:.5}; axis error 4 vs 8 voxels ratio {ratio:.2}; {} iterations",
            sol.steps
        );
        assert!(
            worst_shell < 0.01,
            "α={albedo}: shell-averaged error {worst_shell}"
        );
        assert!(
            worst_far < 0.01,
            "α={albedo}: per-voxel error beyond 8 voxels {worst_far}"
        );
        assert!(
            (2.0..8.0).contains(&ratio),
            "α={albedo}: axis error ratio {ratio} is not ~4 (r⁻²)"
        );
    }
}

/// Acceptance 2: a manufactured solution with variable D = 1/(3σt) and variable σa shows
/// second-order convergence. φ = sin(πx) sin(πy) sin(πz) on the unit cube, σt and α smooth,
/// j = −∇·(D∇φ) + σa φ in closed form, Dirichlet values = φ at the boundary-layer centres.
#[test]
fn manufactured_solution_converges_at_second_order() {
    use std::f64::consts::PI;
    let phi = |p: [f64; 3]| 2.0 + (PI * p[0]).sin() * (PI * p[1]).sin() * (PI * p[2]).sin();
    let sigma = |p: [f64; 3]| 2.0 + (2.0 * p[0] + p[1]).sin() * 0.3 + 0.2 * p[2];
    let dsigma = |p: [f64; 3]| {
        [
            0.6 * (2.0 * p[0] + p[1]).cos(),
            0.3 * (2.0 * p[0] + p[1]).cos(),
            0.2,
        ]
    };
    let albedo = |p: [f64; 3]| 0.5 + 0.2 * (3.0 * p[1]).cos() * p[0];
    let source = |p: [f64; 3]| {
        let s = sigma(p);
        let d = 1.0 / (3.0 * s);
        let ds = dsigma(p);
        let grad_d = ds.map(|g| -g / (3.0 * s * s));
        let (sx, sy, sz) = ((PI * p[0]).sin(), (PI * p[1]).sin(), (PI * p[2]).sin());
        let (cx, cy, cz) = ((PI * p[0]).cos(), (PI * p[1]).cos(), (PI * p[2]).cos());
        let grad_phi = [PI * cx * sy * sz, PI * sx * cy * sz, PI * sx * sy * cz];
        let lap = -3.0 * PI * PI * sx * sy * sz;
        let div =
            d * lap + grad_d[0] * grad_phi[0] + grad_d[1] * grad_phi[1] + grad_d[2] * grad_phi[2];
        (1.0 - albedo(p)) * s * phi(p) - div
    };
    let mut errors = Vec::new();
    for n in [16, 32, 64, 128] {
        let g = Grid::cube(n, 1.0).unwrap();
        let medium = Medium::new(g, g.sample(sigma), g.sample(albedo), g.sample(source)).unwrap();
        let cfg = FldConfig::cda()
            .with_omega(FldConfig::poisson_optimal_omega(n))
            .with_tolerance(1e-11)
            .with_max_iterations(50_000);
        let sol = CpuFld::new(&medium, &Boundary::from_fn(&g, phi), &cfg)
            .unwrap()
            .solve();
        assert!(sol.converged(), "n={n}");
        let exact = g.sample(phi);
        let l2 = (sol
            .phi
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / exact.iter().map(|b| b * b).sum::<f64>())
        .sqrt();
        errors.push((n, l2));
    }
    for w in errors.windows(2) {
        let order = (w[0].1 / w[1].1).log2();
        println!(
            "n {} → {}: relative L2 error {:.3e} → {:.3e}, order {order:.3}",
            w[0].0, w[1].0, w[0].1, w[1].1
        );
        assert!(
            order >= 1.9,
            "observed order {order} between n = {} and {}",
            w[0].0,
            w[1].0
        );
    }
}

/// Relative L2 error against Grosjean over voxels with 0 < τ < 1 (source voxel excluded).
fn near_source_error<T: Real>(n: usize, albedo: f64, limiter: FluxLimiter) -> f64 {
    let (medium, src) = scenes::point_source::<T>(n, 4.0, albedo).unwrap();
    let g = medium.grid;
    let ps = PointSource::new(4.0, albedo).unwrap();
    let cfg = FldConfig::fld(limiter).with_omega(FldConfig::poisson_optimal_omega(n));
    let sol = CpuFld::new(&medium, &Boundary::Zero, &cfg).unwrap().solve();
    assert!(sol.converged(), "{limiter} α={albedo}: {:?}", sol.stop);
    let (mut num, mut den) = (0.0, 0.0);
    for idx in 0..g.len() {
        let r = distance(&g, src, idx);
        let tau = 4.0 * r;
        if r > 0.0 && tau < 1.0 {
            let exact = ps.fluence(Solution::Grosjean, r);
            num += (sol.phi[idx].f() - exact).powi(2);
            den += exact * exact;
        }
    }
    (num / den).sqrt()
}

/// Acceptance 4: FLD-LP is closer to Grosjean than CDA near the source (τ < 1) at every
/// albedo of FLD Fig 5, zero Dirichlet boundary, 63³ (the figure itself uses 127³).
#[test]
fn fld_lp_beats_cda_near_the_source() {
    for albedo in FIG5_ALBEDOS {
        let e_cda = near_source_error::<f64>(63, albedo, FluxLimiter::Cda);
        let e_lp = near_source_error::<f64>(63, albedo, FluxLimiter::LevermorePomraning);
        println!("α={albedo}: relative L2 error for τ < 1: CDA {e_cda:.4}, FLD-LP {e_lp:.4}");
        assert!(
            e_lp < e_cda,
            "α={albedo}: FLD-LP {e_lp} is not below CDA {e_cda}"
        );
    }
}

/// Acceptance 5: on the Fig 4 case (51³ cloud in vacuum, f64) the solver converges to
/// R̄/j̄ < 10⁻⁶ for SOR factors 1.0 … 1.9, and in f32 to 10⁻⁴ with no NaN, Inf or negative φ.
#[test]
fn fig4_case_converges_for_sor_1_to_1_9() {
    let medium = scenes::vacuum_cloud::<f64>(51, 1).unwrap();
    let medium32 = medium.cast::<f32>();
    for omega in [1.0, 1.3, 1.6, 1.9] {
        let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning)
            .with_omega(omega)
            .with_max_iterations(20_000);
        let sol = CpuFld::new(&medium, &Boundary::Zero, &cfg).unwrap().solve();
        println!("ω={omega}: f64 {} iterations, {:?}", sol.steps, sol.stop);
        assert!(
            sol.converged(),
            "ω={omega}: {:?} after {} iterations, R̄/j̄ = {}",
            sol.stop,
            sol.steps,
            sol.final_residual()
        );
        let sol32 = CpuFld::new(&medium32, &Boundary::Zero, &cfg)
            .unwrap()
            .solve();
        assert!(sol32.converged(), "f32 ω={omega}: {:?}", sol32.stop);
        assert!(sol32.phi.iter().all(|x| x.is_finite() && *x >= 0.0));
        // f32 and f64 agree where φ is not negligible.
        let max = sol.phi.iter().fold(0.0f64, |a, &b| a.max(b));
        let worst = sol
            .phi
            .iter()
            .zip(&sol32.phi)
            .filter(|(a, _)| **a > 1e-3 * max)
            .map(|(a, b)| (*b as f64 / a - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 2e-2,
            "ω={omega}: f32 vs f64 max relative difference {worst}"
        );
    }
}
