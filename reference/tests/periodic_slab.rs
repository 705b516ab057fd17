//! Independent checks of the laterally periodic slab tracer
//! ([`reference::pathtracer::PeriodicSlab`]):
//!
//! * laterally homogeneous slabs (every column τ = 2, or every column τ = 18; the I3RC
//!   step-cloud grid, 32 × 3 × 16 voxels of 15.625 m) against adding–doubling
//!   ([`reference::transport::slab`]) for zenith 0° and 60°, g = 0.85, ω0 ∈ {1, 0.99}: the
//!   domain R and T within 3σ, every column's R and T within a Šidák 3σ-family band;
//! * energy: R + T + A = 1 for the domain means to rounding (≤ 10⁻¹², exact per path);
//! * the 1-D limit: a step cloud whose two halves are 40 slab thicknesses wide, so each
//!   half's centre is far from the steps: there R and T are those of the homogeneous slab
//!   of the same τ (adding–doubling) within 3σ.
//!
//! Path counts (sized for ≲ 30 s on 2 release cores): 1 000 000 per homogeneous case (8 cases),
//! 200 000 per 1-D-limit case (2 cases).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::pathtracer::estimators::sidak_z;
use reference::pathtracer::{Beam, PathSettings, PeriodicSlab, PeriodicTally};
use reference::transport::slab::Slab;
use solvers::scene::Phase;
use solvers::{Grid, Medium};

const G: f64 = 0.85;
/// Cloud thickness, km.
const H: f64 = 0.25;

fn settings(paths: u64, seed: u64) -> PathSettings {
    PathSettings {
        paths,
        seed,
        batches: 32,
        max_depth: None,
    }
}

/// The I3RC step-cloud grid with optical depth `tau(x index)` per column.
fn step_grid(tau: impl Fn(usize) -> f64, albedo: f64) -> PeriodicSlab {
    let grid = Grid::new([32, 3, 16], 0.5 / 32.0).unwrap();
    let sigma = (0..grid.len())
        .map(|v| tau(grid.coords(v)[0]) / H)
        .collect::<Vec<_>>();
    let m = Medium::new(grid, sigma, vec![albedo; grid.len()], vec![0.0; grid.len()]).unwrap();
    // Per-voxel tracking on every axis: exercises the DDA, its lateral wraps and the
    // vertical voxel steps (the shortcut for invariant axes is checked against it in the
    // module's unit tests, and used by the 1-D-limit test below).
    PeriodicSlab::per_voxel(&m, Phase::HenyeyGreenstein { g: G }).unwrap()
}

fn balance_exact(t: &PeriodicTally) {
    let d = &t.domain;
    let sum = d.reflectance.mean + d.transmittance.mean + d.absorptance.mean;
    assert!((sum - 1.0).abs() < 1e-12, "R + T + A = {sum}");
    assert!((t.balance.mean - 1.0).abs() < 1e-12, "{:?}", t.balance);
    assert!(t.balance.stderr < 1e-12, "{:?}", t.balance);
    let tsum = d.transmittance_direct.mean + d.transmittance_diffuse.mean;
    assert!((tsum - d.transmittance.mean).abs() < 1e-12);
}

