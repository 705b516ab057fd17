//! One interface for every multiple-scattering method, and one registry of them.
//!
//! A method solves one kind of [`Problem`]: a medium on its solve grid (restricted and padded
//! by the pipeline), whose `emission` field is the volume source q (power per unit volume:
//! q_ri = σs·L_ri of the baked lights, FLD Eq 6, plus the emission j if it is rendered), the
//! scene's lights (for methods that take lights themselves) and its phase function. It returns
//! one [`Solution`]: the fluence φ on that grid with the steps it took, its last convergence
//! measure, why it stopped ([`Stop`]) and its timings.
//!
//! [`METHODS`] lists every method family. Everything that offers a choice of method reads it:
//! the pipeline's multiple-scattering pass ([`crate::pipeline`]), the planner (from
//! [`Method::capabilities`]), `render --method`, `renderings --methods`, the accuracy atlas,
//! the benches and the generic conformance suite (`solvers/tests/conformance.rs`,
//! `method_conformance!`). Adding a method is its module folder plus one line here.
//!
//! ## Names
//! A method is named `family[:variant]`, case-insensitive: `cda`, `fld` (= `fld:lp`, the
//! paper's Levermore–Pomraning limiter), `fld:<limiter>`, `lbm`, each with an anisotropy
//! variant `:paper` (the default, not printed) or `:similarity` ([`AnisotropyScaling`]).
//! [`parse`] turns a name into a method with the family's defaults; [`parse_with`] also
//! takes named numeric parameters (`omega=1.5`), each family listing those it accepts
//! ([`MethodFamily::params`]); an unknown name or parameter is a typed
//! [`SolverError::UnknownName`] that lists what exists.
//!
//! ## One tolerance
//! [`Tolerance::rel`] is the stopping level of the method's own convergence measure, which
//! is its [`Solution::last_change`]; each family states how it maps `rel` (FLD: the
//! normalised residual R̄/j̄ < rel, FLD Eq 37; LBM: the relative change of the total lattice
//! density per step < rel·10⁻², the mapping the pipeline has used since LBM joined it, see
//! [`crate::lbm::method`]). At the same `rel` the methods stop well inside their own
//! discretisation error: in the committed atlas (`results/accuracy_cost/points.csv`, nebula at
//! downsample 4, f32) the image error changes between rel = 10⁻³ and 10⁻⁴ by 3·10⁻⁶ (LBM,
//! 0.124906 → 0.124910), 1·10⁻⁶ (CDA) and 7·10⁻⁶ (FLD-LP, 0.241700 → 0.241692), while the
//! methods differ from each other by 0.1–0.4. [`Tolerance::max_steps`] caps the steps of
//! every method; a
//! solve that stops there reports [`Stop::Cap`], not an error.

use crate::gpu::Timer;
use crate::gpu::kernel::KernelSpec;
use crate::scene::{Light, Phase};
use crate::{Backend, Grid, Medium, Precision, Real, SolverError};
use serde::Serialize;
use std::fmt;
use std::sync::Arc;

/// The input of a multiple-scattering solve.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// σt and albedo on the solve grid; its `emission` is the volume source q (power per
    /// unit volume). The outermost voxel layer is the boundary of grid methods.
    pub medium: &'a Medium<f64>,
    /// The scene's lights, in the medium's frame. Read only by methods whose
    /// [`Capabilities::lights`] is [`LightInput::Direct`]; for the others the pipeline has
    /// baked them into the source.
    pub lights: &'a [Light],
    /// The phase function (read by methods with [`Capabilities::anisotropic`]).
    pub phase: Phase,
}

/// When a solve stops; one meaning for every method (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Stopping level of the method's convergence measure ([`Solution::last_change`]).
    /// 0 runs exactly `max_steps` steps.
    pub rel: f64,
    /// Step cap (iterations of FLD, lattice steps of LBM).
    pub max_steps: usize,
}

impl Default for Tolerance {
    /// R̄/j̄ < 10⁻⁴ (the paper's level for its renderings, FLD Section 6.2), at most 20 000
    /// steps.
    fn default() -> Self {
        Self {
            rel: 1e-4,
            max_steps: 20_000,
        }
    }
}

impl Tolerance {
    /// `rel` with the default step cap.
    pub fn rel(rel: f64) -> Self {
        Self {
            rel,
            ..Self::default()
        }
    }

