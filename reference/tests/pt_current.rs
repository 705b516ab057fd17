//! The path tracer's direction tally (`pathtracer::current`): the per-voxel track-length
//! current J = Σ ℓ·ω against two exact answers.
//!
//! 1. **Pure absorber under a collimated beam.** Every track runs along the beam, so
//!    J = φ·d in every voxel: ⟨μ⟩ = J·d/φ = 1 and the transverse moments vanish to rounding
//!    (the standard error is 0 too), and the beam leaves through the far face(s) with the
//!    fraction e^{−τ} within its error.
//! 2. **Isotropic point source in an (effectively) unbounded medium.** σt = 1, albedo
//!    c = 0.7, isotropic scattering, unit power at the centre of a 16³ box of unit voxels
//!    (half-width 8 mean free paths). Energy conservation gives the exact radial current
//!    4πr²J_r(r) = 1 − (1 − c)∫₀ʳ ρ(r′) dr′ with ρ = 4πr²φ the exact radial density
//!    ([`reference::transport::point`]); J_x = J_r·x/r and φ are averaged exactly over
//!    probe blocks [a, a+1]×[−1, 1]² on the +x axis by 8-point Gauss–Legendre per axis.
//!    The box is finite: the missing return from beyond 8 mfp is ≈ e^{−2κ(8 − r)} ≈ 10⁻³ at
//!    r = 4 (κ = 0.83 at c = 0.7), below the Monte Carlo error here.

#![allow(clippy::unwrap_used)]

use reference::pathtracer::PathSettings;
use reference::pathtracer::current::current;
use reference::transport::point::ExactPointSource;
use solvers::scene::{Light, Phase, Sampler, Scene};
use solvers::{Grid, Medium};

fn scene(medium: Medium<f64>, lights: Vec<Light>) -> Scene {
    Scene {
        medium,
        phase: Phase::Isotropic,
        lights,
        camera: None,
        sampler: Sampler { spp: 1, seed: 1 },
        interpolation: Default::default(),
    }
}

#[test]
fn pure_absorber_beam_has_unit_mean_cosine() {
    let grid = Grid::cube(8, 1.0).unwrap();
    let tau = 2.0;
    for d in [[1.0, 0.0, 0.0], [0.6, 0.0, 0.8]] {
        let medium = Medium::homogeneous(grid, tau, 0.0).unwrap();
        let s = scene(medium, vec![Light::directional(d, 1.0).unwrap()]);
        let t = current(&s, &PathSettings::new(20_000, 3)).unwrap();
        let all: Vec<usize> = (0..grid.len()).collect();
        let mu = t.mean_cosine(&all, d);
        assert!((mu.mean - 1.0).abs() < 1e-12, "{d:?}: ⟨μ⟩ = {mu:?}");
        assert!(mu.stderr < 1e-12);
        for v in [0, 77, grid.len() - 1] {
            let m = t.mean_cosine(&[v], d);
            assert!((m.mean - 1.0).abs() < 1e-12, "voxel {v}: {m:?}");
            let y = t.mean_cosine(&[v], [0.0, 1.0, 0.0]);
            assert!(y.mean.abs() < 1e-12, "voxel {v}: ⟨ω_y⟩ = {y:?}");
        }
        if d[2] == 0.0 {
            // Everything not absorbed leaves through +x: e^{−τ}.
            let exact = (-tau).exp();
            let z = t.exits[1].z(exact);
            assert!(z.abs() < 4.0, "T = {:?} vs {exact}, z = {z}", t.exits[1]);
            for f in [0, 2, 3, 4, 5] {
                assert_eq!(t.exits[f].mean, 0.0, "face {f}");
            }
        }
    }
}

