//! The `solvers` integration tests, one test binary (`cargo test -p solvers --test integration`;
//! one file's tests: append its module name as a filter, e.g. `-- conformance::`).
//!
//! *Why one binary:* a release build compiles the solvers' generic code once per test
//! binary; as 18 binaries that was most of a clean test build's extra time (CONTRIBUTING.md,
//! "The test suite's time", has the measurement). The files keep their names and their docs
//! (each its own `allow`s); the GPU tests share one device (`common`) and run one at a time.

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
