//! The steady RDE behind the [`Method`] interface: the registry entry `rde[:operator]`.
//!
//! The method runs the FTCS of [`crate::rde`] to its steady state on the problem's medium:
//! β = 1/(3σt∆) (g = 0, as the thesis fixes in Ch. 4 and as CDA scatters isotropically with
//! σs as given), a = (1 − α)σt∆, source q = the problem's emission, φ = 0 on the outermost
//! layer (as CDA). **Defaults** (a decision measured in the module docs of [`crate::rde`],
//! "β cap"): β capped at CDA's 1/(3σ_ε∆) ([`cda_beta_cap`]) instead of the thesis's 1, and
//! the local step r_p = 0.9/(a_p + Σβ_ps) (damped Jacobi), so the steady state is CDA's
//! system; `local=0` gives one global r = safety·r_G and `beta_max=1` the thesis's range.
//!
//! **Tolerance.** By default (`stop=1`) it stops when the estimated relative error of φ,
//! ‖φ_k − φ_{k−1}‖/‖φ_k‖ over blocks of 32 steps divided by 1 − ρ̂ (ρ̂ the measured block
//! contraction), is < [`Tolerance::rel`] (the module docs of [`crate::rde`], "Stopping rule":
//! FLD Eq 37's residual stopped 45–49 % from steady state on the albedo-1 cubes). `stop=0`
//! keeps the residual stop: R̄/j̄ < rel, with R_p = (φⁿ⁺¹_p − φⁿ_p)/(c∆t_p), FLD Eq 37's
//! residual of the same linear system CDA solves (the RMS over the same interior window,
//! normalised by the same j̄; code shared with [`crate::fld`]). `rel` = 0 runs exactly
//! `max_steps` steps.
//!
//! Variants: `conservative` (default), `expanded` (thesis Eq 4.8, sign fixed), `verbatim`
//! (thesis Eq 4.8 as printed; reproduction only, never in the atlas, which takes each
//! family's default). Parameters: `local`, `safety`, `r` (a fixed r = c∆t/∆, checked against
//! r_G), `beta_max` and `stop`.

use super::{Coefficients, Operator, RdeConfig, Run, SteadyStop, TimeStep};
use crate::method::{
    Capabilities, Fluence, LightInput, Method, MethodFamily, Params, Problem, Tolerance,
};
use crate::{Backend, Grid, Precision, SolverError};

/// The steady RDE with its settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RdeMethod {
    /// The solver settings; `run` is replaced by `Steady` with the [`Tolerance`] of each
    /// solve.
    pub config: RdeConfig,
    /// The cap on β = D/∆ ([`Coefficients::from_medium_capped`]); `None`: CDA's, β ≤
    /// 1/(3σ_ε∆) with FLD's σ_ε = 10⁻³/L (L the grid's longest edge), so that the steady
    /// state is CDA's.
    pub beta_max: Option<f64>,
}

impl Default for RdeMethod {
    /// Local time step (safety 0.9) and CDA's cap: see the module docs.
    fn default() -> Self {
        Self {
            config: RdeConfig::default()
                .with_time_step(TimeStep::Local { safety: 0.9 })
                .with_stop(SteadyStop::ErrorBound),
            beta_max: None,
        }
    }
}

/// CDA's cap on β = D/∆ on `grid`: 1/(3σ_ε∆) with σ_ε = 10⁻³/L (FLD Eq 33's floor, as
/// `FldConfig::sigma_eps` defaults).
pub fn cda_beta_cap(grid: &Grid) -> f64 {
    1.0 / (3.0 * (1e-3 / grid.extent()) * grid.dl)
}

impl RdeMethod {
    /// The settings of one solve.
    pub fn config_for(&self, tolerance: &Tolerance) -> RdeConfig {
        RdeConfig {
            run: Run::Steady {
                tolerance: Some(tolerance.rel),
                max_steps: tolerance.max_steps,
            },
            ..self.config.clone()
        }
    }

