//! Bounded work, no silently ignored option, and warnings for degenerate scenes (issue 13,
//! items 5–7): every binary is spawned as a user would run it.
//!
//! * Runs whose cost estimate (`experiments::cost`) exceeds the work budget are refused
//!   within 2 s, with the estimate and `--force` in the message; `--force` lets them through.
//! * Options that do not apply to the chosen method or backend are errors naming them.
//! * Valid scenes that cannot show anything print one warning line per reason.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::spawn::{Outcome, scratch, spawn, workspace};
use std::path::Path;

fn dir(tag: &str) -> std::path::PathBuf {
    scratch(&format!("bounded-{tag}"))
}

fn scene(name: &str) -> String {
    workspace().join("scenes").join(name).display().to_string()
}

/// Exits with a plain error (code 1 or clap's 2), no signal, within 2 s, and says `needles`.
fn refused(o: &Outcome, what: &str, needles: &[&str]) {
    assert!(
        o.signal.is_none(),
        "{what}: killed by signal {:?}",
        o.signal
    );
    assert!(
        matches!(o.code, Some(1 | 2)),
        "{what}: exit {:?}\n{}",
        o.code,
        o.stderr
    );
    assert!(o.seconds < 2.0, "{what}: took {:.2} s", o.seconds);
    for n in needles {
        assert!(o.stderr.contains(n), "{what}: no `{n}` in\n{}", o.stderr);
    }
}

