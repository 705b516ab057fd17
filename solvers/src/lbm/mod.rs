//! Lattice-Boltzmann lighting (Geist et al., *Lattice-Boltzmann Lighting*): photon density
//! transport on a D3Q19 lattice with a per-site collision matrix Θ (LB Eqs 3–6), light
//! injected at the boundary (LB Section 5, Appendix A), streaming to neighbours and outflow
//! into a sink (LB Appendix B), iterated until the total density is steady.
//!
//! * [`LbmConfig`]: phase function and Henyey–Greenstein normalisation, absorption model,
//!   σ mapping, light resolution, stopping rule.
//! * [`Injection`]: per-lattice-direction beam irradiances from directional lights.
//! * [`cpu::CpuLbm`]: the rayon kernel, generic over `f32`/`f64`.
//! * [`gpu::GpuLbm`]: the wgpu kernel (f32, `lbm.wgsl`), same layout and arithmetic.
//! * [`solve`] / [`solve_scene`]: backend-dispatching entry points; [`LbmSolution`] carries
//!   the fluence φ per voxel in physical units.
//!
//! ## Lattice (LB Section 3)
//! c₀ = 0 (rest), c₁…c₆ the axial directions ±x, ±y, ±z, c₇…c₁₈ the twelve non-corner
//! diagonals, in the order of [`C`] (opposite directions adjacent). Isotropic weights
//! w = 1/12 (axial) and 1/24 (diagonal) ([`W`]): the scattering and re-emission weights of
//! LB Eqs 5–6; Σᵢ wᵢ = 1.
//!
//! ## Collision (LB Eqs 4–6) and its variants
//! With in = the densities arriving at a site and σs, σa the site's per-step fractions:
//!
//! out₀ = σa Σⱼ₌₁¹⁸ inⱼ (LB Eq 4),
//! outᵢ = (1 − σt) inᵢ + σs Σⱼ₌₁¹⁸ Sᵢⱼ inⱼ + wᵢ in₀ (LB Eqs 5–6; isotropic Sᵢⱼ = wᵢ).
//!
//! * **Henyey–Greenstein** ([`HgNormalisation`]). LB Section 4 scales σs in Θᵢⱼ by
//!   pᵢⱼ / (Σⱼ₌₁¹⁸ pᵢⱼ / 18) with the discrete HG phase pᵢⱼ = (1 − g²)/(1 − 2g nᵢ·nⱼ + g²)^{3/2}
//!   ([`HgNormalisation::Paper`]). That normalises *rows*; conservation needs *columns*
//!   (Σᵢ Θᵢⱼ = 1), and the paper's scaling breaks it for g ≠ 0: the column sums of
//!   σs·S are σs·(1 + e_j) with e_j from [`Scattering::column_sum_error`] (measured:
//!   axial/diagonal columns +0.62 %/−0.31 % at g = 0.25, +9.0 %/−4.5 % at g = ±0.5,
//!   +47 %/−23 % at g = 0.85; test `paper_hg_scaling_breaks_conservation`; the steady-state
//!   energy error this causes is measured in `tests/lbm_conformance.rs`). [`HgNormalisation::Renormalised`] (the default) uses
//!   Sᵢⱼ = wᵢ aᵢ pᵢⱼ aⱼ with a from a symmetric Sinkhorn iteration, which is column-stochastic
//!   to rounding *and* keeps the isotropic equilibrium w stationary (S w = w, because p is
//!   symmetric), so LB Eq 13 still holds.
//! * **Absorption** ([`Absorption`]). In LB Eq 4 row 0 collects σa of the moving density and
//!   column 0 (LB Eqs 5–6, j = 0) re-emits all of it isotropically on the next step: σa is a
//!   one-step delay, not a loss, and the paper's steady state conserves energy whatever σa
//!   ([`Absorption::PaperDelay`], the default, faithful). [`Absorption::Loss`] zeroes
//!   column 0: absorbed density goes to a sink and leaves the system, as in transport.
//!
//! ## Physical units (a decision of this crate, tested in `cpu.rs`)
//! Lattice spacing λ = Δl (one site per voxel, at the voxel centre), time step τ = one step.
//! * **σ mapping** ([`SigmaMapping`]): the per-step extinction of a site is the probability
//!   that light crossing one axial lattice spacing interacts, σt,lat = 1 − exp(−σt Δl)
//!   ([`SigmaMapping::Exponential`], default; exact transmission for axial beams, never
//!   needs clamping), or the paper-style linear σt,lat = σt Δl clamped to 1
//!   ([`SigmaMapping::Linear`]; the number of clamped sites is reported in
//!   `LbmSolution::clamped_sites`). σs,lat = α σt,lat, σa,lat = (1 − α) σt,lat. The paper's
//!   per-site density scaling (LB Section 4) is the medium's σt field itself.
//! * **Density** is power: a directional density f carries f units of energy per step, so
//!   injecting P per step and counting outflow per step compare powers directly.
//! * **Injection** (LB Section 5, Appendix A): a directional light of irradiance E along d is
//!   resolved into beam irradiances Eᵢ = E wᵢ(d) along lattice directions ([`Resolve`]). A
//!   uniform beam along cᵢ crosses an axis plane with power density fᵢ/Δl² per site, which
//!   equals the physical Eᵢ (nᵢ·axis) when fᵢ = Eᵢ Δl²/|cᵢ|. Every site whose upstream
//!   neighbour r − cᵢ lies outside the grid therefore receives the constant inflow
//!   fᵢ = Eᵢ Δl²/|cᵢ| each step ("fixed at a constant value", LB Section 5): the grid sits
//!   in an unbounded uniform beam. Edges and corners need no special case. Emission j adds
//!   j Δl³ per step to a site's outgoing densities with weights w.
//! * **Fluence** (track length): density fᵢ moves |cᵢ| Δl per step, so the voxel-averaged
//!   fluence is φ = Σᵢ₌₁¹⁸ |cᵢ| (inᵢ + outᵢ) / (2 Δl²) — half of a link's track lies in each
//!   voxel it joins. For an axial beam in a pure absorber this is the trapezoid rule of the
//!   exact voxel average (relative error (σΔl)²/12, tested).
//! * **What the mapping cannot match.** Θ has one σt for all directions although a diagonal
//!   link is √2 Δl long, so diagonal beams attenuate as if σt were σt/√2, and the lattice mean
//!   free path Σwᵢ|cᵢ| Δl/σt,lat is 1.207× the physical one. In the diffusive limit the LB
//!   diffusion coefficient (LB Eq 19) in fluence form is D_LB/v̄ = 1/(2(1+√2)σt) ≈ 0.414/σt
//!   against transport's 1/(3σt) (lattice speed v̄ = (1+√2)/2 Δl per step): LB diffuses
//!   about 24 % too fast. With the paper's absorption the steady state does not absorb at all.
//!   The tests bound the homogeneous-cube fluence against the path tracer (order of magnitude,
//!   see `tests/lbm_conformance.rs`); [`Absorption::Loss`] is the variant to compare with
//!   transport in absorbing media.
//!
//! ## Anisotropy variants (issue 12, item 2; decisions where the paper is silent)
//! `lbm` (= `lbm:paper`) scatters with LB Section 4's HG kernel on the 18 moving directions
//! (renormalised, above). `lbm:similarity` scatters isotropically on the transport-scaled
//! medium σs' = (1 − g)σs, σt' = σa + σs' ([`crate::method::AnisotropyScaling`]); in the
//! pipeline its source is δ-scaled too (lights baked through σt', scattered at σs').
//! * **Why the plan warns for `paper` at |g| > 0.5.** The D3Q19 kernel's discrete mean
//!   cosine ḡ overshoots g: axial/diagonal 0.321/0.296 at g = 0.3, 0.578/0.504 at 0.5,
//!   0.849/0.792 at 0.7, 0.994/0.991 at 0.9, 1.0000/1.0000 at 0.99: for strong anisotropy the
//!   kernel keeps scattered density on its own link, i.e. it hardly scatters at all, while
//!   the baked source σs·L_ri still enters isotropically (test
//!   `the_lattice_kernel_under_resolves_strong_anisotropy`).
//! * **Measured (default stays `paper`).** In `results/accuracy_hg` (noise cloud and
//!   shell_core at 32³, 32×32 pixels, ds 4 and 2, tol 1e-3 f32, 2048-spp reference), the
//!   relative RMSE of the multiple-scattering image is lower with `similarity` in 10 of 16
//!   cases: all 8 at g ≥ 0.9 (g = 0.9 cloud ds 4: 2.15 → 0.371; g = 0.99: 8.98 → 0.979), 2 of
//!   4 at g = 0.7 (ds 2: 0.386 → 0.271, 0.403 → 0.374; ds 4 paper 0.302 vs 0.322, 0.387 vs
//!   0.455) and none at g = 0.3 (cloud ds 2: 0.091 paper vs 0.152). In
//!   `reference/tests/anisotropy_scaling.rs` (ds 4, 16×16) it is 4 of 8 (all at g ≥ 0.9). The
//!   crossover lies between g = 0.7 and 0.9, the anisotropic datasets of this repository have
//!   g = 0.3, and CDA and FLD keep `paper` for the same split, so LBM keeps it too.
//!   Tests: `at_g_zero_the_variants_are_identical`,
//!   `similarity_is_the_isotropic_solve_on_the_transport_scaled_medium` (`method.rs`).
//!
//! ## Stopping rule
//! Steady when the relative change of the total lattice density per step falls below the
//! tolerance (default 10⁻⁹ in f64, 10⁻⁶ in f32, see [`LbmConfig::tolerance`]), or at
//! `max_steps`. The GPU measures totals by a reduction at checkpoints every
//! [`LbmConfig::check_every`] steps and uses the change between checkpoints divided by the
//! steps between them. Total density counts all 19 directions with [`Absorption::PaperDelay`]
//! (ρ of LB Section 3) and the 18 moving ones with [`Absorption::Loss`] (where the rest slot
//! holds only the density absorbed in the last step, which is counted as `absorbed`).
//!
//! ## Emissive albedo-1 media (issue 12, items 3–4: what is the method, measured)
//! `emissive_cube` (16³, j = 1, albedo 1, no lights) has LBM 27–48 % below the path tracer
//! (0.0221 at σt = 100, downsample 1, vs 0.0305 ± 0.0003) while CDA/FLD with the Marshak
//! face match within 1.3 %. Measured causes, in order of elimination:
//! * **Not an energy leak.** `tests/lbm_energy_balance.rs` (8³ emissive cube in one vacuum
//!   layer, f64, lattice tolerance 10⁻¹¹ per step): outflow/source = 1.000000 at σt·Δl =
//!   0.01, 1 and 100 (35, 147, 248 steps). The lattice conserves energy; every unit emitted
//!   leaves.
//! * **Not under-convergence.** `emissive_cube --methods lbm --tol 1e-7` (per-step change
//!   10⁻⁹): σt = 100, ds 1 mean 0.0221478 (659 steps) vs 0.0221473 at the default (391); ds 4
//!   0.0169889 vs 0.0169888.
//! * **The method: the lattice cannot diffuse slower than one collision per site.**
//!   σt,lat = 1 − e^(−σtΔl) saturates at 1, so the lattice mean free path never falls below
//!   ≈ 1.2 Δl and D_LB/v̄ ≥ 0.414 Δl, against transport's 1/(3σt) = 0.053 Δl at σt·Δl = 6.25
//!   (σt = 100 on 16³; 7.8× too diffusive) and 0.0033 Δl at σt·Δl = 100 (124×). The same
//!   test measures LBM/`cda:marshak` fluence at the centre 1.69 / 0.871 / 0.020 and over the
//!   surface layer 1.39 / 1.03 / 0.029 at σt·Δl = 0.01 / 1 / 100: agreement at σt·Δl ≈ 1, a
//!   fluence far too low once the voxels are optically thick (and too high in the free
//!   streaming limit, where the lattice's 18 discrete directions and its per-step transport
//!   differ from transport). The camera sees the surface layer, so the image is low; the
//!   remedy is resolution (σt·Δl ≲ 1), not a change of the lattice, which is LB's.
//!   Not measured: how much of the image gap each of the surface φ and the pipeline's φ
//!   interpolation in the first voxel explain.
//!
//! ## Supported lights ([`solve_scene`])
//! Directional lights (boundary injection) and volume emission j (source term). Point, sphere
//! and environment lights return [`SolverError::Unsupported`].

