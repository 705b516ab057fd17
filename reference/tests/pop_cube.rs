//! POP (`solvers::pop`) against the path tracer on the Fig 12 cube (spec pop.md §3, T19's
//! Monte Carlo parts and T20): unit cube, σs = 4, albedo 1, 16³ voxels = POP cells,
//! one directional light along d = +x of unit irradiance (unit power), POP converged
//! (R/P_inj < 10⁻⁶, f64), the path tracer's current tally (`pathtracer::current`).
//!
//! Probes: five blocks of 2×2×2 voxels on the cube's axis (y, z ∈ [7/16, 9/16]) at voxel
//! pairs x ∈ {1–2, 4–5, 7–8, 10–11, 13–14}; ⟨μ⟩ = Σ J·d / Σ φ over a probe (POP: J = Σ L^m a^m).
//! Each test prints its numbers; the bounds are the measured values with a margin, and the
//! claims are the spec's reading (§5 W1–W4): POP is close at g = 0.96 and far off below.

#![allow(clippy::unwrap_used)]

use reference::pathtracer::PathSettings;
use reference::pathtracer::current::{CurrentTally, current};
use reference::pathtracer::estimators::Estimate;
use solvers::pop::{self, Ordinate, PopConfig, PopMedium};
use solvers::scene::{Light, Phase, Sampler, Scene};
use solvers::{Grid, Medium};

const N: usize = 16;
const PROBES: [[usize; 2]; 5] = [[1, 2], [4, 5], [7, 8], [10, 11], [13, 14]];

fn probe_voxels(grid: &Grid, p: [usize; 2]) -> Vec<usize> {
    let mut v = Vec::new();
    for i in p {
        for j in [7, 8] {
            for k in [7, 8] {
                v.push(grid.index(i, j, k));
            }
        }
    }
    v
}

struct Pop {
    /// φ per voxel (POP cell gathered at the voxel centre) and J along d.
    phi: Vec<f64>,
    j: Vec<f64>,
    /// R, T, side exits over injected.
    exits: [f64; 3],
}

fn pop_cube(g: f64) -> Pop {
    let grid = Grid::cube(N, 1.0).unwrap();
    let m = PopMedium::homogeneous(grid, 4.0, 0.0, g).unwrap();
    let o = [Ordinate::directional([1.0, 0.0, 0.0], 1.0).unwrap()];
    let sol = pop::solve::<f64>(&m, &o, &PopConfig::new::<f64>(N)).unwrap();
    let run = &sol.runs[0];
    let mut phi = vec![0.0; grid.len()];
    let mut j = vec![0.0; grid.len()];
    for (v, (p, q)) in phi.iter_mut().zip(j.iter_mut()).enumerate() {
        let [x, y, z] = grid.coords(v);
        let c = grid.center(x, y, z);
        *p = run.fluence_at(0, c);
        *q = run.grid.interpolate_with(&run.acc, pop::cpu::ACC, 1, c);
    }
    let l = &run.ledger[0];
    Pop {
        phi,
        j,
        exits: [l.exit_back, l.exit_front, l.exit_side].map(|e| e / l.injected),
    }
}

fn pt_cube(g: f64, paths: u64) -> CurrentTally {
    let grid = Grid::cube(N, 1.0).unwrap();
    let scene = Scene {
        medium: Medium::homogeneous(grid, 4.0, 1.0).unwrap(),
        phase: if g == 0.0 {
            Phase::Isotropic
        } else {
            Phase::HenyeyGreenstein { g }
        },
        lights: vec![Light::directional([1.0, 0.0, 0.0], 1.0).unwrap()],
        camera: None,
        sampler: Sampler { spp: 1, seed: 1 },
        interpolation: Default::default(),
    };
    let mut s = PathSettings::new(paths, 17);
    s.batches = 32;
    current(&scene, &s).unwrap()
}

fn pt_exits(t: &CurrentTally) -> [Estimate; 3] {
    let e = &t.exits;
    let side = [2, 3, 4, 5].iter().map(|&f| e[f].mean).sum();
    let side_err = [2, 3, 4, 5]
        .iter()
        .map(|&f| e[f].stderr.powi(2))
        .sum::<f64>()
        .sqrt();
    [
        e[0],
        e[1],
        Estimate {
            mean: side,
            stderr: side_err,
        },
    ]
}

