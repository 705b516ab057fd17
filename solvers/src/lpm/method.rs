//! Light propagation maps behind the [`Method`] interface: the registry entry `lpm[:paper]`.
//!
//! **Two ways in** (the contract of φ is [`LightInput`]'s):
//! * `lpm` (default, [`LightInput::Direct`]): the method takes the scene's lights as boundary
//!   radiance in cell averages (LPM §3, spec D13): a directional light snapped to the
//!   direction cell that contains it with L = E/|Ω^i| ([`BoundaryLight::directional`]), a
//!   constant environment L on every direction ([`BoundaryLight::uniform`]); point and
//!   sphere lights are [`SolverError::LightKind`]. The emission j (when rendered) is U⁰ = j/4π.
//!   It returns φ = Σ_p φ^p minus the order-0 fluence of the directional lights alone, which
//!   a second, one-order solve with those lights and no source computes on the same ray
//!   tables (LPM is linear, so the difference is the directional lights' scattered light
//!   to rounding; their single scattering is the pipeline's exact raymarch). An
//!   environment's order 0 stays in φ: its single scattering is σs·φ/4π.
//! * `lpm:baked` ([`LightInput::Baked`], the first-collision mode of D13): U⁰ = q/4π of the
//!   pipeline's baked source q = σs·L_ri + j, no boundary light, φ = Σ_p φ^p: the fluence
//!   of light scattered at least once, as CDA, FLD and LBM return. `lpm:paper` is baked too.
//!
//! **Both ways agree** (`pipeline::direct_lpm_counts_every_effect_once`: 16³ unit cube,
//! σt = 4, albedo 0.9, isotropic, light along −z, downsample 1, rel 10⁻⁵, f64): mean
//! multiple-scattering image 3.8461·10⁻² (direct) vs 3.8362·10⁻² (baked), relative 2.6·10⁻³,
//! with the single image's mean 2.38·10⁻², 0.62 of it (the bound is 5 %: counting the single
//! scattering twice fails it). Point lights: `lpm:baked` (the default refuses them).
//!
//! **Tolerance.** One order is one step. It stops when the unshot power after an order is at
//! most [`Tolerance::rel`] × the power deposited by order 0 (D1); that ratio is
//! [`Solution::last_change`]. At albedo 1 everything unshot would still leave, so the
//! outflow misses exactly the unshot power: the balance's outflow/source is 1 − O(rel).
//! `rel` = 0 runs exactly `max_steps` orders (Alg 2's fixed count; the paper's 3).
//!
//! **Backends.** CPU f32 and f64 ([`CpuLpm`]) and the GPU in f32 ([`GpuLpm`]) for `lpm` and
//! `lpm:baked`; `lpm:paper` is CPU-only (its deposit has no GPU kernel: a typed
//! [`SolverError::Unsupported`], and `capabilities().gpu` is false).
//!
//! Variants: none and `baked` (the exact formulas) and `paper` (LPM Eqs 3, 4, 6 literally with the zero
//! wrap: reproduction only, never in the atlas, which takes each family's default).
//! Parameter: `m` (cells per face edge, default 5: 150 directions).

use super::{
    BoundaryLight, CpuLpm, Deposit, Formulas, GpuLpm, LpmConfig, LpmSolution, Orders, WrapBc,
};
use crate::gpu::Timer;
use crate::method::{
    Balance, Capabilities, DirectLight, Fluence, LightInput, Method, MethodFamily, Problem,
    Solution, StepSettings, Tolerance,
};
use crate::{Backend, Grid, Medium, Precision, Real, SolverError};

/// LPM with its settings.
#[derive(Debug, Clone, PartialEq)]
pub struct LpmMethod {
    /// The solver settings; `phase` and `orders` are replaced per solve.
    pub config: LpmConfig,
    /// Whether it takes the lights itself (`lpm`) or the baked source (`lpm:baked`,
    /// `lpm:paper`).
    pub lights: LightInput,
}

impl Default for LpmMethod {
    fn default() -> Self {
        Self {
            config: LpmConfig {
                keep_orders: false,
                ..LpmConfig::default()
            },
            lights: LightInput::Direct,
        }
    }
}

impl LpmMethod {
    /// The settings of one solve.
    pub fn config_for(&self, problem: &Problem<'_>, tolerance: &Tolerance) -> LpmConfig {
        LpmConfig {
            phase: problem.phase,
            orders: if tolerance.rel > 0.0 {
                Orders::Converge {
                    rel: tolerance.rel,
                    max_orders: tolerance.max_steps,
                }
            } else {
                Orders::Fixed(tolerance.max_steps)
            },
            ..self.config.clone()
        }
    }

