//! The Marshak vacuum face (`cda:marshak`, `fld:<limiter>:marshak`, issue 12 items 3 and
//! acceptance 2) on issue 12's emissive albedo-1 cube (no lights, j = 1, albedo 1).
//!
//! 1. Energy: the net flux through the medium–vacuum faces, with the Marshak face
//!    coefficient 2DΔl/(Δl + 4D) the solver uses, equals ∫ j dV (10⁻³ in f64 at R̄/j̄ < 10⁻⁸),
//!    for CDA and every limiter, at σt·Δl ∈ {0.01, 1, 100}.
//! 2. The image: the pipeline's image mean at downsample 1 agrees with the path tracer's
//!    within 10 % (measured −6.3 % at 2.3 % standard error, z = −2.7: diffusion's own bias
//!    at the surface), and is independent of σt in the thick limit (σt = 100 and
//!    1000, within 2 %), as the exitance of a conservative cube must be (all of ∫ j dV
//!    leaves). The paper's face misses both (measured on this 8³ cube: FLD-LP 0.262 and 2.33,
//!    CDA 4.4·10⁻⁴ and 4.0·10⁻⁵, path tracer 0.0297 ± 0.0025 at σt = 100).
//! 3. The analytic slab (issue 15 acceptance 6): CDA with the Marshak face against the
//!    extrapolated-boundary solution of φ ∓ 2Dφ′ = 0, max relative error over the column,
//!    n = 8, 16, 32 voxels across: τ = 1, α = 0.9: 6.1e-4, 8.7e-5, 1.2e-5 (orders 2.8, 2.9);
//!    τ = 8, α = 0.9: 2.0e-2, 5.5e-3, 1.1e-3 (1.9, 2.3); τ = 2, α = 1: 1.9e-3, 2.9e-4,
//!    4.2e-5 (2.7, 2.8). The paper's face misses by 0.999 at n = 32 (it pins φ ≈ 0 on the
//!    surface voxel, and the slab's φ lies mostly within 2D of a surface).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::effects::render_components;
use reference::pathtracer::{Contributions, RenderSettings};
use solvers::fld::{Boundary, CpuFld, FldConfig, FluxLimiter, VacuumFace};
use solvers::method::MethodRef;
use solvers::pipeline::{self, PipelineConfig};
use solvers::scene::SceneFile;
use solvers::{Backend, Grid, Medium, Precision};
use std::path::Path;

#[test]
fn emission_leaves_through_marshak_faces_for_every_limiter() {
    let n = 8;
    for lim in FluxLimiter::ALL {
        for tau in [0.01, 1.0, 100.0] {
            let grid = Grid::new([n + 2; 3], 1.0).unwrap();
            let len = grid.len();
            let (mut st, mut a, mut j) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
            for idx in 0..len {
                let [x, y, z] = grid.coords(idx);
                if !grid.is_boundary(x, y, z) {
                    (st[idx], a[idx], j[idx]) = (tau, 1.0, 1.0);
                }
            }
            let m = Medium::new(grid, st, a, j).unwrap();
            let cfg = FldConfig {
                limiter: lim,
                omega: 1.8,
                max_iterations: 20_000,
                vacuum_face: VacuumFace::Marshak,
                ..FldConfig::default()
            }
            .with_tolerance(1e-8);
            let mut s = CpuFld::new(&m, &Boundary::Zero, &cfg).unwrap();
            let mut converged = false;
            while s.iterations() < cfg.max_iterations {
                if s.iterate() < 1e-8 {
                    converged = true;
                    break;
                }
            }
            let (phi, d) = (s.phi(), s.diffusion_coefficient());
            let dl = grid.dl;
            let (mut out, mut src) = (0.0, 0.0);
            for idx in 0..len {
                let [x, y, z] = grid.coords(idx);
                if grid.is_boundary(x, y, z) {
                    continue;
                }
                src += m.emission[idx] * dl.powi(3);
                for [dx, dy, dz] in [
                    [-1i64, 0, 0],
                    [1, 0, 0],
                    [0, -1, 0],
                    [0, 1, 0],
                    [0, 0, -1],
                    [0, 0, 1],
                ] {
                    let nb = [x as i64 + dx, y as i64 + dy, z as i64 + dz].map(|v| v as usize);
                    if grid.is_boundary(nb[0], nb[1], nb[2]) {
                        let b = grid.index(nb[0], nb[1], nb[2]);
                        let face = 2.0 * d[idx] * dl / (dl + 4.0 * d[idx]);
                        out += face * (phi[idx] - phi[b]) * dl;
                    }
                }
            }
            let r = out / src;
            println!(
                "{lim:?} σtΔl {tau}: out/∫j = {r:.8} ({} it)",
                s.iterations()
            );
            assert!(converged, "{lim:?} σtΔl {tau}: not converged");
            assert!((r - 1.0).abs() < 1e-3, "{lim:?} σtΔl {tau}: out/∫j = {r}");
        }
    }
}

