//! `transport_references` on a CI-sized run: its CSV columns and the headline claims it
//! tabulates (energy balance, Grosjean's few-percent band for high albedo).

// Test helpers unwrap: a failed setup should fail the test loudly.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use clap::Parser;
use experiments::transport_references;
use std::path::Path;

fn header(path: &Path) -> Vec<String> {
    experiments::common::csv_header(path).unwrap()
}

fn assert_header(path: &Path, cols: &[&str]) {
    assert_eq!(header(path), cols, "{}", path.display());
}

#[test]
fn transport_references_quick_writes_its_interface() {
    let dir = std::env::temp_dir().join(format!("scatterbench-tr-{}", std::process::id()));
    let args = transport_references::Args::parse_from([
        "transport_references",
        "--quick",
        "--no-progress",
        "--out",
        dir.to_str().unwrap_or("."),
    ]);
    let summary = transport_references::run(&args).unwrap();
    assert_header(
        &dir.join("point_source.csv"),
        &[
            "albedo",
            "r",
            "radial_density",
            "radial_density_collided",
            "grosjean_radial_density",
            "cda_radial_density",
            "rel_err_grosjean",
            "rel_err_cda",
        ],
    );
    assert_header(
        &dir.join("point_source_summary.csv"),
        &[
            "albedo",
            "nu0",
            "discrete_amplitude",
            "energy_balance",
            "grosjean_max_abs_rel_err_near",
            "grosjean_max_abs_rel_err_far",
            "cda_max_abs_rel_err_far",
        ],
    );
    assert_header(
        &dir.join("h_function.csv"),
        &["albedo", "mu", "h_integral", "h_nystrom", "plane_albedo"],
    );
    assert_header(
        &dir.join("slab.csv"),
        &[
            "albedo",
            "g",
            "mu0",
            "tau",
            "streams",
            "reflectance",
            "transmittance_diffuse",
            "transmittance_direct",
        ],
    );
    assert_header(
        &dir.join("slab_half_space.csv"),
        &[
            "albedo",
            "g",
            "mu0",
            "streams",
            "reflectance",
            "plane_albedo",
        ],
    );
    for f in [
        "meta.json",
        "point_radial_density.png",
        "point_relative_error.png",
        "h_function.png",
        "plane_albedo.png",
        "slab_reflectance.png",
        "slab_transmittance.png",
    ] {
        assert!(dir.join(f).is_file(), "missing {f}");
    }
    assert_eq!(summary.len(), 4);
    for s in &summary {
        assert!((s.energy_balance - 1.0).abs() < 1e-12, "{s:?}");
        if s.albedo >= 0.7 {
            assert!(s.grosjean_max_abs_rel_err_far < 0.03, "{s:?}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn transport_references_rejects_bad_flags() {
    for bad in [
        ["--albedo", "1.0"],
        ["--h-albedo", "1.5"],
        ["--g", "1"],
        ["--mu0", "0"],
    ] {
        let mut argv = vec!["transport_references", "--quick", "--no-progress"];
        argv.extend(bad);
        let a = transport_references::Args::parse_from(argv);
        assert!(transport_references::run(&a).is_err(), "{bad:?}");
    }
}
