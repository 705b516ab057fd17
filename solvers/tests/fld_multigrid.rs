//! FAS multigrid (`solvers::fld::multigrid`) against red-black SOR (FLD Algorithm 1): the
//! same fixed point, grid-independent cycle counts, typed stall status, method names.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use solvers::fld::multigrid::{CoarseD, CoarseOp, CoarseSigma, CpuMultigrid, Cycle, MgConfig};
use solvers::fld::{Boundary, CpuFld, FldConfig, FluxLimiter};
use solvers::{Medium, Stop, scenes};

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

fn mg(medium: &Medium<f64>, cfg: &FldConfig, mgc: &MgConfig) -> solvers::fld::FldSolution<f64> {
    CpuMultigrid::new(medium, &Boundary::Zero, cfg, mgc)
        .unwrap()
        .solve()
}

/// Acceptance 1, point source (CI-sized): both solvers converged to R̄/j̄ < 1e-10 agree to
/// 1e-6 relative L2, for CDA and every limiter, V- and F-cycles (17³: 15-voxel interior,
/// coarse levels of 9 and 5 voxels, vertex-coarsened). Measured before the per-axis
/// coarsening: 10 cycles vs 112–117 SOR iterations (ω = 1.8), rel L2 ≈ 2e-10.
#[test]
fn multigrid_and_sor_reach_the_same_solution_on_the_point_source() {
    let (ps, _) = scenes::point_source::<f64>(17, 10.0, 0.9).unwrap();
    for lim in FluxLimiter::ALL {
        let cfg = FldConfig::fld(lim)
            .with_tolerance(1e-10)
            .with_max_iterations(200_000)
            .with_omega(1.8);
        let sor = CpuFld::new(&ps, &Boundary::Zero, &cfg).unwrap().solve();
        assert_eq!(sor.stop, Stop::Converged, "{lim}: SOR");
        let cfg_mg = cfg.clone().with_max_iterations(200);
        for cycle in [Cycle::V, Cycle::F] {
            let m = mg(
                &ps,
                &cfg_mg,
                &MgConfig {
                    cycle,
                    ..MgConfig::default()
                },
            );
            assert_eq!(
                m.stop,
                Stop::Converged,
                "{lim} {cycle:?}: {:?}",
                m.residuals()
            );
            let e = rel_l2(&m.phi, &sor.phi);
            assert!(e < 1e-6, "{lim} {cycle:?}: rel L2 {e:.2e}");
            assert!(
                m.steps * 5 < sor.steps,
                "{lim} {cycle:?}: {} cycles",
                m.steps
            );
        }
    }
}

/// Acceptance 1 on FLD Fig 4's cloud in vacuum (24³, CI-sized): for CDA and every limiter,
/// multigrid converged to R̄/j̄ < 1e-9 agrees with SOR converged to 1e-10 to 1e-6 relative L2.
/// Possible for CDA since the harmonic coarse σ. Measured: CDA 21 cycles vs 118 SOR
/// iterations (ω = 1.8), rel L2 6.5·10⁻¹²; every limiter 31 cycles vs 394–410, 8–10·10⁻¹¹.
#[test]
fn multigrid_and_sor_reach_the_same_solution_on_the_fig4_cloud() {
    let cloud = scenes::vacuum_cloud::<f64>(24, 3).unwrap();
    for lim in FluxLimiter::ALL {
        let cfg = FldConfig::fld(lim)
            .with_tolerance(1e-10)
            .with_max_iterations(200_000)
            .with_omega(1.8);
        let sor = CpuFld::new(&cloud, &Boundary::Zero, &cfg).unwrap().solve();
        assert_eq!(sor.stop, Stop::Converged, "{lim}: SOR");
        let m = mg(
            &cloud,
            &cfg.clone().with_tolerance(1e-9).with_max_iterations(200),
            &MgConfig::default(),
        );
        let e = rel_l2(&m.phi, &sor.phi);
        eprintln!(
            "Fig 4 cloud {lim}: {} in {} cycles vs SOR {} iterations, rel L2 {e:.2e}",
            m.stop, m.steps, sor.steps
        );
        assert_eq!(m.stop, Stop::Converged, "{lim}: {:?}", m.residuals());
        assert!(e < 1e-6, "{lim}: rel L2 {e:.2e}");
    }
}