pub mod cpu;
pub mod gpu;
pub mod method;

pub use cpu::CpuLbm;
pub use gpu::GpuLbm;
pub use method::{LBM, LbmMethod};

use crate::gpu::Timer;
use crate::method::{Balance, Solution, Stop};
use crate::scene::{Light, Phase, Scene};
use crate::{Backend, Grid, Medium, Precision, Real, SolverError};

/// Number of lattice directions (rest + 6 axial + 12 diagonal).
pub const Q: usize = 19;

/// The D3Q19 directions c₀…c₁₈ (LB Section 3): rest, ±x, ±y, ±z, then the twelve
/// non-corner diagonals; each direction is followed by its opposite.
pub const C: [[i32; 3]; Q] = [
    [0, 0, 0],
    [1, 0, 0],
    [-1, 0, 0],
    [0, 1, 0],
    [0, -1, 0],
    [0, 0, 1],
    [0, 0, -1],
    [1, 1, 0],
    [-1, -1, 0],
    [1, -1, 0],
    [-1, 1, 0],
    [1, 0, 1],
    [-1, 0, -1],
    [1, 0, -1],
    [-1, 0, 1],
    [0, 1, 1],
    [0, -1, -1],
    [0, 1, -1],
    [0, -1, 1],
];

/// Isotropic weights (LB Eqs 5–6, column 0): 0 for rest, 1/12 axial, 1/24 diagonal.
pub const W: [f64; Q] = {
    let mut w = [0.0; Q];
    let mut i = 1;
    while i < Q {
        w[i] = if i <= 6 { 1.0 / 12.0 } else { 1.0 / 24.0 };
        i += 1;
    }
    w
};

