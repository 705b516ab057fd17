//! Lattice-Boltzmann conformance: one test body per case on CPU-f32, CPU-f64 and the GPU
//! (issue "Lattice-Boltzmann lighting", acceptance 1–2), property tests on random media,
//! the paper-HG energy error, and the physical-unit fluence against the path tracer.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::on_backend;

use proptest::prelude::*;
use reference::pathtracer::{PathSettings, fluence};
use solvers::lbm::{
    self, Absorption, HgNormalisation, Injection, LbmConfig, LbmSolution, Resolve, SigmaMapping,
};
use solvers::scene::{Light, Phase, Sampler, Scene};
use solvers::{Backend, Grid, Medium, Precision, scenes};
use std::sync::OnceLock;

conformance!(
    energy_balance_without_absorption,
    mirror_symmetric_under_an_axial_beam,
    finite_and_non_negative_on_a_hostile_medium,
    fluence_matches_the_path_tracer_in_order_of_magnitude,
);

fn solve(b: &Backend<'_>, m: &Medium<f64>, inj: &Injection, cfg: &LbmConfig) -> LbmSolution<f64> {
    lbm::solve(b, m, inj, cfg, |_, _| {}).unwrap()
}

/// A beam along (0.48, 0.6, −0.64), irradiance 1.
fn oblique() -> Injection {
    Injection::directional([0.48, 0.6, -0.64], 1.0, Resolve::FluxPreserving).unwrap()
}

/// Steady state of a conservative medium (albedo 1) with an oblique beam and a point
/// emitter: injected = outflow per step. f64 within 10⁻⁶ relative (acceptance 1); f32 (CPU
/// and GPU reductions) within 10⁻³.
fn energy_balance_without_absorption(b: &Backend<'_>) {
    let grid = Grid::cube(14, 1.0).unwrap();
    let mut m = Medium::homogeneous(grid, 5.0, 1.0).unwrap();
    m.emission[grid.index(4, 9, 6)] = 100.0;
    let (cfg, bound) = match b.precision() {
        Precision::F64 => (LbmConfig::default().with_tolerance(1e-12), 1e-6),
        Precision::F32 => (LbmConfig::default(), 1e-3),
    };
    let sol = solve(b, &m, &oblique(), &cfg);
    assert!(sol.converged(), "{b}: {:?} after {}", sol.stop, sol.steps);
    let r = sol.last().unwrap();
    let resid = (r.injected - r.outflow).abs() / r.injected;
    eprintln!(
        "{b}: steady after {} steps, injected {:.8e}, outflow {:.8e}, relative residual {resid:.2e}",
        sol.steps, r.injected, r.outflow
    );
    assert!(resid < bound, "{b}: residual {resid:.3e} ≥ {bound:.0e}");
}

/// A beam along +z on a cube (odd size, isotropic HG-free medium with a centred emitter):
/// φ is invariant under the x and y mirrors and the x↔y swap, to rounding. An indexing error
/// in a kernel breaks this at O(1).
fn mirror_symmetric_under_an_axial_beam(b: &Backend<'_>) {
    let n = 11;
    let grid = Grid::cube(n, 1.0).unwrap();
    let mut m = Medium::homogeneous(grid, 4.0, 0.8).unwrap();
    m.emission[grid.index(5, 5, 3)] = 10.0;
    let inj = Injection::directional([0.0, 0.0, 1.0], 2.0, Resolve::FluxPreserving).unwrap();
    for cfg in [
        LbmConfig::default().fixed_steps(30),
        LbmConfig::default()
            .with_phase(
                Phase::HenyeyGreenstein { g: 0.6 },
                HgNormalisation::Renormalised,
            )
            .with_absorption(Absorption::Loss)
            .fixed_steps(30),
    ] {
        let sol = solve(b, &m, &inj, &cfg);
        let max = sol.phi.iter().cloned().fold(0.0, f64::max);
        let tol = match b.precision() {
            Precision::F32 => 1e-5,
            Precision::F64 => 1e-12,
        } * max;
        let at = |i: usize, j: usize, k: usize| sol.phi[grid.index(i, j, k)];
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let v = at(i, j, k);
                    for (what, w) in [
                        ("x mirror", at(n - 1 - i, j, k)),
                        ("y mirror", at(i, n - 1 - j, k)),
                        ("x-y swap", at(j, i, k)),
                    ] {
                        assert!(
                            (v - w).abs() <= tol,
                            "{b}: {what} at ({i},{j},{k}): {v:.8e} vs {w:.8e}"
                        );
                    }
                }
            }
        }
        assert!(
            at(5, 5, 1) > at(5, 5, n - 2),
            "{b}: beam not attenuated along +z"
        );
    }
}

