//! The experiments' CSV interfaces (columns named in the issues) and their headline claims,
//! on CI-sized runs.

// Test helpers unwrap: a failed setup should fail the test loudly.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use clap::Parser;
use experiments::{convergence, point_source};
use std::path::Path;

fn header(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .next()
        .unwrap_or_default()
        .split(',')
        .map(str::to_string)
        .collect()
}

fn assert_columns(path: &Path, cols: &[&str]) {
    let h = header(path);
    for c in cols {
        assert!(
            h.iter().any(|x| x == c),
            "{} lacks column `{c}` (has {h:?})",
            path.display()
        );
    }
}

#[test]
fn point_source_quick_writes_its_interface_and_fld_beats_cda_near_source() {
    let dir = std::env::temp_dir().join(format!("scatterbench-ps-{}", std::process::id()));
    let args = point_source::Args::parse_from([
        "point_source",
        "--quick",
        "--no-progress",
        "--limiter",
        "cda,lp",
        "--albedo",
        "0.5,0.9",
        "--out",
        dir.to_str().unwrap_or("."),
    ]);
    let runs = point_source::run(&args).unwrap();
    assert_columns(
        &dir.join("profiles.csv"),
        &[
            "method",
            "limiter",
            "boundary",
            "albedo",
            "n",
            "tau_extent",
            "tau",
            "phi_norm",
        ],
    );
    assert_columns(
        &dir.join("analytic.csv"),
        &["albedo", "tau", "grosjean", "cda", "transport_limit"],
    );
    for f in [
        "meta.json",
        "fig5a_cda_analytic_boundary.png",
        "fig5b_cda_zero_boundary.png",
        "fig5c_fld_lp_zero_boundary.png",
    ] {
        assert!(dir.join(f).is_file(), "missing {f}");
    }
    for a in [0.5, 0.9] {
        let err = |lim: &str| {
            runs.iter()
                .find(|r| r.limiter == lim && r.boundary == "zero" && r.albedo == a)
                .map(|r| r.err_grosjean_near)
                .unwrap_or(f64::NAN)
        };
        assert!(
            err("lp") < err("cda"),
            "α={a}: LP {} vs CDA {}",
            err("lp"),
            err("cda")
        );
    }
    assert!(runs.iter().all(|r| r.converged));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn convergence_quick_writes_its_interface() {
    let dir = std::env::temp_dir().join(format!("scatterbench-cv-{}", std::process::id()));
    let args = convergence::Args::parse_from([
        "convergence",
        "--quick",
        "--no-progress",
        "--omega",
        "1.0,1.9",
        "--sigma-eps",
        "1e-3",
        "--out",
        dir.to_str().unwrap_or("."),
    ]);
    let rows = convergence::run(&args).unwrap();
    assert_columns(
        &dir.join("residuals.csv"),
        &["case", "omega", "n", "sigma_eps", "iteration", "residual"],
    );
    assert_columns(
        &dir.join("iterations.csv"),
        &[
            "case",
            "omega",
            "n",
            "sigma_eps",
            "iterations",
            "seconds",
            "converged",
        ],
    );
    // Our default θ = 0.5 converges at both SOR factors; iterations grow with resolution.
    assert!(rows.iter().filter(|r| r.case == "sor").all(|r| r.converged));
    let res: Vec<usize> = rows
        .iter()
        .filter(|r| r.case == "resolution")
        .map(|r| r.iterations)
        .collect();
    assert!(
        res.windows(2).all(|w| w[1] >= w[0]),
        "iterations vs n not monotone: {res:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_flags_are_errors_not_panics() {
    let a = point_source::Args::parse_from(["point_source", "--n", "32", "--no-progress"]);
    assert!(point_source::run(&a).is_err());
    let a = point_source::Args::parse_from([
        "point_source",
        "--quick",
        "--limiter",
        "nonsense",
        "--no-progress",
    ]);
    assert!(point_source::run(&a).is_err());
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