/// Link length |cᵢ| in lattice units (0, 1 or √2).
pub fn speed(i: usize) -> f64 {
    let c = C[i];
    ((c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) as f64).sqrt()
}

/// The unit vector nᵢ = cᵢ/|cᵢ| (zero for the rest direction).
pub fn unit(i: usize) -> [f64; 3] {
    let s = speed(i);
    if s == 0.0 {
        return [0.0; 3];
    }
    C[i].map(|c| c as f64 / s)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// How LB Section 4's Henyey–Greenstein scaling is normalised (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HgNormalisation {
    /// LB Section 4 verbatim: σs in Θᵢⱼ scaled by pᵢⱼ/(Σⱼ pᵢⱼ/18). Not column-stochastic for
    /// g ≠ 0: energy is created or destroyed at every scattering.
    Paper,
    /// Sᵢⱼ = wᵢ aᵢ pᵢⱼ aⱼ, symmetric Sinkhorn scaling: column-stochastic and S w = w.
    #[default]
    Renormalised,
}

/// What happens to density absorbed into the rest direction (LB Eq 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Absorption {
    /// LB Eqs 4–6 verbatim: re-emitted isotropically on the next step (a delay, no loss).
    #[default]
    PaperDelay,
    /// Column 0 of Θ is zero: absorbed density leaves the system (counted as `absorbed`).
    Loss,
}