/// The white-noise medium with empty and saturated sites (σΔl = 10³), sparse emission, an
/// oblique beam, HG g = 0.9 renormalised and g = −0.9 paper, both absorption models:
/// φ and ρ finite and ≥ 0 after 60 steps.
fn finite_and_non_negative_on_a_hostile_medium(b: &Backend<'_>) {
    let m = hostile(7, [13, 10, 12]);
    for cfg in [
        LbmConfig::default().with_phase(
            Phase::HenyeyGreenstein { g: 0.9 },
            HgNormalisation::Renormalised,
        ),
        LbmConfig::default()
            .with_phase(Phase::HenyeyGreenstein { g: -0.9 }, HgNormalisation::Paper)
            .with_absorption(Absorption::Loss)
            .with_sigma_mapping(SigmaMapping::Linear),
    ] {
        let sol = solve(b, &m, &oblique(), &cfg.clone().fixed_steps(60));
        assert_eq!(sol.steps, 60);
        for (what, f) in [("phi", &sol.phi), ("rho", &sol.trace.rho)] {
            if let Some((i, v)) = f
                .iter()
                .enumerate()
                .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
            {
                panic!("{b} {cfg:?}: {what}[{i}] = {v}");
            }
        }
        assert!(sol.phi.iter().any(|v| *v > 0.0));
    }
}

/// White noise (30 % vacuum) plus 10 % saturated and 10 % more empty sites.
fn hostile(seed: u64, n: [usize; 3]) -> Medium<f64> {
    let mut m = scenes::random_heterogeneous::<f64>(n, seed, 0.3).unwrap();
    let dl = m.grid.dl;
    for (k, s) in m.sigma_t.iter_mut().enumerate() {
        let h = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ seed;
        match h % 10 {
            0 => *s = 1e3 / dl,
            1 => *s = 0.0,
            _ => {}
        }
    }
    m
}

/// The scene of the path-tracer comparison: a 16³ homogeneous cube of extent 1, σt = 8
/// (σΔl = 0.5), albedo `albedo`, lit along +z with irradiance 1.
fn beam_scene(albedo: f64) -> Scene {
    let grid = Grid::cube(16, 1.0).unwrap();
    Scene {
        interpolation: Default::default(),
        medium: Medium::homogeneous(grid, 8.0, albedo).unwrap(),
        phase: Phase::Isotropic,
        lights: vec![Light::directional([0.0, 0.0, 1.0], 1.0).unwrap()],
        camera: None,
        sampler: Sampler { spp: 1, seed: 3 },
    }
}

/// Per z-layer mean of a field.
fn layers(g: &Grid, f: &[f64]) -> Vec<f64> {
    let per = g.n[0] * g.n[1];
    f.chunks(per)
        .map(|c| c.iter().sum::<f64>() / per as f64)
        .collect()
}

/// Path-tracer layer means of `beam_scene(albedo)`, computed once per albedo.
fn pt_layers(albedo: f64) -> &'static (Vec<f64>, Vec<f64>) {
    static CACHE: OnceLock<[(Vec<f64>, Vec<f64>); 2]> = OnceLock::new();
    let c = CACHE.get_or_init(|| {
        [0.9, 0.5].map(|a| {
            let s = beam_scene(a);
            let f = fluence(&s, &PathSettings::new(200_000, 11)).unwrap();
            let g = s.medium.grid;
            let se: Vec<f64> = layers(
                &g,
                &f.total.stderr.iter().map(|e| e * e).collect::<Vec<_>>(),
            )
            .iter()
            .map(|v| (v / (g.n[0] * g.n[1]) as f64).sqrt())
            .collect();
            (layers(&g, &f.total.mean), se)
        })
    });
    if albedo == 0.9 { &c[0] } else { &c[1] }
}