    /// Exactly `n` steps (no convergence test).
    pub fn fixed_steps(n: usize) -> Self {
        Self {
            rel: 0.0,
            max_steps: n,
        }
    }

    /// Checks both fields.
    pub fn validate(&self) -> Result<(), SolverError> {
        if !(self.rel.is_finite() && self.rel >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "tolerance",
                value: self.rel,
                reason: "must be finite and ≥ 0",
            });
        }
        Ok(())
    }
}

/// Why a solve stopped (every method).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stop {
    /// The convergence measure fell below the tolerance.
    Converged,
    /// The step cap was reached first.
    Cap,
    /// The solution or its convergence measure became NaN or infinite (reported, not hidden).
    NonFinite,
    /// The iteration stopped making progress before the tolerance (multigrid: no cycle
    /// reduced the best residual by 10 % within the stall window). Never a "converged".
    Stalled,
}

impl fmt::Display for Stop {
    /// `converged`, `cap` or `non_finite` (as in JSON).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stop::Converged => "converged",
            Stop::Cap => "cap",
            Stop::NonFinite => "non_finite",
            Stop::Stalled => "stalled",
        })
    }
}

/// The result of a solve, for every method. `T` is the precision φ is held in; `E` holds what
/// only one method has (FLD: the residual history; LBM: the lattice density and per-step
/// totals); [`Fluence`] is the method-independent form [`Method::solve`] returns.
#[derive(Debug, Clone)]
pub struct Solution<T, E = ()> {
    /// The grid φ lives on.
    pub grid: Grid,
    /// Fluence φ per voxel (power per unit area; x fastest), boundary layer included.
    pub phi: Vec<T>,
    /// Steps run (FLD iterations, LBM lattice steps).
    pub steps: usize,
    /// The method's convergence measure after the last step (FLD: R̄/j̄; LBM: the relative
    /// change of the total lattice density per step); NaN if no step ran or it is unknown.
    pub last_change: f64,
    /// Why it stopped.
    pub stop: Stop,
    /// Wall-clock seconds of the steps (setup excluded; see `timer`).
    pub seconds: f64,
    /// Wall-clock seconds of setup (packing the medium; GPU: also uploads and pipelines).
    pub setup_seconds: f64,
    /// How `seconds` was measured.
    pub timer: Timer,
    /// Power balance of the last step, for methods that define an outflow (LBM); `None`
    /// for the others.
    pub balance: Option<Balance>,
    /// Method-specific results.
    pub trace: E,
}

/// Power per step of a method that tracks where light goes: what the source injected, what
/// left the grid and what was absorbed. At steady state source = outflow + absorbed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Balance {
    /// Injected by the volume source (and boundary inflow).
    pub source: f64,
    /// Streamed out of the grid.
    pub outflow: f64,
    /// Absorbed.
    pub absorbed: f64,
}

/// φ in f64 without method-specific extras: what [`Method::solve`] returns.
pub type Fluence = Solution<f64>;

impl<T, E> Solution<T, E> {
    /// Whether the tolerance was reached.
    pub fn converged(&self) -> bool {
        self.stop == Stop::Converged
    }

    /// The same solution without its method-specific part.
    pub fn erase(self) -> Solution<T> {
        self.map_trace(|_| ())
    }

    /// Replaces the method-specific part.
    pub fn map_trace<F>(self, f: impl FnOnce(E) -> F) -> Solution<T, F> {
        self.map(|phi| phi, f)
    }

    /// Maps φ and the method-specific part, keeping everything else.
    pub fn map<U, F>(
        self,
        phi: impl FnOnce(Vec<T>) -> Vec<U>,
        trace: impl FnOnce(E) -> F,
    ) -> Solution<U, F> {
        Solution {
            grid: self.grid,
            phi: phi(self.phi),
            steps: self.steps,
            last_change: self.last_change,
            stop: self.stop,
            seconds: self.seconds,
            setup_seconds: self.setup_seconds,
            timer: self.timer,
            balance: self.balance,
            trace: trace(self.trace),
        }
    }
}

impl<T: Real, E> Solution<T, E> {
    /// φ in f64; `f` widens the method-specific part.
    pub fn widen_with<F>(self, f: impl FnOnce(E) -> F) -> Solution<f64, F> {
        self.map(|phi| phi.iter().map(|x| x.f()).collect(), f)
    }
}

