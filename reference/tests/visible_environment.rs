//! The visible environment and voxel interpolation, against exact answers.
//!
//! * The background term (order 0 from the lights, L_env·T along the camera ray) of the grid
//!   pipeline against the path tracer's order-0 render, on an environment-lit dense sphere
//!   in vacuum seen in perspective (vacuum pixels see L_env exactly); `hide_background`
//!   removes it from both.
//! * Trilinear against nearest: the transmittance through a two-voxel step seen across the
//!   step (rays along y, the step along x), against the analytic pixel averages of
//!   exp(−σ(x)·ℓ) for the step (nearest) and for the clamped linear ramp (trilinear).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::compare::{ImageEstimate, compare};
use reference::effects::render_components;
use reference::pathtracer::{Contributions, RenderSettings, render_image};
use solvers::pipeline::{PipelineConfig, render};
use solvers::scene::{
    Camera, EffectSelection, Interpolation, Light, Phase, Projection, Sampler, Scene,
};
use solvers::{Backend, Grid, Medium, Precision};

/// An HG sphere (σt given, albedo 0.9, radius 0.35 in the unit box of a 16³ grid) lit by
/// an environment of radiance 2, seen along +y by an orthographic camera whose 20×20 pixels
/// each cover one voxel column (so T is constant over a pixel and the pixel average is
/// exact), with a two-pixel ring of vacuum around the box.
pub fn sphere_scene(sigma_t: f64, hide_background: bool) -> Scene {
    let grid = Grid::cube(16, 1.0).unwrap();
    let sigma = grid.sample(|p| {
        let r2: f64 = (0..3).map(|a| (p[a] - 0.5) * (p[a] - 0.5)).sum();
        if r2 < 0.35 * 0.35 { sigma_t } else { 0.0 }
    });
    let n = grid.len();
    Scene {
        medium: Medium::new(grid, sigma, vec![0.9; n], vec![0.0; n]).unwrap(),
        phase: Phase::HenyeyGreenstein { g: 0.5 },
        lights: vec![Light::Environment { radiance: 2.0 }],
        camera: Some(Camera {
            eye: [0.5, -2.0, 0.5],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Orthographic { width: 1.25 },
            resolution: [20, 20],
            hide_background,
        }),
        sampler: Sampler { spp: 16, seed: 0 },
        interpolation: Interpolation::Nearest,
    }
}

#[test]
fn pipeline_background_is_the_path_tracers_order_zero() {
    // σt = 5: τ ≤ 3.5 through the centre, so every pixel's T is resolved by 4096 paths (a
    // pixel whose paths all collide has a zero standard error and an infinite z).
    let scene = sphere_scene(5.0, false);
    assert!(
        scene
            .implied_effects()
            .contains(solvers::scene::Effect::Background)
    );
    let config = PipelineConfig {
        effects: EffectSelection::only(&["background"]).unwrap(),
        pixel_samples: 2,
        ..PipelineConfig::default()
    };
    let r = render(&scene, &config, &Backend::Cpu(Precision::F64)).unwrap();
    assert!(r.plan.runs("raymarch_background"), "{}", r.plan.explain());
    let bg = &r.channels[0].background;
    assert_eq!(bg, &r.channels[0].total);
    let [w, h] = scene.camera.unwrap().resolution;
    let batches = 16;
    let pt = render_image(
        &scene,
        &RenderSettings {
            spp: 4096,
            seed: 3,
            batches,
            contributions: Contributions::background(),
        },
    )
    .unwrap();
    let ours = ImageEstimate::exact(w, h, bg.clone());
    let theirs = ImageEstimate::batched(w, h, pt.mean.clone(), pt.stderr.clone(), batches);
    let c = compare(&ours, &theirs, 0.01).unwrap();
    eprintln!(
        "background: pipeline {:.5} vs path tracer {:.5} ± {:.1e}, z {:+.2}, passing {:.3}",
        c.mean_ours.0, c.mean_theirs.0, c.mean_theirs.1, c.mean_z, c.fraction_passing
    );
    assert!(c.passed(), "z {} passing {}", c.mean_z, c.fraction_passing);
    // Corner pixels see vacuum only: exactly L_env in both; the centre is dark (τ ≈ 3.5).
    assert_eq!(bg[0], 2.0);
    assert_eq!(pt.mean[0], 2.0);
    let centre = bg[10 * w + 10];
    assert!(centre < 2.0 * (-3.0f64).exp(), "centre {centre}");
    // Hidden: the pipeline plans no background and the path tracer's order 0 is black.
    let hidden = sphere_scene(5.0, true);
    assert!(
        !hidden
            .implied_effects()
            .contains(solvers::scene::Effect::Background)
    );
    let pt = render_image(
        &hidden,
        &RenderSettings {
            spp: 64,
            seed: 3,
            batches,
            contributions: Contributions::background(),
        },
    )
    .unwrap();
    assert!(pt.mean.iter().all(|&v| v == 0.0));
}

