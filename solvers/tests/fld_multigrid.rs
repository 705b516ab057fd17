//! FAS multigrid (`solvers::fld::multigrid`) against red-black SOR (FLD Algorithm 1): the
//! same fixed point, grid-independent cycle counts, typed stall status, method names.

use solvers::fld::multigrid::{CpuMultigrid, Cycle, MgConfig};
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

/// Acceptance 1 (CI-sized): both solvers converged to R̄/j̄ < 1e-10 agree to 1e-6 relative
/// L2, for CDA and every limiter, on the point source (odd grid, 2^k − 1 interior) and the
/// Fig 4 cloud (even grid, 22-voxel interior: odd coarse levels, vacuum around the cloud).
#[test]
fn multigrid_and_sor_reach_the_same_solution() {
    let (ps, _) = scenes::point_source::<f64>(17, 10.0, 0.9).unwrap();
    let cloud = scenes::vacuum_cloud::<f64>(24, 3).unwrap();
    for (name, medium) in [("point source 17³", &ps), ("Fig 4 cloud 24³", &cloud)] {
        for lim in FluxLimiter::ALL {
            let cfg = FldConfig::fld(lim)
                .with_tolerance(1e-10)
                .with_max_iterations(200_000)
                .with_omega(1.8);
            let sor = CpuFld::new(medium, &Boundary::Zero, &cfg).unwrap().solve();
            assert_eq!(sor.stop, Stop::Converged, "{name} {lim}: SOR");
            let cfg_mg = cfg.clone().with_max_iterations(200);
            for cycle in [Cycle::V, Cycle::F] {
                let m = mg(
                    medium,
                    &cfg_mg,
                    &MgConfig {
                        cycle,
                        ..MgConfig::default()
                    },
                );
                assert_eq!(
                    m.stop,
                    Stop::Converged,
                    "{name} {lim} {cycle:?}: multigrid residuals {:?}",
                    m.residuals()
                );
                let e = rel_l2(&m.phi, &sor.phi);
                assert!(
                    e < 1e-6,
                    "{name} {lim} {cycle:?}: rel L2 {e:.2e} after {} cycles vs {} SOR iterations",
                    m.steps,
                    sor.steps
                );
                eprintln!(
                    "{name} {lim} {cycle:?}: {} cycles vs {} SOR iterations, rel L2 {e:.2e}",
                    m.steps, sor.steps
                );
            }
        }
    }
}

/// Acceptance 2 (modest n): V-cycles to R̄/j̄ < 1e-6 vary by ≤ 25 % over n = 17, 33, 65 for
/// CDA and FLD-LP on the point source (SOR's iterations grow ~n^1.7 over the same range).
#[test]
fn cycles_are_grid_independent() {
    for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
        let cycles: Vec<usize> = [17, 33, 65]
            .iter()
            .map(|&n| {
                let (m, _) = scenes::point_source::<f64>(n, 10.0, 0.9).unwrap();
                let cfg = FldConfig::fld(lim)
                    .with_tolerance(1e-6)
                    .with_max_iterations(200);
                let s = mg(&m, &cfg, &MgConfig::default());
                assert_eq!(
                    s.stop,
                    Stop::Converged,
                    "{lim} n = {n}: {:?}",
                    s.residuals()
                );
                s.steps
            })
            .collect();
        let (lo, hi) = (
            *cycles.iter().min().unwrap() as f64,
            *cycles.iter().max().unwrap() as f64,
        );
        eprintln!("{lim}: cycles {cycles:?}");
        assert!(
            hi <= 1.25 * lo,
            "{lim}: cycles over n = 17, 33, 65: {cycles:?}"
        );
    }
}

/// Albedo 1 and 10⁴ contrast converge to SOR's answer; the 95 %-vacuum white noise either
/// converges for real or says `Stalled`/`Cap`, never a wrong `Converged`.
#[test]
fn hard_media_converge_or_report_a_stall() {
    let (ps, _) = scenes::point_source::<f64>(17, 10.0, 1.0).unwrap();
    let noise = scenes::random_heterogeneous::<f64>([19, 16, 21], 7, 0.3).unwrap();
    for (name, medium) in [("albedo 1", &ps), ("white noise 30 % vacuum", &noise)] {
        for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
            let cfg = FldConfig::fld(lim)
                .with_tolerance(1e-9)
                .with_max_iterations(300);
            let m = mg(medium, &cfg, &MgConfig::default());
            assert_eq!(m.stop, Stop::Converged, "{name} {lim}: {:?}", m.residuals());
            let sor = CpuFld::new(
                medium,
                &Boundary::Zero,
                &cfg.clone().with_max_iterations(400_000).with_omega(1.8),
            )
            .unwrap()
            .solve();
            if sor.stop == Stop::Converged {
                let e = rel_l2(&m.phi, &sor.phi);
                assert!(e < 1e-5, "{name} {lim}: rel L2 {e:.2e}");
            }
        }
    }
    let vac = scenes::random_heterogeneous::<f64>([17, 17, 17], 11, 0.95).unwrap();
    let cfg = FldConfig::fld(FluxLimiter::LevermorePomraning)
        .with_tolerance(1e-9)
        .with_max_iterations(60);
    let m = mg(&vac, &cfg, &MgConfig::default());
    eprintln!(
        "95 % vacuum: {} after {} cycles, residuals {:?}",
        m.stop,
        m.steps,
        m.residuals()
    );
    assert!(m.phi.iter().all(|x| x.is_finite() && *x >= 0.0));
    match m.stop {
        Stop::Converged => assert!(m.final_residual() < 1e-9),
        Stop::Stalled | Stop::Cap => assert!(m.final_residual() >= 1e-9),
        Stop::NonFinite => panic!("non-finite residual"),
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
}
