//! Tests of the RDE (spec `../shared/specs/rde.md` §5; ids A1–E21 in the names). Every
//! CPU test body runs in f32 and f64 (`both!`); the GPU tests (E19–E21) run on the first
//! adapter and skip with one line without one.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::needless_range_loop)]

use super::cpu::naive;
use super::*;
use crate::fld::{self, FldConfig};
use crate::noise::SplitMix64;

/// Stamps `cpu_f32` and `cpu_f64` tests of a body `fn(Precision)`.
macro_rules! both {
    ($($case:ident),* $(,)?) => {$(
        mod $case {
            #[test]
            fn cpu_f32() {
                super::$case(crate::Precision::F32);
            }
            #[test]
            fn cpu_f64() {
                super::$case(crate::Precision::F64);
            }
        }
    )*};
}

fn run(p: Precision, coef: &Coefficients, cfg: &RdeConfig) -> RdeSolution<f64> {
    solve(&Backend::Cpu(p), coef, cfg, |_, _| {}).unwrap()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// max|a − b| / max|b|.
fn rel_max(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / max_abs(b)
}

/// ‖a − b‖₂ / ‖b‖₂.
fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let n: f64 = b.iter().map(|y| y * y).sum();
    (d / n).sqrt()
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Random β ∈ U[lo, 1], a ∈ U[0, amax], sparse sources.
fn random_coef(n: [usize; 3], seed: u64, lo: f64, amax: f64) -> Coefficients {
    let grid = Grid::new(n, 1.0).unwrap();
    let mut rng = SplitMix64::new(seed);
    let len = grid.len();
    let beta = (0..len).map(|_| lo + (1.0 - lo) * rng.next_f64()).collect();
    let ka = (0..len).map(|_| amax * rng.next_f64()).collect();
    let src = (0..len)
        .map(|_| {
            if rng.next_f64() < 0.1 {
                rng.next_f64()
            } else {
                0.0
            }
        })
        .collect();
    Coefficients::from_maps(grid, beta, ka, src).unwrap()
}

/// A homogeneous medium of β = 1/(3σt∆) on a ∆ = 1 cube of n³ voxels with a unit source in
/// the centre voxel, as a `Medium` (for CDA) and its coefficients.
fn homogeneous(n: usize, beta: f64, albedo: f64) -> (Medium<f64>, Coefficients) {
    let grid = Grid::new([n; 3], 1.0).unwrap();
    let mut m = Medium::homogeneous(grid, 1.0 / (3.0 * beta), albedo).unwrap();
    m.emission[grid.index(n / 2, n / 2, n / 2)] = 1.0;
    let c = Coefficients::from_medium(&m, 0.0).unwrap();
    (m, c)
}

/// CDA (FLD Algorithm 1 with F = 1/3) to R̄/j̄ < 10⁻¹¹ in f64.
fn cda(m: &Medium<f64>) -> Vec<f64> {
    let n = m.grid.n[0];
    let cfg = FldConfig::cda()
        .with_omega(FldConfig::poisson_optimal_omega(n))
        .with_tolerance(1e-11)
        .with_max_iterations(200_000);
    let s = fld::solve(
        &Backend::Cpu(Precision::F64),
        m,
        &fld::Boundary::Zero,
        &cfg,
        |_, _| {},
    )
    .unwrap();
    assert!(s.converged());
    s.phi
}

fn tight(p: Precision) -> f64 {
    match p {
        Precision::F64 => 1e-11,
        Precision::F32 => 1e-5,
    }
}

// ---------------------------------------------------------------------------------------
// The kernel against the plain update, and determinism.

#[test]
fn kernel_matches_the_plain_update_for_every_operator_boundary_and_step() {
    for dims in [[9, 8, 7], [5, 6, 5]] {
        let coef = random_coef(dims, 7, 0.01, 0.5).with_initial(
            (0..dims.iter().product::<usize>())
                .map(|i| (i % 5) as f64 * 0.1)
                .collect(),
        );
        for op in Operator::ALL {
            for bc in [BoundaryCondition::Dirichlet, BoundaryCondition::Neumann] {
                for ts in [TimeStep::default(), TimeStep::Local { safety: 0.8 }] {
                    let cfg = RdeConfig::default()
                        .with_operator(op)
                        .with_boundary(bc)
                        .with_time_step(ts);
                    let mut k = CpuRde::<f64>::new(&coef, &cfg).unwrap();
                    let step = resolve_step(&coef, &cfg, &coef.bounds(bc)).unwrap();
                    let r = |idx: usize| match &step {
                        ResolvedStep::Global(r) => *r,
                        ResolvedStep::Local(v) => v[idx],
                    };
                    let mut phi = coef.initial.clone().unwrap();
                    for _ in 0..6 {
                        k.step(false);
                        phi = naive::step(&coef, op, bc, &r, &phi);
                    }
                    let got = k.phi();
                    let e = rel_max(&got, &phi);
                    assert!(e < 1e-13, "{op:?} {bc:?} {ts:?} {dims:?}: {e:.3e}");
                    let mut k32 = CpuRde::<f32>::new(&coef, &cfg).unwrap();
                    for _ in 0..6 {
                        k32.step(false);
                    }
                    let got32: Vec<f64> = k32.phi().iter().map(|x| f64::from(*x)).collect();
                    let e = rel_max(&got32, &phi);
                    assert!(e < 1e-5, "f32 {op:?} {bc:?} {ts:?}: {e:.3e}");
                }
            }
        }
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let coef = random_coef([23, 19, 21], 3, 0.01, 0.3);
    let cfg = RdeConfig::default().steady(0.0, 50);
    let on = |threads: usize| {
        crate::test_util::with_threads(threads, || CpuRde::<f32>::new(&coef, &cfg).unwrap().run())
    };
    let (a, b) = (on(1), on(3));
    assert_eq!(a.phi, b.phi);
    assert_eq!(a.trace.residuals, b.trace.residuals);
}

// ---------------------------------------------------------------------------------------
// A. Steady state equals CDA.

/// A1: homogeneous β = 0.5, α ∈ {0.9, 0.99}, 33³, one-voxel source, zero Dirichlet layer:
/// every operator's steady state equals CDA's (the same discrete system). f64: ≤ 10⁻⁶ of max φ
/// (stopped at R̄/j̄ < 10⁻¹¹); f32 (stopped at 10⁻⁵): ≤ 10⁻³.
fn a1_homogeneous_steady_state_equals_cda(p: Precision) {
    for albedo in [0.9, 0.99] {
        let (m, coef) = homogeneous(33, 0.5, albedo);
        let reference = cda(&m);
        for op in Operator::ALL {
            let cfg = RdeConfig::default()
                .with_operator(op)
                .steady(tight(p), 100_000);
            let s = run(p, &coef, &cfg);
            assert!(s.converged(), "{op:?} α={albedo}: {:?}", s.stop);
            let e = rel_max(&s.phi, &reference);
            let bound = if p == Precision::F64 { 1e-6 } else { 1e-3 };
            eprintln!(
                "A1 {p:?} {op:?} α={albedo}: {} steps, max|Δφ|/max φ = {e:.2e}",
                s.steps
            );
            assert!(e <= bound, "{op:?} α={albedo}: {e:.3e} > {bound:e}");
        }
    }
}

/// A smooth bump β(x) = β0 + (β1 − β0) exp(−|x − c|²/w²) of physical width w on a cube of
/// edge L with n voxels, physical D = β∆ held fixed when n changes; albedo α through
/// a = (1 − α)/(3β) (g = 0); Gaussian source of physical width L/8.
fn bump(n: usize, d0: f64, d1: f64, w: f64, albedo: f64) -> (Medium<f64>, Coefficients) {
    let l = 1.0;
    let grid = Grid::cube(n, l).unwrap();
    let c = 0.5 * l;
    let d = grid.sample(|p| {
        let r2 = (0..3).map(|a| (p[a] - c).powi(2)).sum::<f64>();
        d0 + (d1 - d0) * (-r2 / (w * w)).exp()
    });
    let q = grid.sample(|p| {
        let r2 = (0..3).map(|a| (p[a] - 0.4 * l).powi(2)).sum::<f64>();
        (-r2 / (l / 8.0).powi(2)).exp()
    });
    let sigma_t: Vec<f64> = d.iter().map(|d| 1.0 / (3.0 * d)).collect();
    let m = Medium::new(grid, sigma_t, vec![albedo; grid.len()], q).unwrap();
    let coef = Coefficients::from_medium(&m, 0.0).unwrap();
    assert_eq!(coef.beta_capped, 0);
    (m, coef)
}

/// A2: smooth heterogeneity (β 0.5 → 0.9 over a bump of ≈ 8 voxels): `Conservative` equals
/// CDA (≤ 10⁻⁶ f64); `ThesisExpanded` differs from CDA by ≤ 1 % (relative L2), and at fixed
/// physical D the difference falls ≥ 3.5× per halving of ∆ (second order).
fn a2_smooth_heterogeneity(p: Precision) {
    let albedo = 0.9;
    // n = 25: ∆ = 1/25, D = β∆ with β 0.5 → 0.9; w = 8 voxels.
    let (n0, w) = (25, 8.0 / 25.0);
    let dl0 = 1.0 / n0 as f64;
    let (m, coef) = bump(n0, 0.5 * dl0, 0.9 * dl0, w, albedo);
    let reference = cda(&m);
    let cons = run(p, &coef, &RdeConfig::default().steady(tight(p), 100_000));
    let e = rel_max(&cons.phi, &reference);
    let bound = if p == Precision::F64 { 1e-6 } else { 1e-3 };
    eprintln!("A2 {p:?} conservative vs CDA: {e:.2e}");
    assert!(e <= bound, "conservative vs CDA {e:.3e}");
    let exp_cfg = RdeConfig::default()
        .with_operator(Operator::ThesisExpanded)
        .steady(tight(p), 100_000);
    let exp = run(p, &coef, &exp_cfg);
    let d0 = rel_l2(&exp.phi, &reference);
    eprintln!("A2 {p:?} expanded vs CDA at n = {n0}: {d0:.3e}");
    assert!(d0 <= 1e-2 && d0 > 1e-5, "expanded vs CDA {d0:.3e}");
    if p == Precision::F32 {
        return; // the convergence order needs differences below f32's steady-state noise
    }
    // Halving ∆ at fixed physical D: β doubles (0.26 → 0.47 at n = 13, 0.52 → 0.94 at 26).
    let diff = |n: usize| {
        let (_, c) = bump(n, 0.5 * dl0, 0.9 * dl0, w, albedo);
        let cons = run(p, &c, &RdeConfig::default().steady(1e-11, 200_000));
        let exp = run(p, &c, &exp_cfg);
        rel_l2(&exp.phi, &cons.phi)
    };
    let (dc, df) = (diff(13), diff(26));
    eprintln!(
        "A2 expanded − conservative: {dc:.3e} (n = 13), {df:.3e} (n = 26), ratio {:.2}",
        dc / df
    );
    assert!(dc / df >= 3.5, "ratio {:.2} < 3.5", dc / df);
}

/// A3: sharp step β 0.1 | 0.9 (α = 0.99): `Conservative` stays ≥ 0 and equals CDA;
/// `ThesisExpanded` reports the voxels where its neighbour weights are negative.
fn a3_sharp_step(p: Precision) {
    let n = 21;
    let grid = Grid::new([n; 3], 1.0).unwrap();
    let beta = |i: usize| if i < n / 2 { 0.1 } else { 0.9 };
    let sigma_t: Vec<f64> = (0..grid.len())
        .map(|idx| 1.0 / (3.0 * beta(grid.coords(idx)[0])))
        .collect();
    let mut q = vec![0.0; grid.len()];
    q[grid.index(n / 2 - 2, n / 2, n / 2)] = 1.0;
    let m = Medium::new(grid, sigma_t, vec![0.99; grid.len()], q).unwrap();
    let coef = Coefficients::from_medium(&m, 0.0).unwrap();
    let reference = cda(&m);
    let cons = run(p, &coef, &RdeConfig::default().steady(tight(p), 200_000));
    assert!(cons.trace.min_phi >= 0.0, "min φ {}", cons.trace.min_phi);
    assert_eq!(cons.trace.expanded_violations, 0);
    let e = rel_max(&cons.phi, &reference);
    let bound = if p == Precision::F64 { 1e-6 } else { 1e-3 };
    eprintln!("A3 {p:?} conservative vs CDA: {e:.2e}");
    assert!(e <= bound, "{e:.3e}");
    let exp = CpuRde::<f64>::new(
        &coef,
        &RdeConfig::default().with_operator(Operator::ThesisExpanded),
    )
    .unwrap();
    // The step is one voxel wide: |β₊ − β₋| = 0.8 > 4 β_p = 0.4 on the 0.1 side.
    assert_eq!(
        exp.trace().expanded_violations,
        (n - 2) * (n - 2),
        "one plane"
    );
}

/// A4: the steady state does not depend on r: r = 0.9 r_G and r/2 agree to ≤ 10⁻⁸ (f64) of
/// max φ in a heterogeneous medium.
fn a4_steady_state_independent_of_r(p: Precision) {
    let coef = random_coef([15, 14, 13], 5, 0.05, 0.2);
    let r = 0.9 * coef.bounds(BoundaryCondition::Dirichlet).gershgorin;
    let a = run(
        p,
        &coef,
        &RdeConfig::default()
            .with_time_step(TimeStep::Fixed(r))
            .steady(tight(p), 200_000),
    );
    let b = run(
        p,
        &coef,
        &RdeConfig::default()
            .with_time_step(TimeStep::Fixed(r / 2.0))
            .steady(tight(p), 200_000),
    );
    assert!(a.converged() && b.converged());
    let e = rel_max(&a.phi, &b.phi);
    let bound = if p == Precision::F64 { 1e-8 } else { 1e-3 };
    eprintln!(
        "A4 {p:?}: r {r:.4} {} steps, r/2 {} steps, diff {e:.2e}",
        a.steps, b.steps
    );
    assert!(e <= bound, "{e:.3e}");
    assert!(
        (b.steps as f64 / a.steps as f64 - 2.0).abs() < 0.1,
        "{} vs {}",
        a.steps,
        b.steps
    );
}

/// A5: point source vs the CDA Green's function (FLD Eq 27, `reference::point_source`) with its
/// values on the Dirichlet layer, as the CDA test does: shell averages beyond 3 voxels within
/// 2 % (33³ unit cube, σt = 16.5 so that σt∆ = 1/2 and β = 2/3 stays below the cap, α = 0.9).
fn a5_point_source_matches_eq_27(p: Precision) {
    use reference::point_source::{PointSource, Solution as Sol};
    let (n, albedo, sigma_t) = (33, 0.9, 16.5);
    let (medium, src) = crate::scenes::point_source::<f64>(n, sigma_t, albedo).unwrap();
    let g = medium.grid;
    let ps = PointSource::new(sigma_t, albedo).unwrap();
    let c = g.center(src[0], src[1], src[2]);
    let dist = |q: [f64; 3]| ((0..3).map(|a| (q[a] - c[a]).powi(2)).sum::<f64>()).sqrt();
    let coef = Coefficients::from_medium(&medium, 0.0).unwrap();
    assert_eq!(coef.beta_capped, 0);
    let boundary: Vec<f64> = (0..g.len())
        .map(|idx| {
            let [i, j, k] = g.coords(idx);
            if g.is_boundary(i, j, k) {
                ps.fluence(Sol::Cda, dist(g.center(i, j, k)))
            } else {
                0.0
            }
        })
        .collect();
    let coef = coef.with_initial(boundary);
    let sol = run(p, &coef, &RdeConfig::default().steady(tight(p), 200_000));
    assert!(sol.converged());
    let mut shells = vec![(0.0, 0.0); n];
    for idx in 0..g.len() {
        let [i, j, k] = g.coords(idx);
        let r = dist(g.center(i, j, k));
        let shell = (r / g.dl).round() as usize;
        if shell > 3 && !g.is_boundary(i, j, k) {
            shells[shell].0 += sol.phi[idx];
            shells[shell].1 += ps.fluence(Sol::Cda, r);
        }
    }
    let worst = shells
        .iter()
        .filter(|v| v.1 > 0.0)
        .map(|(num, ana)| (num - ana).abs() / ana)
        .fold(0.0, f64::max);
    eprintln!("A5 {p:?}: worst shell vs Eq 27 {worst:.3e}");
    assert!(worst < 0.02, "{worst:.3e}");
}

both!(
    a1_homogeneous_steady_state_equals_cda,
    a2_smooth_heterogeneity,
    a3_sharp_step,
    a4_steady_state_independent_of_r,
    a5_point_source_matches_eq_27,
);

// ---------------------------------------------------------------------------------------
// B. Stability.

/// The highest Dirichlet mode Π sin(N m π/(N + 1)) of an N³ interior (exact eigenvector of
/// the uniform operator), on the (N + 2)³ grid.
fn top_mode(grid: &Grid) -> Vec<f64> {
    let n = grid.n[0] - 2;
    (0..grid.len())
        .map(|idx| {
            let [i, j, k] = grid.coords(idx);
            if grid.is_boundary(i, j, k) {
                return 0.0;
            }
            [i, j, k]
                .iter()
                .map(|&m| (n as f64 * m as f64 * std::f64::consts::PI / (n + 1) as f64).sin())
                .product()
        })
        .collect()
}

/// B6: uniform (β, α) over a 10 × 10 grid, 16³ Dirichlet, started from the highest mode: the
/// per-step factor is 1 − r(a + 12β cos²(π/(2(N+1)))) (to 10⁻¹² f64, 10⁻⁵ f32); at
/// 1.02·r_crit it grows and at 0.98·r_crit it decays within 2000 steps; Eq 4.9 < r_crit
/// everywhere, and r_G < r_crit.
fn b6_top_mode_factor_and_critical_r(p: Precision) {
    let grid = Grid::new([16; 3], 1.0).unwrap();
    let nn = 14.0;
    let mode = top_mode(&grid);
    let cos2 = (std::f64::consts::PI / (2.0 * (nn + 1.0))).cos().powi(2);
    let mut worst_ratio: f64 = f64::INFINITY;
    for ib in 0..10 {
        let beta = 0.05 + 0.95 * ib as f64 / 9.0;
        for ia in 0..10 {
            let albedo = 0.99 * ia as f64 / 9.0;
            let a = (1.0 - albedo) / (3.0 * beta);
            let coef = Coefficients::uniform(grid, beta, a)
                .unwrap()
                .with_initial(mode.clone());
            let lam = a + 12.0 * beta * cos2;
            let r_crit = 2.0 / lam;
            let bounds = coef.bounds(BoundaryCondition::Dirichlet);
            assert!(bounds.gershgorin < r_crit);
            assert!(eq_4_9_printed(beta, albedo) < r_crit);
            assert!((eq_4_9_printed(beta, albedo) - bounds.eq49).abs() < 1e-12);
            worst_ratio = worst_ratio.min(r_crit / bounds.gershgorin);
            let cfg = |r: f64, steps: usize| {
                RdeConfig::default()
                    .with_time_step(TimeStep::Fixed(r))
                    .with_check(StepCheck::Unchecked)
                    .frames(steps, 0)
            };
            let r = 0.9 * bounds.gershgorin;
            let one = run(p, &coef, &cfg(r, 1));
            let g = 1.0 - r * lam;
            let expect: Vec<f64> = mode.iter().map(|x| g * x).collect();
            let e = rel_max(&one.phi, &expect);
            let tol = if p == Precision::F64 { 1e-12 } else { 1e-5 };
            assert!(e < tol, "β={beta} α={albedo}: factor error {e:.3e}");
            let grow = run(p, &coef, &cfg(1.02 * r_crit, 2000));
            let decay = run(p, &coef, &cfg(0.98 * r_crit, 2000));
            let (ng, nd, n0) = (norm2(&grow.phi), norm2(&decay.phi), norm2(&mode));
            assert!(ng > 10.0 * n0, "β={beta} α={albedo}: 1.02 r_crit: {ng:.3e}");
            assert!(nd < 0.1 * n0, "β={beta} α={albedo}: 0.98 r_crit: {nd:.3e}");
        }
    }
    eprintln!("B6 {p:?}: min r_crit / r_G over the grid = {worst_ratio:.4}");
}

/// A tube phantom β = max(exp(−(‖∇S‖/σ)²), 10⁻³) of a scalar S = 1 inside a cylinder of
/// radius 4 voxels (thesis gradient mapping, σ = 0.1), central differences.
fn tube_phantom(n: usize) -> Vec<f64> {
    let grid = Grid::new([n; 3], 1.0).unwrap();
    let c = n as f64 / 2.0;
    let s = grid.sample(|q| {
        if ((q[0] - c).powi(2) + (q[1] - c).powi(2)).sqrt() < 4.0 {
            1.0
        } else {
            0.0
        }
    });
    (0..grid.len())
        .map(|idx| {
            let p = grid.coords(idx);
            let d = |axis: usize| -> f64 {
                let at = |dir: i64| {
                    let mut q = p;
                    q[axis] = (p[axis] as i64 + dir).clamp(0, n as i64 - 1) as usize;
                    s[grid.index(q[0], q[1], q[2])]
                };
                (at(1) - at(-1)) / 2.0
            };
            let gn = (d(0).powi(2) + d(1).powi(2) + d(2).powi(2)).sqrt();
            (-(gn / 0.1).powi(2)).exp().max(1e-3)
        })
        .collect()
}

/// B7: the conservative scheme at r = r_G never increases ‖φ‖₂ (its update matrix is
/// symmetric with eigenvalues in [−1, 1]) over 5000 steps on a β step, random U[0.01, 1], a
/// voxel checkerboard and the tube phantom, 16³, α = 0.99 (a = 0.01/(3β)).
fn b7_conservative_is_stable_at_the_gershgorin_bound(p: Precision) {
    let n = 16;
    let grid = Grid::new([n; 3], 1.0).unwrap();
    let mut rng = SplitMix64::new(17);
    let media: Vec<(&str, Vec<f64>)> = vec![
        (
            "step",
            (0..grid.len())
                .map(|i| if grid.coords(i)[0] < n / 2 { 1.0 } else { 0.01 })
                .collect(),
        ),
        (
            "random",
            (0..grid.len())
                .map(|_| 0.01 + 0.99 * rng.next_f64())
                .collect(),
        ),
        (
            "checkerboard",
            (0..grid.len())
                .map(|i| {
                    let [x, y, z] = grid.coords(i);
                    if (x + y + z) % 2 == 0 { 1.0 } else { 0.01 }
                })
                .collect(),
        ),
        ("tube", tube_phantom(n)),
    ];
    for (name, beta) in media {
        let ka: Vec<f64> = beta.iter().map(|b| 0.01 / (3.0 * b)).collect();
        let init: Vec<f64> = (0..grid.len()).map(|_| rng.next_f64() - 0.5).collect();
        let coef = Coefficients::from_maps(grid, beta, ka, vec![0.0; grid.len()])
            .unwrap()
            .with_initial(init);
        let rg = coef.bounds(BoundaryCondition::Dirichlet).gershgorin;
        let cfg = RdeConfig::default()
            .with_time_step(TimeStep::Fixed(rg))
            .frames(5000, 500);
        let s = run(p, &coef, &cfg);
        let mut prev = norm2(&coef.initial.clone().unwrap());
        for (step, snap) in &s.trace.snapshots {
            let nrm = norm2(snap);
            assert!(
                nrm <= prev * (1.0 + 1e-6),
                "{name}: ‖φ‖ grew at step {step}: {prev:.6e} → {nrm:.6e}"
            );
            prev = nrm;
        }
    }
}

/// B8: regression test of the spec's finding. Random voxel-scale β ~ U[0.01, 1] at α = 1
/// (a = 0), r = 0.02 (inside thesis Eq 4.9's 0.074), random start: `ThesisExpanded` grows
/// more than 10³× in 20 000 steps, `Conservative` decays. 3D: 10³ Dirichlet (seed 3); 2D:
/// 22² × 3 with Neumann walls and a z-constant field (seed 1).
fn b8_expanded_grows_where_conservative_decays(p: Precision) {
    for (dims, bc, seed) in [
        ([10, 10, 10], BoundaryCondition::Dirichlet, 3),
        ([22, 22, 3], BoundaryCondition::Neumann, 1),
    ] {
        let grid = Grid::new(dims, 1.0).unwrap();
        let plane = dims[0] * dims[1];
        let two_d = dims[2] == 3;
        let mut rng = SplitMix64::new(seed);
        let cells = if two_d { plane } else { grid.len() };
        let b: Vec<f64> = (0..cells).map(|_| 0.01 + 0.99 * rng.next_f64()).collect();
        let x: Vec<f64> = (0..cells).map(|_| rng.next_f64() - 0.5).collect();
        let (beta, init): (Vec<f64>, Vec<f64>) = (0..grid.len())
            .map(|i| (b[i % cells], x[i % cells]))
            .unzip();
        let coef =
            Coefficients::from_maps(grid, beta, vec![0.0; grid.len()], vec![0.0; grid.len()])
                .unwrap()
                .with_initial(init.clone());
        assert!(0.02 < coef.bounds(bc).eq49);
        let n0 = norm2(&init);
        let go = |op| {
            let cfg = RdeConfig::default()
                .with_operator(op)
                .with_boundary(bc)
                .with_time_step(TimeStep::Fixed(0.02))
                .frames(20_000, 0);
            norm2(&run(p, &coef, &cfg).phi) / n0
        };
        let (exp, cons) = (go(Operator::ThesisExpanded), go(Operator::Conservative));
        eprintln!(
            "B8 {p:?} {dims:?}: ‖φ‖ ratio after 20000 steps: expanded {exp:.3e}, conservative {cons:.3e}"
        );
        assert!(exp > 1e3, "{dims:?}: expanded {exp:.3e}");
        assert!(cons < 1.0, "{dims:?}: conservative {cons:.3e}");
    }
}

/// B9: the fixed-r presets on uniform β = 1, α = 0 (a = 1/3): r = 0.1 exceeds Eq 4.9 (0.072)
/// but not r_G (0.162): accepted by default, rejected by `Eq49Strict`; r = 0.2 is rejected by
/// both, each with an error naming `r`.
fn b9_fixed_r_presets(p: Precision) {
    let grid = Grid::new([8; 3], 1.0).unwrap();
    let coef = Coefficients::uniform(grid, 1.0, 1.0 / 3.0).unwrap();
    let b = coef.bounds(BoundaryCondition::Dirichlet);
    assert!((b.eq49 - 6.0 / 83.0).abs() < 1e-12, "{}", b.eq49);
    assert!((b.gershgorin - 2.0 / (1.0 / 3.0 + 12.0)).abs() < 1e-12);
    let cfg = |r, check| {
        RdeConfig::default()
            .with_time_step(TimeStep::Fixed(r))
            .with_check(check)
            .frames(3, 0)
    };
    assert!(
        solve(
            &Backend::Cpu(p),
            &coef,
            &cfg(0.1, StepCheck::Gershgorin),
            |_, _| {}
        )
        .is_ok()
    );
    for (r, check, bound) in [
        (0.1, StepCheck::Eq49Strict, b.eq49),
        (0.2, StepCheck::Gershgorin, b.gershgorin),
        (0.2, StepCheck::Eq49Strict, b.gershgorin),
    ] {
        match solve(&Backend::Cpu(p), &coef, &cfg(r, check), |_, _| {}) {
            Err(SolverError::StepAboveBound {
                name: "r",
                value,
                bound: got,
                ..
            }) => {
                assert_eq!(value, r);
                assert!((got - bound).abs() < 1e-12, "{check:?}: bound {got}");
            }
            other => panic!("r = {r} {check:?}: {other:?}"),
        }
    }
}

both!(
    b6_top_mode_factor_and_critical_r,
    b7_conservative_is_stable_at_the_gershgorin_bound,
    b8_expanded_grows_where_conservative_decays,
    b9_fixed_r_presets,
);

// ---------------------------------------------------------------------------------------
// D. Conservation, transients, positivity, symmetry, homogeneity.

/// D14: per step, Σφⁿ⁺¹ = Σ(1 − r a_p)φⁿ_p + r∆Σq_p − r Σ_{faces to the Dirichlet layer}
/// β_ps φⁿ_p to 10⁻¹² relative (f64; f32 10⁻⁵) for `Conservative` on a heterogeneous medium;
/// `ThesisExpanded` breaks it (imbalance > 10⁻³).
fn d14_conservation_per_step(p: Precision) {
    let coef = random_coef([12, 11, 10], 9, 0.01, 0.3);
    let g = coef.grid;
    let imbalance = |op| {
        let cfg = RdeConfig::default().with_operator(op).frames(1, 0);
        let mut phi = run(p, &coef, &RdeConfig { ..cfg.clone() }.frames(30, 0)).phi;
        let r = 0.9 * coef.bounds(BoundaryCondition::Dirichlet).gershgorin;
        let next = run(p, &coef.clone().with_initial(phi.clone()), &cfg).phi;
        let mut expect = 0.0;
        let mut scale = 0.0;
        for idx in 0..g.len() {
            let [i, j, k] = g.coords(idx);
            if g.is_boundary(i, j, k) {
                phi[idx] = 0.0;
                continue;
            }
            expect += (1.0 - r * coef.ka_dl[idx]) * phi[idx] + r * g.dl * coef.source[idx];
            scale += phi[idx].abs();
            for (axis, &x) in [i, j, k].iter().enumerate() {
                for dir in [-1i64, 1] {
                    let mut q = [i, j, k];
                    q[axis] = (x as i64 + dir) as usize;
                    if g.is_boundary(q[0], q[1], q[2]) {
                        let bf = 0.5 * (coef.beta[idx] + coef.beta[g.index(q[0], q[1], q[2])]);
                        expect -= r * bf * phi[idx];
                    }
                }
            }
        }
        (next.iter().sum::<f64>() - expect).abs() / scale
    };
    let cons = imbalance(Operator::Conservative);
    let exp = imbalance(Operator::ThesisExpanded);
    eprintln!("D14 {p:?}: relative imbalance conservative {cons:.2e}, expanded {exp:.2e}");
    let tol = if p == Precision::F64 { 1e-12 } else { 1e-5 };
    assert!(cons < tol, "conservative {cons:.3e}");
    assert!(exp > 1e-3, "expanded {exp:.3e}");
}

/// D15: a unit pulse in a homogeneous 65³ medium (β = 0.5, a = 0.01): while the spread
/// √(2βτ) ≤ 5 voxels (τ = n r), Σφ = (1 − ra)ⁿ to 10⁻⁶, and φ matches the continuous Green's
/// function (4πβτ)^{−3/2} e^{−R²/(4βτ)} (1 − ra)ⁿ to ≤ 10⁻² relative L2 beyond 2 voxels (the
/// discrete decay (1 − ra)ⁿ, not e^{−aτ}: that would add a first-order time error).
fn d15_pulse_matches_the_greens_function(p: Precision) {
    let n = 65;
    let grid = Grid::new([n; 3], 1.0).unwrap();
    let (beta, a) = (0.5, 0.01);
    let mut init = vec![0.0; grid.len()];
    let c = n / 2;
    init[grid.index(c, c, c)] = 1.0;
    let coef = Coefficients::uniform(grid, beta, a)
        .unwrap()
        .with_initial(init);
    for r in [0.1, 0.3] {
        let steps = (25.0 / (2.0 * beta * r)) as usize;
        let cfg = RdeConfig::default()
            .with_time_step(TimeStep::Fixed(r))
            .frames(steps, 0);
        let s = run(p, &coef, &cfg);
        let decay = (1.0 - r * a).powi(steps as i32);
        let mass: f64 = s.phi.iter().sum();
        let tol = if p == Precision::F64 { 1e-6 } else { 1e-4 };
        assert!(
            (mass / decay - 1.0).abs() < tol,
            "r={r}: mass {mass} vs {decay}"
        );
        let tau = steps as f64 * r;
        let (mut num, mut den) = (0.0, 0.0);
        for idx in 0..grid.len() {
            let [i, j, k] = grid.coords(idx);
            let r2 = [i, j, k]
                .iter()
                .map(|&x| (x as f64 - c as f64).powi(2))
                .sum::<f64>();
            if r2 <= 4.0 {
                continue;
            }
            let green = (4.0 * std::f64::consts::PI * beta * tau).powf(-1.5)
                * (-r2 / (4.0 * beta * tau)).exp()
                * decay;
            num += (s.phi[idx] - green).powi(2);
            den += green * green;
        }
        let e = (num / den).sqrt();
        eprintln!(
            "D15 {p:?}: r = {r}, {steps} steps: mass error {:.2e}, profile L2 {e:.2e}",
            mass / decay - 1.0
        );
        assert!(e < 1e-2, "r={r}: {e:.3e}");
        assert!((s.trace.light_path - steps as f64 * r).abs() < 1e-9);
    }
}

/// D16: `Conservative` at r = r_pos with q ≥ 0 keeps min φⁿ ≥ 0 at every step, on random media
/// with 10⁴ contrast in β and absorption up to a = 10.
fn d16_positivity(p: Precision) {
    for seed in [1, 2, 3] {
        let grid = Grid::new([11, 12, 13], 1.0).unwrap();
        let mut rng = SplitMix64::new(seed);
        let beta = (0..grid.len())
            .map(|_| 10f64.powf(-4.0 * rng.next_f64()))
            .collect();
        let ka = (0..grid.len())
            .map(|_| 10.0 * rng.next_f64().powi(3))
            .collect();
        let q = (0..grid.len())
            .map(|_| if rng.next_f64() < 0.05 { 1.0 } else { 0.0 })
            .collect();
        let coef = Coefficients::from_maps(grid, beta, ka, q).unwrap();
        let rp = coef.bounds(BoundaryCondition::Dirichlet).positivity;
        let cfg = RdeConfig::default().with_time_step(TimeStep::Fixed(rp));
        let check = |phi: Vec<f64>, step| {
            let m = phi.iter().cloned().fold(f64::INFINITY, f64::min);
            assert!(
                m >= 0.0 && phi.iter().all(|x| x.is_finite()),
                "seed {seed} step {step}: {m}"
            );
        };
        match p {
            Precision::F64 => {
                let mut k = CpuRde::<f64>::new(&coef, &cfg).unwrap();
                for s in 0..300 {
                    k.step(false);
                    check(k.phi(), s);
                }
            }
            Precision::F32 => {
                let mut k = CpuRde::<f32>::new(&coef, &cfg).unwrap();
                for s in 0..300 {
                    k.step(false);
                    check(k.phi().iter().map(|x| f64::from(*x)).collect(), s);
                }
            }
        }
    }
}

/// D17: reciprocity G(a → b) = G(b → a) to 10⁻¹⁰ (f64, stopped at R̄/j̄ < 10⁻¹⁴; f32 10⁻²,
/// stopped at 10⁻⁶: G(a → b) is 10⁻⁴ of the source voxel's φ) for `Conservative` in a
/// heterogeneous medium (symmetric operator); `ThesisExpanded` is not reciprocal (asymmetry
/// above 10⁻³). β ~ U[0.2, 1], where the expanded form is still stable (at U[0.01, 1] it is not,
/// B8).
fn d17_reciprocity(p: Precision) {
    let base = random_coef([13, 12, 11], 21, 0.2, 0.2);
    let g = base.grid;
    let (pa, pb) = (g.index(3, 4, 3), g.index(7, 6, 6));
    let tol = if p == Precision::F64 { 1e-14 } else { 1e-6 };
    let green = |op, from: usize, to: usize| {
        let mut c = base.clone();
        c.source = vec![0.0; g.len()];
        c.source[from] = 1.0;
        let s = run(
            p,
            &c,
            &RdeConfig::default().with_operator(op).steady(tol, 200_000),
        );
        assert!(s.converged());
        s.phi[to]
    };
    let asym = |op| {
        let (ab, ba) = (green(op, pa, pb), green(op, pb, pa));
        (ab - ba).abs() / ab.abs().max(ba.abs())
    };
    let (cons, exp) = (asym(Operator::Conservative), asym(Operator::ThesisExpanded));
    eprintln!("D17 {p:?}: asymmetry conservative {cons:.2e}, expanded {exp:.2e}");
    let bound = if p == Precision::F64 { 1e-10 } else { 1e-2 };
    assert!(cons < bound, "{cons:.3e}");
    assert!(exp > 1e-3, "{exp:.3e}");
}

/// D18: degree-1 homogeneity in q for scales 10⁻³⁰ … 10³⁰ in both precisions (the run is on
/// q/j̄): φ(λq)/λ = φ(q) to rounding after 40 steps.
fn d18_homogeneity_in_the_source(p: Precision) {
    let coef = random_coef([10, 9, 11], 4, 0.01, 0.3);
    let cfg = RdeConfig::default().frames(40, 0);
    let base = run(p, &coef, &cfg).phi;
    let tol = if p == Precision::F64 { 1e-12 } else { 1e-5 };
    for scale in [1e-30, 1e-3, 1e3, 1e30] {
        let mut c = coef.clone();
        c.source.iter_mut().for_each(|q| *q *= scale);
        let phi: Vec<f64> = run(p, &c, &cfg).phi.iter().map(|x| x / scale).collect();
        let e = rel_max(&phi, &base);
        assert!(e < tol, "scale {scale:e}: {e:.3e}");
    }
}

both!(
    d14_conservation_per_step,
    d15_pulse_matches_the_greens_function,
    d16_positivity,
    d17_reciprocity,
    d18_homogeneity_in_the_source,
);

// ---------------------------------------------------------------------------------------
// Bad input (acceptance 4).

#[test]
fn bad_input_is_a_typed_error_naming_the_parameter() {
    let grid = Grid::new([6; 3], 1.0).unwrap();
    let n = grid.len();
    let field = |r: Result<Coefficients, SolverError>| match r {
        Err(SolverError::FieldValue { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(
        field(Coefficients::from_maps(
            grid,
            vec![1.5; n],
            vec![0.1; n],
            vec![0.0; n]
        )),
        "beta"
    );
    assert_eq!(
        field(Coefficients::from_maps(
            grid,
            vec![-0.1; n],
            vec![0.1; n],
            vec![0.0; n]
        )),
        "beta"
    );
    assert_eq!(
        field(Coefficients::from_maps(
            grid,
            vec![0.5; n],
            vec![-0.1; n],
            vec![0.0; n]
        )),
        "ka_dl"
    );
    assert_eq!(
        field(Coefficients::from_maps(
            grid,
            vec![0.5; n],
            vec![f64::NAN; n],
            vec![0.0; n]
        )),
        "ka_dl"
    );
    assert!(matches!(
        Coefficients::from_maps(grid, vec![0.5; n - 1], vec![0.1; n], vec![0.0; n]),
        Err(SolverError::FieldSize { field: "beta", .. })
    ));
    let coef = Coefficients::uniform(grid, 0.5, 0.1).unwrap();
    let name = |cfg: RdeConfig| match CpuRde::<f64>::new(&coef, &cfg) {
        Err(SolverError::BadParameter { name, .. }) => name,
        Err(SolverError::StepAboveBound { name, .. }) => name,
        other => panic!("{other:?}"),
    };
    for r in [0.0, -0.1, f64::NAN, f64::INFINITY, 10.0] {
        assert_eq!(
            name(RdeConfig::default().with_time_step(TimeStep::Fixed(r))),
            "r"
        );
    }
    for s in [0.0, 1.5, f64::NAN] {
        assert_eq!(
            name(RdeConfig::default().with_time_step(TimeStep::Gershgorin { safety: s })),
            "safety"
        );
    }
    assert_eq!(name(RdeConfig::default().steady(f64::NAN, 10)), "tolerance");
    let zero = Coefficients::uniform(grid, 0.0, 0.0).unwrap();
    assert!(matches!(
        CpuRde::<f64>::new(&zero, &RdeConfig::default()),
        Err(SolverError::BadParameter { name: "beta", .. })
    ));
    let m = Medium::<f64>::homogeneous(grid, 1.0, 0.5).unwrap();
    assert!(matches!(
        Coefficients::from_medium(&m, 1.0),
        Err(SolverError::BadParameter { name: "g", .. })
    ));
}

/// β = 1/(3σt(1 − αg)∆) is capped at 1 and counted; a = (1 − α)σt∆.
#[test]
fn physical_parameters_map_to_beta_and_absorption() {
    let grid = Grid::new([5; 3], 0.5).unwrap();
    let mut m = Medium::<f64>::homogeneous(grid, 4.0, 0.75).unwrap();
    m.sigma_t[0] = 0.0;
    m.sigma_t[1] = 0.5;
    let c = Coefficients::from_medium(&m, 0.2).unwrap();
    assert_eq!(c.beta_capped, 2);
    assert_eq!(c.beta[0], BETA_MAX);
    let b = 1.0 / (3.0 * 4.0 * (1.0 - 0.75 * 0.2) * 0.5);
    assert!((c.beta[5] - b).abs() < 1e-15);
    assert!((c.ka_dl[5] - 0.25 * 4.0 * 0.5).abs() < 1e-15);
    // Eq 4.6: Ka = (1 − α)/(3(1 − αg)D).
    let ka = (1.0 - 0.75) / (3.0 * (1.0 - 0.75 * 0.2) * b * 0.5);
    assert!((c.ka_dl[5] / 0.5 - ka).abs() < 1e-12);
}

// ---------------------------------------------------------------------------------------
// E. GPU vs CPU (lavapipe in CI; skipped with one line without an adapter).

/// The largest |gpu − cpu|/cpu where cpu > 10⁻⁶ max|cpu|.
fn rel_where_resolved(gpu: &[f64], cpu: &[f64]) -> f64 {
    let max = max_abs(cpu);
    gpu.iter()
        .zip(cpu)
        .filter(|(_, c)| c.abs() > 1e-6 * max)
        .map(|(g, c)| (g - c).abs() / c.abs())
        .fold(0.0, f64::max)
}

/// E19–E21 on one device.
///
/// * E19: after 200 steps (transient), GPU f32 vs CPU f32 ≤ 10⁻⁴ relative where φ > 10⁻⁶ max φ,
///   for every operator, both boundaries and the local step.
/// * E20: at steady state (steps past convergence) both f32 backends lie within
///   10 ε₃₂/(r λ₁) of CPU f64 (homogeneous 21³, λ₁ = a + 12β sin²(π/(2(N+1)))); `Steady` step
///   counts of CPU f32 and GPU agree within 2 %.
/// * E21: ping-pong hazard: 10 GPU steps equal the CPU's double-buffered result to 10⁻⁶,
///   while an in-place (Gauss–Seidel order) update differs from it by more than 10⁻².
#[test]
fn e19_e21_gpu_matches_cpu() {
    let ctx = match crate::gpu::GpuContext::for_tests() {
        Ok(Some(c)) => c,
        Ok(None) => {
            crate::gpu::log_uncaptured("e19_e21_gpu_matches_cpu: skipped: no GPU adapter");
            return;
        }
        Err(e) => panic!("SCATTERBENCH_REQUIRE_GPU is set: {e}"),
    };
    crate::gpu::log_uncaptured(&format!(
        "e19_e21_gpu_matches_cpu: ran on {}",
        ctx.describe()
    ));
    let gpu = Backend::Gpu(&ctx);
    let cpu32 = Backend::Cpu(Precision::F32);
    // E19.
    let coef = random_coef([24, 19, 21], 8, 0.2, 0.3);
    let mut worst: f64 = 0.0;
    for op in Operator::ALL {
        for bc in [BoundaryCondition::Dirichlet, BoundaryCondition::Neumann] {
            for ts in [TimeStep::default(), TimeStep::Local { safety: 0.9 }] {
                let cfg = RdeConfig::default()
                    .with_operator(op)
                    .with_boundary(bc)
                    .with_time_step(ts)
                    .frames(200, 100);
                let g = solve(&gpu, &coef, &cfg, |_, _| {}).unwrap();
                let c = solve(&cpu32, &coef, &cfg, |_, _| {}).unwrap();
                assert_eq!(g.steps, 200);
                assert_eq!(g.trace.snapshots.len(), 2);
                let e = rel_where_resolved(&g.phi, &c.phi);
                assert!(e <= 1e-4, "E19 {op:?} {bc:?} {ts:?}: {e:.3e}");
                worst = worst.max(e);
            }
        }
    }
    eprintln!("E19: max GPU vs CPU-f32 relative difference after 200 steps {worst:.3e}");
    // E20.
    let (m, hom) = homogeneous(21, 0.5, 0.99);
    let _ = m;
    let a = hom.ka_dl[0];
    let lam = a + 12.0 * 0.5 * (std::f64::consts::PI / (2.0 * 20.0)).sin().powi(2);
    let r = 0.9 * hom.bounds(BoundaryCondition::Dirichlet).gershgorin;
    let bound = 10.0 * f64::from(f32::EPSILON) / (r * lam);
    let long = RdeConfig::default().steady(0.0, 3000);
    let f64sol = solve(&Backend::Cpu(Precision::F64), &hom, &long, |_, _| {}).unwrap();
    assert!(f64sol.trace.residuals.last().unwrap() < &1e-9);
    for b in [&gpu, &cpu32] {
        let s = solve(b, &hom, &long, |_, _| {}).unwrap();
        let e = rel_max(&s.phi, &f64sol.phi);
        eprintln!("E20 {b}: steady vs CPU f64 {e:.3e} (bound 10ε/(rλ₁) = {bound:.3e})");
        assert!(e <= bound, "E20 {b}: {e:.3e} > {bound:.3e}");
    }
    let steady = RdeConfig::default().steady(1e-4, 100_000);
    let (sg, sc) = (
        solve(&gpu, &hom, &steady, |_, _| {}).unwrap(),
        solve(&cpu32, &hom, &steady, |_, _| {}).unwrap(),
    );
    assert!(sg.converged() && sc.converged());
    let (ng, nc) = (sg.steps as f64, sc.steps as f64);
    eprintln!("E20: steps to R̄/j̄ < 1e-4: GPU {ng}, CPU-f32 {nc}");
    assert!((ng - nc).abs() <= 0.02 * nc, "E20 steps {ng} vs {nc}");
    assert_eq!(sg.trace.residuals.len(), sg.steps);
    // E21.
    let coef = random_coef([16, 15, 14], 2, 0.2, 0.3);
    let cfg = RdeConfig::default().frames(10, 0);
    let g = solve(&gpu, &coef, &cfg, |_, _| {}).unwrap();
    let r = 0.9 * coef.bounds(BoundaryCondition::Dirichlet).gershgorin;
    let mut double = vec![0.0; coef.grid.len()];
    let mut in_place = double.clone();
    for _ in 0..10 {
        double = naive::step(
            &coef,
            Operator::Conservative,
            BoundaryCondition::Dirichlet,
            &|_| r,
            &double,
        );
        in_place = in_place_step(&coef, r, in_place);
    }
    let (eg, ei) = (rel_max(&g.phi, &double), rel_max(&in_place, &double));
    eprintln!("E21: GPU vs double-buffered {eg:.3e}; in-place vs double-buffered {ei:.3e}");
    assert!(eg <= 1e-6, "E21 GPU {eg:.3e}");
    assert!(ei > 1e-2, "E21 the in-place control {ei:.3e}");
}

/// The conservative update written in place (each voxel sees the already-updated values of
/// the voxels before it): the hazard the ping-pong buffers avoid.
fn in_place_step(coef: &Coefficients, r: f64, mut phi: Vec<f64>) -> Vec<f64> {
    let g = coef.grid;
    for idx in 0..g.len() {
        let p = g.coords(idx);
        if g.is_boundary(p[0], p[1], p[2]) {
            continue;
        }
        let mut lap = 0.0;
        for axis in 0..3 {
            for dir in [-1i64, 1] {
                let mut q = p;
                q[axis] = (p[axis] as i64 + dir) as usize;
                let s = g.index(q[0], q[1], q[2]);
                lap += 0.5 * (coef.beta[idx] + coef.beta[s]) * (phi[s] - phi[idx]);
            }
        }
        phi[idx] += r * (coef.source[idx] * g.dl - coef.ka_dl[idx] * phi[idx] + lap);
    }
    phi
}

// ---------------------------------------------------------------------------------------
// F. Tools (thesis §4.2.5).

/// F22: a negative point source of equal magnitude mirrored about the midplane of a
/// mirror-symmetric medium gives φ = 0 on the midplane (to 10⁻¹² of max|φ| in f64, 10⁻⁵ in
/// f32); φ is antisymmetric and negative on the negative side (allowed by design). A point
/// source of power P equals a volume source P/∆³ in its voxel.
fn f22_negative_source_cancels_on_the_midplane(p: Precision) {
    let (nx, ny, nz) = (21, 12, 11);
    let grid = Grid::new([nx, ny, nz], 0.5).unwrap();
    let half = random_coef([nx / 2 + 1, ny, nz], 12, 0.05, 0.3);
    let mirror = |idx: usize| {
        let [i, j, k] = grid.coords(idx);
        half.grid.index(i.min(nx - 1 - i), j, k)
    };
    let beta = (0..grid.len()).map(|i| half.beta[mirror(i)]).collect();
    let ka = (0..grid.len()).map(|i| half.ka_dl[mirror(i)]).collect();
    let coef = Coefficients::from_maps(grid, beta, ka, vec![0.0; grid.len()])
        .unwrap()
        .with_point_sources(&[
            PointSource {
                voxel: [6, 5, 5],
                power: 2.0,
            },
            PointSource {
                voxel: [nx - 1 - 6, 5, 5],
                power: -2.0,
            },
        ])
        .unwrap();
    assert!(coef.signed_source);
    assert_eq!(coef.source[grid.index(6, 5, 5)], 2.0 / 0.125);
    let s = run(p, &coef, &RdeConfig::default().frames(300, 0));
    let max = max_abs(&s.phi);
    let mid = (0..grid.len())
        .filter(|&i| grid.coords(i)[0] == nx / 2)
        .map(|i| s.phi[i].abs())
        .fold(0.0, f64::max);
    let tol = if p == Precision::F64 { 1e-12 } else { 1e-5 };
    eprintln!(
        "F22 {p:?}: max |φ| on the midplane / max |φ| = {:.2e}",
        mid / max
    );
    assert!(mid <= tol * max, "{:.3e}", mid / max);
    assert!(s.trace.min_phi < -0.5 * max);
    // Unsigned sources stay validated as ≥ 0.
    let mut bad = coef.clone();
    bad.signed_source = false;
    assert!(matches!(
        bad.validate(),
        Err(SolverError::FieldValue {
            field: "source",
            ..
        })
    ));
}

/// F23: painting: the effective source is the union of the visited voxels, each counted once
/// however often the brush passes.
#[test]
fn f23_painting_is_the_union_of_visited_voxels() {
    let grid = Grid::new([8; 3], 1.0).unwrap();
    let path = [
        [1, 1, 1],
        [2, 1, 1],
        [2, 2, 1],
        [2, 1, 1],
        [1, 1, 1],
        [3, 3, 3],
    ];
    let c = Coefficients::uniform(grid, 0.5, 0.1)
        .unwrap()
        .paint(&path, 1.5)
        .unwrap();
    let mask: Vec<usize> = (0..grid.len()).filter(|&i| c.source[i] != 0.0).collect();
    let mut union: Vec<usize> = path.iter().map(|v| grid.index(v[0], v[1], v[2])).collect();
    union.sort_unstable();
    union.dedup();
    assert_eq!(mask, union);
    assert!(mask.iter().all(|&i| c.source[i] == 1.5));
    assert!(matches!(
        Coefficients::uniform(grid, 0.5, 0.1)
            .unwrap()
            .paint(&[[8, 0, 0]], 1.0),
        Err(SolverError::BadParameter {
            name: "point_source.voxel",
            ..
        })
    ));
}

both!(f22_negative_source_cancels_on_the_midplane);

// ---------------------------------------------------------------------------------------
// C. The P1 control and the checkerboard (thesis Fig 3.6(a)).

mod p1_tests {
    use super::super::p1::{Checkerboard, P1, P1Config, P1Stencil, p1_critical_r};
    use super::*;

    /// Uniform β, α (g = 0) on a 19³ grid (17³ unknowns) with a unit point source at
    /// (8, 8, 8): its sublattice holds the Dirichlet layer (even indices), the coarse grid is
    /// 10³ with 8³ unknowns.
    fn setup(beta: f64, albedo: f64) -> (Coefficients, [usize; 3]) {
        let grid = Grid::new([19; 3], 1.0).unwrap();
        let src = [8, 8, 8];
        let c = Coefficients::uniform(grid, beta, (1.0 - albedo) / (3.0 * beta))
            .unwrap()
            .with_point_sources(&[PointSource {
                voxel: src,
                power: 1.0,
            }])
            .unwrap();
        (c, src)
    }

    fn widen<T: Real>(v: &[T]) -> Vec<f64> {
        v.iter().map(|x| x.f()).collect()
    }

    /// Whether voxel `c` lies on the sublattice of offsets (from `src`) with parity `par`
    /// per axis (0 even, 1 odd).
    fn on(c: [usize; 3], src: [usize; 3], par: [usize; 3]) -> bool {
        (0..3).all(|a| (c[a] + src[a]) % 2 == par[a])
    }

    /// C10: after 1, 10 and 4000 steps φ is exactly 0.0 off the source's sublattice and E_j
    /// exactly 0.0 off its own (offset odd along j, even across), bitwise in f32 and f64; the
    /// steady source-sublattice φ equals CDA on the coarse grid H = 2∆ (β_H = β/2,
    /// (Ka∆)_H = 2Ka∆, the same q; Dirichlet layer on the sublattice) to 10⁻¹² (f64; f32 10⁻⁵).
    fn c10_sublattices_decouple_exactly(p: Precision) {
        match p {
            Precision::F64 => c10::<f64>(1e-12),
            Precision::F32 => c10::<f32>(1e-5),
        }
    }

    fn c10<T: Real>(tol: f64) {
        let (beta, albedo) = (1.0 / 3.0, 0.9);
        let (coef, src) = setup(beta, albedo);
        let g = coef.grid;
        let a = coef.ka_dl[0];
        let r = 0.9 * p1_critical_r(a, 1.0 / (3.0 * beta));
        let mut s = P1::<T>::new(
            &coef,
            P1Config {
                r,
                verbatim: false,
                stencil: P1Stencil::Central,
            },
        )
        .unwrap();
        let mut done = 0;
        for n in [1, 10, 4000] {
            while done < n {
                s.step();
                done += 1;
            }
            for idx in 0..g.len() {
                let c = g.coords(idx);
                if !on(c, src, [0, 0, 0]) {
                    assert!(s.phi[idx] == T::zero(), "step {n}: φ{c:?} = {}", s.phi[idx]);
                }
                for axis in 0..3 {
                    let mut par = [0; 3];
                    par[axis] = 1;
                    if !on(c, src, par) {
                        assert!(s.e[axis][idx] == T::zero(), "step {n}: E{axis}{c:?}");
                    }
                }
            }
        }
        let phi = widen(&s.phi);
        assert!(phi.iter().any(|v| *v > 0.0));
        // Coarse CDA (the conservative RDE's steady state) on the even sublattice.
        let cg = Grid::new([10; 3], 2.0).unwrap();
        let mut q = vec![0.0; cg.len()];
        q[cg.index(4, 4, 4)] = coef.source[g.index(8, 8, 8)];
        let coarse =
            Coefficients::from_maps(cg, vec![beta / 2.0; cg.len()], vec![2.0 * a; cg.len()], q)
                .unwrap();
        let cs = run(
            Precision::F64,
            &coarse,
            &RdeConfig::default().steady(1e-13, 100_000),
        );
        assert!(cs.converged());
        let fine_on_coarse: Vec<f64> = (0..cg.len())
            .map(|ci| {
                let [i, j, k] = cg.coords(ci);
                phi[g.index(2 * i, 2 * j, 2 * k)]
            })
            .collect();
        let e = rel_max(&fine_on_coarse, &cs.phi);
        eprintln!(
            "C10 {}: P1 source sublattice vs coarse CDA {e:.2e} (r = {r:.4})",
            T::NAME
        );
        assert!(e <= tol, "{e:.3e}");
    }

    /// C11: the detector flags P1 (off-sublattice fraction 0, Nyquist-plane energy above 0.1)
    /// and passes the RDE on the same medium (off-sublattice above 0.5, Nyquist below 0.1).
    /// The spec's 2D thresholds (0.05, 0.01 on Nyquist *lines* at 64²) do not carry over to
    /// the union of three Nyquist planes at 19³: the RDE's point source puts 0.0355 there.
    fn c11_detector_flags_p1_and_passes_rde(p: Precision) {
        let (coef, src) = setup(1.0 / 3.0, 0.9);
        let g = coef.grid;
        let a = coef.ka_dl[0];
        let r = 0.9 * p1_critical_r(a, 1.0);
        let phi = match p {
            Precision::F64 => {
                let mut s = P1::<f64>::new(
                    &coef,
                    P1Config {
                        r,
                        verbatim: false,
                        stencil: P1Stencil::Central,
                    },
                )
                .unwrap();
                (0..2000).for_each(|_| s.step());
                s.phi
            }
            Precision::F32 => {
                let mut s = P1::<f32>::new(
                    &coef,
                    P1Config {
                        r,
                        verbatim: false,
                        stencil: P1Stencil::Central,
                    },
                )
                .unwrap();
                (0..2000).for_each(|_| s.step());
                widen(&s.phi)
            }
        };
        let p1 = Checkerboard::measure(&g, &phi, src);
        let rde = run(p, &coef, &RdeConfig::default().steady(tight(p), 100_000));
        let d = Checkerboard::measure(&g, &rde.phi, src);
        eprintln!(
            "C11 {p:?}: P1 off-sublattice {:.3}, Nyquist {:.4}; RDE off-sublattice {:.3}, Nyquist {:.4}",
            p1.off_sublattice, p1.nyquist, d.off_sublattice, d.nyquist
        );
        assert!(p1.off_sublattice == 0.0 && p1.nyquist > 0.1, "{p1:?}");
        assert!(p1.is_checkerboard());
        assert!(d.off_sublattice > 0.5 && d.nyquist < 0.1, "{d:?}");
        assert!(!d.is_checkerboard());
        // Thesis Fig 3.6(b): the Sobel-weighted stencil couples the sublattices but keeps
        // energy on the Nyquist planes (axis-aligned alternation).
        let mut s = P1::<f64>::new(
            &coef,
            P1Config {
                r: 0.5 * r,
                verbatim: false,
                stencil: P1Stencil::Sobel,
            },
        )
        .unwrap();
        (0..2000).for_each(|_| s.step());
        let sob = Checkerboard::measure(&g, &s.phi, src);
        let min = s.phi.iter().cloned().fold(f64::INFINITY, f64::min);
        eprintln!(
            "C11 Sobel: off-sublattice {:.3}, Nyquist {:.4}, min/max φ {:.3}",
            sob.off_sublattice,
            sob.nyquist,
            min / max_abs(&s.phi)
        );
        assert!(sob.off_sublattice > 0.3, "{sob:?}");
        assert!(sob.nyquist > d.nyquist && sob.is_checkerboard(), "{sob:?}");
        assert!(
            min < 0.0,
            "the Sobel control's axis-aligned alternation: min φ {min}"
        );
    }

    /// C12: the run the thesis's P1 criterion (Kt c∆t, c∆t/(2∆)) < (1, 1) admits but the exact
    /// bound does not (β = 1, α = 0.9, r = 1.0) grows more than 100× between steps 30 and 60,
    /// with the row through the source reading + 0 − 0 + …; at 0.9 of the exact bound the run
    /// settles (its last step changes φ by less than 10⁻⁸ of max φ after 4000 steps).
    fn c12_admitted_unstable_p1_diverges(p: Precision) {
        let (coef, src) = setup(1.0, 0.9);
        let g = coef.grid;
        let (a, b) = (coef.ka_dl[0], 1.0 / 3.0);
        let rc = p1_critical_r(a, b);
        eprintln!("C12: exact P1 bound at β = 1, α = 0.9: r_crit = {rc:.4}");
        assert!(rc < 1.0 && b * 1.0 < 1.0);
        let mut s = P1::<f64>::new(
            &coef,
            P1Config {
                r: 1.0,
                verbatim: false,
                stencil: P1Stencil::Central,
            },
        )
        .unwrap();
        let mut n30 = 0.0;
        for n in 1..=60 {
            s.step();
            if n == 30 {
                n30 = max_abs(&s.phi);
            }
        }
        let n60 = max_abs(&s.phi);
        eprintln!("C12: r = 1.0: max|φ| {n30:.3e} (30 steps) → {n60:.3e} (60 steps)");
        assert!(n60 > 100.0 * n30);
        let row: Vec<f64> = (src[0]..g.n[0] - 1)
            .map(|i| s.phi[g.index(i, src[1], src[2])])
            .collect();
        for (m, v) in row.iter().enumerate() {
            if m % 2 == 1 {
                assert_eq!(*v, 0.0, "offset {m}");
            }
        }
        for m in (0..row.len() - 2).step_by(2) {
            assert!(row[m] * row[m + 2] < 0.0, "offsets {m}, {}: {row:?}", m + 2);
        }
        let stable = |steps: usize| -> (Vec<f64>, Vec<f64>) {
            match p {
                Precision::F64 => {
                    let mut s = P1::<f64>::new(
                        &coef,
                        P1Config {
                            r: 0.9 * rc,
                            verbatim: false,
                            stencil: P1Stencil::Central,
                        },
                    )
                    .unwrap();
                    (0..steps).for_each(|_| s.step());
                    let before = s.phi.clone();
                    s.step();
                    (before, s.phi)
                }
                Precision::F32 => {
                    let mut s = P1::<f32>::new(
                        &coef,
                        P1Config {
                            r: 0.9 * rc,
                            verbatim: false,
                            stencil: P1Stencil::Central,
                        },
                    )
                    .unwrap();
                    (0..steps).for_each(|_| s.step());
                    let before = widen(&s.phi);
                    s.step();
                    (before, widen(&s.phi))
                }
            }
        };
        let (before, after) = stable(4000);
        let change = rel_max(&after, &before);
        let tol = if p == Precision::F64 { 1e-8 } else { 1e-5 };
        assert!(change < tol, "0.9 r_crit: change {change:.3e}");
    }

    both!(
        c10_sublattices_decouple_exactly,
        c11_detector_flags_p1_and_passes_rde,
        c12_admitted_unstable_p1_diverges,
    );
}

mod fe_tests {
    use super::super::fe::FeJacobi;
    use super::*;

    /// C13: thesis Eq 3.22's Jacobi iteration flips a uniform field's sign and multiplies it by
    /// exactly 5/4 (2D) and 19/8 (3D) per iteration, for Kt∆ ∈ {1, 10, 100} (to 10⁻¹² f64,
    /// 10⁻⁵ f32); a random start grows at least as fast (spectral radius ≥ 19/8 in 3D).
    fn c13_fe_jacobi_diverges_with_sign_flips(p: Precision) {
        match p {
            Precision::F64 => c13::<f64>(1e-12),
            Precision::F32 => c13::<f32>(1e-5),
        }
    }

    fn c13<T: Real>(tol: f64) {
        for (dims, factor) in [(2, -1.25f64), (3, -19.0 / 8.0)] {
            for kt in [1.0, 10.0, 100.0] {
                let init = [1.0, 0.3, -0.2, 0.7];
                let mut s = FeJacobi::<T>::new(dims, 6, kt, |c, _| init[c]);
                for it in 1..=4 {
                    s.iterate();
                    let expect = factor.powi(it);
                    for (c, field) in s.x.iter().enumerate() {
                        for v in field {
                            let e = (v.f() / (init[c] * expect) - 1.0).abs();
                            assert!(e < tol, "{dims}D Kt∆ = {kt} it {it} comp {c}: {e:.3e}");
                        }
                    }
                }
            }
        }
        for kt in [0.1, 1.0] {
            let mut rng = SplitMix64::new(5);
            let vals: Vec<f64> = (0..4 * 216).map(|_| rng.next_f64() - 0.5).collect();
            let mut s = FeJacobi::<T>::new(3, 6, kt, |c, i| vals[c * 216 + i]);
            let norm = |s: &FeJacobi<T>| {
                s.x.iter()
                    .flatten()
                    .map(|v| v.f() * v.f())
                    .sum::<f64>()
                    .sqrt()
            };
            let mut rho = 0.0;
            for _ in 0..40 {
                let before = norm(&s);
                s.iterate();
                rho = norm(&s) / before;
                // Renormalised (power iteration) so that f32 does not overflow.
                let scale = T::c(1.0 / norm(&s));
                s.x.iter_mut().flatten().for_each(|v| *v = *v * scale);
            }
            eprintln!(
                "C13 {}: 3D Kt∆ = {kt}: growth per iteration {rho:.3}",
                T::NAME
            );
            assert!(rho >= 19.0 / 8.0 * (1.0 - 1e-6), "Kt∆ = {kt}: {rho}");
        }
    }

    both!(c13_fe_jacobi_diverges_with_sign_flips);
}

/// F24: forcing after 100 steps (voxels at ≥ 10 % of max φ become sources of the original
/// source's density) changes the converged field by more than 1 % and keeps it finite.
fn f24_forcing_changes_the_converged_field(p: Precision) {
    let (_, coef) = homogeneous(17, 0.5, 0.9);
    let steady = RdeConfig::default().steady(tight(p), 100_000);
    let plain = run(p, &coef, &steady);
    let early = run(p, &coef, &RdeConfig::default().frames(100, 0)).phi;
    let mut forced = coef.clone();
    let q = coef.source.iter().cloned().fold(0.0, f64::max);
    let n = forced.force(&early, 0.1, q).unwrap();
    assert!(n > 1, "{n} voxels forced");
    let forced = forced.with_initial(early);
    let s = run(p, &forced, &steady);
    assert!(s.converged() && s.phi.iter().all(|x| x.is_finite()));
    let d = rel_l2(&s.phi, &plain.phi);
    eprintln!("F24 {p:?}: {n} voxels forced, converged field differs by {d:.3e} (L2)");
    assert!(d > 1e-2, "{d:.3e}");
}

both!(f24_forcing_changes_the_converged_field);

// ---------------------------------------------------------------------------------------
// F25: Perona–Malik selective diffusion (thesis Eqs 3.1–3.5).

mod pm_tests {
    use super::super::pm::{Conductance, PeronaMalik, Phantom, PmConfig};
    use super::*;

    both!(
        f25_clamped_source_floods_the_connected_region,
        f25_flood_time_scales_as_one_over_the_edge_conductance,
    );

    fn pm_run<T: Real>(ph: &Phantom, cfg: &PmConfig, cap: usize, tol: f64) -> (Vec<f64>, usize) {
        let mut pm = PeronaMalik::<T>::new(ph.grid, &ph.data, &ph.sources, cfg).unwrap();
        let level = cfg.source_level;
        let mut its = 0;
        while its < cap {
            let change = pm.step();
            its += 1;
            // Maximum principle (λ ≤ 1/(2d), C ≤ 1): 0 ≤ E ≤ E_src at every step.
            let (lo, hi) = pm
                .energy()
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
                    (l.min(x.f()), h.max(x.f()))
                });
            assert!(lo >= 0.0 && hi <= level, "step {its}: E in [{lo}, {hi}]");
            if change <= tol {
                break;
            }
        }
        (pm.energy().iter().map(|x| x.f()).collect(), its)
    }

    /// F25a: Neumann walls, clamped source. Through a one-voxel gap both chambers of a 16² box
    /// reach E_src (to 10⁻⁶ in f64; 2·10⁻⁴ in f32, where the increments through the gap fall
    /// below half an ulp of E_src and the field creeps by ulps: measured 8.6·10⁻⁵ at every cap
    /// from 3·10⁴ to 4·10⁵ iterations, 5.0·10⁻⁴ at 2·10⁴); with the gap closed (wall contrast
    /// 1, σ = 0.05, thesis Eq 3.2: C = e⁻⁴⁰⁰) the far chamber stays below 10⁻¹⁰⁰ while the
    /// near one fills. The cap, 10⁵ iterations, is 1.6× the 63 531 the f64 gap run needs to
    /// stop (2026-12-07; the f32 run, which never stops, took 20 s at the former 4·10⁵).
    fn f25_clamped_source_floods_the_connected_region(p: Precision) {
        match p {
            Precision::F64 => f25a::<f64>(1e-6),
            Precision::F32 => f25a::<f32>(2e-4),
        }
    }

    fn f25a<T: Real>(tol: f64) {
        let cfg = PmConfig {
            conductance: Conductance::Exponential,
            sigma: 0.05,
            lambda: None,
            source_level: 2.5,
        };
        let open = Phantom::gap_edge(16, 1).unwrap();
        let (e, its) = pm_run::<T>(&open, &cfg, 100_000, 1e-12);
        let wall = |idx: usize| open.data[idx] > 0.5;
        let err = (0..e.len())
            .filter(|&i| !wall(i))
            .map(|i| (e[i] / cfg.source_level - 1.0).abs())
            .fold(0.0, f64::max);
        eprintln!("F25a gap: {its} iterations, max|E/E_src − 1| = {err:.3e}");
        assert!(err <= tol, "{err}");
        let closed = Phantom::gap_edge(16, 0).unwrap();
        let (e, its) = pm_run::<T>(&closed, &cfg, 100_000, 1e-12);
        let near = (0..e.len())
            .filter(|&i| closed.inside[i])
            .map(|i| (e[i] / cfg.source_level - 1.0).abs())
            .fold(0.0, f64::max);
        let far = (0..e.len())
            .filter(|&i| !closed.inside[i] && !wall(i))
            .map(|i| e[i])
            .fold(0.0, f64::max);
        eprintln!("F25a closed: {its} iterations, near {near:.3e}, far max E {far:.3e}");
        assert!(near <= tol, "{near}");
        assert!(far < 1e-100, "{far}");
    }

    /// F25b: flood time (the mean E of the far chamber reaches E_src/2) across an edge of
    /// contrast 1 scales as 1/C(1) over σ ∈ {0.05, 0.1, 0.2} within 20 % (thesis Eq 3.3, an
    /// 4×3(×3) two-chamber phantom fed by a clamped plane, so the edge is the bottleneck).
    fn f25_flood_time_scales_as_one_over_the_edge_conductance(p: Precision) {
        match p {
            Precision::F64 => f25b::<f64>(),
            Precision::F32 => f25b::<f32>(),
        }
    }

    fn f25b<T: Real>() {
        let ph = Phantom::step_edge(4, 3).unwrap();
        let mut products = Vec::new();
        for sigma in [0.05, 0.1, 0.2] {
            let cfg = PmConfig {
                conductance: Conductance::Rational,
                sigma,
                lambda: None,
                source_level: 1.0,
            };
            let mut pm = PeronaMalik::<T>::new(ph.grid, &ph.data, &ph.sources, &cfg).unwrap();
            let c_edge = Conductance::Rational.eval(1.0, sigma);
            assert!((pm.face_conductance(0, 1) - c_edge).abs() <= 1e-6 * c_edge);
            let far: Vec<usize> = (0..ph.grid.len()).filter(|&i| !ph.inside[i]).collect();
            let mut t = None;
            for it in 1..=1_000_000 {
                pm.step();
                let mean = far.iter().map(|&i| pm.energy()[i].f()).sum::<f64>() / far.len() as f64;
                if mean >= 0.5 {
                    t = Some(it);
                    break;
                }
            }
            let t = t.expect("flooded within the cap") as f64;
            eprintln!(
                "F25b σ = {sigma}: C = {c_edge:.4e}, t = {t}, t·C = {:.2}",
                t * c_edge
            );
            products.push(t * c_edge);
        }
        let (lo, hi) = products
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, h), &x| (l.min(x), h.max(x)));
        assert!(hi / lo <= 1.2, "t·C = {products:?}");
    }

    /// λ above thesis Eq 3.5's 1/6 (3D) is a typed error naming `lambda`; σ ≤ 0 names `sigma`.
    #[test]
    fn pm_bad_input_names_the_parameter() {
        let ph = Phantom::gap_edge(8, 1).unwrap();
        let err =
            |cfg: PmConfig| match PeronaMalik::<f64>::new(ph.grid, &ph.data, &ph.sources, &cfg) {
                Err(SolverError::StepAboveBound { name, .. })
                | Err(SolverError::BadParameter { name, .. }) => name,
                other => panic!("{other:?}"),
            };
        let base = PmConfig::default();
        assert_eq!(
            err(PmConfig {
                lambda: Some(0.17),
                ..base
            }),
            "lambda"
        );
        assert_eq!(err(PmConfig { sigma: 0.0, ..base }), "sigma");
        assert!(
            PeronaMalik::<f64>::new(
                ph.grid,
                &ph.data,
                &ph.sources,
                &PmConfig {
                    lambda: Some(1.0 / 6.0),
                    ..base
                }
            )
            .is_ok()
        );
        assert!(PeronaMalik::<f64>::new(ph.grid, &ph.data, &[[8, 0, 0]], &base).is_err());
    }
}

/// Thesis-style images (`dvr`): the closed forms of thesis Eqs 1.12–1.14 on axis columns.
mod dvr_images {
    use super::super::dvr::{ThesisStyle, render};
    use crate::{Grid, SolverError};

    fn style(axis: usize, opacity: f64, gain: f64) -> ThesisStyle {
        ThesisStyle {
            axis,
            opacity,
            low: [0.2, 0.4, 0.6],
            high: [1.0, 0.5, 0.0],
            gain,
            log_decades: None,
        }
    }

    /// Uniform data S along every column of n voxels: α_out = 1 − (1 − α)ⁿ (Eq 1.14's
    /// recursion summed) and C = c(S)·α_out (Eq 1.13), for each ray axis.
    #[test]
    fn dvr_uniform_column_closed_form() {
        let grid = Grid::new([5, 7, 9], 1.0).unwrap();
        let s = 0.6;
        let data = vec![s; grid.len()];
        let phi = vec![0.0; grid.len()];
        for axis in 0..3 {
            let st = style(axis, 0.3, 1.0);
            let img = render(&grid, &data, &phi, &st).unwrap();
            let n = grid.n[axis] as i32;
            let a1 = 1.0 - (-0.3 * s).exp();
            let a_out = 1.0 - (1.0 - a1).powi(n);
            assert_eq!(img.w * img.h, grid.len() / grid.n[axis]);
            for p in 0..img.w * img.h {
                assert!((img.alpha[p] - a_out).abs() < 1e-14, "axis {axis}");
                for ch in 0..3 {
                    let tf = st.low[ch] + (st.high[ch] - st.low[ch]) * s;
                    assert!((img.rgb[ch][p] - tf * a_out).abs() < 1e-14);
                }
            }
        }
    }

    /// One emitting voxel behind one absorbing voxel: green = (1 − α_front)·Q_e∆x; in a
    /// transparent volume the emission of a column sums (Eq 1.12 with τ = 1).
    #[test]
    fn dvr_emission_attenuated_and_summed() {
        let grid = Grid::new([3, 3, 3], 1.0).unwrap();
        let mut data = vec![0.0; grid.len()];
        let mut phi = vec![0.0; grid.len()];
        data[grid.index(0, 1, 1)] = 1.0;
        phi[grid.index(2, 1, 1)] = 2.0;
        phi[grid.index(1, 0, 0)] = 1.0;
        phi[grid.index(2, 0, 0)] = 0.5;
        let st = style(0, 0.7, 0.8);
        let img = render(&grid, &data, &phi, &st).unwrap();
        let front = 1.0 - (-0.7f64).exp();
        // Pixel (y = 1, z = 1): the absorber then the peak emitter.
        let p = img.w + 1;
        let expect = front * st.high[1] + (1.0 - front) * 0.8;
        assert!((img.rgb[1][p] - expect).abs() < 1e-14);
        // Pixel (0, 0): transparent, emitters at φ/max = 0.5 and 0.25.
        assert!((img.rgb[1][0] - 0.8 * 0.75).abs() < 1e-14);
        assert_eq!(img.rgb[0][0], 0.0);
        assert_eq!(img.alpha[0], 0.0);
        // Logarithmic weight over 2 decades: 1 + log10(x)/2.
        let log = ThesisStyle {
            log_decades: Some(2.0),
            ..st
        };
        let img = render(&grid, &data, &phi, &log).unwrap();
        let w = |x: f64| 1.0 + x.log10() / 2.0;
        assert!((img.rgb[1][0] - 0.8 * (w(0.5) + w(0.25))).abs() < 1e-14);
    }

    #[test]
    fn dvr_bad_input_names_the_parameter() {
        let grid = Grid::new([3, 3, 3], 1.0).unwrap();
        let ok = vec![0.5; grid.len()];
        let st = ThesisStyle::default();
        let name = |r: Result<_, SolverError>| match r {
            Err(SolverError::BadParameter { name, .. }) => name.to_string(),
            Err(SolverError::FieldSize { field, .. }) => field.to_string(),
            Err(SolverError::FieldValue { field, .. }) => field.to_string(),
            other => format!("{other:?}"),
        };
        assert_eq!(name(render(&grid, &ok[1..], &ok, &st)), "data");
        assert_eq!(name(render(&grid, &ok, &ok[1..], &st)), "phi");
        let mut bad = ok.clone();
        bad[4] = 1.5;
        assert_eq!(name(render(&grid, &bad, &ok, &st)), "data");
        bad[4] = f64::NAN;
        assert_eq!(name(render(&grid, &ok, &bad, &st)), "phi");
        let axis = ThesisStyle { axis: 3, ..st };
        assert_eq!(name(render(&grid, &ok, &ok, &axis)), "axis");
        let op = ThesisStyle {
            opacity: -1.0,
            ..st
        };
        assert_eq!(name(render(&grid, &ok, &ok, &op)), "opacity");
        let dec = ThesisStyle {
            log_decades: Some(0.0),
            ..st
        };
        assert_eq!(name(render(&grid, &ok, &ok, &dec)), "log_decades");
    }
}