/// Converged is never wrong, stalls are typed, and the harmonic coarse σ
/// ([`CoarseSigma::Harmonic`]) makes CDA converge where vacuum or contrast broke it. Must
/// converge to R̄/j̄ < 1e-9 and agree with SOR to 1e-6: albedo 1 (both), and for CDA the Fig 4
/// cloud and white noise with 30 % and 95 % vacuum (measured with the defaults of
/// 2026-12-06, F cycles with Krylov acceleration and the Picard fallback: 13, 19 and 7
/// cycles; plain V cycles 21, 52 and 11; with the arithmetic coarse σ all three diverged,
/// ×2–10⁴ per cycle, and ended `Stalled`); FLD-LP converges on the cloud (19 cycles; plain V
/// 31) and may stall on the noises (it converges on both now, in 42 and 31 cycles; plain V
/// cycles stalled at R̄/j̄ 2.4·10⁻⁴ and 2.2·10⁻²): a stall must end `Stalled` or `Cap`
/// above the tolerance.
#[test]
fn converged_is_never_wrong_and_stalls_are_typed() {
    let (a1, _) = scenes::point_source::<f64>(17, 10.0, 1.0).unwrap();
    let cloud = scenes::vacuum_cloud::<f64>(24, 3).unwrap();
    let noise = scenes::random_heterogeneous::<f64>([19, 16, 21], 7, 0.3).unwrap();
    let vac = scenes::random_heterogeneous::<f64>([17, 17, 17], 11, 0.95).unwrap();
    let tol = 1e-9;
    for (name, medium, must_cda, must_lp) in [
        ("albedo 1", &a1, true, true),
        ("Fig 4 cloud", &cloud, true, true),
        ("white noise 30 % vacuum", &noise, true, false),
        ("white noise 95 % vacuum", &vac, true, false),
    ] {
        for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
            let cfg = FldConfig::fld(lim)
                .with_tolerance(tol)
                .with_max_iterations(100);
            let m = mg(medium, &cfg, &MgConfig::default());
            eprintln!(
                "{name} {lim}: {} after {} cycles, R/j {:.2e}",
                m.stop,
                m.steps,
                m.final_residual()
            );
            assert_ne!(m.stop, Stop::NonFinite, "{name} {lim}");
            if (lim == FluxLimiter::Cda && must_cda) || (lim != FluxLimiter::Cda && must_lp) {
                assert_eq!(m.stop, Stop::Converged, "{name} {lim}: {:?}", m.residuals());
            }
            if m.stop == Stop::Converged {
                assert!(m.final_residual() < tol);
                let sor = CpuFld::new(
                    medium,
                    &Boundary::Zero,
                    &cfg.clone().with_max_iterations(200_000).with_omega(1.8),
                )
                .unwrap()
                .solve();
                if sor.stop == Stop::Converged {
                    let e = rel_l2(&m.phi, &sor.phi);
                    assert!(e < 1e-6, "{name} {lim}: rel L2 {e:.2e}");
                }
            } else {
                assert!(m.final_residual() >= tol, "{name} {lim}: {}", m.stop);
            }
        }
    }
    // Why the harmonic σ is the default: with the arithmetic one CDA on the cloud diverges.
    let cfg = FldConfig::fld(FluxLimiter::Cda)
        .with_tolerance(tol)
        .with_max_iterations(100);
    let arithmetic = MgConfig {
        coarse_sigma: CoarseSigma::Arithmetic,
        ..MgConfig::default()
    };
    let m = mg(&cloud, &cfg, &arithmetic);
    eprintln!(
        "Fig 4 cloud cda, arithmetic coarse sigma: {} after {} cycles",
        m.stop, m.steps
    );
    assert_ne!(m.stop, Stop::Converged);
    assert!(m.final_residual() > 1.0, "{:?}", m.residuals());
}

/// Grid independence at CI size (issue 15 acceptance 2, n = 17 and 33 only): V(2,2)
/// cycles to R̄/j̄ < 1e-6 on the point source (τ = 10, albedo 0.9 and 1) differ by at most
/// 25 % between n = 17 and 33, for CDA and FLD-LP, and each is at most 10. Measured
/// (2026-12-06, with the error-estimate stop; identical with either coarse σ on this
/// homogeneous medium): CDA 6, 7 (albedo 0.9) and 7, 7 (albedo 1), FLD-LP 7, 7 and 9, 10.
/// With the defaults of 2026-12-06 (F cycles, Krylov depth 3): CDA 5, 5 and 5, 5, FLD-LP 6,
/// 7 and 7, 7.
/// Before the per-axis vertex/cell coarsening CDA took 6 and 8 (33 %) and FLD-LP stalled at
/// albedo 1 with vertex injection. Also pins that both coarse-layer treatments converge there.
#[test]
fn cycles_to_1e6_do_not_grow_with_n_on_the_point_source() {
    for ext in [false, true] {
        let mgc = MgConfig {
            extrapolated_layer: ext,
            ..MgConfig::default()
        };
        for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
            for albedo in [0.9, 1.0] {
                let cycles: Vec<usize> = [17, 33]
                    .iter()
                    .map(|&n| {
                        let (m, _) = scenes::point_source::<f64>(n, 10.0, albedo).unwrap();
                        let cfg = FldConfig::fld(lim)
                            .with_tolerance(1e-6)
                            .with_max_iterations(60);
                        let s = mg(&m, &cfg, &mgc);
                        assert_eq!(s.stop, Stop::Converged, "{lim} a={albedo} n={n} ext={ext}");
                        assert!(s.final_residual() < 1e-6);
                        s.steps
                    })
                    .collect();
                eprintln!("{lim} albedo {albedo} ext={ext}: cycles at n = 17, 33: {cycles:?}");
                let (lo, hi) = (cycles[0].min(cycles[1]), cycles[0].max(cycles[1]));
                assert!(hi <= 10, "{lim} a={albedo}: {cycles:?}");
                assert!(
                    (hi as f64) <= 1.25 * lo as f64,
                    "{lim} a={albedo} ext={ext}: {cycles:?}"
                );
            }
        }
    }
}