    /// One solve with `solve` (a CPU or GPU solver built per call): the lights, the
    /// directional lights' order 0 subtracted, the balance.
    fn run<T: Real>(
        &self,
        problem: &Problem<'_>,
        tolerance: &Tolerance,
        observer: &mut dyn FnMut(usize, f64),
        solve: &SolveFn<'_, T>,
        timer: Timer,
    ) -> Result<Fluence, SolverError> {
        let setup = std::time::Instant::now();
        let cfg = self.config_for(problem, tolerance);
        cfg.validate()?;
        let dirs = super::Directions::new(cfg.m)?;
        let (boundary, directional) = match self.lights {
            LightInput::Baked => (BoundaryLight::none(&dirs), None),
            LightInput::Direct => self.boundary(&dirs, problem)?,
        };
        let mut s = solve(problem.medium, &cfg, &boundary, observer)?;
        // Everything before the dark solve but the orders themselves is setup.
        let setup_seconds = (setup.elapsed().as_secs_f64() - s.seconds).max(0.0);
        if let Some(dir) = directional {
            // The directional lights' order 0 alone: same ray tables, no source, one order.
            let mut dark = problem.medium.clone();
            dark.emission.iter_mut().for_each(|j| *j = 0.0);
            let once = LpmConfig {
                orders: Orders::Fixed(1),
                ..cfg.clone()
            };
            let t0 = std::time::Instant::now();
            let zero = solve(&dark, &once, &dir, &mut |_, _| {})?;
            // Its whole wall time on the CPU (as before), its kernel time on GPU timestamps.
            s.seconds += match timer {
                Timer::WallClock => t0.elapsed().as_secs_f64(),
                Timer::GpuTimestamps => zero.seconds,
            };
            for (p, z) in s.phi.iter_mut().zip(&zero.phi) {
                *p = (*p - *z).max(T::zero());
            }
        }
        let first = s.tallies.first().map_or(f64::NAN, |t| t.unshot);
        let last = s.tallies.last().map_or(f64::NAN, |t| t.unshot / first);
        let sum = |f: fn(&super::OrderTally) -> f64| s.tallies.iter().map(f).sum::<f64>();
        let balance = Balance {
            source: sum(|t| t.injected) + s.tallies.first().map_or(0.0, |t| t.emitted),
            outflow: sum(|t| t.exited),
            absorbed: sum(|t| t.absorbed),
        };
        Ok(Solution {
            grid: s.grid,
            phi: s.phi.iter().map(|x| x.f()).collect(),
            steps: s.orders,
            last_change: last,
            stop: s.stop,
            seconds: s.seconds,
            setup_seconds,
            timer,
            balance: Some(balance),
            trace: (),
        })
    }
}

/// A solver built per call: (medium, settings, boundary light, observer) → solution.
type SolveFn<'s, T> = dyn Fn(
        &Medium<f64>,
        &LpmConfig,
        &BoundaryLight,
        &mut dyn FnMut(usize, f64),
    ) -> Result<LpmSolution<T>, SolverError>
    + 's;

impl LpmMethod {
    /// The boundary radiance of every light of `problem`, and that of its directional
    /// lights alone (`None` without directional lights).
    fn boundary(
        &self,
        dirs: &super::Directions,
        problem: &Problem<'_>,
    ) -> Result<(BoundaryLight, Option<BoundaryLight>), SolverError> {
        let mut all = BoundaryLight::none(dirs);
        let mut dir = BoundaryLight::none(dirs);
        let mut any_dir = false;
        for l in crate::method::direct_lights(&self.name(), problem.lights, false)? {
            let (b, is_dir) = match l {
                DirectLight::Directional {
                    direction,
                    irradiance,
                    ..
                } => (
                    BoundaryLight::directional(dirs, direction, irradiance)?,
                    true,
                ),
                DirectLight::Environment { radiance, .. } => {
                    (BoundaryLight::uniform(dirs, radiance), false)
                }
                // Not returned without `direct_points`; refused the same way if it were.
                DirectLight::Point { index, .. } => {
                    return Err(SolverError::LightKind {
                        method: self.name(),
                        index,
                        kind: "point",
                    });
                }
            };
            for (k, r) in b.radiance.iter().enumerate() {
                all.radiance[k] += r;
                if is_dir {
                    dir.radiance[k] += r;
                }
            }
            any_dir |= is_dir;
        }
        Ok((all, any_dir.then_some(dir)))
    }
}

