//! Which voxels FLD Eq 37's RMS residual counts, and its normalisation: shared by every
//! method that stops on R̄/j̄ (FLD and CDA here, the RDE's `Steady` mode in [`crate::rde`]).
//!
//! The RMS runs over the interior voxels further than `margin` voxels from the boundary
//! layer (FLD Section 5, "ignoring voxels close to the boundary"); a grid too small for the
//! margin falls back to every interior voxel. The solvers run on fields divided by j̄, so the
//! RMS of the normalised residual is R̄/j̄ directly.

use crate::Grid;

/// The voxels counted in the RMS residual: lo ≤ i ≤ hi[0], lo ≤ j ≤ hi[1], lo ≤ k ≤ hi[2].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ResidualWindow {
    /// The margin in effect (0 after the small-grid fallback).
    pub margin: usize,
    /// Lowest counted index on every axis, 1 + margin.
    pub lo: usize,
    /// Highest counted index per axis.
    pub hi: [usize; 3],
    /// Number of counted voxels.
    pub count: usize,
}

impl ResidualWindow {
    /// The window of `grid` with `margin` voxels left out next to the boundary layer.
    pub fn new(grid: &Grid, margin: usize) -> Self {
        let [nx, ny, nz] = grid.n;
        let inner = |n: usize, m: usize| n.saturating_sub(2 + 2 * m);
        let margin = if inner(nx, margin) * inner(ny, margin) * inner(nz, margin) == 0 {
            // Grid too small for the margin: fall back to every interior voxel.
            0
        } else {
            margin
        };
        Self {
            margin,
            lo: 1 + margin,
            hi: [nx, ny, nz].map(|n| n - 2 - margin.min(n - 2)),
            count: inner(nx, margin) * inner(ny, margin) * inner(nz, margin),
        }
    }

    /// Whether row (j, k) holds counted voxels.
    #[inline(always)]
    pub fn counts_row(&self, j: usize, k: usize) -> bool {
        (self.lo..=self.hi[1]).contains(&j) && (self.lo..=self.hi[2]).contains(&k)
    }

    /// The RMS of a sum of squared normalised residuals, R̄/j̄.
    pub fn rms(&self, sumsq: f64) -> f64 {
        (sumsq / self.count as f64).sqrt()
    }
}
