//! Lattice-Boltzmann lighting behind the [`Method`] interface: the registry entry `lbm`.
//!
//! The method runs LB in its transport configuration ([`LbmConfig::transport`]: absorbed
//! light leaves, renormalised HG with the problem's phase function, exponential σ mapping).
//! The problem's source q (its emission field: q_ri + j in the pipeline) enters as an
//! isotropic volume source, so φ is, as for CDA and FLD, the fluence of light scattered at
//! least once. No light is injected at the boundary ([`Injection::none`]).
//!
//! **Anisotropy (issue 12, item 2).** Two variants, named like CDA's and FLD's
//! ([`AnisotropyScaling`]): `lbm` (= `lbm:paper`) scatters with the problem's phase function
//! on the lattice (LB Section 4's HG kernel, renormalised, see [`super::HgNormalisation`]);
//! `lbm:similarity` scatters isotropically on the transport-scaled medium σs' = (1 − g)σs,
//! σt' = σa + σs', with the source unchanged. On D3Q19 the paper's kernel cannot resolve a
//! strongly forward-peaked phase function: its discrete mean cosine Σᵢ Sᵢⱼ nᵢ·nⱼ is below g
//! (measured in `the_lattice_kernel_under_resolves_strong_anisotropy`), which is why the plan
//! warns when `paper` runs with |g| > 0.5. Which variant is closer to the path tracer is
//! measured in `results/accuracy_hg` (the numbers and the default: the `lbm` module docs).
//!
//! **Tolerance.** It stops when the relative change of the total lattice density per step is
//! below [`Tolerance::rel`] × 10⁻² (the diffusion default 10⁻⁴ gives 10⁻⁶): a per-step change
//! is a much smaller number than the error it leaves, and this is the mapping the pipeline has
//! used since LB joined it (`results/accuracy_cost`: LBM's image error changes by 3·10⁻⁶
//! between rel = 10⁻³ and 10⁻⁴ on nebula at downsample 4).

use super::{Injection, LbmConfig, Q};
use crate::method::{
    AnisotropyScaling, Capabilities, Fluence, LightInput, Method, MethodFamily, Problem, Tolerance,
};
use crate::scene::Phase;
use crate::{Backend, Grid, Precision, SolverError};

/// The factor from [`Tolerance::rel`] to LB's per-step relative density change.
pub const TOLERANCE_FACTOR: f64 = 1e-2;

/// Lattice-Boltzmann lighting with its settings.
#[derive(Debug, Clone, PartialEq)]
pub struct LbmMethod {
    /// The solver settings; `phase` is replaced by the problem's, `tolerance` and
    /// `max_steps` by the [`Tolerance`] of each solve.
    pub config: LbmConfig,
    /// The paper's lattice HG kernel or the similarity scaling (a spec suffix `:similarity`).
    pub anisotropy: AnisotropyScaling,
}

impl Default for LbmMethod {
    fn default() -> Self {
        Self {
            config: LbmConfig::transport(),
            anisotropy: AnisotropyScaling::default(),
        }
    }
}

impl LbmMethod {
    /// Builder: the anisotropy variant.
    pub fn with_anisotropy(mut self, a: AnisotropyScaling) -> Self {
        self.anisotropy = a;
        self
    }

    /// The solver settings of one solve: the problem's phase function for the paper's
    /// variant, isotropic scattering for the similarity scaling (whose medium
    /// [`AnisotropyScaling::apply`] scales).
    pub fn config_for(&self, problem: &Problem<'_>, tolerance: &Tolerance) -> LbmConfig {
        LbmConfig {
            phase: match self.anisotropy {
                AnisotropyScaling::Paper => problem.phase,
                AnisotropyScaling::Similarity => Phase::Isotropic,
            },
            tolerance: Some(tolerance.rel * TOLERANCE_FACTOR),
            max_steps: tolerance.max_steps,
            ..self.config.clone()
        }
    }
}

impl Method for LbmMethod {
    fn name(&self) -> String {
        match self.anisotropy {
            AnisotropyScaling::Paper => "lbm".into(),
            a => format!("lbm:{a}"),
        }
    }

    fn anisotropy(&self) -> Option<AnisotropyScaling> {
        Some(self.anisotropy)
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            gpu: true,
            f64: true,
            volume_source: true,
            // The similarity variant scatters isotropically (on the scaled medium).
            anisotropic: self.anisotropy == AnisotropyScaling::Paper,
            lights: LightInput::Baked,
            conserves_energy: true,
            direct_points: false,
        }
    }

    fn solve(
        &self,
        backend: &Backend<'_>,
        problem: &Problem<'_>,
        tolerance: &Tolerance,
        observer: &mut dyn FnMut(usize, f64),
    ) -> Result<Fluence, SolverError> {
        tolerance.validate()?;
        let cfg = self.config_for(problem, tolerance);
        let scaled = self.anisotropy.apply(problem.medium, problem.phase);
        let medium = scaled.as_ref().unwrap_or(problem.medium);
        super::solve(backend, medium, &Injection::none(), &cfg, |i, r| {
            observer(i, r)
        })
        .map(|s| s.erase())
    }

    fn kernels(&self) -> &'static [&'static crate::gpu::kernel::KernelSpec] {
        &[&super::gpu::SPEC]
    }

    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize {
        // 19 values read and 19 written per site (as `CpuLbm::bytes_per_step`).
        let word = precision.bytes();
        2 * Q * grid.len() * word
    }
}