/// The CPU precision a CPU-only method or variant (today `lpm:paper`, whose deposit has no
/// GPU kernel) runs `backend` in, or a typed [`SolverError::Unsupported`] naming `name` on
/// the GPU.
pub fn cpu_precision(name: &str, backend: &Backend<'_>) -> Result<Precision, SolverError> {
    match backend {
        Backend::Cpu(p) => Ok(*p),
        Backend::Gpu(_) => Err(SolverError::Unsupported(format!(
            "{name}: the GPU kernel is not implemented yet (CPU only)"
        ))),
    }
}

/// How a method receives the scene's lights, and what its φ then holds.
///
/// ## The contract of φ
/// Let φ_s be the fluence of light that has scattered at least once, and let every method
/// return φ such that the pipeline's σs·φ/4π (FLD Eq 8) is the radiance of the effect
/// `multiple` (orders ≥ 2 from the lights, orders ≥ 1 from emission) with no effect counted
/// twice:
/// * [`LightInput::Baked`]: the pipeline bakes each directional or point light into the volume
///   source q_ri = σs·L_ri (FLD Eq 6, order 1); φ is the fluence sourced by q_ri (+ j), i.e.
///   φ_s of the lights plus the emission's fluence of orders ≥ 0.
/// * [`LightInput::Direct`]: the pipeline bakes nothing for the method. It hands it
///   [`Problem::lights`] (in the medium's frame; the emission j, when rendered, is still
///   the volume source) and the method returns
///   - for each **directional** light: φ_s only — its uncollided fluence E·e^{−τ} removed,
///     because the pipeline renders that light's single scattering by its exact raymarch
///     with the scene's phase function (the effect `single_scattering[i]` is the raymarch's);
///   - for each **environment** light: its fluence of every order, uncollided included,
///     because the grid pipeline has no single-scattering raymarch for an environment: the
///     effect `single_scattering[i]` of an environment light is the method's, rendered as
///     σs·φ/4π (isotropic in-scattering of the uncollided light; the plan warns under
///     anisotropy). The environment seen directly (`background`) stays the raymarch's;
///   - plus, with emission, the emission's fluence of orders ≥ 0, as for `Baked`.
///
///   - for each **point** light, when the method takes them ([`Capabilities::direct_points`]:
///     POP's radial grids): φ_s only, its uncollided fluence P·e^{−τ}/(4πr²) removed, as for
///     a directional light (the pipeline's raymarch renders its single scattering).
///
/// Sphere lights, and point lights of a method without `direct_points`, are refused with
/// [`SolverError::LightKind`] naming the light ([`direct_lights`]).
///
/// The planner records per pass which effects it computes ([`crate::pipeline::Planned`]'s
/// `computes`); `pipeline::tests::direct_lpm_counts_every_effect_once` checks the contract
/// numerically against the baked path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LightInput {
    /// The pipeline bakes each light into the volume source q_ri = σs·L_ri (FLD Eq 6); φ is
    /// the fluence of light scattered at least once.
    Baked,
    /// The method reads [`Problem::lights`] itself (propagation methods such as LPM, POP);
    /// φ as in the contract above.
    Direct,
}

/// A light as a [`LightInput::Direct`] method takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DirectLight {
    /// A collimated beam of `irradiance` travelling along the unit `direction`; the method
    /// removes its uncollided fluence from φ.
    Directional {
        /// Index in [`Problem::lights`].
        index: usize,
        /// Unit direction of travel.
        direction: [f64; 3],
        /// Irradiance perpendicular to it.
        irradiance: f64,
    },
    /// A constant environment of `radiance`; φ keeps its uncollided fluence.
    Environment {
        /// Index in [`Problem::lights`].
        index: usize,
        /// Radiance.
        radiance: f64,
    },
    /// An isotropic point light of total `power` at `position` (only for a method with
    /// [`Capabilities::direct_points`]); as for a directional light, the method removes its
    /// uncollided fluence P·e^{−τ}/(4πr²) from φ.
    Point {
        /// Index in [`Problem::lights`].
        index: usize,
        /// Position, in the medium's frame.
        position: [f64; 3],
        /// Power (W), 4π times the intensity.
        power: f64,
    },
}

