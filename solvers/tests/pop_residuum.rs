//! T24 (spec pop.md §6): POP's isotropic residuum (Sec 5.4) against the full propagation on
//! the Fig 8 setting: a homogeneous 4 m box of 16³ voxels (Δx = 0.25 m), σs = 1.07 m⁻¹,
//! albedo 0.999, g = 0.95, a unit constant environment by 64 Fibonacci ordinates (D11
//! prefilter), 16³ ordinate grids, f64, full run to R/P_inj < 10⁻⁶.
//!
//! Compared: the paper's m′ = 20 followed by 20 isotropic iterations on a 32³ grid, and
//! m′ from Eq 10 (ε_a = 0.1) followed by isotropic iterations to the same tolerance. Metrics:
//! volume-mean φ, relative L2 of φ and of an orthographic emission–absorption image (camera
//! on +z: pixel = Σ_k σs·L_acc·e^{−σt(4 − z_k)}·Δl, L_acc the Eq 8 accumulator towards the
//! camera), the power in flight at the switch and dropped at the end, and the speed-up in cell
//! updates (the CPU-time ratio is printed; the machine is shared, so it is not asserted).

#![allow(clippy::unwrap_used)]

use solvers::pop::residuum::{self, IsoResiduum, Residuum, ResiduumSolution};
use solvers::pop::{
    CpuPop, Observer, Ordinate, PopConfig, PopMedium, Prefilter, PropagationGrid,
    environment_ordinates,
};
use solvers::{Grid, Medium};

const N: usize = 16;
const SIGMA_S: f64 = 1.07;
const ALBEDO: f64 = 0.999;
const G: f64 = 0.95;

fn setting() -> (PopMedium, Vec<Ordinate>) {
    let grid = Grid::cube(N, 4.0).unwrap();
    let medium = Medium::homogeneous(grid, SIGMA_S / ALBEDO, ALBEDO).unwrap();
    let pm = PopMedium::new(&[medium], &[G]).unwrap();
    let o = environment_ordinates(|_| 1.0, 64, Prefilter::Voronoi, 32).unwrap();
    (pm, o)
}

fn config(res: Residuum) -> PopConfig {
    PopConfig {
        observer: Some(Observer::Direction([0.0, 0.0, 1.0])),
        residuum: res,
        ..PopConfig::new::<f64>(N)
    }
}

