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
//! **Throughput** (issue 14). Where a render's time goes was found with `perf record` on
//! `reference/examples/pt_profile.rs` (the path tracer alone on a scene file; it prints
//! paths/s and a hash of the image bits, so that a change meant to leave the estimator
//! alone is checked to be bit-identical). The wins taken, each unbiased and deterministic:
//! camera constants computed once (a `tan` and three divisions per path were 7 % of the
//! profile); one global block walked without a DDA (a homogeneous medium's flights and
//! shadow rays paid nine divisions of set-up each); the azimuth sampled as a fraction of a
//! turn with exact range reduction and branch-free octant polynomials instead of libm's
//! `sin_cos` (12 %; `math.rs`); the seed's hash computed once per render; the sphere light
//! being sampled not tested as its own occluder; a uniform albedo not looked up; lookups
//! multiplying by 1/∆l; one division per majorant piece instead of two per tentative point;
//! ratio tracking carrying its exponential variate across pieces; rays clipped to the box
//! outside which σt is 0 ([`tracking`]); a DDA step without divisions or data-dependent
//! branches ([`volume`]). Measured on this 2-core AMD EPYC VM (minimum of 3 runs of
//! `pt_profile`, before → after, same seeds): `emissive_sphere` 1024 spp 0.998 s → 0.630 s
//! (1.58×, bit-identical up to the azimuth change), `cloud_directional` 256 spp 0.808 s →
//! 0.611 s (1.32×), `environment_sphere` 1024 spp 0.309 s → 0.191 s (1.62×),
//! `dense_half_space` 64 spp 0.071 s → 0.043 s (1.66×), `dense_voxel` 64 spp 0.0135 s →
//! 0.0092 s (1.47×). Tried and not taken: f32 σt for lookups (3 % on the cloud: lookups
//! are not bandwidth-bound), residual ratio tracking with a per-block control σt (no gain:
//! few 8³ blocks have a minimum worth an extra `exp`), 4³ or 2³ majorant blocks (slower:
//! more walk steps than null collisions saved). AVX2 code generation (`-C
//! target-cpu=x86-64-v3`) gave the tracer only 3 % (bit-identical); the workspace now builds
//! with it anyway (`.cargo/config.toml`) because the grid solvers' sweeps gain 1.5–1.9×
//! from it (`solvers::fld`, "Code generation"), and the numbers above are from the SSE2
//! baseline build.
//!
//! Units: lengths in the grid's units, σt in inverse length, emission j in power per volume
//! (an isotropic source of radiance j/4π per unit length), light powers in watts; fluence in
//! power per area, radiance in power per area per steradian.

pub mod angular;
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
pub mod sphere;
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