/// (φ ratio POP/PT, PT volume-mean φ, per probe (POP ⟨μ⟩, PT ⟨μ⟩), POP exits, PT exits).
type Comparison = (f64, Estimate, Vec<(f64, Estimate)>, [f64; 3], [Estimate; 3]);

/// The comparison at one g.
fn compare(g: f64, paths: u64) -> Comparison {
    let grid = Grid::cube(N, 1.0).unwrap();
    let p = pop_cube(g);
    let t = pt_cube(g, paths);
    let pop_mean = p.phi.iter().sum::<f64>() / grid.len() as f64;
    let pt_mean = t.mean_fluence();
    let mus: Vec<(f64, Estimate)> = PROBES
        .iter()
        .map(|&pr| {
            let v = probe_voxels(&grid, pr);
            let mu_pop =
                v.iter().map(|&i| p.j[i]).sum::<f64>() / v.iter().map(|&i| p.phi[i]).sum::<f64>();
            (mu_pop, t.mean_cosine(&v, [1.0, 0.0, 0.0]))
        })
        .collect();
    let ex = pt_exits(&t);
    eprintln!(
        "g = {g}: volume-mean φ POP {pop_mean:.4}, PT {:.4} ± {:.4} (ratio {:.3})",
        pt_mean.mean,
        pt_mean.stderr,
        pop_mean / pt_mean.mean
    );
    for (k, (a, b)) in mus.iter().enumerate() {
        eprintln!(
            "  probe {k} (x-voxels {:?}): ⟨μ⟩ POP {a:.4}, PT {:.4} ± {:.4}, diff {:+.4}",
            PROBES[k],
            b.mean,
            b.stderr,
            a - b.mean
        );
    }
    eprintln!(
        "  exits R/T/side POP {:.4}/{:.4}/{:.4}, PT {:.4}±{:.4}/{:.4}±{:.4}/{:.4}±{:.4}",
        p.exits[0],
        p.exits[1],
        p.exits[2],
        ex[0].mean,
        ex[0].stderr,
        ex[1].mean,
        ex[1].stderr,
        ex[2].mean,
        ex[2].stderr
    );
    (pop_mean / pt_mean.mean, pt_mean, mus, p.exits, ex)
}

/// T20: where POP should be good. g = 0.96: volume-mean φ within 15 % of the path tracer
/// (measured +11.1 %, PT 0.9522 ± 0.0004, POP 1.0580) and ⟨μ⟩ within 0.03 at the centre
/// probe (measured +0.007). The spec's "⟨μ⟩ within 0.03 at every probe" does **not** hold:
/// POP's ⟨μ⟩ falls linearly with depth (Eq 4: 0.979 → 0.857 over the five probes) while the
/// path tracer's stays at 0.91–0.93, so the differences are +0.045, +0.032, +0.007, −0.020,
/// −0.053 (PT errors ≤ 0.005). Pinned: the largest |Δ⟨μ⟩| lies in (0.03, 0.07) and the
/// sign flips along the axis (too forward near the entry, too diffuse near the far face).
#[test]
fn t20_cube_g096_mean_cosine_and_fluence_close_to_the_path_tracer() {
    let (ratio, pt, mus, pop_exits, pt_exits) = compare(0.96, 200_000);
    assert!(pt.relative_stderr() < 0.01);
    assert!((ratio - 1.0).abs() < 0.15, "φ ratio {ratio}");
    for (k, (_, b)) in mus.iter().enumerate() {
        assert!(b.stderr < 0.01, "probe {k}: PT error {}", b.stderr);
    }
    let diff: Vec<f64> = mus.iter().map(|(a, b)| a - b.mean).collect();
    assert!(diff[2].abs() < 0.03, "centre probe: {}", diff[2]);
    let worst = diff.iter().fold(0f64, |m, d| m.max(d.abs()));
    assert!(worst > 0.03 && worst < 0.07, "largest |Δ⟨μ⟩| {worst}");
    assert!(diff[0] > 0.02 && diff[4] < -0.02, "{diff:?}");
    // W4: POP transmits too much and loses too little through the sides.
    assert!(pop_exits[1] > pt_exits[1].mean + 10.0 * pt_exits[1].stderr);
    assert!(pop_exits[2] < pt_exits[2].mean - 10.0 * pt_exits[2].stderr);
}

