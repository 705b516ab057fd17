//! # solvers
//!
//! Grid-based methods for multiple scattering in participating media, each measured by the
//! `reference` crate against analytic solutions and Monte Carlo ground truth.
//!
//! | module | method | paper |
//! |---|---|---|
//! | [`fld`] | classical diffusion (CDA) and flux-limited diffusion (FLD), red-black SOR | Koerner et al., *Flux-Limited Diffusion for Multiple Scattering in Participating Media* (FLD Eqs 30–37, Algorithm 1) |
//! | [`lbm`] | lattice-Boltzmann lighting, D3Q19 photon transport | Geist et al., *Lattice-Boltzmann Lighting* (LB Eqs 3–6, 19, Appendices A–B) |
//! | [`lpm`] | light propagation maps: Fattal's maps with Gruson's propagate/collect split, CPU (rayon) | Gruson et al., *Light Propagation Maps on Parallel Graphics Architectures* (LPM Eqs 1–6, Algorithms 1–2) |
//! | [`rde`] | unsteady radiance diffusion, FTCS (conservative and the thesis's expanded forms) | Murray, *Legible Visualization of Semi-Transparent Objects using Light Transport* (thesis Eqs 4.1–4.9) |
//! | [`pop`] | principal-ordinates propagation: ordinate-aligned grids, HG lobes per cell, 6-neighbour gather | Elek et al., *Principal-Ordinates Propagation* (Computers & Graphics 45, 2014; POP Eqs 1–8) |
//! | [`method`] | one interface ([`Method`]) and one registry ([`method::METHODS`]) for every method above | |
//! | [`pipeline`] | light baking → diffusion → primary raymarch, planned from the scene's effects | FLD Fig 2, Eqs 3, 6, 8, Section 6.2 |
//!
//! Shared building blocks: [`grid`] (the voxel grid), [`medium`] (σt, albedo and emission
//! fields), [`scene`] (medium + phase + lights + camera, shared with the path tracer),
//! [`scenes`] (procedural test media), [`noise`] (seeded gradient noise) and
//! [`real`] (the `f32`/`f64` abstraction every CPU kernel is generic over).
//!
//! Conventions: lengths in arbitrary but consistent units; σt in inverse length; emission
//! `j` in power per unit volume; fluence φ in power per unit area. Arrays are stored with
//! x fastest: `index = i + nx * (j + ny * k)`.
#![deny(missing_docs)]

pub mod backend;
pub mod budget;
pub mod error;
pub mod fld;
pub mod gpu;
pub mod grid;
pub mod lbm;
pub mod lpm;
pub mod medium;
pub mod method;
pub mod noise;
pub mod pipeline;
pub mod pop;
pub mod rde;
pub mod real;
pub mod scene;
pub mod scenes;
pub mod vec3;

pub use backend::{Backend, Precision};
pub use error::SolverError;
pub use grid::Grid;
pub use medium::Medium;
pub use method::{Method, MethodRef, Problem, Solution, Stop, Tolerance};
pub use real::Real;

#[cfg(test)]
pub(crate) mod test_util {
    //! Helpers shared by the unit tests of several modules.

    /// Runs `f` in a fresh rayon pool of `threads` threads (the determinism tests compare
    /// one thread with several).
    #[allow(clippy::unwrap_used)]
    pub(crate) fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }
}