/// Local relaxation around the point source ([`MgConfig::local_sweeps`], default 8) keeps
/// FLD-LP's cycles to R̄/j̄ < 1e-6 on the point source (τ = 4, albedo 0.5, `point_source`'s
/// Fig 5 medium) flat over n = 31, 63, 127 (within 25 %), cuts them to at most 75 % of the
/// cycles without it at n = 127, and both reach the same φ (rel. L2 < 1e-5, both at the
/// tolerance). Without it the cycles grow with n (the one-voxel source holds j = 1/Δl³ and
/// R ≈ 1/(σr) near it grows as Δl shrinks). Measured (2026-12-07, 2-vCPU AMD EPYC Zen 5):
/// without 8, 9, 10 cycles, with 6, 6, 6; the box has half-width 4, 8, 16 voxels. With the
/// full-multigrid start (both sides, 2026-12-07, later): 8, 9, 10 and 5, 5, 5.
#[test]
fn local_relaxation_keeps_the_point_source_flat_in_n() {
    let off = MgConfig {
        local_sweeps: 0,
        ..MgConfig::default()
    };
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning)
        .with_tolerance(1e-6)
        .with_max_iterations(60);
    let mut with = Vec::new();
    for n in [31, 63, 127] {
        let (m, _) = scenes::point_source::<f64>(n, 4.0, 0.5).unwrap();
        let (a, b) = (mg(&m, &cfg, &off), mg(&m, &cfg, &MgConfig::default()));
        let e = rel_l2(&b.phi, &a.phi);
        eprintln!(
            "n = {n}: {} cycles without, {} with local relaxation, rel L2 {e:.2e}",
            a.steps, b.steps
        );
        assert_eq!(a.stop, Stop::Converged, "n = {n} without");
        assert_eq!(b.stop, Stop::Converged, "n = {n} with");
        assert!(e < 1e-5, "n = {n}: rel L2 {e:.2e}");
        if n == 127 {
            assert!(
                b.steps as f64 <= 0.75 * a.steps as f64,
                "{} cycles with against {}",
                b.steps,
                a.steps
            );
        }
        with.push(b.steps);
    }
    let (lo, hi) = (with.iter().min().unwrap(), with.iter().max().unwrap());
    assert!(*hi as f64 <= 1.25 * *lo as f64, "cycles with: {with:?}");
}

/// The full-multigrid start ([`MgConfig::full_multigrid`], default on) on the point source
/// (33³, τ = 10, albedo 0.9), CDA and FLD-LP, to R̄/j̄ < 1e-9: the residual after the first
/// cycle is at most a fifth of the one from φ = 0, the solve needs no more cycles, and both
/// reach the same φ (rel. L2 < 1e-6). A nested-iteration guess carries the coarse levels'
/// solution of the smooth part, so the first cycle starts near the discretisation error.
/// Measured (2026-12-07, 2-vCPU AMD EPYC Zen 5): first residual CDA 3.9·10⁻³ → 3.5·10⁻⁴,
/// FLD-LP 8.2·10⁻³ → 7.6·10⁻⁴; cycles 6 → 5 and 7 → 6.
#[test]
fn the_full_multigrid_start_cuts_the_first_residual() {
    let (m, _) = scenes::point_source::<f64>(33, 10.0, 0.9).unwrap();
    let off = MgConfig {
        full_multigrid: false,
        ..MgConfig::default()
    };
    for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
        let cfg = FldConfig::fld(lim)
            .with_tolerance(1e-9)
            .with_max_iterations(60);
        let (a, b) = (mg(&m, &cfg, &off), mg(&m, &cfg, &MgConfig::default()));
        let (ra, rb) = (a.residuals()[0], b.residuals()[0]);
        let e = rel_l2(&b.phi, &a.phi);
        eprintln!(
            "{lim}: first residual {ra:.2e} from 0, {rb:.2e} with FMG; cycles {} and {}; \
             rel L2 {e:.2e}",
            a.steps, b.steps
        );
        assert_eq!(a.stop, Stop::Converged, "{lim} from 0");
        assert_eq!(b.stop, Stop::Converged, "{lim} with FMG");
        assert!(
            rb <= 0.2 * ra,
            "{lim}: first residual {rb:.2e} against {ra:.2e}"
        );
        assert!(
            b.steps <= a.steps,
            "{lim}: {} cycles against {}",
            b.steps,
            a.steps
        );
        assert!(e < 1e-6, "{lim}: rel L2 {e:.2e}");
    }
}