fn cube(sigma_t: f64) -> SceneFile {
    let text = format!(
        r#"
format = 1
[medium]
generator = "homogeneous"
params = {{ n = 8, extent = 1.0, sigma_t = {sigma_t}, albedo = 1.0 }}
emission = 1.0
[camera]
eye = [0.5, -1.5, 0.8]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "perspective"
fov_y = 50.0
resolution = [16, 16]
"#
    );
    SceneFile::parse(&text, Path::new("."), Path::new("cube.toml")).unwrap()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn the_marshak_face_renders_the_emissive_albedo_1_cube_like_the_path_tracer() {
    let be = Backend::Cpu(Precision::F64);
    for spec in ["cda:marshak", "fld:lp:marshak"] {
        let cfg = PipelineConfig {
            method: spec.parse::<MethodRef>().unwrap(),
            downsample: 1,
            pixel_samples: 3,
            ..PipelineConfig::default()
        };
        let means: Vec<f64> = [100.0, 1000.0]
            .iter()
            .map(|&s| {
                let r = pipeline::render_file(&cube(s), &cfg, &be).unwrap();
                assert!(r.diffusion[0].stop == solvers::method::Stop::Converged);
                mean(&r.channels[0].total)
            })
            .collect();
        let rel = means[1] / means[0] - 1.0;
        println!(
            "{spec}: σt 100 → {:.5}, σt 1000 → {:.5} ({rel:+.4})",
            means[0], means[1]
        );
        assert!(
            rel.abs() < 0.02,
            "{spec}: the thick limit depends on σt ({rel})"
        );
        if spec == "cda:marshak" {
            let file = cube(100.0);
            let r = pipeline::render_file(&file, &cfg, &be).unwrap();
            let pt = render_components(
                &file.scene,
                &r.plan.effects,
                &RenderSettings {
                    spp: 256,
                    seed: 5,
                    batches: 16,
                    contributions: Contributions::all(),
                },
            )
            .unwrap();
            let m = mean(&pt.total.mean);
            let se = pt.total.stderr.iter().map(|x| x * x).sum::<f64>().sqrt()
                / pt.total.stderr.len() as f64;
            let (z, rel) = ((means[0] - m) / se, means[0] / m - 1.0);
            println!(
                "{spec}: ours {:.5} vs path tracer {m:.5} ± {se:.5}, z {z:+.2}, {rel:+.4}",
                means[0]
            );
            // Measured: 0.02942 vs 0.03139 ± 0.00072 (−6.3 %, z = −2.7): diffusion's own
            // bias at the surface, far inside the 10 % accepted here; the paper's faces are
            // +780 % (FLD-LP) and −98 % (CDA) off.
            assert!(rel.abs() < 0.1 && se < 0.03 * m, "{rel:+.4} (z = {z:+.2})");
        }
    }
}

/// The CDA slab with the extrapolated (Marshak) boundary, analytic: −(Dφ′)′ + σa φ = j on
/// 0 < z < L with φ ∓ 2Dφ′ = 0 at z = 0 and z = L (the solver's F = φ_f/2 on a face to
/// vacuum) has φ(z) = (j/σa)(1 − A cosh κ(z − L/2)), κ = √(σa/D),
/// A = 1/(cosh(κL/2) + 2Dκ sinh(κL/2)); at albedo 1, φ(z) = j z(L − z)/(2D) + jL.
fn slab_exact(z: f64, len: f64, sigma_t: f64, albedo: f64) -> f64 {
    let d = 1.0 / (3.0 * sigma_t);
    let sa = (1.0 - albedo) * sigma_t;
    if sa == 0.0 {
        return z * (len - z) / (2.0 * d) + len;
    }
    let k = (sa / d).sqrt();
    let a = 1.0 / ((k * len / 2.0).cosh() + 2.0 * d * k * (k * len / 2.0).sinh());
    (1.0 - a * (k * (z - len / 2.0)).cosh()) / sa
}

/// The relative max error over the centre column of a `cda:marshak` (or paper-face) slab of
/// `n` voxels across thickness `len`, j = 1; the four side faces hold the exact φ(z) as
/// Dirichlet values in medium voxels, so only the two vacuum faces are Marshak (or paper).
fn slab_error(n: usize, len: f64, sigma_t: f64, albedo: f64, face: VacuumFace) -> f64 {
    let dl = len / n as f64;
    let grid = Grid::with_origin([5, 5, n + 2], dl, [0.0, 0.0, -dl]).unwrap();
    let size = grid.len();
    let (mut st, mut a, mut j) = (vec![0.0; size], vec![0.0; size], vec![0.0; size]);
    let mut bv = vec![0.0; size];
    for idx in 0..size {
        let [x, y, z] = grid.coords(idx);
        if z == 0 || z == n + 1 {
            continue; // the vacuum faces: σt = 0, φ = 0
        }
        (st[idx], a[idx], j[idx]) = (sigma_t, albedo, 1.0);
        if grid.is_boundary(x, y, z) {
            bv[idx] = slab_exact(grid.center(x, y, z)[2], len, sigma_t, albedo);
        }
    }
    let m = Medium::new(grid, st, a, j).unwrap();
    let cfg = FldConfig {
        limiter: FluxLimiter::Cda,
        omega: 1.9,
        max_iterations: 200_000,
        vacuum_face: face,
        ..FldConfig::default()
    }
    .with_tolerance(1e-12);
    let mut s = CpuFld::new(&m, &Boundary::Values(bv), &cfg).unwrap();
    let mut converged = false;
    while s.iterations() < cfg.max_iterations {
        if s.iterate() < 1e-12 {
            converged = true;
            break;
        }
    }
    assert!(converged, "slab n = {n}: not converged");
    let phi = s.phi();
    (1..=n)
        .map(|k| {
            let idx = grid.index(2, 2, k);
            let exact = slab_exact(grid.center(2, 2, k)[2], len, sigma_t, albedo);
            (phi[idx] - exact).abs() / exact
        })
        .fold(0.0, f64::max)
}

/// The Marshak face converges to the analytic extrapolated-boundary slab at second order
/// (issue 15 acceptance 6): thin (τ = 1), thick (τ = 8, a half-space for the surface) and
/// conservative (albedo 1) slabs. The paper's face pins the surface to φ ≈ 0 instead and its
/// error does not shrink with Δl.
#[test]
fn cda_marshak_slab_converges_to_the_extrapolated_boundary_solution() {
    for (len, albedo) in [(1.0, 0.9), (8.0, 0.9), (2.0, 1.0)] {
        let errs: Vec<f64> = [8, 16, 32]
            .iter()
            .map(|&n| slab_error(n, len, 1.0, albedo, VacuumFace::Marshak))
            .collect();
        let orders: Vec<f64> = errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
        let paper = slab_error(32, len, 1.0, albedo, VacuumFace::Paper);
        println!(
            "L {len} α {albedo}: Marshak max rel error n = 8, 16, 32: {:.3e} {:.3e} {:.3e}, \
             orders {orders:.2?}; paper face at n = 32: {paper:.3e}",
            errs[0], errs[1], errs[2]
        );
        assert!(errs[2] < 2e-3, "L {len} α {albedo}: error {:.3e}", errs[2]);
        assert!(
            orders.iter().all(|&p| p > 1.75),
            "L {len} α {albedo}: orders {orders:?}"
        );
        assert!(
            paper > 0.1,
            "L {len} α {albedo}: paper face error {paper:.3e}"
        );
    }
}
