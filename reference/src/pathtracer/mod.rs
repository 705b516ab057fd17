//! A Woodcock-tracking (delta-tracking) Monte Carlo path tracer: the ground truth the grid
//! methods are measured against (FLD Section 6.2 uses "the standard Woodcock tracking
//! method \[RSK06\] … validated using Chandrasekhar's analytical solution for multiple
//! scattering in a slab geometry"; we validate against the exact point-source and slab
//! solutions of [`crate::transport`] when present, and analytic limits otherwise).
//!
//! Every estimate carries a standard error by batch means ([`estimators`]) and is
//! bit-identical for any number of threads (each path's random stream depends only on the
//! seed and the path index, [`rng`]; sums are reduced in a fixed order).
//!
//! | module | what |
//! |---|---|
//! | [`camera`] | images of a [`Scene`](solvers::scene::Scene): [`render_image`] |
//! | [`contributions`] | which scattering orders and emitters an image keeps |
//! | [`fluence`](mod@fluence) | per-voxel track-length fluence of a scene, collided and uncollided: [`fluence()`] |
//! | [`infinite`] | point source in an unbounded medium: shell tallies of 4πr²φ |
//! | [`slab`] | plane-parallel slab: R, T_d, T_dir, A |
//! | [`periodic`] | laterally periodic voxel slab under a collimated beam: R, T, A per column |
//! | [`tracking`] | majorant grid, delta tracking, ratio tracking |
//! | [`volume`] | nearest / trilinear lookups, DDA, exact line integrals |
//! | [`phase`] | isotropic and Henyey–Greenstein phase functions |
//! | [`estimators`] | batch means, Šidák thresholds, quantiles |
//! | [`rng`] | counter-seeded PCG streams |
//! | [`shard`] | a run's batches split across processes; per-batch sums that merge bit-identically |
//!
//! Units: lengths in the grid's units, σt in inverse length, emission j in power per volume
//! (an isotropic source of radiance j/4π per unit length), light powers in watts; fluence in
//! power per area, radiance in power per area per steradian.

pub mod camera;
pub mod contributions;
pub mod current;
pub mod estimators;
pub mod fluence;
pub mod infinite;
pub(crate) mod math;
pub mod periodic;
pub mod phase;
pub mod rng;
pub mod shard;
pub mod slab;
pub mod tracking;
pub mod volume;
pub(crate) mod world;

pub use camera::{Image, RenderSettings, render_image, render_image_with};
pub use contributions::Contributions;
pub use estimators::{Estimate, MIN_BATCHES};
pub use fluence::{Field, Fluence, PathSettings, fluence, fluence_with};
pub use infinite::{InfiniteMedium, Shell};
pub use periodic::{Beam, ColumnFluxes, PeriodicSlab, PeriodicTally};
pub use shard::{BatchSums, Shard};
pub use slab::{SlabMedium, SlabTally};
pub use volume::Interpolation;

/// How a bounded scene is traced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TraceOptions {
    /// Reconstruction of the voxel fields (default: nearest, the project convention).
    pub interpolation: Interpolation,
    /// Majorant block edge in voxels (default 8; ≥ the grid size: one global majorant).
    pub majorant_block: usize,
    /// Whether high-contrast blocks are walked cell by cell (default true; false: coarse
    /// blocks only; see [`tracking`], "Refined blocks").
    pub refine: bool,
}

/// The majorant structure the path tracer chooses for `scene` under `options` (the same
/// one [`render_image_with`] and the fluence tallies build): global, coarse blocks, or
/// blocks with some walked cell by cell. Fails like the renderers on an invalid scene.
pub fn majorant_report(
    scene: &solvers::scene::Scene,
    options: &TraceOptions,
) -> Result<tracking::MajorantReport, crate::ReferenceError> {
    Ok(world::World::new(scene, options)?.tracker.majorant.report())
}

impl TraceOptions {
    /// The options a scene asks for: its [`solvers::scene::Interpolation`], default blocks.
    pub fn of(scene: &solvers::scene::Scene) -> Self {
        Self {
            interpolation: scene.interpolation,
            ..Self::default()
        }
    }
}

impl Default for TraceOptions {
    fn default() -> Self {
        Self {
            interpolation: Interpolation::Nearest,
            majorant_block: tracking::DEFAULT_BLOCK,
            refine: true,
        }
    }
}

#[cfg(test)]
mod tests;
