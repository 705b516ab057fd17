//! # experiments
//!
//! One module and one binary per paper figure. Each experiment builds its scenes, calls the
//! solvers, and writes `results/<name>/` (or `--out DIR`): CSV tables, PNG plots, and a
//! `meta.json` with the command line, git revision, machine and timings. `--quick` shrinks
//! every experiment to a CI-sized run. The `figures` binary runs them all and writes
//! `results/README.md` from the [`experiment::EXPERIMENTS`] registry.
#![deny(missing_docs)]

pub mod accuracy_cost;
pub mod common;
pub mod convergence;
pub mod convergence_check;
pub mod cost;
pub mod emissive_cube;
pub mod experiment;
pub mod i3rc_step_cloud;
pub mod images;
pub mod lbm_convergence;
pub mod lbm_diffusion_limit;
pub mod lpm_accuracy;
pub mod lpm_cases;
pub mod lpm_cloud;
pub mod lpm_memory;
pub mod lpm_speedup;
pub mod methods;
pub mod mitsuba_compare;
pub mod multigrid_scaling;
pub mod plot;
pub mod point_source;
pub mod point_source_analytic;
pub mod pop_convergence;
pub mod pop_cube;
pub mod pop_ordinates;
pub mod pop_radial;
pub mod pop_residuum;
pub mod pop_weaknesses;
pub mod progress;
pub mod pt_point_source;
pub mod pt_render;
pub mod pt_slab;
pub mod rde_controls;
pub mod rde_stability;
pub mod rde_steady;
pub mod render;
pub mod renderings;
pub mod report;
pub mod scenes;
pub mod shard;
pub mod transport_references;