/// Physical σt, Δl → per-step lattice σ (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SigmaMapping {
    /// σt,lat = 1 − exp(−σt Δl): the interaction probability over one axial link.
    #[default]
    Exponential,
    /// σt,lat = min(σt Δl, 1); clamped sites are counted.
    Linear,
}

impl SigmaMapping {
    /// The per-step extinction for physical σt over spacing Δl, and whether it was clamped.
    pub fn lattice_sigma(self, sigma_t: f64, dl: f64) -> (f64, bool) {
        let x = sigma_t * dl;
        match self {
            SigmaMapping::Exponential => (-(-x).exp_m1(), false),
            SigmaMapping::Linear => (x.min(1.0), x > 1.0),
        }
    }
}

/// How a light direction is resolved into lattice directions (LB Section 5, Appendix A).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Resolve {
    /// The procedure of LB Section 5's text: repeatedly take the unselected lattice direction
    /// with the largest dot product with the *remaining* light vector and subtract its
    /// projection; weights are those projections, so Σ wᵢ nᵢ = d (the injected power is
    /// right) and Σ wᵢ ≥ 1 (the uncollided fluence is Σwᵢ E; 1 for axial and face-diagonal
    /// light, 1.39 for d ∝ (1,1,1)).
    #[default]
    FluxPreserving,
    /// LB Appendix A's pseudocode verbatim: sort by dot product with d, assign
    /// min(dot, remaining intensity) until the unit intensity is used (Σ wᵢ = 1); stops at a
    /// non-positive dot product (the pseudocode would assign a negative weight).
    AppendixA,
}