/// The lights of `problem` as a Direct method of name `method` takes them: directional and
/// environment lights, and point lights when `points` ([`Capabilities::direct_points`]);
/// any other point light, and every sphere light, is [`SolverError::LightKind`] naming it.
pub fn direct_lights(
    method: &str,
    lights: &[Light],
    points: bool,
) -> Result<Vec<DirectLight>, SolverError> {
    lights
        .iter()
        .enumerate()
        .map(|(index, l)| match *l {
            Light::Directional {
                direction,
                irradiance,
            } => Ok(DirectLight::Directional {
                index,
                direction,
                irradiance,
            }),
            Light::Environment { radiance } => Ok(DirectLight::Environment { index, radiance }),
            Light::Point { position, power } if points => Ok(DirectLight::Point {
                index,
                position,
                power,
            }),
            Light::Point { .. } => Err(SolverError::LightKind {
                method: method.to_string(),
                index,
                kind: "point",
            }),
            Light::Sphere { .. } => Err(SolverError::LightKind {
                method: method.to_string(),
                index,
                kind: "sphere",
            }),
        })
        .collect()
}

/// The uncollided fluence Σ E·e^{−τ(x)} of the directional lights at the voxel centres of
/// `medium` (τ exact for the piecewise-constant σt, the pipeline's deep shadow map): what a
/// Direct method whose own φ includes the uncollided beam subtracts (POP).
pub fn uncollided_directional(medium: &Medium<f64>, lights: &[DirectLight]) -> Vec<f64> {
    let g = medium.grid;
    let mut out = vec![0.0; g.len()];
    for l in lights {
        if let DirectLight::Directional {
            index,
            direction,
            irradiance,
        } = *l
        {
            let light = Light::Directional {
                direction,
                irradiance,
            };
            if let Some(b) = crate::pipeline::bake::bake(medium, index, &light) {
                out.iter_mut()
                    .enumerate()
                    .for_each(|(i, v)| *v += b.at_voxel(&g, i));
            }
        }
    }
    out
}

/// What a method supports; the planner, the atlas and the conformance suite read this
/// instead of knowing methods by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Capabilities {
    /// Runs on [`Backend::Gpu`].
    pub gpu: bool,
    /// Runs on [`Backend::Cpu`] in f64 (f32 on the CPU is always supported).
    pub f64: bool,
    /// Takes a volume source ([`Problem::medium`]'s emission); without it, emission cannot
    /// be multiply scattered by this method.
    pub volume_source: bool,
    /// Sees the phase function (otherwise it scatters isotropically with σs as given).
    pub anisotropic: bool,
    /// How it receives the lights.
    pub lights: LightInput,
    /// Defines an outflow whose balance with the source holds at albedo 1 (the conformance
    /// suite's energy test runs when true).
    pub conserves_energy: bool,
    /// With [`LightInput::Direct`]: takes point lights itself ([`DirectLight::Point`]; POP's
    /// radial grids). Without it a Direct method refuses them ([`direct_lights`]); a
    /// [`LightInput::Baked`] method gets every point light baked and ignores this.
    pub direct_points: bool,
}

impl Capabilities {
    /// Whether the method runs on `backend`.
    pub fn supports(&self, backend: &Backend<'_>) -> bool {
        match backend {
            Backend::Gpu(_) => self.gpu,
            Backend::Cpu(Precision::F64) => self.f64,
            Backend::Cpu(Precision::F32) => true,
        }
    }
}

/// Fixed step counts of a method that are settings of their own: a method whose step has a
/// meaning beyond "one more iteration toward convergence" says so here, and the accuracy
/// atlas renders it at each count (run with [`Tolerance::fixed_steps`]) beside its tolerance
/// ladder. LPM: one step is one scattering order (LPM §3.1, spec §1.7), and the paper renders
/// with a fixed 3 (Alg 2). Iterative solvers (CDA, FLD, LBM, RDE) have none: a fixed count
/// of their iterations is only a badly converged solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct StepSettings {
    /// What one step is, plural, for table headers (`scattering orders`).
    pub unit: &'static str,
    /// The counts to show, strictly ascending, each ≥ 1.
    pub counts: &'static [usize],
}