#[test]
fn homogeneous_slabs_match_adding_doubling() {
    let cases: Vec<(f64, f64, f64)> = [2.0, 18.0]
        .into_iter()
        .flat_map(|tau| {
            [0.0, 60.0]
                .into_iter()
                .flat_map(move |z| [1.0, 0.99].map(move |w| (tau, z, w)))
        })
        .collect();
    let zcol = sidak_z(cases.len() * 32 * 2, 0.0027);
    let mut worst = 0.0f64;
    for (k, &(tau, zenith, albedo)) in cases.iter().enumerate() {
        let s = step_grid(|_| tau, albedo);
        let beam = Beam::from_degrees(zenith, 0.0).unwrap();
        let t = s
            .simulate(&beam, &settings(1_000_000, 100 + k as u64))
            .unwrap();
        let ad = Slab::new(tau, albedo, G)
            .unwrap()
            .solve(beam.mu0())
            .unwrap();
        let t_ref = ad.transmittance_diffuse + ad.transmittance_direct;
        let d = &t.domain;
        let zr = d.reflectance.z(ad.reflectance);
        let zt = d.transmittance.z(t_ref);
        let zdir = d.transmittance_direct.z(ad.transmittance_direct);
        println!(
            "τ={tau} θ0={zenith} ω0={albedo}: R {:.5}±{:.5} (AD {:.5}, z {zr:+.2}), \
             T {:.5}±{:.5} (AD {:.5}, z {zt:+.2}), T_dir z {zdir:+.2}, A {:.5}",
            d.reflectance.mean,
            d.reflectance.stderr,
            ad.reflectance,
            d.transmittance.mean,
            d.transmittance.stderr,
            t_ref,
            d.absorptance.mean
        );
        for z in [zr, zt] {
            assert!(z.abs() < 3.0, "τ={tau} θ0={zenith} ω0={albedo}: z = {z}");
            worst = worst.max(z.abs());
        }
        // T_dir is e^{-τ/μ0}: ~0 at τ = 18, so only judged where it was sampled.
        if ad.transmittance_direct > 1e-4 {
            assert!(zdir.abs() < 3.0, "T_dir z = {zdir}");
        }
        if albedo == 1.0 {
            assert_eq!(d.absorptance.mean, 0.0);
        } else {
            assert!(d.absorptance.mean > 0.0);
        }
        balance_exact(&t);
        for (c, col) in t.columns.iter().enumerate() {
            let (zr, zt) = (
                col.reflectance.z(ad.reflectance),
                col.transmittance.z(t_ref),
            );
            assert!(
                zr.abs() < zcol && zt.abs() < zcol,
                "column {c}: z_R {zr}, z_T {zt} (band {zcol})"
            );
        }
    }
    println!("worst domain |z| = {worst:.2}; per-column band {zcol:.2}");
}

/// A step cloud with halves of 10 km (40 thicknesses) each, τ = 2 and τ = 18, at zenith 60°
/// (the harder case: light travels sideways): the voxel columns at each half's centre are
/// the homogeneous slab of their τ. Voxels are 1/3 of the thickness (nz = 3), so a half is
/// 120 voxel columns; the 24 central ones of each half are pooled into one tally group.
#[test]
fn wide_columns_reach_the_one_dimensional_limit() {
    let half = 120usize;
    let grid = Grid::new([2 * half, 3, 3], H / 3.0).unwrap();
    let tau_of = |x: usize| if x < half { 2.0 } else { 18.0 };
    // Group 0: centre of the thin half, 1: centre of the thick half, 2: everything else.
    let group: Vec<usize> = (0..2 * half)
        .map(|x| match x % half {
            48..72 => x / half,
            _ => 2,
        })
        .collect();
    for (k, albedo) in [1.0, 0.99].into_iter().enumerate() {
        let sigma = (0..grid.len())
            .map(|v| tau_of(grid.coords(v)[0]) / H)
            .collect::<Vec<_>>();
        let m = Medium::new(grid, sigma, vec![albedo; grid.len()], vec![0.0; grid.len()]).unwrap();
        let s = PeriodicSlab::new(&m, Phase::HenyeyGreenstein { g: G }).unwrap();
        let beam = Beam::from_degrees(60.0, 0.0).unwrap();
        let t = s
            .simulate_grouped(&beam, &settings(200_000, 7 + k as u64), &group)
            .unwrap();
        balance_exact(&t);
        for (g, tau) in [(0usize, 2.0), (1, 18.0)] {
            let ad = Slab::new(tau, albedo, G)
                .unwrap()
                .solve(beam.mu0())
                .unwrap();
            let t_ref = ad.transmittance_diffuse + ad.transmittance_direct;
            let c = &t.columns[g];
            let (zr, zt) = (c.reflectance.z(ad.reflectance), c.transmittance.z(t_ref));
            println!(
                "1-D limit τ={tau} ω0={albedo}: R {:.5}±{:.5} (AD {:.5}, z {zr:+.2}), \
                 T {:.5}±{:.5} (AD {:.5}, z {zt:+.2})",
                c.reflectance.mean,
                c.reflectance.stderr,
                ad.reflectance,
                c.transmittance.mean,
                c.transmittance.stderr,
                t_ref
            );
            assert!(
                zr.abs() < 3.0 && zt.abs() < 3.0,
                "τ={tau}: z_R {zr}, z_T {zt}"
            );
        }
    }
}