#[test]
fn runs_over_the_work_budget_are_refused_with_their_estimate_and_force_runs_them() {
    let d = dir("work");
    let cloud = scene("cloud_directional.toml");
    let out = d.join("out").display().to_string();
    let cases: Vec<(&str, Vec<&str>)> = vec![
        (
            env!("CARGO_BIN_EXE_pt_slab"),
            vec!["--tau", "1e6", "--albedo", "1"],
        ),
        (
            env!("CARGO_BIN_EXE_pt_point_source"),
            vec!["--albedo", "0.9999999"],
        ),
        // 64² pixels × 64² rays × 110 voxels / 0.001 raymarch samples, with shadow rays.
        (
            env!("CARGO_BIN_EXE_render"),
            vec![
                "--scene",
                &cloud,
                "--step",
                "0.001",
                "--pixel-samples",
                "64",
            ],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &cloud, "--method", "pt", "--spp", "1e9"],
        ),
        (env!("CARGO_BIN_EXE_pt_render"), vec!["--spp", "1e8"]),
        (
            env!("CARGO_BIN_EXE_point_source"),
            vec!["--tolerance", "0", "--max-iterations", "1e9"],
        ),
        (
            env!("CARGO_BIN_EXE_convergence"),
            vec!["--max-iterations", "1e9"],
        ),
        // SOR on every problem up to 255³ at a tolerance no solve reaches.
        (
            env!("CARGO_BIN_EXE_multigrid_scaling"),
            vec![
                "--sor-max-n",
                "255",
                "--tolerance",
                "1e-300",
                "--max-iterations",
                "1e9",
            ],
        ),
        (
            env!("CARGO_BIN_EXE_i3rc_step_cloud"),
            vec!["--paths", "1e13"],
        ),
        (env!("CARGO_BIN_EXE_renderings"), vec!["--spp", "1e9"]),
        (
            env!("CARGO_BIN_EXE_accuracy_cost"),
            vec!["--reference-spp", "1e9"],
        ),
        (
            env!("CARGO_BIN_EXE_lbm_diffusion_limit"),
            vec!["--max-steps", "1e12"],
        ),
        (
            env!("CARGO_BIN_EXE_lbm_convergence"),
            vec!["--max-steps-factor", "1e9"],
        ),
    ];
    for (bin, args) in &cases {
        let mut a = args.clone();
        a.extend(["--out", &out, "--no-progress"]);
        let o = spawn(bin, &a, &[], &d);
        refused(
            &o,
            &format!("{bin} {args:?}"),
            &["estimated at", "--force", "work budget"],
        );
        assert!(!Path::new(&out).exists(), "{bin}: refused run wrote {out}");
    }
    // The budget reaches every binary: at one operation even a quick run is refused, and
    // --force runs it to completion.
    let o = spawn(
        env!("CARGO_BIN_EXE_pt_slab"),
        &["--quick", "--out", &out, "--no-progress"],
        &[("SCATTERBENCH_WORK_BUDGET", "1")],
        &d,
    );
    refused(
        &o,
        "pt_slab --quick at budget 1",
        &["set by SCATTERBENCH_WORK_BUDGET"],
    );
    let o = spawn(
        env!("CARGO_BIN_EXE_pt_slab"),
        &[
            "--quick",
            "--tau",
            "1",
            "--albedo",
            "0.5",
            "--g",
            "0",
            "--mu0",
            "1",
            "--paths",
            "1e4",
            "--force",
            "--out",
            &out,
            "--no-progress",
        ],
        &[("SCATTERBENCH_WORK_BUDGET", "1")],
        &d,
    );
    assert_eq!(o.code, Some(0), "--force: {}", o.stderr);
    let meta = std::fs::read_to_string(Path::new(&out).join("meta.json")).unwrap();
    assert!(
        meta.contains("\"work_estimate\""),
        "meta.json records the estimate"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn options_that_do_not_apply_are_errors_that_name_them() {
    let d = dir("flags");
    let cloud = scene("cloud_directional.toml");
    let out = d.join("out").display().to_string();
    let render = env!("CARGO_BIN_EXE_render");
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec!["--method", "pt", "--backend", "gpu"],
            vec!["--backend gpu", "CPU only"],
        ),
        (
            vec!["--method", "pt", "--precision", "f32"],
            vec!["--precision", "grid methods"],
        ),
        (
            vec!["--method", "pt", "--downsample", "2", "--omega", "1.5"],
            vec!["--downsample, --omega"],
        ),
        (
            vec!["--method", "pt", "--spp", "4"],
            vec!["--spp = 4", "at least 16"],
        ),
        (
            vec!["--downsample", "1000"],
            vec!["--downsample 1000", "1×1×1", "at most --downsample 21"],
        ),
        (
            vec!["--max-iterations", "0"],
            vec!["--max-iterations", "at least 1"],
        ),
        (vec!["--tolerance", "-1"], vec!["--tolerance -1", "[0, 1)"]),
        (vec!["--step", "1e-9"], vec!["--step 1e-9", "[0.001, 1]"]),
        (
            vec!["--pixel-samples", "100000"],
            vec!["--pixel-samples 100000", "at most 64"],
        ),
        (
            vec!["--precision", "f64", "--backend", "gpu"],
            vec!["f32 only"],
        ),
    ];
    for (args, needles) in &cases {
        let mut a = vec!["--scene", cloud.as_str(), "--quick"];
        a.extend(args.iter().copied());
        a.extend(["--out", &out, "--no-progress"]);
        let o = spawn(render, &a, &[], &d);
        refused(&o, &format!("render {args:?}"), needles);
    }
    // Boolean flags take no value; counts take the float notation of the help texts.
    let o = spawn(
        env!("CARGO_BIN_EXE_pt_render"),
        &["--global", "false", "--quick"],
        &[],
        &d,
    );
    refused(&o, "pt_render --global false", &["--global"]);
    let o = spawn(
        env!("CARGO_BIN_EXE_pt_point_source"),
        &[
            "--quick",
            "--paths",
            "1e3",
            "--batches",
            "16",
            "--albedo",
            "0.5",
            "--g",
            "0",
            "--out",
            &out,
            "--no-progress",
        ],
        &[],
        &d,
    );
    assert_eq!(o.code, Some(0), "--paths 1e3: {}", o.stderr);
    let rows = std::fs::read_to_string(Path::new(&out).join("runs.csv")).unwrap();
    assert!(rows.lines().nth(1).unwrap().contains(",1000,"), "{rows}");
    // `render --seed` changes the path tracer's image; the same seed reproduces it.
    let mut images = Vec::new();
    for seed in ["1", "2", "1"] {
        let o = spawn(
            render,
            &[
                "--scene",
                &cloud,
                "--method",
                "pt",
                "--quick",
                "--seed",
                seed,
                "--out",
                &out,
                "--no-progress",
            ],
            &[],
            &d,
        );
        assert_eq!(o.code, Some(0), "--seed {seed}: {}", o.stderr);
        images.push(std::fs::read(Path::new(&out).join("image.pfm")).unwrap());
    }
    assert_ne!(images[0], images[1], "--seed 2 renders other paths");
    assert_eq!(images[0], images[2], "--seed 1 reproduces itself");
    let _ = std::fs::remove_dir_all(&d);
}

