//! DOCS_PLACEHOLDER

pub mod cpu;
pub mod env;
pub mod grid;
pub mod kernel;
#[cfg(test)]
mod tests;

pub use cpu::{CpuPop, Ledger};
pub use env::{Prefilter, environment_ordinates, fibonacci};
pub use grid::{PropagationGrid, frame};
pub use kernel::{Fractions, cumulative, decay, fractions, hg};

use crate::method::Stop;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;

/// Initialisation of a propagation grid (spec §1.5, V1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Init {
    /// Decision D1: a wavefront injected into the entry slice k = 0 only, L = E·e^{−σa Δx/2},
    /// a = a_n·g^{σs Δx/2}. Energy-exact.
    #[default]
    EntrySlice,
    /// POP Sec 4.1 as printed: every cell L_i = E·T_i (T_i with σt to the cell centre along
    /// d), a = a_n. Counts the beam (j+1) times in cell j (test T6).
    PaperPerCell,
}

/// Which lobe Eq 8 accumulates towards the observer (spec D8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Eq8 {
    /// In-scattered radiance: Σ_m L^m f_hg(u, a^m·g) (HG self-convolution).
    #[default]
    PhaseConvolved,
    /// POP Eq 8 as printed: Σ_m L^m f_hg(u, a^m), a clamped to ≤ 1 − 10⁻⁴.
    Literal,
}

/// The lateral faces of a propagation grid (the faces parallel to d).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Lateral {
    /// Light leaving through a lateral face is lost (the paper).
    #[default]
    Open,
    /// Laterally periodic: a slab of infinite extent (tests T7, T19 vs adding–doubling).
    Periodic,
}

/// The observer of Eq 8 (spec D7: u = d·(direction from the cell to the observer)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Observer {
    /// A camera at this world position (perspective).
    Point([f64; 3]),
    /// A camera infinitely far along this unit direction (orthographic).
    Direction([f64; 3]),
}

/// One principal ordinate: a collimated beam along `direction` with `irradiance` measured
/// perpendicular to it and initial lobe anisotropy `anisotropy` (1: a directional light;
/// lower after prefiltering, Sec 5.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ordinate {
    /// Unit direction of travel d_n.
    pub direction: [f64; 3],
    /// E_n, irradiance on a plane perpendicular to d_n (every channel).
    pub irradiance: f64,
    /// a_n ∈ [0, 1].
    pub anisotropy: f64,
}

impl Ordinate {
    /// A directional light: one ordinate with a = 1 (Sec 5, spec §1.2). Fails on a zero or
    /// non-finite direction or an irradiance that is not finite and ≥ 0.
    pub fn directional(direction: [f64; 3], irradiance: f64) -> Result<Self, SolverError> {
        let o = Self {
            direction: grid::normalise("ordinate.direction", direction)?,
            irradiance,
            anisotropy: 1.0,
        };
        o.validate()?;
        Ok(o)
    }

    /// Checks the fields (unit direction, E ≥ 0 finite, a ∈ [0, 1]).
    pub fn validate(&self) -> Result<(), SolverError> {
        let len = grid::dot(self.direction, self.direction).sqrt();
        if !((len - 1.0).abs() <= 1e-9) {
            return Err(SolverError::BadParameter {
                name: "ordinate.direction",
                value: len,
                reason: "must be a unit vector (use Ordinate::directional to normalise)",
            });
        }
        if !(self.irradiance.is_finite() && self.irradiance >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "ordinate.irradiance",
                value: self.irradiance,
                reason: "must be finite and ≥ 0",
            });
        }
        if !(0.0..=1.0).contains(&self.anisotropy) {
            return Err(SolverError::BadParameter {
                name: "ordinate.anisotropy",
                value: self.anisotropy,
                reason: "POP lobes have a ∈ [0, 1]",
            });
        }
        Ok(())
    }
}

/// The medium as POP reads it: σs and σa per channel per voxel of one grid, and the
/// Henyey–Greenstein g of each channel (the project's phase is one per scene; POP's per-cell
/// g, Sec 4, is not needed by any scene here).
#[derive(Debug, Clone, PartialEq)]
pub struct PopMedium {
    /// The medium's voxel grid.
    pub grid: Grid,
    /// σs per channel per voxel.
    pub sigma_s: Vec<Vec<f64>>,
    /// σa per channel per voxel.
    pub sigma_a: Vec<Vec<f64>>,
    /// g per channel, in [0, 1] (negative g is excluded, POP Sec 4).
    pub g: Vec<f64>,
}

