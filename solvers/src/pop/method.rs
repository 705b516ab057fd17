//! POP behind the [`Method`] interface: the registry entry `pop[:variant]`, a method that takes
//! the lights itself ([`LightInput::Direct`]).
//!
//! **What it returns** (the contract in [`LightInput`]). Every light of the problem becomes
//! ordinates: a directional light one ordinate (a = 1), a constant environment `ordinates`
//! Fibonacci ordinates with the D11 prefilter ([`super::environment_ordinates`]); point and
//! sphere lights are [`SolverError::LightKind`]. POP's own φ = Σ_m L^m (gathered onto the
//! solve grid by [`super::PopSolution::fluence_on`]) holds the uncollided beam too (POP
//! attenuates a lobe by absorption only and lets scattering widen it, Eqs 2–4), so the
//! method subtracts the exact uncollided fluence E·e^{−τ} of each directional light at the
//! voxel centres ([`crate::method::uncollided_directional`]) and returns the rest, clamped at
//! 0 (where POP's resampled beam is weaker than the exact one). An environment's φ is kept
//! whole: its single scattering is the method's.
//!
//! **Tolerance.** One step is one propagation iteration of every ordinate (they run
//! independently; `steps` is the largest count). [`Tolerance::rel`] is D9's R^m/P_inj, the
//! power in flight over the injected power; [`Solution::last_change`] is its largest final
//! value over the ordinates; `rel` = 0 runs exactly `max_steps` iterations (the paper's M).
//!
//! **Variants** (the paper-faithful choices of `mod.rs`): none (D1 entry-slice init, D11
//! prefilter), `per-cell` (Sec 4.1's per-cell init, [`Init::PaperPerCell`]), `heuristic`
//! (the paper's prefilter a_n = (1 − w_n/N)^β, parameter `beta`, default 1). The literal
//! Eq 8 ([`super::Eq8::Literal`]) changes only the view-dependent accumulator, which the
//! pipeline does not read (its raymarch takes φ), so it is not a variant here.
//! **Parameters:** `cells` (N, cells per axis of every ordinate grid; default 0 = the solve
//! grid's largest dimension, so an axis ordinate's cells are the solve grid's voxels),
//! `ordinates` (per environment light, default 64, the paper's Fig 14), `beta`.
//!
//! **Input errors:** g < 0 (`phase.g`, POP Sec 4), zero ordinates, N < 2, a medium with
//! emission (POP takes no volume source), grids beyond the memory budget
//! ([`SolverError::TooLarge`], from [`PopConfig::validate`]).

use super::{Init, PopConfig, PopMedium, Prefilter};
use crate::gpu::Timer;
use crate::method::{
    Balance, Capabilities, DirectLight, Fluence, LightInput, Method, MethodFamily, Params, Problem,
    Solution, Stop, Tolerance,
};
use crate::{Backend, Grid, Precision, Real, SolverError};

/// Rows of the latitude–longitude map an environment is rasterised on (D10; a constant
/// environment's energy and first moment are exact at any resolution).
const ENV_ROWS: usize = 32;

/// POP with its settings.
#[derive(Debug, Clone, PartialEq)]
pub struct PopMethod {
    /// Initialisation (D1).
    pub init: Init,
    /// Environment prefilter (D11).
    pub prefilter: Prefilter,
    /// Cells per axis of every ordinate grid; 0: the solve grid's largest dimension.
    pub cells: usize,
    /// Ordinates per environment light.
    pub ordinates: usize,
}

impl Default for PopMethod {
    fn default() -> Self {
        Self {
            init: Init::EntrySlice,
            prefilter: Prefilter::Voronoi,
            cells: 0,
            ordinates: 64,
        }
    }
}

impl PopMethod {
    /// The ordinate grid size on `grid`.
    pub fn cells_on(&self, grid: &Grid) -> usize {
        if self.cells == 0 {
            grid.n.iter().copied().max().unwrap_or(2).max(2)
        } else {
            self.cells
        }
    }

    fn run<T: Real>(
        &self,
        problem: &Problem<'_>,
        tolerance: &Tolerance,
        observer: &mut dyn FnMut(usize, f64),
    ) -> Result<Fluence, SolverError> {
        let setup = std::time::Instant::now();
        let medium = problem.medium;
        medium.validate()?;
        if let Some(index) = medium.emission.iter().position(|&j| j != 0.0) {
            return Err(SolverError::FieldValue {
                field: "emission",
                index,
                value: medium.emission[index],
                range: "{0} (POP takes no volume source, only lights)",
            });
        }
        let lights = crate::method::direct_lights(&self.name(), problem.lights)?;
        let mut ordinates = Vec::new();
        for l in &lights {
            match *l {
                DirectLight::Directional {
                    direction,
                    irradiance,
                    ..
                } => ordinates.push(super::Ordinate::directional(direction, irradiance)?),
                DirectLight::Environment { radiance, .. } => {
                    ordinates.extend(super::environment_ordinates(
                        |_| radiance,
                        self.ordinates,
                        self.prefilter,
                        ENV_ROWS,
                    )?);
                }
            }
        }
        let pm = PopMedium::new(std::slice::from_ref(medium), &[problem.phase.mean_cosine()])?;
        let mut config = if tolerance.rel > 0.0 {
            PopConfig {
                tolerance: tolerance.rel,
                max_iterations: tolerance.max_steps,
                ..PopConfig::new::<T>(self.cells_on(&medium.grid))
            }
        } else {
            PopConfig::fixed::<T>(self.cells_on(&medium.grid), tolerance.max_steps)
        };
        config.init = self.init;
        let setup_seconds = setup.elapsed().as_secs_f64();
        let t0 = std::time::Instant::now();
        let sol = super::solve::<T>(&pm, &ordinates, &config)?;
        let seconds = t0.elapsed().as_secs_f64();
        let steps = sol.runs.iter().map(|r| r.steps).max().unwrap_or(0);
        // The largest R^m/P_inj over the ordinates after each iteration, for the observer.
        for m in 0..steps {
            let worst = sol
                .runs
                .iter()
                .filter_map(|r| r.history.get(m).or(r.history.last()))
                .fold(0.0, |a: f64, &b| a.max(b));
            observer(m + 1, worst);
        }
        let last_change = sol
            .runs
            .iter()
            .filter_map(|r| r.history.last())
            .fold(f64::NAN, |a: f64, &b| if a.is_nan() { b } else { a.max(b) });
        let stop = sol.runs.iter().map(|r| r.stop).fold(Stop::Converged, worse);
        let total = sol.fluence_on(&medium.grid).swap_remove(0);
        let uncollided = crate::method::uncollided_directional(medium, &lights);
        let phi = total
            .iter()
            .zip(&uncollided)
            .map(|(t, u)| (t - u).max(0.0))
            .collect();
        let ledger = |f: fn(&super::Ledger) -> f64| {
            sol.runs
                .iter()
                .flat_map(|r| r.ledger.iter())
                .map(f)
                .sum::<f64>()
        };
        Ok(Solution {
            grid: medium.grid,
            phi,
            steps,
            last_change,
            stop,
            seconds,
            setup_seconds,
            timer: Timer::WallClock,
            balance: Some(Balance {
                source: ledger(|l| l.injected),
                outflow: ledger(|l| l.exited()),
                absorbed: ledger(|l| l.absorbed),
            }),
            trace: (),
        })
    }
}