#[test]
fn method_names_select_multigrid() {
    for spec in [
        "cda:mg",
        "fld:lp:mg",
        "fld:mg",
        "fld:larsen2:mg",
        "FLD:SUM:MG",
    ] {
        let m = solvers::method::parse(spec).unwrap();
        assert!(m.name().ends_with(":mg"), "{spec} -> {}", m.name());
        assert_eq!(solvers::method::parse(&m.name()).unwrap().name(), m.name());
    }
    assert_eq!(
        solvers::method::parse("fld:mg").unwrap().name(),
        "fld:lp:mg"
    );
    assert!(solvers::method::parse("cda:bogus").is_err());
    assert!(solvers::method::parse("fld:bogus:mg").is_err());
    // `:auto` selects `Solver::Auto`; one solver per method.
    for (spec, name) in [("cda:auto", "cda:auto"), ("FLD:Auto", "fld:lp:auto")] {
        assert_eq!(solvers::method::parse(spec).unwrap().name(), name);
    }
    assert!(solvers::method::parse("fld:lp:mg:auto").is_err());
    // The multigrid parameters, each refused without `:mg`/`:auto` and out of its range
    // with an error naming it: the Krylov depth (an integer 0–16), the smoother's ω (in
    // (0, 2)), the local relaxation's sweeps (an integer 0–64) and the full-multigrid start
    // (0 or 1).
    use solvers::method::{Params, parse_with};
    // (parameter, what its errors name, accepted (method, value), refused ones)
    type Case<'a> = (&'a str, &'a str, [(&'a str, f64); 3], &'a [(&'a str, f64)]);
    let cases: [Case; 4] = [
        (
            "krylov",
            "krylov",
            [("cda:mg", 0.0), ("fld:lp:mg", 16.0), ("cda:auto", 2.0)],
            &[
                ("cda", 3.0),
                ("cda:mg", 2.5),
                ("cda:mg", 17.0),
                ("fld:mg", -1.0),
            ],
        ),
        (
            "smoother_omega",
            "smoother",
            [("cda:mg", 1.0), ("fld:lp:auto", 1.9), ("cda:mg", 1.2)],
            &[
                ("fld:lp", 1.2),
                ("cda:mg", 0.0),
                ("cda:mg", 2.0),
                ("fld:mg", f64::NAN),
            ],
        ),
        (
            "local_sweeps",
            "local_sweeps",
            [("cda:mg", 0.0), ("fld:lp:auto", 64.0), ("fld:mg", 8.0)],
            &[
                ("fld:lp", 8.0),
                ("cda:mg", 1.5),
                ("cda:mg", 65.0),
                ("fld:mg", -1.0),
                ("fld:mg", f64::INFINITY),
            ],
        ),
        (
            "full_multigrid",
            "full_multigrid",
            [("cda:mg", 0.0), ("fld:lp:auto", 1.0), ("fld:mg", 1.0)],
            &[
                ("cda", 1.0),
                ("cda:mg", 0.5),
                ("cda:mg", 2.0),
                ("fld:mg", -1.0),
            ],
        ),
    ];
    for (param, named, good, bad) in cases {
        let with = |spec: &str, v: f64| parse_with(spec, &Params::none().with(param, v));
        for (spec, v) in good {
            assert!(with(spec, v).is_ok(), "{spec} {param}={v}");
        }
        for &(spec, v) in bad {
            let e = with(spec, v)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains(named), "{spec} {param}={v}: {e:?}");
        }
    }
}

/// The four media of the Krylov and smoother-ω tests: the Fig 4 cloud (24³) and white
/// noise with 30 % vacuum (19 × 16 × 21), where vacuum slows the plain cycle, and the
/// homogeneous point source (33³, τ = 10, albedo 0.9), with the limiter each runs.
fn vacuum_and_point_cases() -> Vec<(&'static str, Medium<f64>, FluxLimiter)> {
    let cloud = scenes::vacuum_cloud::<f64>(24, 3).unwrap();
    let noise = scenes::random_heterogeneous::<f64>([19, 16, 21], 7, 0.3).unwrap();
    let (ps, _) = scenes::point_source::<f64>(33, 10.0, 0.9).unwrap();
    vec![
        ("Fig 4 cloud", cloud, FluxLimiter::Cda),
        ("white noise 30 % vacuum", noise, FluxLimiter::Cda),
        ("point source", ps.clone(), FluxLimiter::Cda),
        ("point source", ps, FluxLimiter::LevermorePomraning),
    ]
}

/// Runs `a` and `b` on every case of [`vacuum_and_point_cases`] to R̄/j̄ < 1e-9 and checks
/// that both converge to the same φ (rel. L2 < 1e-6) and that `b` needs at most `ratio[i]`
/// of `a`'s cycles on case i.
fn compare_cycles(a: &MgConfig, b: &MgConfig, what: &str, ratio: [f64; 4]) {
    for ((name, medium, lim), ratio) in vacuum_and_point_cases().iter().zip(ratio) {
        let cfg = FldConfig::fld(*lim)
            .with_tolerance(1e-9)
            .with_max_iterations(200);
        let (sa, sb) = (mg(medium, &cfg, a), mg(medium, &cfg, b));
        let e = rel_l2(&sb.phi, &sa.phi);
        eprintln!(
            "{name} {lim}: {} cycles ({}), {what} {} cycles ({}), rel L2 {e:.2e}",
            sa.steps, sa.stop, sb.steps, sb.stop
        );
        assert_eq!(sa.stop, Stop::Converged, "{name} {lim} before {what}");
        assert_eq!(sb.stop, Stop::Converged, "{name} {lim} {what}");
        assert!(e < 1e-6, "{name} {lim}: rel L2 {e:.2e}");
        assert!(
            sb.steps as f64 <= ratio * sa.steps as f64,
            "{name} {lim}: {} cycles with {what} against {}",
            sb.steps,
            sa.steps
        );
    }
}