/// LB/PT ratio of the layer means (min, max) and the relative error of the volume mean.
fn errors_vs_pt(b: &Backend<'_>, albedo: f64, absorption: Absorption) -> ((f64, f64), f64) {
    let s = beam_scene(albedo);
    let cfg = LbmConfig::default().with_absorption(absorption);
    let sol = lbm::solve_scene(b, &s, &cfg).unwrap();
    assert!(sol.converged(), "{b}: {:?}", sol.stop);
    let lb = layers(&s.medium.grid, &sol.phi);
    let (pt, _) = pt_layers(albedo);
    let ratios = lb
        .iter()
        .zip(pt)
        .map(|(a, p)| a / p)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r), hi.max(r))
        });
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    (ratios, (mean(&lb) - mean(pt)) / mean(pt))
}

/// Physical units: LB fluence of a beam-lit homogeneous cube (τ = 8 deep) against the path
/// tracer's track-length fluence of the same `Scene` (2·10⁵ paths, layer standard errors
/// < 1 %), per z-layer mean. This is an order-of-magnitude check by design (see the `lbm`
/// module docs: LB's diagonal links and lattice mean free path make it diffuse ~24 % too far):
/// measured on every backend, the loss model's layer means are 1.10–2.17× the path tracer's
/// (the ratio grows with depth), volume means +19 % (albedo 0.9) and
/// +20 % (albedo 0.5). Bounds: every layer ratio in [0.4, 2.5], volume mean within 25 %. The
/// paper's delay model does not absorb at steady state: at albedo 0.5 it is 66× too bright in
/// the last layer — the loss variant is the one comparable with transport.
fn fluence_matches_the_path_tracer_in_order_of_magnitude(b: &Backend<'_>) {
    let (layer9, vol9) = errors_vs_pt(b, 0.9, Absorption::Loss);
    let (layer5, vol5) = errors_vs_pt(b, 0.5, Absorption::Loss);
    let (layer5p, vol5p) = errors_vs_pt(b, 0.5, Absorption::PaperDelay);
    eprintln!(
        "{b}: LB/PT layer ratio range and volume-mean error: albedo 0.9 loss: {layer9:.3?}, {vol9:+.3}; \
         albedo 0.5 loss: {layer5:.3?}, {vol5:+.3}; albedo 0.5 paper delay: {layer5p:.3?}, {vol5p:+.3}"
    );
    let (_, se) = pt_layers(0.9);
    assert!(se.iter().all(|e| e.is_finite()));
    for (what, (lo, hi), vol) in [("albedo 0.9", layer9, vol9), ("albedo 0.5", layer5, vol5)] {
        assert!(
            lo >= 0.4 && hi <= 2.5,
            "{b}: {what}: layer ratios {lo}..{hi}"
        );
        assert!(vol.abs() < 0.25, "{b}: {what}: volume mean error {vol}");
    }
    assert!(
        layer5p.1 > 10.0,
        "{b}: paper delay model absorbs? {layer5p:?}"
    );
}

/// GPU vs CPU-f32 after the same number of steps (acceptance 2): max relative difference of
/// φ ≤ 10⁻⁴ where φ > 10⁻⁶ max φ, on the hostile medium with emission, isotropic and HG, both
/// absorption models; the checkpoint totals agree to 10⁻⁴ too.
#[test]
fn gpu_agrees_with_cpu_f32_after_the_same_steps() {
    on_backend("gpu", "gpu_agrees_with_cpu_f32_after_the_same_steps", |b| {
        let m = hostile(3, [17, 14, 19]);
        let cases = [
            ("isotropic, paper", LbmConfig::default()),
            (
                "HG 0.7 renormalised, loss",
                LbmConfig::default()
                    .with_phase(
                        Phase::HenyeyGreenstein { g: 0.7 },
                        HgNormalisation::Renormalised,
                    )
                    .with_absorption(Absorption::Loss),
            ),
        ];
        for (what, cfg) in cases {
            let cfg = cfg.fixed_steps(64);
            let cpu = solve(&Backend::Cpu(Precision::F32), &m, &oblique(), &cfg);
            let gpu = solve(b, &m, &oblique(), &cfg);
            assert_eq!(cpu.steps, gpu.steps);
            let max = cpu.phi.iter().cloned().fold(0.0, f64::max);
            let (d, idx) = gpu
                .phi
                .iter()
                .zip(&cpu.phi)
                .enumerate()
                .filter(|(_, (_, c))| **c > 1e-6 * max)
                .map(|(i, (g, c))| ((g - c).abs() / c, i))
                .fold((0.0, 0), |a, x| if x.0 > a.0 { x } else { a });
            let (tc, tg) = (
                cpu.last().unwrap().total_density,
                gpu.last().unwrap().total_density,
            );
            let dt = (tc - tg).abs() / tc;
            eprintln!(
                "{what}: GPU vs CPU-f32 after {} steps: max rel diff of φ {d:.2e} (site {idx}), total density {dt:.2e}",
                cpu.steps
            );
            assert!(
                d <= 1e-4,
                "{what}: site {idx}: {} vs {}: {d:.3e}",
                gpu.phi[idx],
                cpu.phi[idx]
            );
            assert!(dt <= 1e-4, "{what}: totals {tg} vs {tc}");
        }
    });
}

