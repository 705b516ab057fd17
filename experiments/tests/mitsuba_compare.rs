//! `mitsuba_compare` on both example scenes, CI-sized (32×32, 1024 paths per pixel): per-pixel
//! agreement with Mitsuba 3 and agreement of the image means (its files and CSV columns are
//! checked by `tests/registry.rs`).
//!
//! Needs Mitsuba 3 (scripts/setup-mitsuba.sh). Without it the test prints one "skipped" line
//! and passes, unless SCATTERBENCH_REQUIRE_MITSUBA=1, when it fails.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use clap::Parser;
use experiments::mitsuba_compare;
use reference::mitsuba::{MitsubaConfig, MitsubaError};
use std::io::Write;
use std::path::Path;

fn mitsuba_installed() -> bool {
    match MitsubaConfig::new("scalar_rgb").probe() {
        Ok(_) => true,
        Err(e @ MitsubaError::NotInstalled { .. }) => {
            assert!(
                std::env::var("SCATTERBENCH_REQUIRE_MITSUBA").as_deref() != Ok("1"),
                "SCATTERBENCH_REQUIRE_MITSUBA=1 but {e}"
            );
            // Written to the stream directly so that the test harness does not capture it.
            let _ = writeln!(
                std::io::stderr(),
                "skipped: Mitsuba not installed (run scripts/setup-mitsuba.sh)"
            );
            false
        }
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn both_example_scenes_agree_with_mitsuba() {
    if !mitsuba_installed() {
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for scene in ["cloud_directional.toml", "emissive_sphere.toml"] {
        let dir =
            std::env::temp_dir().join(format!("scatterbench-mc-{}-{scene}", std::process::id()));
        let scene_path = root.join("scenes").join(scene);
        let args = mitsuba_compare::Args::parse_from([
            "mitsuba_compare",
            "--quick",
            "--spp",
            "1024",
            "--no-progress",
            "--scene",
            scene_path.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ]);
        let rows = mitsuba_compare::run(&args).unwrap();
        let meta = std::fs::read_to_string(dir.join("meta.json")).unwrap();
        assert!(
            meta.contains("\"variants\"") && meta.contains("scalar_rgb"),
            "{meta}"
        );
        let r = &rows[0];
        assert_eq!(r.pixels, 32 * 32);
        assert!(r.fraction_passing >= 0.99, "{scene}: {r:?}");
        // Image means within 4 combined standard errors (a false alarm has probability 6e-5).
        assert!(r.mean_z.abs() < 4.0, "{scene}: {r:?}");
        // … and the test has the power to see a 5 % difference.
        let combined = r.mean_ours_stderr.hypot(r.mean_mitsuba_stderr);
        assert!(0.05 * r.mean_mitsuba > 4.0 * combined, "{scene}: {r:?}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