/// Krylov acceleration ([`MgConfig::krylov`], default 3) against plain cycles, both with the
/// default smoother: where vacuum makes the plain cycle slow (CDA on the Fig 4 cloud and on
/// white noise with 30 % vacuum) the accelerated one needs at most 75 % (cloud) and 60 %
/// (noise) of its cycles, on the homogeneous point source no more, and both reach the same φ.
/// Measured (2026-12-07, F cycles, smoother ω = 1.2): cloud 14 → 10 cycles, noise 37 → 17,
/// point source CDA 7 → 6 and FLD-LP 10 → 8 (8 → 7 with the local relaxation around the
/// source, 2026-12-07, later); rel. L2 between the two 5.0·10⁻¹⁰ at most.
/// With ω = 1 (Gauss–Seidel, the default until 2026-12-07): 20 → 13, 52 → 19, 9 → 7, 11 → 9.
/// Both arms start from φ = 0 (no full-multigrid start), so the test measures the Krylov
/// history alone; with the FMG start on both (2026-12-07, later) the cycles are 14 → 11,
/// 37 → 17, 6 → 5, 7 → 6.
#[test]
fn krylov_acceleration_cuts_cycles_where_vacuum_slows_the_plain_cycle() {
    let accelerated = MgConfig {
        full_multigrid: false,
        ..MgConfig::default()
    };
    let plain = MgConfig {
        krylov: 0,
        ..accelerated.clone()
    };
    compare_cycles(&plain, &accelerated, "krylov 3", [0.75, 0.6, 1.0, 1.0]);
}

/// The smoother's ω ([`MgConfig::smoother_omega`], default 1.2) against Gauss–Seidel
/// smoothing (ω = 1), both Krylov-accelerated: over-relaxed red-black smoothing needs at most
/// 80 % (cloud) and 90 % (noise) of the cycles on the vacuum media and no more on the point
/// source, to the same φ. Measured (2026-12-07): cloud 13 → 10, noise 19 → 17, point source
/// CDA 7 → 6, FLD-LP 9 → 8 (8 → 7 with the local relaxation around the source). With the
/// full-multigrid start (2026-12-07, later): cloud 14 → 11, noise 19 → 17, point source CDA
/// 6 → 5, FLD-LP 7 → 6.
#[test]
fn over_relaxed_smoothing_cuts_cycles() {
    let gauss_seidel = MgConfig {
        smoother_omega: 1.0,
        ..MgConfig::default()
    };
    compare_cycles(
        &gauss_seidel,
        &MgConfig::default(),
        "omega 1.2",
        [0.8, 0.9, 1.0, 1.0],
    );
}

/// The coarse D of FLD ([`CoarseD`]) on shell_core (18³: a dense core, σt = 100, inside a
/// thin shell, σt = 8, with an enclosed vacuum gap; emission in every medium voxel): the FAS
/// coarse levels (`Recomputed`) stall FLD-LP, the Picard ones (`Restricted`) converge, and
/// the default (`Auto`: FAS, then Picard once it stalls) converges to the same φ as SOR and
/// as `Restricted` (rel. L2 < 1e-6). Measured (2026-12-06, tolerance 1e-9, F cycles,
/// Krylov depth 3): `Recomputed` stalled at R̄/j̄ 3.9 after 9 cycles; `Restricted` converged
/// in 40 cycles, `Auto` in 31, SOR (ω = 1.8) in 110042 iterations; rel. L2 3.8·10⁻¹⁰ and
/// 2.8·10⁻¹⁰. (V cycles: stalled at 2.7 after 14; 42, 45.)
#[test]
fn the_picard_coarse_levels_take_over_where_the_fas_stalls() {
    use solvers::scene::datasets::ShellCore;
    use solvers::scene::generators::Generator;
    let shell = ShellCore {
        n: 18,
        ..ShellCore::default()
    }
    .generate()
    .unwrap();
    // Emission in every medium voxel (the dataset is lit by a light instead).
    let emission = shell
        .sigma_t
        .iter()
        .map(|&s| if s > 0.0 { 1.0 } else { 0.0 })
        .collect();
    let medium = Medium::new(shell.grid, shell.sigma_t, shell.albedo, emission).unwrap();
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning)
        .with_tolerance(1e-9)
        .with_max_iterations(200);
    let run = |coarse_d| {
        mg(
            &medium,
            &cfg,
            &MgConfig {
                coarse_d,
                ..MgConfig::default()
            },
        )
    };
    let (fas, picard, auto) = (
        run(CoarseD::Recomputed),
        run(CoarseD::Restricted),
        run(CoarseD::Auto),
    );
    let sor = CpuFld::new(
        &medium,
        &Boundary::Zero,
        &cfg.clone().with_max_iterations(200_000).with_omega(1.8),
    )
    .unwrap()
    .solve();
    eprintln!(
        "shell_core lp: FAS {} after {} ({:.1e}), Picard {} after {}, Auto {} after {}, SOR {} after {}",
        fas.stop,
        fas.steps,
        fas.final_residual(),
        picard.stop,
        picard.steps,
        auto.stop,
        auto.steps,
        sor.stop,
        sor.steps
    );
    assert_eq!(fas.stop, Stop::Stalled);
    assert!(fas.final_residual() > 1e-6);
    for (name, s) in [("Restricted", &picard), ("Auto", &auto)] {
        assert_eq!(s.stop, Stop::Converged, "{name}: {:?}", s.residuals());
    }
    assert_eq!(sor.stop, Stop::Converged);
    let (e_sor, e_picard) = (rel_l2(&auto.phi, &sor.phi), rel_l2(&auto.phi, &picard.phi));
    eprintln!("Auto vs SOR {e_sor:.2e}, vs Restricted {e_picard:.2e}");
    assert!(
        e_sor < 1e-6 && e_picard < 1e-6,
        "{e_sor:.2e} {e_picard:.2e}"
    );
}