/// The paper's HG scaling creates or destroys energy at each scattering: in a conservative
/// cube lit by a beam the steady state's outflow differs from the injection. Measured
/// relative energy error (outflow − injected)/injected is printed for g = 0.5 and 0.85;
/// it must exceed 10⁻³ for the paper's scaling, and stay below 10⁻⁶ renormalised (f64).
#[test]
fn paper_hg_energy_error_at_steady_state() {
    let grid = Grid::cube(14, 1.0).unwrap();
    let m = Medium::homogeneous(grid, 6.0, 1.0).unwrap();
    let inj = Injection::directional([0.0, 0.0, 1.0], 1.0, Resolve::FluxPreserving).unwrap();
    for g in [0.5, 0.85] {
        let mut errs = [0.0; 2];
        for (k, hg) in [HgNormalisation::Paper, HgNormalisation::Renormalised]
            .into_iter()
            .enumerate()
        {
            let cfg = LbmConfig::default()
                .with_phase(Phase::HenyeyGreenstein { g }, hg)
                .with_tolerance(1e-12);
            let sol = solve(&Backend::Cpu(Precision::F64), &m, &inj, &cfg);
            assert!(sol.converged(), "g={g} {hg:?}: {:?}", sol.stop);
            let r = sol.last().unwrap();
            errs[k] = (r.outflow - r.injected) / r.injected;
            eprintln!(
                "g = {g}, {hg:?}: steady after {} steps, (outflow − injected)/injected = {:+.4e}, total density {:.4e}",
                sol.steps, errs[k], r.total_density
            );
        }
        assert!(errs[0].abs() > 1e-3, "g={g}: paper error {}", errs[0]);
        assert!(
            errs[1].abs() < 1e-6,
            "g={g}: renormalised error {}",
            errs[1]
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Acceptance 1 on random media (random seed, vacuum fraction, g, size), CPU f32 and
    /// f64: φ ≥ 0 and finite everywhere after 25 steps, including empty and saturated sites.
    #[test]
    fn random_media_stay_finite_and_non_negative(
        seed in 0u64..1000,
        vacuum in 0.0..1.0f64,
        g in -0.95..0.95f64,
        n in 4usize..9,
        loss in proptest::bool::ANY,
        paper_hg in proptest::bool::ANY,
    ) {
        let m = hostile(seed, [n, n + 1, n + 2]);
        let mut m2 = m.clone();
        for (k, s) in m2.sigma_t.iter_mut().enumerate() {
            if ((k as u64 * 2_654_435_761) % 1000) as f64 / 1000.0 < vacuum {
                *s = 0.0;
            }
        }
        let hg = if paper_hg { HgNormalisation::Paper } else { HgNormalisation::Renormalised };
        let cfg = LbmConfig::default()
            .with_phase(Phase::HenyeyGreenstein { g }, hg)
            .with_absorption(if loss { Absorption::Loss } else { Absorption::PaperDelay })
            .fixed_steps(25);
        for p in [Precision::F32, Precision::F64] {
            let sol = solve(&Backend::Cpu(p), &m2, &oblique(), &cfg);
            prop_assert!(sol.phi.iter().all(|v| v.is_finite() && *v >= 0.0));
            prop_assert!(sol.trace.history.iter().all(|r| r.total_density.is_finite() && r.outflow >= 0.0));
        }
    }
}
