//! Lattice-Boltzmann lighting behind the [`Method`] interface: the registry entry `lbm`.
//!
//! The method runs LB in its transport configuration ([`LbmConfig::transport`]: absorbed
//! light leaves, renormalised HG with the problem's phase function, exponential σ mapping).
//! The problem's source q (its emission field: q_ri + j in the pipeline) enters as an
//! isotropic volume source, so φ is, as for CDA and FLD, the fluence of light scattered at
//! least once. No light is injected at the boundary ([`Injection::none`]).
//!
//! **Tolerance.** It stops when the relative change of the total lattice density per step is
//! below [`Tolerance::rel`] × 10⁻² (the diffusion default 10⁻⁴ gives 10⁻⁶): a per-step change
//! is a much smaller number than the error it leaves, and this is the mapping the pipeline has
//! used since LB joined it (`results/accuracy_cost`: LBM's image error changes by 3·10⁻⁶
//! between rel = 10⁻³ and 10⁻⁴ on nebula at downsample 4).

use super::{Injection, LbmConfig, Q};
use crate::method::{Capabilities, Fluence, LightInput, Method, MethodFamily, Problem, Tolerance};
use crate::{Backend, Grid, Precision, SolverError};

/// The factor from [`Tolerance::rel`] to LB's per-step relative density change.
pub const TOLERANCE_FACTOR: f64 = 1e-2;

/// Lattice-Boltzmann lighting with its settings.
#[derive(Debug, Clone, PartialEq)]
pub struct LbmMethod {
    /// The solver settings; `phase` is replaced by the problem's, `tolerance` and
    /// `max_steps` by the [`Tolerance`] of each solve.
    pub config: LbmConfig,
}

impl Default for LbmMethod {
    fn default() -> Self {
        Self {
            config: LbmConfig::transport(),
        }
    }
}

impl LbmMethod {
    /// The solver settings of one solve.
    pub fn config_for(&self, problem: &Problem<'_>, tolerance: &Tolerance) -> LbmConfig {
        LbmConfig {
            phase: problem.phase,
            tolerance: Some(tolerance.rel * TOLERANCE_FACTOR),
            max_steps: tolerance.max_steps,
            ..self.config.clone()
        }
    }
}

impl Method for LbmMethod {
    fn name(&self) -> String {
        "lbm".into()
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            gpu: true,
            f64: true,
            volume_source: true,
            anisotropic: true,
            lights: LightInput::Baked,
            conserves_energy: true,
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
        super::solve(backend, problem.medium, &Injection::none(), &cfg, |i, r| {
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
    variants: "",
    params: &[],
    build: |variant, _params| match variant {
        None => Ok(Box::new(LbmMethod::default())),
        Some(v) => Err(SolverError::UnknownName {
            what: "variant of lbm",
            got: v.to_string(),
            known: "none".into(),
        }),
    },
};