fn image(sol: &ResiduumSolution<f64>, grid: &Grid) -> Vec<f64> {
    let l = sol.l_acc_on(grid);
    let sigma_t = SIGMA_S / ALBEDO;
    let mut img = vec![0.0; N * N];
    for k in 0..N {
        let z = grid.center(0, 0, k)[2];
        let att = (-sigma_t * (4.0 - z)).exp();
        for j in 0..N {
            for i in 0..N {
                img[i + N * j] += SIGMA_S * l[grid.index(i, j, k)] * att * grid.dl;
            }
        }
    }
    img
}

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn t24_fig8_residuum_vs_full() {
    let (pm, o) = setting();
    let grid = pm.grid;
    let run = |res: Residuum| {
        let t = std::time::Instant::now();
        let sol = residuum::solve::<f64>(&pm, &o, &config(res)).unwrap();
        (sol, t.elapsed().as_secs_f64())
    };
    let (full, t_full) = run(Residuum::Off);
    let phi_full = full.fluence_on(&grid).swap_remove(0);
    let img_full = image(&full, &grid);
    let steps_full: Vec<usize> = full.anisotropic.runs.iter().map(|r| r.steps).collect();
    eprintln!(
        "full: steps {}..{}, {} cell updates, {t_full:.2} s, volume-mean φ {:.4}",
        steps_full.iter().min().unwrap(),
        steps_full.iter().max().unwrap(),
        full.cell_updates(),
        mean(&phi_full)
    );
    let injected: f64 = full
        .anisotropic
        .runs
        .iter()
        .map(|r| r.ledger[0].injected)
        .sum();
    let mut out = Vec::new();
    for (name, res) in [
        ("paper m'=20 + 20 iso", IsoResiduum::paper(20, 20)),
        ("Eq 10 + iso to tolerance", IsoResiduum::eq10()),
    ] {
        let (sol, t) = run(Residuum::Isotropic(res));
        let phi = sol.fluence_on(&grid).swap_remove(0);
        let img = image(&sol, &grid);
        let at_switch: f64 = sol
            .anisotropic
            .runs
            .iter()
            .filter(|r| r.stop != solvers::method::Stop::Converged)
            .map(|r| r.ledger[0].in_flight)
            .sum::<f64>()
            / injected;
        let dropped = sol.iso.as_ref().map_or(0.0, |i| i.ledger[0].in_flight) / injected;
        let speedup = full.cell_updates() as f64 / sol.cell_updates() as f64;
        let d_phi = rel_l2(&phi, &phi_full);
        let d_img = rel_l2(&img, &img_full);
        let d_mean = mean(&phi) / mean(&phi_full) - 1.0;
        eprintln!(
            "{name}: switch {:?}, iso steps {:?}, in flight at switch {at_switch:.4}, dropped {dropped:.4}, \
             φ mean {d_mean:+.4}, φ rel L2 {d_phi:.4}, image rel L2 {d_img:.4}, image mean {:+.4}, \
             speed-up {speedup:.2}× (cell updates), {:.2}× (wall, loaded machine)",
            (sol.switch.raw, sol.switch.m, sol.switch.clamp),
            sol.iso.as_ref().map(|i| i.steps),
            mean(&img) / mean(&img_full) - 1.0,
            t_full / t
        );
        out.push((sol, d_phi, d_img, speedup, at_switch, dropped));
    }
    // Max a over every cell at m = 20 of the +x ordinate of a directional light (spec: 0.75).
    let cfg = PopConfig::fixed::<f64>(N, 20);
    let g = PropagationGrid::over(&grid, [1.0, 0.0, 0.0], N);
    let mip = solvers::pop::grid::box_filter(&pm, 0);
    let mut cp = CpuPop::<f64>::new(g, &mip, &pm.g, &cfg);
    cp.inject(
        &Ordinate::directional([1.0, 0.0, 0.0], 1.0).unwrap(),
        cfg.init,
    );
    cp.run(0.0, 20);
    let a_max = (0..g.len())
        .filter(|&c| cp.cell(c, 0).0 > 0.0)
        .map(|c| cp.cell(c, 0).1)
        .fold(0.0, f64::max);
    eprintln!("max a at m = 20 (one +x ordinate): {a_max:.3} (ε_a = 0.1)");
    // Measured (f64, deterministic): max a = 0.755 (spec prototype 0.75).
    assert!(
        (a_max - 0.755).abs() < 0.01,
        "the paper's m′ = 20 violates |a| < ε_a"
    );
    // Paper m′ = 20 + 20 isotropic: 5.17 % in flight at the switch, 1.36 % dropped, φ mean
    // +2.64 %, φ rel L2 0.0346, image rel L2 0.0352, 2.06× fewer cell updates. T24's flags:
    // the difference exceeds 2 % (flagged: not "negligible"), the speed-up just passes 2×
    // (the paper's 4× is not reached: the full run converges in 42–50 iterations, not 100).
    let (paper, d_phi, d_img, speedup, at_switch, dropped) = &out[0];
    assert_eq!(paper.switch.m, 20);
    assert!(
        *speedup > 2.0 && *speedup < 2.2,
        "paper residuum speed-up {speedup}"
    );
    assert!((at_switch - 0.0517).abs() < 0.002 && (dropped - 0.0136).abs() < 0.001);
    assert!(*d_phi > 0.02 && *d_phi < 0.05, "φ rel L2 {d_phi}");
    assert!(*d_img > 0.02 && *d_img < 0.05, "image rel L2 {d_img}");
    // Eq 10 with ā = 0.984 (the D11 prefilter at N = 64) and the mean Δx_n (diagonal
    // ordinates have cells up to √3 larger) gives m′ = 108.9: every ordinate converges first
    // (42–50 iterations), so the residuum never starts and the result is the full one.
    let (eq10, d_phi, ..) = &out[1];
    assert!((eq10.switch.raw - 108.9).abs() < 0.5, "{:?}", eq10.switch);
    assert_eq!(eq10.switch.clamp, residuum::Clamp::None);
    assert!(eq10.iso.is_none() && *d_phi == 0.0);
}

use crate::common;

/// The residuum variants have no GPU kernel: on the GPU backend `pop:residuum` and
/// `pop:residuum-fld` are a typed [`solvers::SolverError::Unsupported`] naming the variant,
/// never a silent CPU run (lavapipe in CI; skipped with one line without an adapter).
#[test]
fn residuum_variants_refuse_the_gpu_with_a_typed_error() {
    use solvers::method::{self, Problem, Tolerance};
    use solvers::scene::{Light, Phase};
    let medium = Medium::homogeneous(Grid::cube(8, 1.0).unwrap(), 4.0, 0.9).unwrap();
    let sun = [Light::directional([1.0, 0.0, 0.0], 1.0).unwrap()];
    let p = Problem {
        medium: &medium,
        lights: &sun,
        phase: Phase::HenyeyGreenstein { g: 0.7 },
    };
    common::on_backend("gpu", "residuum_variants_refuse_the_gpu", |b| {
        for spec in ["pop:residuum", "pop:residuum-fld"] {
            let m = method::parse(spec).unwrap();
            assert!(!m.capabilities().supports(b), "{spec}");
            match m.solve(b, &p, &Tolerance::rel(1e-3), &mut |_, _| {}) {
                Err(solvers::SolverError::Unsupported(msg)) => {
                    assert!(msg.contains(spec), "{msg}")
                }
                other => panic!("{spec} on the GPU: {other:?}"),
            }
        }
        // Plain POP does run there.
        let pop = method::parse("pop").unwrap();
        assert!(
            pop.solve(b, &p, &Tolerance::rel(1e-3), &mut |_, _| {})
                .is_ok()
        );
    });
}