/// A 4³ grid of edge ¼ in the unit box with σt = a for x < ½ and b above, no
/// scattering, a constant environment, and an orthographic camera looking along +y.
fn step_scene(interpolation: Interpolation, a: f64, b: f64, px: usize) -> Scene {
    let grid = Grid::cube(4, 1.0).unwrap();
    let sigma = grid.sample(|p| if p[0] < 0.5 { a } else { b });
    let n = grid.len();
    Scene {
        medium: Medium::new(grid, sigma, vec![0.0; n], vec![0.0; n]).unwrap(),
        phase: Phase::Isotropic,
        lights: vec![Light::Environment { radiance: 1.0 }],
        camera: Some(Camera {
            eye: [0.5, -1.0, 0.5],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Orthographic { width: 1.0 },
            resolution: [px, 1],
            hide_background: false,
        }),
        sampler: Sampler { spp: 16, seed: 0 },
        interpolation,
    }
}

/// Mean of exp(−σ(x)) over [x0, x1] (path length 1) for σ piecewise linear: constant a
/// below the centre ⅜ of the last a-voxel, linear a → b up to the centre ⅝ of the first
/// b-voxel, b above (trilinear), or the step at ½ (nearest).
fn exact_column(interpolation: Interpolation, a: f64, b: f64, x0: f64, x1: f64) -> f64 {
    let sigma = |x: f64| match interpolation {
        Interpolation::Nearest => {
            if x < 0.5 {
                a
            } else {
                b
            }
        }
        Interpolation::Trilinear => a + (b - a) * ((x - 0.375) / 0.25).clamp(0.0, 1.0),
    };
    // Composite Simpson on a fine grid (the integrand is smooth on each piece; the kinks
    // at ⅜, ½, ⅝ fall on nodes).
    let m = 4096;
    let h = (x1 - x0) / m as f64;
    let mut s = 0.0;
    for k in 0..=m {
        let w = if k == 0 || k == m {
            1.0
        } else if k % 2 == 1 {
            4.0
        } else {
            2.0
        };
        s += w * (-sigma(x0 + k as f64 * h)).exp();
    }
    s * h / 3.0 / (x1 - x0)
}

#[test]
fn trilinear_and_nearest_transmittance_through_a_step() {
    let (a, b, px) = (0.5, 3.0, 8);
    let batches = 16;
    let mut renders = Vec::new();
    for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
        let scene = step_scene(interp, a, b, px);
        let img = render_image(
            &scene,
            &RenderSettings {
                spp: 1 << 16,
                seed: 11,
                batches,
                contributions: Contributions::all(),
            },
        )
        .unwrap();
        renders.push((
            interp,
            ImageEstimate::batched(px, 1, img.mean, img.stderr, batches),
        ));
    }
    // `render --method pt` and `mitsuba_compare` go through `render_components` (one pass per
    // effect): it must honour the scene's interpolation too (it traced nearest voxels
    // whatever the scene said until issue 14's stop 25).
    let scene = step_scene(Interpolation::Trilinear, a, b, px);
    let comp = render_components(
        &scene,
        &scene.implied_effects(),
        &RenderSettings {
            spp: 1 << 16,
            seed: 12,
            batches,
            contributions: Contributions::all(),
        },
    )
    .unwrap();
    renders.push((
        Interpolation::Trilinear,
        ImageEstimate::batched(px, 1, comp.total.mean, comp.total.stderr, batches),
    ));
    let exact = |interp| {
        let mean = (0..px)
            .map(|i| {
                exact_column(
                    interp,
                    a,
                    b,
                    i as f64 / px as f64,
                    (i + 1) as f64 / px as f64,
                )
            })
            .collect();
        ImageEstimate::exact(px, 1, mean)
    };
    for (interp, im) in &renders {
        for truth in [Interpolation::Nearest, Interpolation::Trilinear] {
            let c = compare(&exact(truth), im, 0.01).unwrap();
            eprintln!(
                "{interp:?} render vs {truth:?} exact: mean {:.5} vs {:.5}, z {:+.2}, passing {:.3}",
                c.mean_theirs.0, c.mean_ours.0, c.mean_z, c.fraction_passing
            );
            // Each render matches its own reconstruction and fails the other's.
            assert_eq!(c.passed(), *interp == truth, "{interp:?} vs {truth:?}");
        }
    }
}
