//! Flag errors and headline claims of the path-tracer experiments
//! (`pt_point_source`, `pt_slab`, `pt_render`) on CI-sized runs.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use clap::Parser;
use common::tmp;
use experiments::{pt_point_source, pt_render, pt_slab};
use reference::pathtracer::estimators::sidak_z;

#[test]
fn pt_point_source_quick_the_ballistic_part_is_exact() {
    let dir = tmp("ptps");
    let args = pt_point_source::Args::parse_from([
        "pt_point_source",
        "--quick",
        "--no-progress",
        "--albedo",
        "0.3,0.9",
        "--g",
        "0,0.5",
        "--edges",
        "0,0.25,0.5,1,2,4",
        "--paths",
        "50000",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let rows = pt_point_source::run(&args).unwrap();
    assert_eq!(rows.len(), 2 * 2 * 5);
    for f in ["meta.json", "runs.csv", "radial_density_g0.png"] {
        assert!(dir.join(f).is_file(), "missing {f}");
    }
    // The uncollided part is the exact e^{−r}; the seed is shared across albedos and g
    // (common random numbers), so only the 5 shells of one case are independent tests.
    let zmax = sidak_z(5, 0.0027);
    assert!(rows.iter().all(|r| r.z_ballistic.abs() < zmax), "{rows:?}");
    assert!(rows.iter().all(|r| r.collided <= r.radial_density));
    // Isotropic rows carry the exact solution; total and collided agree with it.
    let iso: Vec<_> = rows.iter().filter(|r| r.g == 0.0).collect();
    let zmax = sidak_z(2 * iso.len(), 0.0027);
    for r in &iso {
        let (z, zc) = (r.z.unwrap(), r.z_collided.unwrap());
        assert!(z.abs() < zmax && zc.abs() < zmax, "{r:?}");
    }
    assert!(
        rows.iter()
            .filter(|r| r.g != 0.0)
            .all(|r| r.exact.is_none())
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn pt_slab_quick_conserves_energy_and_matches_adding_doubling() {
    let dir = tmp("ptslab");
    let args = pt_slab::Args::parse_from([
        "pt_slab",
        "--quick",
        "--no-progress",
        "--tau",
        "1,inf",
        "--albedo",
        "0.5,0.99",
        "--g",
        "0,0.9",
        "--mu0",
        "1,0.5",
        "--paths",
        "20000",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let rows = pt_slab::run(&args).unwrap();
    assert_eq!(rows.len(), 16);
    assert!(dir.join("meta.json").is_file() && dir.join("slab.png").is_file());
    // Every particle ends in exactly one of R, T_d, A or the (exactly known) direct beam.
    let zmax = sidak_z(rows.len(), 0.0027);
    for r in &rows {
        let z = (r.balance - 1.0) / r.balance_stderr.max(1e-300);
        assert!(r.balance == 1.0 || z.abs() < zmax, "{r:?}");
        if r.tau.is_infinite() {
            assert_eq!((r.t_diffuse, r.t_direct), (0.0, 0.0));
        }
        // Against the adding–doubling reference (R and T_d of every row).
        assert!(r.z_r.abs() < sidak_z(2 * rows.len(), 0.0027), "{r:?}");
        assert!(r.z_t.abs() < sidak_z(2 * rows.len(), 0.0027), "{r:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn pt_bad_flags_are_errors_not_panics() {
    let ps = |extra: &[&str]| {
        let mut v = vec![
            "pt_point_source",
            "--quick",
            "--no-progress",
            "--paths",
            "100",
        ];
        v.extend_from_slice(extra);
        let Ok(mut a) = pt_point_source::Args::try_parse_from(v) else {
            return Err(anyhow::anyhow!("rejected by the flag parser"));
        };
        a.common.out = Some(tmp("ptps-bad"));
        pt_point_source::run(&a)
    };
    // The baseline with the same settings runs, so each error below is the flag's.
    assert!(ps(&[]).is_ok());
    assert!(ps(&["--albedo", "1.0"]).is_err());
    assert!(ps(&["--albedo", "x"]).is_err());
    assert!(ps(&["--g", "1.5"]).is_err());
    assert!(ps(&["--edges", "0,1,0.5"]).is_err());
    assert!(ps(&["--edges", "1"]).is_err());
    assert!(ps(&["--batches", "4"]).is_err());
    let slab = |extra: &[&str]| {
        let mut v = vec!["pt_slab", "--quick", "--no-progress", "--paths", "100"];
        v.extend_from_slice(extra);
        let Ok(mut a) = pt_slab::Args::try_parse_from(v) else {
            return Err(anyhow::anyhow!("rejected by the flag parser"));
        };
        a.common.out = Some(tmp("ptslab-bad"));
        pt_slab::run(&a)
    };
    assert!(slab(&[]).is_ok());
    assert!(slab(&["--tau=-1"]).is_err());
    assert!(slab(&["--tau", "inf", "--albedo", "1"]).is_err());
    assert!(slab(&["--mu0", "0"]).is_err());
    assert!(slab(&["--g=-1"]).is_err());
    assert!(slab(&["--albedo", "1.2"]).is_err());
    let _ = std::fs::remove_dir_all(tmp("ptps-bad"));
    let _ = std::fs::remove_dir_all(tmp("ptslab-bad"));
}

#[test]
fn pt_render_quick_writes_timings_and_an_image() {
    let dir = tmp("ptrender");
    let args = pt_render::Args::parse_from([
        "pt_render",
        "--quick",
        "--no-progress",
        "--res",
        "8",
        "--spp",
        "16",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let rows = pt_render::run(&args).unwrap();
    assert!(dir.join("image.png").is_file());
    assert_eq!(rows.len(), 2);
    assert!(
        rows.iter()
            .all(|r| r.paths == 8 * 8 * 16 && r.mean_radiance > 0.0)
    );
    assert!(pt_render::Args::try_parse_from(["pt_render", "--interpolation", "cubic"]).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}