/// T19 (Monte Carlo parts): at g = 0 and 0.7 POP is far off. g = 0: Eq 4 kills the beam
/// in the first cell, so the centre ⟨μ⟩ is ~0 (PT ≈ 0.24) and POP reflects about twice
/// the path tracer's R; g = 0.7: the converged lattice walk traps light, volume-mean φ
/// about 4× the path tracer's, and the centre ⟨μ⟩ is far below.
#[test]
fn t19_cube_g0_and_g07_are_far_from_the_path_tracer() {
    let (ratio0, _, mus0, pop0, pt0) = compare(0.0, 200_000);
    let centre = &mus0[2];
    assert!(centre.1.mean > 0.15, "PT centre ⟨μ⟩ {:?}", centre.1);
    assert!(centre.0 < 0.05 && centre.1.mean - centre.0 > 0.1);
    assert!(
        pop0[0] > 1.5 * pt0[0].mean,
        "R: POP {} vs PT {:?}",
        pop0[0],
        pt0[0]
    );
    assert!((ratio0 - 1.0).abs() < 0.4, "g = 0: φ ratio {ratio0}");
    let (ratio7, _, mus7, _, _) = compare(0.7, 200_000);
    assert!(ratio7 > 3.0, "g = 0.7: φ ratio {ratio7}");
    let centre = &mus7[2];
    assert!(
        centre.1.mean - centre.0 > 0.3,
        "g = 0.7 centre ⟨μ⟩ {centre:?}"
    );
}

/// Fig 12's polar plots as numbers: the band-averaged angular radiance at the centre probe
/// (20 bands of μ = ω·d), POP converged (`pop::probe::angular`) vs the path tracer's
/// direction-binned tally (`pathtracer::angular`), relative L2 over the bands weighted by
/// their solid angle. Measured (2·10⁵ paths): 0.05 at g = 0.96 (POP 1.46 vs PT 1.40 in the
/// forward band, within 30 % elsewhere), and POP far off at g = 0.7 (backward bands 0.64 vs
/// 0.02: the converged lattice walk, W1/W2). Bounds: < 0.1 at g = 0.96, > 1 at g = 0.7.
#[test]
fn fig12_angular_radiance_at_the_centre_probe() {
    use reference::pathtracer::angular::angular;
    let grid = Grid::cube(N, 1.0).unwrap();
    let voxels = probe_voxels(&grid, PROBES[2]);
    let points: Vec<[f64; 3]> = voxels
        .iter()
        .map(|&v| {
            let [x, y, z] = grid.coords(v);
            grid.center(x, y, z)
        })
        .collect();
    let bands = 20;
    let edges: Vec<f64> = (0..=bands)
        .map(|k| -1.0 + 2.0 * k as f64 / bands as f64)
        .collect();
    for (g, bound_lo, bound_hi) in [(0.96, 0.0, 0.1), (0.7, 1.0, f64::INFINITY)] {
        let m = PopMedium::homogeneous(grid, 4.0, 0.0, g).unwrap();
        let o = Ordinate::directional([1.0, 0.0, 0.0], 1.0).unwrap();
        let pop = pop::probe::angular::<f64>(
            &m,
            &o,
            &PopConfig::new::<f64>(N),
            std::slice::from_ref(&points),
            &edges,
        )
        .unwrap();
        let scene = Scene {
            medium: Medium::homogeneous(grid, 4.0, 1.0).unwrap(),
            phase: Phase::HenyeyGreenstein { g },
            lights: vec![Light::directional([1.0, 0.0, 0.0], 1.0).unwrap()],
            camera: None,
            sampler: Sampler { spp: 1, seed: 1 },
            interpolation: Default::default(),
        };
        let mut s = PathSettings::new(200_000, 29);
        s.batches = 32;
        let pt = angular(
            &scene,
            &s,
            std::slice::from_ref(&voxels),
            [1.0, 0.0, 0.0],
            bands,
        )
        .unwrap();
        let (mut num, mut den) = (0.0, 0.0);
        for b in 0..bands {
            let (a, r) = (pop[0][b], pt.radiance[0][b]);
            eprintln!(
                "g {g} μ {:+.2}..{:+.2}: POP {a:.4}, PT {:.4} ± {:.4}",
                edges[b],
                edges[b + 1],
                r.mean,
                r.stderr
            );
            num += (a - r.mean).powi(2);
            den += r.mean * r.mean;
        }
        let rel = (num / den).sqrt();
        eprintln!("g {g}: relative L2 over the bands {rel:.4}");
        assert!(rel > bound_lo && rel < bound_hi, "g {g}: {rel}");
    }
}
