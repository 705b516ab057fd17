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
//! **Backends.** CPU f32/f64 ([`super::solve`]) and the GPU (f32, [`super::gpu::solve`]),
//! which tests `rel` every [`super::gpu::DEFAULT_CHECK_EVERY`] iterations, so it stops up to
//! that many − 1 iterations after the CPU would (397 vs 400 on the Fig 12 cube, `mod.rs`);
//! the observer then sees those checkpoints only.
//!
//! **Variants** (the paper-faithful choices of `mod.rs`): none (D1 entry-slice init, D11
//! prefilter), `per-cell` (Sec 4.1's per-cell init, [`Init::PaperPerCell`]), `heuristic`
//! (the paper's prefilter a_n = (1 − w_n/N)^β, parameter `beta`, default 1). The literal
//! Eq 8 ([`super::Eq8::Literal`]) changes only the view-dependent accumulator, which the
//! pipeline does not read (its raymarch takes φ), so it is not a variant here.
//! **Parameters:** `cells` (N, cells per axis of every ordinate grid; default 0 = the solve
//! grid's largest dimension up to [`DEFAULT_CELLS_MAX`], so on solve grids up to 32³ an axis
//! ordinate's cells are the solve grid's voxels),
//! `ordinates` (per environment light, default 64, the paper's Fig 14), `beta`.
//!
//! **Measured in the pipeline** (`pipeline.rs`, `every_registered_method_…`: the 16³ vacuum
//! cloud, albedo 0.9, g = 0.4, one directional light, downsample 2, f64): POP's mean
//! multiple-scattering image is 4.04 × FLD-LP's (LPM 1.60, LBM 1.31): the over-bright
//! isotropised random walk of `mod.rs` (volume-mean φ 3.5 vs the path tracer's 0.89 on the
//! Fig 12 cube at g = 0.7). The comparison with the path tracer (issue 17 item 6, measure)
//! is not run yet.
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

