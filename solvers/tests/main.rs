//! The `solvers` integration tests, one test binary (`cargo test -p solvers --test integration`;
//! one file's tests: append its module name as a filter, e.g. `-- conformance::`).
//!
//! *Why one binary:* in a release build every test binary compiles its own copy of the
//! solvers' generic code (`CpuFld<f32>`, `CpuMultigrid<f64>`, …), since Rust shares generic
//! instances across crates only in unoptimised builds. As 18 binaries, a clean
//! `cargo test --workspace --release` spent 630 of its 2456 crate-seconds on six of them
//! (`fld_multigrid_gpu` 128 s, `fld_multigrid` 118, `energy_balance` 114, `conformance` 112,
//! `analytic` 110, `marshak` 49; 2-vCPU AMD EPYC Zen 3, cargo `--timings`, 2026-12-08), most
//! of it the same instances compiled again.
//!
//! The files keep their names and their docs; the GPU tests share one device (`common`), as
//! they did within each former binary, and run one at a time.

#![allow(clippy::unwrap_used, clippy::expect_used)]

#[macro_use]
mod common;
mod fuzz_corpus;
#[path = "support/lit_cube.rs"]
mod lit_cube;

mod analytic;
mod conformance;
mod default_stop;
mod energy_balance;
mod fld_multigrid;
mod fld_multigrid_gpu;
mod fuzz_scene;
mod gpu_errors;
mod kernel_contract;
mod lbm_conformance;
mod lbm_energy_balance;
mod marshak;
mod pipeline;
mod pop_gpu;
mod pop_residuum;
mod rde_default_stop;
mod vdb_file;
mod wgsl;