/// 8-point Gauss–Legendre nodes and weights on [−1, 1].
const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887),
    (-0.183_434_642_495_650, 0.362_683_783_378_362),
    (0.183_434_642_495_650, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

fn gauss(a: f64, b: f64, f: impl Fn(f64) -> f64) -> f64 {
    let (m, h) = ((a + b) / 2.0, (b - a) / 2.0);
    GL8.iter().map(|&(x, w)| w * f(m + h * x)).sum::<f64>() * h
}

#[test]
fn point_source_current_matches_energy_conservation() {
    let c = 0.7;
    let exact = ExactPointSource::new(c).unwrap();
    // A(r) = ∫₀ʳ ρ on panels of 0.05.
    let panel = 0.05;
    let mut cumulative = vec![0.0];
    for i in 0..200 {
        let (a, b) = (i as f64 * panel, (i + 1) as f64 * panel);
        let last = cumulative[i];
        cumulative.push(last + gauss(a, b, |r| exact.radial_density(r)));
    }
    let absorbed_within = |r: f64| {
        let i = ((r / panel) as usize).min(199);
        cumulative[i] + gauss(i as f64 * panel, r, |s| exact.radial_density(s))
    };
    let j_r =
        |r: f64| (1.0 - (1.0 - c) * absorbed_within(r)) / (4.0 * std::f64::consts::PI * r * r);
    // ∫ over [a, a+1]×[0, 1]² (×4 by symmetry) of J_x and of φ.
    let block = |a: f64| {
        let (mut jx, mut phi) = (0.0, 0.0);
        for &(xu, wx) in &GL8 {
            let x = a + 0.5 + 0.5 * xu;
            for &(yu, wy) in &GL8 {
                let y = 0.5 + 0.5 * yu;
                for &(zu, wz) in &GL8 {
                    let z = 0.5 + 0.5 * zu;
                    let r = (x * x + y * y + z * z).sqrt();
                    let w = wx * wy * wz / 8.0 * 4.0;
                    jx += w * j_r(r) * x / r;
                    phi += w * exact.fluence(r);
                }
            }
        }
        (jx, phi)
    };
    let grid = Grid::with_origin([16; 3], 1.0, [-8.0; 3]).unwrap();
    let medium = Medium::homogeneous(grid, 1.0, c).unwrap();
    let light = Light::Point {
        position: [0.0; 3],
        power: 1.0,
    };
    let mut settings = PathSettings::new(2_000_000, 11);
    settings.batches = 32;
    let t = current(&scene(medium, vec![light]), &settings).unwrap();
    for a in [1usize, 2, 3] {
        let i = 8 + a;
        let voxels: Vec<usize> = [(7, 7), (7, 8), (8, 7), (8, 8)]
            .iter()
            .map(|&(j, k)| grid.index(i, j, k))
            .collect();
        let (jx_exact, phi_exact) = block(a as f64);
        let jx: f64 = voxels.iter().map(|&v| t.current[0].mean[v]).sum();
        let jx_err = voxels
            .iter()
            .map(|&v| t.current[0].stderr[v].powi(2))
            .sum::<f64>()
            .sqrt();
        let phi = t.sum_estimate(&voxels, 1.0);
        let mu = t.mean_cosine(&voxels, [1.0, 0.0, 0.0]);
        let mu_exact = jx_exact / phi_exact;
        let z_j = (jx - jx_exact) / jx_err;
        let z_mu = mu.z(mu_exact);
        eprintln!(
            "r ∈ [{a}, {}]: J_x {jx:.5} ± {jx_err:.5} (exact {jx_exact:.5}, z {z_j:+.2}); φ {:.5} ± {:.5} (exact {phi_exact:.5}, z {:+.2}); ⟨μ_x⟩ {:.4} ± {:.4} (exact {mu_exact:.4}, z {z_mu:+.2})",
            a + 1,
            phi.mean,
            phi.stderr,
            phi.z(phi_exact),
            mu.mean,
            mu.stderr
        );
        assert!(z_j.abs() < 4.0, "J_x z = {z_j}");
        assert!(phi.z(phi_exact).abs() < 4.0, "φ z = {}", phi.z(phi_exact));
        assert!(z_mu.abs() < 4.0, "⟨μ⟩ z = {z_mu}");
        // The tally is not trivially 1 or 0: far from the source ⟨μ_x⟩ is between.
        assert!(mu.mean > 0.2 && mu.mean < 0.9);
    }
}
