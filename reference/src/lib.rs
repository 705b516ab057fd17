//! # reference
//!
//! Ground truth for the solvers: analytic solutions of transport and diffusion theory.
//!
//! * [`point_source`]: a unit-power isotropic point source in an infinite homogeneous,
//!   isotropically scattering medium: Grosjean's approximation (FLD Eq 24), the CDA Green's
//!   function (FLD Eq 27), FLD's transport limit (FLD Eq 29), and the Knudsen number of the
//!   Grosjean solution (FLD Fig 3c), in physical units and in the normalised form of FLD Eq 25.
//! * [`transport`]: exact transport references — the Case–Zweifel point-source solution,
//!   Chandrasekhar's H-function and plane albedo, and an adding–doubling slab solver.
//! * [`pathtracer`]: a delta-tracking Monte Carlo path tracer with batch-means error bars —
//!   camera images and per-voxel fluence of voxel scenes, point-source shell tallies in an
//!   unbounded medium, and slab reflectance/transmittance.
//! * [`mitsuba`]: a bridge to Mitsuba 3 (scene export, K-seed renders through its Python
//!   package) and [`compare`]: per-pixel Welch t-tests with Šidák correction between two
//!   Monte Carlo images.
//!
//! Everything is `f64`.
#![deny(missing_docs)]

pub mod compare;
pub mod effects;
pub mod mitsuba;
pub mod pathtracer;
pub mod point_source;
pub mod quadrature;
pub mod transport;

use solvers::error::Compact;
use thiserror::Error;

/// Errors of the reference computations.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ReferenceError {
    /// A parameter is outside its domain.
    #[error("parameter `{name}` = {} is invalid: {reason}", Compact(*.value))]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// One entry of a list parameter is outside its domain (the list itself may be fine
    /// elsewhere).
    #[error("parameter `{name}[{index}]` = {} is invalid: {reason}", Compact(*.value))]
    BadListEntry {
        /// Parameter name.
        name: &'static str,
        /// 0-based index of the offending entry.
        index: usize,
        /// Its value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// The scene (medium, lights, camera) is invalid; the solver error is the source.
    #[error("invalid scene")]
    Scene(#[from] solvers::SolverError),
    /// An image was requested from a scene without a camera.
    #[error("the scene has no camera; an image render needs `scene.camera`")]
    NoCamera,
    /// Too few batches for a batch-means standard error.
    #[error("{batches} batches requested; batch-means standard errors need at least {min}")]
    TooFewBatches {
        /// Requested batches.
        batches: u32,
        /// The minimum.
        min: u32,
    },
    /// A combination of options the estimator does not implement.
    #[error("unsupported: {what}")]
    Unsupported {
        /// What, in words.
        what: &'static str,
    },
    /// A `--shard i/N` that names no shard.
    #[error("shard `{shard}`: {reason}")]
    BadShard {
        /// The shard as given.
        shard: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// Shards (or per-batch sums) that do not belong to one run, or do not cover it.
    #[error("shards do not merge: {what}")]
    ShardMismatch {
        /// What differs or is missing.
        what: String,
    },
    /// An iterative solve did not converge (a bug or a parameter at the edge of the domain).
    #[error("{what} did not converge (parameter {})", Compact(*.parameter))]
    NoConvergence {
        /// What was being solved.
        what: &'static str,
        /// The parameter (e.g. albedo) it was solved for.
        parameter: f64,
    },
}