/// Lattice-Boltzmann lighting (D3Q19).
pub const LBM: MethodFamily = MethodFamily {
    name: "lbm",
    title: "lattice-Boltzmann lighting (D3Q19)",
    paper: "Geist et al., Lattice-Boltzmann Lighting (LB Eqs 3–6, 13–19, Appendices A–B)",
    variants: "[paper|similarity]",
    params: &[],
    build: |variant, _params| match variant {
        None => Ok(Box::new(LbmMethod::default())),
        Some(v) => match AnisotropyScaling::parse(v) {
            Some(a) => Ok(Box::new(LbmMethod::default().with_anisotropy(a))),
            None => Err(SolverError::UnknownName {
                what: "variant of lbm",
                got: v.to_string(),
                known: "paper, similarity".into(),
            }),
        },
    },
};

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::method::{self, Problem};
    use crate::{Grid, Medium};

    #[test]
    fn the_anisotropy_variant_parses_and_round_trips() {
        for (spec, name) in [
            ("lbm", "lbm"),
            ("lbm:paper", "lbm"),
            ("LBM:Similarity", "lbm:similarity"),
        ] {
            let m = method::parse(spec).unwrap();
            assert_eq!(m.name(), name, "{spec}");
            assert_eq!(method::parse(&m.name()).unwrap().name(), name);
        }
        assert!(method::parse("lbm:bogus").is_err());
        let sim = method::parse("lbm:similarity").unwrap();
        assert_eq!(sim.anisotropy(), Some(AnisotropyScaling::Similarity));
        assert!(!sim.capabilities().anisotropic);
        assert!(method::parse("lbm").unwrap().capabilities().anisotropic);
    }

    /// A heterogeneous emissive medium (albedo 0.95, σt·Δl between 0.5 and 2.5).
    fn medium() -> Medium<f64> {
        let grid = Grid::new([10; 3], 0.1).unwrap();
        let mut m = Medium::<f64>::homogeneous(grid, 10.0, 0.95).unwrap();
        for (k, (st, j)) in m.sigma_t.iter_mut().zip(m.emission.iter_mut()).enumerate() {
            *st = 5.0 + 20.0 * ((k * 7919) % 101) as f64 / 100.0;
            *j = if k % 3 == 0 { 1.0 } else { 0.0 };
        }
        m
    }

    fn run(spec: &str, med: &Medium<f64>, phase: Phase) -> Vec<f64> {
        let p = Problem {
            medium: med,
            lights: &[],
            phase,
        };
        method::parse(spec)
            .unwrap()
            .solve(
                &Backend::Cpu(Precision::F64),
                &p,
                &Tolerance::rel(1e-6),
                &mut |_, _| {},
            )
            .unwrap()
            .phi
    }

    fn rel(a: &[f64], b: &[f64]) -> f64 {
        let n: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
        (n / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
    }

    /// At g = 0 the two variants are the same solve, bit for bit.
    #[test]
    fn at_g_zero_the_variants_are_identical() {
        let m = medium();
        let hg0 = Phase::HenyeyGreenstein { g: 0.0 };
        assert_eq!(run("lbm", &m, hg0), run("lbm:similarity", &m, hg0));
    }

    /// The similarity variant under HG g is the isotropic solve on the medium with
    /// σs' = (1 − g)σs, σt' = σa + σs' (built here from σs and σa, not by
    /// [`AnisotropyScaling::apply`]), and differs from the paper's lattice-HG solve
    /// (measured relative L2 distance of φ 0.058, 0.105, 0.071 at g = 0.3, 0.9, 0.99: as g → 1
    /// both stop scattering, σs' → 0 here and ḡ → 1 on the lattice, see
    /// `the_lattice_kernel_under_resolves_strong_anisotropy`).
    #[test]
    fn similarity_is_the_isotropic_solve_on_the_transport_scaled_medium() {
        let m = medium();
        for g in [0.3, 0.9, 0.99] {
            let mut scaled = m.clone();
            for (st, a) in scaled.sigma_t.iter_mut().zip(scaled.albedo.iter_mut()) {
                let (s, ab) = (*a * *st, (1.0 - *a) * *st);
                let s2 = (1.0 - g) * s;
                *st = ab + s2;
                *a = s2 / *st;
            }
            let hg = Phase::HenyeyGreenstein { g };
            let sim = run("lbm:similarity", &m, hg);
            let iso = run("lbm", &scaled, Phase::Isotropic);
            assert!(rel(&sim, &iso) < 1e-9, "g {g}: {}", rel(&sim, &iso));
            let paper = run("lbm", &m, hg);
            let d = rel(&sim, &paper);
            eprintln!("g {g}: similarity vs paper {d}");
            assert!(d > 0.01, "g {g}: similarity vs paper {d}");
        }
    }
}