/// The worse of two stops (non-finite > stalled > cap > converged).
fn worse(a: Stop, b: Stop) -> Stop {
    let rank = |s: Stop| match s {
        Stop::Converged => 0,
        Stop::Cap => 1,
        Stop::Stalled => 2,
        Stop::NonFinite => 3,
    };
    if rank(b) > rank(a) { b } else { a }
}

impl Method for PopMethod {
    fn name(&self) -> String {
        let base = match (self.init, self.prefilter) {
            (Init::PaperPerCell, _) => "pop:per-cell",
            (_, Prefilter::Heuristic { .. }) => "pop:heuristic",
            _ => "pop",
        };
        base.into()
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            gpu: false,
            f64: true,
            volume_source: false,
            anisotropic: true,
            lights: LightInput::Direct,
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
        match backend {
            Backend::Cpu(Precision::F64) => self.run::<f64>(problem, tolerance, observer),
            Backend::Cpu(Precision::F32) => self.run::<f32>(problem, tolerance, observer),
            Backend::Gpu(_) => Err(SolverError::Unsupported(format!(
                "{}: the GPU kernel is not implemented yet (CPU only)",
                self.name()
            ))),
        }
    }

    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize {
        // Per ordinate grid cell per iteration: read the 6 neighbours' (L, a) and the
        // precomputed link T and γ, write (L, a) and the three accumulators (mod.rs, Cost).
        let n = self.cells_on(grid);
        n * n * n * (6 * 2 + 2 * 6 + 2 + 3) * precision.bytes()
    }
}

fn whole(name: &'static str, v: f64, min: f64) -> Result<usize, SolverError> {
    if !(v.is_finite() && v >= min && v.fract() == 0.0) {
        return Err(SolverError::BadParameter {
            name,
            value: v,
            reason: "must be a whole number in range (cells: 0 = the solve grid's size or ≥ 2; ordinates: ≥ 1)",
        });
    }
    Ok(v as usize)
}

fn build(variant: Option<&str>, params: &Params) -> Result<Box<dyn Method>, SolverError> {
    let mut m = PopMethod::default();
    let beta = params.get("beta").unwrap_or(1.0);
    if !(beta.is_finite() && beta > 0.0) {
        return Err(SolverError::BadParameter {
            name: "beta",
            value: beta,
            reason: "the heuristic prefilter's exponent must be finite and > 0",
        });
    }
    match variant {
        None => {}
        Some("per-cell") => m.init = Init::PaperPerCell,
        Some("heuristic") => m.prefilter = Prefilter::Heuristic { beta },
        Some(v) => {
            return Err(SolverError::UnknownName {
                what: "variant of pop",
                got: v.to_string(),
                known: "per-cell, heuristic".into(),
            });
        }
    }
    if let Some(c) = params.get("cells") {
        m.cells = whole("cells", c, 0.0)?;
        if m.cells == 1 {
            return Err(SolverError::BadParameter {
                name: "cells",
                value: 1.0,
                reason: "a propagation grid needs at least 2 cells per axis (0: the solve grid's size)",
            });
        }
    }
    if let Some(o) = params.get("ordinates") {
        m.ordinates = whole("ordinates", o, 1.0)?;
    }
    Ok(Box::new(m))
}

/// Principal-ordinates propagation (Elek et al. 2014).
pub const POP: MethodFamily = MethodFamily {
    name: "pop",
    title: "principal-ordinates propagation (HG lobes on ordinate-aligned grids; takes the lights itself)",
    paper: "Elek et al., Principal-Ordinates Propagation for real-time rendering of participating media (POP Eqs 1–7, Sec 5.1)",
    variants: "per-cell, heuristic",
    params: &[
        (
            "cells",
            "cells per axis of every ordinate grid (default 0: the solve grid's largest dimension)",
        ),
        (
            "ordinates",
            "ordinates per environment light (default 64, POP Fig 14)",
        ),
        (
            "beta",
            "exponent of the heuristic prefilter (variant `heuristic`, default 1)",
        ),
    ],
    build,
};
