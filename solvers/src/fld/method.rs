//! CDA and FLD behind the [`Method`] interface: the registry entries `cda` and `fld[:limiter]`.
//!
//! The method solves FLD Eq 20 (CDA: FLD Eq 12) with zero Dirichlet values on the solve grid's
//! outermost layer (FLD Section 5), source q = the problem's emission field, and stops when
//! R̄/j̄ (FLD Eq 37) < [`Tolerance::rel`]. Its defaults are the pipeline's: ω = 1.8 (measured
//! against 1.0 and 1.5 on `nebula` and `shell_core`, see
//! [`crate::pipeline::PipelineConfig::tolerance`]), θ = 0.5 and the other settings of
//! [`FldConfig::default`]. Parameters: `omega` (SOR factor ω, FLD Eq 36) and `theta` (the
//! under-relaxation of the D update, see the module docs of [`crate::fld`]).

use super::multigrid::{CpuMultigrid, MgConfig};
use super::{Boundary, FldConfig, FluxLimiter};
use crate::method::{
    Capabilities, Fluence, LightInput, Method, MethodFamily, Params, Problem, Tolerance,
};
use crate::{Backend, Grid, Precision, SolverError};

/// CDA or FLD with one limiter and its solver settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FldMethod {
    /// The solver settings; `tolerance` and `max_iterations` are replaced by the
    /// [`Tolerance`] of each solve.
    pub config: FldConfig,
    /// `Some`: solve by FAS multigrid ([`super::multigrid`], CPU only) instead of SOR.
    pub multigrid: Option<MgConfig>,
}

impl FldMethod {
    /// The method with the pipeline's defaults (ω = 1.8) and this limiter.
    pub fn new(limiter: FluxLimiter) -> Self {
        Self {
            config: FldConfig {
                limiter,
                ..FldConfig::default()
            }
            .with_omega(1.8),
            multigrid: None,
        }
    }

    /// The same method solved by FAS multigrid with default cycle settings.
    pub fn multigrid(mut self) -> Self {
        self.multigrid = Some(MgConfig::default());
        self
    }

    /// The solver settings of one solve.
    pub fn config_for(&self, tolerance: &Tolerance) -> FldConfig {
        FldConfig {
            tolerance: Some(tolerance.rel),
            max_iterations: tolerance.max_steps,
            ..self.config.clone()
        }
    }

    fn with_params(mut self, params: &Params) -> Result<Self, SolverError> {
        if let Some(w) = params.get("omega") {
            self.config.omega = w;
        }
        if let Some(t) = params.get("theta") {
            self.config.d_relaxation = t;
        }
        self.config.validate()?;
        Ok(self)
    }
}

impl Method for FldMethod {
    fn name(&self) -> String {
        let base = match self.config.limiter {
            FluxLimiter::Cda => "cda".to_string(),
            l => format!("fld:{l}"),
        };
        match self.multigrid {
            Some(_) => format!("{base}:mg"),
            None => base,
        }
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            gpu: true,
            f64: true,
            volume_source: true,
            anisotropic: false,
            lights: LightInput::Baked,
            conserves_energy: false,
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
        let cfg = self.config_for(tolerance);
        if let Some(mg) = &self.multigrid {
            let obs = |i, r| observer(i, r);
            return match backend {
                Backend::Cpu(Precision::F64) => {
                    Ok(
                        CpuMultigrid::new(problem.medium, &Boundary::Zero, &cfg, mg)?
                            .solve_observed(obs)
                            .erase(),
                    )
                }
                Backend::Cpu(Precision::F32) => Ok(CpuMultigrid::<f32>::new(
                    &problem.medium.cast(),
                    &Boundary::Zero,
                    &cfg,
                    mg,
                )?
                .solve_observed(obs)
                .widen_with(|t| t)
                .erase()),
                Backend::Gpu(_) => Err(SolverError::Unsupported(format!(
                    "{}: multigrid runs on the CPU only (GPU multigrid is not implemented)",
                    self.name()
                ))),
            };
        }
        super::solve(backend, problem.medium, &Boundary::Zero, &cfg, |i, r| {
            observer(i, r)
        })
        .map(|s| s.erase())
    }

    fn kernels(&self) -> &'static [&'static crate::gpu::kernel::KernelSpec] {
        &[&super::gpu::SPEC]
    }

    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize {
        // Words per voxel and iteration as `CpuFld::bytes_per_iteration` counts them: 7 for
        // a constant limiter (CDA), 9 for FLD (the D update reads and writes more).
        let word = precision.bytes();
        let per_voxel = if self.config.limiter.is_constant() {
            7
        } else {
            9
        };
        grid.len() * per_voxel * word
    }
}

const PARAMS: &[(&str, &str)] = &[
    ("omega", "SOR factor ω ∈ (0, 2) (FLD Eq 36); default 1.8"),
    (
        "theta",
        "under-relaxation θ ∈ (0, 1] of the D update; default 0.5, 1 = FLD Algorithm 1 verbatim",
    ),
];

/// Classical diffusion: FLD's solver with the constant limiter 1/3 (FLD Eq 12, Section 6.1).
pub const CDA: MethodFamily = MethodFamily {
    name: "cda",
    title: "classical diffusion (CDA), red-black SOR",
    paper: "Koerner et al., Flux-Limited Diffusion (FLD Eqs 11–12, 26–27, 30–37, Algorithm 1)",
    variants: "mg",
    params: PARAMS,
    build: |variant, params| match variant {
        None => Ok(Box::new(
            FldMethod::new(FluxLimiter::Cda).with_params(params)?,
        )),
        Some("mg") => Ok(Box::new(
            FldMethod::new(FluxLimiter::Cda)
                .multigrid()
                .with_params(params)?,
        )),
        Some(v) => Err(SolverError::UnknownName {
            what: "variant of cda",
            got: v.to_string(),
            known: "mg".into(),
        }),
    },
};

/// Flux-limited diffusion with one of the five limiters of FLD Table 2 (default
/// Levermore–Pomraning, the paper's choice).
pub const FLD: MethodFamily = MethodFamily {
    name: "fld",
    title: "flux-limited diffusion (FLD), red-black SOR",
    paper: "Koerner et al., Flux-Limited Diffusion (FLD Eqs 15–20, Table 2, Algorithm 1)",
    variants: "lp|sum|max|kershaw|larsen<n>[:mg]",
    params: PARAMS,
    build: |variant, params| {
        let (variant, mg) = match variant {
            Some("mg") => (None, true),
            Some(v) => match v.strip_suffix(":mg") {
                Some(l) => (Some(l), true),
                None => (Some(v), false),
            },
            None => (None, false),
        };
        let limiter = match variant {
            None => FluxLimiter::LevermorePomraning,
            Some(v) => v.parse()?,
        };
        let m = FldMethod::new(limiter);
        let m = if mg { m.multigrid() } else { m };
        Ok(Box::new(m.with_params(params)?))
    },
};