impl Method for LpmMethod {
    fn name(&self) -> String {
        if self.config.formulas == Formulas::paper() {
            "lpm:paper".into()
        } else if self.lights == LightInput::Baked {
            "lpm:baked".into()
        } else {
            "lpm".into()
        }
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            // The paper's deposit has no GPU kernel (`lpm:paper`).
            gpu: self.config.formulas.deposit != Deposit::Paper,
            f64: true,
            volume_source: true,
            anisotropic: true,
            lights: self.lights,
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
        if let Backend::Gpu(ctx) = backend {
            if !self.capabilities().gpu {
                return Err(SolverError::Unsupported(format!(
                    "{}: the paper's deposit has no GPU kernel (CPU only)",
                    self.name()
                )));
            }
            return self.run::<f32>(
                problem,
                tolerance,
                observer,
                &|m, c, b, o| GpuLpm::new(ctx, m, c)?.solve(b, o),
                ctx.timer(),
            );
        }
        match crate::method::cpu_precision(&self.name(), backend)? {
            Precision::F64 => self.run::<f64>(
                problem,
                tolerance,
                observer,
                &|m, c, b, o| CpuLpm::<f64>::new(&m.cast(), c)?.solve(b, o),
                Timer::WallClock,
            ),
            Precision::F32 => self.run::<f32>(
                problem,
                tolerance,
                observer,
                &|m, c, b, o| CpuLpm::<f32>::new(&m.cast(), c)?.solve(b, o),
                Timer::WallClock,
            ),
        }
    }

    fn kernels(&self) -> &'static [&'static crate::gpu::kernel::KernelSpec] {
        &[&super::gpu::SPEC]
    }

    fn step_settings(&self) -> Option<StepSettings> {
        Some(ORDER_SETTINGS)
    }

    fn with_baked_lights(&self) -> Option<Box<dyn Method>> {
        (self.lights == LightInput::Direct).then(|| {
            Box::new(LpmMethod {
                lights: LightInput::Baked,
                ..self.clone()
            }) as Box<dyn Method>
        })
    }

    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize {
        // Per order: each of the 6m² sweeps reads σt and U and reads and writes T once per
        // voxel (sub-segments of one voxel hit the same cache lines); each of the 6 collects
        // reads the m² T buffers and σs, σt and reads and writes 6 U, 1 I and φ.
        let per = self.config.m * self.config.m;
        let words = 6 * per * 4 + 6 * (per + 2 + 2 * 8);
        words * grid.len() * precision.bytes()
    }
}

/// LPM's fixed step counts ([`Method::step_settings`]): one step is one scattering order, and
/// 1, 2 and 3 orders (the paper's count, Alg 2) are shown beside the converged solve. What k
/// orders put in the image differs by one between the two ways in: `lpm` runs order 0 from
/// the boundary light (the directional beam's own order 0 is subtracted and its single
/// scattering is the pipeline's raymarch), so k orders render scattering orders 1 … k of
/// the lights (k = 1: single scattering alone); `lpm:baked` starts from the once-scattered
/// source q, so k orders render orders 1 … k + 1. Emission: orders 0 … k in both.
pub const ORDER_SETTINGS: StepSettings = StepSettings {
    unit: "scattering orders",
    counts: &[1, 2, 3],
};

/// Light propagation maps (Fattal 2009, Gruson et al. 2012).
pub const LPM: MethodFamily = MethodFamily {
    name: "lpm",
    title: "light propagation maps (discrete ordinates on exact ray tables, order by order)",
    paper: "Gruson et al., Light Propagation Maps on Parallel Graphics Architectures (LPM Eqs 1–6, Algorithms 1–2)",
    variants: "baked, paper",
    params: &[(
        "m",
        "propagation cells per cube-face edge, 1..=64 (default 5: 150 directions, the paper's 25 per face)",
    )],
    build: |variant, params| {
        let mut method = LpmMethod::default();
        match variant {
            None => {}
            Some("baked") => method.lights = LightInput::Baked,
            Some("paper") => {
                method.config.formulas = Formulas::paper();
                method.config.wrap = WrapBc::Zero;
                method.lights = LightInput::Baked;
            }
            Some(v) => {
                return Err(SolverError::UnknownName {
                    what: "variant of lpm",
                    got: v.to_string(),
                    known: "baked, paper".into(),
                });
            }
        }
        if let Some(m) = params.get("m") {
            if !(m.is_finite() && m >= 0.0 && m.fract() == 0.0) {
                return Err(SolverError::BadParameter {
                    name: "m",
                    value: m,
                    reason: "must be a whole number of cells per face edge",
                });
            }
            method.config.m = m as usize;
        }
        method.config.validate()?;
        Ok(Box::new(method))
    },
};