/// How a diffusion-type method (CDA, FLD, LBM) treats an anisotropic phase function
/// (issue 12, item 2): `paper` (its paper's use) or `similarity` (a spec suffix, e.g.
/// `fld:lp:similarity`, `lbm:similarity`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AnisotropyScaling {
    /// The papers' use of σs as given: CDA and FLD scatter isotropically (the phase function
    /// is ignored); LBM scatters with the lattice's Henyey–Greenstein kernel (LB Section 4).
    #[default]
    Paper,
    /// The similarity (transport) scaling σs' = (1 − g)σs, σt' = σa + σs' with isotropic
    /// scattering. A method scales the medium of its [`Problem`] and takes its source q as
    /// given; the pipeline gives it the δ-scaled source, its lights baked through the scaled
    /// medium and scattered at σs' (`q_ri = σs'·L_ri'`, see [`crate::pipeline`]).
    Similarity,
}

impl AnisotropyScaling {
    /// The variant's name in a method spec: `paper` or `similarity`.
    pub fn name(&self) -> &'static str {
        match self {
            AnisotropyScaling::Paper => "paper",
            AnisotropyScaling::Similarity => "similarity",
        }
    }

    /// Parses `paper` or `similarity` (case-insensitive); `None` for anything else.
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "paper" => Some(AnisotropyScaling::Paper),
            "similarity" => Some(AnisotropyScaling::Similarity),
            _ => None,
        }
    }

    /// The medium the method solves on: `None` (the medium as given) for [`Self::Paper`] or
    /// g = 0; for [`Self::Similarity`], σt' = σt(1 − αg) and α' = α(1 − g)/(1 − αg), i.e.
    /// σs' = (1 − g)σs and σa unchanged, with the emission (the source) unchanged.
    pub fn apply(&self, medium: &Medium<f64>, phase: Phase) -> Option<Medium<f64>> {
        let g = phase.mean_cosine();
        if *self == AnisotropyScaling::Paper || g == 0.0 {
            return None;
        }
        let mut m = medium.clone();
        for (st, a) in m.sigma_t.iter_mut().zip(m.albedo.iter_mut()) {
            let keep = 1.0 - *a * g;
            *st *= keep;
            *a = if keep > 0.0 {
                (*a * (1.0 - g) / keep).clamp(0.0, 1.0)
            } else {
                0.0
            };
        }
        Some(m)
    }
}

impl fmt::Display for AnisotropyScaling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A multiple-scattering method with its settings.
pub trait Method: fmt::Debug + Send + Sync {
    /// Its name: `family[:variant]`, parseable by [`parse`] (e.g. `fld:lp`, `cda`, `lbm`).
    fn name(&self) -> String;

    /// What it supports.
    fn capabilities(&self) -> Capabilities;

    /// Solves `problem` on `backend` until `tolerance`. `observer(step, measure)` sees the
    /// convergence measure as it is computed (every step on the CPU, every checkpoint on the
    /// GPU). A backend the method does not support is [`SolverError::Unsupported`].
    fn solve(
        &self,
        backend: &Backend<'_>,
        problem: &Problem<'_>,
        tolerance: &Tolerance,
        observer: &mut dyn FnMut(usize, f64),
    ) -> Result<Fluence, SolverError>;

    /// Bytes one step reads and writes on `grid` in `precision` (the benches' bandwidth
    /// figure).
    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize;