/// `CoarseOp::Galerkin` (CDA): on the vacuum cloud at 31³ (vertex- then cell-coarsened
/// axes, so 27-point and 125-point coarse stencils) its cycles reach SOR's solution to 1e-6
/// relative L2, and plain F(2, 2) cycles need at least a quarter fewer than the
/// rediscretised coarse levels (measured: 13 against 20 to 1e-6); FLD refuses it (its
/// operator changes with φ).
#[test]
fn galerkin_coarse_levels_cut_cda_cycles_on_the_vacuum_cloud() {
    let cloud = scenes::vacuum_cloud::<f64>(31, 1).unwrap();
    let cfg = FldConfig::fld(FluxLimiter::Cda)
        .with_tolerance(1e-9)
        .with_max_iterations(200_000)
        .with_omega(1.8);
    let sor = CpuFld::new(&cloud, &Boundary::Zero, &cfg).unwrap().solve();
    assert_eq!(sor.stop, Stop::Converged);
    let cfg_mg = cfg.clone().with_max_iterations(200);
    let galerkin = MgConfig {
        coarse_op: CoarseOp::Galerkin,
        ..MgConfig::default()
    };
    let m = mg(&cloud, &cfg_mg, &galerkin);
    assert_eq!(m.stop, Stop::Converged, "{:?}", m.residuals());
    let e = rel_l2(&m.phi, &sor.phi);
    assert!(e < 1e-6, "Galerkin vs SOR: rel L2 {e:.2e}");
    let plain = |coarse_op| {
        let cfg = cfg_mg.clone().with_tolerance(1e-6);
        let mgc = MgConfig {
            coarse_op,
            krylov: 0,
            ..MgConfig::default()
        };
        let s = mg(&cloud, &cfg, &mgc);
        assert_eq!(
            s.stop,
            Stop::Converged,
            "{coarse_op:?}: {:?}",
            s.residuals()
        );
        s.steps
    };
    let (g, r) = (plain(CoarseOp::Galerkin), plain(CoarseOp::Rediscretised));
    assert!(4 * g <= 3 * r, "Galerkin {g} cycles, rediscretised {r}");
    let fld = FldConfig::fld(FluxLimiter::LevermorePomraning);
    let err = CpuMultigrid::new(&cloud, &Boundary::Zero, &fld, &galerkin).unwrap_err();
    assert!(
        matches!(err, solvers::SolverError::Unsupported(_)),
        "{err:?}"
    );
}

/// `FldTrace::seconds_to_tolerance` (issue 15's like-for-like time to R̄/j̄ < tolerance):
/// recorded at the first step whose R̄/j̄ is below the tolerance, within the solve's seconds,
/// strictly before the end where multigrid's error estimate kept it cycling past that step
/// (it does here: SOR stops at that step, multigrid one or more cycles later), and absent when
/// the tolerance was never reached.
#[test]
fn seconds_to_tolerance_marks_the_first_step_below_the_tolerance() {
    let (ps, _) = scenes::point_source::<f64>(33, 4.0, 0.5).unwrap();
    let tol = 1e-6;
    let cfg = FldConfig::cda()
        .with_tolerance(tol)
        .with_max_iterations(5000);
    let sor = CpuFld::new(&ps, &Boundary::Zero, &cfg).unwrap().solve();
    let m = mg(&ps, &cfg, &MgConfig::default());
    for (name, s) in [("sor", &sor), ("multigrid", &m)] {
        assert_eq!(s.stop, Stop::Converged, "{name}");
        let first = s.residuals().iter().position(|&r| r < tol).unwrap() + 1;
        let t = s.trace.seconds_to_tolerance.unwrap();
        assert!(t > 0.0 && t <= s.seconds, "{name}: {t} of {} s", s.seconds);
        if name == "sor" {
            assert_eq!(
                first, s.steps,
                "SOR stops at the first step below the tolerance"
            );
        } else {
            // Multigrid went on for its error estimate: the mark sits before the end.
            assert!(first < s.steps, "multigrid: {:?}", s.residuals());
            assert!(t < s.seconds, "multigrid: step {first} of {}", s.steps);
        }
    }
    let capped = mg(
        &ps,
        &cfg.clone().with_tolerance(1e-14).with_max_iterations(1),
        &MgConfig::default(),
    );
    assert_eq!(capped.stop, Stop::Cap);
    assert_eq!(capped.trace.seconds_to_tolerance, None);
}

