//! `render` honours the scene file's `[outputs] write`: `fluence` writes φ of the
//! multiple-scattering solve as a `.vol` grid that our loader reads back equal to the solver's
//! φ (f32-rounded), on the solve grid's box; `image` alone is what writes the images; the
//! path tracer refuses `fluence` with a message saying why.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use clap::Parser;
use experiments::render;
use solvers::pipeline::{self, PipelineConfig};
use solvers::scene::{SceneFile, VolGrid};
use solvers::{Backend, Precision};
use std::path::{Path, PathBuf};

/// A small coloured cloud (32³, solved on 8³ + padding) with the given `[outputs]` list.
fn scene_file(dir: &Path, write: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        format!(
            r#"format = 1
[medium]
generator = "noise_cloud"
params = {{ n = 32, seed = 7, sigma_max = 20.0, albedo = 0.9 }}
sigma_t_rgb = [0.5, 1.0, 1.5]

[[light]]
type = "directional"
direction = [0.4, 0.5, -1.0]
irradiance = 3.0

[camera]
eye = [0.5, -1.0, 0.5]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "orthographic"
width = 1.0
resolution = [16, 16]

[outputs]
write = {write}
"#
        ),
    )
    .unwrap();
    path
}

fn run(scene: &Path, out: &Path, method: &str) -> anyhow::Result<render::RenderOutput> {
    let args = render::Args::parse_from([
        "render",
        "--no-progress",
        "--scene",
        scene.to_str().unwrap(),
        "--method",
        method,
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    render::run(&args)
}

#[test]
fn fluence_output_is_the_solvers_phi_as_a_vol_grid() {
    let dir = common::tmp("render-outputs-fluence");
    let scene = scene_file(&dir, r#"["fluence"]"#);
    let out = dir.join("out");
    run(&scene, &out, "fld").unwrap();
    assert!(
        !out.join("image.pfm").exists(),
        "only `fluence` was asked for"
    );
    let vol = VolGrid::read(&out.join("fluence.vol")).unwrap();

    // The same solve as `render`'s defaults (FLD:LP, downsample 4, CPU f64, 1e-4).
    let file = SceneFile::load(&scene).unwrap();
    let r = pipeline::render_file(
        &file,
        &PipelineConfig::default(),
        &Backend::Cpu(Precision::F64),
    )
    .unwrap();
    assert_eq!(r.diffusion.len(), 3, "three colour channels");
    let grid = r.diffusion[0].solve_grid;
    assert_eq!(vol.dims, grid.n);
    assert_eq!(vol.channels, 3);
    assert_eq!(vol.grid().unwrap().n, grid.n);
    for a in 0..3 {
        assert_eq!(vol.min[a], grid.origin[a] as f32);
        assert_eq!(vol.max[a], (grid.origin[a] + grid.size()[a]) as f32);
    }
    let mut positive = 0;
    for (c, d) in r.diffusion.iter().enumerate() {
        assert_eq!(d.solve_grid, grid);
        let read = vol.channel(c).unwrap();
        assert_eq!(read.len(), d.phi.len());
        for (v, (&got, &want)) in read.iter().zip(&d.phi).enumerate() {
            assert_eq!(got, f64::from(want as f32), "channel {c}, voxel {v}");
        }
        positive += d.phi.iter().filter(|&&p| p > 0.0).count();
    }
    assert!(positive > 0, "a lit cloud has some fluence");
    // The channels differ (σt is scaled per channel), so the interleaving is tested.
    assert_ne!(vol.channel(0).unwrap(), vol.channel(2).unwrap());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn image_and_fluence_together_write_both_and_image_alone_writes_no_fluence() {
    let dir = common::tmp("render-outputs-both");
    let both = scene_file(&dir.join("both"), r#"["image", "fluence"]"#);
    run(&both, &dir.join("both/out"), "fld").unwrap();
    assert!(dir.join("both/out/image.pfm").exists());
    assert!(dir.join("both/out/fluence.vol").exists());
    let image = scene_file(&dir.join("image"), r#"["image"]"#);
    run(&image, &dir.join("image/out"), "fld").unwrap();
    assert!(dir.join("image/out/image.pfm").exists());
    assert!(!dir.join("image/out/fluence.vol").exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn path_tracer_refuses_the_fluence_output_and_unknown_outputs_are_named() {
    let dir = common::tmp("render-outputs-pt");
    let scene = scene_file(&dir, r#"["fluence"]"#);
    let e = run(&scene, &dir.join("out"), "pt").unwrap_err();
    let msg = format!("{e:#}");
    assert!(msg.contains("fluence"), "{msg}");
    assert!(msg.contains("path tracer"), "{msg}");
    assert!(!dir.join("out/fluence.vol").exists());

    let unknown = scene_file(&dir.join("unknown"), r#"["image", "movie"]"#);
    let e = run(&unknown, &dir.join("unknown/out"), "fld").unwrap_err();
    let msg = format!("{e:#}");
    assert!(msg.contains("`movie`"), "{msg}");
    assert!(msg.contains("outputs.write[1]"), "{msg}");
    std::fs::remove_dir_all(&dir).ok();
}