    /// Its GPU kernels' declarations, checked against their WGSL by the contract test
    /// (`solvers/tests/kernel_contract.rs`); none by default.
    fn kernels(&self) -> &'static [&'static KernelSpec] {
        &[]
    }

    /// How it uses σs under an anisotropic phase function, for methods that scatter
    /// isotropically and offer the choice ([`AnisotropyScaling`]); `None` for the others.
    fn anisotropy(&self) -> Option<AnisotropyScaling> {
        None
    }

    /// Its fixed step counts worth a setting of their own ([`StepSettings`]); `None` (the
    /// default) when a step is only an iteration toward convergence.
    fn step_settings(&self) -> Option<StepSettings> {
        None
    }

    /// Settings of its own parameters worth points of their own in the accuracy atlas
    /// ([`ParamSetting`]; POP: 8 and 216 ordinates per environment light and for emission, and its residuum
    /// variants); none by default. Each is rendered at the atlas's converged setting and at
    /// its [`Method::step_settings`] counts.
    fn param_settings(&self) -> Vec<ParamSetting> {
        Vec::new()
    }

    /// The same method taking the pipeline's baked lights ([`LightInput::Baked`]) instead of
    /// the scene's lights, for a [`LightInput::Direct`] method that has that form (LPM:
    /// `lpm:baked`, spec D13's first-collision injection). A caller that must render a scene
    /// whose lights the method refuses (point and sphere lights, [`direct_lights`]) uses it;
    /// `None` (the default) when there is no such form.
    fn with_baked_lights(&self) -> Option<Box<dyn Method>> {
        None
    }

    /// The face coefficient its solve uses between medium and vacuum voxels; the pipeline's
    /// raymarch reconstructs φ inside a surface voxel from it (see [`crate::pipeline`]). The
    /// paper's face by default.
    fn vacuum_face(&self) -> crate::fld::VacuumFace {
        crate::fld::VacuumFace::Paper
    }
}

/// A setting of a method's own parameters, or a variant of it, that the accuracy atlas
/// renders beside the method's defaults ([`Method::param_settings`]). The atlas records the
/// point under `method.name()` and appends `label` to its setting when the name is the
/// defaults' (a parameter such as `ordinates=8`).
#[derive(Debug)]
pub struct ParamSetting {
    /// What it sets, e.g. `ordinates=8`, or the variant's name (`pop:residuum`).
    pub label: String,
    /// The method with that setting.
    pub method: Box<dyn Method>,
    /// It changes the result only where a scene has an environment light or volume emission
    /// (POP's ordinate set, which both are spread over): the atlas renders it on such scenes
    /// only.
    pub ordinate_set_only: bool,
}

/// Named numeric parameters of a method (`omega=1.5`); a family consumes the ones it knows
/// and rejects the rest.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params(Vec<(String, f64)>);

impl Params {
    /// No parameters.
    pub fn none() -> Self {
        Self::default()
    }

    /// Builder: one more parameter (names are case-insensitive).
    pub fn with(mut self, name: &str, value: f64) -> Self {
        self.0.push((name.trim().to_ascii_lowercase(), value));
        self
    }

    /// Parses `name=value` strings.
    pub fn parse<'s>(items: impl IntoIterator<Item = &'s str>) -> Result<Self, SolverError> {
        let mut p = Self::none();
        for item in items {
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| SolverError::UnknownName {
                    what: "method parameter (expected name=value)",
                    got: item.to_string(),
                    known: String::new(),
                })?;
            let value: f64 = v.trim().parse().map_err(|_| SolverError::BadParameter {
                name: "method parameter",
                value: f64::NAN,
                reason: "the value after `=` must be a number",
            })?;
            p = p.with(k, value);
        }
        Ok(p)
    }

    /// The value of `name`, if given.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.0
            .iter()
            .rev()
            .find(|(k, _)| k == name)
            .map(|(_, v)| *v)
    }

    /// Fails with [`SolverError::UnknownName`] if a parameter is not in `known`.
    pub fn only(&self, family: &MethodFamily) -> Result<(), SolverError> {
        match self
            .0
            .iter()
            .find(|(k, _)| !family.params.iter().any(|(n, _)| n == k))
        {
            None => Ok(()),
            Some((k, _)) => Err(SolverError::UnknownName {
                what: "method parameter",
                got: format!("{k} (method {})", family.name),
                known: if family.params.is_empty() {
                    "none".into()
                } else {
                    family
                        .params
                        .iter()
                        .map(|(n, _)| *n)
                        .collect::<Vec<_>>()
                        .join(", ")
                },
            }),
        }
    }
}

/// How a family builds a method from its variant (`None` if no `:`) and parameters.
pub type BuildFn =
    fn(variant: Option<&str>, params: &Params) -> Result<Box<dyn Method>, SolverError>;

/// A registered method family: its names, its paper and how to build it.
#[derive(Debug)]
pub struct MethodFamily {
    /// Name before the `:` (lower case).
    pub name: &'static str,
    /// One line for `--help` and the README.
    pub title: &'static str,
    /// The paper and the equations it implements (cite as in the papers' index).
    pub paper: &'static str,
    /// The variants after the `:` (empty: none), for help texts.
    pub variants: &'static str,
    /// Named parameters it accepts, with a description each.
    pub params: &'static [(&'static str, &'static str)],
    /// Builds the method from its variant (`None` if no `:`) and parameters.
    pub build: BuildFn,
}

