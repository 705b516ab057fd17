//! Energy balance of the diffusion solvers (issue 12, item 3 and acceptance 2).
//!
//! An albedo-1 cube lit only by its own emission j = 1 sits inside the grid's Dirichlet layer
//! of vacuum (as the pipeline pads it: `PipelineConfig::pad = 1`). With σa = 0 every unit of
//! power emitted must leave through the faces between the medium and the boundary layer, so
//! the net discrete flux Σ D_pb (φ_p − φ_b) Δl over those faces (D_pb = (D_p + D_b)/2, the
//! solver's own face coefficient) must equal ∫ j dV. Summed over the medium, the interior
//! faces of the conservative 7-point scheme cancel, so the balance fails only if the solve is
//! under-converged or the face coefficients are not symmetric.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use solvers::fld::{Boundary, CpuFld, FldConfig, FluxLimiter};
use solvers::{Grid, Medium, Real};

/// An n³ emissive albedo-1 cube with σt·Δl = `tau`, inside one layer of vacuum (Δl = 1).
fn cube<T: Real>(n: usize, tau: f64) -> Medium<T> {
    let grid = Grid::new([n + 2; 3], 1.0).unwrap();
    let len = grid.len();
    let (mut st, mut a, mut j) = (
        vec![T::zero(); len],
        vec![T::zero(); len],
        vec![T::zero(); len],
    );
    for idx in 0..len {
        let [x, y, z] = grid.coords(idx);
        if !grid.is_boundary(x, y, z) {
            st[idx] = T::c(tau);
            a[idx] = T::one();
            j[idx] = T::one();
        }
    }
    Medium::new(grid, st, a, j).unwrap()
}

/// (net flux out through the boundary layer / ∫ j dV, iterations, converged).
fn balance<T: Real>(m: &Medium<T>, cfg: &FldConfig) -> (f64, usize, bool) {
    let mut s = CpuFld::new(m, &Boundary::Zero, cfg).unwrap();
    let tol = cfg.tolerance.unwrap();
    let mut converged = false;
    while s.iterations() < cfg.max_iterations {
        if s.iterate() < tol {
            converged = true;
            break;
        }
    }
    let (phi, d) = (s.phi(), s.diffusion_coefficient());
    let g = m.grid;
    let (mut out, mut src) = (0.0, 0.0);
    for idx in 0..g.len() {
        let [x, y, z] = g.coords(idx);
        if g.is_boundary(x, y, z) {
            continue;
        }
        src += m.emission[idx].f() * g.dl.powi(3);
        for [dx, dy, dz] in [
            [-1i64, 0, 0],
            [1, 0, 0],
            [0, -1, 0],
            [0, 1, 0],
            [0, 0, -1],
            [0, 0, 1],
        ] {
            let nb = [x as i64 + dx, y as i64 + dy, z as i64 + dz].map(|v| v as usize);
            if g.is_boundary(nb[0], nb[1], nb[2]) {
                let b = g.index(nb[0], nb[1], nb[2]);
                let dpb = 0.5 * (d[idx].f() + d[b].f());
                out += dpb * (phi[idx].f() - phi[b].f()) * g.dl;
            }
        }
    }
    (out / src, s.iterations(), converged)
}