impl PopMedium {
    /// One channel per medium (all on the same grid), with phase parameter `g[c]` each.
    pub fn new(media: &[Medium<f64>], g: &[f64]) -> Result<Self, SolverError> {
        let first = media.first().ok_or(SolverError::BadParameter {
            name: "channels",
            value: 0.0,
            reason: "at least one channel medium is needed",
        })?;
        if g.len() != media.len() {
            return Err(SolverError::FieldSize {
                field: "g (one per channel)",
                expected: media.len(),
                got: g.len(),
            });
        }
        let mut sigma_s = Vec::with_capacity(media.len());
        let mut sigma_a = Vec::with_capacity(media.len());
        for m in media {
            m.validate()?;
            if m.grid != first.grid {
                return Err(SolverError::Unsupported(
                    "POP channel media must share one grid".into(),
                ));
            }
            sigma_s.push(
                m.sigma_t
                    .iter()
                    .zip(&m.albedo)
                    .map(|(t, a)| t * a)
                    .collect(),
            );
            sigma_a.push(
                m.sigma_t
                    .iter()
                    .zip(&m.albedo)
                    .map(|(t, a)| t * (1.0 - a))
                    .collect(),
            );
        }
        let out = Self {
            grid: first.grid,
            sigma_s,
            sigma_a,
            g: g.to_vec(),
        };
        out.validate()?;
        Ok(out)
    }

    /// A homogeneous single-channel medium on `grid`.
    pub fn homogeneous(
        grid: Grid,
        sigma_s: f64,
        sigma_a: f64,
        g: f64,
    ) -> Result<Self, SolverError> {
        let out = Self {
            grid,
            sigma_s: vec![vec![sigma_s; grid.len()]],
            sigma_a: vec![vec![sigma_a; grid.len()]],
            g: vec![g],
        };
        out.validate()?;
        Ok(out)
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.g.len()
    }

    /// Checks sizes and ranges: σs, σa finite ≥ 0; g ∈ [0, 1] (typed error for g < 0,
    /// which POP does not support: Eq 4 would alternate the sign of a).
    pub fn validate(&self) -> Result<(), SolverError> {
        if self.g.is_empty() {
            return Err(SolverError::BadParameter {
                name: "channels",
                value: 0.0,
                reason: "at least one channel is needed",
            });
        }
        for &g in &self.g {
            if !(0.0..=1.0).contains(&g) {
                return Err(SolverError::BadParameter {
                    name: "phase.g",
                    value: g,
                    reason: "POP supports g ∈ [0, 1] only (Sec 4: negative g is excluded; Eq 4 needs g ≥ 0)",
                });
            }
        }
        for (field, set) in [("sigma_s", &self.sigma_s), ("sigma_a", &self.sigma_a)] {
            if set.len() != self.g.len() {
                return Err(SolverError::FieldSize {
                    field,
                    expected: self.g.len(),
                    got: set.len(),
                });
            }
            for f in set {
                if f.len() != self.grid.len() {
                    return Err(SolverError::FieldSize {
                        field,
                        expected: self.grid.len(),
                        got: f.len(),
                    });
                }
                if let Some((index, &value)) = f
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
                {
                    return Err(SolverError::FieldValue {
                        field,
                        index,
                        value,
                        range: "[0, ∞) and finite",
                    });
                }
            }
        }
        Ok(())
    }
}

/// Settings of a POP solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PopConfig {
    /// Cells per axis of every propagation grid (N³, spec D3). Paper: 8–20.
    pub n: usize,
    /// Initialisation (D1).
    pub init: Init,
    /// Eq 8 lobe (D8); only used with an observer.
    pub eq8: Eq8,
    /// Lateral faces.
    pub lateral: Lateral,
    /// Observer of Eq 8; `None` accumulates no view-dependent radiance.
    pub observer: Option<Observer>,
    /// Stop when R^m/P_inj < tolerance in every channel (D9); 0 runs exactly
    /// `max_iterations` (the paper's fixed M) unless all light has left.
    pub tolerance: f64,
    /// Iteration cap M.
    pub max_iterations: usize,
}

impl PopConfig {
    /// D1 init, phase-convolved Eq 8, open faces, no observer, the precision's default
    /// tolerance (10⁻⁶ f64, 10⁻⁴ f32, spec D9), at most 100 000 iterations.
    pub fn new<T: Real>(n: usize) -> Self {
        Self {
            n,
            init: Init::EntrySlice,
            eq8: Eq8::PhaseConvolved,
            lateral: Lateral::Open,
            observer: None,
            tolerance: T::DEFAULT_TOLERANCE,
            max_iterations: 100_000,
        }
    }

    /// The paper's fixed iteration count M (no convergence test).
    pub fn fixed<T: Real>(n: usize, m: usize) -> Self {
        Self {
            tolerance: 0.0,
            max_iterations: m,
            ..Self::new::<T>(n)
        }
    }