/// Every method family. Add one line per family.
pub static METHODS: &[MethodFamily] = &[
    crate::fld::CDA,
    crate::fld::FLD,
    crate::lbm::LBM,
    crate::lpm::LPM,
    crate::pop::POP,
    crate::rde::RDE,
];

/// The names of every family, with their variants, for help texts and errors: `cda, fld[:…], lbm`.
pub fn names() -> String {
    METHODS
        .iter()
        .map(|f| {
            if f.variants.is_empty() {
                f.name.to_string()
            } else {
                format!("{}[:{}]", f.name, f.variants)
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The family registered under `name` (case-insensitive).
pub fn family(name: &str) -> Option<&'static MethodFamily> {
    let name = name.trim().to_ascii_lowercase();
    METHODS.iter().find(|f| f.name == name)
}

/// A method by name with its family's defaults (see the module docs).
pub fn parse(spec: &str) -> Result<Box<dyn Method>, SolverError> {
    parse_with(spec, &Params::none())
}

/// A method by name with named parameters.
pub fn parse_with(spec: &str, params: &Params) -> Result<Box<dyn Method>, SolverError> {
    let spec = spec.trim().to_ascii_lowercase();
    let (name, variant) = match spec.split_once(':') {
        Some((n, v)) => (n, Some(v.trim())),
        None => (spec.as_str(), None),
    };
    let fam = family(name).ok_or_else(|| SolverError::UnknownName {
        what: "method",
        got: spec.clone(),
        known: names(),
    })?;
    params.only(fam)?;
    (fam.build)(variant, params)
}

/// A shared, comparable handle on a method, for configurations that are `Clone` and
/// `PartialEq` (two handles are equal when their methods have the same name and settings as
/// far as [`Method::name`] and `Debug` tell).
#[derive(Clone)]
pub struct MethodRef(Arc<dyn Method>);

impl MethodRef {
    /// Wraps a method.
    pub fn new(m: Box<dyn Method>) -> Self {
        Self(Arc::from(m))
    }

    /// The method.
    pub fn get(&self) -> &dyn Method {
        self.0.as_ref()
    }
}

impl std::ops::Deref for MethodRef {
    type Target = dyn Method;
    fn deref(&self) -> &Self::Target {
        self.0.as_ref()
    }
}

impl fmt::Debug for MethodRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

impl fmt::Display for MethodRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0.name())
    }
}

impl PartialEq for MethodRef {
    fn eq(&self, other: &Self) -> bool {
        format!("{:?}", self.0) == format!("{:?}", other.0)
    }
}

impl std::str::FromStr for MethodRef {
    type Err = SolverError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse(s).map(Self::new)
    }
}

