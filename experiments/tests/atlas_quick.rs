//! `accuracy_cost` and `renderings` on CI-sized runs: their CSV interfaces and the physics
//! they must show even at this size.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use clap::Parser;
use experiments::common::csv_header;
use experiments::{accuracy_cost, renderings};
use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("scatterbench-{name}-{}", std::process::id()))
}

/// The atlas writes the columns for every dataset and method, the reference noise
/// is positive and below 15 %, and the path tracer's own error falls like
/// 1/√spp: between 16 and 32 spp the debiased error drops by √2 (accepted: 1.15 … 1.75).
#[test]
fn accuracy_cost_quick_atlas() {
    let dir = tmp("accuracy-cost");
    let args = accuracy_cost::Args::parse_from([
        "accuracy_cost",
        "--quick",
        "--no-progress",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let points = accuracy_cost::run(&args).unwrap();
    let header = csv_header(&dir.join("points.csv")).unwrap();
    assert_eq!(
        header[..7],
        [
            "scene",
            "method",
            "setting",
            "backend",
            "seconds",
            "error",
            "error_stderr"
        ]
    );
    for f in ["fastest.csv", "references.csv", "meta.json"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    let scenes = ["nebula", "emissive_cloud", "shell_core", "plume"];
    for s in scenes {
        assert!(dir.join(format!("pareto_{s}.png")).exists());
        for m in accuracy_cost::methods() {
            assert!(
                points.iter().any(|p| p.scene == s && p.method == m.name),
                "{s}: no point of {}",
                m.name
            );
        }
        let mine: Vec<_> = points.iter().filter(|p| p.scene == s).collect();
        assert!(mine.iter().all(|p| p.error.is_finite() && p.seconds > 0.0));
        // The reference's own noise: positive, and small enough at 256 spp to resolve the
        // grid methods' errors (measured 0.048–0.077 over the four quick scenes).
        let noise = mine[0].error_stderr;
        assert!(noise > 0.0 && noise < 0.15, "{s}: reference noise {noise}");
        let pt = |spp: &str| {
            mine.iter()
                .find(|p| p.method == "pt" && p.setting == format!("spp={spp}"))
                .unwrap()
                .error_debiased
        };
        let ratio = pt("16") / pt("32");
        assert!((1.15..1.75).contains(&ratio), "{s}: pt error ratio {ratio}");
    }
    let bad = accuracy_cost::Args::parse_from(["accuracy_cost", "--quick", "--methods", "nope"]);
    assert!(accuracy_cost::run(&bad).is_err());
}

/// The renderings sweep writes its tables; on the nebula FLD-LP's multiple-scattering error
/// is below CDA's at albedo 0.9 at both resolutions (FLD Section 6.2's claim), and a quarter
/// resolution FLD solve costs less than 1/20 of the full-resolution one (FLD Fig 6).
#[test]
fn renderings_quick_sweep() {
    let dir = tmp("renderings");
    let args = renderings::Args::parse_from([
        "renderings",
        "--quick",
        "--no-progress",
        "--scenes",
        "scenes/nebula.toml",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let out = renderings::run(&args).unwrap();
    let header = csv_header(&dir.join("errors.csv")).unwrap();
    assert_eq!(
        header[..8],
        [
            "scene",
            "albedo",
            "method",
            "downsample",
            "backend",
            "error",
            "error_single",
            "error_multiple"
        ]
    );
    for a in ["0.3", "0.9"] {
        assert!(dir.join(format!("nebula_a{a}.png")).exists());
        assert!(dir.join(format!("nebula_a{a}_error.png")).exists());
    }
    let claims: Vec<_> = out.claim.iter().filter(|c| c.albedo == 0.9).collect();
    assert_eq!(claims.len(), 2);
    for c in claims {
        assert!(c.fld_lower, "{c:?}");
    }
    let q = out
        .quarter
        .iter()
        .find(|q| q.method.starts_with("fld:lp"))
        .unwrap();
    assert!(q.cost_ratio < 1.0 / 20.0, "{q:?}");
    // Single scattering does not depend on the diffusion method.
    let single: Vec<f64> = out
        .errors
        .iter()
        .filter(|e| e.albedo == 0.9 && e.downsample == 4)
        .map(|e| e.error_single)
        .collect();
    assert_eq!(single.len(), 2);
    assert_eq!(single[0], single[1]);
}