/// The largest default N (`cells` = 0): iterations to a relative stop grow ∝ N² (mod.rs,
/// t21: 397 at 16³ to 10⁻³ at g = 0.7), so the cost grows ∝ N⁵; N ≤ 32 keeps the atlas's
/// full-resolution points to seconds. Set `cells` for finer grids.
pub const DEFAULT_CELLS_MAX: usize = 32;

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
            grid.n
                .iter()
                .copied()
                .max()
                .unwrap_or(2)
                .clamp(2, DEFAULT_CELLS_MAX)
        } else {
            self.cells
        }
    }

    fn run<T: Real>(
        &self,
        problem: &Problem<'_>,
        tolerance: &Tolerance,
        observer: &mut dyn FnMut(usize, f64),
        solve: impl FnOnce(
            &PopMedium,
            &[super::Ordinate],
            &PopConfig,
        ) -> Result<super::PopSolution<T>, SolverError>,
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
        let sol = solve(&pm, &ordinates, &config)?;
        let seconds = t0.elapsed().as_secs_f64();
        let steps = sol.runs.iter().map(|r| r.steps).max().unwrap_or(0);
        // The largest R^m/P_inj over the ordinates after each iteration where one was
        // recorded (every step on the CPU, every checkpoint on the GPU), for the observer;
        // an ordinate that has stopped counts with its last value.
        let mut at: Vec<usize> = sol
            .runs
            .iter()
            .flat_map(|r| r.history_steps.iter().copied())
            .collect();
        at.sort_unstable();
        at.dedup();
        for m in at {
            let worst = sol
                .runs
                .iter()
                .filter_map(|r| {
                    let i = r.history_steps.partition_point(|&s| s <= m);
                    i.checked_sub(1).and_then(|i| r.history.get(i))
                })
                .fold(0.0, |a: f64, &b| a.max(b));
            observer(m, worst);
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
            gpu: true,
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
            Backend::Cpu(Precision::F64) => {
                self.run::<f64>(problem, tolerance, observer, super::solve::<f64>)
            }
            Backend::Cpu(Precision::F32) => {
                self.run::<f32>(problem, tolerance, observer, super::solve::<f32>)
            }
            Backend::Gpu(ctx) => self.run::<f32>(problem, tolerance, observer, |m, o, c| {
                super::gpu::solve(ctx, m, o, c)
            }),
        }
    }

    fn kernels(&self) -> &'static [&'static crate::gpu::kernel::KernelSpec] {
        &[&super::gpu::SPEC]
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::scene::{Light, Phase};
    use crate::{Medium, method};

    fn solve_with(
        spec: &str,
        phase: Phase,
        lights: &[Light],
        n: usize,
    ) -> Result<Fluence, SolverError> {
        let m = method::parse(spec)?;
        let medium = Medium::homogeneous(Grid::cube(n, 1.0).unwrap(), 4.0, 0.9).unwrap();
        let p = Problem {
            medium: &medium,
            lights,
            phase,
        };
        m.solve(
            &Backend::Cpu(Precision::F64),
            &p,
            &Tolerance::rel(1e-3),
            &mut |_, _| {},
        )
    }

    /// Bad input gives typed errors naming the parameter (issue 17, acceptance 5).
    #[test]
    fn bad_input_is_a_typed_error() {
        let sun = [Light::directional([0.0, 0.0, -1.0], 1.0).unwrap()];
        let hg = |g| Phase::HenyeyGreenstein { g };
        assert!(matches!(
            method::parse_with("pop", &Params::none().with("ordinates", 0.0)),
            Err(SolverError::BadParameter {
                name: "ordinates",
                ..
            })
        ));
        assert!(matches!(
            method::parse_with("pop", &Params::none().with("cells", 1.0)),
            Err(SolverError::BadParameter { name: "cells", .. })
        ));
        assert!(matches!(
            solve_with("pop", hg(-0.3), &sun, 8),
            Err(SolverError::BadParameter {
                name: "phase.g",
                ..
            })
        ));
        assert!(matches!(
            solve_with("pop", hg(0.5), &[], 8),
            Err(SolverError::BadParameter {
                name: "ordinates",
                ..
            })
        ));
        let point = [Light::Point {
            position: [0.5, 0.5, 2.0],
            power: 1.0,
        }];
        assert!(matches!(
            solve_with("pop", hg(0.5), &point, 8),
            Err(SolverError::LightKind {
                index: 0,
                kind: "point",
                ..
            })
        ));
        let big = method::parse_with("pop", &Params::none().with("cells", 4096.0)).unwrap();
        let medium = Medium::homogeneous(Grid::cube(8, 1.0).unwrap(), 4.0, 0.9).unwrap();
        let p = Problem {
            medium: &medium,
            lights: &sun,
            phase: hg(0.5),
        };
        assert!(matches!(
            big.solve(
                &Backend::Cpu(Precision::F32),
                &p,
                &Tolerance::rel(1e-3),
                &mut |_, _| {}
            ),
            Err(SolverError::TooLarge(_))
        ));
        assert!(method::parse("pop:literal").is_err());
        for spec in ["pop", "pop:per-cell", "pop:heuristic"] {
            assert_eq!(method::parse(spec).unwrap().name(), spec);
        }
    }

    /// In a pure absorber POP's beam is exact (D1), so the scattered light it returns for a
    /// directional light is 0 to rounding; with scattering it is positive. The paper's
    /// per-cell init counts the beam (j+1) times (T6), which the returned φ shows.
    #[test]
    fn a_directional_lights_uncollided_beam_is_removed() {
        let sun = [Light::directional([0.0, 0.0, -1.0], 2.0).unwrap()];
        let grid = Grid::cube(8, 1.0).unwrap();
        let absorber = Medium::homogeneous(grid, 3.0, 0.0).unwrap();
        for (spec, zero) in [("pop", true), ("pop:per-cell", false)] {
            let m = method::parse(spec).unwrap();
            let p = Problem {
                medium: &absorber,
                lights: &sun,
                phase: Phase::Isotropic,
            };
            let s = m
                .solve(
                    &Backend::Cpu(Precision::F64),
                    &p,
                    &Tolerance::rel(1e-9),
                    &mut |_, _| {},
                )
                .unwrap();
            let max = s.phi.iter().cloned().fold(0.0, f64::max);
            assert_eq!(max < 1e-9, zero, "{spec}: max φ_s = {max:e}");
        }
        let s = solve_with("pop", Phase::HenyeyGreenstein { g: 0.9 }, &sun, 8).unwrap();
        assert!(s.phi.iter().sum::<f64>() > 0.0);
    }
}