/// Resolves unit direction `d` into non-negative weights over the 19 lattice directions
/// (rest weight 0).
pub fn resolve_direction(d: [f64; 3], mode: Resolve) -> [f64; Q] {
    let mut w = [0.0; Q];
    match mode {
        Resolve::AppendixA => {
            let mut order: Vec<usize> = (1..Q).collect();
            order.sort_by(|&a, &b| dot(unit(b), d).total_cmp(&dot(unit(a), d)));
            let mut intens = 1.0;
            for i in order {
                let dp = dot(unit(i), d);
                if intens < 1e-12 || dp <= 0.0 {
                    break;
                }
                w[i] = dp.min(intens);
                intens -= dp;
            }
        }
        Resolve::FluxPreserving => {
            let mut r = d;
            let mut used = [false; Q];
            for _ in 1..Q {
                let best = (1..Q)
                    .filter(|&i| !used[i])
                    .map(|i| (i, dot(unit(i), r)))
                    .fold((0, 0.0), |b, x| if x.1 > b.1 { x } else { b });
                if best.0 == 0 || best.1 <= 1e-14 {
                    break;
                }
                let (i, p) = best;
                used[i] = true;
                w[i] = p;
                let n = unit(i);
                r = [r[0] - p * n[0], r[1] - p * n[1], r[2] - p * n[2]];
                if dot(r, r).sqrt() < 1e-12 {
                    break;
                }
            }
        }
    }
    w
}

/// Boundary injection: the irradiance Eᵢ of a uniform beam along each lattice direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Injection {
    /// Eᵢ per direction (power per area perpendicular to cᵢ); index 0 (rest) is ignored.
    pub irradiance: [f64; Q],
}

impl Default for Injection {
    fn default() -> Self {
        Self::none()
    }
}

impl Injection {
    /// No external light (emission only).
    pub fn none() -> Self {
        Self {
            irradiance: [0.0; Q],
        }
    }

    /// A directional light along unit `direction` with `irradiance`, resolved by `mode`.
    pub fn directional(
        direction: [f64; 3],
        irradiance: f64,
        mode: Resolve,
    ) -> Result<Self, SolverError> {
        Light::Directional {
            direction,
            irradiance,
        }
        .validate()?;
        let w = resolve_direction(direction, mode);
        Ok(Self {
            irradiance: w.map(|x| x * irradiance),
        })
    }

    /// The injection of a scene's lights: directional lights add up; any other kind is
    /// [`SolverError::Unsupported`].
    pub fn from_lights(lights: &[Light], mode: Resolve) -> Result<Self, SolverError> {
        let mut inj = Self::none();
        for light in lights {
            match *light {
                Light::Directional {
                    direction,
                    irradiance,
                } => {
                    let one = Self::directional(direction, irradiance, mode)?;
                    for (a, b) in inj.irradiance.iter_mut().zip(one.irradiance) {
                        *a += b;
                    }
                }
                other => {
                    return Err(SolverError::Unsupported(format!(
                        "the lattice-Boltzmann solver supports directional lights and volume \
                         emission only, not {other:?}"
                    )));
                }
            }
        }
        Ok(inj)
    }

    /// Checks that every irradiance is finite and ≥ 0.
    pub fn validate(&self) -> Result<(), SolverError> {
        match self
            .irradiance
            .iter()
            .find(|e| !(e.is_finite() && **e >= 0.0))
        {
            Some(&e) => Err(SolverError::BadParameter {
                name: "injection.irradiance",
                value: e,
                reason: "must be finite and ≥ 0",
            }),
            None => Ok(()),
        }
    }

    /// Inflow density fᵢ = Eᵢ Δl²/|cᵢ| per boundary site and step (module docs).
    pub fn inflow(&self, dl: f64) -> [f64; Q] {
        let mut f = [0.0; Q];
        for (i, v) in f.iter_mut().enumerate().skip(1) {
            *v = self.irradiance[i] * dl * dl / speed(i);
        }
        f
    }
}