/// f64 at R̄/j̄ < 10⁻⁸: the outflow equals ∫ j dV within 10⁻³ (measured: within 10⁻⁶ for
/// every limiter and σt·Δl, in 87–180 iterations at ω = 1.8). f32 at its default tolerance
/// 10⁻⁴ (f32 stalls near R̄/j̄ ≈ 10⁻⁵, so 10⁻⁸ is out of its reach): within 10⁻³ as well
/// (measured: within 2.5·10⁻⁵; the same at 10⁻⁴ in f64).
#[test]
fn emission_leaves_through_the_boundary_for_every_limiter_and_precision() {
    for lim in FluxLimiter::ALL {
        for tau in [0.01, 1.0, 100.0] {
            let cfg = FldConfig {
                limiter: lim,
                omega: 1.8,
                max_iterations: 5000,
                ..FldConfig::default()
            };
            let (r64, it64, c64) = balance::<f64>(&cube(8, tau), &cfg.clone().with_tolerance(1e-8));
            let (r32, it32, c32) = balance::<f32>(&cube(8, tau), &cfg.clone().with_tolerance(1e-4));
            println!(
                "{lim:?} σtΔl {tau}: f64 out/∫j = {r64:.8} ({it64} it), f32 {r32:.8} ({it32} it)"
            );
            assert!(
                c64 && c32,
                "{lim:?} σtΔl {tau}: not converged (f64 {c64}, f32 {c32})"
            );
            assert!(
                (r64 - 1.0).abs() < 1e-3,
                "{lim:?} σtΔl {tau}: f64 out/∫j = {r64}"
            );
            assert!(
                (r32 - 1.0).abs() < 1e-3,
                "{lim:?} σtΔl {tau}: f32 out/∫j = {r32}"
            );
        }
    }
}

/// Why the pipeline's emissive albedo-1 images are off although the balance holds: the face
/// coefficient to the vacuum Dirichlet layer is the paper's (D_p + D_b)/2 (FLD Eq 32), and
/// D_b in vacuum is set by the floors of FLD Eqs 33/35. CDA: D_b = 1/(3σ_ε) = L/(3·10⁻³)
/// (3333 here), so the surface voxel is pinned to φ ≈ 0 (measured 1.47·10⁻³ at τ = 1 and
/// 100 alike). FLD: D_b ≈ φ_b/|∇φ| ≈ 0 (measured 7·10⁻¹⁸), so the face carries D_p/2 and the
/// surface voxel sits at φ ≈ 2F·Δl/D_p, 4× the Marshak vacuum value 2F + F·Δl/(2D_p) at
/// τ = 100 (measured 1088 vs 274), growing like σt·Δl. The outflow is right in both cases;
/// only its split between φ near the surface and the face coefficient is not, and the
/// raymarch sees φ within one mean free path of the surface. This pins that documented
/// behaviour of the paper's discretisation (see the `fld` module docs).
#[test]
fn the_vacuum_face_coefficient_sets_the_surface_fluence() {
    let tau = 100.0;
    for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning] {
        let m = cube::<f64>(8, tau);
        let cfg = FldConfig {
            limiter: lim,
            omega: 1.8,
            max_iterations: 5000,
            ..FldConfig::default()
        }
        .with_tolerance(1e-8);
        let mut s = CpuFld::new(&m, &Boundary::Zero, &cfg).unwrap();
        while s.iterations() < cfg.max_iterations && s.iterate() > 1e-8 {}
        let (phi, d) = (s.phi(), s.diffusion_coefficient());
        let g = m.grid;
        // The centre of one face: boundary voxel b, the medium voxel p next to it.
        let (b, p) = (g.index(0, 4, 4), g.index(1, 4, 4));
        let flux = 0.5 * (d[b] + d[p]) * (phi[p] - phi[b]);
        let marshak = 2.0 * flux + flux * g.dl / (2.0 * d[p]);
        let ratio = phi[p] / marshak;
        println!(
            "{lim:?}: D_b {:.3e}, D_p {:.3e}, φ_p {:.4e}, Marshak {marshak:.4e}, ratio {ratio:.3e}",
            d[b], d[p], phi[p]
        );
        if lim.is_constant() {
            assert!((d[b] - 1.0 / (3.0 * 1e-3 / g.extent())).abs() < 1e-6 * d[b]);
            assert!(ratio < 1e-4, "CDA surface φ / Marshak = {ratio}");
        } else {
            assert!(d[b] < 1e-10 * d[p], "FLD D_b = {}", d[b]);
            assert!(
                (3.0..5.0).contains(&ratio),
                "FLD surface φ / Marshak = {ratio}"
            );
        }
    }
}