    /// Checks `n`, the tolerance and, for `ordinates` grids in precision `T` on `channels`
    /// channels, the memory budget ([`crate::budget`]).
    pub fn validate<T: Real>(&self, ordinates: usize, channels: usize) -> Result<(), SolverError> {
        if self.n < 2 {
            return Err(SolverError::BadParameter {
                name: "pop.n",
                value: self.n as f64,
                reason: "a propagation grid needs at least 2 cells per axis",
            });
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "pop.tolerance",
                value: self.tolerance,
                reason: "must be finite and ≥ 0",
            });
        }
        if let Some(Observer::Direction(w)) = self.observer {
            grid::normalise("pop.observer", w)?;
        }
        crate::budget::check(
            format!("POP: {ordinates} ordinate grids of n = {}", self.n),
            Self::bytes::<T>(self.n, ordinates, channels),
        )?;
        Ok(())
    }

    /// Upper bound of the bytes a solve holds: the working state of one grid per rayon
    /// thread and the accumulators of every ordinate.
    pub fn bytes<T: Real>(n: usize, ordinates: usize, channels: usize) -> u64 {
        let size = std::mem::size_of::<T>() as u64;
        let cells = crate::budget::bytes(&[n, n, n, channels], 1);
        let working = cells.saturating_mul(size * 15 + 16 + 8);
        let threads = (rayon::current_num_threads().min(ordinates.max(1))) as u64;
        let kept = cells.saturating_mul(size * cpu::ACC as u64);
        working
            .saturating_mul(threads)
            .saturating_add(kept.saturating_mul(ordinates as u64))
    }
}

/// What one ordinate's propagation produced.
#[derive(Debug, Clone)]
pub struct OrdinateRun<T> {
    /// The ordinate.
    pub ordinate: Ordinate,
    /// Its grid.
    pub grid: PropagationGrid,
    /// Channels.
    pub channels: usize,
    /// `[cell][channel][φ, J, L_acc]`: fluence Σ L^m, flux along d Σ L^m a^m, and the
    /// Eq 8 radiance (0 without observer).
    pub acc: Vec<T>,
    /// Where the power went, per channel.
    pub ledger: Vec<Ledger>,
    /// R^m/P_inj (max over channels) after each step.
    pub history: Vec<f64>,
    /// Steps run.
    pub steps: usize,
    /// Why it stopped.
    pub stop: Stop,
}

impl<T: Real> OrdinateRun<T> {
    /// φ of channel `ch` at world point `p`: clamped trilinear in the rotated grid, 0
    /// outside it (spec D13's gather, on any target grid).
    pub fn fluence_at(&self, ch: usize, p: [f64; 3]) -> f64 {
        let stride = self.channels * cpu::ACC;
        self.grid
            .interpolate_with(&self.acc, stride, ch * cpu::ACC, p)
    }
}

/// All ordinates of a solve.
#[derive(Debug, Clone)]
pub struct PopSolution<T> {
    /// One run per ordinate, in the order given.
    pub runs: Vec<OrdinateRun<T>>,
}

impl<T: Real> PopSolution<T> {
    /// Fluence per channel on `target` (x fastest): Σ over ordinates of the trilinear gather
    /// of each φ at the voxel centres (spec D13 without the 2× merge and the JBU).
    pub fn fluence_on(&self, target: &Grid) -> Vec<Vec<f64>> {
        let nc = self.runs.first().map_or(0, |r| r.channels);
        (0..nc)
            .map(|ch| {
                let mut out = target.sample(|_| 0.0);
                out.par_iter_mut().enumerate().for_each(|(idx, v)| {
                    let [i, j, k] = target.coords(idx);
                    let p = target.center(i, j, k);
                    *v = self.runs.iter().map(|r| r.fluence_at(ch, p)).sum();
                });
                out
            })
            .collect()
    }
}

/// Propagates every ordinate through `medium` (rayon over ordinates and over the slices of
/// each grid; the result does not depend on the thread count).
pub fn solve<T: Real>(
    medium: &PopMedium,
    ordinates: &[Ordinate],
    config: &PopConfig,
) -> Result<PopSolution<T>, SolverError> {
    medium.validate()?;
    if ordinates.is_empty() {
        return Err(SolverError::BadParameter {
            name: "ordinates",
            value: 0.0,
            reason: "POP needs at least one ordinate (a light)",
        });
    }
    for o in ordinates {
        o.validate()?;
    }
    config.validate::<T>(ordinates.len(), medium.channels())?;
    let runs = ordinates
        .par_iter()
        .map(|o| run_ordinate::<T>(medium, o, config))
        .collect();
    Ok(PopSolution { runs })
}

/// One ordinate: its grid (D2–D3), the medium at the MIP level of D4, init, iterations.
pub fn run_ordinate<T: Real>(
    medium: &PopMedium,
    ordinate: &Ordinate,
    config: &PopConfig,
) -> OrdinateRun<T> {
    let grid = PropagationGrid::over(&medium.grid, ordinate.direction, config.n);
    let mip = grid::box_filter(medium, grid::mip_level(&medium.grid, grid.dx));
    let mut pop = CpuPop::<T>::new(grid, &mip, &medium.g, config);
    pop.inject(ordinate, config.init);
    let stop = pop.run(config.tolerance, config.max_iterations);
    OrdinateRun {
        ordinate: *ordinate,
        grid,
        channels: medium.channels(),
        ledger: pop.ledger().to_vec(),
        history: pop.history().to_vec(),
        steps: pop.steps(),
        stop,
        acc: pop.accumulators().to_vec(),
    }
}