    fn with_params(mut self, params: &Params) -> Result<Self, SolverError> {
        if let Some(r) = params.get("r") {
            self.config.time_step = TimeStep::Fixed(r);
        }
        match params.get("local") {
            Some(0.0) => {
                let safety = params.get("safety").unwrap_or(0.9);
                if params.get("r").is_none() {
                    self.config.time_step = TimeStep::Gershgorin { safety };
                }
            }
            Some(_) | None => {
                if params.get("r").is_none() {
                    let safety = params.get("safety").unwrap_or(0.9);
                    self.config.time_step = TimeStep::Local { safety };
                }
            }
        }
        match params.get("stop") {
            None | Some(1.0) => self.config.stop = SteadyStop::ErrorBound,
            Some(0.0) => self.config.stop = SteadyStop::Residual,
            Some(v) => {
                return Err(SolverError::BadParameter {
                    name: "stop",
                    value: v,
                    reason: "0 (FLD Eq 37's residual R̄/j̄ < rel) or 1 (the error bound, default)",
                });
            }
        }
        if let Some(b) = params.get("beta_max") {
            if !(b.is_finite() && b >= super::BETA_MAX) {
                return Err(SolverError::BadParameter {
                    name: "beta_max",
                    value: b,
                    reason: "the β cap must be finite and ≥ 1",
                });
            }
            self.beta_max = Some(b);
        }
        self.config.validate()?;
        Ok(self)
    }
}

impl Method for RdeMethod {
    fn name(&self) -> String {
        match self.config.operator {
            Operator::Conservative => "rde".into(),
            op => format!("rde:{}", op.name()),
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
        let grid = problem.medium.grid;
        let cap = self.beta_max.unwrap_or_else(|| cda_beta_cap(&grid));
        let coef = Coefficients::from_medium_capped(problem.medium, 0.0, cap)?;
        let cfg = self.config_for(tolerance);
        super::solve(backend, &coef, &cfg, observer).map(|s| s.erase())
    }

    fn kernels(&self) -> &'static [&'static crate::gpu::kernel::KernelSpec] {
        &[&super::gpu::SPEC]
    }

    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize {
        // φ read and written, β, a, s read (and r_p with the local step): 5 or 6 values per
        // voxel, as `CpuRde::bytes_per_step`.
        let words = if matches!(self.config.time_step, TimeStep::Local { .. }) {
            6
        } else {
            5
        };
        words * grid.len() * precision.bytes()
    }
}

/// The thesis's unsteady radiance diffusion, stepped to its steady state.
pub const RDE: MethodFamily = MethodFamily {
    name: "rde",
    title: "unsteady radiance diffusion (RDE), FTCS to steady state",
    paper: "Murray, Legible Visualization of Semi-Transparent Objects (thesis Eqs 4.1–4.9)",
    variants: "conservative|expanded|verbatim",
    params: &[
        (
            "safety",
            "factor on the local (or, with local=0, the Gershgorin) time-step bound, in (0, 1]; default 0.9",
        ),
        (
            "r",
            "fixed r = c∆t/∆ (the thesis uses 0.1), rejected above r_G",
        ),
        (
            "local",
            "0: one global r = safety·r_G (the thesis's FTCS); 1 (default): local r_p = safety/(Ka∆ + Σβ_ps), damped Jacobi with the same steady state",
        ),
        (
            "stop",
            "1 (default): stop when the estimated relative error of φ, ‖φⁿ − φⁿ⁻³²‖/‖φⁿ‖/(1 − ρ̂), is < rel (ρ̂ the measured contraction per 32 steps); 0: FLD Eq 37's residual R̄/j̄ < rel",
        ),
        (
            "beta_max",
            "cap on β = D/∆, ≥ 1 (the thesis's range is 1); default CDA's 1/(3σ_ε∆)",
        ),
    ],
    build: |variant, params| {
        let operator = match variant {
            None | Some("conservative") => Operator::Conservative,
            Some("expanded") => Operator::ThesisExpanded,
            Some("verbatim") => Operator::ThesisVerbatim,
            Some(v) => {
                return Err(SolverError::UnknownName {
                    what: "variant of rde",
                    got: v.to_string(),
                    known: "conservative, expanded, verbatim".into(),
                });
            }
        };
        Ok(Box::new(
            RdeMethod {
                config: RdeMethod::default().config.with_operator(operator),
                ..RdeMethod::default()
            }
            .with_params(params)?,
        ))
    },
};
