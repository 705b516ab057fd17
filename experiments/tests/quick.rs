//! `point_source` and `convergence`: flag errors, and the GPU backend against the CPU. Their
//! interfaces and their CPU claims are checked on the `figures --quick` runs in
//! `tests/registry.rs`.

// Test helpers unwrap: a failed setup should fail the test loudly.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use clap::Parser;
use common::assert_columns;
use experiments::{convergence, point_source};

#[test]
fn bad_flags_are_errors_not_panics() {
    let a = point_source::Args::parse_from(["point_source", "--n", "32", "--no-progress"]);
    assert!(point_source::run(&a).is_err());
    // Malformed lists and unknown names are rejected when the flags are parsed; an empty
    // list is an error, not an empty CSV.
    for (flag, value) in [
        ("--limiter", "nonsense"),
        ("--albedo", ""),
        ("--albedo", "0.5,"),
        ("--boundary", "reflective"),
        ("--precision", "f16"),
        ("--backend", "tpu"),
    ] {
        assert!(
            point_source::Args::try_parse_from(["point_source", flag, value]).is_err(),
            "{flag} {value}"
        );
    }
    let a = point_source::Args::parse_from([
        "point_source",
        "--quick",
        "--albedo",
        "1.5",
        "--no-progress",
    ]);
    assert!(point_source::run(&a).is_err());
    let a = convergence::Args::parse_from([
        "convergence",
        "--quick",
        "--omega",
        "2.5",
        "--no-progress",
    ]);
    assert!(convergence::run(&a).is_err());
}

/// `--backend both` (GPU issue, acceptance 3): the GPU rows and `_gpu` plots are written and
/// reproduce the CPU's numbers: point-source errors against Grosjean within 1 % (CPU f64 vs
/// GPU f32), and the f32 σ_ε job of Fig 4c converging in the same number of iterations ±2 %.
#[test]
fn gpu_backend_reproduces_the_cpu_figures() {
    match solvers::gpu::GpuContext::for_tests() {
        Ok(Some(ctx)) => solvers::gpu::log_uncaptured(&format!(
            "gpu_backend_reproduces_the_cpu_figures: ran on {}",
            ctx.describe()
        )),
        Ok(None) => {
            solvers::gpu::log_uncaptured(
                "gpu_backend_reproduces_the_cpu_figures: skipped: no GPU adapter",
            );
            return;
        }
        Err(e) => panic!("SCATTERBENCH_REQUIRE_GPU is set: {e}"),
    }
    let dir = std::env::temp_dir().join(format!("scatterbench-gpu-{}", std::process::id()));
    let ps_dir = dir.join("point_source");
    let args = point_source::Args::parse_from([
        "point_source",
        "--quick",
        "--no-progress",
        "--backend",
        "both",
        "--limiter",
        "cda,lp",
        "--albedo",
        "0.9",
        "--out",
        ps_dir.to_str().unwrap_or("."),
    ]);
    let runs = point_source::run(&args).unwrap();
    assert_columns(&ps_dir.join("runs.csv"), &["precision", "backend", "timer"]);
    for f in [
        "fig5c_fld_lp_zero_boundary.png",
        "fig5c_fld_lp_zero_boundary_gpu.png",
    ] {
        assert!(ps_dir.join(f).is_file(), "missing {f}");
    }
    let meta = std::fs::read_to_string(ps_dir.join("meta.json")).unwrap();
    assert!(
        meta.contains("\"adapter\""),
        "meta.json lacks the adapter: {meta}"
    );
    for lim in ["cda", "lp"] {
        let err = |backend: &str| {
            runs.iter()
                .find(|r| r.limiter == lim && r.boundary == "zero" && r.backend == backend)
                .map(|r| r.err_grosjean_near)
                .unwrap()
        };
        let (c, g) = (err("cpu"), err("gpu"));
        assert!(
            (c - g).abs() <= 0.01 * c,
            "{lim}: CPU error {c} vs GPU error {g}"
        );
    }
    let cv_dir = dir.join("convergence");
    let args = convergence::Args::parse_from([
        "convergence",
        "--quick",
        "--no-progress",
        "--backend",
        "both",
        "--omega",
        "1.9",
        "--resolutions",
        "13",
        "--sigma-eps",
        "1e-3",
        "--max-iterations",
        "800",
        "--out",
        cv_dir.to_str().unwrap_or("."),
    ]);
    let rows = convergence::run(&args).unwrap();
    assert!(cv_dir.join("fig4a_residual_vs_iteration_gpu.png").is_file());
    let it = |backend: &str| {
        rows.iter()
            .find(|r| r.case == "sigma_eps" && r.backend == backend)
            .map(|r| (r.iterations as f64, r.converged))
            .unwrap()
    };
    let ((ic, cc), (ig, cg)) = (it("cpu"), it("gpu"));
    assert!(cc && cg, "σε job did not converge: CPU {cc}, GPU {cg}");
    assert!(
        (ic - ig).abs() <= 0.02 * ic,
        "σε job: CPU-f32 {ic} vs GPU {ig} iterations"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