/// The scattering kernel S of a configuration: Sᵢⱼ for i, j ∈ 1…18 (index 0 unused).
#[derive(Debug, Clone, PartialEq)]
pub struct Scattering {
    /// Sᵢⱼ = fraction of scattered density from direction j that goes to direction i.
    pub s: [[f64; Q]; Q],
    /// Whether S is the isotropic kernel Sᵢⱼ = wᵢ (the fast path of the kernels).
    pub isotropic: bool,
}

impl Scattering {
    /// The kernel for `phase` with the given HG normalisation.
    pub fn new(phase: Phase, hg: HgNormalisation) -> Result<Self, SolverError> {
        phase.validate()?;
        let g = phase.mean_cosine();
        let mut s = [[0.0; Q]; Q];
        if g == 0.0 {
            for (i, row) in s.iter_mut().enumerate().skip(1) {
                for v in row.iter_mut().skip(1) {
                    *v = W[i];
                }
            }
            return Ok(Self { s, isotropic: true });
        }
        let p = |i: usize, j: usize| {
            (1.0 - g * g) / (1.0 - 2.0 * g * dot(unit(i), unit(j)) + g * g).powf(1.5)
        };
        match hg {
            HgNormalisation::Paper => {
                for (i, row) in s.iter_mut().enumerate().skip(1) {
                    let mean: f64 = (1..Q).map(|j| p(i, j)).sum::<f64>() / 18.0;
                    for (j, v) in row.iter_mut().enumerate().skip(1) {
                        *v = W[i] * p(i, j) / mean;
                    }
                }
            }
            HgNormalisation::Renormalised => {
                // a_j Σ_i w_i a_i p_ij = 1 for all j (symmetric Sinkhorn with a square-root
                // damped update; converges for a positive symmetric kernel).
                let mut a = [1.0; Q];
                for _ in 0..10_000 {
                    let mut worst: f64 = 0.0;
                    let mut next = a;
                    for j in 1..Q {
                        let col: f64 = (1..Q).map(|i| W[i] * a[i] * p(i, j)).sum();
                        worst = worst.max((a[j] * col - 1.0).abs());
                        next[j] = (a[j] / col).sqrt();
                    }
                    a = next;
                    if worst < 1e-15 {
                        break;
                    }
                }
                for (i, row) in s.iter_mut().enumerate().skip(1) {
                    for (j, v) in row.iter_mut().enumerate().skip(1) {
                        *v = W[i] * a[i] * p(i, j) * a[j];
                    }
                }
            }
        }
        Ok(Self {
            s,
            isotropic: false,
        })
    }

    /// Σᵢ Sᵢⱼ − 1 for each column j (0 for a conservative kernel; index 0 unused).
    pub fn column_sum_error(&self) -> [f64; Q] {
        let mut e = [0.0; Q];
        for (j, v) in e.iter_mut().enumerate().skip(1) {
            *v = (1..Q).map(|i| self.s[i][j]).sum::<f64>() - 1.0;
        }
        e
    }

    /// The discrete mean cosine Σᵢ Sᵢⱼ nᵢ·nⱼ of column j (a scattering from direction j).
    pub fn mean_cosine(&self, j: usize) -> f64 {
        (1..Q).map(|i| self.s[i][j] * dot(unit(i), unit(j))).sum()
    }

    /// The full 19×19 collision matrix Θ (LB Eqs 4–6, with this kernel) of a site with
    /// per-step σs, σa: Θᵢⱼ is the fraction of incoming direction j sent to direction i.
    pub fn theta(&self, sigma_s: f64, sigma_a: f64, absorption: Absorption) -> [[f64; Q]; Q] {
        let mut t = [[0.0; Q]; Q];
        let sigma_t = sigma_s + sigma_a;
        for j in 1..Q {
            t[0][j] = sigma_a;
            for (i, row) in t.iter_mut().enumerate().skip(1) {
                row[j] = sigma_s * self.s[i][j] + if i == j { 1.0 - sigma_t } else { 0.0 };
            }
        }
        if absorption == Absorption::PaperDelay {
            for (i, row) in t.iter_mut().enumerate().skip(1) {
                row[0] = W[i];
            }
        }
        t
    }
}