/// A sphere light around the example camera's eye.
const SPHERE_AT_EYE: &str =
    "[[light]]\ntype = \"sphere\"\ncenter = [0.5, -1.0, 0.5]\nradius = 0.2\nradiance = 1.0\n";

/// A valid 8³ `.vol` grid of zeros on the unit box.
fn zero_vol(d: &Path) -> String {
    let mut b = b"VOL\x03".to_vec();
    for v in [1i32, 8, 8, 8, 1] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in [0f32, 0., 0., 1., 1., 1.] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend(std::iter::repeat_n(0u8, 4 * 512));
    let path = d.join("zero.vol");
    std::fs::write(&path, b).unwrap();
    path.display().to_string()
}

#[test]
fn degenerate_scenes_warn_once_per_reason() {
    let d = dir("degenerate");
    let base = std::fs::read_to_string(scene("cloud_directional.toml")).unwrap();
    let light =
        "[[light]]\ntype = \"directional\"\ndirection = [0.4, 0.5, -1.0]\nirradiance = 3.0\n";
    assert!(base.contains(light));
    // The `[medium]` generator lines, replaced by a `.vol` of zeros for the empty medium.
    let params = base.lines().find(|l| l.starts_with("params = ")).unwrap();
    let cloud_medium = format!("generator = \"noise_cloud\"\n{params}\n");
    assert!(base.contains(&cloud_medium));
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "no_light",
            base.replace(light, ""),
            "no light and no volume emission",
        ),
        (
            "away",
            base.replace("target = [0.5, 0.5, 0.5]", "target = [0.5, -2.0, 0.5]"),
            "no camera ray meets the medium",
        ),
        (
            "only_none",
            format!("{base}\n[effects]\nonly = []\n"),
            "excludes every light-transport effect",
        ),
        (
            "empty",
            base.replace(
                &cloud_medium,
                &format!("file = \"{}\"\nalbedo = 0.9\n", zero_vol(&d)),
            ),
            "the medium is empty",
        ),
        (
            "inside_sphere",
            base.replace(light, SPHERE_AT_EYE),
            "inside sphere light 0",
        ),
    ];
    let out = d.join("out").display().to_string();
    for (name, text, needle) in &cases {
        let path = d.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let o = spawn(
            env!("CARGO_BIN_EXE_render"),
            &[
                "--scene",
                &path.display().to_string(),
                "--method",
                "pt",
                "--quick",
                "--out",
                &out,
                "--no-progress",
            ],
            &[],
            &d,
        );
        let warnings: Vec<&str> = o
            .stderr
            .lines()
            .filter(|l| l.starts_with("warning:"))
            .collect();
        assert!(
            warnings.iter().any(|w| w.contains(needle)),
            "{name}: exit {:?}, no warning `{needle}` in\n{}",
            o.code,
            o.stderr
        );
    }
    // The example scene itself is not degenerate.
    let o = spawn(
        env!("CARGO_BIN_EXE_render"),
        &[
            "--scene",
            &scene("cloud_directional.toml"),
            "--quick",
            "--out",
            &out,
            "--no-progress",
        ],
        &[],
        &d,
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    assert!(!o.stderr.contains("warning:"), "{}", o.stderr);
    let _ = std::fs::remove_dir_all(&d);
}