impl From<Box<dyn Method>> for MethodRef {
    fn from(m: Box<dyn Method>) -> Self {
        Self::new(m)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn names_round_trip_case_insensitively() {
        for spec in ["cda", "fld", "FLD:LP", "fld:sum", "fld:larsen2", "Lbm"] {
            let m = parse(spec).unwrap();
            let again = parse(&m.name()).unwrap();
            assert_eq!(m.name(), again.name(), "{spec}");
            assert_eq!(format!("{m:?}"), format!("{again:?}"), "{spec}");
        }
        assert_eq!(parse("fld").unwrap().name(), "fld:lp");
    }

    #[test]
    fn unknown_names_and_parameters_list_what_exists() {
        let e = parse("lpx").unwrap_err().to_string();
        for f in METHODS {
            assert!(e.contains(f.name), "{e}");
        }
        let e = parse_with("lbm", &Params::none().with("omega", 1.5))
            .unwrap_err()
            .to_string();
        assert!(e.contains("omega") && e.contains("none"), "{e}");
        assert!(parse("fld:bogus").is_err());
        assert!(Params::parse(["omega"]).is_err());
        assert!(Params::parse(["omega=x"]).is_err());
    }

    /// A family's fixed step counts run exactly that many steps (the atlas labels a point by
    /// its count; every family takes a volume source today, one without it would be lit by
    /// a directional light instead of the emission), and a baked twin takes the lights its
    /// Direct original refuses.
    #[test]
    fn step_settings_run_exactly_their_counts_and_baked_twins_take_point_lights() {
        let grid = Grid::cube(6, 1.0).unwrap();
        let dark = Medium::homogeneous(grid, 3.0, 0.9).unwrap();
        let mut medium = dark.clone();
        medium.emission[grid.index(3, 3, 3)] = 1.0;
        let point = [Light::Point {
            position: [0.5, 0.5, 1.5],
            power: 1.0,
        }];
        let sun = [Light::directional([0.0, 0.0, -1.0], 1.0).unwrap()];
        let mut with_steps = 0;
        for fam in METHODS {
            let m = (fam.build)(None, &Params::none()).unwrap();
            if let Some(st) = m.step_settings() {
                with_steps += 1;
                assert!(!st.unit.is_empty() && !st.counts.is_empty(), "{}", fam.name);
                assert!(st.counts[0] >= 1, "{}", fam.name);
                assert!(st.counts.windows(2).all(|w| w[0] < w[1]), "{}", fam.name);
                let (medium, lights): (&Medium<f64>, &[Light]) = if m.capabilities().volume_source {
                    (&medium, &[])
                } else {
                    (&dark, &sun)
                };
                for &k in st.counts {
                    let p = Problem {
                        medium,
                        lights,
                        phase: Phase::Isotropic,
                    };
                    let s = m
                        .solve(
                            &Backend::Cpu(Precision::F64),
                            &p,
                            &Tolerance::fixed_steps(k),
                            &mut |_, _| {},
                        )
                        .unwrap();
                    assert_eq!((s.steps, s.stop), (k, Stop::Cap), "{} at {k}", fam.name);
                }
            }
            let Some(twin) = m.with_baked_lights() else {
                continue;
            };
            assert_eq!(m.capabilities().lights, LightInput::Direct, "{}", fam.name);
            assert_eq!(
                twin.capabilities().lights,
                LightInput::Baked,
                "{}",
                fam.name
            );
            assert_eq!(parse(&twin.name()).unwrap().name(), twin.name());
            let p = Problem {
                medium: &medium,
                lights: &point,
                phase: Phase::Isotropic,
            };
            let run = |x: &dyn Method| {
                x.solve(
                    &Backend::Cpu(Precision::F64),
                    &p,
                    &Tolerance::rel(1e-3),
                    &mut |_, _| {},
                )
            };
            assert!(
                matches!(run(m.as_ref()), Err(SolverError::LightKind { .. })),
                "{}",
                fam.name
            );
            assert!(run(twin.as_ref()).unwrap().phi.iter().any(|&v| v > 0.0));
        }
        // LPM's orders at least.
        assert!(with_steps >= 1);
    }

    /// A family's atlas settings ([`Method::param_settings`]) are its own methods, parseable
    /// by name, with distinct labels, and differ from the defaults in what they print.
    #[test]
    fn param_settings_are_the_familys_own_parseable_methods() {
        let mut any = 0;
        for fam in METHODS {
            let m = (fam.build)(None, &Params::none()).unwrap();
            let settings = m.param_settings();
            let mut labels: Vec<&str> = settings.iter().map(|p| p.label.as_str()).collect();
            labels.sort_unstable();
            labels.dedup();
            assert_eq!(
                labels.len(),
                settings.len(),
                "{}: duplicate labels",
                fam.name
            );
            for ps in &settings {
                any += 1;
                let name = ps.method.name();
                assert_eq!(name.split(':').next(), Some(fam.name), "{name}");
                assert_eq!(parse(&name).unwrap().name(), name);
                assert_ne!(format!("{:?}", ps.method), format!("{m:?}"), "{}", ps.label);
                // A setting's own settings are not expanded again.
                assert!(ps.method.param_settings().is_empty(), "{}", ps.label);
            }
        }
        assert!(any >= 1);
    }

    #[test]
    fn parameters_reach_the_method() {
        let a = parse_with("fld:lp", &Params::parse(["omega=1.5"]).unwrap()).unwrap();
        let b = parse("fld:lp").unwrap();
        assert_ne!(format!("{a:?}"), format!("{b:?}"));
        assert!(parse_with("fld", &Params::none().with("omega", 2.5)).is_err());
    }
}