/// Per-step σs and σa of a site from the paper's (σt, albedo, density) ∈ [0, 1]³
/// (LB Section 4: the σ values scaled by the medium density).
pub fn site_sigmas(sigma_t: f64, albedo: f64, density: f64) -> (f64, f64) {
    let st = sigma_t * density;
    (albedo * st, (1.0 - albedo) * st)
}

/// Solver parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct LbmConfig {
    /// Phase function (the scene's, in [`solve_scene`]).
    pub phase: Phase,
    /// How the HG scaling is normalised (ignored for isotropic scattering).
    pub hg: HgNormalisation,
    /// Paper's delayed re-emission or a true loss.
    pub absorption: Absorption,
    /// Physical σt → per-step σ.
    pub sigma_mapping: SigmaMapping,
    /// Light direction → lattice directions (used by [`solve_scene`]).
    pub resolve: Resolve,
    /// Stop when the relative change of the total density per step is below this; `None`:
    /// 10⁻⁹ in f64, 10⁻⁶ in f32 (the GPU's f32 reduction resolves ~10⁻⁷). 0: run `max_steps`.
    pub tolerance: Option<f64>,
    /// Step cap.
    pub max_steps: usize,
    /// GPU: steps per checkpoint (reduction and read-back of the totals).
    pub check_every: u32,
}

impl Default for LbmConfig {
    fn default() -> Self {
        Self {
            phase: Phase::Isotropic,
            hg: HgNormalisation::Renormalised,
            absorption: Absorption::PaperDelay,
            sigma_mapping: SigmaMapping::Exponential,
            resolve: Resolve::FluxPreserving,
            tolerance: None,
            max_steps: 100_000,
            check_every: 16,
        }
    }
}

impl LbmConfig {
    /// The settings to compare LB with transport references (e.g. the path tracer's fluence
    /// of the same scene): absorbed density leaves ([`Absorption::Loss`]), HG renormalised,
    /// exponential σ mapping, flux-preserving light resolution. One call:
    /// `lbm::solve_scene(&backend, &scene, &LbmConfig::transport())`.
    pub fn transport() -> Self {
        Self::default().with_absorption(Absorption::Loss)
    }

    /// Builder: tolerance.
    pub fn with_tolerance(mut self, tol: f64) -> Self {
        self.tolerance = Some(tol);
        self
    }

    /// Builder: step cap.
    pub fn with_max_steps(mut self, n: usize) -> Self {
        self.max_steps = n;
        self
    }

    /// Builder: exactly `n` steps (tolerance 0).
    pub fn fixed_steps(self, n: usize) -> Self {
        self.with_tolerance(0.0).with_max_steps(n)
    }

    /// Builder: absorption model.
    pub fn with_absorption(mut self, a: Absorption) -> Self {
        self.absorption = a;
        self
    }

    /// Builder: phase function and HG normalisation.
    pub fn with_phase(mut self, phase: Phase, hg: HgNormalisation) -> Self {
        self.phase = phase;
        self.hg = hg;
        self
    }

    /// Builder: σ mapping.
    pub fn with_sigma_mapping(mut self, m: SigmaMapping) -> Self {
        self.sigma_mapping = m;
        self
    }