/// `Solver::Auto` (issue 15 item 4, the measured default of `point_source`): each branch of
/// its rule on a case that takes it, with φ bit for bit that of the solver it hands to.
/// * A small grid SOR finishes within [`AUTO_SOR_SWEEPS`] (17³ CDA point source, ω = 1.8):
///   SOR's φ, `sor`.
/// * A small grid SOR does not finish (33³ FLD-LP point source at ω = 1, Gauss–Seidel, which
///   needs far more than 200 sweeps to 10⁻⁸): `sor>multigrid`, multigrid's φ, cycles and
///   work units plus the 200 sweeps.
/// * An FLD grid of 63³ ([`auto_multigrid_voxels`]): `multigrid` from the start.
/// * A medium where both stall (white noise with 95 % vacuum, FLD-LP: multigrid `stalled` at
///   R̄/j̄ 1.4·10⁻² after 46 cycles, measured 2026-12-06): `sor>multigrid>sor`, never
///   `converged`, SOR's typed stop.
/// * Where multigrid cannot run (Galerkin coarse levels with a non-constant limiter,
///   `Unsupported`; the Marshak face): SOR's φ.
#[test]
fn auto_takes_each_branch_of_its_rule() {
    use solvers::fld::{AUTO_SOR_SWEEPS, Solver, VacuumFace, auto_multigrid_voxels, solve_with};
    use solvers::{Backend, Precision};
    let cpu = Backend::Cpu(Precision::F64);
    let run = |m: &Medium<f64>, cfg: &FldConfig, s: &Solver| {
        solve_with(&cpu, m, &Boundary::Zero, cfg, s, |_, _| {}).unwrap()
    };
    let auto = Solver::Auto(MgConfig::default());
    let multigrid = Solver::Multigrid(MgConfig::default());

    let (small, _) = scenes::point_source::<f64>(17, 10.0, 0.9).unwrap();
    let cfg = FldConfig::fld(FluxLimiter::Cda)
        .with_tolerance(1e-6)
        .with_omega(1.8);
    let (a, s) = (run(&small, &cfg, &auto), run(&small, &cfg, &Solver::Sor));
    assert_eq!(a.trace.solver, "sor");
    assert!(a.converged() && a.steps <= AUTO_SOR_SWEEPS, "{}", a.steps);
    assert_eq!(a.phi, s.phi);

    let (mid, _) = scenes::point_source::<f64>(33, 10.0, 0.9).unwrap();
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning)
        .with_tolerance(1e-8)
        .with_omega(1.0)
        .with_max_iterations(20_000);
    let (a, m) = (run(&mid, &cfg, &auto), run(&mid, &cfg, &multigrid));
    assert_eq!(a.trace.solver, "sor>multigrid");
    assert!(a.converged() && m.converged());
    assert_eq!(a.phi, m.phi);
    assert_eq!(a.steps, m.steps);
    assert_eq!(
        a.trace.work_units,
        m.trace.work_units + AUTO_SOR_SWEEPS as f64
    );
    assert!(a.seconds > a.trace.seconds_to_tolerance.unwrap());

    let (big, _) = scenes::point_source::<f64>(63, 10.0, 0.9).unwrap();
    assert!(big.grid.len() >= auto_multigrid_voxels(FluxLimiter::LevermorePomraning));
    assert!(big.grid.len() < auto_multigrid_voxels(FluxLimiter::Cda));
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning).with_tolerance(1e-6);
    let (a, m) = (run(&big, &cfg, &auto), run(&big, &cfg, &multigrid));
    assert_eq!(a.trace.solver, "multigrid");
    assert_eq!(a.phi, m.phi);

    let vac = scenes::random_heterogeneous::<f64>([19, 16, 21], 7, 0.95).unwrap();
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning)
        .with_tolerance(1e-6)
        .with_max_iterations(300);
    let a = run(&vac, &cfg, &auto);
    eprintln!(
        "95 % vacuum, FLD-LP: {} {} after {} steps, R/j {:.2e}",
        a.trace.solver,
        a.stop,
        a.steps,
        a.final_residual()
    );
    assert_eq!(a.trace.solver, "sor>multigrid>sor");
    assert_ne!(a.stop, Stop::Converged);
    assert!(a.final_residual() >= 1e-6);
    assert_eq!(a.phi, run(&vac, &cfg, &Solver::Sor).phi);

    let galerkin = Solver::Auto(MgConfig {
        coarse_op: CoarseOp::Galerkin,
        ..MgConfig::default()
    });
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning).with_tolerance(1e-6);
    let (a, s) = (run(&big, &cfg, &galerkin), run(&big, &cfg, &Solver::Sor));
    assert_eq!((a.trace.solver.as_str(), &a.phi), ("sor", &s.phi));
    let mut marshak = FldConfig::fld(FluxLimiter::Cda).with_tolerance(1e-6);
    marshak.vacuum_face = VacuumFace::Marshak;
    let (a, s) = (
        run(&small, &marshak, &auto),
        run(&small, &marshak, &Solver::Sor),
    );
    assert_eq!((a.trace.solver.as_str(), &a.phi), ("sor", &s.phi));
}

/// Where the point source's growth of FLD-LP cycles with n comes from (issue 15 acceptance
/// 2): its one emitting voxel (j = 1/Δl³) sharpens with n, so the discrete problems do not
/// converge to one continuous problem. The same unit power over a ball of radius 0.1
/// (`scenes::ball_source`, a radius of 3.3 voxels at n = 33) is a fixed problem, and there
/// multigrid's cycles to R̄/j̄ < 10⁻⁶ (τ = 4, albedo 0.9, defaults) differ by at most 25 %
/// between n = 33 and 65 for CDA and FLD-LP (measured: CDA 5, 5; FLD-LP 7, 7; with the
/// full-multigrid start, 2026-12-07: 4, 4 and 6, 6). Over n = 31,
/// 63, 127, 255 (`multigrid_scaling --n 31,63,127,255 --sor-max-n 1 --problems
/// point_source,ball_source --albedo 0.9`, 2026-12-06): ball CDA 5, 5, 5, 4 and FLD-LP 7, 7,
/// 8, 8 cycles; one-voxel source CDA 5, 5, 5, 5 and FLD-LP 8, 9, 11, 13.
#[test]
fn cycles_do_not_grow_with_n_for_a_source_of_fixed_size() {
    for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
        let cycles: Vec<usize> = [33, 65]
            .iter()
            .map(|&n| {
                let m = scenes::ball_source::<f64>(n, 4.0, 0.9, 0.1).unwrap();
                let power: f64 = m.emission.iter().sum::<f64>() * m.grid.dl.powi(3);
                assert!((power - 1.0).abs() < 1e-12, "n = {n}: power {power}");
                let cfg = FldConfig::fld(lim)
                    .with_tolerance(1e-6)
                    .with_max_iterations(100);
                let s = mg(&m, &cfg, &MgConfig::default());
                assert_eq!(s.stop, Stop::Converged, "{lim} n = {n}");
                s.steps
            })
            .collect();
        eprintln!("ball source {lim}: cycles {cycles:?} at n = 33, 65");
        let (lo, hi) = (cycles[0].min(cycles[1]), cycles[0].max(cycles[1]));
        assert!(4 * hi <= 5 * lo, "{lim}: {cycles:?}");
    }
    assert!(scenes::ball_source::<f64>(33, 4.0, 0.9, 0.0).is_err());
    assert!(scenes::cloud_in_thin_medium::<f64>(17, 3, -1.0).is_err());
}

/// Where the Fig 4 cloud's growth of FLD-LP cycles with n comes from (issue 15 acceptance
/// 2; measured in the `multigrid` module docs, "Why the cloud's FLD-LP cycles grow"): in
/// vacuum D tends to φ/|∇φ| and peaks at a critical point of φ, a peak the grid samples ever
/// closer as n grows, up to 1/(3σ_ε). Pinned at n = 31 and 63: the peak more than doubles;
/// with σ_ε = 1 it is lower, and the cycles stay within issue 15's 25 % and are fewer than
/// the default's at n = 63. Also: a φ of the wrong length is an error, and a constant φ in
/// a medium without sources (∇φ = 0, R = 0) gives D = F(0)/σ = 1/(3σ), σ floored at σ_ε.
#[test]
fn the_cloud_s_fld_cycles_follow_the_peak_of_d_in_its_vacuum() {
    let lp = FluxLimiter::LevermorePomraning;
    let field = solvers::fld::multigrid::diffusion_field::<f64>;
    let interior_max =
        |m: &Medium<f64>, d: &[f64]| m.grid.interior().map(|p| d[p]).fold(0.0f64, f64::max);
    let mut peaks = Vec::new();
    let mut cycles = Vec::new();
    for n in [31, 63] {
        let m = scenes::vacuum_cloud::<f64>(n, 1).unwrap();
        let mut row = Vec::new();
        for eps in [None, Some(1.0)] {
            let mut cfg = FldConfig::fld(lp)
                .with_tolerance(1e-6)
                .with_max_iterations(100);
            cfg.sigma_eps = eps;
            let s = mg(&m, &cfg, &MgConfig::default());
            assert_eq!(s.stop, Stop::Converged, "n = {n}, σ_ε {eps:?}");
            let d = field(&m, &Boundary::Zero, &s.phi, &cfg).unwrap();
            row.push((interior_max(&m, &d), s.steps));
        }
        peaks.push([row[0].0, row[1].0]);
        cycles.push([row[0].1, row[1].1]);
    }
    eprintln!("cloud FLD-LP, n = 31, 63: peak D (default, σ_ε = 1) {peaks:?}, cycles {cycles:?}");
    assert!(peaks[1][0] > 2.0 * peaks[0][0], "peak D {peaks:?}");
    assert!(peaks[1][1] < peaks[1][0], "peak D {peaks:?}");
    let (lo, hi) = (
        cycles[0][1].min(cycles[1][1]),
        cycles[0][1].max(cycles[1][1]),
    );
    assert!(4 * hi <= 5 * lo, "capped cycles {cycles:?}");
    assert!(cycles[1][1] < cycles[1][0], "cycles {cycles:?}");
    let m = scenes::vacuum_cloud::<f64>(9, 1).unwrap();
    let cfg = FldConfig::fld(lp);
    assert!(field(&m, &Boundary::Zero, &[1.0; 5], &cfg).is_err());
    let dark = Medium::new(
        m.grid,
        m.sigma_t.clone(),
        m.albedo.clone(),
        vec![0.0; m.grid.len()],
    )
    .unwrap();
    let d = field(&dark, &Boundary::Zero, &vec![1.0; m.grid.len()], &cfg).unwrap();
    for (p, (&d, &s)) in d.iter().zip(&m.sigma_t).enumerate() {
        let want = 1.0 / (3.0 * s.max(1e-3 / m.grid.extent()));
        assert!(
            (d - want).abs() <= 1e-12 * want,
            "voxel {p}: D {d}, want {want}"
        );
    }
}