    /// The tolerance in effect for precision `T`.
    pub fn tolerance_for<T: Real>(&self) -> f64 {
        self.tolerance
            .unwrap_or(if T::NAME == "f64" { 1e-9 } else { 1e-6 })
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.phase.validate()?;
        if let Some(t) = self.tolerance {
            if !(t.is_finite() && t >= 0.0) {
                return Err(SolverError::BadParameter {
                    name: "tolerance",
                    value: t,
                    reason: "must be finite and ≥ 0",
                });
            }
        }
        if self.check_every == 0 {
            return Err(SolverError::BadParameter {
                name: "check_every",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        Ok(())
    }
}

/// Lattice totals after one step (CPU: every step; GPU: at checkpoints). All in density
/// units (power, see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRecord {
    /// Steps completed.
    pub step: usize,
    /// Total density arriving at all sites in this step (before collision).
    pub total_density: f64,
    /// Density injected at the boundary plus emitted in this step.
    pub injected: f64,
    /// Density that streamed out of the grid in this step (the sink).
    pub outflow: f64,
    /// Density absorbed and removed in this step ([`Absorption::Loss`] only; else 0).
    pub absorbed: f64,
}

/// LB's part of a [`Solution`]: the lattice density, the per-step totals and the clamp count.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LbmTrace<T> {
    /// Total site density ρ (LB Section 3; lattice units, power per site), x fastest.
    pub rho: Vec<T>,
    /// Totals per step (CPU) or per checkpoint (GPU).
    pub history: Vec<StepRecord>,
    /// Sites whose σt Δl exceeded 1 and was clamped ([`SigmaMapping::Linear`] only).
    pub clamped_sites: usize,
}

/// The result of a lattice-Boltzmann solve: voxel-averaged fluence φ in physical units
/// (power per area), lattice steps ([`Solution::steps`]), why it stopped, and the lattice
/// density and totals in [`Solution::trace`]. [`Stop::Converged`] means the relative change
/// of the total density per step fell below the tolerance.
pub type LbmSolution<T> = Solution<T, LbmTrace<T>>;

impl<T> Solution<T, LbmTrace<T>> {
    /// The last record, if any step ran.
    pub fn last(&self) -> Option<&StepRecord> {
        self.trace.history.last()
    }

    /// The totals per step (CPU) or per checkpoint (GPU).
    pub fn history(&self) -> &[StepRecord] {
        &self.trace.history
    }
}

/// Assembles a solution (CPU and GPU kernels). `last_change` is the relative change of the
/// total density between the last two records (steps on the CPU, checkpoints on the GPU);
/// NaN with fewer than two.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solution<T>(
    grid: Grid,
    phi: Vec<T>,
    trace: LbmTrace<T>,
    steps: usize,
    stop: Stop,
    seconds: f64,
    setup_seconds: f64,
    timer: Timer,
) -> LbmSolution<T> {
    let last_change = match trace.history.as_slice() {
        [.., a, b] => ((b.total_density - a.total_density) / b.total_density).abs(),
        _ => f64::NAN,
    };
    let balance = trace.history.last().map(|r| Balance {
        source: r.injected,
        outflow: r.outflow,
        absorbed: r.absorbed,
    });
    Solution {
        grid,
        phi,
        steps,
        last_change,
        stop,
        seconds,
        setup_seconds,
        timer,
        balance,
        trace,
    }
}

fn widen<T: Real>(s: LbmSolution<T>) -> LbmSolution<f64> {
    s.widen_with(|t| LbmTrace {
        rho: t.rho.iter().map(|x| x.f()).collect(),
        history: t.history,
        clamped_sites: t.clamped_sites,
    })
}

/// Solves on any [`Backend`]: the medium is given in `f64` and packed in the backend's
/// precision; φ comes back in `f64`. `observer(step, total_density)` sees every step (CPU)
/// or every checkpoint (GPU).
pub fn solve(
    backend: &Backend<'_>,
    medium: &Medium<f64>,
    injection: &Injection,
    config: &LbmConfig,
    observer: impl FnMut(usize, f64),
) -> Result<LbmSolution<f64>, SolverError> {
    match backend {
        Backend::Cpu(Precision::F64) => {
            Ok(CpuLbm::<f64>::new(medium, injection, config)?.solve_observed(observer))
        }
        Backend::Cpu(Precision::F32) => Ok(widen(
            CpuLbm::<f32>::new(medium, injection, config)?.solve_observed(observer),
        )),
        Backend::Gpu(ctx) => Ok(widen(
            GpuLbm::new(ctx, medium, injection, config)?.solve_observed(observer)?,
        )),
    }
}

/// Solves a [`Scene`]: directional lights become boundary injection (resolved with
/// `config.resolve`), the medium's emission the source term, and the scene's phase function
/// replaces `config.phase`. Other light types are [`SolverError::Unsupported`].
pub fn solve_scene(
    backend: &Backend<'_>,
    scene: &Scene,
    config: &LbmConfig,
) -> Result<LbmSolution<f64>, SolverError> {
    scene.medium.validate()?;
    let injection = Injection::from_lights(&scene.lights, config.resolve)?;
    let cfg = LbmConfig {
        phase: scene.phase,
        ..config.clone()
    };
    solve(backend, &scene.medium, &injection, &cfg, |_, _| {})
}

#[cfg(test)]
mod tests;
